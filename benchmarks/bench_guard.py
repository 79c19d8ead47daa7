"""The speed guard: this tree's unlabelled national replay against commit b75c53f's, in the same run.

    python benchmarks/bench_guard.py --tree base=/path/to/b75c53f/venv/bin/python --tree new=.venv/bin/python \\
        [--aircraft 2000] [--radars 28] [--minutes 3 27] [--repeat 3]

For each length, one scenario folder is simulated (national traffic: Mode S, 30 % ADS-B, no truth labels or
truth, so the replay is the TrackManager's and nothing is evaluated) and replayed by each tree in turn, each
replay a new process running ``radartracker replay FOLDER --manager`` through the public command line. The
cost per input is the replay process's CPU time (user + system, ``wait4``: a loaded machine slows the wall
clock, not the CPU time a process is given) less that of the same command on a 20-second scenario of 5
aircraft (imports, the compiled kernels' cache, start-up), over the inputs; peak memory is the process's
maximum resident set. Printed per replay, then the ratio of the trees' median costs and each tree's peak
memory at the longest length over the shortest (flat: near 1).
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import tempfile
from pathlib import Path

GENERATE = """
import sys, numpy as np
from radartracker.io.scenario import write_scenario
from radartracker.simulation.traffic import traffic_scenario
data = traffic_scenario(seed=1, duration=float(sys.argv[2]) * 60.0, aircraft=int(sys.argv[3]), radars=int(sys.argv[4])).run()
data.plots.target = np.full(len(data.plots), None, dtype=object)
data.truth = None
write_scenario(sys.argv[1], data)
print(len(data.plots) + len(data.adsb))
"""
REPLAY = "from radartracker.cli import main; import sys; sys.exit(main(sys.argv[1:]))"


def replay(python: str, folder: Path, out: Path) -> tuple[float, float]:
    """(CPU seconds, peak RSS MB) of one replay in a new process."""
    shutil.rmtree(out, ignore_errors=True)
    env = os.environ | {k: "1" for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMBA_NUM_THREADS")}
    # run outside any checkout: ``python -c`` puts the working folder first on the path
    proc = subprocess.Popen([python, "-c", REPLAY, "replay", str(folder), "--manager", "--quiet", "--out", str(out)],
                            stdout=subprocess.DEVNULL, env=env, cwd=folder.parent)
    _, status, usage = os.wait4(proc.pid, 0)
    if status:
        raise SystemExit(f"{python}: replay of {folder} failed ({status})")
    return usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024.0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tree", action="append", required=True, help="NAME=PYTHON of an environment with the tree")
    ap.add_argument("--aircraft", type=int, default=2000)
    ap.add_argument("--radars", type=int, default=28)
    ap.add_argument("--minutes", type=float, nargs="+", default=[3.0, 27.0])
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    trees = [t.split("=", 1) for t in args.tree]
    cost: dict[str, list[float]] = {name: [] for name, _ in trees}
    peak: dict[tuple[str, float], float] = {}
    with tempfile.TemporaryDirectory(prefix="bench_guard_") as tmp:
        tiny = Path(tmp) / "tiny"
        subprocess.run([trees[0][1], "-c", GENERATE.replace("aircraft=int(sys.argv[3]), radars=int(sys.argv[4])",
                                                            "aircraft=5, radars=2"), str(tiny), "0.34", "5", "2"],
                       check=True, capture_output=True, cwd=tmp)
        startup = {}
        for name, python in trees:  # the first replay also compiles or loads the kernels' cache
            replay(python, tiny, Path(tmp) / "tiny-out")
            startup[name] = min(replay(python, tiny, Path(tmp) / "tiny-out")[0] for _ in range(2))
            print(f"{name:<6} start-up and a 20-second replay of 5 aircraft: {startup[name]:.2f} CPU s", flush=True)
        for minutes in args.minutes:
            folder = Path(tmp) / f"scenario-{minutes:g}"
            inputs = int(subprocess.run([trees[0][1], "-c", GENERATE, str(folder), str(minutes), str(args.aircraft),
                                         str(args.radars)], check=True, capture_output=True, text=True,
                                        cwd=tmp).stdout.split()[-1])
            for k in range(args.repeat if minutes == args.minutes[0] else 1):
                for name, python in trees:  # in turns: the machine's load falls on both alike
                    cpu, rss = replay(python, folder, Path(tmp) / f"out-{name}")
                    us = (cpu - startup[name]) / inputs * 1e6
                    if minutes == args.minutes[0]:
                        cost[name].append(us)
                    peak[name, minutes] = max(peak.get((name, minutes), 0.0), rss)
                    print(f"{name:<6} {args.aircraft} aircraft x {args.radars} radars, {minutes:g} min, run {k + 1}: "
                          f"{inputs} inputs, {us:.1f} CPU us per input, peak RSS {rss:.1f} MB", flush=True)
            shutil.rmtree(folder)
    first = trees[0][0]
    for name, _ in trees:
        med = statistics.median(cost[name])
        line = f"{name:<6} median {med:.1f} us per input ({args.minutes[0]:g} min), {med / statistics.median(cost[first]):.2f}x {first}"
        if len(args.minutes) > 1:
            a, b = peak[name, args.minutes[0]], peak[name, args.minutes[-1]]
            line += f"; peak RSS {a:.1f} MB ({args.minutes[0]:g} min) -> {b:.1f} MB ({args.minutes[-1]:g} min), {b / a:.2f}x"
        print(line)


if __name__ == "__main__":
    main()
