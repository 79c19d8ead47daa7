"""Benchmark: national traffic through the whole unlabelled replay, against one FilterPy cycle.

    python benchmarks/bench_national.py [--aircraft 200 500 1000 2000] [--minutes 3 9 27] [--radars 28]
                                     [--estimator coupled-sparse] [--quality] [--repeat N] [--out FILE]

For each size, a child process simulates ``radartracker simulate --scenario traffic`` (Mode S,
30 % ADS-B, Pd 0.9) into a scenario folder *without truth labels*, then a second child times
``radartracker replay FOLDER --estimator coupled-sparse --out OUT`` (the TrackManager path with the
default motion model: reading, conversion, association, filters, estimator, events, outputs; the
folder holds no truth, so nothing is evaluated), after
timing one FilterPy ``KalmanFilter`` predict+update cycle (4-state CV, 2-D position) in that same
process, so ``ratio`` = µs per input / µs per FilterPy cycle holds on any machine. Peak RSS is the
replay child's maximum resident set (``wait4``); the replay streams the folder (read in blocks, outputs
written as they come: docs/performance.md, "Memory flat in the recording's length"), so it should not
grow with ``--minutes``. ``--repeat N`` replays each folder N times, each in a new process, and prints the
run of median ratio with every run's figures (this machine's single runs vary by ±15 %, the FilterPy cycle
alike). ``--quality`` keeps the labels and adds the track
metrics of the TrackManager replay (breaks, false tracks); ``--labelled`` also times the labelled
replay (association by truth label) without and with its evaluation against truth.

Times are CPU times of the process (``time.process_time``), so that a shared, loaded machine gives
comparable numbers; ``seconds`` and ``realtime_factor_wall`` are wall-clock. One JSON line per size
(with the 1-minute load average, and ``startup_cpu_s``: the CPU time of a ``radartracker --help`` process).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def filterpy_cycle_us(n: int = 20_000, repeat: int = 5) -> float:
    """Median CPU µs of one FilterPy predict + update (CV, 4 states, 2-D position measurement)."""
    import numpy as np
    from filterpy.common import Q_discrete_white_noise
    from filterpy.kalman import KalmanFilter

    kf = KalmanFilter(dim_x=4, dim_z=2)
    dt = 4.0
    kf.F = np.array([[1, 0, dt, 0], [0, 1, 0, dt], [0, 0, 1, 0], [0, 0, 0, 1]], float)
    kf.H = np.array([[1, 0, 0, 0], [0, 1, 0, 0]], float)
    kf.Q = Q_discrete_white_noise(2, dt, 5.0, block_size=2, order_by_dim=False)
    kf.R = np.eye(2) * 100.0**2
    kf.P = np.eye(4) * 1e4
    zs = np.random.default_rng(0).normal(0.0, 100.0, (n, 2)) + np.arange(n)[:, None] * 800.0
    times = []
    for _ in range(repeat):
        t0 = time.process_time()
        for z in zs:
            kf.predict()
            kf.update(z)
        times.append((time.process_time() - t0) / n * 1e6)
    return float(np.median(times))


def startup_cpu_s() -> float:
    """CPU seconds (user + system) of a ``radartracker --help`` process: the imports every command starts with."""
    proc = subprocess.Popen([sys.executable, "-c", "from radartracker.cli import main; main(['--help'])"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    _, _, usage = os.wait4(proc.pid, 0)
    return usage.ru_utime + usage.ru_stime


def child_generate(args: argparse.Namespace) -> None:
    import numpy as np

    from radartracker.io.scenario import write_scenario
    from radartracker.simulation.traffic import traffic_scenario

    data = traffic_scenario(seed=args.seed, duration=args.minutes * 60.0, aircraft=args.aircraft,
                            radars=args.radars).run()
    if not args.quality and not args.labelled:  # the unlabelled replay: no labels, no truth to evaluate
        data.plots.target = np.full(len(data.plots), None, dtype=object)
        data.truth = None
    write_scenario(args.folder, data)
    print(json.dumps({"plots": len(data.plots), "adsb": len(data.adsb)}))


def child_replay(args: argparse.Namespace) -> None:
    import contextlib
    import io

    from radartracker.cli import main

    fp = filterpy_cycle_us()
    argv = ["replay", str(args.folder), "--estimator", args.estimator, "--out", str(args.folder / "out"), "--manager"]
    buf = io.StringIO()
    # warm-up on a tiny scenario: imports and compiled-kernel caches are loaded before the timing
    from radartracker.io.scenario import write_scenario
    from radartracker.simulation.traffic import traffic_scenario

    tiny = args.folder.parent / "tiny"
    write_scenario(tiny, traffic_scenario(seed=2, duration=30.0, aircraft=5, radars=2).run())
    with contextlib.redirect_stdout(buf):
        main(["replay", str(tiny), "--estimator", args.estimator, "--out", str(tiny / "out"), "--manager"])
    t0, c0 = time.perf_counter(), time.process_time()
    with contextlib.redirect_stdout(buf):
        rc = main(argv)
    seconds, cpu = time.perf_counter() - t0, time.process_time() - c0
    summary = json.loads((args.folder / "out" / "summary.json").read_text())
    print(json.dumps({"rc": rc, "seconds": seconds, "cpu_seconds": cpu, "filterpy_us": fp, "motion_model": summary.get("motion_model"),
                      "counts": summary.get("counts"), "tracking": summary.get("tracking")}))


def child_labelled(args: argparse.Namespace) -> None:
    """The labelled replay (association by truth label) timed (CPU) without and with its evaluation."""
    from radartracker.io.sources import read_source
    from radartracker.pipeline.config import RunConfig
    from radartracker.pipeline.run import run

    data = read_source(args.folder)
    t0 = time.process_time()
    result = run(data, RunConfig(association="labels", estimator=args.estimator), progress=False)
    t1 = time.process_time()
    summary = result.summary()
    t2 = time.process_time()
    print(json.dumps({"seconds": t1 - t0, "evaluation_seconds": t2 - t1, "estimator_seconds": result.seconds,
                      "tracking": summary.get("tracking")}))


def run_child(mode: str, args: argparse.Namespace, folder: Path, aircraft: int, minutes: float) -> tuple[dict, float]:
    cmd = [sys.executable, __file__, mode, "--folder", str(folder), "--aircraft", str(aircraft), "--minutes",
           str(minutes), "--radars", str(args.radars), "--estimator", args.estimator, "--seed", str(args.seed)]
    cmd += ["--quality"] if args.quality else []
    cmd += ["--labelled"] if args.labelled else []
    log = folder.parent / f"{mode}.log"  # progress bars and warnings, shown only if the child fails
    with log.open("w") as err:
        one_core = {k: "1" for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")}
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=err, text=True, env=os.environ | one_core)
        out = proc.stdout.read()
        _, status, usage = os.wait4(proc.pid, 0)
    if status != 0:
        sys.stderr.write(log.read_text()[-3000:])
        raise SystemExit(f"{mode} failed for {aircraft} aircraft, {minutes} min")
    return json.loads(out.strip().splitlines()[-1]), usage.ru_maxrss / 1024.0


def emit(line: dict, out: Path | None) -> None:
    """Print one JSON line, and append it to ``out`` when given."""
    print(json.dumps(line), flush=True)
    if out:
        with out.open("a") as f:
            f.write(json.dumps(line) + "\n")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("mode", nargs="?", default="bench", choices=("bench", "generate", "replay", "labelled"))
    ap.add_argument("--aircraft", type=int, nargs="+", default=[200, 500, 1000, 2000])
    ap.add_argument("--minutes", type=float, nargs="+", default=[3.0, 9.0, 27.0])
    ap.add_argument("--radars", type=int, default=28)
    ap.add_argument("--estimator", default="coupled-sparse")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--quality", action="store_true", help="labelled plots, --manager, track metrics")
    ap.add_argument("--labelled", action="store_true",
                    help="also time the labelled replay (association by truth label) and its evaluation")
    ap.add_argument("--repeat", type=int, default=1,
                    help="replay each size this many times, each in a new process; the line is the run of median ratio")
    ap.add_argument("--folder", type=Path, help=argparse.SUPPRESS)
    ap.add_argument("--out", type=Path, help="also append the JSON lines to this file")
    args = ap.parse_args()
    if args.mode != "bench":
        args.aircraft, args.minutes = args.aircraft[0], args.minutes[0]
        {"generate": child_generate, "replay": child_replay, "labelled": child_labelled}[args.mode](args)
        return
    startup = startup_cpu_s()
    for minutes in args.minutes:
        for n in args.aircraft:
            with tempfile.TemporaryDirectory(prefix="bench_national_") as tmp:
                folder = Path(tmp) / "scenario"
                sizes, _ = run_child("generate", args, folder, n, minutes)
                inputs = sizes["plots"] + sizes["adsb"]
                runs = []  # (µs per input / FilterPy µs, result, peak RSS) of each repeat, in its own process
                for _ in range(args.repeat):
                    for made in (folder / "out", folder.parent / "tiny"):  # the replay's outputs, its warm-up folder
                        shutil.rmtree(made, ignore_errors=True)
                    res, rss_mb = run_child("replay", args, folder, n, minutes)
                    runs.append((res["cpu_seconds"] / inputs * 1e6 / res["filterpy_us"], res, rss_mb))
                lab = run_child("labelled", args, folder, n, minutes)[0] if args.labelled else None
            _, res, rss_mb = sorted(runs, key=lambda r: r[0])[len(runs) // 2]  # the run of the median ratio
            us = res["cpu_seconds"] / inputs * 1e6
            line = {"aircraft": n, "radars": args.radars, "minutes": minutes, "estimator": args.estimator,
                    "motion_model": res["motion_model"], "inputs": inputs, "plots": sizes["plots"],
                    "adsb": sizes["adsb"], "seconds": round(res["seconds"], 2), "cpu_seconds": round(res["cpu_seconds"], 2),
                    "us_per_input": round(us, 2),
                    "filterpy_us": round(res["filterpy_us"], 2), "ratio": round(us / res["filterpy_us"], 2),
                    "realtime_factor": round(minutes * 60.0 / res["cpu_seconds"], 1),
                    "realtime_factor_wall": round(minutes * 60.0 / res["seconds"], 1), "peak_rss_mb": round(rss_mb, 1),
                    "startup_cpu_s": round(startup, 2), "load1": os.getloadavg()[0]}
            if args.repeat > 1:  # every repeat's µs per input, FilterPy µs and ratio; the line is the median one's
                line["repeats"] = [[round(r[1]["cpu_seconds"] / inputs * 1e6, 2), round(r[1]["filterpy_us"], 2),
                                    round(r[0], 2)] for r in runs]
            if args.quality and res.get("tracking"):
                line["tracking"] = {k: res["tracking"][k] for k in ("breaks", "false_tracks", "swaps",
                                                                     "confirmed_tracks", "position_rmse_m")}
            if lab is not None:
                line["labelled"] = {"cpu_seconds": round(lab["seconds"], 2),
                                    "evaluation_cpu_seconds": round(lab["evaluation_seconds"], 2),
                                    "with_evaluation_over_without": round(1.0 + lab["evaluation_seconds"] / lab["seconds"], 3)}
            emit(line, args.out)


if __name__ == "__main__":
    main()
