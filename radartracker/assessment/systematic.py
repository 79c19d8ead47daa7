"""A radar's sensor errors fitted to its residuals against the reference: range offset, azimuth offset, range
gain and time-stamp offset (issue 31; the components of :mod:`radartracker.estimation.sensor`).

A matched plot stamped t, at the reference's slant range, azimuth and their rates ρ_ref, θ_ref, ρ̇, θ̇ there,
has to first order the residuals

    u_ρ = ρ − ρ_ref(t) = Δr + g ρ_ref − τ ρ̇ + e_ρ,     e_ρ ~ N(0, σ_ρ²)
    u_θ = θ − θ_ref(t) = Δθ           − τ θ̇ + e_θ,     e_θ ~ N(0, σ_θ²)

(a plot stamped t was measured at t − τ). With x = [Δr, Δθ, g, τ] and rows a_ρ = [1, 0, ρ_ref, −ρ̇],
a_θ = [0, 1, 0, −θ̇], the sums F_k = Σ a aᵀ, b_k = Σ a u, s_k = Σ u² and n_k of each axis k are all the fit
needs, and add up over the time slices of a recording (:class:`SensorSums`). For given σ's, under the
components' zero-mean priors Λ₀⁻¹ = diag(σ₀²) (:data:`FIT_MODEL`),

    P = (F_ρ/σ_ρ² + F_θ/σ_θ² + Λ₀)⁻¹,    x̂ = P (b_ρ/σ_ρ² + b_θ/σ_θ²),

and P is the Cramér–Rao bound of x from these plots; the σ's are then σ_k² = RSS_k(x̂)/(n_k − p_k), with
RSS_k(x) = s_k − 2 xᵀb_k + xᵀF_k x and p_ρ = 3, p_θ = 2 the components in each axis's rows, iterated from the
residuals' raw variances to a fixed point. A component keeps the status its variance gives it against its
prior (:class:`radartracker.estimation.bound.ComponentBound`): a time offset on traffic that is neither
moving in range nor in azimuth, or a range gain on plots all at one range, is ``unobservable`` and not
reported as a figure.

The residuals the fit leaves, e_k = u_k − a_kᵀx̂, have the means and second moments (:func:`residual_moments`)

    Σ e_ρ = b_ρ,0 − x̂ᵀF_ρ,·0,    Σ e_θ = b_θ,1 − x̂ᵀF_θ,·1,    Σ e_k² = RSS_k(x̂),
    Σ e_ρ e_θ = c − x̂ᵀ(d_ρθ + d_θρ) + x̂ᵀ G x̂,

(a_ρ,0 = a_θ,1 = 1 pick Σ a and Σ u out of F and b) with the cross sums G = Σ a_ρ a_θᵀ, d_ρθ = Σ a_ρ u_θ,
d_θρ = Σ a_θ u_ρ and c = Σ u_ρ u_θ, which add over the slices as the others do. Their mean m = Σ e / n and
covariance C = (Σ e eᵀ − n m mᵀ)/(n − 1) (the report's error ellipse) are so made from sums, not from the
residuals themselves.
"""

from __future__ import annotations

import math

import attrs
import numpy as np

from radartracker.estimation.base import EstimatorConfig
from radartracker.estimation.bound import ComponentBound
from radartracker.estimation.sensor import EXTRA_PRIOR_SD, BiasComponent, SensorModel

_DEFAULT = EstimatorConfig()
#: the components fitted, with the priors the joint estimators and ``radartracker register`` use by default
FIT_MODEL = SensorModel.default(_DEFAULT.bias_sd_range_m, _DEFAULT.bias_sd_azimuth_rad).with_components(
    *(BiasComponent(name, sd) for name, sd in EXTRA_PRIOR_SD.items()))
_PER_AXIS = (3, 2)  # components in the range rows and in the azimuth rows
_ITERATIONS = 8


@attrs.define
class SensorSums:
    """Per axis (0 range, 1 azimuth): F = Σ a aᵀ (2 × 4 × 4), b = Σ a u (2 × 4), s = Σ u² (2) and the count n;
    across the axes G = Σ a_ρ a_θᵀ (4 × 4), d = [Σ a_ρ u_θ, Σ a_θ u_ρ] (2 × 4) and c = Σ u_ρ u_θ (module
    docstring), in the order of :data:`FIT_MODEL`'s components; added exactly by :meth:`merge`."""

    F: np.ndarray = attrs.field(factory=lambda: np.zeros((2, 4, 4)))
    b: np.ndarray = attrs.field(factory=lambda: np.zeros((2, 4)))
    s: np.ndarray = attrs.field(factory=lambda: np.zeros(2))
    n: int = 0
    G: np.ndarray = attrs.field(factory=lambda: np.zeros((4, 4)))
    d: np.ndarray = attrs.field(factory=lambda: np.zeros((2, 4)))
    c: float = 0.0

    @classmethod
    def of(cls, u_range: np.ndarray, u_azimuth: np.ndarray, rho_ref: np.ndarray, rho_rate: np.ndarray,
           theta_rate: np.ndarray) -> SensorSums:
        """The sums of plots with residuals ``u_range`` (m), ``u_azimuth`` (rad) at the reference's slant range
        and rates (those with a non-finite value left out)."""
        ok = np.isfinite(u_range) & np.isfinite(u_azimuth) & np.isfinite(rho_ref) & np.isfinite(rho_rate) \
            & np.isfinite(theta_rate)
        rows = design_rows(rho_ref[ok], rho_rate[ok], theta_rate[ok])
        u = (u_range[ok], u_azimuth[ok])
        return cls(np.stack([a.T @ a for a in rows]), np.stack([a.T @ v for a, v in zip(rows, u)]),
                   np.array([v @ v for v in u]), int(ok.sum()), rows[0].T @ rows[1],
                   np.stack([rows[0].T @ u[1], rows[1].T @ u[0]]), float(u[0] @ u[1]))

    def merge(self, other: SensorSums) -> SensorSums:
        return SensorSums(self.F + other.F, self.b + other.b, self.s + other.s, self.n + other.n,
                          self.G + other.G, self.d + other.d, self.c + other.c)


def design_rows(rho_ref: np.ndarray, rho_rate: np.ndarray, theta_rate: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The rows a_ρ = [1, 0, ρ_ref, −ρ̇] and a_θ = [0, 1, 0, −θ̇] of each plot (n × 4 each; module docstring)."""
    one, zero = np.ones(len(rho_ref)), np.zeros(len(rho_ref))
    return (np.stack([one, zero, rho_ref, -rho_rate], axis=1), np.stack([zero, one, zero, -theta_rate], axis=1))


@attrs.frozen
class SensorFit:
    """The fit of :func:`fit_sensor_errors`: ``estimate`` x̂ and ``cov`` P (module docstring, in
    :data:`FIT_MODEL`'s order), each axis's residual sum of squares ``rss`` and degrees of freedom ``dof``
    (the random errors :attr:`sigma`), and each component's ``bounds`` (√P_kk against its prior σ: its
    observability)."""

    estimate: np.ndarray
    cov: np.ndarray
    rss: tuple[float, float]
    dof: tuple[int, int]
    bounds: tuple[ComponentBound, ...]

    @property
    def sigma(self) -> tuple[float, float]:
        """σ_ρ (m) and σ_θ (rad): √(RSS/ν) of each axis."""
        return math.sqrt(self.rss[0] / self.dof[0]), math.sqrt(self.rss[1] / self.dof[1])

    def component(self, name: str) -> tuple[float, float, str]:
        """(estimate, σ, status) of component ``name``."""
        k = FIT_MODEL.index(name)
        return float(self.estimate[k]), float(math.sqrt(self.cov[k, k])), self.bounds[k].status


def fit_sensor_errors(radar: str, sums: SensorSums) -> SensorFit | None:
    """The fit of the module docstring from ``sums`` (None with too few plots to estimate the σ's)."""
    dof = (sums.n - _PER_AXIS[0], sums.n - _PER_AXIS[1])
    if min(dof) < 2:
        return None
    rss = (sums.s - sums.b[:, :2].diagonal() ** 2 / sums.n) * np.array(dof) / (sums.n - 1)  # about the means
    for _ in range(_ITERATIONS):
        x, P = _weighted(sums, np.maximum(rss, 0.0) / np.array(dof) + 1e-300)
        rss = np.array([sums.s[k] - 2.0 * x @ sums.b[k] + x @ sums.F[k] @ x for k in (0, 1)])
    x, P = _weighted(sums, np.maximum(rss, 0.0) / np.array(dof) + 1e-300)
    bounds = tuple(ComponentBound(radar, c.name, float(math.sqrt(P[k, k])), c.prior_sd)
                   for k, c in enumerate(FIT_MODEL.components))
    return SensorFit(x, P, (float(max(rss[0], 0.0)), float(max(rss[1], 0.0))), dof, bounds)


def _weighted(sums: SensorSums, var: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(x̂, P) for the axes' variances ``var`` (module docstring): P = (F_ρ/σ_ρ² + F_θ/σ_θ² + Λ₀)⁻¹."""
    M = sums.F[0] / var[0] + sums.F[1] / var[1] + np.diag(1.0 / np.diag(FIT_MODEL.prior()))
    return _solve(M, sums.b[0] / var[0] + sums.b[1] / var[1])


def _solve(M: np.ndarray, rhs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(M⁻¹ rhs, M⁻¹) for the symmetric positive definite M, through its diagonal scaling (the components'
    units differ by ten orders of magnitude)."""
    d = 1.0 / np.sqrt(np.diag(M))
    inv = np.linalg.inv(M * np.outer(d, d)) * np.outer(d, d)
    return inv @ rhs, 0.5 * (inv + inv.T)


def residual_moments(sums: SensorSums, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The mean m (2: e_ρ m, e_θ rad) and the covariance about it, C = (Σ e eᵀ − n m mᵀ)/(n − 1) (2 × 2), of the
    residuals e = (u_ρ − a_ρᵀx, u_θ − a_θᵀx) that the sensor errors ``x`` (the fit's x̂) leave, from ``sums``
    alone (module docstring); needs n ≥ 2."""
    total = np.array([sums.b[0, 0] - x @ sums.F[0, :, 0], sums.b[1, 1] - x @ sums.F[1, :, 1]])
    square = [sums.s[k] - 2.0 * x @ sums.b[k] + x @ sums.F[k] @ x for k in (0, 1)]
    cross = sums.c - x @ (sums.d[0] + sums.d[1]) + x @ sums.G @ x
    m = total / sums.n
    S = np.array([[square[0], cross], [cross, square[1]]])
    return m, (S - sums.n * np.outer(m, m)) / (sums.n - 1)
