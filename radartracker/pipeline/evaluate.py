"""Comparison of estimates with the truth of a simulated scenario.

Truth positions are interpolated linearly in the system plane at the estimate times; truth
velocities are the finite-difference slopes of that interpolation. NEES is
(χ̂ − χ)ᵀ P⁻¹ (χ̂ − χ) of the 4-dimensional aircraft state.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import attrs
import numpy as np

from radartracker.errors import InputError
from radartracker.io.tables import TruthTable
from radartracker.geometry.plane import SystemPlane
from radartracker.pipeline.indicators import (UPDATE_INTERVAL_S, Assignment, doubled_times, indicators,
                                              initiation_delays, update_counts)


@attrs.frozen
class TruthPaths:
    """Per-target truth in the plane: times, positions and velocities."""

    paths: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]

    @classmethod
    def from_table(cls, truth: TruthTable, plane: SystemPlane) -> TruthPaths:
        x, y = plane.to_plane(truth.lat, truth.lon)
        paths = {}
        for target, idx in _groups(truth.target):
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
    for key, idx in _groups(keys):
        truth, inside = paths.state_at(key, times[idx])
        err[idx] = states[idx] - truth
        ok[idx] = inside
    return err, ok


def _groups(keys: np.ndarray) -> list[tuple[str, np.ndarray]]:
    """(key, ascending row indices) for each distinct ``str(key)``, keys sorted: one pass, not one per key."""
    if not len(keys):
        return []
    names, inverse = np.unique(np.asarray(keys).astype(str), return_inverse=True)
    order = np.argsort(inverse, kind="stable")
    bounds = np.cumsum(np.bincount(inverse, minlength=len(names)))[:-1]
    return list(zip(names.tolist(), np.split(order, bounds)))


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


MAX_GRID_CELLS = 100_000_000  # (targets + tracks) × grid times: ~2.4 GB of positions and masks


@attrs.frozen
class GridSpec:
    """The evaluation grid ``np.arange(start, stop, step)`` described, not made: :func:`track_metrics` makes
    only its times where an aircraft is observed or a track lives (a truth time of 1e9 s made the whole
    grid, 5·10⁸ times, and the positions on it, tens of GiB)."""

    start: float
    stop: float
    step: float

    def times(self, spans: Iterable[tuple[float, float]]) -> tuple[np.ndarray, np.ndarray, int]:
        """The grid times within any of ``spans`` (inclusive; one more on each side against rounding), their
        indices k (time = start + k·step, as np.arange makes them) and the number of grid times in all."""
        n = max(int(math.ceil((self.stop - self.start) / self.step)), 0)
        cuts = sorted((max(int(math.ceil((lo - self.start) / self.step)) - 1, 0),
                       min(int(math.floor((hi - self.start) / self.step)) + 2, n))
                      for lo, hi in spans if hi >= lo and math.isfinite(lo) and math.isfinite(hi))
        merged: list[list[int]] = []
        for a, b in cuts:
            if b <= a:
                continue
            if merged and a <= merged[-1][1]:
                merged[-1][1] = max(merged[-1][1], b)
            else:
                merged.append([a, b])
        k = np.concatenate([np.arange(a, b) for a, b in merged]) if merged else np.zeros(0, int)
        return self.start + k * self.step, k, n


def gospa(d2: np.ndarray, n_missed: int, n_false: int, c: float) -> float:
    """GOSPA (p = 2, α = 2) given squared distances of assigned pairs (each < c)."""
    return float(np.sqrt(np.sum(d2) + c * c / 2 * (n_missed + n_false)))


def detection_gaps(time: np.ndarray, target: np.ndarray, longer_than_s: float) -> dict[str, int]:
    """Per truth label of ``target`` (``None``: no label, left out), how many times its detections (``time``)
    stop for longer than ``longer_than_s``: the aircraft left every sensor's coverage for longer than a track
    is kept without an update."""
    out = {}
    labelled = np.array([t is not None for t in target], bool)
    keys = np.asarray(target[labelled]).astype(str)
    t = np.asarray(time, float)[labelled]
    order = np.lexsort((t, keys))
    keys, t = keys[order], t[order]
    for k, start, stop in zip(*_runs(keys)):
        out[k] = int(np.sum(np.diff(t[start:stop]) > longer_than_s))
    return out


def _runs(keys: np.ndarray) -> tuple[list[str], list[int], list[int]]:
    """The runs of equal values of the sorted ``keys``: each value, its first index and the index after its last."""
    if not len(keys):
        return [], [], []
    cut = np.flatnonzero(keys[1:] != keys[:-1]) + 1
    starts, stops = np.concatenate([[0], cut]), np.concatenate([cut, [len(keys)]])
    return keys[starts].tolist(), starts.tolist(), stops.tolist()


def track_metrics(tracks: dict[int, TrackHistory], paths: TruthPaths, observed: dict[str, tuple[float, float]],
                  grid: np.ndarray | GridSpec, c: float = 2000.0, sensed: Iterable[str] | None = None,
                  first_seen: dict[str, float] | None = None, gaps: dict[str, int] | None = None,
                  samples: bool = False) -> dict:
    """Track-to-truth assignment on a time grid and the metrics derived from it.

    At each grid time the alive tracks are assigned to the observed truths as in CLEAR MOT
    (Bernardin & Stiefelhagen 2008): a track keeps the target it had at the previous time while it
    stays within ``c``; the others are assigned by minimum total distance (Hungarian), pairs
    farther than ``c`` left unassigned. (Without the first rule, two tracks passing through the
    same point at a crossing would "swap" for one instant by an accident of the tie.) Per target, the *right* track
    is the one assigned to it most often; continuity is the fraction of its observed time it holds.
    A *swap* is a track assigned to two different targets; a *break* a change of a target's assigned track;
    ``breaks_in_coverage`` leaves out, per target, as many breaks as its detections have ``gaps``
    (:func:`detection_gaps`; none given: none left out): across such a gap the aircraft was out of every
    sensor's coverage, its track rightly deleted and a new one started when it came back (ESASSP and SASS-C
    judge continuity inside the coverage). A track *follows* an aircraft at a grid time when it is assigned to
    it, or lies within ``c`` of one of the ``sensed`` aircraft (those any plot or report observed; default:
    every aircraft of ``paths``) where it has truth — so a track confirmed during its aircraft's grace period,
    on an aircraft seen only by ADS-B, or a second track on an aircraft follows it. A *false track* follows no
    aircraft for at least half of its life up to its last estimate (what measurements support: a track coasts
    ``delete_after_s`` after its last plot, also when its aircraft has vanished, as simulated flights do at
    their end). A :class:`GridSpec` is evaluated at its times where something lives (the others add nothing
    but zeros to the GOSPA mean, counted in it), with the same results as the whole grid; the times evaluated
    may be at most :data:`MAX_GRID_CELLS` / (targets + tracks), else an InputError. ``indicators``: the
    standards' track-quality indicators (:mod:`radartracker.pipeline.indicators`: multiple tracks, probability
    of update, breaks per flight hour, initiation delay from ``first_seen``, each target's first detection, by
    default the start of its observed span). With ``samples``, also ``samples``: each target's share of those
    figures (:func:`target_samples`), what an interval over the aircraft needs.
    """
    targets = sorted(observed)
    tids = sorted(tracks)
    grid, index, n_all = _grid_times(grid, observed, tracks, len(targets) + len(tids))
    tru_pos, tru_live = _truth_on_grid(paths, observed, targets, grid)
    trk_pos = np.zeros((len(tids), len(grid), 2))
    trk_live = np.zeros((len(tids), len(grid)), bool)
    for q, tid in enumerate(tids):
        trk_pos[q], trk_live[q] = tracks[tid].at(grid)
    assigned, track_targets, g, sq, sq_rows = _assignment(tru_pos, tru_live, trk_pos, trk_live, index, c)
    held = np.zeros(trk_live.shape, bool)
    r, k = np.nonzero(assigned >= 0)
    held[assigned[r, k], k] = True
    judged = _supported(tracks, tids, trk_live, grid)
    t_alive = judged.sum(axis=1)
    t_follows = (held & judged).sum(axis=1) + _unassigned_near(trk_pos, judged, held, paths,
                                                               paths.paths if sensed is None else sensed, grid, c * c)
    tid_of = np.array(tids + [-1])  # index -1 stays -1
    per_target = _per_target(tid_of[assigned], tru_live, targets)
    for tg, v in per_target.items():
        v["breaks_in_coverage"] = max(0, v["breaks"] - (gaps or {}).get(tg, 0))
    breaks = sum(v["breaks"] for v in per_target.values())
    found = Assignment(grid, assigned, trk_pos, trk_live, tru_pos, tru_live, [tracks[t].times for t in tids],
                       np.array([tracks[t].start for t in tids], float))
    seen = first_seen or {}
    spans = {r: observed[tg] for r, tg in enumerate(targets)}
    starts = {r: seen.get(tg, observed[tg][0]) for r, tg in enumerate(targets)}
    quality = indicators(found, spans, starts, breaks, c)
    extra = {"samples": target_samples(found, targets, spans, starts, sq, sq_rows, c)} if samples else {}
    return extra | {
        "per_target": per_target,
        "continuity_min": min((v["continuity"] for v in per_target.values()), default=float("nan")),
        "swaps": sum(len(s) > 1 for s in track_targets),
        "breaks": breaks,
        "breaks_in_coverage": sum(v["breaks_in_coverage"] for v in per_target.values()),
        "false_tracks": int(np.sum((t_alive > 0) & (t_follows < 0.5 * t_alive))),
        "confirmed_tracks": len(tids),
        "position_rmse_m": float(np.sqrt(np.mean(sq))) if sq else float("nan"),
        "gospa_mean_m": float(np.sum(g) / n_all) if n_all else float("nan"),
        "indicators": quality,
        "gospa": g,
    }


def target_samples(a: Assignment, targets: list[str], spans: dict[int, tuple[float, float]],
                   first_seen: dict[int, float], sq: list[float], sq_rows: list[int], c: float) -> dict:
    """Per target (in the order of ``targets``): the sum of its assigned pairs' squared distances
    (``sq_sum_m2``) and their count (``pairs``), its observed grid times (``observed``) and those with a
    multiple track (``multiple``), its expected and updated update intervals (``expected``, ``updated``);
    and the initiation delays (``delays_s``). Each pooled figure of :func:`track_metrics` is a ratio of two of
    these sums (RMSE² = Σ sq_sum / Σ pairs, P_u = Σ updated / Σ expected, …), so resampling the aircraft
    resamples the figure."""
    n = len(targets)
    updated, expected = update_counts(a, spans, UPDATE_INTERVAL_S)
    return {"targets": list(targets),
            "sq_sum_m2": np.bincount(np.asarray(sq_rows, int), weights=np.asarray(sq, float), minlength=n),
            "pairs": np.bincount(np.asarray(sq_rows, int), minlength=n),
            "observed": a.tru_live.sum(axis=1), "multiple": doubled_times(a, c)[0].sum(axis=1),
            "updated": updated, "expected": expected, "delays_s": initiation_delays(a, first_seen)}


def _grid_times(grid: np.ndarray | GridSpec, observed: dict[str, tuple[float, float]],
                tracks: dict[int, TrackHistory], rows: int) -> tuple[np.ndarray, np.ndarray, int]:
    """(grid times evaluated, their indices in the whole grid, the whole grid's length); an InputError
    when the times × ``rows`` (targets + tracks) exceed :data:`MAX_GRID_CELLS`."""
    if isinstance(grid, GridSpec):
        grid, index, n_all = grid.times([*observed.values(), *((h.start, h.end) for h in tracks.values())])
    else:
        index, n_all = np.arange(len(grid)), len(grid)
    if len(grid) * rows > MAX_GRID_CELLS:
        raise InputError(f"evaluation: {len(grid):,} grid times × {rows:,} targets and tracks "
                         f"exceed {MAX_GRID_CELLS:,} (plot or track times spanning {grid[-1] - grid[0]:.3g} s?)")
    return grid, index, n_all


def _truth_on_grid(paths: TruthPaths, observed: dict[str, tuple[float, float]], targets: list[str],
                   grid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Truth positions (targets × grid × 2) and where they count: inside the truth and the observed span."""
    tru_pos = np.zeros((len(targets), len(grid), 2))
    tru_live = np.zeros((len(targets), len(grid)), bool)
    for r, tg in enumerate(targets):
        state, inside = paths.state_at(tg, grid)
        tru_pos[r], tru_live[r] = state[:, :2], inside & (grid >= observed[tg][0]) & (grid <= observed[tg][1])
    return tru_pos, tru_live


def _assignment(tru_pos: np.ndarray, tru_live: np.ndarray, trk_pos: np.ndarray, trk_live: np.ndarray,
                index: np.ndarray, c: float) -> tuple[np.ndarray, list[set[int]], np.ndarray, list[float], list[int]]:
    """The assignment at each grid time (:func:`track_metrics`): the track index each target holds
    (targets × grid, −1: none), the targets each track was assigned to, GOSPA per grid time, the
    squared distances of all assigned pairs and each pair's target row. A target's previous track is the
    one of the grid time before (``index`` consecutive)."""
    n_g = tru_live.shape[1]
    assigned = np.full(tru_live.shape, -1)  # track index held by each target
    track_targets: list[set[int]] = [set() for _ in range(len(trk_live))]
    g, sq, sq_rows = np.zeros(n_g), [], []
    for k in range(n_g):
        live_t = np.flatnonzero(tru_live[:, k])
        live_k = np.flatnonzero(trk_live[:, k])
        if not len(live_t) and not len(live_k):
            continue
        prev = assigned[live_t, k - 1] if k and index[k] == index[k - 1] + 1 else np.full(len(live_t), -1)
        rows, cols, d2 = _assign_at(tru_pos[:, k], trk_pos[:, k], trk_live[:, k], live_t, live_k, prev, c * c)
        g[k] = gospa(np.array(d2), len(live_t) - len(rows), len(live_k) - len(rows), c)
        sq.extend(d2)
        sq_rows.extend(rows)
        assigned[rows, k] = cols
        for r, q in zip(rows, cols):
            track_targets[q].add(r)
    return assigned, track_targets, g, sq, sq_rows


def _assign_at(tru_pos: np.ndarray, trk_pos: np.ndarray, trk_live: np.ndarray, live_t: np.ndarray,
               live_k: np.ndarray, prev: np.ndarray, c2: float) -> tuple[list, list, list]:
    """(target rows, track indices, squared distances) of the pairs at one grid time: a target keeps
    ``prev`` (its track at the time before) while that track lives and stays within c; the free targets
    and tracks are assigned by minimum total squared distance (Hungarian), pairs at c or farther left out."""
    from scipy.optimize import linear_sum_assignment

    keep = prev >= 0
    keep[keep] &= trk_live[prev[keep]]
    d_keep = np.sum((tru_pos[live_t[keep]] - trk_pos[prev[keep]]) ** 2, axis=-1)
    keep[np.flatnonzero(keep)[d_keep >= c2]] = False
    rows, cols = list(live_t[keep]), list(prev[keep])
    d2 = list(np.sum((tru_pos[live_t[keep]] - trk_pos[prev[keep]]) ** 2, axis=-1))
    free_r = live_t[~keep]
    free_q = live_k[~np.isin(live_k, prev[keep])]
    if len(free_r) and len(free_q):
        sub = np.sum((tru_pos[free_r][:, None, :] - trk_pos[free_q][None, :, :]) ** 2, axis=-1)
        a, b = linear_sum_assignment(np.minimum(sub, c2))
        ok = sub[a, b] < c2
        rows += list(free_r[a[ok]])
        cols += list(free_q[b[ok]])
        d2 += list(sub[a[ok], b[ok]])
    return rows, cols, d2


def _per_target(assigned: np.ndarray, tru_live: np.ndarray, targets: list[str]) -> dict[str, dict]:
    """Per target, from the track ids it holds (targets × grid, −1: none): the right track (held most
    often), continuity (the fraction of its observed times the right track holds) and breaks."""
    per_target = {}
    for r, tg in enumerate(targets):
        a = assigned[r]
        inside = tru_live[r]
        held = a[inside & (a >= 0)]
        right = int(np.bincount(held).argmax()) if len(held) else -1
        per_target[tg] = {
            "right_track": right,
            "continuity": float(np.mean(a[inside] == right)) if inside.any() else float("nan"),
            "breaks": int(np.sum(held[1:] != held[:-1])) if len(held) else 0,
        }
    return per_target


def _supported(tracks: dict[int, TrackHistory], tids: list[int], trk_live: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """Per track, the grid times of its life up to its last estimate (at least its first grid time): what
    its measurements support. After that it coasts until deleted, also when its aircraft has vanished."""
    last = np.array([tracks[tid].times[-1] for tid in tids], float).reshape(len(tids), 1)
    out = trk_live & (grid[None, :] <= last)
    lone = np.flatnonzero(~out.any(axis=1) & trk_live.any(axis=1))
    out[lone, np.argmax(trk_live[lone], axis=1)] = True
    return out


def _unassigned_near(trk_pos: np.ndarray, trk_live: np.ndarray, held: np.ndarray, paths: TruthPaths,
                     sensed: Iterable[str], grid: np.ndarray, c2: float) -> np.ndarray:
    """Per track, the grid times it is alive (``trk_live``), not assigned (``held``), and within c of a
    sensed aircraft's truth (only those times are searched: few, so the cost stays linear in the grid)."""
    names = [tg for tg in sensed if tg in paths.paths]
    out = np.zeros(len(trk_live), int)
    if not names:
        return out
    states = [paths.state_at(tg, grid) for tg in names]
    pos = np.stack([s[:, :2] for s, _ in states])  # sensed × grid × 2
    inside = np.stack([m for _, m in states])
    for q in range(len(trk_live)):
        ks = np.flatnonzero(trk_live[q] & ~held[q])
        if len(ks):
            d2 = np.sum((pos[:, ks] - trk_pos[q, ks][None]) ** 2, axis=-1)
            out[q] = int(np.sum(np.any(inside[:, ks] & (d2 < c2), axis=0)))
    return out
