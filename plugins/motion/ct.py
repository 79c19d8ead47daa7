"""Coordinated-turn model with unknown turn rate (5-state, for an extended Kalman filter).

State ξ = [x, y, vx, vy, ω] with ω the rate of change of the heading, positive clockwise (the ATC
convention of DESIGN §3: heading φ from north, v = (v sin φ, v cos φ), so dφ/dt = ω gives
d(vx, vy)/dt = ω (vy, −vx)). Over Δt = T, with s = sin ωT, c = cos ωT::

    x' = x + (s/ω) vx + ((1−c)/ω) vy        vx' =  c vx + s vy
    y' = y − ((1−c)/ω) vx + (s/ω) vy        vy' = −s vx + c vy        ω' = ω

(ω → 0 gives constant velocity). Process noise: white acceleration of density q on the position and
velocity (the CV block of :class:`radartracker.motion.MotionModel`) and a turn-rate random walk,
Var[Δω] = σ_ω² |Δt| with σ_ω = ``turn_rate_sd`` read per √s.
"""

from __future__ import annotations

import numpy as np

from radartracker.api import MotionModel

_SMALL = 1e-4  # |ωT| below which the Taylor series are used


def _sc(w: float, T: float) -> tuple[float, float, float, float]:
    """sin(ωT)/ω, (1−cos ωT)/ω and their derivatives with respect to ω."""
    a = w * T
    if abs(a) < _SMALL:
        # series to O(a⁴): s/ω = T(1 − a²/6), (1−c)/ω = T(a/2 − a³/24)
        f1 = T * (1 - a * a / 6)
        f2 = T * (a / 2 - a**3 / 24)
        d1 = T * T * (-a / 3 + a**3 / 30)
        d2 = T * T * (0.5 - a * a / 8)
        return f1, f2, d1, d2
    s, c = np.sin(a), np.cos(a)
    f1, f2 = s / w, (1 - c) / w
    d1 = (T * c * w - s) / (w * w)
    d2 = (T * s * w - (1 - c)) / (w * w)
    return float(f1), float(f2), float(d1), float(d2)


def ct_transition(xi: np.ndarray, T: float) -> tuple[np.ndarray, np.ndarray]:
    """(f(ξ), ∂f/∂ξ) of the coordinated-turn model over ``T`` seconds."""
    x, y, vx, vy, w = xi
    f1, f2, d1, d2 = _sc(w, T)
    s, c = np.sin(w * T), np.cos(w * T)
    out = np.array([x + f1 * vx + f2 * vy,
                    y - f2 * vx + f1 * vy,
                    c * vx + s * vy,
                    -s * vx + c * vy,
                    w])
    F = np.eye(5)
    F[0, 2:5] = [f1, f2, d1 * vx + d2 * vy]
    F[1, 2:5] = [-f2, f1, -d2 * vx + d1 * vy]
    F[2, 2:5] = [c, s, T * (-s * vx + c * vy)]
    F[3, 2:5] = [-s, c, T * (-c * vx - s * vy)]
    return out, F


def ct_noise(T: float, q: float, turn_rate_sd: float) -> np.ndarray:
    """Process-noise covariance of the coordinated-turn model over ``T`` seconds."""
    Q = np.zeros((5, 5))
    Q[:4, :4] = MotionModel(q).transition(T)[1]
    Q[4, 4] = turn_rate_sd**2 * abs(T)
    return Q
