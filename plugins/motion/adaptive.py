"""Covariance-scaling filters: seed 004's EUROCAT-X filter (``adaptive``) and fading memory (``fading``).

Both predict the state with the constant-velocity A(Δt) and scale the extrapolated covariance
P_a = A P̂ Aᵀ::

    adaptive (seed 004 eq. 9):  P̄ = α P_a + β Q_m,   α + β = 1,  Q_m = Q(Δt) of density q_m
    fading memory:              P̄ = λ P_a + Q,       λ ≥ 1,      Q = Q(Δt) of density q

How α (β = 1 − α) and λ are chosen, the same for both. Each update adds its NIS εₖ = νᵀΛ⁻¹ν to a
window of the last N; when the window is full its sum s is tested against χ²(2N), the law of s for
a consistent filter (2 = measurement dimension). Inside the two-sided interval [χ²_{p/2}, χ²_{1−p/2}]
nothing changes. Outside it the innovations are s/(2N) times too large (or small), so the target
inflation κ of the predicted innovation covariance is rescaled, κ ← clip(κ · s/(2N), 1, κ_max), and
the window restarts (one piece of evidence acts once). At each prediction the parameter is then the
one whose innovation covariance has κ times the trace of the nominal one (β = β_min, λ = 1), with
the R of the last update standing in for the next one::

    tr(H P̄(θ) Hᵀ) + tr R = κ (tr(H P̄(θ_nom) Hᵀ) + tr R)      (linear in θ = β or λ)

The convex family P̄(β) = P_a + β (Q_m − P_a) only reaches innovation covariances between those of
P_a and Q_m: where Q_m ≺ P_a (short Δt, or a large P̂) inflating needs α > 1, i.e. β < 0, and
P̄ = α P_a − |β| Q_m is positive definite only while |β| Q_m ≺ α P_a. By default β is clipped to
[β_min, β_max] ⊂ [0, 1]; ``allow_negative_beta`` lets β go below 0, halving |β| from the matching
value until P̄ keeps a Cholesky factor with margin (P̄ ⪰ ½ α P_a is what is checked). ``docs/tracking.md`` compares
this with the fading factor, which inflates P_a without touching Q.

Settings (:class:`AdaptiveConfig`, :class:`FadingConfig`; both: ``window`` N (5), ``significance`` p
(0.05), ``kappa_max`` (100)); fixed values ``fixed_alpha`` (adaptive, β = 1 − α) or ``fixed_lambda``
(fading) switch the adaptation off. adaptive only: ``q_manoeuvre`` q_m (m²/s³, default 400 ≈ a²T for
a 3°/s turn at 200 m/s, a ≈ 10 m/s², over a T = 4 s scan), ``beta_min`` (0.02), ``beta_max`` (1),
``allow_negative_beta`` (False); fading only: ``q`` (m²/s³, 1).
"""

from __future__ import annotations

import attrs
import numpy as np

from radartracker.api import ConfigurationError, MotionConfig, MotionModel, TrackFilter, symmetrize
from radartracker_plugins.motion.base import check_measurement, check_time, position_update, require_started, start_state

_v = attrs.validators
_optional_float = attrs.converters.optional(float)


@attrs.frozen
class ScaledConfig(MotionConfig):
    """The NIS-window rule shared by ``adaptive`` and ``fading``: window N, two-sided significance p
    of the χ²(2N) test, and the largest inflation κ_max of the innovation covariance."""

    window: int = attrs.field(default=5, converter=int, validator=_v.ge(1))
    significance: float = attrs.field(default=0.05, converter=float, validator=[_v.gt(0.0), _v.lt(1.0)])
    kappa_max: float = attrs.field(default=100.0, converter=float, validator=_v.ge(1.0))


@attrs.frozen
class AdaptiveConfig(ScaledConfig):
    """Settings of ``adaptive``: P̄ = α P_a + β Q_m with Q_m of density ``q_manoeuvre`` (m²/s³) and
    β ∈ [``beta_min``, ``beta_max``] (β < 0 allowed by ``allow_negative_beta``); ``fixed_alpha`` fixes α."""

    q_manoeuvre: float = attrs.field(default=400.0, converter=float, validator=_v.ge(0.0))
    beta_min: float = attrs.field(default=0.02, converter=float)
    beta_max: float = attrs.field(default=1.0, converter=float)
    allow_negative_beta: bool = attrs.field(default=False, validator=_v.instance_of(bool))
    fixed_alpha: float | None = attrs.field(default=None, converter=_optional_float)

    def __attrs_post_init__(self) -> None:
        if not 0.0 <= self.beta_min <= self.beta_max <= 1.0:
            raise ConfigurationError(f"AdaptiveConfig: need 0 ≤ beta_min ≤ beta_max ≤ 1, got {self.beta_min}, {self.beta_max}")


@attrs.frozen
class FadingConfig(ScaledConfig):
    """Settings of ``fading``: P̄ = λ P_a + Q with Q of density ``q`` (m²/s³); ``fixed_lambda`` fixes λ."""

    q: float = attrs.field(default=1.0, converter=float, validator=_v.ge(0.0))
    fixed_lambda: float | None = attrs.field(default=None, converter=_optional_float)


class _ScaledCV(TrackFilter):
    """Constant-velocity Kalman filter whose predicted covariance is scaled from the NIS window."""

    def __init__(self, config: ScaledConfig | None = None) -> None:
        super().__init__(config)
        self.window, sig = self.config.window, self.config.significance
        from scipy.stats import chi2  # here: scipy.stats costs 0.3 s to import, listing the plugins none

        self.bounds = (chi2.ppf(sig / 2, 2 * self.window), chi2.ppf(1 - sig / 2, 2 * self.window))
        self.kappa_max = self.config.kappa_max
        self.time: float | None = None
        self.x, self.P = np.zeros(4), np.eye(4)
        self.R = np.eye(2)
        self.kappa = 1.0
        self.nis: list[float] = []
        self.theta = self.nominal

    # subclass interface: the covariance family P̄(θ) and its admissible θ
    nominal: float

    def _family(self, Pa: np.ndarray, dt: float, theta: float) -> np.ndarray:
        raise NotImplementedError

    def _fixed(self) -> float | None:
        raise NotImplementedError

    def _clip(self, theta: float, Pa: np.ndarray, dt: float) -> float:
        raise NotImplementedError

    def _choose(self, Pa: np.ndarray, dt: float) -> float:
        """θ with tr(H P̄(θ) Hᵀ) + tr R = κ (tr(H P̄(θ_nom) Hᵀ) + tr R), clipped."""
        fixed = self._fixed()
        if fixed is not None:
            return fixed
        if self.kappa == 1.0:
            return self.nominal
        t0 = np.trace(self._family(Pa, dt, 0.0)[:2, :2])
        t1 = np.trace(self._family(Pa, dt, 1.0)[:2, :2]) - t0
        r = np.trace(self.R)
        nominal = t0 + self.nominal * t1 + r
        if abs(t1) <= 1e-12 * max(nominal, 1.0):
            return self.nominal
        return self._clip((self.kappa * nominal - r - t0) / t1, Pa, dt)

    def _prior(self, time: float) -> tuple[np.ndarray, np.ndarray, float]:
        dt = time - self.time
        A = MotionModel(0.0).transition(dt)[0]
        Pa = A @ self.P @ A.T
        theta = self._choose(Pa, dt)
        return A @ self.x, symmetrize(self._family(Pa, dt, theta)), theta

    # --- TrackFilter -----------------------------------------------------------------------------
    def start(self, time: float, z: np.ndarray, R: np.ndarray) -> None:
        self.time, z, self.R = check_measurement(time, z, R)
        self.x, self.P = start_state(z, self.R, self.config.prior_sd_velocity_mps)
        self.kappa, self.nis, self.theta = 1.0, [], self.nominal

    def predict(self, time: float) -> tuple[np.ndarray, np.ndarray]:
        x, P, _ = self._prior(check_time(time, self.time, self.config.max_gap_s))
        return x, P

    def update(self, time: float, z: np.ndarray, R: np.ndarray) -> float:
        time, z, R = check_measurement(time, z, R)
        check_time(time, self.time, self.config.max_gap_s)
        x, P, theta = self._prior(time)
        step = position_update(x, P, z, R)
        self.time, self.x, self.P, self.R, self.theta = time, step.x, step.P, R, theta
        self.nis.append(step.nis)
        if len(self.nis) == self.window:
            s = sum(self.nis)
            self.nis = []
            if not self.bounds[0] <= s <= self.bounds[1]:
                self.kappa = float(np.clip(self.kappa * s / (2 * self.window), 1.0, self.kappa_max))
        return step.nis

    def estimate(self) -> tuple[float, np.ndarray, np.ndarray]:
        require_started(self.time)
        return self.time, self.x.copy(), self.P.copy()


class AdaptiveFilter(_ScaledCV):
    """Seed 004's EUROCAT-X filter: P̄ = α A P̂ Aᵀ + β Q_m, α + β = 1, β from the NIS window."""

    name = "adaptive"
    config_class = AdaptiveConfig

    def __init__(self, config: AdaptiveConfig | None = None) -> None:
        super().__init__(config)
        c = self.config
        self.model = MotionModel(c.q_manoeuvre)
        self.beta_min, self.beta_max, self.negative = c.beta_min, c.beta_max, c.allow_negative_beta

    @property
    def nominal(self) -> float:
        return self.config.beta_min

    def _fixed(self) -> float | None:
        return None if self.config.fixed_alpha is None else 1.0 - self.config.fixed_alpha

    def _family(self, Pa: np.ndarray, dt: float, beta: float) -> np.ndarray:
        return (1.0 - beta) * Pa + beta * self.model.transition(dt)[1]

    def _clip(self, beta: float, Pa: np.ndarray, dt: float) -> float:
        if beta >= self.beta_min or not self.negative:
            return float(np.clip(beta, self.beta_min, self.beta_max))
        # β < 0: P̄ − ½ α P_a = ½ α P_a − |β| Q_m must stay positive definite; halve |β| until it does
        while beta < -1e-6:
            try:
                np.linalg.cholesky(0.5 * (1.0 - beta) * Pa + beta * self.model.transition(dt)[1])
                return float(beta)
            except np.linalg.LinAlgError:
                beta *= 0.5
        return 0.0

    @property
    def alpha_beta(self) -> tuple[float, float]:
        """(α, β) of the last prediction used in an update."""
        return 1.0 - self.theta, self.theta


class FadingFilter(_ScaledCV):
    """Fading-memory filter: P̄ = λ A P̂ Aᵀ + Q, λ ≥ 1 from the NIS window (or fixed)."""

    name = "fading"
    config_class = FadingConfig
    nominal = 1.0

    def __init__(self, config: FadingConfig | None = None) -> None:
        super().__init__(config)
        self.model = MotionModel(self.config.q)

    def _fixed(self) -> float | None:
        return self.config.fixed_lambda

    def _family(self, Pa: np.ndarray, dt: float, lam: float) -> np.ndarray:
        return lam * Pa + self.model.transition(dt)[1]

    def _clip(self, lam: float, Pa: np.ndarray, dt: float) -> float:
        return float(max(lam, 1.0))
