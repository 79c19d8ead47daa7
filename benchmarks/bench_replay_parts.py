"""Benchmark: ``radartracker replay FOLDER --manager`` taken apart through public calls, CPU µs per input.

    python benchmarks/bench_replay_parts.py FOLDER [--repeat 3] [--part NAME ...] [--gc-young N ...]

FOLDER is an unlabelled scenario folder (``python benchmarks/bench_national.py generate --folder F`` writes
one). The parts, each a prefix of the replay's work so that the differences of two lines say what a stage
costs:

* ``startup``: CPU seconds (user + system) of a ``radartracker --help`` process: the imports every command
  pays (not per input);
* ``blocks``: ``open_scenario(FOLDER)`` and both files read block by block (``ScenarioFiles.plot_blocks``,
  ``adsb_blocks``): read, checked, converted to column tables;
* ``read``: ``iter_files(open_scenario(FOLDER))`` used up: the blocks, made into ``Plot`` / ``AdsbReport``
  items merged in time order;
* ``manager``: a TrackManager of the replay's settings (``registry.make_manager`` with the resolved
  ``RunConfig(association="manager")``) given those items, already read into a list, by
  ``TrackManager.process``, then ``flush``: admission, frames, association, track filters, the bias
  estimator and events (no listener);
* ``run``: ``pipeline.run.run`` on the same list: the manager with the replay's recorder listening to its
  events and logging the biases (no file written);
* ``replay``: ``radartracker replay FOLDER --manager --quiet`` in this process: reading, tracking and
  writing every output file.

Each part runs once untimed (imports, compiled kernels' caches), then ``--repeat`` times; one JSON line per
timed run, CPU (``time.process_time``, this process only) so a shared machine gives comparable numbers;
``load1`` says how shared it was. The parts run under the replay's collector setting (``young_garbage``);
``--gc-young N ...`` runs the ``manager`` part under each threshold N of the youngest generation instead,
in turns (700 is Python's default), to check the replay's choice.
"""

from __future__ import annotations

import argparse
import collections
import contextlib
import io
import json
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from radartracker.cli import main as cli
from radartracker.io.scenario import open_scenario
from radartracker.pipeline.config import RunConfig, resolve
from radartracker.pipeline.run import GC_YOUNG_THRESHOLD, run, young_garbage
from radartracker.pipeline.stream import iter_files
from radartracker.registry import default_estimator, make_manager

CONFIG = RunConfig(association="manager")


def startup_cpu_s() -> float:
    """CPU seconds of a ``radartracker --help`` process."""
    proc = subprocess.Popen([sys.executable, "-c", "from radartracker.cli import main; main(['--help'])"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    _, _, usage = os.wait4(proc.pid, 0)
    return usage.ru_utime + usage.ru_stime


def parts(folder: Path, out: Path, gc_young: int = GC_YOUNG_THRESHOLD) -> dict[str, Callable[[], float]]:
    """Each part: a function returning its CPU seconds (what it needs made before its clock starts)."""
    def blocks() -> float:
        c0 = time.process_time()
        files = open_scenario(folder)
        collections.deque(files.plot_blocks(), maxlen=0)
        collections.deque(files.adsb_blocks(), maxlen=0)
        return time.process_time() - c0

    def read() -> float:
        c0 = time.process_time()
        collections.deque(iter_files(open_scenario(folder)), maxlen=0)
        return time.process_time() - c0

    def manager() -> float:
        files = open_scenario(folder)
        items = list(iter_files(files))
        cfg = resolve(CONFIG, files.data, default_estimator())
        mgr = make_manager(files.data.radars, files.data.reference, cfg.manager_settings())
        with young_garbage(gc_young):
            c0 = time.process_time()
            for item in items:
                mgr.process(item)
            mgr.flush()
            return time.process_time() - c0

    def run_() -> float:
        files = open_scenario(folder)
        items = list(iter_files(files))
        c0 = time.process_time()
        run(files.data, CONFIG, progress=False, inputs=items, total=len(items))
        return time.process_time() - c0

    def replay() -> float:
        c0 = time.process_time()
        with contextlib.redirect_stdout(io.StringIO()):
            rc = cli(["replay", str(folder), "--out", str(out), "--manager", "--quiet", "--overwrite"])
        if rc != 0:
            raise SystemExit(f"replay of {folder} failed (exit {rc})")
        return time.process_time() - c0

    return {"blocks": blocks, "read": read, "manager": manager, "run": run_, "replay": replay}


def gc_turns(folder: Path, thresholds: list[int], repeat: int) -> None:
    """The ``manager`` part under each collector threshold in turns, so a changing load falls on all alike."""
    inputs = sum(1 for _ in iter_files(open_scenario(folder)))
    with tempfile.TemporaryDirectory(prefix="bench_replay_parts_") as tmp:
        runs = {n: parts(folder, Path(tmp) / "out", n)["manager"] for n in thresholds}
        runs[thresholds[0]]()  # warm-up
        for _ in range(repeat):
            for n, part in runs.items():
                cpu = part()
                print(json.dumps({"folder": str(folder), "part": "manager", "gc_young": n, "inputs": inputs,
                                  "cpu_s": round(cpu, 3), "us_per_input": round(cpu / inputs * 1e6, 2),
                                  "load1": round(os.getloadavg()[0], 2)}), flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("folder", type=Path)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--part", action="append", help="only this part (repeatable; default: all)")
    ap.add_argument("--gc-young", type=int, nargs="+", help="thresholds for the manager part (in turns)")
    args = ap.parse_args()
    if args.gc_young:
        gc_turns(args.folder, args.gc_young, args.repeat)
        return
    chosen = args.part or ["startup", "blocks", "read", "manager", "run", "replay"]
    if "startup" in chosen:
        print(json.dumps({"folder": str(args.folder), "part": "startup", "cpu_s": round(startup_cpu_s(), 3),
                          "load1": round(os.getloadavg()[0], 2)}), flush=True)
    inputs = sum(1 for _ in iter_files(open_scenario(args.folder)))
    with tempfile.TemporaryDirectory(prefix="bench_replay_parts_") as tmp:
        for name, part in parts(args.folder, Path(tmp) / "out").items():
            if name not in chosen:
                continue
            part()  # warm-up
            for _ in range(args.repeat):
                cpu = part()
                print(json.dumps({"folder": str(args.folder), "part": name, "inputs": inputs, "cpu_s": round(cpu, 3),
                                  "us_per_input": round(cpu / inputs * 1e6, 2),
                                  "load1": round(os.getloadavg()[0], 2)}), flush=True)


if __name__ == "__main__":
    main()
