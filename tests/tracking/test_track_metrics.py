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


def test_a_track_coasting_after_its_aircraft_vanished_is_not_false():
    # aircraft "c" flies 0-30 s then vanishes (a simulated flight's end); its track's last estimate is at
    # 30 s and it coasts, extrapolated, until deleted at 75 s: 45 of its 76 s far from every aircraft
    t = np.arange(0.0, 31.0, 1.0)
    paths = dict(truth().paths, c=(t, np.stack([t * 100.0, np.full_like(t, -20000.0)], axis=1),
                                   np.tile([100.0, 0.0], (len(t), 1))))
    times = np.arange(0.0, 31.0, 4.0)
    states = np.stack([times * 100.0, np.full_like(times, -20000.0), np.full_like(times, 100.0),
                       np.full_like(times, 300.0)], axis=1)  # its velocity is wrong northwards: it drifts
    tracks = {1: track(0.0), 2: track(5000.0), 3: TrackHistory(times, states, 0.0, 75.0)}
    obs = dict(OBS, c=(0.0, 30.0))
    assert track_metrics(tracks, TruthPaths(paths), obs, GRID)["false_tracks"] == 0
    # the same track updated (estimates) far from every aircraft during its life is false
    off = states.copy()
    off[:, 1] = -40000.0
    tracks[3] = TrackHistory(times, off, 0.0, 75.0)
    assert track_metrics(tracks, TruthPaths(paths), obs, GRID)["false_tracks"] == 1


def test_gospa_definition():
    # two assigned pairs at 3 m and 4 m, one missed target, c = 10: sqrt(9 + 16 + 100/2)
    assert gospa(np.array([9.0, 16.0]), 1, 0, 10.0) == pytest.approx(np.sqrt(75.0), rel=1e-12)


def test_false_tracks_follow_no_sensed_aircraft():
    """False tracks against a count made by construction: aircraft flying east in three regions
    100 km apart (observed by plots; seen by ADS-B only; seen by nothing), 20 km apart within a
    region, and tracks of known kinds, some confirmed during their aircraft's 20 s grace period."""
    rng = np.random.default_rng(7)
    grid = np.arange(0.0, 600.0, 2.0)
    paths, observed, sensed = {}, {}, set()
    kinds = {"plots": 6, "adsb": 3, "unseen": 3}
    for region, (kind, n) in enumerate(kinds.items()):
        for i in range(n):
            t = np.arange(rng.uniform(0, 100), rng.uniform(400, 600), 1.0)
            v = np.array([rng.uniform(100, 250), 0.0])
            p = np.array([0.0, region * 1e5 + i * 2e4]) + v * (t[:, None] - t[0])
            paths[f"{kind}{i}"] = (t, p, np.repeat(v[None], len(t), 0))
            if kind != "unseen":
                sensed.add(f"{kind}{i}")
            if kind == "plots":
                observed[f"{kind}{i}"] = (t[0] + 20.0, t[-1])
    truth = TruthPaths(paths)

    def follow(name, start, end, offset=0.0):
        tt, pp, vv = paths[name]
        times = np.arange(start, end, 3.0)
        st = np.column_stack([np.interp(times, tt, pp[:, 0]), np.interp(times, tt, pp[:, 1]) + offset,
                              np.tile(vv[0], (len(times), 1))])
        st[:, :2] += rng.normal(0, 300, (len(times), 2))
        return TrackHistory(times, st, times[0], times[-1])

    tracks, expect_false, not_assigned = {}, 0, 0
    for name, (tt, _, _) in paths.items():
        if name.startswith("plots"):
            # confirmed 10 s after the first plot, inside the grace period: a real track
            tracks[len(tracks) + 1] = follow(name, tt[0] + 10.0, tt[-1])
            if name in ("plots0", "plots1"):  # a second track on the same aircraft: a duplicate, not false
                tracks[len(tracks) + 1] = follow(name, tt[0] + 60.0, tt[0] + 200.0)
                not_assigned += 1
        elif name.startswith("adsb"):  # follows an aircraft that only ADS-B saw: real
            tracks[len(tracks) + 1] = follow(name, tt[0], tt[-1])
            not_assigned += 1
        else:  # follows an aircraft no sensor saw: it cannot come from that aircraft's measurements
            tracks[len(tracks) + 1] = follow(name, tt[0], tt[-1])
            expect_false += 1
    for _ in range(4):  # 5 km off an observed aircraft's path (c = 2 km; the next aircraft is 15 km away): false
        name = f"plots{rng.integers(2, 6)}"
        tt = paths[name][0]
        tracks[len(tracks) + 1] = follow(name, tt[0] + 30.0, tt[0] + 150.0, offset=5000.0)
        expect_false += 1
    m = track_metrics(tracks, truth, observed, grid, sensed=sensed)
    assert m["false_tracks"] == expect_false == 7
    assert m["breaks"] == 0 and m["swaps"] == 0 and m["continuity_min"] > 0.9
    # the old rule (assigned to an observed aircraft less than half of its life) also counted the
    # ADS-B-only tracks and the duplicates
    right = {v["right_track"] for v in m["per_target"].values()}
    assert len(tracks) - len(right) == expect_false + not_assigned
    # without ``sensed`` every aircraft of the truth counts as seen: the unseen ones' tracks are real
    assert track_metrics(tracks, truth, observed, grid)["false_tracks"] == expect_false - kinds["unseen"]
