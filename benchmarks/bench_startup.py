"""Benchmark: how long the ``radartracker`` command takes to start, in new processes.

    python benchmarks/bench_startup.py [--tree NAME=PYTHON ...] [--repeat 5]

Each command (``radartracker --help``, ``radartracker estimators``, ``radartracker replay --help``) is
started ``--repeat`` times as a new process through the environment's own console script (the
``radartracker`` beside its Python), the trees in turns, so that a load on the machine falls on each
alike. One JSON line per tree and command: the median and every wall-clock second, and the load of
the machine. The command line imports a module only when a command needs it (radartracker.cli):
``--help`` reads the entry points and builds the parsers, nothing more.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

COMMANDS = (("--help",), ("estimators",), ("replay", "--help"))


def wall(script: Path, command: tuple[str, ...]) -> float:
    """Wall-clock seconds of one ``script COMMAND`` process, to its exit."""
    started = time.perf_counter()
    subprocess.run([str(script), *command], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True)
    return time.perf_counter() - started


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--tree", action="append", default=None,
                    help="NAME=PYTHON of an environment with the tree (default: this Python's)")
    ap.add_argument("--repeat", type=int, default=5, help="processes per tree and command (default 5)")
    args = ap.parse_args()
    trees = [t.split("=", 1) for t in args.tree or [f"this={sys.executable}"]]
    # the console script beside the interpreter, as a user's shell finds it; not resolved: a venv's python is a link
    scripts = {name: Path(python).parent / "radartracker" for name, python in trees}
    for command in COMMANDS:
        walls: dict[str, list[float]] = {name: [] for name in scripts}
        for name, script in scripts.items():
            wall(script, command)  # the files read once: the first process is not a cold disk's
        for _ in range(args.repeat):
            for name, script in scripts.items():
                walls[name].append(wall(script, command))
        for name, w in walls.items():
            print(json.dumps({"bench": "startup", "tree": name, "command": " ".join(command),
                              "median_wall_s": round(statistics.median(w), 3), "wall_s": [round(x, 3) for x in w],
                              "load1": round(os.getloadavg()[0], 2)}), flush=True)


if __name__ == "__main__":
    main()
