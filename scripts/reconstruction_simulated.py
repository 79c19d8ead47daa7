"""Simulated flights with known controls: recovered segment counts, switch times, controls, position RMSE.

Random flights of the seed's model (4–6 legs of 60–240 s, |u| ≤ 3.5 m/s² on turns, |w| ≤ 0.8 m/s²,
120–230 m/s) past two radars (σ 70 m / 0.08°, periods 4–12 s) through radartracker.simulate.
Compared on the same plots: the tuned RTS smoother, and the reconstruction without the joint
least-squares refinement (Hooke–Jeeves with the seed's constants only).

Prints one JSON line per flight and a summary; writes docs/figures/reconstruction_simulated_example.png.
Usage: python scripts/reconstruction_simulated.py [--flights N] [--workers W]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from radartracker.geometry.plane import SystemPlane
from radartracker.simulation.simulator import KinematicTrajectory, Leg
from radartracker_plugins.reconstruction import ReconstructionConfig
from radartracker_plugins.reconstruction.engine import executor, run_many
from radartracker_plugins.reconstruction.integrate import sample
from radartracker_plugins.reconstruction.output import plot_reconstruction
from radartracker_plugins.reconstruction.sim import REFERENCE, radars_around, simulate_flight
from radartracker_plugins.reconstruction.smoother import tuned_rts

FIG = Path(__file__).resolve().parents[1] / "docs" / "figures"


def random_flight(rng):
    legs = []
    for i in range(int(rng.integers(4, 7))):
        d = float(rng.uniform(60, 240))
        if i % 2 == 0:
            legs.append(Leg(d, w=float(rng.choice([0.0, rng.uniform(-0.8, 0.8)]))))
        else:
            legs.append(Leg(d, u=float(rng.uniform(1.0, 3.5) * rng.choice([-1, 1])), w=float(rng.uniform(-0.3, 0.3))))
    v = float(rng.uniform(120, 230))
    return KinematicTrajectory(0.0, rng.uniform(-30e3, 30e3), rng.uniform(-30e3, 30e3), rng.uniform(3000, 9000),
                               rng.uniform(0, 2 * np.pi), v, legs)


def rmse(p, q):
    return float(np.sqrt(np.mean(np.sum((p[:, :2] - q) ** 2, axis=1))))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--flights", type=int, default=12)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--seed", type=int, default=5)
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    plane = SystemPlane(*REFERENCE)
    flights, tracks, truth = {}, [], {}
    for i in range(args.flights):
        traj = random_flight(rng)
        radars = radars_around(plane, [(-70, -40), (60, 50)], rng.uniform(4, 12, 2))
        pt, tr = simulate_flight(traj, radars, seed=i)
        pt = type(pt)(f"sim{i:02d}", pt.t, pt.z, pt.h, pt.radar, pt.R, pt.C)
        tracks.append(pt)
        truth[pt.key], flights[pt.key] = tr, traj
    out = {}
    with executor("process", args.workers) as ex:
        for name, cfg in (("hj+lm", ReconstructionConfig()), ("hj_only", ReconstructionConfig(refine=False))):
            out[name] = {r.key: r for r in run_many(tracks, cfg, ex, batch_plots=300, progress=False)}
    rows = []
    for pt in tracks:
        traj, tr = flights[pt.key], truth[pt.key]
        r = out["hj+lm"][pt.key]
        legs = traj.legs
        true_sw = np.cumsum([leg.duration for leg in legs])[:-1]
        row = {"flight": pt.key, "plots": len(pt), "true_segments": len(legs), "found_segments": len(r.control),
               "rmse_m": round(rmse(sample(r.control, pt.t), tr), 1),
               "rmse_hj_only_m": round(rmse(sample(out["hj_only"][pt.key].control, pt.t), tr), 1),
               "rmse_rts_m": round(rmse(tuned_rts(pt.t, pt.z, pt.R)[0], tr), 1),
               "rmse_plots_m": round(rmse(pt.z, tr), 1)}
        if len(r.control) == len(legs):
            row["switch_err_s"] = np.round(np.abs(r.control.switch_times - true_sw), 1).tolist()
            row["u_err"] = np.round(np.abs(r.control.u - [leg.u for leg in legs]), 3).tolist()
            row["w_err"] = np.round(np.abs(r.control.w - [leg.w for leg in legs]), 3).tolist()
        rows.append(row)
        print(json.dumps(row))
    matched = [r for r in rows if "switch_err_s" in r]
    cat = lambda k: np.concatenate([r[k] for r in matched]) if matched else np.array([np.nan])  # noqa: E731
    summary = {"flights": len(rows), "segment_count_right": len(matched),
               "switch_err_s": {"median": round(float(np.median(cat("switch_err_s"))), 2),
                                "p90": round(float(np.percentile(cat("switch_err_s"), 90)), 2)},
               "u_err_mps2": {"median": round(float(np.median(cat("u_err"))), 3), "p90": round(float(np.percentile(cat("u_err"), 90)), 3)},
               "w_err_mps2": {"median": round(float(np.median(cat("w_err"))), 3), "p90": round(float(np.percentile(cat("w_err"), 90)), 3)}}
    for k in ("rmse_m", "rmse_hj_only_m", "rmse_rts_m", "rmse_plots_m"):
        summary[f"median_{k}"] = round(float(np.median([r[k] for r in rows])), 1)
    print(json.dumps({"summary": summary}))
    ex_key = max(matched or rows, key=lambda r: r["true_segments"])["flight"]
    r = out["hj+lm"][ex_key]
    plot_reconstruction(r, FIG / "reconstruction_simulated_example.png", (r.plots.t, truth[ex_key]))


if __name__ == "__main__":
    main()
