"""A radar's random errors drawn as the report's error scatter: the residuals against the reference of its
matched plots, the fitted sensor errors removed (:mod:`radartracker.assessment.systematic`), in the radar's
own coordinates — range error e_ρ (m) against azimuth error e_θ (deg), where its stated σ_r, σ_θ
(radars.csv) and the 1997 EUROCONTROL standard's limits are expressed — with two 95 % ellipses:

* **measured**: the covariance C of the residuals about their mean m (:func:`residual_moments`, from the
  fit's sums only, so it adds over the time slices), the points p with (p − m)ᵀ C⁻¹ (p − m) = χ²₂(0.95)
  = −2 ln 0.05 = 5.991: p = m + √5.991 V Λ^½ [cos t, sin t]ᵀ, C = V Λ Vᵀ;
* **stated** (dashed): the same for diag(σ_r², σ_θ²), centred on m, what the radar should show.

A cross-range error ρ e_θ in metres would make the azimuth error's ellipse grow with each plot's range: over
plots at 10 km and at 200 km it describes none of them, and no stated σ gives it. Their correlation
r = C_ρθ / √(C_ρρ C_θθ) is a figure (``range_azimuth_correlation``, Fisher's z interval): a time-stamp
error on crossing traffic, or an error of the reference, couples the two axes; the radar's own noise does not.

The points drawn are a bounded sample (:class:`ErrorSample`): at most :data:`SAMPLE_SIZE` plots per radar
whatever the recording's length, those of least hash key κ(t, u_ρ) of their time stamp and range residual —
a sample of equally likely plots, the same whichever time slices the plots were summed in, since the least k keys of
a union are the least k of each part's least k.
"""

from __future__ import annotations

import math

import attrs
import numpy as np

from radartracker.assessment import stats
from radartracker.assessment.stats import Estimate
from radartracker.assessment.systematic import SensorFit, SensorSums, design_rows, residual_moments
from radartracker.domain import Radar

SAMPLE_SIZE = 2000
LEVEL_RADIUS = math.sqrt(-2.0 * math.log(1.0 - stats.LEVEL))  # √χ²₂(0.95): the 2-D normal's 95 % contour
_DEG = math.degrees(1.0)
_MIX = (np.uint64(0x9E3779B97F4A7C15), np.uint64(0xBF58476D1CE4E5B9), np.uint64(0x94D049BB133111EB))


def hash_keys(time: np.ndarray, u_range: np.ndarray) -> np.ndarray:
    """κ(t, u_ρ): SplitMix64's finaliser (Steele, Lea & Flood 2014) of the bits of t xor those of u_ρ times the
    golden ratio's 2⁶⁴ fraction; a function of the plot and the reference alone (not of the slice it is summed
    in), spread uniformly over 64 bits."""
    z = np.ascontiguousarray(time, float).view(np.uint64) ^ (np.ascontiguousarray(u_range, float).view(np.uint64)
                                                             * _MIX[0])
    z = (z ^ (z >> np.uint64(30))) * _MIX[1]
    z = (z ^ (z >> np.uint64(27))) * _MIX[2]
    return z ^ (z >> np.uint64(31))


@attrs.define
class ErrorSample:
    """At most :data:`SAMPLE_SIZE` plots (module docstring): their ``key`` κ and ``values``, the columns raw
    residuals u_ρ (m), u_θ (rad), the reference's ρ_ref (m), ρ̇ (m/s), θ̇ (rad/s) — what the fit's residuals
    e = u − aᵀx̂ need once x̂ is known."""

    key: np.ndarray = attrs.field(factory=lambda: np.zeros(0, np.uint64))
    values: np.ndarray = attrs.field(factory=lambda: np.zeros((0, 5)))

    @classmethod
    def of(cls, time: np.ndarray, u_range: np.ndarray, u_azimuth: np.ndarray, rho_ref: np.ndarray,
           rho_rate: np.ndarray, theta_rate: np.ndarray) -> ErrorSample:
        """The sample of these plots (those with a non-finite value left out, as the fit's sums leave them)."""
        values = np.stack([u_range, u_azimuth, rho_ref, rho_rate, theta_rate], axis=1).astype(float)
        ok = np.isfinite(values).all(axis=1)
        return cls(hash_keys(time[ok], values[ok, 0]), values[ok]).merge(cls())

    def merge(self, other: ErrorSample) -> ErrorSample:
        """The least :data:`SAMPLE_SIZE` keys of both (ties by the values: the same whatever the order)."""
        key, values = np.concatenate([self.key, other.key]), np.concatenate([self.values, other.values])
        order = np.lexsort((*values.T[::-1], key))[:SAMPLE_SIZE]
        return ErrorSample(key[order], values[order])

    def residuals(self, x: np.ndarray) -> np.ndarray:
        """The sample's residuals e_ρ (m), e_θ (deg) after the sensor errors ``x`` (k × 2)."""
        u, (rho, rho_rate, theta_rate) = self.values[:, :2], self.values[:, 2:].T
        a_r, a_t = design_rows(rho, rho_rate, theta_rate)
        return np.stack([u[:, 0] - a_r @ x, (u[:, 1] - a_t @ x) * _DEG], axis=1)


@attrs.frozen
class ErrorEllipse:
    """One radar's error scatter (module docstring), in m and deg: the residuals' ``mean`` (2) and ``cov``
    (2 × 2) over ``n`` plots, the ``stated`` covariance diag(σ_r², σ_θ²), and the sampled residuals
    ``points`` (k × 2)."""

    mean: np.ndarray
    cov: np.ndarray
    n: int
    stated: np.ndarray
    points: np.ndarray

    def correlation(self) -> Estimate:
        """r = C_ρθ / √(C_ρρ C_θθ) with Fisher's z interval (:func:`stats.correlation`); none without spread."""
        spread = float(self.cov[0, 0] * self.cov[1, 1])
        if not spread > 0.0:
            return stats.missing("fisher-z")
        return stats.correlation(float(self.cov[0, 1]) / math.sqrt(spread), self.n)


def error_ellipse(radar: Radar, sums: SensorSums, fit: SensorFit, sample: ErrorSample) -> ErrorEllipse:
    """``radar``'s error scatter from its fit's ``sums``, the fit and its plots' ``sample``."""
    m, C = residual_moments(sums, fit.estimate)
    scale = np.array([1.0, _DEG])
    return ErrorEllipse(m * scale, C * np.outer(scale, scale), sums.n,
                        np.diag([radar.sigma_range_m, radar.sigma_azimuth_rad * _DEG]) ** 2,
                        sample.residuals(fit.estimate))


def ellipse_points(mean: np.ndarray, cov: np.ndarray, count: int = 181) -> np.ndarray:
    """``count`` points (count × 2) of the 95 % ellipse of the normal N(mean, cov) (module docstring)."""
    lam, V = np.linalg.eigh(cov)
    t = np.linspace(0.0, 2.0 * math.pi, count)
    unit = np.stack([np.cos(t), np.sin(t)])
    return mean + (LEVEL_RADIUS * V @ (np.sqrt(np.maximum(lam, 0.0))[:, None] * unit)).T
