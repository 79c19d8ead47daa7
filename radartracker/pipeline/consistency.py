"""Where the mean of a filter's NEES or NIS values should fall if the filter is consistent.

A consistent filter's NEES eᵀP⁻¹e of an n-dimensional estimate is χ²ₙ, its NIS νᵀΛ⁻¹ν of an m-dimensional
measurement χ²ₘ. The innovations of a consistent filter are white, so the mean NIS of N measurements is a
mean of N independent χ² values and :func:`mean_chi2_band` is its band (Bar-Shalom, Li & Kirubarajan §5.4).
Its estimation errors are not: consecutive estimates of one track share most of their information, and
the mean of N NEES values varies as much as that of N/τ independent ones, τ = 1 + 2 Σₖ ρₖ the integrated
autocorrelation time of the series. :func:`effective_count` estimates N/τ from the values themselves
(Geyer's initial positive sequence, as for the effective sample size of a Markov chain), and the band of a
mean NEES is :func:`mean_chi2_band` of that count (the χ² whose mean and variance match: 2n/(N/τ)).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

MAX_LAG = 1000  # estimates of one track: a correlation longer than this (an hour of updates) is cut there

def mean_chi2_band(dof: float, n: float, level: float = 0.95) -> list[float] | None:
    """Where the mean of ``n`` independent χ² values of ``dof`` degrees of freedom falls with probability
    ``level``: [χ²_{n·dof}((1 − level)/2), χ²_{n·dof}((1 + level)/2)] / n; ``None`` without values. ``n`` may
    be an :func:`effective_count` (not a whole number)."""
    if not n > 0:
        return None
    from scipy.stats import chi2

    lo, hi = chi2.ppf([(1 - level) / 2, (1 + level) / 2], dof * n) / n
    return [float(lo), float(hi)]


def effective_count(values: np.ndarray, series: Sequence | np.ndarray) -> float:
    """How many independent values the correlated ``values`` are worth for their mean: N/τ, with
    τ = 1 + 2 Σₖ ρₖ. ``series`` names the series of each value (a track); within a series the values are
    in time order. ρₖ = Σ dₜ dₜ₊ₖ / Σ dₜ² over the pairs k apart in one series (d: the values less their
    mean), summed in pairs Γₘ = ρ₂ₘ + ρ₂ₘ₊₁ while Γₘ > 0 (Geyer 1992: beyond that the estimates are noise),
    up to lag :data:`MAX_LAG` (the work is N per lag). N where the values do not vary; never more than N nor
    less than 1."""
    v = np.asarray(values, float)
    n = len(v)
    if n < 2:
        return float(n)
    series = np.asarray(series)
    order = np.argsort(series, kind="stable")  # each series together, its values in their order
    d, s = v[order] - v.mean(), series[order]
    total = float(d @ d)
    if total == 0.0:
        return float(n)
    tau, m = -1.0, 0  # τ = −1 + 2 Σₘ Γₘ (ρ₀ = 1 is in Γ₀)
    while 2 * m < min(n, MAX_LAG):
        pair = (_lagged(d, s, 2 * m) + _lagged(d, s, 2 * m + 1)) / total
        if pair <= 0.0:
            break
        tau += 2.0 * pair
        m += 1
    return float(max(n / max(tau, 1.0), 1.0))


def _lagged(d: np.ndarray, s: np.ndarray, k: int) -> float:
    """Σ dₜ dₜ₊ₖ over the pairs of one series k apart (k = 0: Σ dₜ²)."""
    if k == 0:
        return float(d @ d)
    if k >= len(d):
        return 0.0
    same = s[k:] == s[:-k]
    return float(np.dot(d[k:][same], d[:-k][same]))
