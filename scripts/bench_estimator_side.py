from radartracker.registry import make_manager
"""CPU cost of the estimator side of each measurement in the TrackManager, against the compiled kernel alone.

    python scripts/bench_estimator_side.py [FOLDER] [--repeat 3] [--parts] [--evict MB]

FOLDER is a scenario folder replayed as ``radartracker replay FOLDER --manager`` does (default: simulated
traffic, 200 aircraft × 28 radars × 3 minutes). The manager's estimator work is recorded (aircraft added and
removed, and each run of queued measurements that ``TrackManager._flush_estimator`` hands to ``_update_run``),
then replayed on a new ``coupled-sparse`` estimator and coupling graph in two ways, after a warm-up:

* ``manager_path``: what the TrackManager does per run — ``_update_run`` (the run's arrays gathered,
  ``Estimator.update_many``, ``CouplingGraph.observe_many`` and the counts);
* ``kernel``: the compiled loop ``update_batch`` alone on the same arrays, stacked beforehand;
* with ``--parts``, also the manager path's steps timed one by one (on a third estimator and graph):
  ``stack`` (the run's columns and its z, C, R arrays, as ``_update_run`` gathers them), ``update_many``
  (the estimator's call, kernel included) and ``coupling`` (``CouplingGraph.observe_many`` and the counts).
  A third replay in the turns changes what the caches hold for the other two: compare ``us_overhead`` only
  between runs with the same setting.

All include the (rare) add/remove of aircraft, so the difference of the first two is the per-measurement
overhead around the kernel; they run in turns of 64 runs, so a changing load on a shared machine hits them
alike. With ``--evict MB``, MB of memory is read before each run, untimed, as the rest of a frame's work
does between two of the estimator's runs in a replay: the caches' refill is a cost per run (per frame),
which light traffic pays on fewer measurements. One JSON line per repeat: CPU µs per measurement
(``time.process_time``), and whether the replays end in the same estimator state (bit for bit).
"""

from __future__ import annotations

import argparse
import json
import os
import time

import numpy as np


def record(folder: str | None) -> tuple[list, list, "object"]:
    """Radar ids, the manager's estimator work in order, and the manager itself (for its _update_run)."""
    from radartracker.pipeline.config import RunConfig, resolve
    from radartracker.pipeline.run import motion_factory
    from radartracker.pipeline.stream import iter_files, iter_scenario
    from radartracker.tracking.manager import TrackManager

    if folder is None:
        from radartracker.simulation.traffic import traffic_scenario
        data = traffic_scenario(seed=1, duration=180.0, aircraft=200, radars=28).run()
        items = iter_scenario(data)
    else:
        from radartracker.io.scenario import open_scenario
        files = open_scenario(folder)
        data, items = files.data, iter_files(files)
    # as `replay --manager`: simulated traffic carries truth labels, so "auto" would pick labels association
    cfg = resolve(RunConfig(association="manager"), data, "coupled-sparse")
    mgr = make_manager(data.radars, data.reference, cfg.manager_settings(), None, filter_factory=motion_factory(cfg))
    est, calls, update_run = mgr.estimator, [], mgr._update_run

    class Recording:  # forwards everything; logs the calls that add or remove aircraft
        def __getattr__(self, name):
            f = getattr(est, name)
            if name in ("add_aircraft", "remove_aircraft"):
                return lambda *a: (calls.append((name, a)), f(*a))[1]
            return f

    def recorded_run(run: list) -> None:  # with the frame's measurements its rows refer to
        calls.append(("run", (list(run), mgr._meas)))
        update_run(run)

    mgr.estimator, mgr._update_run = Recording(), recorded_run
    for item in items:
        mgr.process(item)
    mgr.flush()
    mgr.estimator = est
    del mgr._update_run
    return [r.id for r in data.radars], calls, mgr


def stacked(calls: list, est, mgr) -> list:
    """The kernel's arguments per recorded run (slots as a replay from a new estimator assigns them)."""
    out = []
    for name, a in calls:
        if name == "add_aircraft":
            est.add_aircraft(*a)
        elif name == "remove_aircraft":
            est.remove_aircraft(*a)
        else:
            run, mgr._meas = a
            _, t, key, radar, rows, _ = zip(*run)
            z, C, R = mgr._measurements(rows)
            n = len(run)
            out.append((np.array([est._ac[k] for k in key], np.int64),
                        np.array([-1 if r is None else est._rad[r] for r in radar], np.int64),
                        np.array(t, float), z, C, R,
                        np.zeros((n, 7))))
            est.update_many(t, key, radar, np.array(z), np.array(C), np.array(R))
    return out


def replay(radars: list, calls: list, mgr, args: list, with_parts: bool, evict: np.ndarray | None = None,
           chunk: int = 64) -> tuple[float, float, dict, int, bool]:
    """CPU seconds of replaying ``calls`` by the compiled loop alone, by the manager's path and (``with_parts``)
    by its parts, each on a new estimator and coupling graph, in turns of ``chunk`` runs (so a changing machine
    load hits them alike), ``evict`` read before each run, untimed; the number of measurements, and whether
    all end in the same estimator state."""
    from collections import Counter

    from radartracker.estimation.coupling import CouplingGraph
    from radartracker.registry import make_estimator
    from radartracker.tracking.manager import _USED
    from radartracker_plugins.coupled_sparse import _kernels as K

    ek, em, ep = (make_estimator("coupled-sparse", mgr.estimator.config, radars) for _ in range(3))
    mgr.estimator, mgr.coupling = em, CouplingGraph(radars)
    ck, cm, cp, update_run = CouplingGraph(radars), mgr.coupling, CouplingGraph(radars), mgr._update_run
    cpu = [0.0, 0.0]
    parts = dict.fromkeys(("stack", "update_many", "coupling"), 0.0)
    counts: Counter = Counter()
    runs = iter(args)

    def change(est, coupling, name: str, a: tuple) -> None:  # an aircraft added or removed, as the manager does
        getattr(est, name)(*a)
        getattr(coupling, name)(a[0])

    def run_parts(part: list) -> None:
        clock = time.process_time
        for name, a in part:
            if name == "run":  # the steps of TrackManager._update_run (none is refused here)
                if evict is not None:
                    evict.sum()
                t0 = clock()
                run, mgr._meas = a
                _, t, key, radar, rows, kind = zip(*run)
                Z, Cs, Rs = mgr._measurements(rows)
                t1 = clock()
                ep.update_many(t, key, radar, Z, Cs, Rs)
                t2 = clock()
                cp.observe_many(key, radar, t)
                counts.update(map(_USED.__getitem__, kind))
                t3 = clock()
                parts["stack"] += t1 - t0
                parts["update_many"] += t2 - t1
                parts["coupling"] += t3 - t2
            else:
                change(ep, cp, name, a)

    def run(part: list, kernel: bool) -> None:
        est, coupling = (ek, ck) if kernel else (em, cm)
        clock = time.process_time
        t0 = clock()
        for name, a in part:
            if name == "run":
                if evict is not None:  # untimed
                    cpu[not kernel] += clock() - t0
                    evict.sum()
                    t0 = clock()
                if kernel:
                    K.update_batch(est._F, est._I, est._work.flat, *next(runs))
                else:
                    run, mgr._meas = a
                    update_run(run)
            else:
                change(est, coupling, name, a)
        cpu[not kernel] += clock() - t0

    for i in range(0, len(calls), chunk):
        run(calls[i:i + chunk], True)
        run(calls[i:i + chunk], False)
        if with_parts:
            run_parts(calls[i:i + chunk])
    n = sum(len(c[1][0]) for c in calls if c[0] == "run")
    same = np.array_equal(ek._F, em._F) and (not with_parts or np.array_equal(ek._F, ep._F))
    return cpu[0], cpu[1], parts if with_parts else {}, n, bool(same)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("folder", nargs="?")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--parts", action="store_true", help="also time the manager path's steps one by one")
    ap.add_argument("--evict", type=float, metavar="MB", help="read MB of memory before each run (untimed)")
    args = ap.parse_args()
    evict = None if args.evict is None else np.ones(int(args.evict * 2**17))
    from radartracker.registry import make_estimator

    radars, calls, mgr = record(args.folder)
    kernel_args = stacked(calls, make_estimator("coupled-sparse", mgr.estimator.config, radars), mgr)
    replay(radars, calls, mgr, kernel_args, args.parts, evict)  # warm-up
    for _ in range(args.repeat):
        tk, tm, parts, n, same = replay(radars, calls, mgr, kernel_args, args.parts, evict)
        print(json.dumps({"bench": "estimator_side", "folder": args.folder, "evict_mb": args.evict, "measurements": n,
                          "aircraft_added": sum(c[0] == "add_aircraft" for c in calls),
                          "runs": sum(c[0] == "run" for c in calls),
                          "us_kernel": round(tk / n * 1e6, 2), "us_manager_path": round(tm / n * 1e6, 2),
                          "us_overhead": round((tm - tk) / n * 1e6, 2),
                          **{f"us_{k}": round(v / n * 1e6, 2) for k, v in parts.items()}, "same_bits": same,
                          "load1": os.getloadavg()[0]}), flush=True)


if __name__ == "__main__":
    main()
