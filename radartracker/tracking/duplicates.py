"""Two tracks on one aircraft: found when the younger is about to be confirmed, and resolved by keeping the
older track number, as operational trackers do (ESASSP counts a second track as a *multiple track*).

A tentative track that reaches M of N is compared with the live tracks near it (the frame's
:class:`~radartracker.tracking.frame.Prediction`, within ``merge_distance_m``). An older track is the
same aircraft when no identity tells them apart (Mode S addresses, Mode 3/A codes, Mode C altitudes
within :data:`ALTITUDE_M`) and

* it has *lost* the aircraft (it has had no measurement since the new track began), its straight-line
  position within ``merge_distance_m`` of the new track's and its velocity within :data:`SPEED_SHARE` of
  the new track's speed (plus :data:`SPEED_SLACK_MPS`): its covariance, which let the aircraft get out
  of its gate, cannot be trusted to judge; the older number *takes over* the new track's filter;
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
    x_old = np.array(old.state_at(t))
    d = x_old - x_new
    if old.last_update <= new.created:  # not a measurement since the new track began: it took them all
        speed = math.hypot(x_new[2], x_new[3])
        near = math.hypot(d[0], d[1]) <= distance_m
        return LOST if near and math.hypot(d[2], d[3]) <= SPEED_SHARE * speed + SPEED_SLACK_MPS else None
    t_old, _, P_old = old.estimate()
    if t_old > t:  # judged at the later estimate: the old track's is not extrapolated backwards
        return None
    try:
        d2 = float(d @ np.linalg.solve(P_old + P_new, d))
    except np.linalg.LinAlgError:
        return None
    return TWIN if d2 <= TWIN_GATE else None


def duplicate_of(new: Track, pred: Prediction | None, distance_m: float) -> tuple[Track, str] | None:
    """The oldest track of ``pred`` (the frame's live tracks) that ``new`` duplicates, with the relation."""
    if pred is None or not len(pred):
        return None
    _, x, _ = new.estimate()
    # pred.position is at the frame's middle: up to half a frame (0.25 s) of flight, 75 m at 300 m/s, from t
    near = np.flatnonzero(np.hypot(*(pred.position - x[:2]).T) <= distance_m + 75.0)
    for i in sorted(near.tolist(), key=lambda k: pred.tracks[k].id):
        old = pred.tracks[i]
        if old.id < new.id and (how := relation(old, new, distance_m)) is not None:
            return old, how
    return None
