"""What a run produced — one type for both associations — and its evaluation against the truth.

``summary.json`` (docs/formats.md) is :meth:`RunResult.summary`: settings, reference point, input
accounting, final biases with their errors and z-scores against ``truth_biases.csv``, the estimates'
errors against ``truth.csv`` (RMSE, NEES) and the track metrics (continuity, breaks, swaps, false
tracks, GOSPA; :func:`radartracker.pipeline.evaluate.track_metrics`), and a consistency check:

* mean NEES of the track estimates against the truth (4 degrees of freedom: expected 4), with the 95 % band
  of a mean of that many values correlated as they are (:mod:`radartracker.pipeline.consistency`);
* mean NIS of the estimator's innovations (2 degrees of freedom: expected 2; labelled path) and of the track
  filters' (with the band of independent values: a consistent filter's innovations are white).

A mean more than :data:`CONSISTENCY_FACTOR` times off its expectation (either way) gives a warning in the log
and in ``summary.json`` (once: :meth:`RunResult.summary_table` shows the values, not the warnings again), saying
what it means and what to change (:func:`consistency_warning`).
"""

from __future__ import annotations

import functools
import logging
import math
from typing import TYPE_CHECKING

import attrs
import numpy as np
import pyarrow as pa

from radartracker.domain import BiasState
from radartracker.errors import ConfigurationError
from radartracker.estimation.coupling import CouplingGraph
from radartracker.geometry.plane import SystemPlane
from radartracker.io.tables import ScenarioData, label_spans
from radartracker.pipeline.config import RunConfig
from radartracker.pipeline.consistency import effective_count, mean_chi2_band
from radartracker.pipeline.evaluate import (GridSpec, TrackHistory, TruthPaths, detection_gaps, nees, state_errors,
                                            track_metrics)
from radartracker.pipeline.outputs import bias_table, event_tables
from radartracker.pipeline.recorder import BiasLog, Events
from radartracker.tracking.events import ENDS

if TYPE_CHECKING:  # pandas is imported by pyarrow's to_pandas, when a DataFrame is asked for
    import pandas as pd

log = logging.getLogger(__name__)
CONSISTENCY_FACTOR = 2.0


# what each mean is of, and whose innovations or errors it weighs
_CONSISTENCY = {"nees": ("NEES", "the track estimates' errors", ""),
                "nis": ("NIS of the estimator", "the estimator's innovations", " or the radars' σ in radars.csv"),
                "track_nis": ("NIS of the track filters", "the track filters' innovations",
                              " or the radars' σ in radars.csv")}


def consistency_warning(what: str, value: float, dof: float, q: float) -> str:
    """What a mean NEES (``what`` "nees": the track estimates against the truth) or NIS ("nis": the
    estimator's innovations, "track_nis": the track filters') of ``value`` against its expectation ``dof``
    means, and what to change: the errors are √(value / dof) times the σ the filter states. Too large: its
    covariance is too small (overconfident), the process noise q (m²/s³) too small for how the aircraft move
    (a NIS: or the radars' σ too small); too small: the other way round (docs/user-guide.md, "When a run
    warns")."""
    name, errors, sigmas = _CONSISTENCY[what]
    if value > dof:
        meaning = (f"the filter is overconfident: q = {q:g} m²/s³{sigmas} too small for how these aircraft move; "
                   "raise --q")
    else:
        meaning = f"the filter is too cautious: q = {q:g} m²/s³{sigmas} larger than these aircraft need; lower --q"
    return (f"mean {name} {value:.2f} against {dof:.0f} expected: {errors} are {math.sqrt(value / dof):.1f} times "
            f"the σ the filter states ({meaning}; docs/user-guide.md, 'When a run warns')")


GRACE_S = 20.0  # a target counts as observed this long after its first plot (M-of-N confirmation)


def observed_spans(spans: dict[str, tuple[float, float]]) -> dict[str, tuple[float, float]]:
    """Each aircraft's observed time from its plots' first and last times ``spans``: from ``GRACE_S`` after the
    first (a track needs that long to be confirmed) to the last; aircraft seen for less are left out."""
    return {k: (lo + GRACE_S, hi) for k, (lo, hi) in spans.items() if hi - lo > GRACE_S}


_PLAIN = frozenset({str, int, bool, type(None)})  # exact types strict() gives back as they are


def strict(value):
    """``value`` with every non-finite float replaced by ``None`` (strict JSON: null, never NaN)."""
    t = type(value)  # the exact types of a summary's ~700 values first, without a call per plain value
    if t is float:
        return value if math.isfinite(value) else None
    if t in _PLAIN:
        return value
    if isinstance(value, dict):
        return {k if type(k) is str else str(k): v if type(v) in _PLAIN else strict(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [v if type(v) in _PLAIN else strict(v) for v in value]
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, np.integer):
        return int(value)
    return value


def _fmt(value: float | None, spec: str) -> str:
    return "-".rjust(int(spec.split(".")[0] or 0)) if value is None else format(value, spec)


@attrs.define
class RunResult:
    """A run's events (track estimates among them), bias history, final biases, counts and timing.

    ``config`` is the effective configuration (what ``config.json`` holds); ``plugins`` the estimator's
    and motion model's effective typed settings. A streamed run (``streamed``) wrote its events and
    biases as it went and holds them only if the evaluation against truth needs them (``data.truth``).
    """

    data: ScenarioData
    config: RunConfig
    plane: SystemPlane
    events: Events
    biases: BiasLog
    final_biases: dict[str, BiasState]
    counts: dict[str, int]  # every input under the reason it was used or refused
    seconds: float
    mean_nis: float  # the estimator's mean normalised innovation νᵀΛ⁻¹ν over the run (NaN: none)
    coupling: CouplingGraph
    plugins: dict = attrs.field(factory=dict)
    #: the tables were written as the run went (``events`` then holds only what the evaluation needs)
    streamed: bool = False
    #: the number of tracks with an estimate (``None``: counted from ``events``)
    track_count: int | None = None
    #: what happened to tracks beyond their events (``tracks_reinitialised``), apart from the inputs' counts
    track_counts: dict[str, int] = attrs.field(factory=dict)
    #: the confirmed tracks' innovations (:meth:`TrackManager.innovations`: ``count``, ``mean_nis``)
    track_nis: dict[str, float] = attrs.field(factory=lambda: {"count": 0, "mean_nis": math.nan})
    #: first and last plot time of each truth label (``None``: from ``data.plots``; see :func:`label_spans`)
    label_spans: dict[str, tuple[float, float]] | None = None

    @property
    def estimator_name(self) -> str:
        return str(self.config.estimator)

    @functools.cached_property
    def tracks(self) -> Events:
        """The track estimates (events ``confirmed`` and ``updated``), as in ``tracks.csv``."""
        return self.events.estimates()

    def _held(self) -> None:
        """Refuse a table of a run that streamed them into its output folder and kept none (no truth)."""
        if self.streamed and self.data.truth is None:
            raise ConfigurationError("this run streamed its tables into its output folder and kept none: read them "
                                     "with radartracker.pipeline.outputs.read_output(OUT / 'tracks.csv').to_pandas()")

    def _event_tables(self) -> tuple[pa.Table, pa.Table]:
        self._held()
        return event_tables(self.events, self.plane)

    def tracks_frame(self) -> pd.DataFrame:
        """The track estimates as a DataFrame: the columns, units and values of ``tracks.csv`` (docs/formats.md;
        a value not known is NaN or None)."""
        return self._event_tables()[1].to_pandas()

    def events_frame(self) -> pd.DataFrame:
        """Every track event as a DataFrame: the columns, units and values of ``events.csv``."""
        return self._event_tables()[0].to_pandas()

    def biases_frame(self) -> pd.DataFrame:
        """The bias estimates over time as a DataFrame: the columns, units and values of ``biases.csv``."""
        self._held()
        return bias_table(self.biases).to_pandas()

    def track_ends(self) -> dict[int, float]:
        """The tracks that ended (deleted, or merged into another), each at its first such event's time."""
        ev = self.events
        deleted = np.isin(ev.kind, ENDS)
        return dict(zip(ev.track[deleted][::-1].tolist(), ev.time[deleted][::-1].tolist()))  # first deletion wins

    def histories(self) -> dict[int, TrackHistory]:
        """Each track's estimates and life span (created to deleted, or to its last estimate)."""
        est = self.tracks
        end = self.track_ends()
        order = np.argsort(est.track, kind="stable")
        ids, first = np.unique(est.track[order], return_index=True)
        out = {}
        for tid, idx in zip(ids.tolist(), np.split(order, first[1:]) if len(order) else []):
            t = est.time[idx]
            out[tid] = TrackHistory(t, est.state[idx], float(t[0]), end.get(tid, float(t[-1])))
        return out

    @functools.cached_property
    def _assessment(self) -> tuple[dict, np.ndarray, np.ndarray] | None:
        d, est = self.data, self.tracks
        if d.truth is None or not len(d.truth) or not len(est):  # a truth.csv of only a header: nothing to score
            return None
        paths = TruthPaths.from_table(d.truth, self.plane)
        spans = self.label_spans if self.label_spans is not None else label_spans(d.plots.time, d.plots.target)
        if not spans:
            spans = {tg: (float(p[0].min()), float(p[0].max())) for tg, p in paths.paths.items()}
        observed = observed_spans(spans)
        grid = GridSpec(float(d.truth.time.min()), float(d.truth.time.max()), 2.0)  # its live times only
        gaps = detection_gaps(d.plots.time, d.plots.target, self.config.manager_settings().delete_after_s)
        tracking = track_metrics(self.histories(), paths, observed, grid,
                                 first_seen={tg: lo for tg, (lo, _) in spans.items()}, gaps=gaps)
        tracking.pop("gospa")
        # the target of each estimate: its truth label, else the target its track was assigned to
        owner = {v["right_track"]: tg for tg, v in tracking["per_target"].items() if v["right_track"] >= 0}
        target = np.array([str(tg) if tg is not None else owner.get(int(k), "") for tg, k in zip(est.target, est.track)],
                          object)
        err, ok = state_errors(paths, target, est.time, est.state)
        return tracking, err, ok

    def estimate_errors(self) -> tuple[np.ndarray, np.ndarray]:
        """Estimate − truth (N, 4) of each track estimate and the mask of those with a truth to compare."""
        a = self._assessment
        n = len(self.tracks)
        return (a[1], a[2]) if a else (np.full((n, 4), np.nan), np.zeros(n, bool))

    @functools.cached_property
    def evaluation(self) -> dict | None:
        """``{"truth": …, "tracking": …}`` against ``truth.csv``; ``None`` without truth or estimates."""
        if self._assessment is None:
            return None
        tracking, err, ok = self._assessment
        e, cov, track = err[ok], self.tracks.cov[ok], self.tracks.track[ok]
        finite = np.isfinite(cov).all(axis=(1, 2))
        values = nees(e[finite], cov[finite])  # in time order within each track (events are)
        truth = {
            "estimates_compared": int(ok.sum()),
            "position_rmse_m": float(np.sqrt(np.mean(np.sum(e[:, :2] ** 2, axis=1)))) if len(e) else math.nan,
            "velocity_rmse_mps": float(np.sqrt(np.mean(np.sum(e[:, 2:] ** 2, axis=1)))) if len(e) else math.nan,
            "mean_nees": float(np.mean(values)) if finite.any() else math.nan,
            "nees_compared": int(finite.sum()),
            "nees_effective_count": effective_count(values, track[finite]),
        }
        return {"truth": truth, "tracking": tracking}

    @functools.cached_property
    def observability(self) -> dict:
        """The coupling graph's observability report (:meth:`CouplingGraph.report`), made once: the graph is the
        run's final one, and the report's work grows with the aircraft (the graph's components, and each
        radar's partners through the aircraft it shares); :meth:`summary` copies it."""
        return self.coupling.report()

    def consistency(self) -> dict:
        """Mean NEES and NIS against their expectations, with warnings when far off (module docstring)."""
        ev = self.evaluation
        out = {"mean_nees": ev["truth"]["mean_nees"] if ev else math.nan, "expected_nees": 4.0,
               "nees_band_95": mean_chi2_band(4, ev["truth"]["nees_effective_count"] if ev else 0),
               "mean_nis": self.mean_nis, "expected_nis": 2.0,
               "mean_track_nis": self.track_nis["mean_nis"], "expected_track_nis": 2.0,
               "track_nis_band_95": mean_chi2_band(2, self.track_nis["count"]),
               "warnings": []}
        for what, dof in (("nees", 4.0), ("nis", 2.0), ("track_nis", 2.0)):
            value = out[f"mean_{what}"]
            if math.isfinite(value) and not dof / CONSISTENCY_FACTOR <= value <= dof * CONSISTENCY_FACTOR:
                out["warnings"].append(consistency_warning(what, value, dof, self.config.q))
        return out

    def bias_entry(self, rid: str) -> dict:
        """One radar's final bias, its σ, the components the data did not inform (``unobservable``: reported
        at their prior) and, with ``truth_biases.csv``, the truth, error and z-score."""
        b = self.final_biases[rid]
        entry = {"range_bias_m": b.range_m, "azimuth_bias_deg": math.degrees(b.azimuth_rad),
                 "sd_range_m": b.sd_range_m, "sd_azimuth_deg": math.degrees(b.sd_azimuth_rad),
                 "true_range_bias_m": None, "true_azimuth_bias_deg": None, "error_range_m": None,
                 "error_azimuth_deg": None, "z_range": None, "z_azimuth": None, "unobservable": list(b.unobservable)}
        if rid in (self.data.truth_biases or {}):
            tr, ta = self.data.truth_biases[rid]
            entry.update({"true_range_bias_m": tr, "true_azimuth_bias_deg": math.degrees(ta),
                          "error_range_m": b.range_m - tr, "error_azimuth_deg": math.degrees(b.azimuth_rad - ta),
                          "z_range": (b.range_m - tr) / b.sd_range_m if b.sd_range_m else math.nan,
                          "z_azimuth": (b.azimuth_rad - ta) / b.sd_azimuth_rad if b.sd_azimuth_rad else math.nan})
        return entry

    def summary(self) -> dict:
        """The contents of ``summary.json`` (docs/formats.md); strict JSON values."""
        n_meas = sum(v for k, v in self.counts.items() if k.endswith("_used"))
        ev = self.evaluation
        c = self.config
        return strict({
            "scenario": self.data.name,
            "association": c.association,
            "estimator": c.estimator,
            "motion_model": c.motion_model,
            "q": c.q,
            "reference": {"lat": self.data.reference[0], "lon": self.data.reference[1]},
            "counts": dict(self.counts),
            "track_counts": dict(self.track_counts),
            "skipped_input_rows": dict(self.data.skipped),
            "seconds": self.seconds,
            "seconds_per_measurement": self.seconds / max(n_meas, 1),
            "tracks": self.track_count if self.track_count is not None else int(len(np.unique(self.tracks.track))),
            "consistency": self.consistency(),
            "biases": {rid: self.bias_entry(rid) for rid in self.final_biases},
            "truth": ev["truth"] if ev else None,
            "tracking": ev["tracking"] if ev else None,
            "observability": self.observability,
        })

    def summary_table(self) -> str:
        """Biases (true, estimated, σ, z) and the evaluation as text."""
        s = self.summary()
        f = _fmt
        lines = [f"{'radar':<8} {'range bias m':>30} {'azimuth bias deg':>34}",
                 f"{'':<8} {'true':>8} {'est':>8} {'±σ':>6} {'z':>5} {'true':>8} {'est':>9} {'±σ':>7} {'z':>6}"]
        for rid, b in s["biases"].items():
            lines.append(f"{rid:<8} {f(b['true_range_bias_m'], '8.1f')} {f(b['range_bias_m'], '8.1f')} "
                         f"{f(b['sd_range_m'], '6.1f')} {f(b['z_range'], '5.2f')} {f(b['true_azimuth_bias_deg'], '8.3f')} "
                         f"{f(b['azimuth_bias_deg'], '9.4f')} {f(b['sd_azimuth_deg'], '7.4f')} {f(b['z_azimuth'], '6.2f')}"
                         + (f"  unobservable, at the prior: {', '.join(b['unobservable'])}"
                            if b["unobservable"] else ""))
        if s["truth"]:
            tm, tk = s["truth"], s["tracking"]
            lines.append(f"position RMSE {f(tm['position_rmse_m'], '.1f')} m, velocity RMSE "
                         f"{f(tm['velocity_rmse_mps'], '.2f')} m/s, mean NEES {f(tm['mean_nees'], '.2f')} (4 expected); "
                         f"{s['tracks']} tracks, {tk['breaks']} breaks, {tk['swaps']} swaps, "
                         f"{tk['false_tracks']} false tracks")
            q = tk["indicators"]
            pct = {k: None if q[k] is None else 100.0 * q[k] for k in ("multiple_share_of_time", "probability_of_update")}
            lines.append(f"multiple tracks {q['multiple_tracks']} ({f(pct['multiple_share_of_time'], '.2f')} % of "
                         f"flight time, {q['flights_with_multiple_tracks']} flights), probability of update "
                         f"{f(pct['probability_of_update'], '.1f')} % (per {q['update_interval_s']:g} s), "
                         f"initiation delay p95 {f(q['initiation_delay_p95_s'], '.1f')} s")
        cons = s["consistency"]
        if cons["mean_track_nis"] is not None:
            lines.append(f"track filters' mean NIS {cons['mean_track_nis']:.2f} (2 expected) over "
                         f"{self.track_nis['count']} accepted measurements")
        c = s["counts"]
        lines.append(f"{c.get('plots_used', 0)} plots and {c.get('adsb_used', 0)} ADS-B reports used in "
                     f"{s['seconds']:.2f} s; not used: "
                     + (", ".join(f"{k} {v}" for k, v in c.items() if not k.endswith('_used')) or "none"))
        return "\n".join(lines)
