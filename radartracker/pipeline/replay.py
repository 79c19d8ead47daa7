"""Replay a scenario through an estimator plugin and write the results (docs/formats.md).

Plots and ADS-B reports are converted to the plane in bulk, merged in time order and handed one
at a time to the estimator. Association here is by the plot's truth label (``target`` column) or
its Mode S address — the TrackManager brings real association. An aircraft starts with a wide
prior centred on its first measurement and is removed (marginalised) after ``drop_after_s``
without measurements. Every input row is used or counted under a named reason.
"""

from __future__ import annotations

import json
import logging
import math
import time as _time
from collections import Counter
from collections.abc import Hashable
from pathlib import Path

import attrs
import numpy as np
from tqdm import tqdm

from radartracker.estimation.coupling import CouplingGraph
from radartracker.pipeline.evaluate import TruthPaths, nees, state_errors
from radartracker.io.tables import ScenarioData
from radartracker.geometry.plane import SystemPlane
from radartracker.estimation.kalman import SingularInnovation
from radartracker.estimation.measurement import (Measurements, convert_adsb, convert_plots, fill_altitudes, merge, plot_keys)
from radartracker.estimation.motion import MotionModel
from radartracker.estimation.base import Estimator, EstimatorConfig, PlaneMeasurement
from radartracker.registry import make_estimator

log = logging.getLogger(__name__)
DEFAULT_Q = 5.0  # m²/s³, white-acceleration density for real traffic


@attrs.frozen
class ReplayOptions:
    """How a replay runs: estimator settings, track prior and life time, association source."""

    config: EstimatorConfig = attrs.field(factory=EstimatorConfig)
    prior_sd_position_m: float = 10_000.0
    prior_sd_velocity_mps: float = 300.0
    drop_after_s: float = 60.0
    default_altitude_m: float = 0.0
    use_truth_labels: bool = True

    @classmethod
    def for_scenario(cls, data: ScenarioData, q: float | None = None) -> ReplayOptions:
        """Defaults for ``data``; process noise ``q`` = 5 m²/s³ unless given (real aircraft turn:
        with the seed's q = 0 a manoeuvre is explained away as radar bias)."""
        drop = 3.0 * max(r.period_s for r in data.radars) + 30.0
        config = EstimatorConfig(motion=MotionModel(DEFAULT_Q if q is None else q))
        return cls(config=config, drop_after_s=drop)

    def prior(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        state = np.array([z[0], z[1], 0.0, 0.0])
        cov = np.diag([self.prior_sd_position_m**2] * 2 + [self.prior_sd_velocity_mps**2] * 2)
        return state, cov


@attrs.define
class ReplayResult:
    """What a replay produced: estimate histories (columns), final biases, counts and timing."""

    data: ScenarioData
    estimator_name: str
    plane: SystemPlane
    track_time: np.ndarray
    track_key: np.ndarray
    track_state: np.ndarray
    track_cov: np.ndarray
    bias_time: np.ndarray
    bias_radar: np.ndarray
    bias_value: np.ndarray
    bias_cov: np.ndarray
    final_biases: dict[str, tuple[np.ndarray, np.ndarray]]
    counts: dict[str, int]
    seconds: float
    nis: np.ndarray
    coupling: CouplingGraph | None = None

    def summary(self) -> dict:
        """The contents of summary.json (see docs/formats.md)."""
        n_meas = self.counts.get("plots_used", 0) + self.counts.get("adsb_used", 0)
        out: dict = {
            "scenario": self.data.name,
            "estimator": self.estimator_name,
            "reference": {"lat": self.data.reference[0], "lon": self.data.reference[1]},
            "counts": dict(self.counts),
            "skipped_input_rows": dict(self.data.skipped),
            "seconds": self.seconds,
            "seconds_per_measurement": self.seconds / max(n_meas, 1),
            "mean_nis": float(np.mean(self.nis)) if len(self.nis) else None,
            "biases": {},
        }
        if self.coupling is not None:
            out["observability"] = self.coupling.report()
        truth_b = self.data.truth_biases or {}
        for rid, (b, P) in self.final_biases.items():
            entry = {"range_bias_m": float(b[0]), "azimuth_bias_deg": math.degrees(b[1]),
                     "sd_range_m": math.sqrt(P[0, 0]), "sd_azimuth_deg": math.degrees(math.sqrt(P[1, 1]))}
            if rid in truth_b:
                tr, ta = truth_b[rid]
                entry.update({"true_range_bias_m": tr, "true_azimuth_bias_deg": math.degrees(ta),
                              "error_range_m": float(b[0] - tr), "error_azimuth_deg": math.degrees(b[1] - ta),
                              "z_range": float((b[0] - tr) / math.sqrt(P[0, 0])),
                              "z_azimuth": float((b[1] - ta) / math.sqrt(P[1, 1]))})
            out["biases"][rid] = entry
        if self.data.truth is not None and len(self.track_time):
            out["truth"] = self.truth_metrics()
        return out

    def truth_metrics(self) -> dict:
        paths = TruthPaths.from_table(self.data.truth, self.plane)
        err, ok = state_errors(paths, self.track_key, self.track_time, self.track_state)
        e = err[ok]
        return {
            "estimates_compared": int(ok.sum()),
            "position_rmse_m": float(np.sqrt(np.mean(np.sum(e[:, :2] ** 2, axis=1)))),
            "velocity_rmse_mps": float(np.sqrt(np.mean(np.sum(e[:, 2:] ** 2, axis=1)))),
            "mean_nees": float(np.mean(nees(e, self.track_cov[ok]))),
        }

    def summary_table(self) -> str:
        """True vs estimated biases as a text table."""
        s = self.summary()
        lines = [f"{'radar':<8} {'range bias m':>30} {'azimuth bias deg':>34}",
                 f"{'':<8} {'true':>8} {'est':>8} {'±σ':>6} {'z':>5} {'true':>8} {'est':>9} {'±σ':>7} {'z':>6}"]
        for rid, b in s["biases"].items():
            lines.append(
                f"{rid:<8} {b.get('true_range_bias_m', math.nan):8.1f} {b['range_bias_m']:8.1f} {b['sd_range_m']:6.1f} "
                f"{b.get('z_range', math.nan):5.2f} {b.get('true_azimuth_bias_deg', math.nan):8.3f} "
                f"{b['azimuth_bias_deg']:9.4f} {b['sd_azimuth_deg']:7.4f} {b.get('z_azimuth', math.nan):6.2f}")
        if "truth" in s:
            tm = s["truth"]
            lines.append(f"position RMSE {tm['position_rmse_m']:.1f} m, velocity RMSE {tm['velocity_rmse_mps']:.2f} m/s, "
                         f"mean NEES {tm['mean_nees']:.2f} (4 expected)")
        c = s["counts"]
        lines.append(f"{c.get('plots_used', 0)} plots and {c.get('adsb_used', 0)} ADS-B reports used in "
                     f"{s['seconds']:.2f} s; not used: "
                     + (", ".join(f"{k} {v}" for k, v in c.items() if not k.endswith('_used')) or "none"))
        return "\n".join(lines)


def prepare(data: ScenarioData, options: ReplayOptions) -> tuple[SystemPlane, Measurements, Counter]:
    """Plane, converted measurements in time order, and counts of what could not be converted."""
    plane = SystemPlane(*data.reference)
    counts: Counter[str] = Counter()
    keys = plot_keys(data.plots, options.use_truth_labels and data.plots.has_truth_labels)
    alt, defaulted = fill_altitudes(data.plots, keys, options.default_altitude_m)
    if defaulted:
        counts["plots_altitude_assumed"] = defaulted
    meas = merge(convert_plots(data.plots, data.radars, plane, keys, alt), convert_adsb(data.adsb, plane))
    return plane, meas, counts


def replay(data: ScenarioData, estimator: str | Estimator, options: ReplayOptions | None = None) -> ReplayResult:
    """Run ``estimator`` (a plugin name or an instance) over ``data``."""
    options = options or ReplayOptions.for_scenario(data)
    plane, meas, counts = prepare(data, options)
    est = make_estimator(estimator, options.config, [r.id for r in data.radars]) if isinstance(estimator, str) else estimator
    name = estimator if isinstance(estimator, str) else type(estimator).name

    last_seen: dict[Hashable, float] = {}
    coupling = CouplingGraph(est.radars)
    rec_t, rec_k, rec_x, rec_P, nis_list = [], [], [], [], []
    b_t, b_r, b_v, b_P = [], [], [], []
    next_sweep = -math.inf
    started = _time.perf_counter()
    for i in tqdm(range(len(meas)), desc=f"replay {name}", unit="meas", delay=2.0, mininterval=1.0):
        t, radar, key = float(meas.time[i]), meas.radar[i], meas.key[i]
        kind = "plots" if radar is not None else "adsb"
        if key is None:
            counts[f"{kind}_unassociated"] += 1
            continue
        if not meas.valid[i]:
            counts[f"{kind}_impossible_geometry"] += 1
            continue
        if t >= next_sweep:  # remove aircraft unseen for drop_after_s
            for k in [k for k, ts in last_seen.items() if t - ts > options.drop_after_s]:
                est.remove_aircraft(k)
                coupling.remove_aircraft(k)
                del last_seen[k]
            next_sweep = t + 1.0
        m = PlaneMeasurement(t, key, radar, meas.z[i], meas.C[i], meas.R[i])
        if key not in last_seen:
            est.add_aircraft(key, t, *options.prior(m.z))
        try:
            innov = est.update(m)
        except SingularInnovation as exc:
            counts[f"{kind}_singular"] += 1
            log.warning("measurement at t=%s of %s not used: %s", t, key, exc)
            continue
        last_seen[key] = t
        coupling.observe(key, radar, t)
        counts[f"{kind}_used"] += 1
        nis_list.append(innov.nis)
        a = est.aircraft(key)
        rec_t.append(t), rec_k.append(key), rec_x.append(a.state), rec_P.append(a.cov)
        if radar is not None:
            b = est.bias(radar)
            b_t.append(t), b_r.append(radar), b_v.append(b.bias), b_P.append(b.cov)
    seconds = _time.perf_counter() - started
    final = {r: (est.bias(r).bias, est.bias(r).cov) for r in est.radars}
    obj = np.empty(len(rec_k), object)
    obj[:] = rec_k
    return ReplayResult(
        data=data, estimator_name=name, plane=plane,
        track_time=np.array(rec_t), track_key=obj, track_state=np.array(rec_x).reshape(-1, 4),
        track_cov=np.array(rec_P).reshape(-1, 4, 4), bias_time=np.array(b_t), bias_radar=np.array(b_r, object),
        bias_value=np.array(b_v).reshape(-1, 2), bias_cov=np.array(b_P).reshape(-1, 2, 2),
        final_biases=final, counts=dict(counts), seconds=seconds, nis=np.array(nis_list), coupling=coupling,
    )


def write_outputs(result: ReplayResult, out: Path | str, *, figures: bool = False) -> None:
    """Write biases.csv, tracks.csv, summary.json (and figures) into ``out``."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    with (out / "biases.csv").open("w") as f:
        f.write("time,radar,range_bias_m,azimuth_bias_deg,sd_range_m,sd_azimuth_deg\n")
        for t, r, v, P in zip(result.bias_time, result.bias_radar, result.bias_value, result.bias_cov):
            f.write(f"{t:.3f},{r},{v[0]:.3f},{math.degrees(v[1]):.6f},{math.sqrt(P[0, 0]):.3f},"
                    f"{math.degrees(math.sqrt(P[1, 1])):.6f}\n")
    if len(result.track_time):
        lat, lon = result.plane.to_geodetic(result.track_state[:, 0], result.track_state[:, 1])
    with (out / "tracks.csv").open("w") as f:
        f.write("time,track,lat,lon,x_m,y_m,vx_mps,vy_mps,sd_x_m,sd_y_m\n")
        for i in range(len(result.track_time)):
            x, P = result.track_state[i], result.track_cov[i]
            f.write(f"{result.track_time[i]:.3f},{result.track_key[i]},{lat[i]:.8f},{lon[i]:.8f},{x[0]:.2f},"
                    f"{x[1]:.2f},{x[2]:.3f},{x[3]:.3f},{math.sqrt(P[0, 0]):.2f},{math.sqrt(P[1, 1]):.2f}\n")
    (out / "summary.json").write_text(json.dumps(result.summary(), indent=1))
    if result.coupling is not None:
        result.coupling.write_graphml(out / "coupling.graphml")
    if figures:
        from radartracker.pipeline.figures import plot_biases

        plot_biases(result, out / "biases.png")
