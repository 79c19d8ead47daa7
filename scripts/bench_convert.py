"""Benchmark ``radartracker convert`` on synthetic recordings of 100 MB and 2 GB (seed 000 §2.6).

Generates each recording under /tmp, converts it in a child process (every aircraft selected, the
worst case for the external sort) and prints one JSON line per size: input size, wall time, MB/s
and the child's peak resident memory (``ru_maxrss`` from ``wait4``). The recordings and outputs are
deleted afterwards. Usage: ``python scripts/bench_convert.py [--sizes-mb 100 2000]``.
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

from radartracker.io.recording import write_synthetic_recording

CHILD = """
import json, sys
from radartracker.io.convert import ConvertOptions, convert
r = convert(sys.argv[1], sys.argv[2], ConvertOptions(AZN_TRACKS_MAX=10**9))
print(json.dumps({"aircraft": len(r["selected_aircraft"]), "buckets": r["buckets"],
                  "lines": sum(f["lines"] for f in r["files"].values()),
                  "written": sum(f.get("written", 0) for f in r["files"].values()),
                  "output_files": sum(f["output_files"] for f in r["files"].values())}))
"""


def bench(size_mb: int, root: Path) -> dict:
    rec, out = root / f"rec_{size_mb}MB", root / f"new_{size_mb}MB"
    t0 = time.perf_counter()
    nbytes = write_synthetic_recording(rec, target_bytes=size_mb * 10**6, seed=size_mb,
                                     aircraft_per_batch=50)
    gen_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-c", CHILD, str(rec), str(out)], stdout=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    info = json.loads(proc.stdout.read())
    proc.stdout.close()
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"convert failed on {rec}")
    return {
        "bench": "convert", "target_mb": size_mb, "input_mb": round(nbytes / 1e6, 1),
        "generate_s": round(gen_s, 1), "convert_s": round(wall, 1),
        "mb_per_s": round(nbytes / 1e6 / wall, 2), "peak_rss_mb": round(usage.ru_maxrss / 1024, 1),
        **info,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--sizes-mb", type=int, nargs="+", default=[100, 2000])
    ap.add_argument("--tmp", type=Path, default=Path("/tmp"))
    args = ap.parse_args()
    for size in args.sizes_mb:
        root = Path(tempfile.mkdtemp(prefix="rt_bench_convert_", dir=args.tmp))
        try:
            print(json.dumps(bench(size, root)), flush=True)
        finally:
            shutil.rmtree(root, ignore_errors=True)  # the 2 GB recording must not stay behind


if __name__ == "__main__":
    main()
