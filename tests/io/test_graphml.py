"""GraphML written directly has the bytes of networkx.write_graphml (the oracle), or is networkx's own."""

import math

import networkx as nx
import numpy as np
import pytest

from radartracker.io.graphml import graphml_text, write_graphml

ODD = ["", "a&b", "<x>", 'say "hi"', "tab\there", "two\nlines", "cr\rhere", "é ü ∑", "\ud800 lone surrogate",
       "  ", "7"]


def _random_graph(seed: int) -> nx.Graph:
    rng = np.random.default_rng(seed)
    g = nx.Graph()
    values = [lambda: int(rng.integers(-5, 10**12)), lambda: float(rng.normal(0, 1e6)), lambda: bool(rng.integers(2)),
              lambda: ODD[int(rng.integers(len(ODD)))], lambda: [math.nan, math.inf, -0.0, 1e-300][int(rng.integers(4))]]
    names = ["kind", "label", "count", 3, "x y", 'q"']
    nodes = [f"n{i}" if i % 3 else ODD[i % len(ODD)] + str(i) for i in range(int(rng.integers(0, 30)))]
    for n in nodes:
        k = int(rng.integers(0, 4))
        g.add_node(n, **{str(a): values[int(rng.integers(len(values)))]() for a in rng.choice(names, k, replace=False)})
    for _ in range(int(rng.integers(0, 60))) if nodes else ():
        u, v = rng.choice(nodes, 2)
        g.add_edge(u, v, **{str(a): values[int(rng.integers(len(values)))]() for a in
                            rng.choice(names, int(rng.integers(0, 4)), replace=False)})
    return g


def _networkx_bytes(g, tmp_path) -> bytes:
    nx.write_graphml(g, str(tmp_path / "nx.graphml"))
    return (tmp_path / "nx.graphml").read_bytes()


@pytest.mark.parametrize("seed", range(40))
def test_the_bytes_of_networkx(seed, tmp_path):
    g = _random_graph(seed)
    assert graphml_text(g) is not None
    write_graphml(g, tmp_path / "ours.graphml")
    assert (tmp_path / "ours.graphml").read_bytes() == _networkx_bytes(g, tmp_path)


def test_the_empty_graph_and_nodes_without_data(tmp_path):
    for g in (nx.Graph(), nx.Graph([("a", "b")]), nx.path_graph(3)):
        write_graphml(g, tmp_path / "ours.graphml")
        assert (tmp_path / "ours.graphml").read_bytes() == _networkx_bytes(g, tmp_path)


@pytest.mark.parametrize("make", [
    lambda: nx.DiGraph([("a", "b")]),
    lambda: nx.MultiGraph([("a", "b"), ("a", "b")]),
    lambda: nx.Graph(name="titled"),
    lambda: nx.Graph([("a", "b", {"w": np.float64(1.5)})]),
    lambda: nx.Graph([("a", "b", {"w": np.int64(2)})]),
])
def test_other_graphs_go_to_networkx(make, tmp_path):
    g = make()
    assert graphml_text(g) is None
    write_graphml(g, tmp_path / "ours.graphml")
    assert (tmp_path / "ours.graphml").read_bytes() == _networkx_bytes(make(), tmp_path)
