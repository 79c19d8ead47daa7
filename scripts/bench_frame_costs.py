"""Benchmark: ``radartracker replay FOLDER --manager`` split into per-run, per-frame and per-input CPU.

    python scripts/bench_frame_costs.py FOLDER [FOLDER ...] [--repeat 3]

FOLDER is an unlabelled scenario folder (``scripts/bench_national.py`` writes them). The cost per input
is flat in the traffic only if what a run pays once, and what a frame pays whatever its inputs, are small
beside what the inputs pay; this script measures the three.

* **per run**: the replay of a copy of FOLDER cut to its first frame (its radars, reference and aircraft,
  the plots and ADS-B reports before the first frame's end), less that frame's own CPU: set-up, outputs,
  summary. The same cut replay again with timers on the steps a run takes once (nested: a step's time
  includes the steps it calls) gives one JSON line per step (``"part": "run"``).
* **per frame**: the replay of a copy of FOLDER thinned to ``--thin`` aircraft (the first Mode S addresses
  of ``plots.csv``, their plots and ADS-B reports: the same radars and frames, about one input per frame)
  with the TrackManager's frame methods timed, each call with ``time.process_time``: a frame's own CPU
  there (``_run_frame`` less the ``_apply`` of its inputs) is what a frame costs whatever the traffic. One
  line per method (``"part": "frame"``) gives its µs per frame in that thin replay and in the whole one
  (timed the same way), and µs per input of the whole one.
* **progress bar**: what the bar of a replay without ``--quiet`` adds per input, over the folder's inputs with
  a body that does nothing (``"part": "progress"``): the plain loop (``--quiet``), tqdm's own iterator (the
  replay's loop before) and the pieces of ``radartracker.pipeline.run.counted`` (the loop now), µs per input.
* **bias log**: each radar's bias recorded once a second after one of its plots, whatever the traffic
  (``"part": "bias_log"``): the records of the replay, and µs per record of the replay's way (the
  estimator's ``bias_arrays`` into ``Recorder.bias_arrays``) and of the way before (a ``BiasState`` from
  ``bias`` into ``Recorder.bias``), replayed in turns on the replay's final estimator.
* **per input**: the rest of the untimed whole replay's CPU, ``(total − per_run − frames × per_frame) /
  inputs`` (reading, admission, ``_apply``, events, and the frame work that grows with inputs and tracks).

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
RUN_STEPS = (("radartracker.tracking.manager", "TrackManager._run_frame"), ("radartracker.cli", "_parser"),
             ("radartracker.pipeline.writer", "prepare"),
             ("radartracker.pipeline.run", "replay_folder"), ("radartracker.pipeline.run", "open_scenario"),
             ("radartracker.pipeline.writer", "OutputStream.__init__"), ("radartracker.pipeline.run", "resolve"),
             ("radartracker.pipeline.run", "make_estimator"), ("radartracker.pipeline.run", "motion_factory"),
             ("radartracker.pipeline.run", "default_estimator"), ("radartracker.registry", "_group"),
             ("radartracker.tracking.manager", "TrackManager.__init__"), ("radartracker.pipeline.run", "_by_manager"),
             ("radartracker.tracking.manager", "TrackManager.flush"),
             ("radartracker.pipeline.writer", "OutputStream.close"),
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


def thin(folder: Path, out: Path, aircraft: int) -> int:
    """``folder`` copied to ``out`` with only the plots and ADS-B reports of its first ``aircraft`` Mode S
    addresses; their number."""
    out.mkdir(parents=True, exist_ok=True)
    for f in folder.iterdir():
        if f.is_file() and f.name not in ("plots.csv", "adsb.csv"):
            shutil.copy(f, out / f.name)
    kept, codes = 0, []
    for name, column in (("plots.csv", "mode_s"), ("adsb.csv", "icao24")):
        with (folder / name).open(newline="") as f:
            rows = list(csv.reader(f))
        k = rows[0].index(column)
        if not codes:
            codes = list(dict.fromkeys(r[k] for r in rows[1:] if r[k]))[:aircraft]
        keep = [rows[0]] + [r for r in rows[1:] if r[k] in codes]
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


def run_steps(cut: Path, out: Path) -> tuple[list[dict], float]:
    """CPU of each once-per-run step in a replay of the cut folder (nested times included), and of its
    frames (``_run_frame``)."""
    acc: dict[str, list[float]] = defaultdict(list)
    with contextlib.ExitStack() as stack:
        for mod, path in RUN_STEPS:
            owner = importlib.import_module(mod)
            *outer, name = path.split(".")
            for part in outer:
                owner = getattr(owner, part)
            stack.enter_context(timed(owner, name, acc[path].append))
        total = replay_cpu(cut, out)
    lines = [{"part": "run", "step": k, "calls": len(v), "cpu_ms": round(1e3 * sum(v), 2)} for k, v in acc.items()]
    return lines + [{"part": "run", "step": "whole replay (timed)", "calls": 1, "cpu_ms": round(1e3 * total, 2)}], \
        sum(acc["TrackManager._run_frame"])


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
            current["calls"] = current.get("calls", 0) + 1
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


def own_us(frames: list[dict], overhead_s: float) -> float:
    """Mean CPU µs of a frame less the ``_apply`` of its inputs and the timers of the calls inside it."""
    return 1e6 * float(np.mean([f.get("_run_frame", 0.0) - f.get("_apply", 0.0) - overhead_s * (f.get("calls", 1) - 1)
                                for f in frames]))


def progress_costs(folder: Path, repeat: int) -> dict:
    """CPU µs per input of a loop that does nothing over the folder's inputs: plain, through tqdm's iterator,
    and in the pieces of :func:`radartracker.pipeline.run.counted` (the bar as the replay sets it up)."""
    from tqdm import tqdm

    from radartracker.io.scenario import open_scenario
    from radartracker.pipeline.run import counted
    from radartracker.pipeline.stream import iter_files

    items = list(iter_files(open_scenario(folder)))
    sink = io.StringIO()  # the bar's text, if the loop outlasts its delay

    def plain() -> None:
        for _ in items:
            pass

    def tqdm_iterator() -> None:
        for _ in tqdm(items, total=len(items), delay=2.0, mininterval=1.0, file=sink):
            pass

    def pieces() -> None:
        with tqdm(total=len(items), delay=2.0, mininterval=1.0, file=sink) as bar:
            for piece in counted(items, bar):
                for _ in piece:
                    pass

    cpu: dict[str, list[float]] = defaultdict(list)
    for _ in range(max(repeat, 3)):  # in turns: a load that comes and goes falls on all three
        for name, loop in (("plain", plain), ("tqdm_iterator", tqdm_iterator), ("pieces", pieces)):
            c0 = time.process_time()
            loop()
            cpu[name].append(time.process_time() - c0)
    return {"folder": str(folder), "part": "progress", "inputs": len(items),
            **{f"{k}_us_per_input": round(1e6 * min(v) / len(items), 3) for k, v in cpu.items()}}


def bias_log_costs(folder: Path, out: Path, repeat: int) -> dict:
    """From a replay of ``folder`` with its bias records (item time and radar) and final estimator captured:
    CPU µs per record of recording them again on that estimator, through ``bias_arrays`` and through a
    BiasState."""
    import radartracker.pipeline.run as run_module
    from radartracker.pipeline.recorder import Recorder

    calls, made = [], []
    make, record = run_module.make_estimator, Recorder.bias_arrays

    def capture(self, time, radar, *arrays):
        calls.append((time, radar))
        return record(self, time, radar, *arrays)

    run_module.make_estimator = lambda *a, **k: made.append(make(*a, **k)) or made[-1]
    Recorder.bias_arrays = capture
    try:
        replay_cpu(folder, out)
    finally:
        run_module.make_estimator, Recorder.bias_arrays = make, record
    est = made[-1]

    def arrays() -> None:
        rec = Recorder()
        for t, rid in calls:
            if rec.bias_due(rid, t):
                rec.bias_arrays(t, rid, *est.bias_arrays(rid))
        rec.biases()

    def states() -> None:
        rec = Recorder()
        for t, rid in calls:
            if rec.bias_due(rid, t):
                rec.bias(t, est.bias(rid))
        rec.biases()

    cpu: dict[str, list[float]] = defaultdict(list)
    for _ in range(max(repeat, 5)):  # in turns
        for name, loop in (("bias_arrays", arrays), ("bias_state", states)):
            c0 = time.process_time()
            loop()
            cpu[name].append(time.process_time() - c0)
    median = {k: float(np.median(v)) for k, v in cpu.items()}
    bias = {f"{k}_us_per_record": round(1e6 * median[k] / len(calls), 2) for k in ("bias_arrays", "bias_state")}
    return {"folder": str(folder), "part": "bias_log", "records": len(calls), **bias}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folders", type=Path, nargs="+")
    ap.add_argument("--repeat", type=int, default=3, help="untimed replays of each folder (minimum kept)")
    ap.add_argument("--thin", type=int, default=5, help="aircraft kept in the thin replay (per-frame cost)")
    args = ap.parse_args()

    from radartracker.tracking.manager import ManagerConfig

    frame_s = ManagerConfig().frame_s
    repeat, overhead = max(args.repeat, 1), timer_overhead_s()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for folder in args.folders:
            cut, sparse = tmp / f"{folder.name}_cut", tmp / f"{folder.name}_thin"
            cut_inputs, thin_inputs = cut_first_frame(folder, cut, frame_s), thin(folder, sparse, args.thin)
            replay_cpu(cut, tmp / "warm")  # imports, kernel caches, pyproj's database
            cut_cpu = min(replay_cpu(cut, tmp / "cut_out") for _ in range(repeat))
            steps, cut_frames = run_steps(cut, tmp / "cut_out")
            for line in steps:
                print(json.dumps({"folder": str(folder), **line}), flush=True)
            per_run = cut_cpu - cut_frames
            print(json.dumps(progress_costs(folder, repeat)), flush=True)
            print(json.dumps(bias_log_costs(folder, tmp / "out", repeat)), flush=True)
            thin_run, thin_frames = frame_costs(sparse, tmp / "out")
            total = min(replay_cpu(folder, tmp / "out") for _ in range(repeat))
            timed_run, frames = frame_costs(folder, tmp / "out")
            inputs, n = sum(f["inputs"] for f in frames), len(frames)
            for name in FRAME_METHODS:
                v, w = timed_run["totals"].get(name, []), thin_run["totals"].get(name, [])
                print(json.dumps({"folder": str(folder), "part": "frame", "method": name, "calls": len(v),
                                  "thin_us_per_frame": round(1e6 * sum(w) / max(len(thin_frames), 1), 1),
                                  "us_per_frame": round(1e6 * sum(v) / n, 1),
                                  "us_per_call": round(1e6 * sum(v) / max(len(v), 1), 2),
                                  "us_per_input": round(1e6 * sum(v) / inputs, 2)}), flush=True)
            per_frame = own_us(thin_frames, overhead) * 1e-6
            per_input = (total - per_run - n * per_frame) / inputs
            print(json.dumps({"folder": str(folder), "part": "split", "inputs": inputs, "frames": n,
                              "inputs_per_frame": round(inputs / n, 1), "replay_cpu_s": round(total, 3),
                              "us_per_input": round(1e6 * total / inputs, 2), "per_run_cpu_s": round(per_run, 4),
                              "per_frame_fixed_us": round(1e6 * per_frame, 1),
                              "per_input_us": round(1e6 * per_input, 2),
                              "per_run_share_us_per_input": round(1e6 * per_run / inputs, 2),
                              "per_frame_share_us_per_input": round(1e6 * n * per_frame / inputs, 2),
                              "frame_own_us": round(own_us(frames, overhead), 1), "cut_inputs": cut_inputs,
                              "thin_aircraft": args.thin, "thin_inputs": thin_inputs,
                              "thin_inputs_per_frame": round(thin_inputs / max(len(thin_frames), 1), 2),
                              "timed_replay_cpu_s": round(timed_run["total"], 3),
                              "timer_overhead_us_per_call": round(1e6 * overhead, 3)}), flush=True)


if __name__ == "__main__":
    main()
