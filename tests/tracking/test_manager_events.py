"""TrackEvent, the record every TrackManager event is: named fields, immutable, equal only to an equal
TrackEvent; what on_event receives is what process returns; a snapshot taken right after events were
returned restores."""

import pickle

import pytest

from radartracker.registry import make_manager, restore_manager
from radartracker.pipeline.stream import scenario_stream
from radartracker.simulation.scenarios import build_scenario
from radartracker.tracking.config import ManagerConfig
from radartracker.tracking.events import EVENT_KINDS, EventSink, TrackEvent


def test_track_event_is_an_immutable_record():
    ev = TrackEvent(12.5, 7, "updated", "confirmed", (1.0, -2.0, 3.5, 0.0))
    assert (ev.time, ev.track, ev.kind, ev.status, ev.state) == (12.5, 7, "updated", "confirmed", (1.0, -2.0, 3.5, 0.0))
    with pytest.raises(AttributeError):
        ev.kind = "deleted"
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
    mgr = make_manager(tracking.radars, tracking.reference, ManagerConfig(), seen.append)
    returned = mgr.process_many(scenario_stream(tracking))
    assert len(returned) > 100 and {e.kind for e in returned} >= {"created", "confirmed", "updated", "deleted"}
    assert all(a is b for a, b in zip(returned, seen, strict=True))
    assert all(type(e) is TrackEvent and e.kind in EVENT_KINDS and len(e.state) == 4
               and all(type(v) is float for v in (e.time, *e.state)) for e in returned)


def test_snapshot_right_after_events_restores(tracking, tmp_path):
    """A manager whose last call returned events (held until the next call) is saved and continues alike."""
    items = scenario_stream(tracking)
    half = len(items) // 2
    whole = make_manager(tracking.radars, tracking.reference, ManagerConfig())
    expected = whole.process_many(items)
    first = make_manager(tracking.radars, tracking.reference, ManagerConfig())
    got = []
    k = 0
    while k < half or not got or not got[-1]:  # stop right after a call that returned events
        got.append(first.process(items[k]))
        k += 1
    first.snapshot(tmp_path / "s.rtsnap")
    second = restore_manager(tmp_path / "s.rtsnap")
    assert [e for evs in got for e in evs] + second.process_many(items[k:]) == expected


def test_listeners_get_each_event_with_its_track_as_it_happens(tracking):
    """A listener of the manager's EventSink gets every event with its track, when it happens: the event's
    state is the track's estimate then (oracle: the filter read in the listener itself), or that estimate
    extrapolated in a straight line for a coasting or deleted event; the events the calls return are the
    same objects in the same order."""
    import numpy as np

    seen = []

    def listen(ev, tr):
        t0, x, _ = tr.filter.estimate()
        x = np.asarray(x, float)[:4]
        dt = max(ev.time - t0, 0.0)
        seen.append((ev, tr.id, x[:2] + x[2:4] * dt, tr.status))

    mgr = make_manager(tracking.radars, tracking.reference, ManagerConfig())
    mgr.events.subscribe(listen)
    returned = mgr.process_many(scenario_stream(tracking)[:3000])
    assert len(returned) == len(seen) > 100
    for ev, (got, tid, pos, status) in zip(returned, seen):
        assert ev is got and ev.track == tid and ev.status == status
        np.testing.assert_allclose(ev.state[:2], pos, rtol=1e-12, atol=1e-6)
    assert {e.kind for e in returned} >= {"created", "confirmed", "updated", "deleted"}


def test_event_sink_takes_what_was_emitted_once():
    sink, got = EventSink(), []
    sink.subscribe(lambda ev, tr: got.append((ev, tr)))
    a = TrackEvent(1.0, 1, "created", "tentative", (0.0, 0.0, 0.0, 0.0))
    sink.emit(a, "track")
    assert sink.take() == [a] and sink.take() == [] and got == [(a, "track")]
