"""Reconstruction speed: seconds per flight-hour on one core, and the speed-up with 2 Dask workers.

The same real flights (OpenSky Network, radar plots simulated as in reconstruction_real.py) are
reconstructed serially in this process, then on a Dask LocalCluster of 2 single-threaded workers.
Prints JSON lines. ``--module`` benchmarks another copy of the plugin (e.g. the code before a change,
extracted with ``git show`` into a package on PYTHONPATH) on the same flights, for before/after figures;
``--before PACKAGE`` times that copy serially first, in the same run, and prints both CPU costs per
flight-hour and their ratio.
Usage: python scripts/reconstruction_bench.py [--flights N] [--workers W] [--module PACKAGE] [--before PACKAGE]
[--jump-sd A]
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


def serial_cpu(module: str, tracks, cfg_kwargs: dict) -> tuple[int, float, float]:
    """(flights reconstructed, wall s, CPU s of this process) of ``module``'s serial engine on ``tracks``."""
    pkg = importlib.import_module(module)
    engine_mod = importlib.import_module(f"{module}.engine")
    with engine_mod.executor("serial", None) as ex:
        t0, c0 = time.perf_counter(), time.process_time()
        n = sum(1 for _ in engine_mod.run_many(tracks, pkg.ReconstructionConfig(**cfg_kwargs), ex, batch_plots=300,
                                               progress=False))
        return n, time.perf_counter() - t0, time.process_time() - c0


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--flights", type=int, default=8)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--module", default="radartracker_plugins.reconstruction", help="the plugin package to time")
    ap.add_argument("--before", default=None, help="a copy of the plugin to time serially first (before/after)")
    ap.add_argument("--engines", default="serial,dask", help="comma-separated: serial, dask")
    ap.add_argument("--jump-sd", type=float, default=None, help="control-jump prior (m/s²); default: the configuration's")
    args = ap.parse_args()
    allf = load_flights(DATA)
    ids = sorted(k for k in allf if k.startswith("paris-"))[: args.flights]
    tracks, _ = flights_to_plots({k: allf[k] for k in ids}, 0, 3)
    hours = sum(pt.duration for pt in tracks) / 3600
    cfg_kwargs = {"max_u": 9.5, **({} if args.jump_sd is None else {"jump_sd": args.jump_sd})}
    if args.before:
        cost = {}
        for role, module in (("before", args.before), ("after", args.module)):
            n, wall, cpu = serial_cpu(module, tracks, cfg_kwargs)
            cost[role] = cpu / hours
            print(json.dumps({"role": role, "module": module, "engine": "serial", "flights": n,
                              "flight_hours": round(hours, 2), "wall_s": round(wall, 1),
                              "cpu_s_per_flight_hour": round(cost[role], 1)}))
        print(json.dumps({"cpu_s_per_flight_hour_before": round(cost["before"], 1),
                          "cpu_s_per_flight_hour_after": round(cost["after"], 1),
                          "ratio": round(cost["before"] / cost["after"], 1)}))
        return
    pkg = importlib.import_module(args.module)
    engine_mod = importlib.import_module(f"{args.module}.engine")
    ReconstructionConfig, executor, run_many = pkg.ReconstructionConfig, engine_mod.executor, engine_mod.run_many
    cfg = ReconstructionConfig(**cfg_kwargs)
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
