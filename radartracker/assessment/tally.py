"""One radar's sufficient statistics over a time slice, and their sum over the slices of a recording.

Every figure of :mod:`radartracker.assessment.radar` is a function of sums over the radar's plots, sweeps
and expected crossings: counts (plots per revolution, unmatched plots and reflections among them, split
sweeps, each code's plots per aircraft, Mode S plots), the sums of the sensor-error fit
(:mod:`radartracker.assessment.systematic`), :class:`~radartracker.assessment.stats.Moments` of the
time-stamp offsets (their n, mean and M₂, merged exactly), the expected crossings themselves (Pd, its bins
and map) and a bounded sample of the plots for the error scatter
(:class:`~radartracker.assessment.ellipse.ErrorSample`, merged to the one-pass sample). A slice's
:class:`RadarTally` holds those sums for the plots stamped inside the slice [t₀, t₁) and the sweeps whose
first plot is, and :meth:`RadarTally.merge` adds two slices: counts exactly, sums and moments to round-off,
the sample exactly. Every plot is counted in exactly one slice, by its time; the margin either side of a slice
(:mod:`radartracker.assessment.slices`) only lets its sweeps, detections and crossings see across the
boundary.
"""

from __future__ import annotations

from collections import Counter

import attrs
import numpy as np

from radartracker.assessment.ellipse import ErrorSample
from radartracker.assessment.matching import RadarMatch, antenna_offsets, wrap_angle
from radartracker.assessment.stats import Moments
from radartracker.assessment.systematic import SensorSums
from radartracker.io.tables import PlotTable, label_spans

EXPECTED = ("aircraft", "time", "range_m", "azimuth_deg", "elevation_deg", "altitude_m", "x", "y", "above_cone",
            "detected")


def merge_spans(a: dict[str, tuple[float, float]], b: dict[str, tuple[float, float]]) -> dict:
    """Each key's (first, last) time over both ``a`` and ``b``."""
    out = dict(a)
    for k, (lo, hi) in b.items():
        lo0, hi0 = out.get(k, (lo, hi))
        out[k] = (min(lo0, lo), max(hi0, hi))
    return out


@attrs.define
class RadarTally:
    """One radar's sums over a slice (module docstring).

    Of the sweeps' nearest plots: ``offsets``, the moments of their time-stamp offsets (s); ``errors``, their
    errors e_ρ (m) and e_θ (deg) with the joint estimator's bias removed, for the report's histograms;
    ``sensor``, the sums of the sensor-error fit of their raw residuals ρ − ρ_ref and θ − θ_ref
    (:class:`~radartracker.assessment.systematic.SensorSums`) and ``sample``, a bounded number of them with those
    residuals, for the report's error scatter (:class:`~radartracker.assessment.ellipse.ErrorSample`).
    ``scans``: plots per antenna revolution (revolution → count). ``unmatched``: plots matched to no reference
    aircraft, ``reflections`` those of them carrying a reference aircraft's code (:func:`reflections`);
    ``coded_sweeps``: the sweeps whose plot carries a code (of an aircraft whose reflections can be told).
    ``mode_3a``: matched plots per (aircraft, code or None); ``mode_c``: per aircraft, matched plots, those with
    an altitude and those within the tolerance; ``mode_s``: [plots of a known address carrying one, right
    ones]. ``carries``: whether any plot carries an altitude, a Mode 3/A code, a Mode S address. ``spans``:
    each aircraft's first and last matched plot time."""

    plots: int = 0
    unmatched: int = 0
    reflections: int = 0
    sweeps: int = 0
    coded_sweeps: int = 0
    split_sweeps: int = 0
    offsets: Moments = attrs.field(factory=Moments)
    errors: dict[str, list[np.ndarray]] = attrs.field(factory=lambda: {"range_m": [], "azimuth_deg": []})
    sensor: SensorSums = attrs.field(factory=SensorSums)
    sample: ErrorSample = attrs.field(factory=ErrorSample)
    scans: Counter = attrs.field(factory=Counter)
    mode_3a: Counter = attrs.field(factory=Counter)
    mode_c: dict[str, Counter] = attrs.field(factory=dict)
    mode_s: np.ndarray = attrs.field(factory=lambda: np.zeros(2, np.int64))
    carries: np.ndarray = attrs.field(factory=lambda: np.zeros(3, bool))
    expected: dict[str, list[np.ndarray]] = attrs.field(factory=lambda: {k: [] for k in EXPECTED})
    spans: dict[str, tuple[float, float]] = attrs.field(factory=dict)

    def merge(self, other: RadarTally) -> RadarTally:
        """The sums of both slices (module docstring): ``self`` updated and returned."""
        self.plots += other.plots
        self.unmatched += other.unmatched
        self.reflections += other.reflections
        self.sweeps += other.sweeps
        self.coded_sweeps += other.coded_sweeps
        self.split_sweeps += other.split_sweeps
        self.offsets = self.offsets.merge(other.offsets)
        self.sensor = self.sensor.merge(other.sensor)
        self.sample = self.sample.merge(other.sample)
        for k, v in other.errors.items():
            self.errors[k] += v
        self.scans.update(other.scans)
        self.mode_3a.update(other.mode_3a)
        for k, v in other.mode_c.items():
            self.mode_c[k] = self.mode_c.get(k, Counter()) + v
        self.mode_s = self.mode_s + other.mode_s
        self.carries = self.carries | other.carries
        for k, v in other.expected.items():
            self.expected[k] += v
        self.spans = merge_spans(self.spans, other.spans)
        return self

    def expected_table(self) -> dict[str, np.ndarray]:
        """The expected crossings of every slice as one table (:attr:`RadarMatch.expected`'s columns)."""
        kinds = {"aircraft": object, "above_cone": bool, "detected": bool}
        return {k: np.concatenate(v) if v else np.empty(0, kinds.get(k, float)) for k, v in self.expected.items()}

    def error_arrays(self) -> dict[str, np.ndarray]:
        """e_ρ (m) and e_θ (deg) of every slice's sweeps."""
        return {k: np.concatenate(v) if v else np.empty(0) for k, v in self.errors.items()}


def tally(plots: PlotTable, match: RadarMatch, bias: tuple[float, float], period_s: float,
          addresses: dict[str, str | None], config_tolerance_m: float,
          keep: tuple[float, float] = (-np.inf, np.inf)) -> RadarTally:
    """The sums of one radar's ``plots`` (a slice and its margin, matched in ``match``) over the slice
    ``keep`` = [t₀, t₁): the plots stamped inside it, the sweeps whose first plot is, and the crossings
    ``match`` kept (module docstring). ``bias``: the estimator's Δr̂ (m), Δθ̂ (rad); ``addresses``: each
    reference aircraft's Mode S address (None: not known); ``config_tolerance_m``: the Mode C tolerance."""
    out = RadarTally()
    own = (plots.time >= keep[0]) & (plots.time < keep[1])
    group, nearest = sweeps(plots.time, match, period_s)
    first_own = _first_plot_own(plots.time, group, keep)
    used = nearest & first_own[np.maximum(group, 0)] & (group >= 0)
    _residuals(plots, match, bias, used, period_s, out)
    sizes = np.bincount(group[group >= 0], minlength=len(first_own)) if len(first_own) else np.zeros(0, np.int64)
    out.sweeps, out.split_sweeps = int(first_own.sum()), int(((sizes > 1) & first_own).sum())
    out.coded_sweeps = sum(1 for s, a in zip(plots.mode_s[used].tolist(), plots.mode_3a[used].tolist())
                           if s is not None or a is not None)
    out.plots = int(own.sum())
    lost = own & (match.aircraft == "")
    out.unmatched = int(lost.sum())
    out.reflections = reflections(plots, match, lost, addresses)
    out.scans = Counter(dict(zip(*(a.tolist() for a in np.unique(match.scan[own], return_counts=True)))))
    _codes(plots, match, own, addresses, config_tolerance_m, out)
    for k in EXPECTED:
        out.expected[k].append(match.expected[k])
    matched = own & (match.aircraft != "")
    out.spans = label_spans(plots.time[matched], match.aircraft[matched])
    return out


def reflections(plots: PlotTable, match: RadarMatch, lost: np.ndarray, addresses: dict[str, str | None]) -> int:
    """The plots of ``lost`` (matched to no reference aircraft) that carry a reference aircraft's Mode S address,
    or, without an address, a Mode 3/A code that a matched plot of the radar carries: an aircraft's reply seen
    where no aircraft is, a reflection."""
    known = {a for a in addresses.values() if a is not None}
    codes = {c for c in plots.mode_3a[match.aircraft != ""].tolist() if c is not None}
    rows = np.flatnonzero(lost)
    return sum(1 for s, a in zip(plots.mode_s[rows].tolist(), plots.mode_3a[rows].tolist())
               if (s in known if s is not None else a is not None and a in codes))


def _first_plot_own(t: np.ndarray, group: np.ndarray, keep: tuple[float, float]) -> np.ndarray:
    """Per sweep group, whether its first plot (by time) lies in the slice ``keep``: the slice that counts it."""
    n = int(group.max()) + 1 if len(group) and group.max() >= 0 else 0
    first_t = np.full(n, np.inf)
    g = group >= 0
    np.minimum.at(first_t, group[g], t[g])
    return (first_t >= keep[0]) & (first_t < keep[1])


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


def _residuals(plots: PlotTable, match: RadarMatch, bias: tuple[float, float], used: np.ndarray,
               period_s: float, out: RadarTally) -> None:
    """The ``used`` plots' errors, the moments of their time-stamp offsets, the sums of their sensor-error
    fit and their sample (module docstring) into ``out``."""
    raw_r = plots.range_m[used] - match.ref_range[used]
    raw_a = wrap_angle(plots.azimuth_rad[used] - match.ref_azimuth[used])
    reference = (match.ref_range[used], match.ref_rate[0, used], match.ref_rate[1, used])
    out.sensor = SensorSums.of(raw_r, raw_a, *reference)
    out.sample = ErrorSample.of(plots.time[used], raw_r, raw_a, *reference)
    e_r, e_a = raw_r - bias[0], np.degrees(wrap_angle(raw_a - bias[1]))
    _, offset = antenna_offsets(plots.time[used], plots.azimuth_rad[used], period_s, match.north_time)
    out.offsets = Moments.of(offset)
    out.errors["range_m"].append(e_r)
    out.errors["azimuth_deg"].append(e_a)


def _codes(plots: PlotTable, match: RadarMatch, own: np.ndarray, addresses: dict[str, str | None],
           tolerance_m: float, out: RadarTally) -> None:
    """The code counts of the slice's matched plots (:class:`RadarTally`) into ``out``."""
    matched = own & (match.aircraft != "")
    keys = match.aircraft[matched].tolist()
    alt = plots.altitude_m[matched]
    out.mode_3a = Counter(zip(keys, plots.mode_3a[matched].tolist()))
    valid = np.isfinite(alt)
    close = valid & (np.abs(alt - match.ref_altitude[matched]) <= tolerance_m)
    for name, flags in (("matched", np.ones(len(keys), bool)), ("valid", valid), ("close", close)):
        out.mode_c[name] = Counter(k for k, f in zip(keys, flags.tolist()) if f)
    ms = plots.mode_s[matched].tolist()
    present = [c is not None and addresses.get(k) is not None for c, k in zip(ms, keys)]
    right = [p and c == addresses.get(k) for p, c, k in zip(present, ms, keys)]
    out.mode_s = np.array([sum(present), sum(right)], np.int64)
    out.carries = np.array([bool(np.isfinite(plots.altitude_m[own]).any()),
                            any(c is not None for c in plots.mode_3a[own]),
                            any(c is not None for c in plots.mode_s[own])])
