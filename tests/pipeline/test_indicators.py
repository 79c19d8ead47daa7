"""The surveillance indicators (multiple tracks, probability of update, breaks per flight hour,
initiation delay) on hand-made tracks whose answers are counted by hand in each test."""

import numpy as np
import pytest

from radartracker.pipeline.evaluate import TrackHistory, TruthPaths, detection_gaps, track_metrics

GRID = np.arange(0.0, 100.0, 1.0)  # 100 grid times, 0–99 s
OBS = {"a": (0.0, 99.0), "b": (0.0, 99.0)}


def truth():
    t = np.arange(0.0, 101.0, 1.0)
    v = np.tile([100.0, 0.0], (len(t), 1))
    return TruthPaths({"a": (t, np.stack([t * 100.0, np.zeros_like(t)], axis=1), v),
                       "b": (t, np.stack([t * 100.0, np.full_like(t, 5000.0)], axis=1), v)})


def track(y, times=GRID, start=None, end=99.0):
    """A track along the line y (on target a: 0, on b: 5000) reporting at ``times``."""
    times = np.asarray(times, float)
    states = np.stack([times * 100.0, np.full_like(times, y), np.full_like(times, 100.0), np.zeros_like(times)], axis=1)
    return TrackHistory(times, states, float(times[0]) if start is None else start, end)


def test_a_second_track_on_one_aircraft_is_a_multiple_track_for_its_time():
    # track 3 follows a 150 m off from 40 s to 59 s (20 grid times) while track 1 holds a
    spare = track(150.0, np.arange(40.0, 60.0), end=59.0)
    q = track_metrics({1: track(0.0), 2: track(5000.0), 3: spare}, truth(), OBS, GRID)["indicators"]
    assert q["multiple_tracks"] == 1
    assert q["multiple_share_of_time"] == pytest.approx(20 / 200)  # 20 of the 2 × 100 observed grid times
    assert q["flights_with_multiple_tracks"] == 1 and q["flights_with_multiple_share"] == 0.5


def test_a_track_far_from_every_aircraft_is_not_a_multiple_track():
    q = track_metrics({1: track(0.0), 2: track(5000.0), 3: track(-30000.0)}, truth(), OBS, GRID)["indicators"]
    assert q["multiple_tracks"] == 0 and q["multiple_share_of_time"] == 0.0


def test_probability_of_update_counts_the_8_s_intervals_with_an_estimate():
    # a: 99 s observed → 12 whole 8 s intervals [0, 8), …, [88, 96); its track reports every 4 s except
    # between 24 and 44 s (no estimate at 24, 28, …, 40 s): intervals [24, 32) and [32, 40) have none
    # ([40, 48) has 44 s); b's track reports every 4 s: 12 of 12
    gap = np.array([t for t in np.arange(0.0, 100.0, 4.0) if not 24.0 <= t < 44.0])
    m = track_metrics({1: track(0.0, gap), 2: track(5000.0, np.arange(0.0, 100.0, 4.0))}, truth(), OBS, GRID)
    assert m["indicators"]["probability_of_update"] == pytest.approx(22 / 24)
    assert m["indicators"]["update_interval_s"] == 8.0


def test_breaks_per_flight_hour_and_initiation_delay():
    # a is held by track 1 until 50 s, then by track 4 (one break); b's track starts at 30 s, b first seen at 5 s
    tracks = {1: track(0.0, np.arange(0.0, 51.0), end=50.0), 4: track(0.0, np.arange(51.0, 100.0)),
              2: track(5000.0, np.arange(30.0, 100.0))}
    m = track_metrics(tracks, truth(), OBS, GRID, first_seen={"a": 0.0, "b": 5.0})
    q = m["indicators"]
    assert m["breaks"] == 1
    assert q["flight_hours"] == pytest.approx(2 * 99.0 / 3600.0)
    assert q["breaks_per_flight_hour"] == pytest.approx(1 / (2 * 99.0 / 3600.0))
    # delays: a 0 s (track 1 from 0 s), b 25 s
    assert q["initiation_delay_max_s"] == 25.0 and q["initiation_delay_median_s"] == 12.5


def test_a_break_across_a_gap_in_the_detections_is_not_a_break_in_coverage():
    """a's detections stop from 45 to 100 s (one gap of 55 s, longer than 40 s) and its track changes across it
    (one break, not in coverage); b's detections never stop for more than 10 s and its track changes at 60 s
    (one break in coverage). detection_gaps counts the gaps by hand's count; unlabelled plots are left out."""
    t_a = np.concatenate([np.arange(0.0, 46.0, 5.0), np.arange(100.0, 150.0, 5.0)])
    t_b = np.arange(0.0, 150.0, 10.0)
    time = np.concatenate([t_a, t_b, [70.0]])
    target = np.array(["a"] * len(t_a) + ["b"] * len(t_b) + [None], object)
    gaps = detection_gaps(time, target, 40.0)
    assert gaps == {"a": 1, "b": 0}
    tracks = {1: track(0.0, np.arange(0.0, 51.0), end=50.0), 3: track(0.0, np.arange(51.0, 100.0)),
              2: track(5000.0, np.arange(0.0, 61.0), end=60.0), 4: track(5000.0, np.arange(61.0, 100.0))}
    m = track_metrics(tracks, truth(), OBS, GRID, gaps=gaps)
    assert m["breaks"] == 2 and m["breaks_in_coverage"] == 1
    assert [m["per_target"][k]["breaks_in_coverage"] for k in ("a", "b")] == [0, 1]
    assert track_metrics(tracks, truth(), OBS, GRID)["breaks_in_coverage"] == 2  # no gaps given: every break
