"""Coupling graph: edges, marginalisation fill-in, components, observability report, GraphML."""

from __future__ import annotations

import json
from itertools import combinations

import networkx as nx
import numpy as np
import pytest

from radartracker.estimation.coupling import ADSB, CouplingGraph
from radartracker.simulation.linsim import make_linear_scenario
from radartracker.estimation.base import EstimatorConfig
from radartracker.registry import make_estimator


def test_edges_count_observations_and_last_time():
    g = CouplingGraph(["R1", "R2"])
    for t in (1.0, 5.0, 3.0):
        g.observe("A", "R1", t)
    g.observe("A", None, 2.0)
    e = g.graph.edges["aircraft:A", "radar:R1"]
    assert (e["count"], e["last_time"]) == (3, 5.0)
    assert g.graph.has_edge("aircraft:A", ADSB)
    assert not g.graph.has_edge("aircraft:A", "radar:R2")


def test_report_statuses_and_marginalisation_keeps_ties():
    g = CouplingGraph(["R1", "R2", "R3", "R4"])
    g.observe("A", "R1", 0.0), g.observe("A", "R2", 1.0)  # R1–R2 share A
    g.observe("B", "R3", 0.0), g.observe("B", None, 1.0)  # R3 sees an ADS-B aircraft
    rep = g.report()["radars"]
    assert rep["R1"]["status"] == "relative" and rep["R1"]["shares_aircraft_with"] == ["R2"]
    assert rep["R3"]["status"] == "anchored" and rep["R3"]["adsb_direct"]
    assert rep["R4"]["status"] == "isolated" and rep["R4"]["shares_aircraft_with"] == []
    g.remove_aircraft("A"), g.remove_aircraft("B")
    assert "aircraft:A" not in g.graph
    rep2 = g.report()
    assert rep2["radars"]["R1"]["shares_aircraft_with"] == ["R2"]  # fill-in edge
    assert rep2["radars"]["R3"]["adsb_reference"] and rep2["radars"]["R1"]["measurements"] == 1
    assert g.graph.edges["radar:R1", "radar:R2"]["kind"] == "marginalised"
    # an aircraft seen by R2 and R3 chains R1 to the ADS-B reference
    g.observe("C", "R2", 2.0), g.observe("C", "R3", 2.5)
    assert g.report()["radars"]["R1"]["status"] == "anchored"
    assert not g.report()["radars"]["R1"]["adsb_direct"]


def test_graph_is_the_sparsity_of_the_coupled_information_matrix():
    """Oracle: nonzero blocks of Y = P⁻¹ of the coupled filter are exactly the graph's edges.

    A radar–radar block of Y is nonzero only through marginalised aircraft, an aircraft–radar
    block only where that radar measured it; ADS-B touches only aircraft blocks.
    """
    sc = make_linear_scenario(n_aircraft=6, n_radars=4, duration=60.0, rng=4)
    keep = {"R00": {"A0000", "A0001"}, "R01": {"A0001", "A0002"}, "R02": {"A0003"}, "R03": {"A0004"}}
    g = CouplingGraph(sc.radar_ids)
    est = make_estimator("coupled", EstimatorConfig(), sc.radar_ids)
    for k, x in sc.initial.items():
        est.add_aircraft(k, 0.0, x, np.diag([1e4, 1e4, 100.0, 100.0]))
        g.add_aircraft(k)
    for m in sc.measurements:
        if m.aircraft in keep[m.radar]:
            est.update(m), g.observe(m.aircraft, m.radar, m.time)
    est.remove_aircraft("A0001"), g.remove_aircraft("A0001")
    keys = est.aircraft_keys
    _, P = est.joint(keys)
    Y = np.linalg.inv(P)
    blocks = [(f"aircraft:{k}", 4) for k in keys] + [(f"radar:{r}", 2) for r in sc.radar_ids]
    starts = np.cumsum([0] + [n for _, n in blocks])
    for (u, nu_), su in zip(blocks, starts):
        for (v, nv), sv in zip(blocks, starts):
            if u >= v:
                continue
            nz = np.abs(Y[su:su + nu_, sv:sv + nv]).max() > 1e-9 * np.sqrt(
                np.abs(np.diag(Y)[su:su + nu_]).max() * np.abs(np.diag(Y)[sv:sv + nv]).max())
            assert nz == g.graph.has_edge(u, v), (u, v)
    comps = g.report()["components"]
    assert {"R00", "R01"} in [set(c["radars"]) for c in comps]


def test_graphml_round_trip(tmp_path):
    g = CouplingGraph(["R1"])
    g.observe(17, "R1", 3.0), g.observe(17, None, 4.0)
    g.remove_aircraft(17)
    g.observe("X", "R1", 5.0)
    path = tmp_path / "coupling.graphml"
    g.write_graphml(path)
    h = nx.read_graphml(path)
    assert set(h.nodes) == set(g.graph.nodes)
    assert h.edges["radar:R1", ADSB]["kind"] == "marginalised"
    assert h.edges["aircraft:X", "radar:R1"]["count"] == 1


def test_replay_writes_graphml_and_observability(tmp_path):
    """seed scenario (no ADS-B): radars share aircraft but are not anchored; demo: ADS-B anchors all."""
    from radartracker.pipeline.config import RunConfig
    from radartracker.pipeline.run import run
    from radartracker.pipeline.writer import write_outputs
    from radartracker.simulation.scenarios import build_scenario

    for name, status in (("seed", "relative"), ("demo", "anchored")):
        result = run(build_scenario(name, seed=3, duration=120.0).run(), RunConfig(estimator="coupled"), progress=False)
        write_outputs(result, tmp_path / name)
        h = nx.read_graphml(tmp_path / name / "coupling.graphml")
        radars = {d["label"] for _, d in h.nodes(data=True) if d["kind"] == "radar"}
        assert radars == {"R1", "R2", "R3"}
        obs = json.loads((tmp_path / name / "summary.json").read_text())["observability"]
        assert {r["status"] for r in obs["radars"].values()} == {status}
        assert sum(r["measurements"] for r in obs["radars"].values()) == result.counts["plots_used"]


def _reference_observe(g: nx.Graph, aircraft, radar, time) -> None:
    """observe() written straight on networkx (the graph's definition, without CouplingGraph's caches)."""
    a, r = f"aircraft:{aircraft}", ADSB if radar is None else f"radar:{radar}"
    if a not in g:
        g.add_node(a, kind="aircraft", label=str(aircraft))
    if r not in g:
        g.add_node(r, kind="radar", label=str(radar), measurements=0)
    g.nodes[r]["measurements"] += 1
    if g.has_edge(a, r):
        g.edges[a, r]["count"] += 1
        g.edges[a, r]["last_time"] = max(g.edges[a, r]["last_time"], float(time))
    else:
        g.add_edge(a, r, kind="observation", count=1, last_time=float(time))


@pytest.mark.parametrize("batched", [False, True])
@pytest.mark.parametrize("keys", [(7, "7", 8, "x", 9), (1, 1.0, True, "1", 2)])
def test_cached_observations_give_the_graph_built_straight_on_networkx(tmp_path, batched, keys):
    """Oracle: the same random observations, removals (also of keys observed again later, of keys written
    alike, 7 and "7", and of keys equal but written differently, 1, 1.0 and True), new radars and a snapshot
    round trip, applied to a plain networkx graph:
    equal state dicts (node and neighbour order included) and byte-identical GraphML. ``batched``: the
    observations between two removals or snapshots go to observe_many in runs of 1 to 40 (its loop below
    16, its arrays above; with new pairs, pairs seen twice in a run, times out of order, keys seen again
    after their removal)."""
    rng, sizes = np.random.default_rng(11), np.random.default_rng(12)
    pending: list[tuple] = []  # batched: observations not yet given to g

    def observe_pending() -> None:
        while pending:
            n = int(sizes.integers(1, 41))
            g.observe_many(*zip(*pending[:n]))
            del pending[:n]
    g = CouplingGraph(["R1", "R2", "R3"])
    ref = nx.Graph()
    ref.add_node(ADSB, kind="reference", label=ADSB, measurements=0)
    for r in ("R1", "R2", "R3"):
        ref.add_node(f"radar:{r}", kind="radar", label=r, measurements=0)
    rare = 0.2 if batched else 1.0  # batched: removals and snapshots 5x rarer, so runs of observations are long
    for step in range(int(600 / rare)):
        u = rng.random() / rare
        key = keys[rng.integers(len(keys))]
        if u < 0.05 and f"aircraft:{key}" in ref:
            observe_pending()
            g.remove_aircraft(key)
            edges = ref.edges(f"aircraft:{key}", data=True)
            last = {src: d["last_time"] for _, src, d in edges}
            for p, q in combinations(sorted(last), 2):
                t = max(last[p], last[q])
                if ref.has_edge(p, q):
                    ref.edges[p, q]["count"] += 1
                    ref.edges[p, q]["last_time"] = max(ref.edges[p, q]["last_time"], t)
                else:
                    ref.add_edge(p, q, kind="marginalised", count=1, last_time=t)
            ref.remove_node(f"aircraft:{key}")
        elif u < 0.08:  # into a new graph, or into the same one (its caches must go)
            observe_pending()
            g2 = CouplingGraph() if u < 0.065 else g
            g2.load_state_dict(g.state_dict())
            g = g2
        else:
            radar = [None, "R1", "R2", "R3", "R4"][rng.integers(5)]
            t = float(rng.uniform(0, 100))
            if batched:
                pending.append((key, radar, t))
            else:
                g.observe(key, radar, t)
            _reference_observe(ref, key, radar, t)
    observe_pending()
    mine = g.state_dict()
    assert mine == {"nodes": [(n, dict(d)) for n, d in ref.nodes(data=True)],
                    "adj": [(u, [(v, dict(d)) for v, d in nbrs.items()]) for u, nbrs in ref.adj.items()]}
    assert any(d["kind"] == "marginalised" for *_, d in ref.edges(data=True))
    g.write_graphml(tmp_path / "a.graphml")
    nx.write_graphml(ref, str(tmp_path / "b.graphml"))
    assert (tmp_path / "a.graphml").read_bytes() == (tmp_path / "b.graphml").read_bytes()


def test_keys_written_alike_share_a_node_and_go_with_it():
    """Oracle: the plain networkx graph. Keys written alike (7 and "7") are one node, so removing one of
    them drops the pair's cached edge for both; keys equal as dict keys but written differently (1, 1.0,
    True) are three nodes. A cache of edges keyed by the aircraft key gets both wrong."""
    g, ref = CouplingGraph(["R1"]), nx.Graph()
    ref.add_node(ADSB, kind="reference", label=ADSB, measurements=0)
    ref.add_node("radar:R1", kind="radar", label="R1", measurements=0)
    for step, (key, t) in enumerate([(7, 1.0), ("7", 2.0), (None, 7), ("7", 3.0), (1, 4.0), (1.0, 5.0), (True, 6.0)]):
        if key is None:
            g.remove_aircraft(t)
            ref.remove_node(f"aircraft:{t}")
            continue
        g.observe(key, "R1", t)
        _reference_observe(ref, key, "R1", t)
        assert g.state_dict() == {"nodes": [(n, dict(d)) for n, d in ref.nodes(data=True)],
                                  "adj": [(u, [(v, dict(d)) for v, d in nbrs.items()]) for u, nbrs in ref.adj.items()]}, step


def test_observe_many_counts_each_key_on_its_own_node_after_removals():
    """Oracle: the plain networkx graph. observe_many finds the table rows of int and str keys by key (7 and
    "7" share one, as they share a node); removing either frees the row for both, so a later aircraft can take
    it while 7 is counted on a new one; a removal writes the aircraft's counts before its node goes."""
    g, ref = CouplingGraph(["R1", "R2"]), nx.Graph()
    ref.add_node(ADSB, kind="reference", label=ADSB, measurements=0)
    for r in ("R1", "R2"):
        ref.add_node(f"radar:{r}", kind="radar", label=r, measurements=0)
    steps = [[(7, "R1", 1.0), ("7", "R2", 2.0), (8, "R1", 3.0)] * 6, "7",
             [(9, "R1", 4.0), (7, "R2", 5.0), (8, "R2", 6.0)] * 6,
             [(7, "R1", 8.0), (9, "R1", 9.0), (9, None, 7.0)] * 6, 7, 9,
             [(7, "R1", 10.0), (8, None, 11.0)] * 8]
    for step in steps:
        if isinstance(step, list):
            assert len(step) >= 16  # observe_many's arrays
            g.observe_many(*zip(*step))
            for obs in step:
                _reference_observe(ref, *obs)
        else:
            g.remove_aircraft(step)
            a = f"aircraft:{step}"
            last = {src: d["last_time"] for _, src, d in ref.edges(a, data=True)}
            for p, q in combinations(sorted(last), 2):
                if ref.has_edge(p, q):
                    ref.edges[p, q]["count"] += 1
                    ref.edges[p, q]["last_time"] = max(ref.edges[p, q]["last_time"], last[p], last[q])
                else:
                    ref.add_edge(p, q, kind="marginalised", count=1, last_time=max(last[p], last[q]))
            ref.remove_node(a)
    assert g.state_dict() == {"nodes": [(n, dict(d)) for n, d in ref.nodes(data=True)],
                              "adj": [(u, [(v, dict(d)) for v, d in nbrs.items()]) for u, nbrs in ref.adj.items()]}
