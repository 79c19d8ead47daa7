"""Track metrics and state errors: the vectorised evaluation against the straightforward loops."""

import numpy as np
import pytest

from radartracker.pipeline.evaluate import GridSpec, TrackHistory, TruthPaths, gospa, state_errors, track_metrics


def naive_track_metrics(tracks: dict[int, TrackHistory], paths: TruthPaths, observed: dict[str, tuple[float, float]],
                  grid: np.ndarray, c: float = 2000.0) -> dict:
    """The straightforward loop over grid times and pairs (the first implementation)."""
    from scipy.optimize import linear_sum_assignment

    targets = sorted(observed)
    tids = sorted(tracks)
    assigned = {tg: np.full(len(grid), -1) for tg in targets}
    t_alive = {tid: 0 for tid in tids}
    t_assigned = {tid: 0 for tid in tids}
    track_targets: dict[int, set[str]] = {tid: set() for tid in tids}
    g, sq = np.zeros(len(grid)), []
    tpos = {tid: tracks[tid].at(grid) for tid in tids}
    truth = {tg: paths.state_at(tg, grid) for tg in targets}
    # a track is judged over its life up to its last estimate (at least its first grid time)
    judged = {tid: [k for k in range(len(grid)) if tpos[tid][1][k] and grid[k] <= tracks[tid].times[-1]]
              or [k for k in range(len(grid)) if tpos[tid][1][k]][:1] for tid in tids}
    for k, t in enumerate(grid):
        live_t = [tg for tg in targets if observed[tg][0] <= t <= observed[tg][1] and truth[tg][1][k]]
        live_k = [tid for tid in tids if tpos[tid][1][k]]
        for tid in live_k:
            t_alive[tid] += k in judged[tid]
        if not live_t and not live_k:
            continue
        P = np.array([truth[tg][0][k, :2] for tg in live_t]).reshape(-1, 2)
        Q = np.array([tpos[tid][0][k] for tid in live_k]).reshape(-1, 2)
        D2 = np.sum((P[:, None, :] - Q[None, :, :]) ** 2, axis=-1)
        pairs = [(r, q) for r, tg in enumerate(live_t) for q, tid in enumerate(live_k)
                 if k and assigned[tg][k - 1] == tid and D2[r, q] < c * c]
        free_r = [r for r in range(len(live_t)) if all(r != a for a, _ in pairs)]
        free_q = [q for q in range(len(live_k)) if all(q != b for _, b in pairs)]
        if free_r and free_q:
            sub = D2[np.ix_(free_r, free_q)]
            rows, cols = linear_sum_assignment(np.minimum(sub, c * c))
            pairs += [(free_r[r], free_q[q]) for r, q in zip(rows, cols) if sub[r, q] < c * c]
        d2 = np.array([D2[r, q] for r, q in pairs])
        g[k] = gospa(d2, len(live_t) - len(pairs), len(live_k) - len(pairs), c)
        sq.extend(d2)
        for r, q in pairs:
            assigned[live_t[r]][k] = live_k[q]
            t_assigned[live_k[q]] += 1
            track_targets[live_k[q]].add(live_t[r])
    per_target = {}
    for tg in targets:
        a = assigned[tg]
        inside = (grid >= observed[tg][0]) & (grid <= observed[tg][1]) & truth[tg][1]
        held = a[inside & (a >= 0)]
        right = int(np.bincount(held).argmax()) if len(held) else -1
        seq = a[inside & (a >= 0)]
        per_target[tg] = {
            "right_track": right,
            "continuity": float(np.mean(a[inside] == right)) if inside.any() else float("nan"),
            "breaks": int(np.sum(seq[1:] != seq[:-1])) if len(seq) else 0,
        }
        per_target[tg]["breaks_in_coverage"] = per_target[tg]["breaks"]  # no detection gaps given: all of them
    # a track follows an aircraft where it is assigned or within c of any aircraft of the truth
    held = {(tid, k) for a in assigned.values() for k, tid in enumerate(a) if tid >= 0}
    every = {tg: paths.state_at(tg, grid) for tg in paths.paths}
    follows = {tid: sum(1 for k in judged[tid] if (
        (tid, k) in held or any(every[tg][1][k] and np.hypot(*(tpos[tid][0][k] - every[tg][0][k, :2])) < c
                                for tg in every))) for tid in tids}
    return {
        "per_target": per_target,
        "continuity_min": min((v["continuity"] for v in per_target.values()), default=float("nan")),
        "swaps": sum(len(s) > 1 for s in track_targets.values()),
        "breaks": sum(v["breaks"] for v in per_target.values()),
        "breaks_in_coverage": sum(v["breaks_in_coverage"] for v in per_target.values()),
        "false_tracks": sum(1 for tid in tids if t_alive[tid] and follows[tid] < 0.5 * t_alive[tid]),
        "confirmed_tracks": len(tids),
        "position_rmse_m": float(np.sqrt(np.mean(sq))) if sq else float("nan"),
        "gospa_mean_m": float(np.mean(g)),
        "gospa": g,
    }


def scene(seed: int, n_targets: int, n_tracks: int):
    rng = np.random.default_rng(seed)
    paths = {}
    for i in range(n_targets):
        t = np.arange(rng.uniform(-100, 300), rng.uniform(300, 700), 1.0)
        v = rng.normal(0, 200, 2)
        p = rng.uniform(-3e4, 3e4, 2) + v * (t[:, None] - t[0])
        paths[f"t{i:03d}"] = (t, p, np.repeat(v[None], len(t), 0))
    tracks = {}
    for j in range(n_tracks):
        tt, pp, vv = paths[f"t{rng.integers(n_targets):03d}"]
        a, b = sorted(rng.uniform(tt[0], tt[-1], 2))
        times = np.arange(a, b, 4.0)
        if len(times) < 2:
            continue
        st = np.column_stack([np.interp(times, tt, pp[:, 0]), np.interp(times, tt, pp[:, 1]),
                              np.tile(vv[0], (len(times), 1))])
        st[:, :2] += rng.normal(0, 800, (len(times), 2)) + (5000 if rng.random() < 0.1 else 0)  # some false tracks
        tracks[j + 1] = TrackHistory(times, st, times[0], b + rng.uniform(0, 30))
    observed = {k: (float(v[0][0]) + 20, float(v[0][-1])) for k, v in paths.items()}
    return TruthPaths(paths), tracks, observed


@pytest.mark.parametrize("seed", [0, 2, 5])
def test_track_metrics_equal_the_straightforward_loop(seed):
    paths, tracks, observed = scene(seed, 30, 60)
    grid = np.arange(0, 600, 2.0)
    fast, slow = track_metrics(tracks, paths, observed, grid), naive_track_metrics(tracks, paths, observed, grid)
    assert slow["breaks"] > 0 and slow["swaps"] > 0 and slow["false_tracks"] > 0  # the scene exercises every rule
    fast.pop("indicators")  # tested on scenes of their own (tests/pipeline/test_indicators.py)
    np.testing.assert_allclose(fast.pop("gospa"), slow.pop("gospa"), rtol=1e-12)
    fast_t, slow_t = fast.pop("per_target"), slow.pop("per_target")
    assert fast_t.keys() == slow_t.keys()
    for tg in slow_t:
        assert fast_t[tg]["right_track"] == slow_t[tg]["right_track"]
        assert fast_t[tg]["breaks"] == slow_t[tg]["breaks"]
        np.testing.assert_equal(fast_t[tg]["continuity"], slow_t[tg]["continuity"])
    assert fast == pytest.approx(slow, rel=1e-12, nan_ok=True)


def test_state_errors_per_key():
    paths, _, _ = scene(5, 10, 0)
    rng = np.random.default_rng(1)
    keys = np.array([f"t{k:03d}" for k in rng.integers(0, 12, 500)], object)  # t010, t011 have no truth
    times = rng.uniform(-50, 700, 500)
    states = rng.normal(size=(500, 4))
    err, ok = state_errors(paths, keys, times, states)
    for i in range(500):
        truth, inside = paths.state_at(keys[i], times[i:i + 1])
        np.testing.assert_array_equal(err[i], states[i] - truth[0])
        assert ok[i] == inside[0]
    assert (~ok[np.isin(keys, ["t010", "t011"])]).all()


@pytest.mark.parametrize("seed", [0, 2])
def test_a_grid_spec_gives_the_whole_grids_metrics(seed):
    """Evaluated at its live times only, a GridSpec gives what the whole np.arange grid gives (the oracle: the
    straightforward loop over the whole grid), also with a far truth time that widens the grid."""
    paths, tracks, observed = scene(seed, 20, 40)
    grid = np.arange(-200.0, 900.0, 2.0)
    slow = naive_track_metrics(tracks, paths, observed, grid)
    fast = track_metrics(tracks, paths, observed, GridSpec(-200.0, 900.0, 2.0))
    slow.pop("gospa"), fast.pop("gospa")
    whole = track_metrics(tracks, paths, observed, grid)["indicators"]
    assert fast.pop("indicators") == pytest.approx(whole, rel=1e-12, nan_ok=True)
    assert fast.pop("per_target") == slow.pop("per_target")
    assert fast == pytest.approx(slow, rel=1e-12, nan_ok=True)
    far = track_metrics(tracks, paths, observed, GridSpec(-200.0, 1e9, 2.0))  # 5·10⁸ grid times: not made
    far.pop("gospa")
    assert far.pop("indicators") == pytest.approx(whole, rel=1e-12, nan_ok=True)
    assert far.pop("per_target") == naive_track_metrics(tracks, paths, observed, grid)["per_target"]
    assert far["gospa_mean_m"] == pytest.approx(slow["gospa_mean_m"] * len(grid) / 500_000_100, rel=1e-9)
    far["gospa_mean_m"] = slow["gospa_mean_m"]
    assert far == pytest.approx(slow, rel=1e-12, nan_ok=True)
