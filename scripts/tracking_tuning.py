"""Choose the ``imm`` settings of the TrackManager by measurement (issue 17, "with Mode S the
en-route p95 drops").

For each value of the IMM's constant-velocity process-noise density ``q`` (m²/s³) and, optionally,
of the coordinated-turn mode's ``q_turn``, runs the TrackManager (defaults otherwise) on the
scenario sets of ``scripts/tracking_report.py`` — en-route with Mode S, en-route primary-only and
approach primary-only by default — and prints one JSON line per run (the report's metrics), then a
Markdown table. ``--q-estimator`` also sets the bias estimator's aircraft process noise
(``EstimatorConfig.motion.q``; by default it stays at its own default and the IMM's ``q`` is given as
a motion option).

Usage: python scripts/tracking_tuning.py [--q 0.2 0.5 1 2 5] [--q-turn 1] [--sets enroute+modeS enroute approach]
       [--enroute-s 3600] [--approach-s 1800]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import tracking_report as report  # noqa: E402

from radartracker.tracking.config import ManagerConfig  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--q", nargs="*", type=float, default=[0.2, 0.5, 1.0, 2.0, 5.0])
    ap.add_argument("--q-turn", nargs="*", type=float, default=[None])
    ap.add_argument("--sets", nargs="*", default=["enroute+modeS", "enroute", "approach"])
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--approach-s", type=float, default=1800.0)
    ap.add_argument("--enroute-s", type=float, default=3600.0)
    ap.add_argument("--max-flights", type=int, default=None)
    args = ap.parse_args()
    rows = []
    for name in args.sets:
        base, mode_s = name.split("+")[0], name.endswith("+modeS")
        data = report.build(base, args, mode_s=mode_s)
        for q in args.q:
            for q_turn in args.q_turn:
                options = {"q": repr(q)} | ({} if q_turn is None else {"q_turn": repr(q_turn)})
                tracks, biases, wall = report.run_manager(data, ManagerConfig(motion_model="imm", motion_options=options))
                row = {"set": name, "q": q, "q_turn": q_turn, **report.evaluate(data, tracks), **biases,
                       "ms_per_plot": 1e3 * wall / len(data.plots)}
                print(json.dumps(row), flush=True)
                rows.append(row)
    print()
    print("| set | IMM q (m²/s³) | q_turn | breaks (% flights) | false confirmed | RMSE (m) | p95 (m) | "
          "p95 straight / turning (m) |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['set']} | {r['q']:g} | {'default' if r['q_turn'] is None else format(r['q_turn'], 'g')} | "
              f"{r['breaks']} ({r['breaks_pct']:.1f} %) | {r['false_confirmed']} | {r['rmse_m']:.1f} | "
              f"{r['p95_m']:.1f} | {r['p95_straight_m']:.0f} / {r['p95_turning_m']:.0f} |")


if __name__ == "__main__":
    main()
