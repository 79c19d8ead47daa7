"""Benchmark: ``radartracker replay FOLDER --manager`` taken apart into reading, tracking and recording.

    python scripts/bench_replay_parts.py FOLDER [--repeat 2] [--record-only] [--convert]

FOLDER is an unlabelled scenario folder (``scripts/bench_national.py`` writes them). One JSON line, CPU
µs per input (``time.process_time``, under the replay's collector setting):

* ``read_us``: the folder's files to the list of ``Plot`` / ``AdsbReport`` items (``iter_files``);
* ``manager_us``: the TrackManager over that list, events made but not recorded (one run per repeat);
* ``manager_log_us``: the same with the run's ``Recorder`` taking every event as a row in the manager's
  ``event_log`` and making rows columns every 8 192 (no tables written), in the same turns;
* ``record_us``: in a third run per repeat, where the recorder hands its columns to an ``OutputStream``
  as the replay's does, the CPU of its ``flush`` calls alone: rows to columns to the CSV rows of
  ``events.csv`` and ``tracks.csv``, written to a temporary folder (the rows in the cache as the
  manager left them, which a replay of captured rows would not reproduce); ``--record-only``: these
  runs alone (the others' lists empty); ``record_write_us``: of that, the ``OutputStream.events`` calls
  (the columns to CSV rows, written), the rest being the rows made columns (``_log_events_of``) and the
  bias rows.

What the whole replay costs beyond ``read_us + manager_log_us`` is writing the tables and the run's files
(``bench_events_path.py`` times that part).

``--convert``: a second line, the frames' conversion to the plane alone: the TrackManager's
``_convert_frame`` calls of one run captured (each frame's plots by radar, ADS-B reports, positions, and
its live tracks' Mode S addresses and altitudes), then replayed on a new manager ``--repeat`` × 3 times;
``convert_us_per_frame`` and ``convert_us_per_input`` per round (the per-frame cost that light traffic pays
per input, without the rest of the replay's noise).
"""

from __future__ import annotations

import argparse
import gc
import json
import tempfile
import time
import types
from pathlib import Path

from radartracker.registry import make_manager
from radartracker.geometry.plane import SystemPlane
from radartracker.io.scenario import open_scenario
from radartracker.pipeline.config import RunConfig, resolve
from radartracker.pipeline.recorder import FLUSH_EVERY, Recorder
from radartracker.pipeline.run import GC_YOUNG_THRESHOLD, motion_factory
from radartracker.pipeline.stream import iter_files
from radartracker.pipeline.writer import OutputStream
from radartracker.tracking.manager import TrackManager


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("folder", type=Path)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--record-only", action="store_true", help="only the runs that time record_us")
    ap.add_argument("--convert", action="store_true", help="also time the frames' conversions alone")
    args = ap.parse_args()
    gc.set_threshold(GC_YOUNG_THRESHOLD)
    files = open_scenario(args.folder)
    c = time.process_time()
    items = list(iter_files(files))
    read = time.process_time() - c
    cfg = resolve(RunConfig(association="manager"), files.data, "coupled-sparse")

    def run(log: bool, out: Path | None = None) -> tuple[float, float, float]:
        """CPU µs per input of the run, of the recorder's flush calls in it and of their sink's events calls."""
        mgr = make_manager(files.data.radars, files.data.reference, cfg.manager_settings(),
                           filter_factory=motion_factory(cfg))
        sink = None if out is None else TimedStream(out, SystemPlane(*files.data.reference))
        rec = Recorder(sink=sink, keep=False)
        if log:
            mgr.event_log = rec.manager_log
        flush = 0.0
        c = time.process_time()
        for item in items:
            mgr.process(item)
            if log and len(rec.manager_log) >= FLUSH_EVERY:
                f = time.process_time()
                rec.flush()
                flush += time.process_time() - f
        mgr.flush()
        f = time.process_time()
        rec.flush()
        end = time.process_time()
        if sink is not None:
            sink.close()
        per_input = 1e6 / len(items)
        return (end - c) * per_input, (flush + end - f) * per_input, sink.cpu * per_input if sink is not None else 0.0

    plain, logged, recorded, written = [], [], [], []
    with tempfile.TemporaryDirectory() as tmp:
        run(True, Path(tmp))  # compiled kernels loaded, caches warm
        for _ in range(args.repeat):
            if not args.record_only:
                plain.append(round(run(False)[0], 2))
                logged.append(round(run(True)[0], 2))
            _, record, write = run(True, Path(tmp))
            recorded.append(round(record, 2))
            written.append(round(write, 2))
    print(json.dumps({"folder": str(args.folder), "inputs": len(items), "read_us": round(read / len(items) * 1e6, 2),
                      "manager_us": plain, "manager_log_us": logged, "record_us": recorded,
                      "record_write_us": written}))
    if args.convert:
        print(json.dumps({"folder": str(args.folder), **convert_costs(files, cfg, items, 3 * args.repeat)}))


class TimedStream(OutputStream):
    """An OutputStream that adds up the CPU of its ``events`` calls (s) in ``cpu``."""

    cpu = 0.0

    def events(self, ev) -> None:
        c = time.process_time()
        super().events(ev)
        self.cpu += time.process_time() - c


def convert_costs(files, cfg, items: list, rounds: int) -> dict:
    """CPU µs per frame and per input of the run's ``TrackManager._convert_frame`` calls replayed alone."""
    def manager() -> TrackManager:
        return make_manager(files.data.radars, files.data.reference, cfg.manager_settings(),
                            filter_factory=motion_factory(cfg))

    calls, original = [], TrackManager._convert_frame

    def capture(self, by_radar, reports, positions, live):
        live_now = [types.SimpleNamespace(mode_s=t.mode_s, altitude_m=t.altitude_m) for t in live]
        calls.append(({r: list(p) for r, p in by_radar.items()}, list(reports), list(positions), live_now))
        return original(self, by_radar, reports, positions, live)

    TrackManager._convert_frame = capture
    try:
        mgr = manager()
        for item in items:
            mgr.process(item)
        mgr.flush()
    finally:
        TrackManager._convert_frame = original
    mgr, per_frame = manager(), []
    inputs = sum(sum(map(len, c[0].values())) + len(c[1]) + len(c[2]) for c in calls)
    for _ in range(rounds):
        c = time.process_time()
        for call in calls:
            mgr._convert_frame(*call)
        per_frame.append((time.process_time() - c) / len(calls) * 1e6)
    return {"part": "convert", "frames": len(calls), "inputs_per_frame": round(inputs / len(calls), 1),
            "convert_us_per_frame": [round(v, 1) for v in per_frame],
            "convert_us_per_input": [round(v * len(calls) / inputs, 2) for v in per_frame]}

if __name__ == "__main__":
    main()
