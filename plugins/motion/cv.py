"""Constant-velocity track filter (plugin ``cv``).

χ̄ = A(Δt) χ̂,  P̄ = A P̂ Aᵀ + Q(Δt)  with A, Q of :class:`radartracker.api.MotionModel`
(computed by the compiled :func:`radartracker_plugins.motion._compiled.cv_predict`)
(white acceleration of density q: Q = q [[Δt³/3 I, Δt²/2 I], [Δt²/2 I, Δt I]]), then the position
correction of :func:`radartracker_plugins.motion.base.position_update`. The prediction is kept until
the state changes: the update at the time innovation screening predicted to reuses it.
"""

from __future__ import annotations

import attrs
import numpy as np

from radartracker.api import MotionConfig, TrackFilter
from radartracker_plugins.motion._compiled import cv_predict
from radartracker_plugins.motion.base import check_measurement, check_time, position_update, require_started, start_state


@attrs.frozen
class CVConfig(MotionConfig):
    """Settings of ``cv``: white-acceleration density ``q`` (m²/s³) of Q(Δt) above."""

    q: float = attrs.field(default=1.0, converter=float, validator=attrs.validators.ge(0.0))


class CVFilter(TrackFilter):
    """Kalman filter on χ = [x, y, vx, vy] with the constant-velocity model of density ``config.q``."""

    name = "cv"
    config_class = CVConfig

    def __init__(self, config: CVConfig | None = None) -> None:
        super().__init__(config)
        self.time: float | None = None
        self.x = np.zeros(4)
        self.P = np.eye(4)
        self._pred: tuple | None = None  # (time, χ̄, P̄) from the current state: screening's, for the update

    def _predicted(self, time: float) -> tuple[np.ndarray, np.ndarray]:
        if self._pred is None or self._pred[0] != time:
            self._pred = (time, *cv_predict(self.x, self.P, time - self.time, self.config.q))
        return self._pred[1:]

    def start(self, time: float, z: np.ndarray, R: np.ndarray) -> None:
        self.time, z, R = check_measurement(time, z, R)
        self.x, self.P = start_state(z, R, self.config.prior_sd_velocity_mps)
        self._pred = None

    def predict(self, time: float) -> tuple[np.ndarray, np.ndarray]:
        x, P = self._predicted(check_time(time, self.time, self.config.max_gap_s))
        return x.copy(), P.copy()

    def update(self, time: float, z: np.ndarray, R: np.ndarray) -> float:
        time, z, R = check_measurement(time, z, R)
        x, P = self._predicted(check_time(time, self.time, self.config.max_gap_s))
        step = position_update(x, P, z, R)
        self.time, self.x, self.P, self._pred = time, step.x, step.P, None
        return step.nis

    def estimate(self) -> tuple[float, np.ndarray, np.ndarray]:
        require_started(self.time)
        return self.time, self.x.copy(), self.P.copy()

    def __getstate__(self) -> dict:  # pickles and snapshots hold the state, not the cached prediction
        return {**vars(self), "_pred": None}

    def state_dict(self) -> dict:
        return {k: v for k, v in super().state_dict().items() if k != "_pred"}

    def load_state_dict(self, state: dict) -> None:
        super().load_state_dict({k: v for k, v in state.items() if k != "_pred"})
        self._pred = None
