from radartracker.registry import make_manager
"""Benchmark: the events-and-outputs part of ``radartracker replay FOLDER --manager``, in CPU µs per input.

    python scripts/bench_events_path.py FOLDER [--repeat 3]

FOLDER is an unlabelled scenario folder (``scripts/bench_national.py`` writes them). That part is the
TrackManager's ``_emit`` (the event's state from the track's kept estimate, the ``TrackEvent``, its row in
the run's ``event_log`` with covariance and identity) and what follows it: the recorder making the rows
columns, the per-plot bias logging, the writing of ``events.csv``, ``tracks.csv`` and ``biases.csv``, and
the end of the run (``coupling.graphml``, ``summary.json``, ``config.json``).

It is isolated as follows. One real run records, for every input, the events the TrackManager emitted
and the state of each event's track at that moment (its estimate (t, x, P), status and identity). The
folder's inputs are read once into a list. Then ``run`` with a sink (``replay_folder``'s streamed branch:
tables written as the run goes, then its summary and remaining files) runs on that list with a stand-in for
the TrackManager that, for the same inputs, reads each event's track estimate as the manager does
(``filter.estimate()`` copying x and P, as the IMM's does) and emits the event again with the manager's
own ``_emit`` (a deleted track as it was at its deletion): everything else is the real code. Its CPU time,
minus that of the stand-in alone over the list reading the estimates but emitting nothing, divided by the
inputs, is ``path_us``; ``emit_us`` is the stand-in emitting without ``on_event`` or event log minus the
stand-in alone, ``tables_us`` the part spent in ``OutputStream`` (formatting and writing the three tables),
``columns_us`` the recorder making event rows columns (``Recorder._columns`` without the tables in it). The
recorded events are frozen out of the garbage collector's scans (``gc.freeze``) and the stand-in runs
under the run's collector setting. Times are ``time.process_time`` (minimum over ``--repeat`` runs) on
whatever load the machine has: one JSON line.
"""

from __future__ import annotations

import argparse
import contextlib
import gc
import io
import json
import tempfile
import time
from pathlib import Path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folder", type=Path)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()

    from radartracker.estimation.coupling import CouplingGraph
    from radartracker.geometry.plane import SystemPlane
    from radartracker.io.scenario import open_scenario
    from radartracker.pipeline import recorder
    from radartracker.pipeline import run as runmod
    from radartracker.pipeline import writer
    from radartracker.pipeline.config import RunConfig, resolve
    from radartracker.pipeline.stream import iter_files
    from radartracker.registry import make_estimator
    from radartracker.tracking.manager import TrackManager, default_estimator

    config = RunConfig(association="manager")
    files = open_scenario(args.folder)
    cfg = resolve(config, files.data, default_estimator())
    est = make_estimator(cfg.estimator, cfg.estimator_settings(), [r.id for r in files.data.radars],
                         cfg.estimator_options)
    per_item: list[list] = []
    current: list = []

    seen: dict = {}  # every track by id (a deleted one is gone from mgr.tracks when its event comes)

    def capture(ev) -> None:
        tr = seen[ev.track] = mgr.tracks.get(ev.track) or seen[ev.track]
        t, x, P = TrackManager._estimate_of(tr)
        current.append((ev, _Track(tr.id, (t, x.copy(), P.copy()), tr.altitude_m, tr.mode_s, tr.mode_3a)))

    mgr = make_manager(files.data.radars, files.data.reference, cfg.manager_settings(), capture, estimator=est,
                       filter_factory=runmod.motion_factory(cfg))
    for item in iter_files(files):
        mgr.process(item)
        per_item.append(current[:])
        current.clear()
    mgr.flush()
    last = current[:]
    inputs, events = len(per_item), sum(map(len, per_item)) + len(last)

    class StandIn:
        """Emits the recorded events of each input, as the TrackManager did (``emit=False``: reads the
        tracks' estimates only)."""

        def __init__(self, radars, reference, config=None, on_event=None, *, estimator=None, filter_factory=None,
                     emit=True):
            self.on_event, self.tracks, self.k, self.emit, self._events = on_event, {}, 0, emit, []
            self.event_log = None
            self.coupling = CouplingGraph([r.id for r in radars])

        _estimate_of = staticmethod(TrackManager._estimate_of)
        _emit_one = TrackManager._emit

        def _emit(self, evs) -> None:
            self._events = []
            for ev, tr in evs:
                tr.estimate = tr.filter.estimate()  # the manager's read (ManagedTrack.estimate)
                if ev.kind == "deleted":
                    self.tracks.pop(ev.track, None)
                else:
                    self.tracks[ev.track] = tr
                if self.emit:
                    tr.status = ev.status
                    self._emit_one(ev.time, tr, ev.kind)

        def process(self, item) -> None:
            self._emit(per_item[self.k])
            self.k += 1

        def flush(self) -> None:
            self._emit(last)

        def accounting(self) -> dict:
            return {}

    tables = [0.0, 0.0, 0.0]  # CPU s in the writer's events and tracks, in its biases, in the recorder's _columns

    def timed(f, k=0):
        def g(*a):
            c = time.process_time()
            f(*a)
            tables[k] += time.process_time() - c
        return g

    runmod.TrackManager = StandIn
    writer.OutputStream.events = timed(writer.OutputStream.events)
    writer.OutputStream.biases = timed(writer.OutputStream.biases, 1)
    recorder.Recorder._columns = timed(recorder.Recorder._columns, 2)
    items = list(iter_files(open_scenario(args.folder)))  # read once: reading is not part of what is timed
    gc.freeze()

    def replay(out: Path) -> float:
        """replay_folder's streamed branch on the items read before."""
        c = time.process_time()
        sink = writer.OutputStream(out, SystemPlane(*files.data.reference))
        result = runmod.run(files.data, config, progress=False, inputs=iter(items), sink=sink, total=inputs)
        result.summary()
        sink.close()
        writer.write_outputs(result, out)
        return time.process_time() - c

    def standin(**kw) -> float:
        c = time.process_time()
        m = StandIn(files.data.radars, files.data.reference, **kw)
        with runmod.young_garbage():  # as run() does
            for item in items:
                m.process(item)
            m.flush()
        return time.process_time() - c

    whole, alone, emit, in_tables, in_columns = [], [], [], [], []
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(args.repeat + 1):  # the first: a warm-up
            tables[:] = [0.0, 0.0, 0.0]
            with contextlib.redirect_stdout(io.StringIO()):
                whole.append(replay(writer.prepare(Path(tmp) / "out", overwrite=True)))
            in_tables.append(tables[0] + tables[1])
            in_columns.append(tables[2] - tables[0])  # _columns hands the events to the writer
            alone.append(standin(emit=False))
            emit.append(standin())
    w, a, e, t, k = min(whole[1:]), min(alone[1:]), min(emit[1:]), min(in_tables[1:]), min(in_columns[1:])
    print(json.dumps({"folder": str(args.folder), "inputs": inputs, "events": events,
                      "path_us": round((w - a) / inputs * 1e6, 2), "emit_us": round((e - a) / inputs * 1e6, 2),
                      "tables_us": round(t / inputs * 1e6, 2), "columns_us": round(k / inputs * 1e6, 2),
                      "replay_standin_us": round(w / inputs * 1e6, 2),
                      "standin_us": round(a / inputs * 1e6, 2)}))


class _Filter:
    __slots__ = ("e",)

    def __init__(self, e: tuple) -> None:
        self.e = e

    def estimate(self) -> tuple:
        return self.e[0], self.e[1].copy(), self.e[2].copy()


class _Track:
    """What ``_emit`` and ``on_event`` read of a ManagedTrack."""

    __slots__ = ("id", "status", "estimate", "filter", "altitude_m", "mode_s", "mode_3a")

    def __init__(self, id: int, estimate: tuple, altitude_m, mode_s, mode_3a) -> None:
        self.id, self.status, self.estimate, self.filter = id, None, None, _Filter(estimate)
        self.altitude_m, self.mode_s, self.mode_3a = altitude_m, mode_s, mode_3a

if __name__ == "__main__":
    main()
