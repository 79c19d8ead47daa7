"""The band of a mean NEES when consecutive values are correlated (radartracker.pipeline.consistency).

Oracle: NEES-like series made of AR(1) Gaussian vectors, xₜ = φ xₜ₋₁ + √(1 − φ²) wₜ, whose squared norms are
χ²ₙ with autocorrelation φ²ᵏ, so τ = 1 + 2 Σ φ²ᵏ = (1 + φ²)/(1 − φ²) in closed form, here in the test.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import binom

from radartracker.pipeline.consistency import effective_count, mean_chi2_band


def ar1_nees(rng: np.random.Generator, lengths: list[int], phi: float, dim: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """(values, series) of independent tracks of the given lengths, each value χ²_dim, correlated by φ²ᵏ."""
    values, series = [], []
    for track, n in enumerate(lengths):
        x = np.empty((n, dim))
        x[0] = rng.standard_normal(dim)
        for t in range(1, n):
            x[t] = phi * x[t - 1] + np.sqrt(1 - phi**2) * rng.standard_normal(dim)
        values.append(np.sum(x**2, axis=1))
        series.append(np.full(n, track))
    return np.concatenate(values), np.concatenate(series)


@pytest.mark.parametrize("phi", [0.0, 0.7, 0.9, 0.97])
def test_effective_count_matches_the_closed_form(phi: float) -> None:
    rng = np.random.default_rng(int(phi * 100))
    values, series = ar1_nees(rng, [3000] * 8, phi)
    tau = (1 + phi**2) / (1 - phi**2)
    assert effective_count(values, series) == pytest.approx(len(values) / tau, rel=0.2)


def test_series_are_not_joined_and_order_within_them_is_kept() -> None:
    rng = np.random.default_rng(3)
    values, series = ar1_nees(rng, [400] * 20, 0.9)
    a = effective_count(values, series)
    interleaved = np.lexsort((np.arange(len(values)), rng.random(20)[series]))  # tracks reordered, each kept in order
    assert effective_count(values[interleaved], series[interleaved]) == pytest.approx(a)
    shuffled = rng.permutation(len(values))  # each track's order lost: the values look independent
    assert effective_count(values[shuffled], series[shuffled]) > 3 * a


def test_band_of_the_mean_holds_the_expectation_95_percent_of_the_time() -> None:
    """Over 300 runs of 12 tracks (φ = 0.95, τ ≈ 19.5), the mean NEES of a run falls inside the band of its
    effective count about 95 % of the time (binomial 99 % band of 300 draws), inside the band of independent
    values far less often."""
    rng = np.random.default_rng(11)
    runs, held, held_naive = 300, 0, 0
    for _ in range(runs):
        values, series = ar1_nees(rng, list(rng.integers(150, 400, 12)), 0.95)
        mean = values.mean()
        lo, hi = mean_chi2_band(4, effective_count(values, series))
        held += lo <= mean <= hi
        nlo, nhi = mean_chi2_band(4, len(values))
        held_naive += nlo <= mean <= nhi
    low, high = binom.ppf([0.005, 0.995], runs, 0.95)
    assert low <= held <= high, held
    assert held_naive < 0.6 * runs, held_naive


def test_edge_cases() -> None:
    assert effective_count(np.array([]), np.array([])) == 0.0
    assert effective_count(np.array([3.0]), np.array([1])) == 1.0
    assert effective_count(np.full(10, 4.0), np.zeros(10)) == 10.0
    assert mean_chi2_band(4, 0) is None
    lo, hi = mean_chi2_band(4, 2.5)
    assert lo < 4.0 < hi


def test_a_trend_is_cut_at_the_largest_lag() -> None:
    """One long series that never decorrelates (a trend) ends at MAX_LAG lags, in bounded work."""
    from radartracker.pipeline.consistency import MAX_LAG

    values = np.linspace(0.0, 8.0, 50_000)
    count = effective_count(values, np.zeros(len(values), int))
    assert 1.0 <= count <= len(values) / MAX_LAG
