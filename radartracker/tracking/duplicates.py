"""Two tracks on one aircraft: found when the younger is about to be confirmed, and resolved by keeping the
older track number, as operational trackers do (ESASSP counts a second track as a *multiple track*).

A tentative track that reaches M of N is compared with the live tracks near it (the frame's
:class:`~radartracker.tracking.frame.Prediction`, within ``merge_distance_m``). An older track is the
same aircraft when no identity tells them apart (Mode S addresses, Mode 3/A codes, Mode C altitudes
within :data:`ALTITUDE_M`) and

* it has *lost* the aircraft (it has had no measurement since the new track began), and some turn at a
  constant rate of at most :data:`TURN_RATE_MAX` (straight on included) from its last estimate (p₀, v₀) at
  t₀ puts the aircraft within ``merge_distance_m`` of the new track's position at t, with a velocity as far
  from the new track's as :data:`SPEED_SHARE` of its speed plus :data:`SPEED_SLACK_MPS` at most: with
  a = ω(t − t₀), p(ω) = p₀ + [[S, −K], [K, S]] v₀ and v(ω) = R(a) v₀, S = sin a / ω, K = (1 − cos a)/ω
  (a lost aircraft is most often one that turned while its track went straight on). Its covariance, which
  let the aircraft get out of its gate, cannot be trusted to judge; the older number *takes over* the new
  track's filter;
* or it is being updated and the two states agree, d² = (χ̂₁ − χ̂₂)ᵀ(P₁ + P₂)⁻¹(χ̂₁ − χ̂₂) ≤
  :data:`TWIN_GATE` (χ²₄ 99.9 %): the new track is a *twin*, dropped, the older one goes on.
"""

from __future__ import annotations

import math

import numpy as np

from radartracker.tracking.frame import Prediction
from radartracker.tracking.track import Track

ALTITUDE_M = 150.0  # Mode C altitudes further apart (500 ft) are two aircraft
SPEED_SHARE, SPEED_SLACK_MPS = 0.5, 20.0  # a lost track's velocity may be this far off the new one's
TWIN_GATE = 18.47  # χ²₄ 99.9 %: two updated tracks whose states agree this well are one aircraft
TURN_RATE_MAX = math.radians(3.0)  # a standard-rate turn: the fastest a lost aircraft is taken to have turned
_TURN_RATES = np.linspace(-TURN_RATE_MAX, TURN_RATE_MAX, 61)  # 0.1°/s apart: 35 m over 20 s at 200 m/s
# how far from its straight line a lost track's aircraft may be: 300 m/s turning at 3°/s for 40 s (the default
# delete_after_s) ends 11 km from it (v ω Δt²/2 = 12.6 km for small angles)
LOST_SEARCH_M = 15_000.0
LOST, TWIN = "lost", "twin"


def _identities_agree(a: Track, b: Track) -> bool:
    """Nothing the tracks' measurements carried tells them apart."""
    for x, y in ((a.mode_s, b.mode_s), (a.mode_3a, b.mode_3a)):
        if x is not None and y is not None and x != y:
            return False
    ha, hb = a.reported_altitude_m, b.reported_altitude_m  # an estimated height tells nothing apart
    return ha is None or hb is None or abs(ha - hb) <= ALTITUDE_M


def relation(old: Track, new: Track, distance_m: float) -> str | None:
    """:data:`LOST` or :data:`TWIN` when ``old`` follows (or followed) the aircraft ``new`` follows (module
    docstring), else ``None``."""
    if old is new or old.status not in ("confirmed", "coasting") or not _identities_agree(old, new):
        return None
    t, x_new, P_new = new.estimate()
    if old.last_update <= new.created:  # not a measurement since the new track began: it took them all
        return LOST if _turned_into(*old.estimate()[:2], t, x_new, distance_m) else None
    t_old, _, P_old = old.estimate()
    if t_old > t:  # judged at the later estimate: the old track's is not extrapolated backwards
        return None
    d = np.array(old.state_at(t)) - x_new
    try:
        d2 = float(d @ np.linalg.solve(P_old + P_new, d))
    except np.linalg.LinAlgError:
        return None
    return TWIN if d2 <= TWIN_GATE else None


def _turned_into(t0: float, x0: np.ndarray, t: float, x: np.ndarray, distance_m: float) -> bool:
    """Whether a turn at a constant rate |ω| ≤ TURN_RATE_MAX from state ``x0`` = [p₀, v₀] at ``t0`` reaches ``x``
    at ``t``: within ``distance_m``, with a velocity close to its (module docstring)."""
    dt = max(t - t0, 0.0)
    a = _TURN_RATES * dt
    S, K = dt * np.sinc(a / np.pi), dt * np.sin(a / 2) * np.sinc(a / (2 * np.pi))  # sin a/ω, (1 − cos a)/ω
    (px, py, vx, vy), c, s = x0, np.cos(a), np.sin(a)
    near = np.hypot(px + S * vx - K * vy - x[0], py + K * vx + S * vy - x[1]) <= distance_m
    alike = np.hypot(c * vx - s * vy - x[2], s * vx + c * vy - x[3]) <= SPEED_SHARE * math.hypot(x[2], x[3]) \
        + SPEED_SLACK_MPS
    return bool(np.any(near & alike))


def duplicate_of(new: Track, pred: Prediction | None, distance_m: float) -> tuple[Track, str] | None:
    """The oldest track of ``pred`` (the frame's live tracks) that ``new`` duplicates, with the relation."""
    if pred is None or not len(pred):
        return None
    _, x, _ = new.estimate()
    # pred.position is at the frame's middle: up to half a frame (0.25 s) of flight, 75 m at 300 m/s, from t;
    # a track that lost its aircraft is looked for up to LOST_SEARCH_M farther (where a turn took it)
    dist = np.hypot(*(pred.position - x[:2]).T)
    near = np.flatnonzero(dist <= distance_m + 75.0 + LOST_SEARCH_M)
    for i in sorted(near.tolist(), key=lambda k: pred.tracks[k].id):
        old = pred.tracks[i]
        if old.id >= new.id or (dist[i] > distance_m + 75.0 and old.last_update > new.created):
            continue
        if (how := relation(old, new, distance_m)) is not None:
            return old, how
    return None
