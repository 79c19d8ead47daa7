"""A radar's systematic errors as named components: the sensor error model (issue 30).

A radar's bias vector ς_j is a list of components, each with a zero-mean prior of standard deviation
``prior_sd``, a random-walk density ``drift`` (unit²/s; zero for a constant) and a column of the
measurement Jacobian. Seed 000 §1.1's model ``z = p + C_s ς + D w`` is generalised to

    z = p(t) + B ς_j + D w,   B = [b_1 … b_m]  (2 × m),   B evaluated at the plot,

with, for a plot at slant range ρ whose base Jacobian is C = ∂p/∂(ρ, θ) = [c_ρ, c_θ] (DESIGN §4)::

    range_offset    Δr  (m)      ρ_meas = ρ + Δr          b = c_ρ
    range_gain      g   (1)      ρ_meas = ρ (1 + g)       b = ρ c_ρ
    azimuth_offset  Δθ  (rad)    θ_meas = θ + Δθ          b = c_θ
    time_offset     τ   (s)      t_stamp = t_true + τ     b = −v   (v the aircraft's plane velocity)

Sign of the time offset: a plot stamped t was measured at t − τ, so z ≈ p(t − τ) = p(t) − v τ. The
column −v depends on the state: estimators linearise it at their predicted velocity v̄ (an EKF step,
with ∂z/∂v = −τ̄ I in the aircraft's columns and ẑ including −τ̄ v̄).

The first two components are always the range and azimuth offsets, in that order, so that
``BiasState.bias[:2]`` is today's [Δr, Δθ] whatever else a radar has; the others follow in the order
above. ``SensorModel.default`` is today's two-component model.
"""

from __future__ import annotations

from collections.abc import Iterable

import attrs
import numpy as np

from radartracker.errors import ConfigurationError

#: the components, in the order they take in a radar's bias vector, with their units
COMPONENTS: dict[str, str] = {"range_offset": "m", "azimuth_offset": "rad", "range_gain": "1", "time_offset": "s"}
BASE = ("range_offset", "azimuth_offset")
#: the default prior σ of the components beyond seed 000's two (``radartracker register``, the assessment's fit)
EXTRA_PRIOR_SD: dict[str, float] = {"range_gain": 1e-3, "time_offset": 0.5}


def _known(inst, attr, value: str) -> None:
    if value not in COMPONENTS:
        raise ConfigurationError(f"unknown bias component {value!r}; known: {', '.join(COMPONENTS)}")


def _non_negative_finite(inst, attr, value: float) -> None:
    if not (np.isfinite(value) and value >= 0.0):
        raise ConfigurationError(f"bias component {inst.name!r}: {attr.name} must be finite and >= 0, got {value!r}")


@attrs.frozen
class BiasComponent:
    """One named systematic error: prior N(0, ``prior_sd``²) and random-walk density ``drift`` (unit²/s)."""

    name: str = attrs.field(validator=_known)
    prior_sd: float = attrs.field(converter=float, validator=_non_negative_finite)
    drift: float = attrs.field(default=0.0, converter=float, validator=_non_negative_finite)

    @property
    def unit(self) -> str:
        return COMPONENTS[self.name]


def _ordered(components: Iterable[BiasComponent]) -> tuple[BiasComponent, ...]:
    comps = tuple(components)
    names = [c.name for c in comps]
    if len(set(names)) != len(names):
        raise ConfigurationError(f"sensor model: a component appears twice in {names}")
    if not set(BASE) <= set(names):
        raise ConfigurationError(f"sensor model: the first components must be {BASE} (given in any order), got {names}")
    order = list(COMPONENTS)
    return tuple(sorted(comps, key=lambda c: order.index(c.name)))


@attrs.frozen
class SensorModel:
    """The components of one radar's bias vector (see the module docstring for the equations)."""

    components: tuple[BiasComponent, ...] = attrs.field(converter=_ordered)

    @classmethod
    def default(cls, sd_range_m: float, sd_azimuth_rad: float, drift_range: float = 0.0,
                drift_azimuth: float = 0.0) -> SensorModel:
        """Seed 000's model: a range and an azimuth offset."""
        return cls((BiasComponent("range_offset", sd_range_m, drift_range),
                    BiasComponent("azimuth_offset", sd_azimuth_rad, drift_azimuth)))

    def with_components(self, *extra: BiasComponent) -> SensorModel:
        """This model with ``extra`` components added (e.g. a range gain and a time offset)."""
        return SensorModel(self.components + tuple(extra))

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(c.name for c in self.components)

    @property
    def size(self) -> int:
        return len(self.components)

    @property
    def extra(self) -> tuple[str, ...]:
        """The components beyond seed 000's two."""
        return self.names[2:]

    @property
    def drifts(self) -> bool:
        return any(c.drift > 0.0 for c in self.components)

    def index(self, name: str) -> int:
        return self.names.index(name)

    def prior(self) -> np.ndarray:
        """Prior covariance diag(σ_k²) of the bias vector."""
        return np.diag([c.prior_sd**2 for c in self.components])

    def drift(self, dt: float) -> np.ndarray:
        """Random-walk covariance diag(q_k)·dt added over ``dt`` seconds."""
        return np.diag([c.drift for c in self.components]) * max(dt, 0.0)

    def jacobian(self, C: np.ndarray, rho: float, velocity: np.ndarray | None) -> np.ndarray:
        """B = ∂z/∂ς (2 × m) of a plot with base Jacobian ``C`` = ∂p/∂(ρ, θ), slant range ``rho`` (needed by a
        range gain) and aircraft plane ``velocity`` (needed by a time offset)."""
        v = None if velocity is None else np.asarray(velocity, float)[None]
        return self.jacobians(np.asarray(C, float)[None], np.array([rho], float), v)[0]

    def jacobians(self, C: np.ndarray, rho: np.ndarray, velocity: np.ndarray | None) -> np.ndarray:
        """B (n × 2 × m) of n plots (module docstring): base Jacobians ``C`` (n × 2 × 2), slant ranges ``rho``
        (n; needed by a range gain) and the aircraft's plane velocities ``velocity`` (n × 2; needed by a time
        offset)."""
        B = np.empty((len(C), 2, self.size))
        for k, name in enumerate(self.names):
            if name == "range_offset":
                B[:, :, k] = C[:, :, 0]
            elif name == "azimuth_offset":
                B[:, :, k] = C[:, :, 1]
            elif name == "range_gain":
                if not np.all(np.isfinite(rho)):
                    raise ValueError("a range gain needs the plot's slant range (PlaneMeasurement.rho)")
                B[:, :, k] = rho[:, None] * C[:, :, 0]
            else:
                if velocity is None or not np.all(np.isfinite(velocity)):
                    raise ValueError("a time offset needs the aircraft's velocity at the plot")
                B[:, :, k] = -velocity
        return B
