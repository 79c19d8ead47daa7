"""A restored estimator state is untrusted input: each built-in estimator's valid state, corrupted field by
field, is refused with an InputError naming the field and leaves the estimator as it was; loaded in a
subprocess and followed by ``update_many`` of valid measurements, no corruption kills the process by a
signal (compiled kernels index with values from the state); crafted snapshots give a SnapshotError."""

from __future__ import annotations

import copy
import functools
import pickle
import signal
import subprocess
import sys
import textwrap
import tracemalloc

import numpy as np
import pytest

from radartracker.errors import InputError
from radartracker.estimation.base import EstimatorConfig
from radartracker.estimation.motion import MotionModel
from radartracker.registry import make_estimator
from radartracker.simulation.linsim import make_linear_scenario

P0 = np.diag([1e4**2, 1e4**2, 300.0**2, 300.0**2])
CONFIG = EstimatorConfig(motion=MotionModel(0.3))
ESTIMATORS = ("coupled", "coupled-sparse", "blom", "decoupled")


def _scenario():
    return make_linear_scenario(n_aircraft=4, n_radars=3, duration=40.0, rng=7, q=0.3, adsb_aircraft=1)


def _fresh(name: str, sc):
    return make_estimator(name, CONFIG, sc.radar_ids)


@functools.cache
def _valid_state(name: str) -> dict:
    """The state after a small scenario with an aircraft removed (a free slot) and one added after it."""
    sc = _scenario()
    est = _fresh(name, sc)
    for k, x in sc.initial.items():
        est.add_aircraft(k, 0.0, x, P0)
    ms = sc.measurements
    for m in ms[: len(ms) // 2]:
        est.update(m)
    est.remove_aircraft(list(sc.initial)[0])
    est.add_aircraft("late", ms[len(ms) // 2].time, np.array([1e3, 2e3, 50.0, 0.0]), P0)
    return est.state_dict()


def _first_key(d: dict):
    return next(iter(d))


def _set(path: tuple, value):
    """A corruption: state[path[0]][path[1]]... = value (a callable of the old value, or the value)."""
    def corrupt(state):
        target = state
        for p in path[:-1]:
            target = target[p(target) if callable(p) else p]
        key = path[-1](target) if callable(path[-1]) else path[-1]
        target[key] = value(target[key]) if callable(value) else value
    return corrupt


def _replace(field: str, fn):
    def corrupt(state):
        state[field] = fn(state[field])
    return corrupt


def _item(field: str, index: tuple, value):
    def corrupt(state):
        state[field] = np.array(state[field])
        state[field][index] = value
    return corrupt


def _live_slot(state) -> int:
    return state["aircraft"][_first_key(state["aircraft"])]


def _sparse_item(field: str, col, value):
    def corrupt(state):
        state[field] = state[field].copy()
        state[field][(_live_slot(state),) + col] = value
    return corrupt


SPARSE = {
    "slot_out_of_range": _set(("aircraft", _first_key), 10**6),
    "slot_negative": _set(("aircraft", _first_key), -1),
    "slot_a_string": _set(("aircraft", _first_key), "0"),
    "slot_given_twice": lambda s: s["aircraft"].update(late=s["aircraft"][_first_key(s["aircraft"])]),
    "free_slot_out_of_range": lambda s: s["free"].append(10**6),
    "free_slot_of_a_live_aircraft": lambda s: s["free"].append(s["aircraft"]["late"]),
    "nk_too_large": _sparse_item("nk", (), 7),
    "nk_huge": _sparse_item("nk", (), 10**12),
    "rk_out_of_range": _sparse_item("rk", (0,), 10**6),
    "rk_negative": _sparse_item("rk", (0,), -7),
    "rk_repeated": lambda s: _sparse_item("rk", (1,), s["rk"][_live_slot(s), 0])(s),
    "free_slot_with_radars": lambda s: _item("nk", (s["free"][0],), 2)(s),
    "tx_wrong_length": _replace("tx", lambda v: v[:-1]),
    "Yxb_wrong_shape": _replace("Yxb", lambda v: v[:, :, :-2]),
    "rk_float_dtype": _replace("rk", lambda v: v.astype(float)),
    "Pb_complex_dtype": _replace("Pb", lambda v: v.astype(complex)),
    "Pb_nan": _item("Pb", (0, 0), np.nan),
    "Pb_asymmetric": _item("Pb", (0, 1), 1e-3),
    "S_indefinite": _replace("S", lambda v: -v),
    "Yxx_indefinite": lambda s: _sparse_item("Yxx", (0, 0), -1.0)(s),
    "alive_count_huge": _item("ctr", (4,), 10**12),
    "since_refresh_negative": _item("ctr", (0,), -5),
    "radars_reordered": _replace("radars", lambda v: v[::-1]),
    "bias_time_a_string": _set(("bias_time",), "soon"),
    "field_missing": lambda s: s.pop("Pb"),
    "field_unknown": lambda s: s.update(_q=1e9),
}
COUPLED = {
    "size_huge": _set(("size",), 10**12),  # memory bomb: must not size anything from the number
    "size_negative": _set(("size",), -4),
    "x_wrong_length": _replace("x", lambda v: v[:-1]),
    "P_wrong_shape": _replace("P", lambda v: v[:-1]),
    "P_nan": _item("P", (0, 0), np.nan),
    "P_indefinite": _item("P", (0, 0), -1.0),
    "aircraft_start_out_of_range": _set(("aircraft", _first_key, 0), 10**6),
    "aircraft_start_on_a_radar": lambda s: _set(("aircraft", _first_key, 0), s["radars"][_first_key(s["radars"])])(s),
    "free_start_negative": lambda s: s["free"].append(-4),
    "radar_start_overlapping": _set(("radars", _first_key), 1),
    "epoch_infinite": _set(("aircraft", _first_key, 1), np.inf),
    "radars_missing": lambda s: s["radars"].pop(_first_key(s["radars"])),
    "bias_time_a_string": _set(("bias_time",), "soon"),
}
BLOM = {
    "s_wrong_length": _replace("s", lambda v: v[:-1]),
    "Ps_nan": _item("Ps", (1, 1), np.nan),
    "Ps_indefinite": _replace("Ps", lambda v: -v),
    "radar_column_out_of_range": _set(("radars", _first_key), 10**6),
    "aircraft_cov_wrong_shape": _set(("aircraft", _first_key, 2), np.eye(3)),
    "aircraft_state_infinite": _set(("aircraft", _first_key, 1), np.full(4, np.inf)),
    "source_unknown_radar": lambda s: s["aircraft"][_first_key(s["aircraft"])][3].update(X=(np.eye(2), np.eye(2))),
    "source_R_singular": lambda s: s["aircraft"][_first_key(s["aircraft"])][3].update(
        {_first_key(s["radars"]): (np.eye(2), np.zeros((2, 2)))}),
    "epoch_a_string": _set(("aircraft", _first_key, 0), "t"),
}
DECOUPLED = {
    "aircraft_state_wrong_length": _set(("aircraft", _first_key, 1), np.zeros(3)),
    "aircraft_cov_nan": lambda s: s["aircraft"][_first_key(s["aircraft"])][2].__setitem__((0, 0), np.nan),
    "radar_cov_indefinite": _set(("radars", _first_key, 2), -np.eye(2)),
    "radars_missing": lambda s: s["radars"].pop(_first_key(s["radars"])),
    "entry_too_short": _set(("aircraft", _first_key), [0.0]),
    "epoch_infinite": _set(("aircraft", _first_key, 0), np.inf),
}
CASES = {"coupled-sparse": SPARSE, "coupled": COUPLED, "blom": BLOM, "decoupled": DECOUPLED}


def _corrupted(name: str, case: str) -> dict:
    state = copy.deepcopy(_valid_state(name))
    CASES[name][case](state)
    return state


def _same_state(a, b) -> bool:
    if isinstance(a, dict):
        return isinstance(b, dict) and list(a) == list(b) and all(_same_state(a[k], b[k]) for k in a)
    if isinstance(a, (list, tuple)):
        return type(a) is type(b) and len(a) == len(b) and all(_same_state(x, y) for x, y in zip(a, b))
    if isinstance(a, np.ndarray):
        return isinstance(b, np.ndarray) and np.array_equal(a, b, equal_nan=True)
    return a == b or (a != a and b != b)


@pytest.mark.parametrize("name,case", [(n, c) for n in ESTIMATORS for c in CASES[n]])
def test_corrupted_state_is_refused_before_anything_changes(name, case):
    """Oracle: the fresh estimator's own state_dict, unchanged after the refused load."""
    sc = _scenario()
    est = _fresh(name, sc)
    before = est.state_dict()
    with pytest.raises(InputError, match=f"{name} state: "):
        est.load_state_dict(_corrupted(name, case))
    assert _same_state(est.state_dict(), before)


@pytest.mark.parametrize("name", ESTIMATORS)
def test_valid_state_loads_and_continues_as_the_original(name):
    """The uncorrupted state of each case's base loads, and continues as the estimator it came from."""
    sc = _scenario()
    est = _fresh(name, sc)
    for k, x in sc.initial.items():
        est.add_aircraft(k, 0.0, x, P0)
    for m in sc.measurements[:30]:
        est.update(m)
    other = _fresh(name, sc)
    other.load_state_dict(copy.deepcopy(est.state_dict()))
    for m in sc.measurements[30:60]:
        a, b = est.update(m), other.update(m)
        np.testing.assert_array_equal(a.nu, b.nu)
        np.testing.assert_array_equal(a.S, b.S)


def test_a_huge_size_is_refused_before_allocating():
    """The memory bomb: ``size = 10¹²`` in a dense coupled state allocates nothing (traced peak < 1 MB)."""
    sc = _scenario()
    est = _fresh("coupled", sc)
    state = _corrupted("coupled", "size_huge")
    tracemalloc.start()
    try:
        with pytest.raises(InputError, match="size = 1000000000000 is outside"):
            est.load_state_dict(state)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 1 << 20


_CHILD = textwrap.dedent("""
    import pickle, sys
    import numpy as np
    from radartracker.errors import InputError
    from radartracker.estimation.base import EstimatorConfig
    from radartracker.estimation.motion import MotionModel
    from radartracker.registry import make_estimator
    from radartracker.simulation.linsim import make_linear_scenario
    name, cases = pickle.loads(sys.stdin.buffer.read())
    sc = make_linear_scenario(n_aircraft=4, n_radars=3, duration=40.0, rng=7, q=0.3, adsb_aircraft=1)
    ms = sc.measurements[len(sc.measurements) // 2:][:40]
    for case, state in cases:
        print(case, flush=True)
        est = make_estimator(name, EstimatorConfig(motion=MotionModel(0.3)), sc.radar_ids)
        try:
            est.load_state_dict(state)
        except InputError:
            pass
        keys = est.aircraft_keys or ["late"]
        for k in list(sc.initial):
            if k not in keys:
                est.add_aircraft(k, ms[0].time, np.array([1e3, 2e3, 0.0, 0.0]), np.eye(4) * 1e6)
        for lo in range(0, len(ms), 8):
            b = ms[lo:lo + 8]
            try:
                est.update_many([m.time for m in b], [m.aircraft for m in b], [m.radar for m in b],
                                np.array([m.z for m in b]), np.array([m.C for m in b]), np.array([m.R for m in b]))
            except (KeyError, ValueError):
                pass
        for k in est.aircraft_keys:
            est.aircraft(k)
    print("done", flush=True)
""")


def _run_child(code: str, payload: bytes) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code], input=payload, capture_output=True, timeout=600)


def _verdict(proc: subprocess.CompletedProcess) -> str:
    """'' if the child exited by itself, else which signal killed it and after which case."""
    if proc.returncode >= 0:
        return ""
    last = proc.stdout.decode().split()[-1:] or ["(none)"]
    return f"killed by {signal.Signals(-proc.returncode).name} in case {last[0]}"


def test_the_subprocess_harness_sees_a_signal():
    """The harness can fail: a child that segfaults is reported as killed by SIGSEGV."""
    proc = _run_child("import os, signal; print('crash', flush=True); os.kill(os.getpid(), signal.SIGSEGV)", b"")
    assert _verdict(proc) == "killed by SIGSEGV in case crash"


@pytest.mark.parametrize("name", ESTIMATORS)
def test_corrupted_states_then_updates_never_kill_the_process(name):
    """Every corruption of ``name``'s state loaded into a fresh estimator in a subprocess, then update_many of
    valid measurements and a read of every aircraft: the process ends by itself."""
    cases = [(case, _corrupted(name, case)) for case in CASES[name]]
    proc = _run_child(_CHILD, pickle.dumps((name, cases)))
    assert _verdict(proc) == "", proc.stderr.decode()[-2000:]
    assert proc.returncode == 0, proc.stderr.decode()[-2000:]
    assert proc.stdout.decode().split()[-1] == "done"


SNAPSHOT_CASES = ("slot_out_of_range", "nk_huge", "rk_out_of_range", "tx_wrong_length", "free_slot_out_of_range",
                  "alive_count_huge")
_SNAPSHOT_CHILD = textwrap.dedent("""
    import pickle, sys
    from radartracker.errors import SnapshotError
    from radartracker.registry import restore_manager
    paths, items = pickle.loads(sys.stdin.buffer.read())
    for path in paths:
        print(path, flush=True)
        try:
            mgr = restore_manager(path)
        except SnapshotError as exc:
            print("refused", str(exc), flush=True)
            continue
        mgr.process_many(items)
        print("restored", flush=True)
    print("done", flush=True)
""")


def test_crafted_snapshots_are_refused_and_never_kill_the_process(tmp_path):
    """Six snapshots with a valid checksum whose coupled-sparse state has an out-of-range slot, a huge radar
    count, an out-of-range radar index, a short array, a free slot beyond the storage and a huge aircraft
    count: restoring each in a subprocess gives a SnapshotError naming the file and the field, no signal."""
    from radartracker.registry import make_manager
    from radartracker.tracking.config import ManagerConfig
    from tests.tracking.test_snapshot import items_and_data

    items, data = items_and_data.__wrapped__()
    mgr = make_manager(data.radars, data.reference, ManagerConfig(estimator="coupled-sparse"))
    half = len(items) // 2
    mgr.process_many(items[:half])
    good = mgr.estimator.state_dict()
    assert good["free"] and good["aircraft"]
    paths = []
    for case in SNAPSHOT_CASES:
        state = copy.deepcopy(good)
        SPARSE[case](state)
        mgr.estimator.state_dict = lambda state=state: state
        paths.append(str(tmp_path / case))
        mgr.snapshot(paths[-1])
    proc = _run_child(_SNAPSHOT_CHILD, pickle.dumps((paths, items[half:half + 300])))
    assert _verdict(proc) == "", proc.stderr.decode()[-2000:]
    lines = proc.stdout.decode().splitlines()
    assert proc.returncode == 0 and lines[-1] == "done", proc.stderr.decode()[-2000:]
    verdicts = dict(zip(lines[0:-1:2], lines[1:-1:2]))
    assert list(verdicts) == paths
    for path, verdict in verdicts.items():
        assert verdict.startswith(f"refused {path}: cannot restore: InputError: coupled-sparse state: "), verdict


def _graph_state() -> dict:
    from radartracker.estimation.coupling import CouplingGraph

    sc = _scenario()
    g = CouplingGraph(sc.radar_ids)
    for m in sc.measurements[:60]:
        g.observe(m.aircraft, m.radar, m.time)
    g.remove_aircraft(list(sc.initial)[0])
    return g.state_dict()


def _adj(state, node):
    return next(nbrs for u, nbrs in state["adj"] if u == node)


GRAPH = {
    "node_kind_unknown": lambda s: s["nodes"][0][1].update(kind="satellite"),
    "node_count_negative": lambda s: s["nodes"][0][1].update(measurements=-1),
    "reference_missing": lambda s: s.update(nodes=[n for n in s["nodes"] if n[0] != "adsb"]),
    "edge_to_a_missing_node": lambda s: _adj(s, "radar:R00").append(("aircraft:ghost", {"kind": "observation",
                                                                                      "count": 1, "last_time": 0.0})),
    "edge_listed_from_one_end": lambda s: _adj(s, "radar:R00").pop(),
    "edge_count_a_string": lambda s: _adj(s, "radar:R00")[0][1].update(count="many"),
    "self_loop": lambda s: _adj(s, "radar:R00").append(("radar:R00", {"kind": "observation", "count": 1,
                                                                      "last_time": 0.0})),
    "adjacency_not_pairs": lambda s: s.update(adj=[1, 2, 3]),
}


@pytest.mark.parametrize("case", GRAPH)
def test_corrupted_coupling_graph_state_is_refused(case):
    """Oracle: the graph's own state_dict, unchanged after the refused load; the valid state loads back equal."""
    from radartracker.estimation.coupling import CouplingGraph

    g = CouplingGraph(_scenario().radar_ids)
    before = g.state_dict()
    state = copy.deepcopy(_graph_state())
    GRAPH[case](state)
    with pytest.raises(InputError, match="coupling graph state: "):
        g.load_state_dict(state)
    assert g.state_dict() == before
    g.load_state_dict(_graph_state())
    assert g.state_dict() == _graph_state()
