"""Benchmark ``radartracker convert`` on synthetic recordings of 100 MB and 2 GB (seed 000 §2.6).

    python benchmarks/bench_convert.py [--sizes-mb 100 2000] [--tmp /tmp]

For each size, ``radartracker write-recording --synthetic-mb N`` writes a recording under ``--tmp``, then
``radartracker convert REC --out NEW --AZN_TRACKS_MAX 1000000000`` (every aircraft selected: the worst
case for the external sort) runs in a child process. One JSON line per size: the recording's size, the
wall seconds of writing and converting it, MB/s, the convert process's peak resident memory (``wait4``)
and the counts of its ``report.json``. The recording and the outputs are deleted afterwards.
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

CLI = "from radartracker.cli import main; import sys; sys.exit(main(sys.argv[1:]))"


def command(*argv: str) -> tuple[float, float]:
    """(wall seconds, peak RSS MB) of ``radartracker ARGV`` in a child process."""
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-c", CLI, *argv], stdout=subprocess.DEVNULL)
    _, status, usage = os.wait4(proc.pid, 0)
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"radartracker {' '.join(argv)} failed")
    return time.perf_counter() - t0, usage.ru_maxrss / 1024


def bench(size_mb: float, root: Path) -> dict:
    rec, out = root / "recording", root / "new"
    gen_s, _ = command("write-recording", "--synthetic-mb", str(size_mb), "--seed", "1", "--out", str(rec))
    nbytes = sum(p.stat().st_size for p in rec.iterdir())
    wall, rss = command("convert", str(rec), "--out", str(out), "--AZN_TRACKS_MAX", str(10**9))
    report = json.loads((out / "report.json").read_text())
    files = report["files"].values()
    return {"bench": "convert", "target_mb": size_mb, "input_mb": round(nbytes / 1e6, 1),
            "generate_s": round(gen_s, 1), "convert_s": round(wall, 1), "mb_per_s": round(nbytes / 1e6 / wall, 2),
            "peak_rss_mb": round(rss, 1), "aircraft": len(report["selected_aircraft"]),
            "lines": sum(f["lines"] for f in files), "written": sum(f.get("written", 0) for f in files),
            "output_files": sum(f["output_files"] for f in files)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes-mb", type=float, nargs="+", default=[100, 2000])
    ap.add_argument("--tmp", type=Path, default=Path(tempfile.gettempdir()))
    args = ap.parse_args()
    for size in args.sizes_mb:
        root = Path(tempfile.mkdtemp(prefix="rt_bench_convert_", dir=args.tmp))
        try:
            print(json.dumps(bench(size, root)), flush=True)
        finally:
            shutil.rmtree(root, ignore_errors=True)  # a 2 GB recording must not stay behind


if __name__ == "__main__":
    main()
