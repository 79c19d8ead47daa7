"""Figure of docs/performance.md from the JSON lines of benchmarks/bench_national.py.

    python scripts/figure_performance.py RESULTS.jsonl [--out docs/figures/performance.png]

Left: µs per input (and the FilterPy predict+update cycle of the same runs) against the number of
aircraft, one line per duration. Right: µs per input and peak RSS against the duration, one line per
number of aircraft.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("results", type=Path, nargs="+")
    ap.add_argument("--out", type=Path, default=Path("docs/figures/performance.png"))
    args = ap.parse_args()
    rows = [json.loads(line) for path in args.results for line in path.read_text().splitlines() if line.strip()]
    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4.2))
    for minutes in sorted({r["minutes"] for r in rows}):
        sel = sorted((r for r in rows if r["minutes"] == minutes), key=lambda r: r["aircraft"])
        line, = a.plot([r["aircraft"] for r in sel], [r["us_per_input"] for r in sel], "o-", label=f"replay, {minutes:g} min")
        for r in sel:  # the spread of a --repeat set (its runs' µs per input)
            if r.get("repeats"):
                us = [v[0] for v in r["repeats"]]
                a.vlines(r["aircraft"], min(us), max(us), color=line.get_color(), alpha=0.5)
    sel = sorted(rows, key=lambda r: r["aircraft"])
    a.plot([r["aircraft"] for r in sel], [r["filterpy_us"] for r in sel], "k.", label="FilterPy predict+update")
    a.set(xlabel="aircraft airborne", ylabel="µs per input (plot or ADS-B report)", xscale="log",
          ylim=(0, 1.3 * max(max(r["us_per_input"], r["filterpy_us"]) for r in rows)),
          title="Cost per input against traffic (bars: spread of repeated runs)")
    sizes = sorted({r["aircraft"] for r in rows})
    a.set_xticks(sizes, [str(n) for n in sizes])
    a.minorticks_off()
    a.legend(fontsize=8)
    b2 = b.twinx()
    for n in sorted({r["aircraft"] for r in rows}):
        sel = sorted((r for r in rows if r["aircraft"] == n), key=lambda r: r["minutes"])
        if len(sel) < 2:
            continue
        line, = b.plot([r["minutes"] for r in sel], [r["us_per_input"] for r in sel], "o-", label=f"{n} aircraft, µs")
        b2.plot([r["minutes"] for r in sel], [r["peak_rss_mb"] for r in sel], "s--", color=line.get_color(),
                label=f"{n} aircraft, RSS")
    b.set(xlabel="recording length (min)", ylabel="µs per input", title="Cost and memory against length",
          ylim=(0, 1.3 * max(r["us_per_input"] for r in rows)))
    b2.set_ylim(0, 1.3 * max(r["peak_rss_mb"] for r in rows))
    b2.set_ylabel("peak RSS (MB, dashed)")
    b.legend(fontsize=8, loc="upper left")
    fig.tight_layout()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=110)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
