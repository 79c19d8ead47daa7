"""The error scatter (radartracker.assessment.ellipse) against independent oracles: the covariance made from the
fit's sums against numpy's of the residuals themselves, the ellipse against scipy's χ² quantile and a Monte
Carlo count, the correlation's interval against scipy's Pearson interval, and the bounded sample against the
same sample drawn in one pass."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats as sps

from radartracker.assessment import stats
from radartracker.assessment.ellipse import SAMPLE_SIZE, ErrorSample, ellipse_points
from radartracker.assessment.systematic import SensorSums, design_rows, fit_sensor_errors, residual_moments

SIGMA = (70.0, math.radians(0.08))
RHO = 0.4  # the simulated correlation of e_ρ and e_θ


def _plots(n: int, seed: int = 1) -> dict[str, np.ndarray]:
    """``n`` plots of a radar with Δr = 90 m, Δθ = 0.1°, g = 200 ppm, τ = 50 ms and correlated noise."""
    rng = np.random.default_rng(seed)
    rho, rho_rate, theta_rate = rng.uniform(20e3, 200e3, n), rng.normal(0, 200, n), rng.normal(0, 2e-3, n)
    cov = np.array([[SIGMA[0] ** 2, RHO * SIGMA[0] * SIGMA[1]], [RHO * SIGMA[0] * SIGMA[1], SIGMA[1] ** 2]])
    e = rng.multivariate_normal([0.0, 0.0], cov, n)
    x = np.array([90.0, math.radians(0.1), 2e-4, 0.05])
    a_r, a_t = design_rows(rho, rho_rate, theta_rate)
    return {"time": np.sort(rng.uniform(0, 3600, n)), "u_range": a_r @ x + e[:, 0], "u_azimuth": a_t @ x + e[:, 1],
            "rho_ref": rho, "rho_rate": rho_rate, "theta_rate": theta_rate}


def _sums(p: dict[str, np.ndarray], rows=slice(None)) -> SensorSums:
    return SensorSums.of(p["u_range"][rows], p["u_azimuth"][rows], p["rho_ref"][rows], p["rho_rate"][rows],
                         p["theta_rate"][rows])


def _fit_residuals(p: dict[str, np.ndarray], x: np.ndarray) -> np.ndarray:
    """e = u − aᵀx of every plot, from the rows themselves (n × 2: m, rad)."""
    a_r, a_t = design_rows(p["rho_ref"], p["rho_rate"], p["theta_rate"])
    return np.stack([p["u_range"] - a_r @ x, p["u_azimuth"] - a_t @ x], axis=1)


def test_the_covariance_from_sums_is_numpys_of_the_residuals_and_adds_over_slices():
    p = _plots(3000)
    sums = _sums(p)
    fit = fit_sensor_errors("R", sums)
    e = _fit_residuals(p, fit.estimate)
    m, C = residual_moments(sums, fit.estimate)
    np.testing.assert_allclose(m / SIGMA, e.mean(axis=0) / SIGMA, rtol=0, atol=1e-9)  # in σ's
    np.testing.assert_allclose(C, np.cov(e.T), rtol=1e-9)
    cuts = [0, 17, 900, 901, 2500, 3000]  # slices of 17, 883, 1, 1599 and 500 plots
    merged = SensorSums()
    for lo, hi in zip(cuts[:-1], cuts[1:]):
        merged = merged.merge(_sums(p, slice(lo, hi)))
    m2, C2 = residual_moments(merged, fit.estimate)
    np.testing.assert_allclose(C2, C, rtol=1e-9)
    np.testing.assert_allclose(m2 / SIGMA, m / SIGMA, rtol=0, atol=1e-9)
    r = C[0, 1] / math.sqrt(C[0, 0] * C[1, 1])  # the simulated covariance recovered, within sampling error
    assert stats.correlation(r, sums.n).contains(RHO)
    assert abs(math.sqrt(C[0, 0]) / SIGMA[0] - 1) < 0.05 and abs(math.sqrt(C[1, 1]) / SIGMA[1] - 1) < 0.05


def test_the_correlation_interval_is_scipys_fisher_interval():
    e = _fit_residuals(p := _plots(400, seed=3), fit_sensor_errors("R", _sums(p)).estimate)
    ours = stats.correlation(float(np.corrcoef(e.T)[0, 1]), len(e))
    theirs = sps.pearsonr(e[:, 0], e[:, 1])
    ci = theirs.confidence_interval(0.95)
    assert ours.method == "fisher-z" and ours.n == 400
    assert (ours.value, ours.low, ours.high) == pytest.approx((theirs.statistic, ci.low, ci.high), rel=1e-9)
    assert stats.correlation(0.5, 3).method == "fisher-z" and math.isnan(stats.correlation(0.5, 3).value)


def test_the_ellipse_is_the_95_percent_contour():
    mean, cov = np.array([5.0, -0.01]), np.array([[4900.0, 0.03], [0.03, 2e-6]])
    ring = ellipse_points(mean, cov)
    d = ring - mean
    mahalanobis = np.einsum("ij,jk,ik->i", d, np.linalg.inv(cov), d)
    np.testing.assert_allclose(mahalanobis, sps.chi2.ppf(0.95, 2), rtol=1e-9)
    draws = np.random.default_rng(5).multivariate_normal(mean, cov, 200_000) - mean
    inside = np.einsum("ij,jk,ik->i", draws, np.linalg.inv(cov), draws) <= mahalanobis[0]
    assert abs(inside.mean() - 0.95) < 0.003  # 6 σ of the binomial's 0.0005


def test_the_sample_is_bounded_and_the_same_however_the_plots_are_sliced():
    p = _plots(10_000, seed=7)
    cols = [p[k] for k in ("time", "u_range", "u_azimuth", "rho_ref", "rho_rate", "theta_rate")]
    whole = ErrorSample.of(*cols)
    assert len(whole.key) == SAMPLE_SIZE and np.all(np.diff(whole.key.astype(np.float64)) >= 0)
    for cuts in ([0, 10_000], [0, 1, 4000, 4001, 9000, 10_000], list(range(0, 10_001, 250))):
        sliced = ErrorSample()
        for lo, hi in zip(cuts[::-1][1:], cuts[::-1][:-1]):  # last slice first: the order does not matter
            sliced = sliced.merge(ErrorSample.of(*(c[lo:hi] for c in cols)))
        assert np.array_equal(sliced.key, whole.key) and np.array_equal(sliced.values, whole.values)
    rows = np.flatnonzero(np.isin(p["u_range"], whole.values[:, 0]))
    assert len(rows) == SAMPLE_SIZE  # every sampled plot is one of the plots, once
    assert sps.kstest(p["time"][rows], "uniform", args=(0, 3600)).pvalue > 1e-3  # spread over the recording
    x = np.array([90.0, math.radians(0.1), 2e-4, 0.05])
    mine = whole.residuals(x)[np.argsort(whole.values[:, 0])]
    e = _fit_residuals({k: v[rows] for k, v in p.items()}, x)[np.argsort(p["u_range"][rows])]
    np.testing.assert_allclose(mine, e * np.array([1.0, math.degrees(1.0)]), rtol=1e-12, atol=1e-9)
    small = ErrorSample.of(*(c[:10] for c in cols))
    assert len(small.key) == 10
