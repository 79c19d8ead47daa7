"""Snapshots: bit-for-bit continuation with every built-in plugin; bad files refused, never executed."""

import hashlib
import os
import pickle
import struct

import msgpack
import numpy as np
import pytest

from radartracker.registry import make_manager, restore_manager
from radartracker.domain import AdsbReport, Plot
from radartracker.errors import SnapshotError
from radartracker.simulation.scenarios import build_scenario
from radartracker.tracking import snapshot
from radartracker.tracking.config import ManagerConfig


def _opt(v):
    return None if v != v else float(v)


@pytest.fixture(scope="module")
def items_and_data():
    data = build_scenario("tracking", seed=11, duration=150.0).run()
    p, a = data.plots, data.adsb
    items = [Plot(float(p.time[i]), p.radar[i], float(p.range_m[i]), float(p.azimuth_rad[i]), _opt(p.altitude_m[i]),
                  p.mode_s[i], p.mode_3a[i]) for i in range(len(p))]
    items += [AdsbReport(float(a.time[i]), a.icao24[i], float(a.lat[i]), float(a.lon[i]), _opt(a.altitude_m[i]),
                         int(a.nacp[i])) for i in range(len(a))]
    return sorted(items, key=lambda i: i.time), data


def _state(mgr, events):
    ests = {k: (e.time, e.state.tolist(), e.cov.tolist()) for k in mgr.estimator.aircraft_keys
            for e in [mgr.estimator.aircraft(k)]}
    biases = {r: (mgr.estimator.bias(r).bias.tolist(), mgr.estimator.bias(r).cov.tolist()) for r in mgr.estimator.radars}
    filters = {i: (t.filter.estimate()[0], t.filter.estimate()[1].tolist(), t.filter.estimate()[2].tolist())
               for i, t in mgr.tracks.items()}
    return events, ests, biases, filters, mgr.accounting(), mgr.coupling.report(), mgr.innovations()


@pytest.mark.parametrize("estimator,motion", [("decoupled", "cv"), ("coupled", "cv"), ("blom", "cv"),
                                              ("coupled-sparse", "cv"), ("decoupled", "imm"),
                                              ("decoupled", "adaptive"), ("decoupled", "fading")])
def test_restore_continues_bit_for_bit(tmp_path, items_and_data, estimator, motion):
    """Half, snapshot, restore, rest == uninterrupted, exactly (every built-in estimator and motion model)."""
    items, data = items_and_data
    cfg = ManagerConfig(estimator=estimator, motion_model=motion)
    whole = make_manager(data.radars, data.reference, cfg)
    ev_whole = whole.process_many(items)
    half = len(items) // 2
    first = make_manager(data.radars, data.reference, cfg)
    ev = [e for i in items[:half] for e in first.process(i)]
    first.snapshot(tmp_path / "snap")
    second = restore_manager(tmp_path / "snap")
    ev += second.process_many(items[half:])
    assert len(ev_whole) > 50
    assert _state(second, ev) == _state(whole, ev_whole)


@pytest.fixture
def saved(tmp_path, items_and_data):
    items, data = items_and_data
    mgr = make_manager(data.radars, data.reference)
    for i in items[:500]:
        mgr.process(i)
    path = tmp_path / "snap"
    mgr.snapshot(path)
    return mgr, path


def _rewrite(path, payload, version=snapshot.FORMAT_VERSION):
    path.write_bytes(struct.pack(">8sIQ32s", snapshot.MAGIC, version, len(payload), hashlib.sha256(payload).digest())
                     + payload)


@pytest.mark.parametrize("damage,message", [
    (lambda b: b[: len(b) // 2], "truncated"),
    (lambda b: b[:30], "truncated"),
    (lambda b: b[:100] + bytes([b[100] ^ 0x01]) + b[101:], "corrupted"),
    (lambda b: b + b"\0", "padded"),
    (lambda b: b"PK\x03\x04" + b[4:], "not a radartracker snapshot"),
    (lambda b: pickle.dumps({"x": 1}), "not a radartracker snapshot"),
    (lambda b: b[:8] + struct.pack(">I", 3) + b[12:], "newer"),
    (lambda b: b[:8] + struct.pack(">I", 1) + b[12:], "earlier release"),
    (lambda b: b"", "not a radartracker snapshot"),
])
def test_bad_files_are_refused_naming_them(saved, damage, message):
    _, path = saved
    path.write_bytes(damage(path.read_bytes()))
    with pytest.raises(SnapshotError, match=message) as err:
        restore_manager(path)
    assert str(path) in str(err.value)


def _craft(path, meta, state):
    _rewrite(path, msgpack.packb([meta, msgpack.packb(state, use_bin_type=True)], use_bin_type=True))


@pytest.mark.parametrize("meta", [
    {"t": "attrs", "v": ["os", "system", [["command", "touch pwned"]]]},  # not radartracker: not even looked up
    {"t": "attrs", "v": ["radartracker.nonexistent", "X", []]},  # not imported: nothing is imported
    {"t": "pickle", "v": b"cos\nsystem\n(S'touch pwned'\ntR."},  # no such tag
    {"kind": "TrackManager"},  # a bare map is not a value
    [1, 2, 3],
])
def test_crafted_payloads_are_refused_and_never_executed(tmp_path, meta, monkeypatch):
    monkeypatch.chdir(tmp_path)
    path = tmp_path / "snap"
    _craft(path, meta, {"t": "dict", "v": []})
    with pytest.raises(SnapshotError, match="cannot restore"):
        restore_manager(path)
    assert not (tmp_path / "pwned").exists()


def test_crafted_state_is_checked_field_by_field(saved):
    """The state is a document of named fields, each checked: an unknown field, a method's name or a wrong
    type is refused naming it; nothing is set on the manager by name."""
    mgr, path = saved
    meta, blob = snapshot.decode(snapshot.read_snapshot_file(path))
    state = snapshot.decode(blob)
    for change, message in ((lambda d: d.update(update=1), "fields"), (lambda d: d.pop("counts"), "fields"),
                            (lambda d: d.update(frame="7"), "frame"), (lambda d: d.update(next_track=-1), "next_track"),
                            (lambda d: d.update(counts={"x": -1}), "counts"),
                            (lambda d: d.update(innovations={"count": 3, "sum": -1.0}), "innovations"),
                            (lambda d: d.update(innovations={"count": 3}), "innovations")):
        bad = dict(state)
        change(bad)
        _rewrite(path, snapshot.encode([meta, snapshot.encode(bad, "state")], "snap"))
        with pytest.raises(SnapshotError, match=message):
            restore_manager(path)


def test_failed_snapshot_leaves_the_previous_one(saved, monkeypatch):
    mgr, path = saved
    good = path.read_bytes()
    mgr.counts[("x", object())] += 1  # a state the format cannot hold
    with pytest.raises(SnapshotError, match="not written"):
        mgr.snapshot(path)
    del mgr.counts[next(k for k in mgr.counts if isinstance(k, tuple))]

    def full_disk(*a):
        raise OSError(28, "No space left on device")
    monkeypatch.setattr(snapshot.os, "fsync", full_disk)
    with pytest.raises(OSError):
        mgr.snapshot(path)
    assert path.read_bytes() == good
    assert os.listdir(path.parent) == [path.name]
    restore_manager(path)


def test_arrays_and_types_round_trip():
    """The codec keeps types exactly: tuples, keys, NumPy scalars, Fortran order, counters."""
    from collections import Counter, deque
    import itertools

    value = {(1, "a"): [np.float32(1.5), np.asfortranarray(np.arange(6.0).reshape(2, 3)), 2 + 3j],
             7: deque([True, None], maxlen=3), "c": Counter(a=2), "n": itertools.count(5), "s": {1.0}}
    out = snapshot.decode(snapshot.encode(value, "v"))
    assert list(out) == list(value) and type(out[(1, "a")][0]) is np.float32
    assert out[(1, "a")][1].flags.f_contiguous and (out[(1, "a")][1] == value[(1, "a")][1]).all()
    assert out[7].maxlen == 3 and list(out[7]) == [True, None] and out["c"] == Counter(a=2)
    assert next(out["n"]) == 5 and out["s"] == {1.0} and out[(1, "a")][2] == 2 + 3j


def test_restore_with_another_estimator_is_refused(saved):
    """A manager given its estimator as an object is restored only with one of the same class."""
    from radartracker.registry import make_estimator

    mgr, path = saved
    other = "blom" if type(mgr.estimator).__name__ != "BlomEstimator" else "decoupled"
    with pytest.raises(SnapshotError, match="estimator was"):
        restore_manager(path, estimator=make_estimator(other, None, []))
    assert type(restore_manager(path, estimator=make_estimator(mgr.config.estimator, None, [])).estimator) \
        is type(mgr.estimator)


def test_a_track_whose_filter_was_never_started_is_refused(saved):
    """Found by fuzzing (a mutated, re-checksummed snapshot, seed 28 input 5 488): a track's filter state that
    loads but holds no estimate made the restored manager's first process() raise. Refused on restore."""
    from radartracker.registry import make_filter_factory

    mgr, path = saved
    meta, blob = snapshot.decode(snapshot.read_snapshot_file(path))
    state = snapshot.decode(blob)
    fresh = make_filter_factory(mgr.config.motion_model)(snapshot.decode(state["tracks"][0]["filter"]["config"]))
    state["tracks"][0]["filter"]["state"] = snapshot.encode(fresh.state_dict(), "filter")
    _rewrite(path, snapshot.encode([meta, snapshot.encode(state, "state")], "snap"))
    with pytest.raises(SnapshotError, match="track\\[0\\] filter"):
        restore_manager(path)


@pytest.mark.parametrize("where", ["meta", "reference"])
def test_a_crafted_meta_is_refused_whatever_it_provokes(saved, where):
    """Found by fuzzing 10⁵ re-checksummed mutations (seed 28, inputs 15 086 and 21 094): a tagged value too
    short for its tag made the decoder raise IndexError, and settings out of range made building the manager
    overflow; both are a SnapshotError naming the file."""
    mgr, path = saved
    meta, blob = snapshot.decode(snapshot.read_snapshot_file(path))
    if where == "meta":
        payload = msgpack.packb([{"t": "deque", "v": []}, blob], use_bin_type=True)
    else:
        meta["reference"] = [1e308, 1e308]
        payload = snapshot.encode([meta, blob], "snap")
    _rewrite(path, payload)
    with pytest.raises(SnapshotError) as err:
        restore_manager(path)
    assert str(path) in str(err.value)


def test_a_vertical_filter_out_of_physical_bounds_is_refused(saved):
    """Found by fuzzing (seed 29, input 1 648): a track's Mode C filter with a time of about −10³⁰⁰ made the
    next altitude update overflow (dt³). Times, altitudes, rates and the covariance are bounded on restore."""
    mgr, path = saved
    meta, blob = snapshot.decode(snapshot.read_snapshot_file(path))
    state = snapshot.decode(blob)
    k = next(i for i, t in enumerate(state["tracks"]) if t["vertical"] is not None)
    state["tracks"][k]["vertical"][0] = -1e300
    _rewrite(path, snapshot.encode([meta, snapshot.encode(state, "state")], "snap"))
    with pytest.raises(SnapshotError, match=f"track\\[{k}\\] vertical"):
        restore_manager(path)


def test_a_schema_2_snapshot_restores_and_a_bad_recent_is_refused(saved, items_and_data):
    """Schema 3 added the window's "recent" times (the stream's confirmed time). A schema 2 snapshot (without
    them, and with re-initialisations among the inputs' counts) still restores, its newest time standing for
    them and the re-initialisations moved to the track counts, and goes on using inputs; a "recent" time
    after the window's newest is refused naming the field."""
    items, _ = items_and_data
    mgr, path = saved
    meta, blob = snapshot.decode(snapshot.read_snapshot_file(path))
    state = snapshot.decode(blob)
    old_state = {k: v for k, v in state.items() if k != "track_counts"}  # schema 2 counted them among counts
    old_state |= {"window": {k: v for k, v in state["window"].items() if k != "recent"},
                  "counts": {**state["counts"], "tracks_reinitialised": 2}}
    old = path.with_name("old")
    _rewrite(old, snapshot.encode([{**meta, "schema": 2}, snapshot.encode(old_state, "state")], "snap"))
    restored = restore_manager(old)
    assert list(restored.window.recent) == [state["window"]["newest"]]
    assert restored.track_counts() == {"tracks_reinitialised": 2} and "tracks_reinitialised" not in restored.accounting()
    assert restored.process_many(items[500:]) and restored.accounting()["plots_used"] > 0
    bad = {**state, "window": {**state["window"], "recent": [state["window"]["newest"] + 1.0]}}
    _rewrite(path, snapshot.encode([meta, snapshot.encode(bad, "state")], "snap"))
    with pytest.raises(SnapshotError, match="window recent"):
        restore_manager(path)
