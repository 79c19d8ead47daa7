"""Peak memory of the replay of a national recording as a CSV folder and as a partitioned Parquet dataset.

    nice python benchmarks/bench_parquet.py [--aircraft 2000] [--radars 28] [--minutes 3 27]

For each length, national traffic is simulated (``traffic_scenario(seed=1, ...)``: Mode S, 30 % ADS-B; no truth
labels or truth, so that the replay is the TrackManager's, streamed, and nothing is evaluated) and written
twice with the public writer: as CSV files (``write_scenario``) and as Parquet with plots and ADS-B reports
partitioned by hour and radar (``write_scenario(..., format="dataset")``). Each folder is replayed in a new
process by the public command line, ``radartracker replay FOLDER --manager --quiet --out OUT``; its peak memory
is the process's maximum resident set, its cost the process's CPU time (``os.wait4``). Printed per replay,
then each format's peak memory at the longest length over the shortest (flat: near 1), and the folders'
sizes on disk. A 20-second replay of 5 aircraft first compiles or loads the kernels' cache.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

GENERATE = """
import sys, numpy as np
from radartracker.io.scenario import write_scenario
from radartracker.simulation.traffic import traffic_scenario
data = traffic_scenario(seed=1, duration=float(sys.argv[2]) * 60.0, aircraft=int(sys.argv[3]), radars=int(sys.argv[4])).run()
data.plots.target = np.full(len(data.plots), None, dtype=object)
data.truth = None
write_scenario(sys.argv[1] + "/csv", data)
write_scenario(sys.argv[1] + "/dataset", data, format="dataset")
print(len(data.plots) + len(data.adsb))
"""
REPLAY = "from radartracker.cli import main; import sys; sys.exit(main(sys.argv[1:]))"
FORMATS = ("csv", "dataset")


def replay(folder: Path, out: Path) -> tuple[float, float]:
    """(CPU seconds, peak RSS MB) of one replay in a new process."""
    shutil.rmtree(out, ignore_errors=True)
    env = os.environ | {k: "1" for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMBA_NUM_THREADS")}
    proc = subprocess.Popen([sys.executable, "-c", REPLAY, "replay", str(folder), "--manager", "--quiet", "--out",
                             str(out)], stdout=subprocess.DEVNULL, env=env, cwd=folder.parent)
    _, status, usage = os.wait4(proc.pid, 0)
    if status:
        raise SystemExit(f"replay of {folder} failed ({status})")
    return usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024.0


def size_mb(folder: Path) -> float:
    return sum(p.stat().st_size for p in folder.rglob("*") if p.is_file()) / 1e6


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--aircraft", type=int, default=2000)
    ap.add_argument("--radars", type=int, default=28)
    ap.add_argument("--minutes", type=float, nargs="+", default=[3.0, 27.0])
    args = ap.parse_args()
    peak: dict[tuple[str, float], float] = {}
    with tempfile.TemporaryDirectory(prefix="bench_parquet_") as tmp:
        tiny = Path(tmp) / "tiny"
        tiny.mkdir()
        subprocess.run([sys.executable, "-c", GENERATE, str(tiny), "0.34", "5", "2"], check=True, capture_output=True,
                       cwd=tmp)
        replay(tiny / "dataset", Path(tmp) / "tiny-out")
        for minutes in args.minutes:
            folder = Path(tmp) / f"scenario-{minutes:g}"
            folder.mkdir()
            inputs = int(subprocess.run([sys.executable, "-c", GENERATE, str(folder), str(minutes), str(args.aircraft),
                                         str(args.radars)], check=True, capture_output=True, text=True,
                                        cwd=tmp).stdout.split()[-1])
            for fmt in FORMATS:
                cpu, rss = replay(folder / fmt, Path(tmp) / "out")
                peak[fmt, minutes] = rss
                print(f"{fmt:<8} {args.aircraft} aircraft x {args.radars} radars, {minutes:g} min: {inputs} inputs, "
                      f"{size_mb(folder / fmt):.1f} MB on disk, {cpu:.1f} CPU s, peak RSS {rss:.1f} MB", flush=True)
            shutil.rmtree(folder)
    if len(args.minutes) > 1:
        first, last = args.minutes[0], args.minutes[-1]
        for fmt in FORMATS:
            a, b = peak[fmt, first], peak[fmt, last]
            print(f"{fmt:<8} peak RSS {a:.1f} MB ({first:g} min) -> {b:.1f} MB ({last:g} min), {b / a:.2f}x")


if __name__ == "__main__":
    main()
