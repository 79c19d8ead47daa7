"""One radar's figures, each an :class:`~radartracker.assessment.stats.Estimate` with its 95 % interval.

With the plots matched to the reference (:mod:`radartracker.assessment.matching`; Δr̂, Δθ̂ the joint
estimator's biases):

* **Systematic errors**: the joint estimator's Δr̂ and Δθ̂ ± 1.96 σ (its own covariance); and the sensor
  errors fitted to the residuals against the reference (:mod:`radartracker.assessment.systematic`): range
  and azimuth offsets, range gain and time-stamp offset ± 1.96 σ (σ the fit's Cramér–Rao bound), each with
  its observability — an unobservable one is not a figure, and says why.
* **Random errors**: σ_ρ and σ_θ of the residuals left by that fit (χ², n − 3 and n − 2 degrees of freedom),
  over the plot nearest the reference in each sweep of an aircraft (a split plot is not noise); the
  correlation of the two (Fisher's z) and their covariance, the report's error ellipse
  (:mod:`radartracker.assessment.ellipse`).
* **Pd**: detected crossings / crossings inside the coverage (Wilson), overall and by range, azimuth and
  altitude bin; by elevation bin over the crossings above the assumed cone of silence too.
* **Cone of silence and coverage achieved**: measured from the crossings
  (:mod:`radartracker.assessment.coverage`): the elevation above which Pd drops (a step fit), the farthest
  slant range at which Pd meets a stated level, over all azimuths and per azimuth sector, and the share of
  the configured coverage it reaches.
* **Plots per scan**: the mean of the plot counts of the revolutions from the first plot to the last (t).
* **False plots per scan**: plots with no reference in the gate, reflections excepted / revolutions (Poisson,
  Garwood) — only against the truth: an ADS-B reference lacks the aircraft that do not broadcast.
* **Reflections**: plots with no reference in the gate that carry a reference aircraft's Mode S address (or,
  without one, a Mode 3/A code a matched plot carries) — an aircraft's reply seen where it is not — per
  sweep of an aircraft that replies with a code (Wilson or Clopper–Pearson); not assessable where no plot
  carries a code (a primary aircraft's reflection has nothing to tell it by: it counts as a false plot).
* **Split plots**: an aircraft's matched plots fall in groups (gaps > T/2 between groups, one group per
  sweep); the share of groups with two plots or more.
* **Codes**: Mode 3/A validity (a code present) and correctness (the aircraft's code), Mode C validity
  (an altitude present) and correctness (within :attr:`RadarConfig.mode_c_tolerance_ft` of the
  reference's height), Mode S address correctness — over the matched plots of aircraft that carry them.
* **Time stamps**: the share of plots stamped earlier than a plot before them in the file (ordering), and
  the σ of the offsets of the plots used for the random errors from the time their antenna pointed at
  their azimuth (:func:`radartracker.assessment.matching.antenna_offsets`; with an exact clock it is
  σ_θ T/2π; its mean is taken up by the antenna phase t_N, so a constant time-stamp bias does not show
  here); the lateness, delivery − time stamp (``PlotTable.received − time``, over all the radar's plots): its
  95th percentile with the order-statistic interval. Only a recording that says when each plot was delivered
  (a pcap capture) has it; elsewhere not assessable. A plot delivered before its time stamp makes it
  negative: the recorder's clock or the radar's time stamping is wrong.
"""

from __future__ import annotations

import math

import attrs
import numpy as np

from radartracker.assessment import stats
from radartracker.assessment.coverage import CoverageConfig, achieved_coverage, measure_cone
from radartracker.assessment.ellipse import ErrorEllipse, error_ellipse
from radartracker.assessment.stats import Estimate
from radartracker.assessment.systematic import SensorFit, fit_sensor_errors
from radartracker.assessment.tally import RadarTally
from radartracker.domain import BiasState, Radar

FT = 0.3048
NOT_ASSESSABLE_LATENESS = "the recording does not say when its plots were delivered (only a pcap capture does)"
#: the fitted components' figures, and their units' scale from the fit's (m, rad, 1, s)
FIT_FIGURES = {"range_offset": ("range_bias_vs_reference_m", 1.0), "azimuth_offset": ("azimuth_bias_vs_reference_deg",
               math.degrees(1.0)), "range_gain": ("range_gain_ppm", 1e6), "time_offset": ("time_offset_ms", 1e3)}


@attrs.frozen
class RadarConfig:
    """The bins of Pd by range, azimuth and altitude, the Mode C tolerance, and the bins and levels of the
    measured cone of silence and coverage."""

    range_bin_km: float = attrs.field(default=25.0, validator=attrs.validators.gt(0.0))
    azimuth_bin_deg: float = attrs.field(default=30.0, validator=attrs.validators.gt(0.0))
    altitude_bin_m: float = attrs.field(default=1500.0, validator=attrs.validators.gt(0.0))
    mode_c_tolerance_ft: float = attrs.field(default=300.0, validator=attrs.validators.gt(0.0))
    coverage: CoverageConfig = attrs.field(factory=CoverageConfig)


@attrs.define
class RadarAssessment:
    """One radar's figures (name → Estimate), why those missing are missing, its Pd bins, and what the
    report draws: the error residuals (m, deg) and the expected detections inside the coverage (plane x, y,
    detected); ``observability``: the coupling graph's status of its biases, ``components``: each fitted sensor
    error's (``observable``, ``weak``, ``unobservable``); ``coverage``: the coverage diagram, per azimuth sector
    (:func:`radartracker.assessment.coverage.achieved_coverage`); ``scan_counts``: its plots in each antenna
    revolution, first to last; ``ellipse``: its error scatter against its stated σ's (None without a fit)."""

    radar: str
    kind: str
    figures: dict[str, Estimate]
    not_assessable: dict[str, str]
    observability: str
    pd_bins: list[dict]
    residuals: dict[str, np.ndarray]
    expected: dict[str, np.ndarray]
    components: dict[str, str] = attrs.field(factory=dict)
    coverage: list[dict] = attrs.field(factory=list)
    scan_counts: np.ndarray = attrs.field(factory=lambda: np.zeros(0, np.int64))
    ellipse: ErrorEllipse | None = None


def assess_radar(radar: Radar, tally: RadarTally, stamps: tuple[int, np.ndarray], bias: BiasState,
                 observability: dict, codes: dict[str, str], reference_kind: str,
                 config: RadarConfig) -> RadarAssessment:
    """The figures of the module docstring for ``radar`` from its sums over the recording (``tally``, every
    slice's merged: :mod:`radartracker.assessment.tally`) and its time stamps (``stamps``: the count of its
    plots out of order in the file and each plot's lateness, s, NaN where not known);
    ``observability``: the coupling graph's report of the radar (:meth:`CouplingGraph.report`: ``status``, the
    estimator's ``measurements``); ``codes``: each reference aircraft's Mode 3/A code."""
    kind = "ssr" if tally.carries.any() else "psr"
    figures: dict[str, Estimate] = {}
    missing: dict[str, str] = {}
    _errors(tally, bias, int(observability.get("measurements", 0)), figures)
    components, fit = _sensor_errors(radar.id, tally, figures, missing)
    ellipse = None if fit is None else error_ellipse(radar, tally.sensor, fit, tally.sample)
    if ellipse is None:
        missing["range_azimuth_correlation"] = "fewer than five plots matched to the reference"
    else:
        figures["range_azimuth_correlation"] = ellipse.correlation()
    crossings = tally.expected_table()
    expected = {k: v[~crossings["above_cone"]] for k, v in crossings.items()}  # inside the assumed coverage
    counts = _detection(tally, expected, figures, missing, reference_kind)
    cone, why = measure_cone(crossings["elevation_deg"], crossings["detected"], config.coverage)
    if cone is None:
        missing["cone_of_silence_deg"] = why
    else:
        figures["cone_of_silence_deg"] = cone
    reach, unreached, diagram = achieved_coverage(expected["range_m"], expected["azimuth_deg"], expected["detected"],
                                                  radar.max_range_m, config.coverage)
    figures |= reach
    missing |= unreached
    _codes(tally, codes, figures, missing)
    _time_stamps(tally, *stamps, figures, missing)
    return RadarAssessment(radar.id, kind, figures, missing, observability.get("status", "unobserved"),
                           pd_bins(crossings, config), tally.error_arrays(),
                           {k: expected[k] for k in ("x", "y", "range_m", "detected")}, components, diagram,
                           counts, ellipse)


def _time_stamps(tally: RadarTally, out_of_order: int, lateness: np.ndarray, figures: dict[str, Estimate],
                 missing: dict[str, str]) -> None:
    """Ordering, jitter and lateness (module docstring) into ``figures``, or why not into ``missing``."""
    figures["out_of_order_share"] = stats.proportion(out_of_order, tally.plots)
    figures["timestamp_jitter_s"] = stats.sigma(tally.offsets)
    known = lateness[np.isfinite(lateness)]
    if len(known):
        figures["timestamp_lateness_s"] = stats.quantile(known, 0.95)
    else:
        missing["timestamp_lateness_s"] = NOT_ASSESSABLE_LATENESS


def _errors(tally: RadarTally, bias: BiasState, measured: int, figures: dict[str, Estimate]) -> None:
    """Systematic and random errors (module docstring) into ``figures`` (``measured``: the measurements the
    estimator took of the radar)."""
    figures["range_bias_m"] = stats.normal(bias.range_m, bias.sd_range_m, measured)
    figures["azimuth_bias_deg"] = stats.scaled(stats.normal(bias.azimuth_rad, bias.sd_azimuth_rad, measured),
                                               math.degrees(1.0))


def _sensor_errors(radar: str, tally: RadarTally, figures: dict[str, Estimate],
                   missing: dict[str, str]) -> tuple[dict[str, str], SensorFit | None]:
    """The sensor errors fitted against the reference and the random errors they leave (module docstring) into
    ``figures`` (an unobservable component into ``missing``, with why); returns each component's status and
    the fit (None with too few plots)."""
    fit = fit_sensor_errors(radar, tally.sensor)
    if fit is None:
        for name in (*(f for f, _ in FIT_FIGURES.values()), "range_sigma_m", "azimuth_sigma_deg"):
            missing[name] = "fewer than five plots matched to the reference"
        return {}, None
    n = tally.sensor.n
    for bound in fit.bounds:
        name, scale = FIT_FIGURES[bound.component]
        value, sd, status = fit.component(bound.component)
        if status == "unobservable":
            missing[name] = (f"unobservable: the plots' geometry adds less than 11 % of the prior's information "
                             f"(√CRLB {sd * scale:.4g} against a prior σ of {bound.prior_sd * scale:.4g})")
        else:
            figures[name] = stats.scaled(stats.normal(value, sd, n), scale)
    (rss_r, rss_a), (dof_r, dof_a) = fit.rss, fit.dof
    figures["range_sigma_m"] = stats.sigma_of_sum(rss_r, dof_r, n)
    figures["azimuth_sigma_deg"] = stats.scaled(stats.sigma_of_sum(rss_a, dof_a, n), math.degrees(1.0))
    return {b.component: b.status for b in fit.bounds}, fit


def _detection(tally: RadarTally, expected: dict[str, np.ndarray], figures: dict[str, Estimate],
               missing: dict[str, str], reference_kind: str) -> np.ndarray:
    """Pd, plots and false plots per scan, split plots (module docstring) into ``figures``; returns the plots
    of each revolution, first to last."""
    figures["pd"] = stats.proportion(int(expected["detected"].sum()), len(expected["detected"]))
    if tally.scans:
        first, last = min(tally.scans), max(tally.scans)
        counts = np.zeros(last - first + 1)
        for scan, c in tally.scans.items():
            counts[scan - first] = c
        figures["plots_per_scan"] = stats.mean(counts)
    else:
        counts = np.zeros(0)
        figures["plots_per_scan"] = stats.missing("t")
    if reference_kind == "truth":
        figures["false_plots_per_scan"] = stats.rate(tally.unmatched - tally.reflections, len(counts))
    else:
        missing["false_plots_per_scan"] = ("the ADS-B reference holds only the aircraft that broadcast: a plot "
                                           "far from all of them may be a non-equipped aircraft")
    figures["split_plot_share"] = stats.proportion(tally.split_sweeps, tally.sweeps)
    if tally.coded_sweeps:
        figures["reflection_share"] = stats.proportion(tally.reflections, tally.coded_sweeps)
    else:
        missing["reflection_share"] = "no plot carries a Mode 3/A code or Mode S address to tell a reflection by"
    return counts.astype(np.int64)


def _codes(tally: RadarTally, codes: dict[str, str], figures: dict[str, Estimate], missing: dict[str, str]) -> None:
    """Mode 3/A, Mode C and Mode S validity and correctness (module docstring) of the matched plots into
    ``figures``; ``codes``: the reference aircraft's Mode 3/A codes."""
    known = [(codes.get(k), c, n) for (k, c), n in tally.mode_3a.items() if codes.get(k) is not None]
    if tally.carries[1] and known:
        present = sum(n for _, c, n in known if c is not None)
        figures["mode_3a_validity"] = stats.proportion(present, sum(n for *_, n in known))
        figures["mode_3a_correctness"] = stats.proportion(sum(n for want, c, n in known if c == want), present)
    else:
        missing["mode_3a_validity"] = missing["mode_3a_correctness"] = "no plot carries a Mode 3/A code"
    c = tally.mode_c
    squawking = [k for k, n in c.get("valid", {}).items() if n > 0]
    if squawking:
        valid = sum(c["valid"].values())
        figures["mode_c_validity"] = stats.proportion(valid, sum(c["matched"][k] for k in squawking))
        figures["mode_c_correctness"] = stats.proportion(sum(c["close"].values()), valid)
    else:
        missing["mode_c_validity"] = missing["mode_c_correctness"] = "no matched plot carries a Mode C altitude"
    if tally.mode_s[0]:
        figures["mode_s_correctness"] = stats.proportion(int(tally.mode_s[1]), int(tally.mode_s[0]))
    else:
        missing["mode_s_correctness"] = "no matched plot of an aircraft of known address carries a Mode S address"


def pd_bins(crossings: dict[str, np.ndarray], config: RadarConfig) -> list[dict]:
    """Pd by slant-range, azimuth and altitude bin of the crossings inside the assumed coverage, and by
    elevation bin of all of them (above the assumed cone of silence too: what the measured cone is read
    from): rows of variable, bin bounds, crossings, detections, Pd and its Wilson interval (bins without a
    crossing left out)."""
    rows = []
    inside = ~crossings["above_cone"]
    for variable, values, width, sel in (
            ("range_km", crossings["range_m"] / 1000.0, config.range_bin_km, inside),
            ("azimuth_deg", crossings["azimuth_deg"], config.azimuth_bin_deg, inside),
            ("altitude_m", crossings["altitude_m"], config.altitude_bin_m, inside),
            ("elevation_deg", crossings["elevation_deg"], config.coverage.elevation_bin_deg, np.ones_like(inside))):
        values, detected = values[sel], crossings["detected"][sel]
        if not len(values):
            continue
        b = np.floor(values / width).astype(np.int64)
        for k in np.unique(b).tolist():
            hit = b == k
            e = stats.proportion(int(detected[hit].sum()), int(hit.sum()))
            rows.append({"variable": variable, "bin_low": k * width, "bin_high": (k + 1) * width,
                         "crossings": e.n, "detected": int(detected[hit].sum()),
                         "pd": e.value, "ci_low": e.low, "ci_high": e.high})
    return rows
