"""One radar's figures, each an :class:`~radartracker.assessment.stats.Estimate` with its 95 % interval.

With the plots matched to the reference (:mod:`radartracker.assessment.matching`; Δr̂, Δθ̂ the joint
estimator's biases):

* **Systematic errors**: the estimator's Δr̂ and Δθ̂ ± 1.96 σ (its own covariance), and, as a check, the
  mean raw residual against the reference, mean(ρ − ρ_ref) and mean(θ − θ_ref) (t interval).
* **Random errors**: the standard deviations of e_ρ = ρ − ρ_ref − Δr̂ and e_θ = θ − θ_ref − Δθ̂ (χ²), over
  the plot nearest the reference in each sweep of an aircraft (a split plot is not noise).
* **Pd**: detected crossings / crossings inside the coverage (Wilson), overall and by range, azimuth and
  altitude bin.
* **Plots per scan**: the mean of the plot counts of the revolutions from the first plot to the last (t).
* **False plots per scan**: plots with no reference in the gate / revolutions (Poisson, Garwood) — only
  against the truth: an ADS-B reference lacks the aircraft that do not broadcast.
* **Split plots**: an aircraft's matched plots fall in groups (gaps > T/2 between groups, one group per
  sweep); the share of groups with two plots or more.
* **Codes**: Mode 3/A validity (a code present) and correctness (the aircraft's code), Mode C validity
  (an altitude present) and correctness (within :attr:`RadarConfig.mode_c_tolerance_ft` of the
  reference's height), Mode S address correctness — over the matched plots of aircraft that carry them.
* **Time stamps**: the share of plots stamped earlier than a plot before them in the file (ordering), and
  the σ of the offsets of the plots used for the random errors from the time their antenna pointed at
  their azimuth (:func:`radartracker.assessment.matching.antenna_offsets`; with an exact clock it is
  σ_θ T/2π; its mean is taken up by the antenna phase t_N, so a constant time-stamp bias does not show
  here). Lateness needs arrival times, which no scenario format carries: not assessable.
"""

from __future__ import annotations

import math
import attrs
import numpy as np

from radartracker.assessment import stats
from radartracker.assessment.matching import RadarMatch, antenna_offsets, wrap_angle
from radartracker.assessment.stats import Estimate
from radartracker.domain import BiasState, Radar
from radartracker.io.tables import PlotTable

FT = 0.3048
NOT_ASSESSABLE_LATENESS = "the recording carries no arrival times"


@attrs.frozen
class RadarConfig:
    """The bins of Pd by range, azimuth and altitude, and the Mode C tolerance."""

    range_bin_km: float = attrs.field(default=25.0, validator=attrs.validators.gt(0.0))
    azimuth_bin_deg: float = attrs.field(default=30.0, validator=attrs.validators.gt(0.0))
    altitude_bin_m: float = attrs.field(default=1500.0, validator=attrs.validators.gt(0.0))
    mode_c_tolerance_ft: float = attrs.field(default=300.0, validator=attrs.validators.gt(0.0))


@attrs.define
class RadarAssessment:
    """One radar's figures (name → Estimate), why those missing are missing, its Pd bins, and what the
    report draws: the error residuals (m, deg) and the expected detections (plane x, y, detected)."""

    radar: str
    kind: str
    figures: dict[str, Estimate]
    not_assessable: dict[str, str]
    observability: str
    pd_bins: list[dict]
    residuals: dict[str, np.ndarray]
    expected: dict[str, np.ndarray]


def assess_radar(radar: Radar, plots: PlotTable, match: RadarMatch, bias: BiasState, observability: dict,
                 codes: dict[str, str], addresses: dict[str, str | None], reference_kind: str,
                 config: RadarConfig) -> RadarAssessment:
    """The figures of the module docstring for ``radar``'s ``plots`` (file order) matched in ``match``;
    ``observability``: the coupling graph's report of the radar (:meth:`CouplingGraph.report`: ``status``, the
    estimator's ``measurements``); ``codes`` and ``addresses``: each reference aircraft's Mode 3/A code and
    Mode S address (``None``: not known)."""
    kind = "ssr" if (np.isfinite(plots.altitude_m).any() or any(c is not None for c in plots.mode_3a)
                     or any(c is not None for c in plots.mode_s)) else "psr"
    figures: dict[str, Estimate] = {}
    missing: dict[str, str] = {"timestamp_lateness_s": NOT_ASSESSABLE_LATENESS}
    group, nearest = sweeps(plots.time, match, radar.period_s)
    residuals = _errors(plots, match, bias, int(observability.get("measurements", 0)), nearest, figures)
    _detection(match, group, figures, missing, reference_kind)
    _codes(plots, match, (codes, addresses), config, figures, missing)
    _timestamps(radar, plots, match, nearest, figures)
    return RadarAssessment(radar.id, kind, figures, missing, observability.get("status", "unobserved"),
                           pd_bins(match.expected, config), residuals,
                           {k: match.expected[k] for k in ("x", "y", "range_m", "detected")})


def _errors(plots: PlotTable, match: RadarMatch, bias: BiasState, measured: int, used: np.ndarray,
            figures: dict[str, Estimate]) -> dict[str, np.ndarray]:
    """Systematic and random errors (module docstring) into ``figures`` (``measured``: the measurements the
    estimator took of the radar); the residuals e_ρ (m), e_θ (deg)."""
    figures["range_bias_m"] = stats.normal(bias.range_m, bias.sd_range_m, measured)
    figures["azimuth_bias_deg"] = stats.scaled(stats.normal(bias.azimuth_rad, bias.sd_azimuth_rad, measured),
                                               math.degrees(1.0))
    raw_r = plots.range_m[used] - match.ref_range[used]
    raw_a = wrap_angle(plots.azimuth_rad[used] - match.ref_azimuth[used])
    figures["range_bias_vs_reference_m"] = stats.mean(raw_r)
    figures["azimuth_bias_vs_reference_deg"] = stats.scaled(stats.mean(raw_a), math.degrees(1.0))
    e_r, e_a = raw_r - bias.range_m, np.degrees(wrap_angle(raw_a - bias.azimuth_rad))
    figures["range_sigma_m"] = stats.sigma(e_r)
    figures["azimuth_sigma_deg"] = stats.sigma(e_a)
    return {"range_m": e_r, "azimuth_deg": e_a}


def _detection(match: RadarMatch, group: np.ndarray, figures: dict[str, Estimate],
               missing: dict[str, str], reference_kind: str) -> None:
    """Pd, plots and false plots per scan, split plots (module docstring) into ``figures``."""
    ex = match.expected
    figures["pd"] = stats.proportion(int(ex["detected"].sum()), len(ex["detected"]))
    if len(match.scan):
        first, last = int(match.scan.min()), int(match.scan.max())
        counts = np.bincount(match.scan - first, minlength=last - first + 1)
        figures["plots_per_scan"] = stats.mean(counts)
    else:
        counts = np.zeros(0)
        figures["plots_per_scan"] = stats.missing("t")
    unmatched = int((match.aircraft == "").sum())
    if reference_kind == "truth":
        figures["false_plots_per_scan"] = stats.rate(unmatched, len(counts))
    else:
        missing["false_plots_per_scan"] = ("the ADS-B reference holds only the aircraft that broadcast: a plot "
                                           "far from all of them may be a non-equipped aircraft")
    sizes = np.bincount(group[group >= 0]) if (group >= 0).any() else np.zeros(0, np.int64)
    figures["split_plot_share"] = stats.proportion(int((sizes > 1).sum()), len(sizes))


def sweeps(t: np.ndarray, match: RadarMatch, period_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Each matched plot's sweep group (−1 unmatched): an aircraft's plots sorted by time, a new group after
    a gap over T/2; and the mask of the plot of least d² in each group (the one the random errors use, so
    that a split plot's offset does not count as noise)."""
    group = np.full(len(t), -1, np.int64)
    nearest = np.zeros(len(t), bool)
    matched = np.flatnonzero(match.aircraft != "")
    order = matched[np.lexsort((t[matched], match.aircraft[matched].astype(str)))]
    if not len(order):
        return group, nearest
    new = np.concatenate([[True], (match.aircraft[order][1:] != match.aircraft[order][:-1])
                          | (np.diff(t[order]) > period_s / 2)])
    group[order] = np.cumsum(new) - 1
    best = np.lexsort((match.d2[order], group[order]))  # by group, then by d²: each group's first is its nearest
    first = np.concatenate([[True], np.diff(group[order][best]) != 0])
    nearest[order[best[first]]] = True
    return group, nearest


def _codes(plots: PlotTable, match: RadarMatch, identity: tuple[dict, dict], config: RadarConfig,
           figures: dict[str, Estimate], missing: dict[str, str]) -> None:
    """Mode 3/A, Mode C and Mode S validity and correctness (module docstring) of the matched plots into
    ``figures``; ``identity``: the reference aircraft's Mode 3/A codes and Mode S addresses."""
    codes, addresses = identity
    matched = match.aircraft != ""
    keys = match.aircraft[matched]
    a3 = plots.mode_3a[matched]
    alt = plots.altitude_m[matched]
    ms = plots.mode_s[matched]
    has_3a = np.array([codes.get(k) is not None for k in keys], bool)
    if any(c is not None for c in plots.mode_3a) and has_3a.any():
        present = np.array([c is not None for c in a3], bool)
        figures["mode_3a_validity"] = stats.proportion(int((present & has_3a).sum()), int(has_3a.sum()))
        right = np.array([c == codes.get(k) for c, k in zip(a3, keys)], bool)
        figures["mode_3a_correctness"] = stats.proportion(int((right & present).sum()), int((present & has_3a).sum()))
    else:
        missing["mode_3a_validity"] = missing["mode_3a_correctness"] = "no plot carries a Mode 3/A code"
    squawking = np.isin(keys, np.unique(match.aircraft[np.isfinite(plots.altitude_m) & (match.aircraft != "")]))
    if squawking.any():
        valid = np.isfinite(alt)
        figures["mode_c_validity"] = stats.proportion(int((valid & squawking).sum()), int(squawking.sum()))
        close = np.abs(alt - match.ref_altitude[matched]) <= config.mode_c_tolerance_ft * FT
        figures["mode_c_correctness"] = stats.proportion(int((close & valid).sum()), int(valid.sum()))
    else:
        missing["mode_c_validity"] = missing["mode_c_correctness"] = "no matched plot carries a Mode C altitude"
    present = np.array([c is not None and addresses.get(k) is not None for c, k in zip(ms, keys)], bool)
    if present.any():
        right = np.array([c == addresses.get(k) for c, k in zip(ms, keys)], bool)
        figures["mode_s_correctness"] = stats.proportion(int((right & present).sum()), int(present.sum()))
    else:
        missing["mode_s_correctness"] = "no matched plot of an aircraft of known address carries a Mode S address"


def _timestamps(radar: Radar, plots: PlotTable, match: RadarMatch, used: np.ndarray,
                figures: dict[str, Estimate]) -> None:
    """Ordering, and the σ of the time stamps' offsets from the antenna position over the ``used`` plots
    (module docstring)."""
    t = plots.time
    late = t[1:] < np.maximum.accumulate(t)[:-1] if len(t) > 1 else np.zeros(0, bool)
    figures["out_of_order_share"] = stats.proportion(int(late.sum()), len(t))
    _, offset = antenna_offsets(t[used], plots.azimuth_rad[used], radar.period_s, match.north_time)
    figures["timestamp_jitter_s"] = stats.sigma(offset)


def pd_bins(expected: dict[str, np.ndarray], config: RadarConfig) -> list[dict]:
    """Pd by slant-range, azimuth and altitude bin: rows of variable, bin bounds, crossings, detections, Pd and
    its Wilson interval (bins without a crossing left out)."""
    rows = []
    for variable, values, width in (("range_km", expected["range_m"] / 1000.0, config.range_bin_km),
                                    ("azimuth_deg", expected["azimuth_deg"], config.azimuth_bin_deg),
                                    ("altitude_m", expected["altitude_m"], config.altitude_bin_m)):
        if not len(values):
            continue
        b = np.floor(values / width).astype(np.int64)
        for k in np.unique(b).tolist():
            sel = b == k
            e = stats.proportion(int(expected["detected"][sel].sum()), int(sel.sum()))
            rows.append({"variable": variable, "bin_low": k * width, "bin_high": (k + 1) * width,
                         "crossings": e.n, "detected": int(expected["detected"][sel].sum()),
                         "pd": e.value, "ci_low": e.low, "ci_high": e.high})
    return rows
