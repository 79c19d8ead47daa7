"""Reconstruction speed: seconds per flight-hour on one core, and the speed-up with 2 Dask workers.

The same real flights (OpenSky Network, radar plots simulated as in reconstruction_real.py) are
reconstructed serially in this process, then on a Dask LocalCluster of 2 single-threaded workers.
Prints JSON lines. ``--module`` benchmarks another copy of the plugin (e.g. the code before a change,
extracted with ``git show`` into a package on PYTHONPATH) on the same flights, for before/after figures.
Usage: python scripts/reconstruction_bench.py [--flights N] [--workers W] [--module PACKAGE] [--jump-sd A]
"""

from __future__ import annotations

import argparse
import importlib
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from reconstruction_real import DATA, flights_to_plots  # noqa: E402

from radartracker.simulation.flights import load_flights  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--flights", type=int, default=8)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--module", default="radartracker_plugins.reconstruction", help="the plugin package to time")
    ap.add_argument("--engines", default="serial,dask", help="comma-separated: serial, dask")
    ap.add_argument("--jump-sd", type=float, default=None, help="control-jump prior (m/s²); default: the configuration's")
    args = ap.parse_args()
    pkg = importlib.import_module(args.module)
    engine_mod = importlib.import_module(f"{args.module}.engine")
    ReconstructionConfig, executor, run_many = pkg.ReconstructionConfig, engine_mod.executor, engine_mod.run_many
    allf = load_flights(DATA)
    ids = sorted(k for k in allf if k.startswith("paris-"))[: args.flights]
    tracks, _ = flights_to_plots({k: allf[k] for k in ids}, 0, 3)
    hours = sum(pt.duration for pt in tracks) / 3600
    cfg = ReconstructionConfig(max_u=9.5, **({} if args.jump_sd is None else {"jump_sd": args.jump_sd}))
    times = {}
    for engine, workers in ((e, None if e == "serial" else args.workers) for e in args.engines.split(",")):
        with executor(engine, workers) as ex:
            t0, c0 = time.perf_counter(), time.process_time()
            n = sum(1 for _ in run_many(tracks, cfg, ex, batch_plots=300, progress=False))
            times[engine] = time.perf_counter() - t0
            cpu = time.process_time() - c0  # this process only: meaningful for the serial engine
        print(json.dumps({"module": args.module, "engine": engine, "workers": workers or 1, "flights": n,
                          "jump_sd": getattr(cfg, "jump_sd", None),
                          "flight_hours": round(hours, 2),
                          "wall_s": round(times[engine], 1), "s_per_flight_hour": round(times[engine] / hours, 1),
                          **({"cpu_s_per_flight_hour": round(cpu / hours, 1)} if engine == "serial" else {})}))
    if len(times) == 2:
        print(json.dumps({"module": args.module, "dask_speedup": round(times["serial"] / times["dask"], 2),
                          "workers": args.workers}))


if __name__ == "__main__":
    main()
