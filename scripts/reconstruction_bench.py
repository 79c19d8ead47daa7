"""Reconstruction speed: seconds per flight-hour on one core, and the speed-up with 2 Dask workers.

The same real flights (OpenSky Network, radar plots simulated as in reconstruction_real.py) are
reconstructed serially in this process, then on a Dask LocalCluster of 2 single-threaded workers.
Prints JSON lines. Usage: python scripts/reconstruction_bench.py [--flights N] [--workers W]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from reconstruction_real import DATA, flights_to_plots  # noqa: E402

from radartracker.simulation.flights import load_flights  # noqa: E402
from radartracker_plugins.reconstruction import ReconstructionConfig  # noqa: E402
from radartracker_plugins.reconstruction.engine import executor, run_many  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--flights", type=int, default=8)
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    allf = load_flights(DATA)
    ids = sorted(k for k in allf if k.startswith("paris-"))[: args.flights]
    tracks, _ = flights_to_plots({k: allf[k] for k in ids}, 0, 3)
    hours = sum(pt.duration for pt in tracks) / 3600
    cfg = ReconstructionConfig(max_u=9.5)
    times = {}
    for engine, workers in (("serial", None), ("dask", args.workers)):
        with executor(engine, workers) as ex:
            t0 = time.perf_counter()
            n = sum(1 for _ in run_many(tracks, cfg, ex, batch_plots=300, progress=False))
            times[engine] = time.perf_counter() - t0
        print(json.dumps({"engine": engine, "workers": workers or 1, "flights": n, "flight_hours": round(hours, 2),
                          "wall_s": round(times[engine], 1), "s_per_flight_hour": round(times[engine] / hours, 1)}))
    print(json.dumps({"dask_speedup": round(times["serial"] / times["dask"], 2), "workers": args.workers}))


if __name__ == "__main__":
    main()
