"""Constant-velocity track filter (plugin ``cv``).

χ̄ = A(Δt) χ̂,  P̄ = A P̂ Aᵀ + Q(Δt)  with A, Q of :class:`radartracker.motion.MotionModel`
(white acceleration of density q: Q = q [[Δt³/3 I, Δt²/2 I], [Δt²/2 I, Δt I]]), then the position
correction of :func:`radartracker_plugins.motion.base.position_update`.
"""

from __future__ import annotations

import numpy as np

from radartracker.api import MotionModel, MotionSettings, TrackFilter
from radartracker_plugins.motion.base import (check_measurement, check_time, max_gap,
                                               position_update, require_started, start_state)


class CVFilter(TrackFilter):
    """Kalman filter on χ = [x, y, vx, vy] with the constant-velocity model of density ``settings.q``.

    ``params["q"]`` overrides ``settings.q`` for this model only; ``params["max_gap_s"]`` (3600 s) is
    the longest prediction accepted (the same in every motion model).
    """

    name = "cv"

    def __init__(self, settings: MotionSettings | None = None) -> None:
        super().__init__(settings)
        self.max_gap = max_gap(self.settings)
        self.model = MotionModel(float(self.settings.params.get("q", self.settings.q)))
        self.time: float | None = None
        self.x = np.zeros(4)
        self.P = np.eye(4)

    def start(self, time: float, z: np.ndarray, R: np.ndarray) -> None:
        self.time, z, R = check_measurement(time, z, R)
        self.x, self.P = start_state(z, R, self.settings.prior_sd_velocity_mps)

    def predict(self, time: float) -> tuple[np.ndarray, np.ndarray]:
        time = check_time(time, self.time, self.max_gap)
        A, Q = self.model.transition(time - self.time)
        return A @ self.x, A @ self.P @ A.T + Q

    def update(self, time: float, z: np.ndarray, R: np.ndarray) -> float:
        time, z, R = check_measurement(time, z, R)
        x, P = self.predict(time)
        step = position_update(x, P, z, R)
        self.time, self.x, self.P = time, step.x, step.P
        return step.nis

    def estimate(self) -> tuple[float, np.ndarray, np.ndarray]:
        require_started(self.time)
        return self.time, self.x.copy(), self.P.copy()
