"""``assess`` of national traffic on a Dask LocalCluster of 1 worker and of 2: both wall times, the speed-up
and the largest difference between the two results (docs/assessment.md, "Scale-out").

    python benchmarks/bench_assess_dask.py [--aircraft 2000] [--radars 28] [--minutes 10] [--slice-s 60] [--no-truth]

The scenario is :func:`radartracker.simulation.traffic.traffic_scenario` (truth kept: the reference; with
``--no-truth`` the truth and the plots' labels are dropped, so that the reference is the validated ADS-B and
the reconstruction of every other aircraft, on the same cluster, as for a user's recording). Each
assessment is the whole of :func:`radartracker.assessment.assess.assess` (the replay, in this process, and
the slices on the cluster, its start included); run it once before timing so that the compiled kernels'
cache is warm.
"""

from __future__ import annotations

import argparse
import math
import time

import attrs
import numpy as np

from radartracker.assessment.assess import AssessmentConfig, assess
from radartracker.assessment.profile import load_profile
from radartracker.assessment.slices import SliceConfig
from radartracker.simulation.traffic import traffic_scenario


def largest_difference(a: dict, b: dict, path: str = "") -> tuple[float, str]:
    """The largest relative difference between two assessment summaries' numbers, and where."""
    if isinstance(a, dict):
        return max((largest_difference(a[k], b[k], f"{path}/{k}") for k in a), default=(0.0, path))
    if isinstance(a, float) and isinstance(b, float) and a != b:
        return abs(a - b) / max(abs(a), abs(b)), path
    return (0.0, path) if a == b or (isinstance(a, float) and math.isnan(a)) else (math.inf, path)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--aircraft", type=int, default=2000)
    ap.add_argument("--radars", type=int, default=28)
    ap.add_argument("--minutes", type=float, default=10.0)
    ap.add_argument("--slice-s", type=float, default=60.0)
    ap.add_argument("--no-truth", action="store_true", help="the reference without truth (ADS-B + reconstruction)")
    args = ap.parse_args()
    t0 = time.perf_counter()
    data = traffic_scenario(seed=1, duration=args.minutes * 60.0, aircraft=args.aircraft, radars=args.radars).run()
    if args.no_truth:
        plots = attrs.evolve(data.plots, target=np.full(len(data.plots), None, dtype=object))
        data = attrs.evolve(data, plots=plots, truth=None)
    print(f"{args.aircraft} aircraft x {args.radars} radars, {args.minutes:g} min: {len(data.plots)} plots, "
          f"simulated in {time.perf_counter() - t0:.1f} s; slices of {args.slice_s:g} s"
          + ("; no truth" if args.no_truth else ""))
    walls, summaries = {}, {}
    for workers in (1, 2):
        t = time.perf_counter()
        a = assess(data, load_profile(), AssessmentConfig(slices=SliceConfig(args.slice_s, workers)), progress=False)
        walls[workers] = time.perf_counter() - t
        summaries[workers] = a.summary()
        print(f"LocalCluster of {workers} worker(s): {walls[workers]:.1f} s wall; reference {a.reference}"
              + (f", {len(a.reference_left_out)} aircraft left out" if a.reference_left_out else ""))
    diff, where = largest_difference(summaries[1], summaries[2])
    print(f"speed-up (1 worker / 2 workers): {walls[1] / walls[2]:.2f}")
    print(f"largest relative difference between the two results: {diff:.3g}" + (f" ({where})" if diff else ""))


if __name__ == "__main__":
    main()
