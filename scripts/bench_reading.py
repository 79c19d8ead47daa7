from radartracker.registry import make_manager
"""Benchmark: what each input of a streamed replay costs before the TrackManager's frames (issue 13), one JSON
line per stage.

    python scripts/bench_reading.py FOLDER [--repeat 2] [--stage NAME ...] [--default-gc] [--replay]
                                           [--warm-up FOLDER]

* ``read``: ``iter_files(open_scenario(FOLDER))`` used up (blocks read, checked, converted to Plot /
  AdsbReport items and merged in time order);
* ``blocks``: the part of ``read`` before any item is made: the folder opened and both files read block by
  block, checked and converted to tables (``ScenarioFiles.plot_blocks`` / ``adsb_blocks``);
* ``admit``: ``TrackManager.process`` of those items (already in a list) with the frame step replaced by
  one that drops the frame's items: admission (kind, duplicates, lateness, time jumps, stream clock), the
  reordering heap and the release into frames, nothing else;
* ``read_admit``: both, the items going from the reader to the manager as in the replay;
* ``frame_inputs``: ``admit`` with each frame's inputs taken in as ``_run_frame`` takes them, before any
  track is looked at: gathered by kind and radar, converted to the plane (``_convert_frame``, all plots at
  the altitude they carry or the primary one: no track exists), the antenna phases (``_track_phases``);
* ``replay`` (with ``--replay``): ``radartracker replay FOLDER --manager`` in this process, after a warm-up
  replay of ``--warm-up`` (default FOLDER itself: imports and compiled-kernel caches loaded).

CPU µs per input (``time.process_time``, this process only, after one warm-up pass of the stage), so a
shared machine gives comparable numbers; ``load1`` says how shared it was. The stages run with the cyclic
garbage collector set as the replay sets it (:func:`radartracker.pipeline.run.young_garbage`; ``gc_young``
in each line), unless ``--default-gc`` (Python's default, as this script measured before session 6: the
reader's items are then scanned again and again, about half of ``read``).
"""

from __future__ import annotations

import argparse
import collections
import contextlib
import gc
import io
import json
import os
import tempfile
import time
from pathlib import Path


def _manager(files, frames: bool = False):
    """A TrackManager of the replay's settings whose frames only drop their inputs (admission and release),
    or with ``frames`` take them in as far as the plane (see ``frame_inputs``)."""
    from radartracker.pipeline.config import RunConfig, resolve
    from radartracker.pipeline.run import motion_factory
    from radartracker.tracking.manager import TrackManager

    cfg = resolve(RunConfig(), files.data, "coupled-sparse")
    mgr = make_manager(files.data.radars, files.data.reference, cfg.manager_settings(), None,
                       filter_factory=motion_factory(cfg))
    if not frames:
        mgr._run_frame = lambda frame: setattr(mgr, "_frame_items", [])
        return mgr
    run_frame, convert = mgr._run_frame, mgr._convert_frame

    def convert_then_stop(by_radar, reports, live):  # _run_frame's input side, then out of it
        convert(by_radar, reports, live)
        mgr._track_phases(by_radar)
        raise _Done

    def take_in(frame: int) -> None:
        try:
            run_frame(frame)
        except _Done:
            pass

    mgr._run_frame, mgr._convert_frame = take_in, convert_then_stop
    return mgr


class _Done(Exception):
    """Ends a ``frame_inputs`` frame once its inputs are in the plane."""


def stages(folder: Path):
    """Each stage: a function giving (inputs, CPU seconds), the manager made before the clock starts."""
    from radartracker.io.scenario import open_scenario
    from radartracker.pipeline.stream import iter_files

    def read() -> tuple[int, float]:
        c0 = time.process_time()
        n = sum(1 for _ in iter_files(open_scenario(folder)))
        return n, time.process_time() - c0

    def blocks() -> tuple[int, float]:
        c0 = time.process_time()
        files = open_scenario(folder)
        n = sum(map(len, files.plot_blocks())) + sum(map(len, files.adsb_blocks()))
        return n, time.process_time() - c0

    def admit() -> tuple[int, float]:
        items = list(iter_files(open_scenario(folder)))  # made and dropped here: not alive in the other stages
        mgr = _manager(open_scenario(folder))
        c0 = time.process_time()
        collections.deque(map(mgr.process, items), maxlen=0)
        mgr.flush()
        return len(items), time.process_time() - c0

    def read_admit() -> tuple[int, float]:
        mgr = _manager(open_scenario(folder))
        c0 = time.process_time()
        n = 0
        for item in iter_files(open_scenario(folder)):
            mgr.process(item)
            n += 1
        mgr.flush()
        return n, time.process_time() - c0

    def frame_inputs() -> tuple[int, float]:
        items = list(iter_files(open_scenario(folder)))
        mgr = _manager(open_scenario(folder), frames=True)
        c0 = time.process_time()
        collections.deque(map(mgr.process, items), maxlen=0)
        mgr.flush()
        return len(items), time.process_time() - c0

    return {"read": read, "blocks": blocks, "admit": admit, "read_admit": read_admit, "frame_inputs": frame_inputs}


def replay(folder: Path, out: Path) -> tuple[int, float]:
    from radartracker.cli import main

    c0 = time.process_time()
    with contextlib.redirect_stdout(io.StringIO()):
        if main(["replay", str(folder), "--out", str(out), "--manager", "--quiet", "--overwrite"]) != 0:
            raise SystemExit("replay failed")
    return 0, time.process_time() - c0


def measure(name: str, folder: Path, f, repeat: int, inputs: int | None = None) -> None:
    for _ in range(repeat):
        n, cpu = f()
        n = inputs or n
        print(json.dumps({"folder": str(folder), "stage": name, "inputs": n, "cpu_s": round(cpu, 3),
                          "us_per_input": round(cpu / n * 1e6, 2), "gc_young": gc.get_threshold()[0],
                          "load1": round(os.getloadavg()[0], 2)}), flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("folder", type=Path)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--replay", action="store_true", help="also the whole replay")
    ap.add_argument("--warm-up", type=Path, help="the folder replayed once before (default: FOLDER)")
    ap.add_argument("--stage", action="append", help="only this stage (repeatable; default: all)")
    ap.add_argument("--default-gc", action="store_true", help="Python's collector settings, not the replay's")
    ap.add_argument("--only-replay", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if not args.only_replay:
        from radartracker.pipeline.run import young_garbage

        with contextlib.nullcontext() if args.default_gc else young_garbage():
            for name, f in stages(args.folder).items():
                if args.stage is None or name in args.stage:
                    f()  # warm-up
                    measure(name, args.folder, f, args.repeat)
    if args.replay or args.only_replay:
        from radartracker.io.scenario import open_scenario
        from radartracker.pipeline.stream import iter_files

        n = sum(1 for _ in iter_files(open_scenario(args.folder)))
        with tempfile.TemporaryDirectory(prefix="bench_reading_") as tmp:
            replay(args.warm_up or args.folder, Path(tmp) / "warm")
            measure("replay", args.folder, lambda: replay(args.folder, Path(tmp) / "out"), args.repeat, n)


if __name__ == "__main__":
    main()
