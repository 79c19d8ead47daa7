from radartracker.registry import make_manager
"""Benchmark pieces of the TrackManager's hot path, one JSON line each (docs/performance.md, "Manager and
estimator hot path").

    python scripts/bench_hot_path.py [--aircraft 200] [--radars 28] [--minutes 3]

* ``startup``: CPU seconds (user + system) of a ``radartracker --help`` process, and of a process that
  only imports ``asterix.generated`` (what every command paid while the replay imported libasterix).
* ``estimator_update``: the ``coupled-sparse`` estimator calls of a TrackManager run on simulated
  traffic (add/remove aircraft, one update per used measurement, a bias read per plot), recorded and
  replayed twice: with ``update()`` (the kernel step called directly) and with the one-row
  ``update_many`` batch that ``update()`` used to build; CPU µs per update call, and whether the two
  give the same bits.
* ``manager``: CPU µs per input of the TrackManager alone (no reading or writing) on the same traffic,
  with the default motion model, after a warm-up run.

CPU times (``time.process_time``), so a shared machine gives comparable numbers.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

import numpy as np


def child_cpu(code: str) -> float:
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    _, _, usage = os.wait4(proc.pid, 0)
    return usage.ru_utime + usage.ru_stime


def record_estimator_calls(data, record: bool = True) -> tuple[list, list, float]:
    """Run the TrackManager on ``data``; its estimator calls in order (if ``record``), and its CPU µs per input."""
    from radartracker.estimation.base import PlaneMeasurement
    from radartracker.pipeline.stream import iter_scenario
    from radartracker.tracking.manager import ManagerConfig, TrackManager

    mgr = make_manager(data.radars, data.reference, ManagerConfig())
    est, calls = mgr.estimator, []

    class Recording:
        def __getattr__(self, name):
            f = getattr(est, name)
            if name == "update_arrays":  # the manager's per-measurement call, recorded as the update it is
                return lambda *a: (calls.append(("update", (PlaneMeasurement(*a),))), f(*a))[1]
            if name not in ("add_aircraft", "update", "remove_aircraft", "bias"):
                return f

            def call(*a):
                calls.append((name, a))
                return f(*a)
            return call

    if record:
        mgr.estimator = Recording()
    items = list(iter_scenario(data))
    t0 = time.process_time()
    for item in items:
        mgr.process(item)
    mgr.flush()
    return [r.id for r in data.radars], calls, (time.process_time() - t0) / len(items) * 1e6


def replay_calls(radars: list, calls: list, one_row_batch: bool) -> tuple[float, np.ndarray]:
    """CPU µs per update of replaying ``calls`` on a new estimator, and every result's numbers."""
    from radartracker.registry import make_estimator
    from radartracker.tracking.manager import ManagerConfig

    cfg = ManagerConfig()
    est = make_estimator(cfg.estimator, cfg.estimator_config, radars)
    out, cpu, n = [], 0.0, 0
    for name, a in calls:
        if name == "update":
            m = a[0]
            t0 = time.process_time()
            if one_row_batch:  # what update() did before: a batch of one row through update_many
                nu, lam, nis = est.update_many([m.time], [m.aircraft], [m.radar], np.asarray(m.z, float)[None],
                                               np.asarray(m.C, float)[None], np.asarray(m.R, float)[None])
                res = (nu[0], lam[0], float(nis[0]))
            else:
                res = est.update(m)
            cpu += time.process_time() - t0
            n += 1
            out.append(np.r_[res[0], np.ravel(res[1]), res[2]])
        else:
            res = getattr(est, name)(*a)
            if name == "bias":
                out.append(np.r_[res.time, res.bias, res.cov.ravel()])
    return cpu / n * 1e6, np.concatenate(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--aircraft", type=int, default=200)
    ap.add_argument("--radars", type=int, default=28)
    ap.add_argument("--minutes", type=float, default=3.0)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    print(json.dumps({"bench": "startup",
                      "radartracker_help_cpu_s": round(child_cpu("from radartracker.cli import main; main(['--help'])"), 2),
                      "import_asterix_generated_cpu_s": round(child_cpu("import asterix.generated"), 2),
                      "load1": os.getloadavg()[0]}), flush=True)

    from radartracker.simulation.traffic import traffic_scenario

    data = traffic_scenario(seed=args.seed, duration=args.minutes * 60.0, aircraft=args.aircraft,
                            radars=args.radars).run()
    record_estimator_calls(traffic_scenario(seed=2, duration=30.0, aircraft=5, radars=2).run())  # warm-up
    radars, calls, _ = record_estimator_calls(data)
    us_input = record_estimator_calls(data, record=False)[2]
    inputs = len(data.plots) + len(data.adsb)
    print(json.dumps({"bench": "manager", "aircraft": args.aircraft, "radars": args.radars, "minutes": args.minutes,
                      "inputs": inputs, "us_per_input": round(us_input, 1), "load1": os.getloadavg()[0]}), flush=True)
    replay_calls(radars, calls[:2000], False)  # warm-up (compiled kernels' caches)
    single, a = replay_calls(radars, calls, False)
    batch, b = replay_calls(radars, calls, True)
    print(json.dumps({"bench": "estimator_update", "updates": sum(c[0] == "update" for c in calls),
                      "us_per_update": round(single, 1), "us_per_update_one_row_batch": round(batch, 1),
                      "same_bits": bool(np.array_equal(a, b, equal_nan=True)), "load1": os.getloadavg()[0]}), flush=True)


if __name__ == "__main__":
    main()
