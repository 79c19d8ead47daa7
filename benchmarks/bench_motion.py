"""Cost of the motion-model path of a track: JSON lines, CPU times.

Two measurements, each printed as one JSON line:

* ``filter`` — one track's inputs through a motion-model plugin's public methods (built by
  ``radartracker.registry.make_filter_factory``), on a track that turns and goes straight with plots
  1–12 s apart: ``update`` and ``estimate`` per plot, and ``screen`` (the screening the TrackManager asks
  for: d² against the prediction, and the update when the plot is in the gate) and ``estimate`` per plot,
  for ``--model`` (default ``imm``); beside it, in the same process, one FilterPy ``KalmanFilter``
  predict + update cycle (4-state CV), so the ratio carries over to another machine.
* ``replay`` (with ``--scenario DIR``) — ``radartracker replay DIR --manager --quiet`` in a child
  process: its CPU time (user + system, ``os.wait4``), inputs (rows of plots.csv and adsb.csv) and
  µs per input; ``--profile`` adds a cProfile run (CPU-time clock) with the ``--top`` functions of the
  motion plugins and the track life cycle by cumulative time (file:line:name, calls, seconds).

    python benchmarks/bench_motion.py --scenario /tmp/nat200 [--profile]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def cpu_per_call(fn, n: int) -> float:
    """CPU µs per call of ``fn`` (best of three blocks of ``n`` calls)."""
    best = math.inf
    for _ in range(3):
        t0 = time.process_time()
        for _ in range(n):
            fn()
        best = min(best, time.process_time() - t0)
    return 1e6 * best / n


def track_inputs(n: int = 400, seed: int = 5) -> list[tuple[float, np.ndarray, np.ndarray]]:
    """Plots of a 220 m/s aircraft alternating 3°/s turns and straight legs, 1–12 s apart, σ 80 m."""
    rng = np.random.default_rng(seed)
    t, x, y, heading, out = 0.0, 0.0, 0.0, 0.3, []
    for k in range(n):
        dt = float(rng.uniform(1.0, 12.0))
        rate = math.radians(3.0) if (k // 40) % 2 else 0.0
        heading += rate * dt
        x, y, t = x + 220.0 * dt * math.sin(heading), y + 220.0 * dt * math.cos(heading), t + dt
        out.append((t, np.array([x, y]) + rng.normal(0, 80.0, 2), 80.0**2 * np.eye(2)))
    return out


def bench_filter(model: str) -> dict:
    from filterpy.kalman import KalmanFilter

    from radartracker.estimation.motion import MotionModel
    from radartracker.registry import make_filter_factory

    factory = make_filter_factory(model, {}, None)
    inputs = track_inputs()
    zero2, zero22 = np.zeros(2), np.zeros((2, 2))

    def updated_track() -> None:
        f = factory()
        f.start(inputs[0][0], inputs[0][1], inputs[0][2])
        for t, z, R in inputs[1:]:
            f.update(t, z, R)
            f.estimate()

    def screened_track() -> None:
        f = factory()
        f.start(inputs[0][0], inputs[0][1], inputs[0][2])
        for t, z, R in inputs[1:]:
            f.screen(t, z, zero22, R, zero2, zero22, 600.0)  # an unbiased sensor: C = 0
            f.estimate()

    updated_track()  # load the compiled kernels
    screened_track()
    n = len(inputs) - 1
    per_update = cpu_per_call(updated_track, 20) / n
    per_screen = cpu_per_call(screened_track, 20) / n
    kf = KalmanFilter(dim_x=4, dim_z=2)
    kf.F, kf.Q = MotionModel(5.0).transition(4.0)
    kf.H, kf.R, kf.P = np.eye(2, 4), 80.0**2 * np.eye(2), np.eye(4) * 1e4
    z = np.zeros(2)

    def cycle() -> None:
        kf.predict()
        kf.update(z)

    fp = cpu_per_call(cycle, 2000)
    return {"bench": "filter", "model": model, "us_per_input_update": round(per_update, 2),
            "us_per_input_screen": round(per_screen, 2), "filterpy_cycle_us": round(fp, 2),
            "ratio_update": round(per_update / fp, 3), "ratio_screen": round(per_screen / fp, 3)}


PROFILED = ("radartracker_plugins/motion", "plugins/motion", "radartracker/tracking/lifecycle",
            "radartracker/tracking/track")


def bench_replay(scenario: Path, motion: str | None, profile: bool, top: int = 15) -> dict:
    inputs = sum(max(0, sum(1 for _ in open(scenario / f)) - 1) for f in ("plots.csv", "adsb.csv")
                 if (scenario / f).exists())
    with tempfile.TemporaryDirectory() as tmp:
        argv = ["replay", str(scenario), "--out", str(Path(tmp) / "out"), "--manager", "--quiet"]
        if motion:
            argv += ["--motion-model", motion]
        call = f"main({argv!r})"
        code = (f"from radartracker.cli import main; import sys; sys.exit({call})" if not profile else
                ("import cProfile, time; from radartracker.cli import main; p = cProfile.Profile(time.process_time); "
                 f"p.runcall(main, {argv!r}); p.dump_stats({str(Path(tmp) / 'prof')!r})"))
        proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.DEVNULL)
        _, status, usage = os.wait4(proc.pid, 0)
        if status != 0:
            raise SystemExit(f"replay failed with status {status}")
        cpu = usage.ru_utime + usage.ru_stime
        out = {"bench": "replay", "scenario": str(scenario), "motion": motion or "default", "profiled": profile,
               "inputs": inputs, "cpu_s": round(cpu, 2), "us_per_input": round(1e6 * cpu / inputs, 1),
               "peak_rss_mb": round(usage.ru_maxrss / 1024, 1)}
        if profile:
            import pstats

            stats = pstats.Stats(str(Path(tmp) / "prof")).stats
            rows = [(ct, ncalls, f"{Path(file).stem}:{line}:{name}")
                    for (file, line, name), (_, ncalls, _, ct, _) in stats.items()
                    if name != "<module>" and any(part in file.replace("\\", "/") for part in PROFILED)]
            out["cumulative_s"] = {k: {"calls": n, "s": round(ct, 3)} for ct, n, k in sorted(rows, reverse=True)[:top]}
        return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default="imm", help="motion model of the filter benchmark")
    ap.add_argument("--scenario", type=Path, help="scenario folder (no truth.csv) for the replay benchmark")
    ap.add_argument("--motion-model", help="--motion-model of the replay (default: the manager's)")
    ap.add_argument("--profile", action="store_true", help="also a cProfile run of the replay")
    ap.add_argument("--no-filter", action="store_true", help="skip the filter benchmark")
    ap.add_argument("--top", type=int, default=15, help="functions listed by the profile")
    args = ap.parse_args()
    if not args.no_filter:
        print(json.dumps(bench_filter(args.model)), flush=True)
    if args.scenario:
        print(json.dumps(bench_replay(args.scenario, args.motion_model, False)), flush=True)
        if args.profile:
            print(json.dumps(bench_replay(args.scenario, args.motion_model, True, args.top)), flush=True)


if __name__ == "__main__":
    main()
