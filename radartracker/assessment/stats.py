"""Estimates with their 95 % confidence intervals, each computed from its own sample.

Every figure of the assessment is an :class:`Estimate`: the value, the interval [low, high] at
:data:`LEVEL`, the sample size and the method that made the interval:

* a probability k/n (Pd, a code's correctness): **Wilson** score interval
  (p̂ + z²/2n ± z √(p̂(1−p̂)/n + z²/4n²)) / (1 + z²/n); for rare events (splits, wrong codes, k ≤ 5 or
  n − k ≤ 5) the exact **Clopper–Pearson** interval [B(α/2; k, n−k+1), B(1−α/2; k+1, n−k)]; both as
  ``scipy.stats.binomtest`` computes them;
* a standard deviation s of n residuals: **χ²**, [s √((n−1)/χ²_{1−α/2, n−1}), s √((n−1)/χ²_{α/2, n−1})];
* a mean of n values: Student's **t**, x̄ ± t_{1−α/2, n−1} s/√n;
* σ also from the sample's :class:`Moments`, which add up over the time slices of a long recording, or
  from a residual sum of squares and its degrees of freedom (a fit's);
* a rate of N events in S scans (false plots per scan): the exact Poisson (**Garwood**) interval
  [χ²_{α/2, 2N}/2, χ²_{1−α/2, 2N+2}/2] / S;
* an estimator's own estimate with its σ (a bias): **normal**, x̂ ± z σ;
* a pooled ratio R = Σ aᵢ / Σ bᵢ over units i that are independent while their own samples are not (the
  aircraft of a system track figure, whose 2 s samples are correlated): the **bootstrap over the units**
  (Efron & Tibshirani 1993, §6 and §13): the units drawn with replacement :data:`BOOTSTRAP_DRAWS` times, R
  recomputed each time, the interval the 2.5 % and 97.5 % quantiles of those R (percentile method);
* a share of time over such units: the same bootstrap; where every unit's share is 0 (or 1) and the bootstrap
  collapses, Clopper–Pearson's bound for m units none (all) of which showed it, [0, 1 − (α/2)^(1/m)];
* a correlation r of n pairs: **Fisher's z**, tanh(atanh r ± z_{1−α/2}/√(n − 3)) (the pairs independent and
  normal);
* a quantile ξ_q of n values: the distribution-free **order-statistic** interval [x₍ₗ₎, x₍ᵤ₎], l the
  smallest k with B(k; n, q) ≥ α/2 and u − 1 the smallest with B(u − 1; n, q) ≥ 1 − α/2 (B the binomial
  distribution function): P(x₍ₗ₎ ≤ ξ_q ≤ x₍ᵤ₎) = B(u − 1) − B(l − 1) ≥ 1 − α; an order outside 1..n is ∓∞.
"""

from __future__ import annotations

import math

import attrs
import numpy as np
from scipy import stats

LEVEL = 0.95
BOOTSTRAP_DRAWS = 2000  # percentile bootstrap: 2000 draws put the 2.5 % quantile's Monte Carlo error near 0.1 σ
BOOTSTRAP_SEED = 0  # the same input gives the same interval
_Z = float(stats.norm.ppf(0.5 + LEVEL / 2))


@attrs.frozen
class Estimate:
    """A figure, its interval at :data:`LEVEL`, the sample it came from and how the interval was made."""

    value: float
    low: float
    high: float
    n: int
    method: str

    def contains(self, x: float) -> bool:
        """Whether ``x`` lies in [low, high]."""
        return self.low <= x <= self.high

    def as_dict(self) -> dict:
        return {"value": self.value, "ci_low": self.low, "ci_high": self.high, "n": self.n, "method": self.method}


def missing(method: str) -> Estimate:
    """An estimate of an empty sample: NaN with the method it would have used."""
    return Estimate(math.nan, math.nan, math.nan, 0, method)


def proportion(k: int, n: int) -> Estimate:
    """k successes in n trials with :func:`proportions`' interval: Wilson's, or Clopper–Pearson's when k or n − k
    is 5 or less (where Wilson's coverage falls below its level)."""
    if n <= 0:
        return missing("wilson")
    p, low, high = (float(v[0]) for v in proportions(np.array([k]), np.array([n])))
    return Estimate(p, low, high, n, "clopper-pearson" if min(k, n - k) <= 5 else "wilson")


def proportions(k: np.ndarray, n: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """k/n with its 95 % interval for many bins at once (n > 0): Wilson's closed form
    (p + z²/2n ± z √(p(1−p)/n + z²/4n²)) / (1 + z²/n), or Clopper–Pearson's [B(α/2; k, n−k+1), B(1−α/2; k+1, n−k)]
    (0 at k = 0, 1 at k = n) where k or n − k is 5 or less — the values ``scipy.stats.binomtest`` gives."""
    k, n = np.asarray(k, float), np.asarray(n, float)
    p, a = k / n, 1 - LEVEL
    centre, half = p + _Z**2 / (2 * n), _Z * np.sqrt(p * (1 - p) / n + _Z**2 / (4 * n * n))
    low, high = (centre - half) / (1 + _Z**2 / n), (centre + half) / (1 + _Z**2 / n)
    exact = np.minimum(k, n - k) <= 5
    with np.errstate(invalid="ignore"):
        cp_low = np.where(k > 0, stats.beta.ppf(a / 2, k, n - k + 1), 0.0)
        cp_high = np.where(k < n, stats.beta.ppf(1 - a / 2, k + 1, n - k), 1.0)
    return p, np.where(exact, cp_low, low), np.where(exact, cp_high, high)


@attrs.frozen
class Moments:
    """The count n, mean x̄ and sum of squared deviations M₂ = Σ(xᵢ − x̄)² of a sample: what its mean and σ
    need, and additive over parts (a time slice each). Two parts merge by Chan et al.'s rule
    n = n_a + n_b, δ = x̄_b − x̄_a, x̄ = x̄_a + δ n_b/n, M₂ = M₂a + M₂b + δ² n_a n_b/n: the same figures as one
    pass over the whole sample, to round-off (relative 1e-12 in practice), with no cancellation of Σx²."""

    n: int = 0
    mean: float = 0.0
    m2: float = 0.0

    @classmethod
    def of(cls, values: np.ndarray) -> Moments:
        x = np.asarray(values, float)
        if not len(x):
            return cls()
        m = float(np.mean(x))
        return cls(len(x), m, float(np.sum((x - m) ** 2)))

    def merge(self, other: Moments) -> Moments:
        if not other.n:
            return self
        if not self.n:
            return other
        n = self.n + other.n
        d = other.mean - self.mean
        return Moments(n, self.mean + d * other.n / n, self.m2 + other.m2 + d * d * self.n * other.n / n)


def sigma(residuals: np.ndarray | Moments) -> Estimate:
    """The sample standard deviation of ``residuals`` (about their mean, n − 1) with its χ² interval."""
    m = residuals if isinstance(residuals, Moments) else Moments.of(residuals)
    return sigma_of_sum(m.m2, m.n - 1, m.n)


def sigma_of_sum(squares: float, dof: int, n: int) -> Estimate:
    """σ = √(``squares``/ν) of a residual sum of squares with ν = ``dof`` degrees of freedom (``n`` values),
    with its χ² interval [σ √(ν/χ²_{1−α/2, ν}), σ √(ν/χ²_{α/2, ν})]."""
    if dof < 2:
        return missing("chi2")
    s = math.sqrt(squares / dof)
    a = 1 - LEVEL
    lo = s * math.sqrt(dof / stats.chi2.ppf(1 - a / 2, dof))
    hi = s * math.sqrt(dof / stats.chi2.ppf(a / 2, dof))
    return Estimate(s, lo, hi, n, "chi2")


def mean(values: np.ndarray) -> Estimate:
    """The sample mean with Student's t interval."""
    x = Moments.of(values)
    n = x.n
    if n < 2:
        return missing("t")
    m, s = x.mean, math.sqrt(x.m2 / (n - 1))
    half = float(stats.t.ppf(0.5 + LEVEL / 2, n - 1)) * s / math.sqrt(n)
    return Estimate(m, m - half, m + half, n, "t")


def rate(events: int, exposures: float, n: int | None = None) -> Estimate:
    """``events`` in ``exposures`` (scans, flight hours; 1 for a count): the Poisson rate with Garwood's exact
    interval; ``n`` the sample it came from (default: ``exposures``)."""
    size = int(exposures) if n is None else n
    if exposures <= 0:
        return missing("poisson-garwood")
    a = 1 - LEVEL
    lo = float(stats.chi2.ppf(a / 2, 2 * events)) / 2 if events > 0 else 0.0
    hi = float(stats.chi2.ppf(1 - a / 2, 2 * events + 2)) / 2
    return Estimate(events / exposures, lo / exposures, hi / exposures, size, "poisson-garwood")


def bootstrap_ratio(num: np.ndarray, den: np.ndarray, root: bool = False) -> Estimate:
    """R = Σ num / Σ den over the units (√R with ``root``: an RMS from squared sums and counts), with the
    percentile interval of the bootstrap over the units (module docstring); units with den = 0 carry nothing
    and are left out. Fewer than two units: the value with no interval (NaN bounds: inconclusive)."""
    num, den = np.asarray(num, float), np.asarray(den, float)
    keep = den > 0
    num, den = num[keep], den[keep]
    m = len(num)
    if not m:
        return missing("bootstrap-aircraft")
    f = np.sqrt if root else (lambda v: v)
    value = float(f(num.sum() / den.sum()))
    if m < 2:
        return Estimate(value, math.nan, math.nan, m, "bootstrap-aircraft")
    draw = np.random.default_rng(BOOTSTRAP_SEED).integers(0, m, (BOOTSTRAP_DRAWS, m))
    r = f(num[draw].sum(axis=1) / den[draw].sum(axis=1))
    a = 1 - LEVEL
    lo, hi = np.quantile(r, [a / 2, 1 - a / 2])
    return Estimate(value, float(lo), float(hi), m, "bootstrap-aircraft")


def share_of_units(num: np.ndarray, den: np.ndarray) -> Estimate:
    """A share of time R = Σ num / Σ den (0 ≤ num ≤ den per unit) with the bootstrap over the units; where no
    unit has any (Σ num = 0) or every unit has only (num = den), the bootstrap's interval collapses to a point,
    so the Clopper–Pearson bound of m units none (all) of which showed it stands instead: [0, 1 − (α/2)^(1/m)]
    ([(α/2)^(1/m), 1]). Each unit's share lies under the chance that it shows it at all, so that bound holds
    the share's expectation too."""
    e = bootstrap_ratio(num, den)
    if not e.n or (0.0 < e.value < 1.0):
        return e
    bound = (1 - LEVEL) / 2
    edge = 1 - bound ** (1 / e.n)
    low, high = (0.0, edge) if e.value == 0.0 else (1 - edge, 1.0)
    return Estimate(e.value, low, high, e.n, "clopper-pearson-aircraft")


def quantile(values: np.ndarray, q: float) -> Estimate:
    """The ``q`` quantile of ``values`` (numpy's linear interpolation) with the order-statistic interval
    (module docstring)."""
    x = np.sort(np.asarray(values, float))
    n = len(x)
    if not n:
        return missing("order-statistic")
    a = 1 - LEVEL
    lo_k = int(stats.binom.ppf(a / 2, n, q))  # l, 1-based
    hi_k = int(stats.binom.ppf(1 - a / 2, n, q)) + 1  # u, 1-based
    low = float(x[lo_k - 1]) if lo_k >= 1 else -math.inf
    high = float(x[hi_k - 1]) if hi_k <= n else math.inf
    return Estimate(float(np.quantile(x, q)), low, high, n, "order-statistic")


def normal(value: float, sd: float, n: int) -> Estimate:
    """An estimator's estimate ``value`` with its stated σ: value ± z σ (``n``: the measurements it used)."""
    if not (math.isfinite(value) and math.isfinite(sd)):
        return missing("normal")
    return Estimate(value, value - _Z * sd, value + _Z * sd, n, "normal")


def scaled(e: Estimate, factor: float) -> Estimate:
    """``e`` in other units (every bound times ``factor`` > 0)."""
    return attrs.evolve(e, value=e.value * factor, low=e.low * factor, high=e.high * factor)


def correlation(r: float, n: int) -> Estimate:
    """A sample correlation ``r`` of ``n`` pairs with Fisher's interval tanh(z ± z_{1−α/2}/√(n − 3)),
    z = atanh r (module docstring); |r| = 1 gives the point [r, r]."""
    if n <= 3 or not math.isfinite(r):
        return missing("fisher-z")
    if abs(r) >= 1.0:
        return Estimate(r, r, r, n, "fisher-z")
    z, half = math.atanh(r), _Z / math.sqrt(n - 3)
    return Estimate(r, math.tanh(z - half), math.tanh(z + half), n, "fisher-z")
