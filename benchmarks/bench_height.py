"""What the height stage costs (issue 29: at most 1.2× the TrackManager without it), at national scale.

    python benchmarks/bench_height.py [--repeat 3] [--set national-primary]

The set (``scripts/tracking_report.py``'s ``national-primary`` by default: 28 radars 200 km apart,
primary-only plots without altitude, 10 minutes) is read into a list once; then a TrackManager of the
default settings is given every input (``process``, then ``flush``) with the height stage off and on
(``ManagerConfig.height.enabled``), in turns, ``--repeat`` times. Prints the CPU time per input of each run
(this process's, so another job on the other core slows the wall clock, not this), then the ratio of the
medians.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
import tracking_report  # noqa: E402

from radartracker.pipeline.stream import scenario_stream  # noqa: E402
from radartracker.registry import make_manager  # noqa: E402
from radartracker.tracking.config import ManagerConfig  # noqa: E402
from radartracker.tracking.height import HeightConfig  # noqa: E402


def cost(data, items: list, enabled: bool) -> float:
    """CPU µs per input of one TrackManager run over ``items``."""
    mgr = make_manager(data.radars, data.reference, ManagerConfig(height=HeightConfig(enabled=enabled)))
    started = time.process_time()
    for item in items:
        mgr.process(item)
    mgr.flush()
    return 1e6 * (time.process_time() - started) / len(items)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--set", default="national-primary")
    args = ap.parse_args()
    sets = argparse.Namespace(approach_s=1800.0, enroute_s=3600.0, max_flights=None, cruise_s=1800.0,
                              national_s=600.0, seed=1)
    data = tracking_report.build(args.set, sets)
    items = list(scenario_stream(data))
    runs: dict[bool, list[float]] = {False: [], True: []}
    for k in range(args.repeat):
        for enabled in (False, True):
            runs[enabled].append(cost(data, items, enabled))
            print(f"run {k + 1}, height stage {'on ' if enabled else 'off'}: {len(items)} inputs, "
                  f"{runs[enabled][-1]:.1f} CPU us per input", flush=True)
    off, on = statistics.median(runs[False]), statistics.median(runs[True])
    print(f"median off {off:.1f}, on {on:.1f} us per input: {on / off:.2f}x")


if __name__ == "__main__":
    main()
