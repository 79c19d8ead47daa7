"""CPU cost of the estimator side of each measurement in the TrackManager, against the compiled kernel alone.

    python scripts/bench_estimator_side.py [FOLDER] [--repeat 3]

FOLDER is a scenario folder replayed as ``radartracker replay FOLDER --manager`` does (default: simulated
traffic, 200 aircraft × 28 radars × 3 minutes). The manager's estimator work is recorded (aircraft added and
removed, and each run of queued measurements that ``TrackManager._flush_estimator`` hands to ``_update_run``),
then replayed on a new ``coupled-sparse`` estimator and coupling graph in two ways, after a warm-up:

* ``manager_path``: what the TrackManager does per run — ``_update_run`` (the run's arrays stacked,
  ``Estimator.update_many``, ``CouplingGraph.observe_many`` and the counts);
* ``kernel``: the compiled loop ``update_batch`` alone on the same arrays, stacked beforehand.

Both include the (rare) add/remove of aircraft, so their difference is the per-measurement overhead
around the kernel; they run in turns of 64 runs, so a changing load on a shared machine hits both alike.
One JSON line per repeat: CPU µs per measurement (``time.process_time``), and whether
both replays end in the same estimator state (bit for bit).
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
    mgr = TrackManager(data.radars, data.reference, cfg.manager_settings(), None, filter_factory=motion_factory(cfg))
    est, calls, update_run = mgr.estimator, [], mgr._update_run

    class Recording:  # forwards everything; logs the calls that add or remove aircraft
        def __getattr__(self, name):
            f = getattr(est, name)
            if name in ("add_aircraft", "remove_aircraft"):
                return lambda *a: (calls.append((name, a)), f(*a))[1]
            return f

    def recorded_run(run: list) -> None:
        calls.append(("run", list(run)))
        update_run(run)

    mgr.estimator, mgr._update_run = Recording(), recorded_run
    for item in items:
        mgr.process(item)
    mgr.flush()
    mgr.estimator = est
    del mgr._update_run
    return [r.id for r in data.radars], calls, mgr


def stacked(calls: list, est) -> list:
    """The kernel's arguments per recorded run (slots as a replay from a new estimator assigns them)."""
    out = []
    for name, a in calls:
        if name == "add_aircraft":
            est.add_aircraft(*a)
        elif name == "remove_aircraft":
            est.remove_aircraft(*a)
        else:
            _, t, key, radar, z, C, R, _ = zip(*a)
            n = len(a)
            out.append((np.array([est._ac[k] for k in key], np.int64),
                        np.array([-1 if r is None else est._rad[r] for r in radar], np.int64),
                        np.array(t, float), np.array(z), np.array(C), np.array(R),
                        np.zeros((n, 2)), np.zeros((n, 2, 2)), np.zeros(n)))
            est.update_many(t, key, radar, np.array(z), np.array(C), np.array(R))
    return out


def replay(radars: list, calls: list, mgr, args: list, chunk: int = 64) -> tuple[float, float, int, bool]:
    """CPU seconds of replaying ``calls`` by the compiled loop alone and by the manager's path, each on a new
    estimator and coupling graph, the two in turns of ``chunk`` runs (so a changing machine load hits both
    alike); the number of measurements, and whether both end in the same estimator state."""
    from radartracker.estimation.coupling import CouplingGraph
    from radartracker.registry import make_estimator
    from radartracker_plugins.coupled_sparse import _kernels as K

    ek, em = (make_estimator("coupled-sparse", mgr.estimator.config, radars) for _ in range(2))
    mgr.estimator, mgr.coupling = em, CouplingGraph(radars)
    ck, cm, update_run = CouplingGraph(radars), mgr.coupling, mgr._update_run
    cpu = [0.0, 0.0]
    runs = iter(args)

    def run(part: list, kernel: bool) -> None:
        est, coupling = (ek, ck) if kernel else (em, cm)
        t0 = time.process_time()
        for name, a in part:
            if name == "run":
                if kernel:
                    K.update_batch(est._F, est._I, est._work.flat, *next(runs))
                else:
                    update_run(a)
            elif name == "add_aircraft":
                est.add_aircraft(*a)
                coupling.add_aircraft(a[0])
            else:
                est.remove_aircraft(*a)
                coupling.remove_aircraft(a[0])
        cpu[not kernel] += time.process_time() - t0

    for i in range(0, len(calls), chunk):
        run(calls[i:i + chunk], True)
        run(calls[i:i + chunk], False)
    n = sum(len(c[1]) for c in calls if c[0] == "run")
    return cpu[0], cpu[1], n, bool(np.array_equal(ek._F, em._F))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("folder", nargs="?")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    from radartracker.registry import make_estimator

    radars, calls, mgr = record(args.folder)
    kernel_args = stacked(calls, make_estimator("coupled-sparse", mgr.estimator.config, radars))
    replay(radars, calls, mgr, kernel_args)  # warm-up
    for _ in range(args.repeat):
        tk, tm, n, same = replay(radars, calls, mgr, kernel_args)
        print(json.dumps({"bench": "estimator_side", "folder": args.folder, "measurements": n,
                          "aircraft_added": sum(c[0] == "add_aircraft" for c in calls),
                          "runs": sum(c[0] == "run" for c in calls),
                          "us_kernel": round(tk / n * 1e6, 2), "us_manager_path": round(tm / n * 1e6, 2),
                          "us_overhead": round((tm - tk) / n * 1e6, 2), "same_bits": same,
                          "load1": os.getloadavg()[0]}), flush=True)


if __name__ == "__main__":
    main()
