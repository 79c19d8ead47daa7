"""Monte Carlo of the radar-bias estimates: joint (reconstruction) against two-step (replay), with NEES.

Each run draws :func:`radartracker_plugins.reconstruction.sim.biased_scenario` (two radars with biases
60 m / 0.08° and −40 m / −0.10°, four flights with one turn, σ 70 m / 0.08°, no ADS-B) and estimates
the biases two ways on the same plots:

* joint: ``--estimate-biases``'s rounds (:func:`~radartracker_plugins.reconstruction.joint.joint_rounds`),
  after the hypothesis search (default) or, with ``--true-structure``, from each flight's true
  segment structure (what the quick test does);
* two-step: ``radartracker replay`` (the default estimator) on the scenario folder, its final biases
  and sd from ``summary.json`` (what ``reconstruct --biases`` would take).

Prints one JSON line per run (bias errors and NEES per radar), then per method the RMS errors and the
NEES summed over runs and radars against the two-sided 99 % χ² interval (2 degrees of freedom per
radar and run; the replay gives sd only, so its NEES uses a diagonal covariance).
Usage: nice python scripts/reconstruction_bias_nees.py [--runs N] [--duration S] [--true-structure]
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.stats import chi2

from radartracker.cli import main as cli
from radartracker.io.scenario import write_scenario
from radartracker_plugins.reconstruction import ReconstructionConfig
from radartracker_plugins.reconstruction.engine import run_many
from radartracker_plugins.reconstruction.hypotheses import Reconstruction, refit
from radartracker_plugins.reconstruction.integrate import geo_track
from radartracker_plugins.reconstruction.joint import joint_rounds
from radartracker_plugins.reconstruction.sim import BIASES, biased_scenario, true_control
from radartracker_plugins.reconstruction.tracks import scenario_tracks

CFG = ReconstructionConfig(max_u=6.0, max_w=2.0, shooting=False, hypotheses=3)


def joint(data, flights, true_structure: bool) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    tracks, _, _ = scenario_tracks(data)
    if true_structure:
        recs = {}
        for pt in tracks:
            ct = true_control(flights[pt.key], float(pt.t[0]), float(pt.t[-1]))
            recs[pt.key] = refit(Reconstruction(pt.key, pt, (), geo_track(ct, CFG.grid_dt), 0.0), pt, CFG)
    else:
        recs = {r.key: r for r in run_many(tracks, CFG, None, progress=False)}
    _, biases, _, _ = joint_rounds(tracks, recs, CFG)
    return {r: (b.value, b.cov) for r, b in biases.items()}


def two_step(data, work: Path) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    write_scenario(work / "scenario", data)
    with contextlib.redirect_stdout(sys.stderr):  # the replay's own report, off the JSON lines
        assert cli(["replay", str(work / "scenario"), "--out", str(work / "replay"), "--quiet"]) == 0
    fb = json.loads((work / "replay" / "summary.json").read_text())["biases"]
    return {r: (np.array([b["range_bias_m"], math.radians(b["azimuth_bias_deg"])]),
                np.diag([b["sd_range_m"] ** 2, math.radians(b["sd_azimuth_deg"]) ** 2])) for r, b in fb.items()}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=20)
    ap.add_argument("--duration", type=float, default=200.0)
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--true-structure", action="store_true", help="joint rounds from the true segment structure")
    args = ap.parse_args()
    err: dict[str, list] = {"joint": [], "two_step": []}
    nees: dict[str, list] = {"joint": [], "two_step": []}
    wall = {"joint": 0.0, "two_step": 0.0}
    for seed in range(args.first_seed, args.first_seed + args.runs):
        data, flights = biased_scenario(seed, args.duration)
        row = {"seed": seed}
        with tempfile.TemporaryDirectory(prefix="bias_nees_") as tmp:
            for name, run in (("joint", lambda: joint(data, flights, args.true_structure)),
                              ("two_step", lambda: two_step(data, Path(tmp)))):
                t0 = time.perf_counter()
                est = run()
                wall[name] += time.perf_counter() - t0
                row[name] = {}
                for radar, true in BIASES.items():
                    value, cov = est[radar]
                    e = value - np.array(true)
                    q = float(e @ np.linalg.solve(cov, e))
                    err[name].append(e)
                    nees[name].append(q)
                    row[name][radar] = {"error_m_deg": [round(float(e[0]), 1), round(math.degrees(e[1]), 4)],
                                        "sd_m_deg": [round(float(np.sqrt(cov[0, 0])), 1),
                                                     round(math.degrees(np.sqrt(cov[1, 1])), 4)],
                                        "nees": round(q, 2)}
        print(json.dumps(row), flush=True)
    for name in err:
        e = np.array(err[name])
        lo, hi = chi2.ppf([0.005, 0.995], 2 * len(nees[name]))
        print(json.dumps({"method": name, "runs": args.runs, "duration_s": args.duration,
                          "true_structure": args.true_structure if name == "joint" else None,
                          "rms_error_range_m": round(float(np.sqrt(np.mean(e[:, 0] ** 2))), 1),
                          "rms_error_azimuth_deg": round(math.degrees(float(np.sqrt(np.mean(e[:, 1] ** 2)))), 4),
                          "nees_mean_per_radar": round(float(np.mean(nees[name])), 2), "nees_dof": 2,
                          "nees_sum": round(float(np.sum(nees[name])), 1),
                          "chi2_99_interval": [round(float(lo), 1), round(float(hi), 1)],
                          "consistent": bool(lo < np.sum(nees[name]) < hi), "wall_s": round(wall[name], 1)}))


if __name__ == "__main__":
    main()
