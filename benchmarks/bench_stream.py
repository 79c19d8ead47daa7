"""Benchmark: the streaming replay with and without reading ahead in a second thread (the second-core study).

    python benchmarks/bench_stream.py [--aircraft 200] [--minutes 9] [--repeat 2] [--out FILE]

Simulates national traffic once (``benchmarks/bench_national.py generate``: no labels, no truth), then, each
in its own child process (one thread for the numerical libraries, as in bench_national), alternating:

* ``read``: only reading the inputs (``iter_files``: blocks read, checked, converted to items) — the work
  a second thread could take off the tracking thread, an upper bound on what reading ahead can save;
* ``replay`` with ``prefetch`` off and on: ``radartracker.pipeline.run.replay_folder`` after a warm-up
  replay (imports and kernel caches loaded).

Prints one JSON line per run: wall seconds, CPU seconds of the process (every thread), peak RSS (``wait4``)
and the 1-minute load average (the machine may be shared: compare runs made close together).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))  # the sibling benchmarks

from bench_national import emit  # noqa: E402

HERE = Path(__file__).resolve().parent


def child(args: argparse.Namespace) -> None:
    from radartracker.io.scenario import open_scenario
    from radartracker.pipeline.config import RunConfig
    from radartracker.pipeline.run import replay_folder
    from radartracker.pipeline.stream import iter_files
    from radartracker.pipeline.writer import prepare

    config = RunConfig(association="manager", estimator="coupled-sparse")
    with tempfile.TemporaryDirectory(prefix="bench_stream_child_") as tmp:
        if args.mode == "replay":  # warm-up: imports and compiled-kernel caches
            from radartracker.io.scenario import write_scenario
            from radartracker.simulation.traffic import traffic_scenario

            write_scenario(Path(tmp) / "tiny", traffic_scenario(seed=2, duration=30.0, aircraft=5, radars=2).run())
            replay_folder(Path(tmp) / "tiny", config, prepare(Path(tmp) / "tiny_out"), progress=False)
        t0, c0 = time.perf_counter(), time.process_time()
        if args.mode == "read":
            n = sum(1 for _ in iter_files(open_scenario(args.folder), prefetch=args.prefetch))
        else:
            result = replay_folder(args.folder, config, prepare(Path(tmp) / "out"), progress=False,
                                   prefetch=args.prefetch)
            n = sum(result.counts.values())
        seconds, cpu = time.perf_counter() - t0, time.process_time() - c0
    print(json.dumps({"seconds": seconds, "cpu_seconds": cpu, "items": n}))


def run_child(mode: str, folder: Path, prefetch: bool) -> dict:
    cmd = [sys.executable, __file__, mode, "--folder", str(folder)] + (["--prefetch"] if prefetch else [])
    one = {k: "1" for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")}
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, env=os.environ | one)
    out = proc.stdout.read()
    _, status, usage = os.wait4(proc.pid, 0)
    if status:
        raise SystemExit(f"{mode} (prefetch {prefetch}) failed")
    res = json.loads(out.strip().splitlines()[-1])
    return {"mode": mode, "prefetch": prefetch, "seconds": round(res["seconds"], 2),
            "cpu_seconds": round(res["cpu_seconds"], 2), "items": res["items"],
            "peak_rss_mb": round(usage.ru_maxrss / 1024.0, 1), "load1": os.getloadavg()[0]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("mode", nargs="?", default="bench", choices=("bench", "read", "replay"))
    ap.add_argument("--aircraft", type=int, default=200, help="size of the simulated traffic (without --folder)")
    ap.add_argument("--minutes", type=float, default=9.0, help="its duration (without --folder)")
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--prefetch", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--folder", type=Path, help="an existing scenario folder (else one is simulated)")
    ap.add_argument("--out", type=Path, help="also append the JSON lines to this file")
    args = ap.parse_args()
    if args.mode != "bench":
        child(args)
        return
    with tempfile.TemporaryDirectory(prefix="bench_stream_") as tmp:
        folder = args.folder
        if folder is None:
            folder = Path(tmp) / "scenario"
            subprocess.run([sys.executable, str(HERE / "bench_national.py"), "generate", "--folder", str(folder),
                            "--aircraft", str(args.aircraft), "--minutes", str(args.minutes)], check=True,
                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        for _ in range(args.repeat):
            for mode, prefetch in (("read", False), ("read", True), ("replay", False), ("replay", True)):
                size = ({"folder": str(args.folder)} if args.folder
                        else {"aircraft": args.aircraft, "minutes": args.minutes})
                emit(size | run_child(mode, folder, prefetch), args.out)


if __name__ == "__main__":
    main()
