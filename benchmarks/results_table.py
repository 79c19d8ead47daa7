"""Results of two trees on the built-in scenarios, side by side: tracking quality and bias errors.

Each scenario is simulated once (by the first tree) and replayed by every tree given, with the truth-label
association and with the TrackManager, through the ``radartracker`` command of each tree's environment
(public interface only). Printed per run: confirmed tracks, breaks, swaps, false tracks, position RMSE of
the estimates against the truth, and the largest range and azimuth bias errors over the radars, with the
change of each tree's figures against the first's. With ``--seeds N`` each scenario is simulated with seeds
1 … N and the figures pooled: counts summed, the RMSE averaged, and the largest bias errors as their root
mean square over the seeds — one seed's largest bias error moves by about its σ from seed to seed, so a
percentage change on one seed says little (docs/design-notes.md, the height stage's note).

    python benchmarks/results_table.py --tree base=/work/base/.venv/bin/radartracker \\
        --tree new=.venv/bin/radartracker [--big] [--seeds 12]
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import tempfile
from pathlib import Path

SCENARIOS = [
    ("demo", ["--scenario", "demo"]),
    ("paris", ["--scenario", "paris"]),
    ("tracking", ["--scenario", "tracking"]),
    ("manoeuvres", ["--scenario", "manoeuvres"]),
    ("traffic-200", ["--scenario", "traffic", "--aircraft", "200", "--duration", "180"]),
    ("traffic-200-primary", ["--scenario", "traffic", "--aircraft", "200", "--duration", "180", "--primary-share", "1.0",
                             "--adsb-share", "0"]),
]
BIG = [("traffic-2000", ["--scenario", "traffic", "--aircraft", "2000", "--duration", "180"])]
ASSOCIATIONS = {"labels": ["--association", "labels"], "manager": ["--manager"]}


def metrics(summary: dict) -> dict:
    """The figures compared, from a run's summary.json."""
    tr, truth, biases = summary.get("tracking") or {}, summary.get("truth") or {}, summary.get("biases") or {}
    err_r = max((abs(b.get("error_range_m", 0.0)) for b in biases.values()), default=float("nan"))
    err_a = max((abs(b.get("error_azimuth_deg", 0.0)) for b in biases.values()), default=float("nan"))
    return {"tracks": tr.get("confirmed_tracks"), "breaks": tr.get("breaks"), "swaps": tr.get("swaps"),
            "false": tr.get("false_tracks"), "rmse_m": truth.get("position_rmse_m"), "bias_r_m": err_r,
            "bias_az_deg": err_a}


def replay(exe: str, scenario: Path, out: Path, association: str) -> dict:
    subprocess.run([exe, "replay", str(scenario), "--out", str(out), "--quiet", *ASSOCIATIONS[association]],
                   check=True, stdout=subprocess.DEVNULL, cwd=out.parent)
    return metrics(json.loads((out / "summary.json").read_text()))


def pooled(runs: list[dict]) -> dict:
    """The figures of one tree over seeds: counts summed, RMSE averaged, bias errors as their RMS."""
    out = {k: sum(m[k] or 0 for m in runs) for k in ("tracks", "breaks", "swaps", "false")}
    rmse = [m["rmse_m"] for m in runs if m["rmse_m"] is not None]
    out["rmse_m"] = sum(rmse) / len(rmse) if rmse else None
    for k in ("bias_r_m", "bias_az_deg"):
        out[k] = math.sqrt(sum(m[k] ** 2 for m in runs) / len(runs))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tree", action="append", required=True, help="NAME=PATH of a radartracker command")
    ap.add_argument("--big", action="store_true", help="also the 2 000-aircraft traffic")
    ap.add_argument("--only", help="comma-separated scenario names")
    ap.add_argument("--seeds", type=int, default=1, help="simulate seeds 1..N of each scenario and pool them")
    args = ap.parse_args()
    trees = [t.split("=", 1) for t in args.tree]
    chosen = SCENARIOS + (BIG if args.big else [])
    if args.only:
        chosen = [s for s in chosen if s[0] in args.only.split(",")]
    work = Path(tempfile.mkdtemp(prefix="results-"))
    print(f"{'scenario':<20} {'assoc':<8} {'tree':<6} {'tracks':>6} {'breaks':>6} {'swaps':>5} {'false':>5} "
          f"{'rmse m':>8} {'bias r m':>9} {'bias az °':>10}  change vs {trees[0][0]}")
    for name, sim in chosen:
        for seed in range(1, args.seeds + 1):
            subprocess.run([trees[0][1], "simulate", str(work / f"{name}-{seed}"), "--seed", str(seed), *sim],
                           check=True, stdout=subprocess.DEVNULL, cwd=work)
        for assoc in ASSOCIATIONS:
            first = None
            for tree, exe in trees:
                m = pooled([replay(exe, work / f"{name}-{seed}", work / f"{name}-{seed}-{assoc}-{tree}", assoc)
                            for seed in range(1, args.seeds + 1)])
                first = first or m
                change = " ".join(f"{k} {100 * (m[k] - first[k]) / first[k]:+.2f}%" for k in ("rmse_m", "bias_r_m", "bias_az_deg")
                                  if m[k] is not None and first[k])
                print(f"{name:<20} {assoc:<8} {tree:<6} {m['tracks']!s:>6} {m['breaks']!s:>6} {m['swaps']!s:>5} "
                      f"{m['false']!s:>5} {m['rmse_m'] or float('nan'):>8.2f} {m['bias_r_m']:>9.3f} "
                      f"{m['bias_az_deg']:>10.5f}  {change}", flush=True)


if __name__ == "__main__":
    main()
