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
from radartracker.estimation.screening import bias_corrected, position_d2
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

    def screen(self, time: float, z: np.ndarray, C: np.ndarray, R: np.ndarray, bias: np.ndarray,
               bias_cov: np.ndarray, gate: float | None = None) -> tuple[float, np.ndarray, np.ndarray, bool]:
        """Innovation screening of a measurement of a sensor with bias estimate (ς̂, P_ς), and its update
        when it passes ``gate``: (d², z_c, R_c, updated) with (float arrays; C = 0 for an unbiased sensor)::

            z_c = z − C ς̂,  R_c = R + C P_ς Cᵀ,  d² = (z_c − p̄)ᵀ (P̄_pp + R_c)⁻¹ (z_c − p̄)

        (p̄, P̄_pp) the position part of :meth:`predict` to ``time``, d² = ∞ if the sum is not positive
        definite (:mod:`radartracker.estimation.screening`). If d² ≤ ``gate`` the filter is updated,
        ``update(time, z_c, R_c)``, ``updated`` is True and z_c, R_c may be None (the caller has no further
        use for them); else (or with no gate) it is unchanged and the caller may update it later with
        (z_c, R_c), which are then arrays. Raises what ``predict`` and ``update`` raise.
        This default is built on ``predict`` and ``update``; a model may override it, e.g. with one
        compiled call that predicts once for both.
        """
        zc, Rc = bias_corrected(z, C, R, bias, bias_cov)
        x, P = self.predict(time)
        d2 = position_d2(zc, Rc, np.ascontiguousarray(x[:2], float), np.ascontiguousarray(P[:2, :2], float))
        if gate is not None and d2 <= gate:
            self.update(time, zc, Rc)
            return d2, zc, Rc, True
        return d2, zc, Rc, False
