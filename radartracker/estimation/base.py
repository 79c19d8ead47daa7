"""The estimator contract: what an estimator plugin implements (DESIGN §4–5).

An *estimator* receives associated measurements already converted to the system plane
(:class:`PlaneMeasurement`) and keeps the aircraft states and the radar biases. The observation
model it must honour is seed 000 eq. 1.5/1.11 (DESIGN §4)::

    z = C_x χ_i + C_s ς_j + D w,   C_x = [I 0],   R = D W Dᵀ

where ``C_s`` and ``R`` come with the measurement (``C_s = 0`` for unbiased sources such as ADS-B).
Aircraft states are χ = [x, y, vx, vy] (metres, m/s, x east, y north); a bias is ς = [Δr, Δθ]
(metres, radians). Each aircraft has its own epoch: an estimator predicts an aircraft only when a
measurement of it arrives.
"""

from __future__ import annotations

import abc
from collections.abc import Container, Hashable, Sequence
from typing import ClassVar, NamedTuple

import attrs
import numpy as np

from radartracker.domain import BiasState
from radartracker.errors import ConfigurationError
from radartracker.estimation.motion import MotionModel
from radartracker.estimation.sensor import SensorModel
from radartracker.estimation.state import default_load_state_dict, default_state_dict


@attrs.frozen
class EstimatorConfig:
    """Settings shared by every estimator.

    ``motion`` is the aircraft motion model (constant velocity with optional white-acceleration
    noise, seed 000 eq. 1.4). Bias priors are zero-mean with the given standard deviations
    (seed eq. 1.7: constant biases); ``bias_drift_*`` are random-walk spectral densities
    (m²/s and rad²/s) for slowly drifting biases — zero by default, as in the seed.

    ``sensors`` maps a radar id to its :class:`~radartracker.estimation.sensor.SensorModel` (range gain,
    time offset, per-component priors and drifts); a radar not named there has the two-component model
    built from the four numbers above (:meth:`sensor`).
    """

    motion: MotionModel = attrs.field(factory=MotionModel)
    bias_sd_range_m: float = 500.0
    bias_sd_azimuth_rad: float = float(np.radians(0.5))
    bias_drift_range: float = 0.0
    bias_drift_azimuth: float = 0.0
    sensors: dict[str, SensorModel] = attrs.field(factory=dict, converter=dict, hash=False,
                                                  validator=attrs.validators.deep_mapping(
                                                      attrs.validators.instance_of(str),
                                                      attrs.validators.instance_of(SensorModel)))

    def sensor(self, radar: str) -> SensorModel:
        """The sensor error model of ``radar``: its entry in ``sensors``, else seed 000's two components."""
        model = self.sensors.get(radar)
        return model if model is not None else self.default_sensor

    @property
    def default_sensor(self) -> SensorModel:
        """Seed 000's two components with this config's priors and drifts."""
        return SensorModel.default(self.bias_sd_range_m, self.bias_sd_azimuth_rad, self.bias_drift_range,
                                   self.bias_drift_azimuth)

    def require_two_components(self, estimator: str, radar: str) -> None:
        """For an estimator that carries seed 000's model only: a one-line ConfigurationError if ``radar`` has a
        component beyond the range and azimuth offsets, or priors and drifts other than this config's numbers."""
        model = self.sensor(radar)
        if model.extra:
            raise ConfigurationError(f"estimator {estimator!r} does not support bias component {model.extra[0]!r} "
                                     f"(radar {radar!r}): use 'coupled'")
        if model != self.default_sensor:
            raise ConfigurationError(f"estimator {estimator!r} takes the bias priors and drifts of EstimatorConfig, "
                                     f"not radar {radar!r}'s own sensor model: use 'coupled'")

    def bias_prior(self) -> np.ndarray:
        """Prior covariance of one radar's bias [Δr, Δθ]."""
        return np.diag([self.bias_sd_range_m**2, self.bias_sd_azimuth_rad**2])

    def bias_drift(self, dt: float) -> np.ndarray:
        """Random-walk covariance added to one radar's bias over ``dt`` seconds."""
        return np.diag([self.bias_drift_range, self.bias_drift_azimuth]) * max(dt, 0.0)

    @property
    def bias_drifts(self) -> bool:
        return self.bias_drift_range > 0.0 or self.bias_drift_azimuth > 0.0 or any(
            m.drifts for m in self.sensors.values())


@attrs.frozen(slots=True)
class PlaneMeasurement:
    """One associated measurement in the system plane.

    ``radar`` is the radar id, or ``None`` for an unbiased position (ADS-B, triangulation);
    ``C`` is the bias Jacobian C_s (2×2, ∂z/∂[Δr, Δθ]) and ``R`` the noise covariance D W Dᵀ; ``rho`` the
    plot's slant range (m), which a radar with a range gain needs (its column is ρ·∂z/∂ρ).
    """

    time: float
    aircraft: Hashable
    radar: str | None
    z: np.ndarray
    C: np.ndarray
    R: np.ndarray
    rho: float = float("nan")


class Innovation(NamedTuple):
    """What an update saw: ν = z − h(ξ̄), its covariance Λ, and ν'Λ⁻¹ν (NIS)."""

    nu: np.ndarray
    S: np.ndarray
    nis: float


@attrs.frozen
class AircraftEstimate:
    """An aircraft's state estimate χ̂ = [x, y, vx, vy] and covariance at ``time``."""

    time: float
    state: np.ndarray
    cov: np.ndarray


class Estimator(abc.ABC):
    """Interface of every bias/motion estimator plugin.

    Lifecycle: ``add_radar`` for each radar, ``add_aircraft`` when a track starts (the prior is
    the caller's), ``update`` for each associated measurement in time order (or ``update_many`` of a
    batch of them, the same updates in turn), ``remove_aircraft`` when a track ends. Reads never modify
    the state.

    A plugin with options names an attrs class in ``options_class`` (its fields' defaults are the
    defaults); the instance is ``self.options``, built by the registry from ``KEY=VALUE`` strings.
    """

    name: ClassVar[str] = "?"
    options_class: ClassVar[type | None] = None

    def __init__(self, config: EstimatorConfig | None = None, options: object | None = None) -> None:
        self.config = config if config is not None else EstimatorConfig()
        if self.options_class is None:
            if options is not None:
                raise ConfigurationError(f"estimator {self.name!r} takes no options")
            self.options = None
        else:
            self.options = options if options is not None else self.options_class()
            if not isinstance(self.options, self.options_class):
                raise ConfigurationError(f"estimator {self.name!r} takes a {self.options_class.__name__}, "
                                         f"not a {type(self.options).__name__}")

    def state_dict(self) -> dict:
        """The state as plain values, for snapshots (default: :mod:`radartracker.estimation.state`)."""
        return default_state_dict(self)

    def load_state_dict(self, state: dict) -> None:
        """Take back a :meth:`state_dict` into an estimator built with the same config and radars. The state
        is untrusted input (it comes from a file): everything is checked before anything is changed, and a
        state that does not fit raises :class:`~radartracker.errors.InputError` naming what is wrong."""
        default_load_state_dict(self, state)

    @abc.abstractmethod
    def add_radar(self, radar: str) -> None:
        """Start estimating the bias of ``radar`` from the configured prior."""

    @abc.abstractmethod
    def add_aircraft(self, key: Hashable, time: float, state: np.ndarray, cov: np.ndarray) -> None:
        """Start estimating aircraft ``key`` with prior N(state, cov) at ``time``."""

    @abc.abstractmethod
    def remove_aircraft(self, key: Hashable) -> None:
        """Stop estimating aircraft ``key`` (its information on the biases is kept)."""

    @abc.abstractmethod
    def update(self, m: PlaneMeasurement) -> Innovation:
        """Predict the measured aircraft (and drifting biases) to ``m.time`` and correct."""

    def update_many(self, time: Sequence[float], aircraft: Sequence[Hashable], radar: Sequence[str | None],
                    z: np.ndarray, C: np.ndarray, R: np.ndarray) -> Innovation:
        """:meth:`update` of each measurement of a time-ordered batch given as columns (the fields of
        PlaneMeasurement, stacked), in turn. A plugin writes its update once: in :meth:`update` (this default
        applies a batch), or here, for a compiled batch, with :meth:`update` a batch of one
        (``coupled-sparse`` does).

        Returns an Innovation of stacked arrays (ν n×2, Λ n×2×2, NIS n). If measurement i fails, those
        before it have been applied and the exception carries ``index = i``.
        """
        nu, lam, nis = [], [], []
        for i in range(len(time)):
            m = PlaneMeasurement(float(time[i]), aircraft[i], radar[i], np.asarray(z[i], float),
                                 np.asarray(C[i], float), np.asarray(R[i], float))
            try:
                inn = self.update(m)
            except Exception as exc:  # any failure names its measurement
                exc.index = i
                raise
            nu.append(inn.nu), lam.append(inn.S), nis.append(inn.nis)
        return Innovation(np.reshape(nu, (-1, 2)), np.reshape(lam, (-1, 2, 2)), np.asarray(nis, float))

    @abc.abstractmethod
    def aircraft(self, key: Hashable) -> AircraftEstimate:
        """The current estimate of aircraft ``key`` at its own epoch."""

    @abc.abstractmethod
    def bias(self, radar: str) -> BiasState:
        """The current bias estimate of ``radar``."""

    @property
    @abc.abstractmethod
    def aircraft_keys(self) -> list[Hashable]:
        """Keys of the aircraft being estimated."""

    @property
    @abc.abstractmethod
    def radars(self) -> list[str]:
        """Ids of the radars whose biases are estimated."""

    def predict(self, key: Hashable, time: float) -> AircraftEstimate:
        """The estimate of aircraft ``key`` predicted to ``time``, without changing the state."""
        est = self.aircraft(key)
        A, Q = self.config.motion.transition(time - est.time)
        return AircraftEstimate(time, A @ est.state, A @ est.cov @ A.T + Q)

def require_new_radar(radar: str, added: Container[str]) -> None:
    """:meth:`Estimator.add_radar`'s contract: ValueError if ``radar`` is among the radars ``added`` already."""
    if radar in added:
        raise ValueError(f"radar {radar!r} already added")


def validated_prior(key: Hashable, state: np.ndarray, cov: np.ndarray,
                    estimated: Container[Hashable] = ()) -> tuple[np.ndarray, np.ndarray]:
    """An aircraft prior for :meth:`Estimator.add_aircraft` as float arrays, checked (``key`` not among the
    aircraft ``estimated`` already; a finite 4-vector and 4×4), copied and symmetrised."""
    if key in estimated:
        raise ValueError(f"aircraft {key!r} already estimated")
    state, cov = np.array(state, float), np.asarray(cov, float)  # the state a copy, the covariance made anew below
    if state.shape != (4,) or cov.shape != (4, 4) or not (np.isfinite(state).all() and np.isfinite(cov).all()):
        raise ValueError(f"aircraft {key!r}: prior must be a finite 4-vector and 4×4 covariance")
    return state, 0.5 * (cov + cov.T)
