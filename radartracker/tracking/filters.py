"""The track-filter contract: what a ``radartracker.motion_models`` plugin implements.

Each motion model has its own typed settings class derived from :class:`MotionConfig` and names it
in ``config_class``; the registry builds it from ``KEY=VALUE`` options (docs/plugins.md).
"""

from __future__ import annotations

import abc
from typing import ClassVar

import attrs
import numpy as np

from radartracker.errors import ConfigurationError
from radartracker.estimation.state import default_load_state_dict, default_state_dict

_positive = attrs.validators.gt(0.0)


@attrs.frozen
class MotionConfig:
    """Settings every motion model shares (each model derives its own ``*Config`` from this one).

    ``prior_sd_velocity_mps`` σ_v (m/s): a track starts from one position with velocity N(0, σ_v² I),
    and the TrackManager hands the bias estimator the same velocity prior; ``max_gap_s`` (s): the
    longest prediction a filter accepts (q Δt³ swamps double precision long before Δt = 10⁹ s).
    """

    prior_sd_velocity_mps: float = attrs.field(default=300.0, converter=float, validator=_positive)
    max_gap_s: float = attrs.field(default=3600.0, converter=float, validator=_positive)


class TrackFilter(abc.ABC):
    """Kinematic filter of one track in the plane (a ``radartracker.motion_models`` plugin).

    The TrackManager feeds it bias-corrected positions z (m) with covariance R (2×2) and reads
    predictions for gating. States are χ = [x, y, vx, vy]; a multiple-model filter reports the
    moment-matched mixture. ``start`` initialises from one position (velocity from the prior).
    ``config`` is an instance of the class's ``config_class`` (its defaults when none is given).
    """

    name: ClassVar[str] = "?"
    config_class: ClassVar[type[MotionConfig]] = MotionConfig

    def __init__(self, config: MotionConfig | None = None) -> None:
        config = config if config is not None else self.config_class()
        if not isinstance(config, self.config_class):
            raise ConfigurationError(f"motion model {self.name!r} takes a {self.config_class.__name__}, "
                                     f"not a {type(config).__name__}")
        self.config = config

    def state_dict(self) -> dict:
        """The filter's state as plain values, for snapshots (default: :mod:`radartracker.estimation.state`)."""
        return default_state_dict(self)

    def load_state_dict(self, state: dict) -> None:
        """Take back a :meth:`state_dict` into a filter built with the same config."""
        default_load_state_dict(self, state)

    @abc.abstractmethod
    def start(self, time: float, z: np.ndarray, R: np.ndarray) -> None:
        """Initialise at ``time`` (s) from position ``z`` (m, 2) with covariance ``R`` (m², 2×2)."""

    @abc.abstractmethod
    def predict(self, time: float) -> tuple[np.ndarray, np.ndarray]:
        """(χ, P) predicted to ``time`` without changing the filter."""

    @abc.abstractmethod
    def update(self, time: float, z: np.ndarray, R: np.ndarray) -> float:
        """Predict to ``time``, correct with position ``z`` (covariance ``R``); return the NIS νᵀΛ⁻¹ν."""

    @abc.abstractmethod
    def estimate(self) -> tuple[float, np.ndarray, np.ndarray]:
        """(time, χ, P) of the current estimate (copies)."""
