"""CPU cost of the estimator side of each measurement in the TrackManager, against the compiled kernel alone.

    python scripts/bench_estimator_side.py [FOLDER] [--repeat 3]

FOLDER is a scenario folder replayed as ``radartracker replay FOLDER --manager`` does (default: simulated
traffic, 200 aircraft × 28 radars × 3 minutes). The manager's estimator calls are recorded, then replayed on
a new ``coupled-sparse`` estimator and coupling graph in two ways, after a warm-up:

* ``manager_path``: what the TrackManager does per used measurement — the bias read of ``_apply`` for a
  plot, then ``TrackManager._estimate`` (estimator update, coupling graph, counts);
* ``kernel``: the compiled step ``update_packed`` alone on the same arrays.

Both include the (rare) add/remove of aircraft, so their difference is the per-measurement overhead
around the kernel; they run in turns of 256 calls, so a changing load on a shared machine hits both alike.
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
    """Radar ids, the manager's estimator calls in order, and the manager itself (for its _estimate)."""
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
    est, calls = mgr.estimator, []

    class Recording:  # forwards everything; logs the calls that change the estimator
        def __getattr__(self, name):
            f = getattr(est, name)
            if name == "update":
                return lambda m: (calls.append(("update", (m.time, m.aircraft, m.radar, m.z, m.C, m.R))), f(m))[1]
            if name in ("add_aircraft", "remove_aircraft"):
                return lambda *a: (calls.append((name, a)), f(*a))[1]
            if name == "update_arrays":
                return lambda *a: (calls.append(("update", a)), f(*a))[1]
            return f

    mgr.estimator = Recording()
    for item in items:
        mgr.process(item)
    mgr.flush()
    mgr.estimator = est
    return [r.id for r in data.radars], calls, mgr


def replay(radars: list, calls: list, mgr, chunk: int = 256) -> tuple[float, float, int, bool]:
    """CPU seconds of replaying ``calls`` by the compiled step alone and by the manager's path, each on a new
    estimator and coupling graph, the two in turns of ``chunk`` calls (so a changing machine load hits both
    alike); the number of updates, and whether both end in the same estimator state."""
    from radartracker.estimation.coupling import CouplingGraph
    from radartracker.registry import make_estimator
    from radartracker_plugins.coupled_sparse import _kernels as K

    ek, em = (make_estimator("coupled-sparse", mgr.estimator.config, radars) for _ in range(2))
    mgr.estimator, mgr.coupling = em, CouplingGraph(radars)
    ck, cm, estimate = CouplingGraph(radars), mgr.coupling, mgr._estimate
    cpu = [0.0, 0.0]

    def run(part: list, kernel: bool) -> None:
        est, coupling = (ek, ck) if kernel else (em, cm)
        t0 = time.process_time()
        for name, a in part:
            if name == "update":
                t, key, radar, z, C, R = a
                if kernel:
                    j = -1 if radar is None else est._rad[radar]
                    K.update_packed(est._F, est._I, est._work.flat, est._ac[key], j, t, z, C, R)
                else:  # as TrackManager._apply, then _estimate
                    if radar is not None:
                        est.bias_arrays(radar)
                    estimate(t, key, radar, z, C, R, "plots" if radar is not None else "adsb")
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
    n = sum(c[0] == "update" for c in calls)
    return cpu[0], cpu[1], n, bool(np.array_equal(ek._F, em._F))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("folder", nargs="?")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    radars, calls, mgr = record(args.folder)
    replay(radars, calls, mgr)  # warm-up
    for _ in range(args.repeat):
        tk, tm, n, same = replay(radars, calls, mgr)
        print(json.dumps({"bench": "estimator_side", "folder": args.folder, "measurements": n,
                          "aircraft_added": sum(c[0] == "add_aircraft" for c in calls),
                          "us_kernel": round(tk / n * 1e6, 2), "us_manager_path": round(tm / n * 1e6, 2),
                          "us_overhead": round((tm - tk) / n * 1e6, 2), "same_bits": same,
                          "load1": os.getloadavg()[0]}), flush=True)


if __name__ == "__main__":
    main()
