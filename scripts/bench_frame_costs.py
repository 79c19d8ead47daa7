"""Benchmark: ``radartracker replay FOLDER --manager`` split into per-run, per-frame and per-input CPU.

    python scripts/bench_frame_costs.py FOLDER [FOLDER ...] [--repeat 3]

FOLDER is an unlabelled scenario folder (``scripts/bench_national.py`` writes them). The cost per input
is flat in the traffic only if what a run pays once, and what a frame pays whatever its inputs, are small
beside what the inputs pay; this script measures the three.

* **per run**: the replay of a copy of FOLDER cut to its first frame (its radars, reference and aircraft,
  the plots and ADS-B reports before the first frame's end): set-up, the one frame, outputs, summary.
  The same cut replay again with timers on the steps a run takes once (nested: a step's time includes
  the steps it calls) gives one JSON line per step (``"part": "run"``).
* **per frame**: the whole replay with timers on the TrackManager's frame methods, each call timed with
  ``time.process_time``: one line per method (``"part": "frame"``: calls, CPU, µs per call, per frame and
  per input). Over the frames, a frame's own cost — ``_run_frame`` less the ``_apply`` of its inputs — is
  fitted by least squares to ``a + b·inputs + c·tracks`` (the frame's inputs and live tracks; tracks grow
  from none at the start, so the three separate): ``a`` is the fixed cost of a frame.
* **per input**: the rest of the untimed replay's CPU, ``(total − per_run − frames·a) / inputs``
  (reading, admission, ``_apply``, events, and the frame work that grows with inputs and tracks).

Times are CPU (``time.process_time``) on whatever load the machine has; the untimed replays take the
minimum over ``--repeat``. A warm-up replay of the cut loads imports and compiled-kernel caches first.
The last line per folder (``"part": "split"``) sums it up.
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import functools
import importlib
import io
import json
import math
import shutil
import tempfile
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

FRAME_METHODS = ("_run_frame", "_predict", "_convert_frame", "_track_phases", "_associate", "_exact", "_misses",
                 "_coverage", "_sweep", "_apply")
# steps a replay takes once: (module, attribute path) as the caller looks them up
RUN_STEPS = (("radartracker.cli", "build_parser"), ("radartracker.pipeline.writer", "prepare"),
             ("radartracker.pipeline.run", "replay_folder"), ("radartracker.pipeline.run", "open_scenario"),
             ("radartracker.pipeline.writer", "OutputStream.__init__"), ("radartracker.pipeline.run", "resolve"),
             ("radartracker.pipeline.run", "make_estimator"), ("radartracker.pipeline.run", "motion_factory"),
             ("radartracker.pipeline.run", "default_estimator"), ("radartracker.registry", "_group"),
             ("radartracker.tracking.manager", "TrackManager.__init__"), ("radartracker.pipeline.run", "_by_manager"),
             ("radartracker.tracking.manager", "TrackManager.flush"), ("radartracker.pipeline.writer", "OutputStream.close"),
             ("radartracker.pipeline.result", "RunResult.summary"), ("radartracker.pipeline.run", "write_outputs"))


def cut_first_frame(folder: Path, out: Path, frame_s: float) -> int:
    """``folder`` copied to ``out`` with only the plots and ADS-B reports of its first frame; their number."""
    out.mkdir(parents=True, exist_ok=True)
    for f in folder.iterdir():
        if f.is_file() and f.name not in ("plots.csv", "adsb.csv"):
            shutil.copy(f, out / f.name)
    rows = {}
    for name in ("plots.csv", "adsb.csv"):
        with (folder / name).open(newline="") as f:
            rows[name] = list(csv.reader(f))
    first = min(float(r[0]) for rs in rows.values() for r in rs[1:])
    end = (math.floor(first / frame_s) + 1) * frame_s
    kept = 0
    for name, rs in rows.items():
        keep = [rs[0]] + [r for r in rs[1:] if float(r[rs[0].index("time")]) < end]
        kept += len(keep) - 1
        with (out / name).open("w", newline="") as f:
            csv.writer(f, lineterminator="\n").writerows(keep)
    return kept


def replay_cpu(folder: Path, out: Path) -> float:
    from radartracker.cli import main

    with contextlib.redirect_stdout(io.StringIO()):
        c0 = time.process_time()
        rc = main(["replay", str(folder), "--out", str(out), "--manager", "--quiet", "--overwrite"])
        cpu = time.process_time() - c0
    if rc != 0:
        raise SystemExit(f"replay of {folder} failed (rc {rc})")
    return cpu


@contextlib.contextmanager
def timed(owner, name: str, on_call):
    """``owner.name`` replaced by a wrapper calling ``on_call(self_or_None, cpu_s, before)`` after each call."""
    original = getattr(owner, name)

    @functools.wraps(original)
    def wrapper(*args, **kwargs):
        c0 = time.process_time()
        try:
            return original(*args, **kwargs)
        finally:
            on_call(time.process_time() - c0)

    setattr(owner, name, wrapper)
    try:
        yield
    finally:
        setattr(owner, name, original)


def timer_overhead_s() -> float:
    """CPU a timed call adds around the call it times (the wrapper and two clock reads)."""
    class Probe:
        def f(self):
            return None
    p, n, acc = Probe(), 20_000, []
    with timed(Probe, "f", acc.append):
        c0 = time.process_time()
        for _ in range(n):
            p.f()
        timed_s = time.process_time() - c0
    Probe.f(p)
    c0 = time.process_time()
    for _ in range(n):
        p.f()
    return max(timed_s - (time.process_time() - c0), 0.0) / n


def run_steps(cut: Path, out: Path) -> list[dict]:
    """CPU of each once-per-run step in a replay of the cut folder (nested times included)."""
    acc: dict[str, list[float]] = defaultdict(list)
    with contextlib.ExitStack() as stack:
        for mod, path in RUN_STEPS:
            owner = importlib.import_module(mod)
            *outer, name = path.split(".")
            for part in outer:
                owner = getattr(owner, part)
            stack.enter_context(timed(owner, name, acc[path].append))
        total = replay_cpu(cut, out)
    return [{"part": "run", "step": k, "calls": len(v), "cpu_ms": round(1e3 * sum(v), 2)} for k, v in acc.items()] + [
        {"part": "run", "step": "whole replay (timed)", "calls": 1, "cpu_ms": round(1e3 * total, 2)}]


def frame_costs(folder: Path, out: Path) -> tuple[dict, list[dict]]:
    """The whole replay with its frame methods timed: per-method totals and one record per frame."""
    from radartracker.tracking.manager import TrackManager

    frames: list[dict] = []
    totals: dict[str, list[float]] = defaultdict(list)
    current: dict = {}

    def on(name: str):
        def record(dt: float) -> None:
            totals[name].append(dt)
            current[name] = current.get(name, 0.0) + dt
        return record

    with contextlib.ExitStack() as stack:
        for name in FRAME_METHODS:
            stack.enter_context(timed(TrackManager, name, on(name)))
        timed_run = TrackManager._run_frame

        def run_frame(self, frame):  # one record per frame: its inputs, live tracks and methods' CPU
            current.clear()
            current["inputs"], current["tracks"] = len(self._frame_items), len(self.tracks)
            timed_run(self, frame)
            frames.append(dict(current))

        TrackManager._run_frame = run_frame
        try:
            total = replay_cpu(folder, out)
        finally:
            TrackManager._run_frame = timed_run
    return {"total": total, "totals": totals}, frames


def fit_frames(frames: list[dict], overhead_s: float) -> dict:
    """Least squares of a frame's own CPU (``_run_frame`` less its ``_apply``) on [1, inputs, tracks]."""
    y = np.array([f.get("_run_frame", 0.0) - f.get("_apply", 0.0) for f in frames])
    X = np.array([[1.0, f["inputs"], f["tracks"]] for f in frames])
    coef, *_ = np.linalg.lstsq(X, y, rcond=None)
    return {"fixed_us": 1e6 * coef[0], "per_input_us": 1e6 * coef[1], "per_track_us": 1e6 * coef[2],
            "mean_us": 1e6 * float(y.mean()), "timer_overhead_us_per_call": 1e6 * overhead_s}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folders", type=Path, nargs="+")
    ap.add_argument("--repeat", type=int, default=3, help="untimed replays of each folder (minimum kept)")
    args = ap.parse_args()

    from radartracker.tracking.manager import ManagerConfig

    frame_s = ManagerConfig().frame_s
    overhead = timer_overhead_s()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for folder in args.folders:
            cut = tmp / f"{folder.name}_cut"
            cut_inputs = cut_first_frame(folder, cut, frame_s)
            replay_cpu(cut, tmp / "warm")  # imports, kernel caches, pyproj's database
            per_run = min(replay_cpu(cut, tmp / "cut_out") for _ in range(max(args.repeat, 1)))
            for line in run_steps(cut, tmp / "cut_out"):
                print(json.dumps({"folder": str(folder), **line}), flush=True)
            total = min(replay_cpu(folder, tmp / "out") for _ in range(max(args.repeat, 1)))
            timed_run, frames = frame_costs(folder, tmp / "out")
            inputs = sum(f["inputs"] for f in frames)
            n = len(frames)
            for name in FRAME_METHODS:
                v = timed_run["totals"].get(name, [])
                s = sum(v)
                print(json.dumps({"folder": str(folder), "part": "frame", "method": name, "calls": len(v),
                                  "cpu_s": round(s, 4), "us_per_call": round(1e6 * s / max(len(v), 1), 2),
                                  "us_per_frame": round(1e6 * s / n, 1), "us_per_input": round(1e6 * s / inputs, 2)}),
                      flush=True)
            fit = fit_frames(frames, overhead)
            per_frame = fit["fixed_us"] * 1e-6
            per_input = (total - per_run - n * per_frame) / inputs
            print(json.dumps({"folder": str(folder), "part": "split", "inputs": inputs, "frames": n,
                              "inputs_per_frame": round(inputs / n, 1), "cut_inputs": cut_inputs,
                              "replay_cpu_s": round(total, 3), "us_per_input": round(1e6 * total / inputs, 2),
                              "per_run_cpu_s": round(per_run, 4), "per_frame_fixed_us": round(fit["fixed_us"], 1),
                              "frame_fit_per_input_us": round(fit["per_input_us"], 2),
                              "frame_fit_per_track_us": round(fit["per_track_us"], 3),
                              "frame_own_mean_us": round(fit["mean_us"], 1),
                              "per_input_us": round(1e6 * per_input, 2),
                              "per_run_share_us_per_input": round(1e6 * per_run / inputs, 2),
                              "per_frame_share_us_per_input": round(1e6 * n * per_frame / inputs, 2),
                              "timed_replay_cpu_s": round(timed_run["total"], 3),
                              "timer_overhead_us_per_call": round(fit["timer_overhead_us_per_call"], 3)}), flush=True)


if __name__ == "__main__":
    main()
