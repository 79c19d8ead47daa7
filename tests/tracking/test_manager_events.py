"""TrackEvent, the record every TrackManager event is: named fields, immutable, equal only to an equal
TrackEvent; what on_event receives is what process returns; a snapshot taken right after events were
returned restores."""

import pickle

import pytest

from radartracker.pipeline.stream import scenario_stream
from radartracker.simulation.scenarios import build_scenario
from radartracker.tracking.manager import EVENT_KINDS, ManagerConfig, TrackEvent, TrackManager, _make_event


def test_track_event_is_an_immutable_record():
    ev = TrackEvent(12.5, 7, "updated", "confirmed", (1.0, -2.0, 3.5, 0.0))
    assert (ev.time, ev.track, ev.kind, ev.status, ev.state) == (12.5, 7, "updated", "confirmed", (1.0, -2.0, 3.5, 0.0))
    with pytest.raises(AttributeError):
        ev.kind = "deleted"
    assert _make_event(TrackEvent, (12.5, 7, "updated", "confirmed", (1.0, -2.0, 3.5, 0.0))) == ev
    same, other = TrackEvent(*ev), ev._replace(track=8)
    assert ev == same and not ev != same and hash(ev) == hash(same) and len({ev, same, other}) == 2
    assert ev != other and not ev == other
    assert ev != tuple(ev) and not ev == tuple(ev)  # a TrackEvent, not any tuple of the same values
    assert repr(ev) == "TrackEvent(time=12.5, track=7, kind='updated', status='confirmed', state=(1.0, -2.0, 3.5, 0.0))"
    assert pickle.loads(pickle.dumps(ev)) == ev


@pytest.fixture(scope="module")
def tracking():
    return build_scenario("tracking", seed=3, duration=120.0).run()


def test_on_event_gets_what_process_returns(tracking):
    seen = []
    mgr = TrackManager(tracking.radars, tracking.reference, ManagerConfig(), seen.append)
    returned = mgr.process_many(scenario_stream(tracking))
    assert len(returned) > 100 and {e.kind for e in returned} >= {"created", "confirmed", "updated", "deleted"}
    assert all(a is b for a, b in zip(returned, seen, strict=True))
    assert all(type(e) is TrackEvent and e.kind in EVENT_KINDS and len(e.state) == 4
               and all(type(v) is float for v in (e.time, *e.state)) for e in returned)


def test_snapshot_right_after_events_restores(tracking, tmp_path):
    """A manager whose last call returned events (held until the next call) is saved and continues alike."""
    items = scenario_stream(tracking)
    half = len(items) // 2
    whole = TrackManager(tracking.radars, tracking.reference, ManagerConfig())
    expected = whole.process_many(items)
    first = TrackManager(tracking.radars, tracking.reference, ManagerConfig())
    got = []
    k = 0
    while k < half or not got or not got[-1]:  # stop right after a call that returned events
        got.append(first.process(items[k]))
        k += 1
    first.snapshot(tmp_path / "s.rtsnap")
    second = TrackManager.restore(tmp_path / "s.rtsnap")
    assert [e for evs in got for e in evs] + second.process_many(items[k:]) == expected


def test_event_log_rows_are_the_events_with_covariance_and_codes(tracking, tmp_path):
    """Each event is appended to event_log as (event, P, altitude, Mode S, Mode 3/A): P the filter's
    covariance when the event's state is its estimate at the event's time, else None; the track's codes
    then. The list is not part of a snapshot. The oracle reads the filter as each event is made, in a
    manager that updates one measurement at a time (the batched one has updated a frame's filters by then)."""
    import numpy as np

    from tests.tracking.reference import OneAtATimeManager

    expected, tracks = [], {}

    def on_event(ev):  # called just before the row is appended
        tr = tracks[ev.track] = mgr.tracks.get(ev.track) or tracks[ev.track]
        t0, _, P = tr.filter.estimate()
        expected.append((ev, P if t0 == ev.time else None, tr.altitude_m, tr.mode_s, tr.mode_3a))

    mgr = OneAtATimeManager(tracking.radars, tracking.reference, ManagerConfig(), on_event)
    mgr.process_many(scenario_stream(tracking)[:3000])
    mgr = TrackManager(tracking.radars, tracking.reference, ManagerConfig())
    mgr.event_log = log = []
    mgr.process_many(scenario_stream(tracking)[:3000])
    assert len(log) == len(expected) > 100 and sum(r[1] is None for r in log) > 10
    for row, want in zip(log, expected):
        assert row[0] == want[0] and row[2:] == want[2:]
        assert (row[1] is None) == (want[1] is None) and (row[1] is None or np.array_equal(row[1], want[1]))
    mgr.snapshot(tmp_path / "s.rtsnap")
    assert TrackManager.restore(tmp_path / "s.rtsnap").event_log is None
