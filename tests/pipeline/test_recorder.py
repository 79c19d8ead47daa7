"""The recorder's events as columns: rows of TrackManager events (its event log, or through on_event) and
of other associations, made columns a chunk at a time, equal the columns built directly from what was
recorded."""

import math

import numpy as np
import pytest

from radartracker.registry import make_manager
from radartracker.pipeline.recorder import Recorder, _concatenate
from radartracker.tracking.manager import TrackEvent

KINDS = ["created", "confirmed", "updated", "coasting", "deleted"]


def _inputs(n: int, seed: int = 4):
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        state = tuple(rng.normal(0, 1e5, 4).tolist())
        cov = None if i % 4 == 1 else rng.normal(0, 10, (4, 4))
        alt = None if i % 3 == 0 else float(rng.normal(9000, 100))
        ident = (alt, None if alt is None or i % 4 == 2 else float(rng.uniform(2, 900)), None if i % 2 else f"{i:06x}",
                 None if i % 5 else "7421", None if i % 7 else f"T{i}")
        out.append((0.25 * i, int(rng.integers(1, 9)), KINDS[i % 5], "confirmed" if i % 5 else "tentative", state, cov,
                    ident))
    return out


class Sink:
    def __init__(self):
        self.chunks, self.bias_rows = [], 0

    def events(self, ev):
        self.chunks.append(ev)

    def biases(self, b):
        self.bias_rows += len(b.time)


@pytest.mark.parametrize("keep", [True, False])
def test_rows_made_columns_equal_the_recorded_values(keep):
    inputs = _inputs(23)
    sink = Sink()
    rec = Recorder(sink=sink, keep=keep, flush_every=5)
    expected_ids = set()
    for i, (t, track, kind, status, state, cov, ident) in enumerate(inputs):
        if i % 2:  # as the TrackManager's run records its events
            rec.track_event(TrackEvent(t, track, kind, status, state), cov, ident)
        else:  # as the labels and distributed associations record theirs (state an array)
            rec.event(t, track, kind, status, np.array(state), cov, ident[0], *ident[2:], altitude_sd_m=ident[1])
        if cov is not None:
            cov[:] = 0.0  # copied when recorded
        if kind in ("confirmed", "updated"):
            expected_ids.add(track)
        assert rec.track_ids == expected_ids
    assert [len(c) for c in sink.chunks] == [5, 5, 5, 5]  # the last 3 wait for flush
    rec.flush()
    assert [len(c) for c in sink.chunks] == [5, 5, 5, 5, 3] and rec.track_ids == expected_ids
    fresh = _inputs(23)  # the same values again, the covariances not zeroed
    got = sink.chunks
    for name, column in [("time", [x[0] for x in fresh]), ("track", [x[1] for x in fresh]),
                         ("kind", [x[2] for x in fresh]), ("status", [x[3] for x in fresh]),
                         ("mode_s", [x[6][2] for x in fresh]), ("mode_3a", [x[6][3] for x in fresh]),
                         ("target", [x[6][4] for x in fresh])]:
        assert [v for c in got for v in getattr(c, name).tolist()] == column, name
    state = np.concatenate([c.state for c in got])
    assert state.shape == (23, 4) and state.tolist() == [list(x[4]) for x in fresh]
    cov = np.concatenate([c.cov for c in got])
    for x, c in zip(fresh, cov):
        assert np.isnan(c).all() if x[5] is None else (c == x[5]).all()
    for k, name in enumerate(("altitude_m", "altitude_sd_m")):
        values = np.concatenate([getattr(c, name) for c in got])
        assert [None if math.isnan(a) else a for a in values.tolist()] == [x[6][k] for x in fresh], name
    mask = np.concatenate([c.estimate_mask() for c in got])
    assert mask.tolist() == [x[2] in ("confirmed", "updated") for x in fresh]
    held = rec.events()
    if keep:
        assert held.time.tolist() == [x[0] for x in fresh] and np.array_equal(held.cov, cov, equal_nan=True)
    else:
        assert len(held) == 0 and held.state.shape == (0, 4) and held.cov.shape == (0, 4, 4)


def test_without_a_sink_every_event_is_kept_in_order():
    inputs = _inputs(11)
    rec = Recorder(flush_every=4)
    for t, track, kind, status, state, cov, ident in inputs:
        rec.track_event(TrackEvent(t, track, kind, status, state), cov, ident)
    ev = rec.events()
    assert ev.time.tolist() == [x[0] for x in inputs] and ev.track.dtype.kind == "i"
    assert ev.state.tolist() == [list(x[4]) for x in inputs] and ev.kind.dtype == object
    assert len(Recorder().events()) == 0


def test_a_covariance_that_is_not_4x4_is_refused():
    rec = Recorder()
    rec.track_event(TrackEvent(0.0, 1, "updated", "confirmed", (0.0, 0.0, 0.0, 0.0)), np.eye(6), (None,) * 5)
    with pytest.raises(ValueError, match="4×4"):
        rec.events()


def _same_events(a, b) -> None:
    for name in ("time", "track", "kind", "status", "state", "altitude_m", "altitude_sd_m", "mode_s", "mode_3a",
                 "target"):
        x, y = getattr(a, name), getattr(b, name)
        assert x.dtype == y.dtype and (np.array_equal(x, y, equal_nan=True) if x.dtype != object
                                       else x.tolist() == y.tolist()), name
    assert np.array_equal(a.cov, b.cov, equal_nan=True)


@pytest.mark.parametrize("keep", [True, False])
def test_a_managers_events_are_recorded_with_the_track_as_it_was(keep):
    """Recorder.listen, subscribed to a TrackManager's events, records each with the covariance of the
    estimate when the event's state is it (none when extrapolated or deleted) and the identity of the track
    then (oracle: a second listener reading the track itself at each event), made columns 7 at a time."""
    from radartracker.pipeline.stream import scenario_stream
    from radartracker.simulation.scenarios import build_scenario
    from radartracker.tracking.config import ManagerConfig

    data = build_scenario("paris", seed=1, duration=120.0).run()
    old = Recorder()

    def oracle(ev, tr):
        t0, _, P = tr.filter.estimate()
        keep_cov = ev.kind != "deleted" and t0 == ev.time
        old.track_event(ev, np.array(P, float) if keep_cov else None, (tr.altitude_m, tr.altitude_sd_m, tr.mode_s, tr.mode_3a, None))

    sink = Sink()
    new = Recorder(sink=sink, keep=keep, flush_every=7)
    mgr = make_manager(data.radars, data.reference, ManagerConfig())
    mgr.events.subscribe(new.listen)
    mgr.events.subscribe(oracle)
    for item in scenario_stream(data):
        mgr.process(item)
        assert new.track_ids == old.track_ids
    mgr.flush()
    new.flush()
    expected = old.events()
    assert len(expected) > 200 and max(len(c) for c in sink.chunks) >= 7
    assert np.isnan(expected.cov).all(axis=(1, 2)).any() and not np.isnan(expected.cov).all()
    _same_events(_concatenate(sink.chunks), expected)
    assert len(new.events()) == (len(expected) if keep else 0)


@pytest.mark.parametrize("keep", [True, False])
def test_biases_recorded_are_the_values_at_that_time(keep):
    from radartracker.domain import BiasState

    rng = np.random.default_rng(7)
    storage = rng.normal(0, 1, (6, 6))  # as an estimator's own arrays: views, changed by its next update
    sink = Sink()
    rec = Recorder(bias_log_interval_s=1.0, sink=sink, keep=keep, flush_every=4)
    expected = []
    for i in range(14):
        t, radar, j = 0.2 * i, f"R{i % 3}", 2 * (i % 3)
        bias, cov = storage[j:j + 2, 0], storage[j:j + 2, j:j + 2]
        due = t - max([e[0] for e in expected if e[1] == radar], default=-math.inf) >= 1.0
        if due:
            expected.append((t, radar, bias.tolist(), cov.tolist()))
        rec.bias(t, BiasState(radar, t, bias, cov))  # views of the estimator's arrays: copied when recorded
        storage += 1.0  # the next update
    rec.flush()
    assert sink.bias_rows == len(expected) and 0 < len(expected) < 14
    if keep:
        b = rec.biases()
        assert b.time.tolist() == [e[0] for e in expected] and b.radar.tolist() == [e[1] for e in expected]
        assert b.value.tolist() == [e[2] for e in expected] and b.cov.tolist() == [e[3] for e in expected]
        assert b.value.flags.c_contiguous and b.cov.shape == (len(expected), 2, 2)
    assert Recorder().biases().value.shape == (0, 2) and Recorder().biases().cov.shape == (0, 2, 2)


def test_a_bias_that_is_not_two_floats_is_refused():
    from radartracker.domain import BiasState

    with pytest.raises(ValueError, match="2×2"):
        Recorder().bias(0.0, BiasState("R1", 0.0, np.zeros(3), np.eye(2)))
    rec = Recorder()
    rec.bias(0.0, BiasState("R1", 0.0, np.array([1, 2]), np.array([[3, 0], [0, 4]])))  # integers: as floats
    assert rec.biases().value.tolist() == [[1.0, 2.0]] and rec.biases().cov.dtype == float
