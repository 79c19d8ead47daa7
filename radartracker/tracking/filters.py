"""The track-filter contract: what a ``radartracker.motion_models`` plugin implements."""

from __future__ import annotations

import abc
from typing import Any, ClassVar

import attrs
import numpy as np


@attrs.frozen
class MotionSettings:
    """Settings of the track kinematic filters; each motion-model plugin reads what it needs.

    ``q`` is the constant-velocity white-acceleration density (m²/s³); ``q_turn`` the density of
    the coordinated-turn model and ``turn_rate_sd`` (rad/s) its turn-rate noise; ``params`` holds
    plugin-specific options (e.g. IMM switching probabilities, the adaptive filter's window).
    """

    q: float = 1.0
    q_turn: float = 1.0
    turn_rate_sd: float = float(np.radians(0.5))
    prior_sd_velocity_mps: float = 300.0
    params: dict[str, Any] = attrs.field(factory=dict)


class TrackFilter(abc.ABC):
    """Kinematic filter of one track in the plane (a ``radartracker.motion_models`` plugin).

    The TrackManager feeds it bias-corrected positions z (m) with covariance R (2×2) and reads
    predictions for gating. States are χ = [x, y, vx, vy]; a multiple-model filter reports the
    moment-matched mixture. ``start`` initialises from one position (velocity from the prior).
    """

    name: ClassVar[str] = "?"

    def __init__(self, settings: MotionSettings | None = None) -> None:
        self.settings = settings if settings is not None else MotionSettings()

    @abc.abstractmethod
    def start(self, time: float, z: np.ndarray, R: np.ndarray) -> None:
        """Initialise at ``time`` from position ``z`` with covariance ``R``."""

    @abc.abstractmethod
    def predict(self, time: float) -> tuple[np.ndarray, np.ndarray]:
        """(χ, P) predicted to ``time`` without changing the filter."""

    @abc.abstractmethod
    def update(self, time: float, z: np.ndarray, R: np.ndarray) -> float:
        """Predict to ``time``, correct with position ``z`` (covariance ``R``); return the NIS."""

    @abc.abstractmethod
    def estimate(self) -> tuple[float, np.ndarray, np.ndarray]:
        """(time, χ, P) of the current estimate."""
