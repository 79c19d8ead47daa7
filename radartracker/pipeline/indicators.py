"""Track-quality indicators as the surveillance standards name them (ESASSP; SASS-C and OpenATS COMPASS
measure the same), from the track-to-truth assignment of :func:`radartracker.pipeline.evaluate.track_metrics`.

On the evaluation grid (times t_k, every 2 s), ``assigned[r, k]`` is the track holding target r (−1: none):

* **Multiple tracks**: a live track that holds no target but lies within c of a target that another track
  holds is a *multiple* (duplicate) track of that target at t_k: the controller sees the aircraft twice.
  Reported: the share of the targets' observed time during which they have one or more (Σ_r #{k: r has a
  multiple track} / Σ_r #{k: r observed}), the flights that ever have one, and the tracks that ever are one.
* **Probability of update** P_u (ESASSP: per expected update interval T_u, 8 s for 5 NM separation): each
  target's observed span [a, b] is cut into ⌊(b − a)/T_u⌋ whole intervals [a + jT_u, a + (j+1)T_u); one is
  *updated* when a track holding the target in it has an estimate (a measurement update) inside it.
  P_u = updated intervals / expected intervals, pooled over the targets.
* **Continuity**: breaks (changes of a target's track, :func:`track_metrics`) per flight hour, the flight
  hours being the targets' observed spans.
* **Initiation delay**: from a target's first detection to the first estimate of the first track that
  holds it (median, 95th percentile and maximum over the targets that get a track).
"""

from __future__ import annotations

import math

import attrs
import numpy as np

UPDATE_INTERVAL_S = 8.0  # ESASSP's measurement interval for P_u at 5 NM separation


@attrs.frozen
class Assignment:
    """What :func:`track_metrics` found on its grid: ``assigned`` (targets × grid, track index or −1),
    the tracks' positions and life (tracks × grid × 2, tracks × grid), the targets' positions and
    observed times (targets × grid × 2, targets × grid), and each track's estimate times and first
    estimate (by track index)."""

    grid: np.ndarray
    assigned: np.ndarray
    trk_pos: np.ndarray
    trk_live: np.ndarray
    tru_pos: np.ndarray
    tru_live: np.ndarray
    updates: list[np.ndarray]
    starts: np.ndarray


def doubled_times(a: Assignment, c: float) -> tuple[np.ndarray, set[int]]:
    """(targets × grid: the target is held and another, spare track lies within ``c`` of it; the spare tracks
    that ever are such a multiple track), as :func:`multiple_tracks` counts them."""
    held_by_some = np.zeros(a.trk_live.shape, bool)
    r, k = np.nonzero(a.assigned >= 0)
    held_by_some[a.assigned[r, k], k] = True
    spare = a.trk_live & ~held_by_some  # tracks × grid: live and holding no target
    doubled = np.zeros(a.tru_live.shape, bool)  # targets × grid: held, with a spare track within c
    extra: set[int] = set()
    for k in np.flatnonzero(spare.any(axis=0) & (a.assigned >= 0).any(axis=0)).tolist():
        rows = np.flatnonzero(a.tru_live[:, k] & (a.assigned[:, k] >= 0))
        qs = np.flatnonzero(spare[:, k])
        if not len(rows):
            continue
        near = np.sum((a.tru_pos[rows, k][:, None] - a.trk_pos[qs, k][None]) ** 2, axis=-1) < c * c
        doubled[rows[near.any(axis=1)], k] = True
        extra.update(qs[near.any(axis=0)].tolist())
    return doubled, extra


def multiple_tracks(a: Assignment, c: float) -> dict:
    """The multiple-track indicators (module docstring) for the association distance ``c``."""
    doubled, extra = doubled_times(a, c)
    observed = int(a.tru_live.sum())
    flights = int(a.tru_live.any(axis=1).sum())
    with_multiple = int(doubled.any(axis=1).sum())
    return {"multiple_tracks": len(extra),
            "multiple_share_of_time": float(doubled.sum() / observed) if observed else math.nan,
            "flights_with_multiple_tracks": with_multiple,
            "flights_with_multiple_share": with_multiple / flights if flights else math.nan}


def update_counts(a: Assignment, spans: dict[int, tuple[float, float]], interval_s: float
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Per target row of ``spans`` (its observed span), in their order: the update intervals that were updated
    and those expected (module docstring, probability of update)."""
    updated, expected = np.zeros(len(spans), int), np.zeros(len(spans), int)
    for i, (r, (lo, hi)) in enumerate(spans.items()):
        n = int(math.floor((hi - lo) / interval_s))
        if n <= 0:
            continue
        expected[i] = n
        ks = np.flatnonzero(a.tru_live[r] & (a.assigned[r] >= 0))
        slot = np.floor((a.grid[ks] - lo) / interval_s).astype(int)
        hit = np.zeros(n, bool)
        for q in np.unique(a.assigned[r, ks]).tolist():
            mine = np.unique(slot[a.assigned[r, ks] == q])  # the intervals in which q holds r
            u = a.updates[q]
            j = np.floor((u[(u >= lo) & (u < lo + n * interval_s)] - lo) / interval_s).astype(int)
            hit[np.intersect1d(mine[(mine >= 0) & (mine < n)], j)] = True
        updated[i] = int(hit.sum())
    return updated, expected


def probability_of_update(a: Assignment, spans: dict[int, tuple[float, float]], interval_s: float) -> float:
    """Pooled P_u (module docstring) of the targets whose observed span (by target row) is in ``spans``."""
    updated, expected = update_counts(a, spans, interval_s)
    return int(updated.sum()) / int(expected.sum()) if expected.sum() else math.nan


def initiation_delays(a: Assignment, first_seen: dict[int, float]) -> np.ndarray:
    """Per target row of ``first_seen`` (its first detection time) that a track ever holds: the first
    estimate of the first track holding it, less that time (never negative)."""
    out = []
    for r, t0 in first_seen.items():
        ks = np.flatnonzero(a.assigned[r] >= 0)
        if len(ks):
            out.append(max(float(a.starts[a.assigned[r, ks[0]]]) - t0, 0.0))
    return np.array(out, float)


def indicators(a: Assignment, spans: dict[int, tuple[float, float]], first_seen: dict[int, float], breaks: int,
               c: float, interval_s: float = UPDATE_INTERVAL_S) -> dict:
    """The indicators of the module docstring; ``spans``: each target row's observed span, ``first_seen``:
    its first detection, ``breaks``: the breaks :func:`track_metrics` counted."""
    hours = sum(hi - lo for lo, hi in spans.values()) / 3600.0
    delays = initiation_delays(a, first_seen)
    return {"update_interval_s": interval_s,
            "probability_of_update": probability_of_update(a, spans, interval_s),
            "flight_hours": hours,
            "breaks_per_flight_hour": breaks / hours if hours > 0 else math.nan,
            **multiple_tracks(a, c),
            **{f"initiation_delay_{name}_s": float(f(delays)) if len(delays) else math.nan
               for name, f in (("median", np.median), ("p95", lambda d: np.percentile(d, 95)), ("max", np.max))}}
