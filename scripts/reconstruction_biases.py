"""Radar biases in reconstruction: none, the truth, two-step (replay → --biases) and joint (--estimate-biases).

Builds the ``manoeuvres`` scenario (radar biases 80 m / 0.1° and −50 m / −0.12°), runs
``radartracker replay`` on it (the default estimator; it also uses the scenario's ADS-B), then
``radartracker reconstruct`` four ways with the same settings, and prints one JSON line per mode:
the pooled horizontal error against truth.csv at the plot times (median, p90 over all flights'
plots, from each flight's summary.json entry), the bias estimates against the truth, and the wall
time. Usage: nice python scripts/reconstruction_biases.py [--duration S] [--seed N] [--out DIR]
"""

from __future__ import annotations

import argparse
import json
import math
import tempfile
import time
from pathlib import Path

from radartracker.cli import main as cli
from radartracker.io.scenario import write_scenario
from radartracker.simulation.scenarios import build_scenario

SETTINGS = ["--engine", "process", "--workers", "2", "--quiet", "--no-figures", "--max-u", "12", "--max-w", "3"]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--duration", type=float, default=400.0)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--out", type=Path, default=None, help="working folder (default: a temporary one)")
    ap.add_argument("--fast", action="store_true", help="--no-shooting --hypotheses 4")
    args = ap.parse_args()
    work = args.out or Path(tempfile.mkdtemp(prefix="rec_biases_"))
    data = build_scenario("manoeuvres", seed=args.seed, duration=args.duration).run()
    scen = work / "scenario"
    write_scenario(scen, data)
    t0 = time.perf_counter()
    assert cli(["replay", str(scen), "--out", str(work / "replay"), "--quiet"]) == 0
    replay_s = time.perf_counter() - t0
    extra = SETTINGS + (["--no-shooting", "--hypotheses", "4"] if args.fast else [])
    modes = {"none": [], "truth": ["--truth-biases"], "two_step": ["--biases", str(work / "replay" / "biases.csv")],
             "joint": ["--estimate-biases"]}
    for mode, opts in modes.items():
        t0 = time.perf_counter()
        rc = cli(["reconstruct", str(scen), "--out", str(work / mode), *extra, *opts])
        wall = time.perf_counter() - t0
        s = json.loads((work / mode / "summary.json").read_text())
        med = [r["truth_error"]["median_m"] for r in s["reconstructed"]]
        p90 = [r["truth_error"]["p90_m"] for r in s["reconstructed"]]
        row = {"mode": mode, "exit": rc, "flights": len(med), "implausible": len(s["implausible"]),
               "median_of_flight_medians_m": round(sorted(med)[len(med) // 2], 1),
               "mean_flight_median_m": round(sum(med) / len(med), 1), "mean_flight_p90_m": round(sum(p90) / len(p90), 1),
               "wall_s": round(wall + (replay_s if mode == "two_step" else 0.0), 1)}
        est = None
        if mode == "joint":
            est = {r: (b["range_bias_m"], b["azimuth_bias_deg"]) for r, b in s["joint_biases"]["biases"].items()}
            row["rounds"] = s["joint_biases"]["rounds"]
        elif mode == "two_step":
            fb = json.loads((work / "replay" / "summary.json").read_text())["biases"]
            est = {r: (b["range_bias_m"], b["azimuth_bias_deg"]) for r, b in fb.items()}
        if est:
            row["bias_error"] = {r: {"range_m": round(est[r][0] - tb[0], 1),
                                     "azimuth_deg": round(est[r][1] - math.degrees(tb[1]), 4)}
                                 for r, tb in data.truth_biases.items()}
        print(json.dumps(row), flush=True)
    print(json.dumps({"work": str(work)}))


if __name__ == "__main__":
    main()
