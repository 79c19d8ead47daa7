"""Comparison of estimates with the truth of a simulated scenario.

Truth positions are interpolated linearly in the system plane at the estimate times; truth
velocities are the finite-difference slopes of that interpolation. NEES is
(χ̂ − χ)ᵀ P⁻¹ (χ̂ − χ) of the 4-dimensional aircraft state.
"""

from __future__ import annotations

import attrs
import numpy as np

from radartracker.io.tables import TruthTable
from radartracker.geometry.plane import SystemPlane


@attrs.frozen
class TruthPaths:
    """Per-target truth in the plane: times, positions and velocities."""

    paths: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]

    @classmethod
    def from_table(cls, truth: TruthTable, plane: SystemPlane) -> TruthPaths:
        x, y = plane.to_plane(truth.lat, truth.lon)
        paths = {}
        for target in np.unique(truth.target.astype(str)):
            idx = np.flatnonzero(truth.target == target)
            idx = idx[np.argsort(truth.time[idx], kind="stable")]
            t = truth.time[idx]
            p = np.stack([x[idx], y[idx]], axis=-1)
            v = np.gradient(p, t, axis=0) if len(t) > 1 else np.zeros_like(p)
            paths[target] = (t, p, v)
        return cls(paths)

    def state_at(self, target: str, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Truth [x, y, vx, vy] (N, 4) at times ``t`` and a mask of times inside the truth span."""
        if target not in self.paths:
            return np.full((len(t), 4), np.nan), np.zeros(len(t), bool)
        tt, p, v = self.paths[target]
        inside = (t >= tt[0]) & (t <= tt[-1])
        cols = [np.interp(t, tt, p[:, 0]), np.interp(t, tt, p[:, 1]),
                np.interp(t, tt, v[:, 0]), np.interp(t, tt, v[:, 1])]
        return np.stack(cols, axis=-1), inside


def state_errors(paths: TruthPaths, keys: np.ndarray, times: np.ndarray, states: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Estimate − truth (N, 4) for each recorded estimate, and the mask where truth exists."""
    err = np.full(states.shape, np.nan)
    ok = np.zeros(len(times), bool)
    for key in np.unique(keys.astype(str)):
        idx = np.flatnonzero(keys.astype(str) == key)
        truth, inside = paths.state_at(key, times[idx])
        err[idx] = states[idx] - truth
        ok[idx] = inside
    return err, ok


def nees(err: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """Normalised estimation error squared eᵀP⁻¹e per row."""
    return np.einsum("ni,ni->n", err, np.linalg.solve(cov, err[..., None])[..., 0])


@attrs.frozen
class TrackHistory:
    """A track's reported states (from its events): times (N,), states (N, 4), and life span."""

    times: np.ndarray
    states: np.ndarray
    start: float
    end: float

    def at(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Positions (extrapolated from the last report ≤ t) and a mask of times within the life span."""
        i = np.clip(np.searchsorted(self.times, t, side="right") - 1, 0, len(self.times) - 1)
        dt = t - self.times[i]
        pos = self.states[i, :2] + self.states[i, 2:] * dt[:, None]
        return pos, (t >= self.start) & (t <= self.end)


def gospa(d2: np.ndarray, n_missed: int, n_false: int, c: float) -> float:
    """GOSPA (p = 2, α = 2) given squared distances of assigned pairs (each < c)."""
    return float(np.sqrt(np.sum(d2) + c * c / 2 * (n_missed + n_false)))


def track_metrics(tracks: dict[int, TrackHistory], paths: TruthPaths, observed: dict[str, tuple[float, float]],
                  grid: np.ndarray, c: float = 2000.0) -> dict:
    """Track-to-truth assignment on a time grid and the metrics derived from it.

    At each grid time the alive tracks are assigned to the observed truths as in CLEAR MOT
    (Bernardin & Stiefelhagen 2008): a track keeps the target it had at the previous time while it
    stays within ``c``; the others are assigned by minimum total distance (Hungarian), pairs
    farther than ``c`` left unassigned. (Without the first rule, two tracks passing through the
    same point at a crossing would "swap" for one instant by an accident of the tie.) Per target, the *right* track
    is the one assigned to it most often; continuity is the fraction of its observed time it holds.
    A *swap* is a track assigned to two different targets; a *break* a change of a target's
    assigned track; a *false track* is assigned to a target less than half of its life.
    """
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
    for k, t in enumerate(grid):
        live_t = [tg for tg in targets if observed[tg][0] <= t <= observed[tg][1] and truth[tg][1][k]]
        live_k = [tid for tid in tids if tpos[tid][1][k]]
        for tid in live_k:
            t_alive[tid] += 1
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
    return {
        "per_target": per_target,
        "continuity_min": min((v["continuity"] for v in per_target.values()), default=float("nan")),
        "swaps": sum(len(s) > 1 for s in track_targets.values()),
        "breaks": sum(v["breaks"] for v in per_target.values()),
        "false_tracks": sum(1 for tid in tids if t_alive[tid] and t_assigned[tid] < 0.5 * t_alive[tid]),
        "confirmed_tracks": len(tids),
        "position_rmse_m": float(np.sqrt(np.mean(sq))) if sq else float("nan"),
        "gospa_mean_m": float(np.mean(g)),
        "gospa": g,
    }
