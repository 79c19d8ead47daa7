"""Shared pieces of the track filters: input checks and the position-measurement Kalman step.

Every model observes the position only, z = H χ + w with H = [I₂ 0] and w ~ N(0, R); the
correction is :func:`radartracker.kalman.correct` with K = P̄ Hᵀ and Λ = H P̄ Hᵀ + R.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from radartracker.api import SingularInnovation
from radartracker_plugins.motion import _compiled


class Step(NamedTuple):
    """A corrected state and what the update saw: ν, Λ, NIS = νᵀΛ⁻¹ν and log N(ν; 0, Λ)."""

    x: np.ndarray
    P: np.ndarray
    nu: np.ndarray
    S: np.ndarray
    nis: float
    loglik: float


def check_measurement(time: float, z: np.ndarray, R: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """Validated (time, z (2,), R (2×2)); a clear ``ValueError`` for anything else."""
    time = float(time)
    z = np.asarray(z, float)
    R = np.asarray(R, float)
    if z.ndim == 1 and R.ndim == 2 and _compiled.measurement_ok(time, z, R) == 0:  # compiled checks, else the messages
        return time, z, R
    if not math.isfinite(time):
        raise ValueError(f"time: not finite ({time})")
    if z.shape != (2,) or not np.all(np.isfinite(z)):
        raise ValueError(f"z: expected 2 finite numbers, got {z.tolist()}")
    if R.shape != (2, 2) or not np.all(np.isfinite(R)) or not np.allclose(R, R.T):
        raise ValueError(f"R: expected a finite symmetric 2×2 matrix, got {R.tolist()}")
    try:
        np.linalg.cholesky(R)
    except np.linalg.LinAlgError:
        raise ValueError(f"R: not positive definite: {R.tolist()}") from None
    return time, z, R


def require_started(current: float | None) -> None:
    """A ``ValueError`` unless ``start`` has been called (``current`` is the filter's epoch)."""
    if current is None:
        raise ValueError("filter not started: call start() first")


def check_time(time: float, current: float | None, max_gap: float) -> float:
    """``time`` as a finite float within ``max_gap`` seconds of the started filter's epoch ``current``.

    A longer extrapolation (either way) is refused: its covariance, of order q Δt³, would swamp
    double precision long before Δt reaches 10⁹ s, and a track that old is no track.
    """
    require_started(current)
    time = float(time)
    if not math.isfinite(time):
        raise ValueError(f"time: not finite ({time})")
    if abs(time - current) > max_gap:
        raise ValueError(f"time: {time} is {time - current:.6g} s from the track's epoch {current}; "
                         f"more than max_gap_s = {max_gap:g}")
    return time


def position_update(x: np.ndarray, P: np.ndarray, z: np.ndarray, R: np.ndarray) -> Step:
    """Kalman correction of (x, P) by position z; the first two state components are x, y
    (:func:`radartracker_plugins.motion._compiled.position_update`)."""
    x_new, P_new, nu, S, nis, loglik, ok = _compiled.position_update(x, P, z, R)
    if not ok:
        raise SingularInnovation(f"innovation covariance not positive definite: {S.tolist()}")
    return Step(x_new, P_new, nu, S, float(nis), float(loglik))


def start_state(z: np.ndarray, R: np.ndarray, sd_velocity: float) -> tuple[np.ndarray, np.ndarray]:
    """One-point initialisation: χ = [z, 0, 0], P = diag(R, σ_v² I)."""
    x = np.concatenate([z, np.zeros(2)])
    P = np.zeros((4, 4))
    P[:2, :2] = R
    P[2:, 2:] = sd_velocity**2 * np.eye(2)
    return x, P
