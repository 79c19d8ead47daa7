"""Real flights (OpenSky Network ADS-B) with simulated radar plots: reconstruction vs a tuned RTS smoother.

Each flight is flown as a recorded trajectory past two simulated radars (σ 70 m / 0.08°, rotation
periods drawn from 4–12 s, sited 40–90 km from the flight) by radartracker.simulate. Errors are
horizontal distances from the ADS-B positions (interpolated to the plot times) for the reconstruction
and for the RTS smoother over a constant-velocity model on the same plots, with q tuned two ways:
by maximum likelihood on the plots (what one can do on real data) and by minimum error against the
truth (an oracle-tuned upper bound for the smoother). Calibration flights are cut into windows.

Prints one JSON line per flight and a summary per group; writes docs/figures/reconstruction_real_*.png.
Usage: python scripts/reconstruction_real.py [--paris N] [--cal N] [--window S] [--workers W] [--dejitter Q --tag _dejittered]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from radartracker.simulation.flights import load_flights
from radartracker.geometry.plane import SystemPlane
from radartracker.simulation.simulator import RecordedTrajectory
from radartracker_plugins.reconstruction import ReconstructionConfig
from radartracker_plugins.reconstruction.engine import Failure, executor, run_many
from radartracker_plugins.reconstruction.integrate import sample
from radartracker_plugins.reconstruction.output import plot_reconstruction
from radartracker_plugins.reconstruction.sim import radars_around, simulate_flight
from radartracker_plugins.reconstruction.smoother import Q_GRID, rts_smooth, tuned_rts

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "real_flights.csv.gz"
FIG = Path(__file__).resolve().parents[1] / "docs" / "figures"


def flights_to_plots(flights, window: float, seed: int, dejitter: float | None = None):
    """(plot tracks, truth at plot times) of every flight (windows of calibration flights).

    ``dejitter``: fly the RTS-smoothed ADS-B track (σ 30 m, q = dejitter m²/s³) instead of the raw
    positions, and measure against it (OpenSky positions are stale or jittered between updates).
    """
    rng = np.random.default_rng(seed)
    tracks, truth = [], {}
    for fid, f in flights.items():
        spans = [(f.time[0], f.time[-1])]
        if fid.startswith("cal_") and window:
            start = f.time[0] + rng.uniform(0, max(f.duration_s - window, 0))
            spans = [(start, start + window)]
        for a, b in spans:
            sel = (f.time >= a) & (f.time <= b)
            if sel.sum() < 20:
                continue
            ref = (float(np.mean(f.lat[sel])), float(np.mean(f.lon[sel])))
            plane = SystemPlane(*ref)
            traj = RecordedTrajectory.from_geodetic(plane, f.time[sel], f.lat[sel], f.lon[sel], f.altitude_m[sel])
            if dejitter:
                z = np.column_stack([traj.x, traj.y])
                xs, _, _ = rts_smooth(traj.t, z, np.tile(np.eye(2) * 30.0**2, (len(z), 1, 1)), dejitter)
                traj = RecordedTrajectory(traj.t, xs[:, 0], xs[:, 1], traj.h)
            ang = rng.uniform(0, 2 * np.pi) + np.array([0.0, rng.uniform(1.5, 4.5)])
            dist = rng.uniform(40, 90, 2)
            sites = np.column_stack([dist * np.sin(ang), dist * np.cos(ang)])
            radars = radars_around(plane, sites, rng.uniform(4, 12, 2))
            pt, true = simulate_flight(traj, radars, seed=int(rng.integers(1 << 30)), reference=ref)
            pt = type(pt)(fid, pt.t, pt.z, pt.h, pt.radar, pt.R, pt.C)
            tracks.append(pt)
            truth[fid] = true
    return tracks, truth


def errors(p, truth):
    return np.hypot(*(p[:, :2] - truth).T)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--paris", type=int, default=24)
    ap.add_argument("--cal", type=int, default=8)
    ap.add_argument("--window", type=float, default=1800.0, help="calibration-flight window (s)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--dejitter", type=float, default=None, metavar="Q",
                    help="fly and score against the RTS-smoothed ADS-B track (q = Q) instead of the raw positions")
    ap.add_argument("--tag", default="", help="suffix of the figure names")
    args = ap.parse_args()
    allf = load_flights(DATA)
    paris = sorted(k for k in allf if not k.startswith("cal_"))[: args.paris]
    cal = sorted(k for k in allf if k.startswith("cal_"))[: args.cal]
    tracks, truth = flights_to_plots({k: allf[k] for k in paris + cal}, args.window, args.seed, args.dejitter)
    cfg = ReconstructionConfig(max_u=9.5)
    t0 = time.perf_counter()
    results = {}
    with executor("process", args.workers) as ex:
        for r in run_many(tracks, cfg, ex, batch_plots=400, progress=False):
            results[r.key] = r
    wall = time.perf_counter() - t0
    groups: dict[str, dict[str, list]] = {"paris": {}, "calibration": {}}
    best_example = None
    for pt in tracks:
        r = results[pt.key]
        if isinstance(r, Failure):
            print(json.dumps({"flight": pt.key, "failed": r.reason}))
            continue
        tr = truth[pt.key]
        e_rec = errors(sample(r.control, pt.t), tr)
        e_ml = errors(tuned_rts(pt.t, pt.z, pt.R)[0], tr)
        e_or = min((errors(rts_smooth(pt.t, pt.z, pt.R, q)[0], tr) for q in Q_GRID), key=lambda e: np.sqrt(np.mean(e**2)))
        e_raw = errors(pt.z, tr)
        g = groups["calibration" if pt.key.startswith("cal_") else "paris"]
        for name, e in (("reconstruction", e_rec), ("rts_ml", e_ml), ("rts_oracle", e_or), ("plots", e_raw)):
            g.setdefault(name, []).append(e)
        row = {"flight": pt.key, "plots": len(pt), "minutes": round(pt.duration / 60, 1), "segments": len(r.control),
               "median_m": {"rec": round(float(np.median(e_rec)), 1), "rts_ml": round(float(np.median(e_ml)), 1),
                            "rts_oracle": round(float(np.median(e_or)), 1)},
               "p90_m": {"rec": round(float(np.percentile(e_rec, 90)), 1), "rts_ml": round(float(np.percentile(e_ml, 90)), 1),
                         "rts_oracle": round(float(np.percentile(e_or, 90)), 1)}}
        print(json.dumps(row))
        if pt.key.startswith("cal_") and (best_example is None or len(r.control) > len(best_example[0].control)):
            best_example = (r, tr)
    summary = {}
    for gname, g in groups.items():
        if not g:
            continue
        s = {"flights": len(g["reconstruction"])}
        for name, es in g.items():
            e = np.concatenate(es)
            s[name] = {"median_m": round(float(np.median(e)), 1), "p90_m": round(float(np.percentile(e, 90)), 1),
                       "rmse_m": round(float(np.sqrt(np.mean(e**2))), 1)}
        per = [(np.median(a), np.median(b)) for a, b in zip(g["reconstruction"], g["rts_oracle"])]
        s["flights_where_rec_median_beats_rts_oracle"] = int(sum(a < b for a, b in per))
        summary[gname] = s
        print(json.dumps({"group": gname, **s}))
    hours = sum(pt.duration for pt in tracks) / 3600
    print(json.dumps({"wall_s": round(wall, 1), "workers": args.workers, "flight_hours": round(hours, 2)}))
    _figures(groups, best_example, args.tag)


def _figures(groups, example, tag: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for ax, (gname, g) in zip(axes, groups.items()):
        for name, style in (("reconstruction", "-"), ("rts_ml", "--"), ("rts_oracle", ":"), ("plots", "-.")):
            if name not in g:
                continue
            e = np.sort(np.concatenate(g[name]))
            ax.plot(e, np.arange(1, len(e) + 1) / len(e), style, label=name)
        ax.set_xscale("log")
        ax.set_xlabel("horizontal error vs ADS-B (m)")
        ax.set_ylabel("fraction of plot times")
        ax.set_title(f"{gname} flights")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle("Real flights (The OpenSky Network), simulated radar plots σ 70 m / 0.08°")
    fig.tight_layout()
    fig.savefig(FIG / f"reconstruction_real_errors{tag}.png", dpi=110)
    plt.close(fig)
    if example is not None:
        r, tr = example
        plot_reconstruction(r, FIG / f"reconstruction_real_example{tag}.png", (r.plots.t, tr))


if __name__ == "__main__":
    main()
