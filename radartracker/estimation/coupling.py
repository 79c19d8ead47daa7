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

from collections.abc import Callable, Hashable, Sequence
from itertools import combinations
from pathlib import Path

import networkx as nx
import numpy as np
from numba import njit

from radartracker.errors import InputError

ADSB = "adsb"
_NODE = "aircraft:{}".format  # _aircraft_node as a callable for map()
# two int or str keys are equal as dict keys only if their nodes are (unlike 1, 1.0 and True, one each):
# observe_many finds the rows of such keys by key, without naming their nodes
_PLAIN_KEYS = frozenset((int, str))
_BATCH = 16  # observe_many: from this many measurements on, counted in one compiled pass, written to the graph later


# compiled when imported (from the disk cache after the first time): the warm-up's tiny run has no batch this long
@njit("intp(intp[:], intp[:], float64[:], boolean[:, :], int64[:, :], float64[:, :], int64[:], intp[:])", cache=True)
def _count(rows: np.ndarray, cols: np.ndarray, times: np.ndarray, known: np.ndarray, count: np.ndarray,
           latest: np.ndarray, source_count: np.ndarray, new: np.ndarray) -> int:
    """Measurement i (aircraft row ``rows[i]``, source column ``cols[i]``, at ``times[i]``) counted into the
    tables in order: ``count`` and ``source_count`` + 1, ``latest`` its maximum (``np.fmax``: a NaN time is
    never latest). ``new[:k]`` = the i of the pairs not ``known`` before, the first of each, marked known;
    returns k."""
    k = 0
    for i in range(rows.shape[0]):
        r, c = rows[i], cols[i]
        if not known[r, c]:
            known[r, c] = True
            new[k] = i
            k += 1
        count[r, c] += 1
        if times[i] > latest[r, c]:
            latest[r, c] = times[i]
        source_count[c] += 1
    return k


_KINDS = {"aircraft": (), "radar": ("measurements",), "reference": ("measurements",)}  # node kinds, their counts
_EDGE_KINDS = ("observation", "marginalised")


def _checked_graph_state(state: object) -> tuple[list, list]:
    """(nodes, edges) of a coupling-graph state to add in order: nodes named by strings with a known
    ``kind``, string labels and non-negative integer counts, the reference node among them; every edge
    between two nodes, listed from both ends with the same attributes (a known kind, a non-negative
    ``count``, a ``last_time``), no self-loops; the edges in an order that gives every node its saved
    order of neighbours. Raises InputError naming what is wrong."""
    def fail(message: str) -> InputError:
        return InputError(f"coupling graph state: {message}")

    if not isinstance(state, dict) or set(state) != {"nodes", "adj"}:
        raise fail("not a map of 'nodes' and 'adj'")
    nodes = {}
    for item in _pairs(state["nodes"], fail, "nodes"):
        name, d = item
        if not isinstance(name, str) or not isinstance(d, dict) or name in nodes:
            raise fail(f"node {name!r} is not a new name with a map of attributes")
        kind = d.get("kind")
        if kind not in _KINDS or set(d) != {"kind", "label", *_KINDS[kind]} or not isinstance(d["label"], str):
            raise fail(f"node {name!r} has attributes {sorted(map(str, d))} of kind {kind!r}")
        for count in _KINDS[kind]:
            _count_ok(d[count], fail, f"node {name!r} {count}")
        nodes[name] = dict(d)
    if nodes.get(ADSB, {}).get("kind") != "reference":
        raise fail(f"the reference node {ADSB!r} is missing")
    order = {}
    for item in _pairs(state["adj"], fail, "adj"):
        u, nbrs = item
        if u not in nodes or u in order:
            raise fail(f"adjacency of {u!r}: not a node, or listed twice")
        order[u] = [v for v, _ in _pairs(nbrs, fail, f"adjacency of {u!r}")]
        for v, d in nbrs:
            _edge_ok(u, v, d, nodes, fail)
    return list(nodes.items()), _edge_order(state["adj"], order, fail)


def _pairs(value: object, fail: Callable[[str], InputError], what: str) -> list:
    if not isinstance(value, (list, tuple)) or not all(isinstance(p, (list, tuple)) and len(p) == 2 for p in value):
        raise fail(f"{what} is not a list of pairs")
    return list(value)


def _count_ok(value: object, fail: Callable[[str], InputError], what: str) -> None:
    if isinstance(value, bool) or not isinstance(value, int) or value < 0:
        raise fail(f"{what} = {value!r} is not a non-negative integer")


def _edge_ok(u: str, v: object, d: object, nodes: dict, fail: Callable[[str], InputError]) -> None:
    if v not in nodes or v == u:
        raise fail(f"edge {u!r} – {v!r}: not a node, or a self-loop")
    if not isinstance(d, dict) or set(d) != {"kind", "count", "last_time"} or d["kind"] not in _EDGE_KINDS:
        raise fail(f"edge {u!r} – {v!r}: attributes {d!r}")
    _count_ok(d["count"], fail, f"edge {u!r} – {v!r} count")
    if isinstance(d["last_time"], bool) or not isinstance(d["last_time"], (int, float)) or np.isinf(d["last_time"]):
        raise fail(f"edge {u!r} – {v!r}: last_time {d['last_time']!r} is not a number")


def _edge_order(adj: list, order: dict[str, list], fail: Callable[[str], InputError]) -> list:
    """The edges (u, v, attributes) in an order that appends every node's neighbours in its saved order:
    a topological order of the edges under "(u, a) before (u, b) when a precedes b in u's list"."""
    data, after = {}, nx.DiGraph()
    for u, nbrs in adj:
        for v, d in nbrs:
            e = frozenset((u, v))
            if e in data and data[e] != d:
                raise fail(f"edge {u!r} – {v!r} has different attributes from its two ends")
            data[e] = d
            after.add_node(e)
        for a, b in zip(order[u], order[u][1:]):
            after.add_edge(frozenset((u, a)), frozenset((u, b)))
    for u, vs in order.items():
        if len(set(vs)) != len(vs) or any(u not in order.get(v, ()) for v in vs):
            raise fail(f"adjacency of {u!r} repeats a neighbour or is not listed from the other end")
    try:
        edges = list(nx.lexicographical_topological_sort(after, key=lambda e: sorted(e)))
    except nx.NetworkXUnfeasible:
        raise fail("the neighbour orders contradict one another") from None
    return [(*sorted(e), dict(data[e])) for e in edges]


def _aircraft_node(key: Hashable) -> str:
    return f"aircraft:{key}"


def _radar_node(radar: str | None) -> str:
    return ADSB if radar is None else f"radar:{radar}"


class CouplingGraph:
    """Radar–aircraft coupling graph, kept current as tracks are created and deleted.

    ``graph`` is read freely but changed only through these methods: :meth:`observe` keeps the attribute
    dicts of the pairs it has seen (O(1) dict updates per measurement, no node names or graph lookups);
    :meth:`observe_many` counts a large batch in arrays by (aircraft row, source column) and writes the
    counts and latest times into those dicts when the graph is read (``graph``) or the aircraft removed."""

    def __init__(self, radars: list[str] | tuple[str, ...] = ()) -> None:
        self._graph = nx.Graph()
        # by aircraft node, then radar: the graph's own attribute dicts of that edge and of the radar's node,
        # so observe() of a known pair updates them without graph lookups
        self._edges: dict[str, dict[str | None, tuple[dict, dict]]] = {}
        self._graph.add_node(ADSB, kind="reference", label=ADSB, measurements=0)
        self._tied: set[str] = set()  # radars found not isolated (:meth:`isolated`)
        self._clear_pending()
        for r in radars:
            self.add_radar(r)

    @property
    def graph(self) -> nx.Graph:
        """The networkx graph, with every observation counted so far (read it; change it through the methods)."""
        if self._dirty:
            self._write_pending()
        return self._graph

    def _clear_pending(self) -> None:
        """Empty tables of observe_many: rows by aircraft node, columns by radar (None: the reference)."""
        self._row: dict[str, int] = {}
        self._key_row: dict[int | str, int] = {}  # the rows of plain keys (_PLAIN_KEYS) seen, by key
        self._keys: dict[int, list] = {}  # by row: its plain keys (7 and "7" share a node, so a row)
        self._free_rows: list[int] = []
        self._col: dict[str | None, int] = {}
        self._source: list[dict | None] = []  # by column: the source node's attribute dict, once observed
        self._pair: dict[tuple[int, int], dict] = {}  # (row, column) → the edge's attribute dict
        self._known = np.zeros((0, 0), bool)  # (row, column): the edge exists and is in _pair
        self._count = np.zeros((0, 0), np.int64)  # observations not yet written into the edge dicts
        self._latest = np.zeros((0, 0))  # their latest time (−inf: none)
        self._source_count = np.zeros(0, np.int64)  # by column: not yet written into the node dicts
        self._dirty = False

    def add_radar(self, radar: str) -> None:
        self._graph.add_node(_radar_node(radar), kind="radar", label=str(radar), measurements=0)

    def add_aircraft(self, key: Hashable) -> None:
        self._graph.add_node(_aircraft_node(key), kind="aircraft", label=str(key))
        self._row_of(key)

    def observe(self, aircraft: Hashable, radar: str | None, time: float) -> None:
        """Record one measurement of ``aircraft`` by ``radar`` (``None``: ADS-B) at ``time``."""
        self.observe_many((aircraft,), (radar,), (time,))

    def observe_many(self, aircraft: Sequence[Hashable], radar: Sequence[str | None], time: Sequence[float]) -> None:
        """:meth:`observe` of each measurement (``aircraft[i]``, ``radar[i]``, ``time[i]``) in turn, with the
        same graph. A batch of ``_BATCH`` or more is counted in arrays (new pairs still join the graph in
        order); a smaller one in observe's loop, without a method call per measurement."""
        n = len(aircraft)
        if n < _BATCH:
            edges = self._edges
            for a, r, t in zip(aircraft, radar, time):
                try:
                    edge, source = edges[f"aircraft:{a}"][r]  # _aircraft_node(a), inlined
                except KeyError:  # a new pair: through the graph, then cached
                    edge, source = self._edge(a, r, t)
                source["measurements"] += 1
                edge["count"] += 1
                t = float(t)
                if t > edge["last_time"]:
                    edge["last_time"] = t
            return
        try:  # by key where every key is plain, else by node name
            rows = (np.fromiter(map(self._key_row.__getitem__, aircraft), np.intp, n)
                    if set(map(type, aircraft)) <= _PLAIN_KEYS else
                    np.fromiter(map(self._row.__getitem__, map(_NODE, aircraft)), np.intp, n))
        except KeyError:  # an aircraft first seen here
            rows = np.fromiter(map(self._row_of, aircraft), np.intp, n)
        try:
            cols = np.fromiter(map(self._col.__getitem__, radar), np.intp, n)
        except KeyError:  # a source first seen here
            cols = np.fromiter(map(self._col_of, radar), np.intp, n)
        new = np.empty(n, np.intp)
        k = _count(rows, cols, np.asarray(time, float), self._known, self._count, self._latest, self._source_count, new)
        for i in new[:k].tolist():  # the new pairs join the graph in order
            r, c = int(rows[i]), int(cols[i])
            self._pair[r, c], self._source[c] = self._edge(aircraft[i], radar[i], time[i])
        self._dirty = True

    def _row_of(self, key: Hashable) -> int:
        """The table row of aircraft ``key``'s node, given it if new (the tables grow by doubling)."""
        node = _NODE(key)
        row = self._row.get(node)
        if row is None:
            row = self._row[node] = self._free_rows.pop() if self._free_rows else len(self._row)
            if row >= self._known.shape[0]:
                self._grow(max(16, 2 * row), self._known.shape[1])
        if type(key) in _PLAIN_KEYS and key not in self._key_row:
            self._key_row[key] = row
            self._keys.setdefault(row, []).append(key)
        return row

    def _col_of(self, radar: str | None) -> int:
        """The table column of source ``radar``, given it if new."""
        col = self._col.get(radar)
        if col is None:
            col = self._col[radar] = len(self._col)
            self._source.append(None)
            self._source_count = np.append(self._source_count, 0)
            if col >= self._known.shape[1]:
                self._grow(self._known.shape[0], max(8, 2 * col))
        return col

    def _grow(self, rows: int, cols: int) -> None:
        """The tables to ``rows`` × ``cols``, keeping their contents."""
        for name, fill in (("_known", False), ("_count", 0), ("_latest", -np.inf)):
            old = getattr(self, name)
            new = np.full((rows, cols), fill, old.dtype)
            new[:old.shape[0], :old.shape[1]] = old
            setattr(self, name, new)

    def _write_row(self, row: int) -> None:
        """Aircraft ``row``'s pending observations into its edge dicts."""
        for col in np.flatnonzero(self._count[row]).tolist():
            edge = self._pair[row, col]
            edge["count"] += int(self._count[row, col])
            t = float(self._latest[row, col])
            if t > edge["last_time"]:
                edge["last_time"] = t
            self._count[row, col], self._latest[row, col] = 0, -np.inf

    def _write_pending(self) -> None:
        """Every pending observation into the graph's dicts."""
        for row in np.flatnonzero(self._count.any(axis=1)).tolist():
            self._write_row(row)
        for col in np.flatnonzero(self._source_count).tolist():
            self._source[col]["measurements"] += int(self._source_count[col])
        self._source_count[:] = 0
        self._dirty = False

    def _edge(self, aircraft: Hashable, radar: str | None, time: float) -> tuple[dict, dict]:
        """The attribute dicts of the edge (aircraft, radar), made with count 0 if new, and of the radar's node."""
        g, a, r = self._graph, _aircraft_node(aircraft), _radar_node(radar)
        if a not in g:
            self.add_aircraft(aircraft)
        if r not in g:
            self.add_radar(radar)
        if not g.has_edge(a, r):
            g.add_edge(a, r, kind="observation", count=0, last_time=float(time))
        pair = self._edges.setdefault(a, {})[radar] = (g.edges[a, r], g.nodes[r])
        return pair

    def remove_aircraft(self, key: Hashable) -> None:
        """Marginalise aircraft ``key``: join the sources it linked, then drop its node."""
        a = _aircraft_node(key)
        self._edges.pop(a, None)
        row = self._row.pop(a, None)
        if row is not None:  # its pending observations first; then its row is free
            self._write_row(row)
            for k in self._keys.pop(row, ()):
                del self._key_row[k]
            for col in np.flatnonzero(self._known[row]).tolist():
                del self._pair[row, col]
            self._known[row] = False
            self._free_rows.append(row)
        g = self._graph
        edges = g.edges(a, data=True)
        last = {src: d["last_time"] for _, src, d in edges}
        for u, v in combinations(sorted(last), 2):
            t = max(last[u], last[v])
            data = g.get_edge_data(u, v)
            if data is None:
                g.add_edge(u, v, kind="marginalised", count=1, last_time=t)
            else:
                data["count"] += 1
                data["last_time"] = max(data["last_time"], t)
        g.remove_node(a)

    # --- snapshots ---------------------------------------------------------------------------------
    def state_dict(self) -> dict:
        """Nodes and adjacency as plain values, in the graph's own order (for snapshots)."""
        g = self.graph
        return {"nodes": [(n, dict(d)) for n, d in g.nodes(data=True)],
                "adj": [(u, [(v, dict(d)) for v, d in nbrs.items()]) for u, nbrs in g.adj.items()]}

    def load_state_dict(self, state: dict) -> None:
        """Rebuild the graph of :meth:`state_dict` through networkx's public API, each node's neighbours in
        their saved order. The state is untrusted: checked first (:func:`_checked_graph_state`)."""
        nodes, edges = _checked_graph_state(state)
        g = nx.Graph()
        g.add_nodes_from(nodes)
        g.add_edges_from(edges)
        self._graph = g
        self._edges = {}
        self._tied = set()
        self._clear_pending()

    # --- diagnostics -------------------------------------------------------------------------------
    def isolated(self, radar: str) -> bool:
        """Whether ``radar`` is tied to nothing: none of its aircraft measured by another source and no source
        joined to it by marginalisation (the ``isolated`` status of :meth:`report`, found from its neighbours,
        not the components). A radar once tied stays tied (a removed aircraft's links are kept), so that is
        remembered and the question costs a set lookup from then on."""
        if radar in self._tied:
            return False
        g, node = self._graph, _radar_node(radar)
        nodes = g.nodes
        for nb in g[node] if node in g else ():
            if nodes[nb]["kind"] != "aircraft" or len(g[nb]) > 1:
                self._tied.add(radar)
                return False
        return True

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
        """The graph as GraphML at ``path``, written by ``networkx.write_graphml``."""
        nx.write_graphml(self.graph, str(path))
