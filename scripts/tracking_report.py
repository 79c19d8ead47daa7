"""Tracking scenario set (issue 17): TrackManager continuity and accuracy per motion model and
association method, with Stone Soup's GNN tracker on the same plots as the peer.

Scenarios (``scripts/tracking_scenarios.py``): ``approach`` and ``enroute`` (real flights of
``../shared/data``, primary-only plots with Mode C), ``pairs`` (crossing and parallel pairs, false
plots), and the built-in ``tracking`` and ``manoeuvres`` scenarios. Prints one JSON line per run,
then a Markdown table. Metrics (:func:`radartracker.pipeline.evaluate.track_metrics`, 2 s grid,
c = 2 km): continuity (min over aircraft), breaks (also in % of flights; ``coverage_gaps`` counts
the gaps longer than ``delete_after_s`` in an aircraft's plots, each an unavoidable break, and
``breaks_continuous`` track_metrics' ``breaks_in_coverage``, an aircraft's breaks beyond its gaps: those while
its plots kept coming), swaps,
RMSE and GOSPA;
the height estimate of tracks whose plots carry no altitude (RMSE against the truth's altitude, mean NEES of
χ²₁, median σ_h and the share of the aircraft's own tracks' estimates with an observable height); here also
the p95 position error of each aircraft's own track (overall, flying straight and turning
faster than 1°/s, and above 7000 m, where the en-route flights have left their climb-out), and
*false confirmed tracks* (track_metrics' ``false_tracks``: tracks that, for half their life, follow
no aircraft any plot or report saw).

Usage: python scripts/tracking_report.py [--sets approach enroute pairs] [--models imm cv adaptive]
       [--approach-s 1800] [--enroute-s 3600] [--no-stonesoup] [--mode-s] [--stonesoup-save DIR | --stonesoup-load DIR]
(``--models`` with no name runs Stone Soup alone: a long Stone Soup run can go in a separate process,
saved with the plots' digest, and be loaded by the report run on the same plots.)
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import tracking_scenarios as scenarios  # noqa: E402
from tracking_stonesoup import load_tracks, plots_digest, save_tracks, stonesoup_gnn  # noqa: E402

from radartracker.registry import make_manager
from radartracker.io.tables import ScenarioData  # noqa: E402
from radartracker.pipeline.consistency import effective_count, mean_chi2_band  # noqa: E402
from radartracker.pipeline.evaluate import TrackHistory, TruthPaths, detection_gaps, track_metrics  # noqa: E402
from radartracker.pipeline.stream import scenario_stream  # noqa: E402
from radartracker.simulation.scenarios import build_scenario  # noqa: E402
from radartracker.tracking.config import ManagerConfig  # noqa: E402
from radartracker.tracking.events import ENDS  # noqa: E402
from radartracker.tracking.manager import TrackManager  # noqa: E402

GRID_S, GRACE_S, C_M, HIGH_M = 2.0, 20.0, 2000.0, 7000.0
# each set without altitude and the same flights with Mode C (issue 29, item 4)
TWINS = {"cruise-no-mode-c": "cruise", "cruise-real-no-mode-c": "cruise-real", "national-primary": "national-mode-c"}
COVS: dict[tuple[int, float], np.ndarray] = {}  # (track, time) → covariance of the estimate, of the last run
HEIGHTS: dict[tuple[int, float], tuple[float, float]] = {}  # (track, time) → estimated height and its σ (m)


def run_manager(data: ScenarioData, config: ManagerConfig) -> tuple[dict[int, TrackHistory], dict, float]:
    """Confirmed-track histories from the manager's events (each estimate's covariance in ``COVS``), the
    largest final bias errors (range m, azimuth millidegrees) against the simulated biases and the track
    filters' mean NIS, and wall seconds."""
    mgr = make_manager(data.radars, data.reference, config)
    COVS.clear()
    HEIGHTS.clear()
    observable = config.height.observable_sd_m

    def keep_cov(ev, tr) -> None:
        if ev.kind in ("confirmed", "updated"):
            t0, _, P = tr.estimate()
            if t0 == ev.time:
                COVS[ev.track, ev.time] = P
            if tr.height is not None:
                h, sd = tr.height.height(ev.time)
                if sd <= observable:
                    HEIGHTS[ev.track, ev.time] = (h, sd)

    mgr.events.subscribe(keep_cov)
    started = time.perf_counter()
    events = mgr.process_many(scenario_stream(data))
    wall = time.perf_counter() - started
    rows: dict[int, list] = {}
    for e in events:
        rows.setdefault(e.track, []).append(e)
    out = {}
    for tid, evs in rows.items():
        rep = [e for e in evs if e.kind in ("confirmed", "updated")]  # estimates (coasting: extrapolated)
        if rep:
            end = next((e.time for e in evs if e.kind in ENDS), rep[-1].time)
            out[tid] = TrackHistory(np.array([e.time for e in rep]), np.array([e.state for e in rep]), rep[0].time, end)
    err = [(abs(b.bias[0] - data.truth_biases[rid][0]), abs(math.degrees(b.bias[1] - data.truth_biases[rid][1])) * 1e3)
           for rid, b in mgr.biases().items()] if data.truth_biases else [(math.nan, math.nan)]
    return out, {"bias_err_range_m": max(e[0] for e in err), "bias_err_azimuth_mdeg": max(e[1] for e in err),
                 "track_nis": mgr.innovations()["mean_nis"], "track_nis_count": mgr.innovations()["count"]}, wall


def evaluate(data: ScenarioData, tracks: dict[int, TrackHistory]) -> dict:
    """track_metrics plus p95 of each aircraft's own-track error and false confirmed tracks."""
    from radartracker.geometry.plane import SystemPlane

    paths = TruthPaths.from_table(data.truth, SystemPlane(*data.reference))
    labelled = np.array([t is not None for t in data.plots.target])
    observed = {}
    for tg in np.unique(data.plots.target[labelled].astype(str)):
        t = np.sort(data.plots.time[data.plots.target == tg])
        if t.max() - t.min() > GRACE_S:
            observed[tg] = (float(t.min()) + GRACE_S, float(t.max()))
    gaps = detection_gaps(data.plots.time, data.plots.target, ManagerConfig().delete_after_s)
    grid = np.arange(data.truth.time.min(), data.truth.time.max(), GRID_S)
    # the aircraft some plot or ADS-B report saw: a track following one of them is not false
    sensed = set(observed) | set(np.unique(data.plots.target[labelled].astype(str))) | set(data.adsb.icao24.astype(str))
    first = {tg: lo - GRACE_S for tg, (lo, _) in observed.items()}
    m = track_metrics(tracks, paths, observed, grid, C_M, sensed=sensed, first_seen=first, gaps=gaps)
    q = m["indicators"]
    err, turning, high, nees4, nees2, dh, sdh, n_est, of_track = [], [], [], [], [], [], [], 0, []
    for tg, v in m["per_target"].items():
        if v["right_track"] < 0:
            continue
        h = tracks[v["right_track"]]
        values = _nees(h, v["right_track"], paths.state_at(tg, h.times), slice(0, 4))
        nees4 += values
        of_track += [v["right_track"]] * len(values)  # each value's track: the series of effective_count
        nees2 += _nees(h, v["right_track"], paths.state_at(tg, h.times), slice(0, 2))
        n_est += len(h.times)
        _height_errors(data, tg, v["right_track"], h, dh, sdh)
        g = grid[(grid >= max(observed[tg][0], h.start)) & (grid <= min(observed[tg][1], h.end))]
        pos, alive = h.at(g)
        truth, inside = paths.state_at(tg, g)
        heading = np.unwrap(np.arctan2(truth[:, 2], truth[:, 3]))
        rate = np.abs(np.gradient(heading, g)) if len(g) > 1 else np.zeros(len(g))
        d = np.hypot(*(pos - truth[:, :2]).T)
        use = alive & inside & (d < C_M)
        err.extend(d[use])
        turning.extend(rate[use] > np.radians(1.0))
        ti = np.flatnonzero(data.truth.target == tg)
        high.extend(np.interp(g[use], data.truth.time[ti], data.truth.altitude_m[ti]) >= HIGH_M)
    e, high = np.array(err), np.array(high, bool)
    continuous = m["breaks_in_coverage"]
    return {"flights": len(observed), "coverage_gaps": sum(gaps[tg] for tg in observed),
            "continuity_min": m["continuity_min"],
            "breaks": m["breaks"], "breaks_pct": 100.0 * m["breaks"] / max(len(observed), 1),
            "breaks_continuous": continuous, "breaks_continuous_pct": 100.0 * continuous / max(len(observed), 1),
            "swaps": m["swaps"],
            "false_confirmed": m["false_tracks"], "confirmed_tracks": m["confirmed_tracks"],
            "rmse_m": m["position_rmse_m"], "p95_m": float(np.percentile(e, 95)) if len(e) else float("nan"),
            "p95_above_7000m_m": float(np.percentile(e[high], 95)) if high.any() else float("nan"),
            "high_pct": 100.0 * float(high.mean()) if len(high) else 0.0,
            "gospa_m": m["gospa_mean_m"], "multiple_tracks": q["multiple_tracks"],
            "multiple_pct_time": 100.0 * q["multiple_share_of_time"],
            "multiple_pct_flights": 100.0 * q["flights_with_multiple_share"],
            "pu_pct": 100.0 * q["probability_of_update"], "init_delay_p95_s": q["initiation_delay_p95_s"],
            "nees": float(np.mean(nees4)) if nees4 else float("nan"),
            "nees_band_95": mean_chi2_band(4, effective_count(np.array(nees4), np.array(of_track, int))),
            "nees_position": float(np.mean(nees2)) if nees2 else float("nan"),
            **_height_summary(np.array(dh), np.array(sdh), n_est),
            **_split(e, np.array(turning, bool))}


def _nees(h: TrackHistory, tid: int, truth: tuple[np.ndarray, np.ndarray], part: slice) -> list[float]:
    """NEES of the ``part`` of the state of each estimate of track ``tid`` whose covariance was kept (COVS),
    inside the truth."""
    state, inside = truth
    out = []
    for k in np.flatnonzero(inside):
        P = COVS.get((tid, float(h.times[k])))
        if P is not None:
            e = h.states[k, part] - state[k, part]
            out.append(float(e @ np.linalg.solve(P[part, part], e)))
    return out


def _height_errors(data: ScenarioData, tg: str, tid: int, h: TrackHistory, dh: list, sdh: list) -> None:
    """The errors against the truth's altitude, and σ, of the heights estimated (HEIGHTS) for track ``tid``'s
    estimates, appended to ``dh`` and ``sdh``."""
    ti = np.flatnonzero(data.truth.target == tg)
    for t in h.times.tolist():
        est = HEIGHTS.get((tid, t))
        if est is not None and data.truth.time[ti[0]] <= t <= data.truth.time[ti[-1]]:
            dh.append(est[0] - float(np.interp(t, data.truth.time[ti], data.truth.altitude_m[ti])))
            sdh.append(est[1])


def _height_summary(dh: np.ndarray, sd: np.ndarray, n_est: int) -> dict:
    """Height RMSE, mean height NEES (χ²₁, mean 1), median σ_h and the share of the aircraft's own tracks'
    estimates with an observable height."""
    if not len(dh):
        return {"height_rmse_m": float("nan"), "height_nees": float("nan"), "height_sd_median_m": float("nan"),
                "height_share_pct": 0.0}
    return {"height_rmse_m": float(np.sqrt(np.mean(dh**2))), "height_nees": float(np.mean((dh / sd) ** 2)),
            "height_sd_median_m": float(np.median(sd)), "height_share_pct": 100.0 * len(dh) / max(n_est, 1)}


def _split(err: np.ndarray, turning: np.ndarray) -> dict:
    """p95 of the error where the aircraft flies straight and where it turns faster than 1°/s."""
    p95 = {k: float(np.percentile(err[m], 95)) if m.any() else float("nan")
           for k, m in (("p95_straight_m", ~turning), ("p95_turning_m", turning))}
    return {**p95, "turning_pct": 100.0 * float(turning.mean()) if len(turning) else 0.0}


def build(name: str, args: argparse.Namespace, mode_s: bool = False) -> ScenarioData:
    if name == "approach":
        return scenarios.approach(args.seed, args.approach_s, mode_s=mode_s)
    if name == "enroute":
        return scenarios.enroute(args.seed, args.enroute_s, mode_s=mode_s, max_flights=args.max_flights)
    if name == "pairs":
        return scenarios.pairs(args.seed)
    if name in ("cruise", "cruise-no-mode-c"):
        return scenarios.cruise(args.seed, args.cruise_s, mode_c=name == "cruise")
    if name in ("cruise-real", "cruise-real-no-mode-c"):
        return scenarios.cruise_real(args.seed, mode_c=name == "cruise-real")
    if name in ("national-primary", "national-mode-c"):
        return scenarios.national_primary(args.seed, args.national_s, mode_c=name == "national-mode-c")
    return build_scenario(name, seed=args.seed).run()


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--sets", nargs="*", default=["approach", "enroute", "pairs", "tracking", "manoeuvres"])
    ap.add_argument("--models", nargs="*", default=["imm", "cv", "adaptive"])
    ap.add_argument("--estimator", default="coupled-sparse")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--approach-s", type=float, default=1800.0)
    ap.add_argument("--enroute-s", type=float, default=3600.0)  # the hour
    ap.add_argument("--max-flights", type=int, default=None)
    ap.add_argument("--cruise-s", type=float, default=1800.0)
    ap.add_argument("--national-s", type=float, default=600.0)
    ap.add_argument("--no-stonesoup", action="store_true")
    ap.add_argument("--stonesoup-save", type=Path, help="also write Stone Soup's tracks to DIR/SET.npz")
    ap.add_argument("--stonesoup-load", type=Path, help="Stone Soup's tracks from DIR/SET.npz (a separate run on "
                    "the same plots, checked by digest) instead of running it")
    ap.add_argument("--mode-s", action="store_true", help="also run the en-route set with Mode S (default settings)")
    args = ap.parse_args()
    rows = []

    def emit(row: dict) -> None:
        print(json.dumps(row), flush=True)
        rows.append(row)

    for name in args.sets:
        data = build(name, args)
        n_plots = len(data.plots)
        for model in args.models:
            tracks, biases, wall = run_manager(data, ManagerConfig(estimator=args.estimator, motion_model=model))
            emit({"set": name, "tracker": f"{model} + GNN", **evaluate(data, tracks), **biases, "plots": n_plots,
                  "ms_per_plot": 1e3 * wall / n_plots})
        if not args.no_stonesoup:
            tracker = "stonesoup-gnn"
            if args.stonesoup_load:
                tracks, wall = load_tracks(args.stonesoup_load / f"{name}.npz", plots_digest(data))
                tracker += " (separate run, same plots)"
            else:
                started = time.perf_counter()
                tracks = stonesoup_gnn(data)
                wall = time.perf_counter() - started
                if args.stonesoup_save:
                    save_tracks(args.stonesoup_save / f"{name}.npz", tracks, plots_digest(data), wall)
            COVS.clear()  # Stone Soup's tracks have no covariance here: no NEES
            HEIGHTS.clear()
            emit({"set": name, "tracker": tracker, **evaluate(data, tracks), "plots": n_plots,
                  "ms_per_plot": 1e3 * wall / n_plots, "plots_digest": plots_digest(data)[:12]})
    if args.mode_s:  # the en-route set again with Mode S, for each motion model (the default among them)
        data = build("enroute", args, mode_s=True)
        for model in args.models or [ManagerConfig().motion_model]:
            tracks, biases, wall = run_manager(data, ManagerConfig(estimator=args.estimator, motion_model=model))
            emit({"set": "enroute+modeS", "tracker": f"{model} + GNN", **evaluate(data, tracks), **biases,
                  "plots": len(data.plots), "ms_per_plot": 1e3 * wall / len(data.plots)})
    print()
    print("| set | tracker | flights | tracks | breaks (% flights) | of them while the plots are continuous | "
          "multiple tracks (% time, % flights) | swaps | "
          "false | P_u (%) | RMSE (m) | p95 (m) | NEES (4) | NEES pos. (2) | track NIS (2) | init. delay p95 (s) | "
          "ms/plot | height RMSE (m) | height NEES (1) | height σ median (m) | height observable (%) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['set']} | {r['tracker']} | {r['flights']} | {r['confirmed_tracks']} | {r['breaks']} "
              f"({r['breaks_pct']:.1f} %) | {r['breaks_continuous']} ({r['breaks_continuous_pct']:.1f} %) | "
              f"{r['multiple_tracks']} ({r['multiple_pct_time']:.2f} %, "
              f"{r['multiple_pct_flights']:.1f} %) | {r['swaps']} | {r['false_confirmed']} | {r['pu_pct']:.1f} | "
              f"{r['rmse_m']:.1f} | {r['p95_m']:.1f} | {r['nees']:.2f} | {r['nees_position']:.2f} | "
              f"{r.get('track_nis', float('nan')):.2f} | {r['init_delay_p95_s']:.1f} | {r['ms_per_plot']:.2f} | "
              f"{r['height_rmse_m']:.1f} | {r['height_nees']:.2f} | {r['height_sd_median_m']:.1f} | "
              f"{r['height_share_pct']:.1f} |")
    done_when(rows, ManagerConfig().motion_model)


def done_when(rows: list[dict], default: str) -> None:
    """The issue's acceptance checks on the rows of the default tracker, printed with their numbers."""
    print()
    for r in (r for r in rows if r["tracker"] == f"{default} + GNN"):
        peer = next((p for p in rows if p["set"] == r["set"] and p["tracker"].startswith("stonesoup")), None)
        checks = [("breaks while the plots are continuous <= 2 % of flights",
                   f"{r['breaks_continuous']} ({r['breaks_continuous_pct']:.1f} %; all breaks {r['breaks']}, gaps in "
                   f"the plots longer than delete_after_s {r['coverage_gaps']})", r["breaks_continuous_pct"] <= 2.0),
                  ("multiple tracks <= 0.5 % of time and <= 2 % of flights",
                   f"{r['multiple_pct_time']:.2f} %, {r['multiple_pct_flights']:.1f} %",
                   r["multiple_pct_time"] <= 0.5 and r["multiple_pct_flights"] <= 2.0),
                  ("no false confirmed track", str(r["false_confirmed"]), r["false_confirmed"] == 0),
                  ("no swap", str(r["swaps"]), r["swaps"] == 0)]
        checks += _consistency_checks(r)
        if peer is not None:
            checks.append(("RMSE below Stone Soup GNN's", f"{r['rmse_m']:.1f} vs {peer['rmse_m']:.1f} m",
                           r["rmse_m"] < peer["rmse_m"]))
        twin = next((p for p in rows if p["tracker"] == r["tracker"] and p["set"] == TWINS.get(r["set"])), None)
        if twin is not None:  # issue 29, item 4: heights from the slant ranges
            more = 100.0 * (r["rmse_m"] / twin["rmse_m"] - 1.0)
            checks.append(("RMSE within 25 % of the same run with Mode C",
                           f"{r['rmse_m']:.1f} vs {twin['rmse_m']:.1f} m ({more:+.0f} %); height RMSE "
                           f"{r['height_rmse_m']:.0f} m, NEES {r['height_nees']:.2f}", more <= 25.0))
        for what, value, ok in checks:
            print(f"done-when {r['set']} ({default}): {what}: {value}: {'yes' if ok else 'NO'}")


def _consistency_checks(r: dict) -> list[tuple[str, str, bool]]:
    """Mean NEES inside the 95 % band of its effective count of values, the track filters' mean NIS inside the
    band of its count (white if the filters are consistent)."""
    out = []
    band = r.get("nees_band_95")
    if band is not None:
        out.append(("mean NEES inside its 95 % band (correlated values)", f"{r['nees']:.2f} in [{band[0]:.2f}, "
                    f"{band[1]:.2f}]", band[0] <= r["nees"] <= band[1]))
    if r.get("track_nis_count"):
        lo, hi = mean_chi2_band(2, r["track_nis_count"])
        out.append(("track filters' mean NIS inside its 95 % band", f"{r['track_nis']:.2f} in [{lo:.3f}, {hi:.3f}] "
                    f"({r['track_nis_count']} values)", lo <= r["track_nis"] <= hi))
    return out


if __name__ == "__main__":
    main()
