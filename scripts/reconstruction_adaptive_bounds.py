"""Adaptive control bounds, evaluated from two runs of ``reconstruction_baselines.py`` with ``--dump``.

A flight whose controls pin at the default bounds (9.5 / 3 m/s²) would be refitted with the bounds × 1.5
(14.25 / 4.5) and the fit with the lower score kept (the rule issue 31 proposed). Both fits of every flight
come from the two runs, so the choice and the pooled errors it gives are exact, without a second search.
Prints a Markdown table: per seed and set, pooled median / p90 (m) at the default, at the raised bounds and
adaptive; how many flights would be refitted and how many keep the raised fit; the refitted flight-minutes.

Runs read (``DIR``, one per seed S, set prefix ``ad`` = Paris + calibration, ``adcr`` = cruise)::

    python scripts/reconstruction_baselines.py --paris 12 --cal 4 --sim 0 --seed S --max-u 9.5 --max-w 3 \
        --dump DIR/ad_sS_u9.5.npz > DIR/ad_sS_u9.5.out        # and --max-u 14.25 --max-w 4.5 → *_u14.25.*
    python scripts/reconstruction_baselines.py --paris 0 --cal 0 --cruise 10 --sim 0 ... → DIR/adcr_sS_u*.*

Usage: python scripts/reconstruction_adaptive_bounds.py DIR [--seeds 1,2]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

SETS = ("approach", "departure", "cruise", "calibration", "paris")


def load(out: Path, npz: Path) -> dict[str, tuple[dict, tuple[str, float], np.ndarray]]:
    """Per flight: (its ``fit`` of the reconstruction, (set, minutes), its per-plot errors from the dump)."""
    rows = {}
    for line in out.read_text().splitlines():
        if line.startswith("{") and '"fit"' in line:
            d = json.loads(line)
            rows[d["flight"]] = (d["fit"]["rec"], (d["group"], d["minutes"]))
    z = np.load(npz)
    return {k: (fit, grp, z[f"{k}|rec|err"]) for k, (fit, grp) in rows.items()}


def _stats(errors: list[np.ndarray]) -> str:
    e = np.concatenate(errors)
    return f"{np.median(e):.1f} / {np.percentile(e, 90):.1f}"


def table(folder: Path, seeds: list[int]) -> None:
    """The Markdown table of the module docstring."""
    print("| seed | set | 9.5 / 3 med / p90 | 14.25 / 4.5 | adaptive | refitted | kept raised | refit minutes / all |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for seed in seeds:
        base, raised = {}, {}
        for pre in ("ad", "adcr"):
            base.update(load(folder / f"{pre}_s{seed}_u9.5.out", folder / f"{pre}_s{seed}_u9.5.npz"))
            raised.update(load(folder / f"{pre}_s{seed}_u14.25.out", folder / f"{pre}_s{seed}_u14.25.npz"))
        for s in SETS:
            keys = [k for k in base if base[k][1][0] == s]
            if not keys:
                continue
            refit = [k for k in keys if base[k][0]["pinned_s"] > 0]
            kept = [k for k in refit if raised[k][0]["score"] < base[k][0]["score"]]
            adaptive = [raised[k][2] if k in kept else base[k][2] for k in keys]
            minutes = sum(base[k][1][1] for k in refit), sum(base[k][1][1] for k in keys)
            print(f"| {seed} | {s} ({len(keys)}) | {_stats([base[k][2] for k in keys])} | "
                  f"{_stats([raised[k][2] for k in keys])} | {_stats(adaptive)} | {len(refit)} | {len(kept)} | "
                  f"{minutes[0]:.0f} / {minutes[1]:.0f} |")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("folder", type=Path)
    ap.add_argument("--seeds", default="1,2")
    args = ap.parse_args()
    table(args.folder, [int(s) for s in args.seeds.split(",")])


if __name__ == "__main__":
    main()
