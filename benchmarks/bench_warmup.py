"""Benchmark: the warm-up a run does before its clock starts, with numba's disk cache empty and then full.

    python benchmarks/bench_warmup.py [--association manager] [--repeat 2]

``radartracker.pipeline.warmup.warm_up`` runs a tiny built-in scenario through the run's association,
estimator and motion model, so every compiled kernel is compiled (first run after installing) or loaded
from numba's disk cache before the real inputs. Each measurement is a new process with
``NUMBA_CACHE_DIR`` set to a fresh temporary folder: the first (``cold``) compiles every kernel the path
uses and writes the cache, the next ones (``warm``) load it. One JSON line per process: the CPU seconds
``warm_up`` returns and the process's CPU seconds in all (user + system, ``wait4``: imports included).
The project's own cache (beside the sources) is not touched.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile

CHILD = """
import sys
from radartracker.pipeline.config import RunConfig
from radartracker.pipeline.warmup import warm_up
print(warm_up(RunConfig(association=sys.argv[1]), labelled=sys.argv[1] == "labels", notice=False))
"""


def child(association: str, cache: str) -> tuple[float, float]:
    """(CPU s of warm_up, CPU s of the process) with numba's cache in ``cache``."""
    one = {k: "1" for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMBA_NUM_THREADS")}
    proc = subprocess.Popen([sys.executable, "-c", CHILD, association], stdout=subprocess.PIPE, text=True,
                            env=os.environ | one | {"NUMBA_CACHE_DIR": cache})
    out = proc.stdout.read()
    _, status, usage = os.wait4(proc.pid, 0)
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit("warm-up failed")
    return float(out.split()[-1]), usage.ru_utime + usage.ru_stime


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--association", default="manager", choices=("manager", "labels"))
    ap.add_argument("--repeat", type=int, default=2, help="warm processes after the cold one")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="bench_warmup_numba_") as cache:
        for k in range(1 + args.repeat):
            warm, total = child(args.association, cache)
            print(json.dumps({"bench": "warm_up", "association": args.association, "cache": "cold" if k == 0 else "warm",
                              "warm_up_cpu_s": round(warm, 2), "process_cpu_s": round(total, 2),
                              "load1": round(os.getloadavg()[0], 2)}), flush=True)


if __name__ == "__main__":
    main()
