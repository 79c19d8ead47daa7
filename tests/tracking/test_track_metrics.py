"""The tracking metrics on hand-made tracks whose answers are known by construction."""

import numpy as np
import pytest

from radartracker.pipeline.evaluate import TrackHistory, TruthPaths, gospa, track_metrics

GRID = np.arange(0.0, 100.0, 1.0)


def truth():
    t = np.arange(0.0, 101.0, 1.0)
    a = np.stack([t * 100.0, np.zeros_like(t)], axis=1)  # east along y = 0
    b = np.stack([t * 100.0, np.full_like(t, 5000.0)], axis=1)  # parallel, 5 km north
    v = np.tile([100.0, 0.0], (len(t), 1))
    return TruthPaths({"a": (t, a, v), "b": (t, b, v)})


def track(y0, y1=None, t_switch=1e9, start=0.0, end=99.0):
    t = GRID.copy()
    y = np.where(t < t_switch, y0, y0 if y1 is None else y1)
    states = np.stack([t * 100.0, y, np.full_like(t, 100.0), np.zeros_like(t)], axis=1)
    return TrackHistory(t, states, start, end)


OBS = {"a": (0.0, 99.0), "b": (0.0, 99.0)}


def test_perfect_tracks():
    m = track_metrics({1: track(10.0), 2: track(5010.0)}, truth(), OBS, GRID)
    assert m["swaps"] == 0 and m["false_tracks"] == 0 and m["continuity_min"] == 1.0
    assert m["position_rmse_m"] == pytest.approx(10.0, rel=1e-12)
    assert m["gospa_mean_m"] == pytest.approx(np.sqrt(200.0), rel=1e-12)


def test_swapped_tracks_detected():
    m = track_metrics({1: track(0.0, 5000.0, 50.0), 2: track(5000.0, 0.0, 50.0)}, truth(), OBS, GRID)
    assert m["swaps"] == 2 and m["breaks"] == 2
    assert m["continuity_min"] == 0.5


def test_false_and_late_tracks():
    m = track_metrics({1: track(0.0), 2: track(5000.0, start=20.0), 3: track(-30000.0)}, truth(), OBS, GRID)
    assert m["false_tracks"] == 1 and m["confirmed_tracks"] == 3
    assert m["per_target"]["b"]["continuity"] == 0.8


def test_gospa_definition():
    # two assigned pairs at 3 m and 4 m, one missed target, c = 10: sqrt(9 + 16 + 100/2)
    assert gospa(np.array([9.0, 16.0]), 1, 0, 10.0) == pytest.approx(np.sqrt(75.0), rel=1e-12)
