"""The coupling graph: which radars and aircraft are tied together through measurements (DESIGN §2).

Nodes: one per aircraft (``kind="aircraft"``), one per radar (``kind="radar"``) and one reference
node :data:`ADSB` (``kind="reference"``) standing for every unbiased source. An edge joins a radar
(or the reference) to each aircraft it has measured, with the number of measurements ``count``
and the time of the last one ``last_time``. This is the sparsity pattern of the joint information
matrix of the coupled filter (seed 000 §1.2.1), with the reference node as the absolute frame.

Removing an aircraft (its track ends) marginalises it, exactly as the coupled filter does: its
node goes, and every pair of sources it linked becomes joined directly (``kind="marginalised"``,
``count`` = number of removed aircraft they shared) — the fill-in of the information matrix. So a
radar that once shared aircraft with another stays coupled to it, and one whose aircraft once
reported ADS-B stays tied to the reference.

The observability report per radar says whether it shares aircraft with other radars and whether
it is tied (directly or through a chain of shared aircraft) to the ADS-B reference. A radar in a
component without the reference has only relative observability: some combinations of biases are
fixed only by geometry, weakly (DESIGN §5).
"""

from __future__ import annotations

from collections.abc import Hashable, Sequence
from itertools import combinations
from pathlib import Path

import networkx as nx

ADSB = "adsb"


def _aircraft_node(key: Hashable) -> str:
    return f"aircraft:{key}"


def _radar_node(radar: str | None) -> str:
    return ADSB if radar is None else f"radar:{radar}"


class CouplingGraph:
    """Radar–aircraft coupling graph, kept current as tracks are created and deleted.

    ``graph`` is read freely but changed only through these methods: :meth:`observe` keeps the attribute
    dicts of the pairs it has seen (O(1) dict updates per measurement, no node names or graph lookups)."""

    def __init__(self, radars: list[str] | tuple[str, ...] = ()) -> None:
        self.graph = nx.Graph()
        # by aircraft node, then radar: the graph's own attribute dicts of that edge and of the radar's node,
        # so observe() of a known pair updates them without graph lookups
        self._edges: dict[str, dict[str | None, tuple[dict, dict]]] = {}
        self.graph.add_node(ADSB, kind="reference", label=ADSB, measurements=0)
        for r in radars:
            self.add_radar(r)

    def add_radar(self, radar: str) -> None:
        self.graph.add_node(_radar_node(radar), kind="radar", label=str(radar), measurements=0)

    def add_aircraft(self, key: Hashable) -> None:
        self.graph.add_node(_aircraft_node(key), kind="aircraft", label=str(key))

    def observe(self, aircraft: Hashable, radar: str | None, time: float) -> None:
        """Record one measurement of ``aircraft`` by ``radar`` (``None``: ADS-B) at ``time``."""
        try:
            edge, source = self._edges[_aircraft_node(aircraft)][radar]
        except KeyError:  # a new pair: through the graph, then cached
            edge, source = self._pair(aircraft, radar, time)
        source["measurements"] += 1
        edge["count"] += 1
        t = float(time)
        if t > edge["last_time"]:
            edge["last_time"] = t

    def observe_many(self, aircraft: Sequence[Hashable], radar: Sequence[str | None], time: Sequence[float]) -> None:
        """:meth:`observe` of each measurement (``aircraft[i]``, ``radar[i]``, ``time[i]``) in turn: the same
        graph, one Python loop without a method call per measurement."""
        edges = self._edges
        for a, r, t in zip(aircraft, radar, time):
            try:
                edge, source = edges[f"aircraft:{a}"][r]  # _aircraft_node(a), inlined
            except KeyError:
                edge, source = self._pair(a, r, t)
            source["measurements"] += 1
            edge["count"] += 1
            t = float(t)
            if t > edge["last_time"]:
                edge["last_time"] = t

    def _pair(self, aircraft: Hashable, radar: str | None, time: float) -> tuple[dict, dict]:
        """The attribute dicts of the edge (aircraft, radar), made with count 0 if new, and of the radar's node."""
        a, r = _aircraft_node(aircraft), _radar_node(radar)
        if a not in self.graph:
            self.add_aircraft(aircraft)
        if r not in self.graph:
            self.add_radar(radar)
        if not self.graph.has_edge(a, r):
            self.graph.add_edge(a, r, kind="observation", count=0, last_time=float(time))
        pair = self._edges.setdefault(a, {})[radar] = (self.graph.edges[a, r], self.graph.nodes[r])
        return pair

    def remove_aircraft(self, key: Hashable) -> None:
        """Marginalise aircraft ``key``: join the sources it linked, then drop its node."""
        a = _aircraft_node(key)
        self._edges.pop(a, None)
        edges = self.graph.edges(a, data=True)
        last = {src: d["last_time"] for _, src, d in edges}
        for u, v in combinations(sorted(last), 2):
            t = max(last[u], last[v])
            data = self.graph.get_edge_data(u, v)
            if data is None:
                self.graph.add_edge(u, v, kind="marginalised", count=1, last_time=t)
            else:
                data["count"] += 1
                data["last_time"] = max(data["last_time"], t)
        self.graph.remove_node(a)

    # --- snapshots ---------------------------------------------------------------------------------
    def state_dict(self) -> dict:
        """Nodes and adjacency as plain values, in the graph's own order (for snapshots)."""
        g = self.graph
        return {"nodes": [(n, dict(d)) for n, d in g.nodes(data=True)],
                "adj": [(u, [(v, dict(d)) for v, d in nbrs.items()]) for u, nbrs in g.adj.items()]}

    def load_state_dict(self, state: dict) -> None:
        """Rebuild the graph of :meth:`state_dict`, with each node's neighbours in their saved order."""
        g = nx.Graph()
        g.add_nodes_from(state["nodes"])
        edges: dict[frozenset, dict] = {}
        for u, nbrs in state["adj"]:
            for v, d in nbrs:
                # one attribute dict shared by both directions, as networkx keeps it
                g._adj[u][v] = edges.setdefault(frozenset((u, v)), dict(d))
        self.graph = g
        self._edges = {}

    # --- diagnostics -------------------------------------------------------------------------------
    def components(self) -> list[set[str]]:
        """Connected components (node names), largest first; independent blocks of the joint filter."""
        return sorted(nx.connected_components(self.graph), key=len, reverse=True)

    def report(self) -> dict:
        """Per-radar observability: partners, ADS-B tie, component; plus component sizes."""
        comps = self.components()
        comp_of = {n: i for i, c in enumerate(comps) for n in c}
        radars = {}
        for node, d in self.graph.nodes(data=True):
            if d["kind"] != "radar":
                continue
            partners = set()
            for nb in self.graph[node]:
                kind = self.graph.nodes[nb]["kind"]
                if kind == "aircraft":
                    partners |= {s for s in self.graph[nb] if s != node}
                else:
                    partners.add(nb)
            shares = sorted(self.graph.nodes[p]["label"] for p in partners if p != ADSB)
            direct_adsb = ADSB in partners
            anchored = comp_of[node] == comp_of[ADSB]
            status = "anchored" if anchored else ("relative" if shares else "isolated")
            radars[d["label"]] = {
                "status": status,
                "shares_aircraft_with": shares,
                "adsb_direct": direct_adsb,
                "adsb_reference": anchored,
                "aircraft_now": sum(1 for nb in self.graph[node] if self.graph.nodes[nb]["kind"] == "aircraft"),
                "measurements": d["measurements"],
                "component": comp_of[node],
            }
        return {
            "radars": radars,
            "components": [
                {"radars": sorted(self.graph.nodes[n]["label"] for n in c if self.graph.nodes[n]["kind"] == "radar"),
                 "aircraft": sum(1 for n in c if self.graph.nodes[n]["kind"] == "aircraft"),
                 "adsb_reference": ADSB in c}
                for c in comps
            ],
        }

    def write_graphml(self, path: Path | str) -> None:
        nx.write_graphml(self.graph, str(path))
