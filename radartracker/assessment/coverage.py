"""The cone of silence and the coverage a radar actually achieved, measured from the reference's crossings
(:attr:`radartracker.assessment.matching.RadarMatch.expected`: each crossing's slant range ρ, azimuth θ,
elevation ε and whether a plot detected it) instead of assumed from its configuration.

* **Cone of silence.** Above some elevation ε_c a rotating radar's beam does not reach: the crossings at
  ε ≥ :attr:`CoverageConfig.cone_min_elevation_deg` (the near field, where range and the horizon do not
  limit detection), sorted by ε, are fitted with a step: Pd = p₁ below ε_c, p₂ < p₁ above. Its
  log-likelihood for a split c between two consecutive distinct elevations is

      L(c) = ℓ(k₁, n₁) + ℓ(k₂, n₂),    ℓ(k, n) = k ln(k/n) + (n − k) ln(1 − k/n)   (0 ln 0 = 0)

  (n₁, k₁ the crossings and detections below c, n₂, k₂ above). The measured cone ε̂_c is the midpoint of
  the gap of greatest L; its 95 % interval, by the profile likelihood, runs from the lower elevation of the
  lowest gap to the upper elevation of the highest gap with 2 (L(ĉ) − L(c)) ≤ 2 ln(2/α) = 7.38 (α = 0.05).
  Not χ²₁'s 3.84: a change point is not a regular parameter. Moving the split away from the true cone, the
  log-likelihood ratio is a random walk whose exponential is a martingale, so by Ville's inequality it
  exceeds ln(2/α) on either side with probability ≤ α/2 (measured: 99 % coverage over 500 draws of 100 or
  400 crossings, where χ²₁'s bound gave 87–91 %). When a constant Pd (no cone) is within that bound too,
  2 (L(ĉ) − ℓ(K, N)) ≤ 7.38, the crossings show no cone: **not assessable**, as when no reference crossed
  above ε_min.
* **Coverage achieved (the R₅₀-style detection range).** The crossings inside the assumed coverage (those
  Pd counts) binned by slant range (:attr:`CoverageConfig.range_bin_km`); a bin is judged when it holds at
  least :attr:`CoverageConfig.min_crossings`. The achieved detection range is the far edge of the farthest
  judged bin whose Pd = k/n meets the stated level P_c (:attr:`CoverageConfig.level`), capped at the
  configured range R_max:

      R = min(R_max, max{(b + 1) Δρ : n_b ≥ n_min, k_b/n_b ≥ P_c})       (0 when no bin meets P_c)

  and its interval the same with the bins' Wilson (or Clopper–Pearson) bounds in place of k_b/n_b — the
  farthest bin whose lower bound meets P_c, the farthest whose upper bound does (the bins' own 95 %
  intervals, not a joint level) — widened by a bin Δρ either side: a bin's Pd averages over it, so the range
  where Pd falls below P_c may lie in the last bin that meets P_c or in the first that does not. It is made
  over all azimuths (``detection_range_km``) and per azimuth sector (:attr:`CoverageConfig.sector_deg`: the
  coverage diagram, R_s against R_max, each with what limits it: the configured range, the detection — a
  judged bin beyond R_s falls short — or the traffic, which stopped first: R_s is then a lower bound).
* **Share of the coverage achieved.** Over the judged cells c (an azimuth sector × a range bin, of area
  a_c = (Δθ/2)(ρ_out² − ρ_in²), ρ_out capped at R_max), the area where Pd meets P_c:

      coverage_share = Σ_c a_c [k_c/n_c ≥ P_c] / Σ_c a_c

  its bounds the same with each cell's Wilson (or Clopper–Pearson) lower and upper bound: the share of the
  configured coverage, where traffic let it be judged, in which the radar detects at the stated level.
"""

from __future__ import annotations

import math

import attrs
import numpy as np
from scipy import special

from radartracker.assessment import stats
from radartracker.assessment.stats import Estimate

LR_BOUND = 2.0 * math.log(2.0 / (1.0 - stats.LEVEL))  # 2 ln 40 = 7.38: Ville's bound, both sides


@attrs.frozen
class CoverageConfig:
    """The bins and levels of the measured cone of silence and achieved coverage (module docstring)."""

    elevation_bin_deg: float = attrs.field(default=5.0, validator=attrs.validators.gt(0.0))
    cone_min_elevation_deg: float = attrs.field(default=10.0, validator=attrs.validators.ge(0.0))
    sector_deg: float = attrs.field(default=30.0, validator=[attrs.validators.gt(0.0), attrs.validators.le(360.0)])
    range_bin_km: float = attrs.field(default=10.0, validator=attrs.validators.gt(0.0))
    level: float = attrs.field(default=0.5, validator=[attrs.validators.gt(0.0), attrs.validators.lt(1.0)])
    min_crossings: int = attrs.field(default=10, validator=attrs.validators.ge(1))


def _loglik(k: np.ndarray, n: np.ndarray) -> np.ndarray:
    """ℓ(k, n) = k ln(k/n) + (n − k) ln(1 − k/n): the binomial log-likelihood at its maximum (0 ln 0 = 0)."""
    k, n = np.asarray(k, float), np.asarray(n, float)
    return special.xlogy(k, k / n) + special.xlogy(n - k, (n - k) / n)


def measure_cone(elevation_deg: np.ndarray, detected: np.ndarray,
                 config: CoverageConfig) -> tuple[Estimate | None, str]:
    """The measured cone of silence (deg) by the step fit of the module docstring, or None and why it is not
    assessable. Order-free: the crossings are sorted by (ε, detected), so slices added in any order agree."""
    floor = config.cone_min_elevation_deg
    sel = elevation_deg >= floor
    if not sel.any():
        return None, f"no reference aircraft crossed the beam at {floor:g}° elevation or above"
    order = np.lexsort((detected[sel], elevation_deg[sel]))
    e, d = elevation_deg[sel][order], detected[sel][order].astype(np.int64)
    n, total = len(e), int(d.sum())
    gap = np.flatnonzero(np.diff(e) > 0)  # split between e[j] and e[j + 1]
    n1, k1 = gap + 1, np.cumsum(d)[gap]
    n2, k2 = n - n1, total - k1
    fit = np.where(k2 * n1 < k1 * n2, _loglik(k1, n1) + _loglik(k2, n2), -np.inf)  # a drop: p₂ < p₁
    best = int(np.argmax(fit)) if len(fit) else -1
    if best < 0 or 2.0 * (fit[best] - float(_loglik(total, n))) <= LR_BOUND:
        return None, (f"Pd does not fall with elevation from {floor:g}° up to {e[-1]:.1f}° ({n} crossings, "
                      f"{total} detected): no cone of silence seen")
    ok = gap[2.0 * (fit[best] - fit) <= LR_BOUND]
    j = gap[best]
    return Estimate(float(e[j] + e[j + 1]) / 2, float(e[ok.min()]), float(e[ok.max() + 1]), n, "step-fit-lr"), ""


def _range_bins(range_km: np.ndarray, detected: np.ndarray, config: CoverageConfig) -> tuple[np.ndarray, ...]:
    """The judged slant-range bins (index b: [b Δρ, (b + 1) Δρ)) of the crossings, their crossings, and each
    one's Pd with its interval (:func:`radartracker.assessment.stats.proportions`): five arrays."""
    if not len(range_km):
        return (np.zeros(0, np.int64),) * 2 + (np.zeros(0),) * 3
    b = np.floor(range_km / config.range_bin_km).astype(np.int64)
    n = np.bincount(b)
    k = np.bincount(b, weights=detected.astype(float), minlength=len(n)).round().astype(np.int64)
    judged = np.flatnonzero(n >= config.min_crossings)
    return (judged, n[judged], *stats.proportions(k[judged], n[judged]))


def detection_range(bins: tuple[np.ndarray, ...], max_range_km: float,
                    config: CoverageConfig) -> tuple[float, float, float, str]:
    """(R, R_low, R_high) in km of the judged range ``bins`` (:func:`_range_bins`, module docstring), and what
    limits R: ``configured range`` (R = R_max), ``detection`` (a judged bin beyond R falls short of P_c) or
    ``traffic`` (no judged bin beyond R: the traffic stopped first, R is a lower bound of the reach)."""
    w, index = config.range_bin_km, bins[0]

    def reach(values: np.ndarray) -> float:
        met = index[values >= config.level]
        return min(max_range_km, float(met.max() + 1) * w) if len(met) else 0.0

    r = reach(bins[2])
    limit = "configured range" if r >= max_range_km else "detection" if index.max() * w >= r else "traffic"
    return r, max(0.0, reach(bins[3]) - w), min(max_range_km, reach(bins[4]) + w), limit


def achieved_coverage(range_m: np.ndarray, azimuth_deg: np.ndarray, detected: np.ndarray, max_range_m: float,
                      config: CoverageConfig) -> tuple[dict[str, Estimate], dict[str, str], list[dict]]:
    """``detection_range_km`` and ``coverage_share`` (module docstring) with what is not assessable and why, and
    the coverage diagram: per azimuth sector its crossings, detections, R_s with its bounds, what limits it,
    and R_max (km)."""
    r_km, r_max, w = range_m / 1000.0, max_range_m / 1000.0, config.range_bin_km
    bins = _range_bins(r_km, detected, config)
    if not len(bins[0]):
        why = f"no {w:g} km range bin holds {config.min_crossings} crossings"
        return {}, {"detection_range_km": why, "coverage_share": why}, []
    whole = detection_range(bins, r_max, config)
    figures = {"detection_range_km": Estimate(*whole[:3], len(r_km), "wilson-bins")}
    sector = np.floor(np.mod(azimuth_deg, 360.0) / config.sector_deg).astype(np.int64)
    rows, cells = [], []  # cells: per sector, its judged range bins' areas, crossings and Pd with its bounds
    for s in range(math.ceil(360.0 / config.sector_deg)):
        sel = sector == s
        width = min(360.0, (s + 1) * config.sector_deg) - s * config.sector_deg
        got = _range_bins(r_km[sel], detected[sel], config)
        cells.append(np.vstack([width * (np.minimum((got[0] + 1) * w, r_max) ** 2 - (got[0] * w) ** 2), *got[1:]]))
        reach = detection_range(got, r_max, config) if len(got[0]) else (math.nan,) * 3 + ("",)
        rows.append({"azimuth_low": s * config.sector_deg, "azimuth_high": s * config.sector_deg + width,
                     "crossings": int(sel.sum()), "detected": int(detected[sel].sum()), "range_km": reach[0],
                     "range_low_km": reach[1], "range_high_km": reach[2], "limited_by": reach[3],
                     "configured_range_km": r_max})
    area, n, *pd = np.hstack(cells)
    if not len(area):
        return figures, {"coverage_share": f"no {config.sector_deg:g}° sector's {w:g} km range bin holds "
                                           f"{config.min_crossings} crossings"}, rows
    share = [float(area[p >= config.level].sum() / area.sum()) for p in pd]
    figures["coverage_share"] = Estimate(*share, int(n.sum()), "wilson-cells")
    return figures, {}, rows
