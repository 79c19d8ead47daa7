"""Where the large position errors of the reconstruction and the smoothers occur along real flights.

Reads the ``--dump`` of ``scripts/reconstruction_baselines.py`` (same ``--seed``, ``--paris``, ``--cal``
and ``--window``, so the reference curves are rebuilt identically) and prints per real flight and
method: median / p90 against the reference (as in the baselines table) and against the same
reference low-passed over ``--smooth`` seconds (a centred running mean of the ADS-B Hermite curve:
what is left when the 1-s hold-and-jump of the OpenSky positions is removed); the share of the
method's 10 % largest errors that lie within ``--near`` s of a switch of the reconstruction's
segments, in turns (the smoothed reference turning faster than 0.5°/s), in the first or last ``--edge``
s of the flight, and where only one radar saw the aircraft within ±30 s, with those shares over all
plots; the p90 in the interior and at the edges; and the median reference acceleration at the large
errors against all plots.
Usage: python scripts/reconstruction_error_sources.py DUMP.npz [--flights paris-1,paris-10] [--smooth 10]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from radartracker.geometry.plane import SystemPlane

sys.path.insert(0, str(Path(__file__).resolve().parent))
from reconstruction_baselines import SHARED, SUBSET, AdsbReference, load_adsb  # noqa: E402


def smoothed_reference(f: dict, t: np.ndarray, width: float) -> np.ndarray:
    """The Hermite reference curve averaged over [t − width/2, t + width/2] (0.25-s samples) at times t."""
    plane = SystemPlane(float(np.mean(f["lat"])), float(np.mean(f["lon"])))
    ref = AdsbReference(plane, *(f[k] for k in ("t", "lat", "lon", "alt", "gs", "track")))
    off = np.arange(-width / 2, width / 2 + 1e-9, 0.25)
    ts = np.clip(t[:, None] + off[None, :], ref.t_start, ref.t_end)
    x, y, _ = ref.position(ts.ravel())
    return np.column_stack([x.reshape(ts.shape).mean(1), y.reshape(ts.shape).mean(1)])


def turn_rate(t: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """|dχ/dt| (deg/s) of a track given at times t (central differences of the course)."""
    v = np.gradient(xy, t, axis=0)
    chi = np.unwrap(np.arctan2(v[:, 0], v[:, 1]))
    return np.abs(np.degrees(np.gradient(chi, t)))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("dump", type=Path)
    ap.add_argument("--flights", default="paris-1,paris-10,paris-100,paris-102")
    ap.add_argument("--methods", default="rec,cv_rts,imm")
    ap.add_argument("--smooth", type=float, default=10.0, help="running-mean width for the smoothed reference (s)")
    ap.add_argument("--near", type=float, default=20.0, help="'near a switch' means within this many seconds")
    ap.add_argument("--edge", type=float, default=120.0, help="'at the edges': the first and last this many seconds")
    args = ap.parse_args()
    d = np.load(args.dump)
    flights = load_adsb(SHARED if SHARED.exists() else SUBSET)
    for key in args.flights.split(","):
        t, truth = d[f"{key}|t"], d[f"{key}|truth"]
        smooth = smoothed_reference(flights[key], t, args.smooth)
        turning = turn_rate(t, smooth) > 0.5
        switches = d[f"{key}|rec|switches"]
        near = (np.min(np.abs(t[:, None] - switches[None, :]), axis=1) <= args.near) if len(switches) else np.zeros(len(t), bool)
        acc = d[f"{key}|ref_acc"]
        edge = (t - t[0] < args.edge) | (t[-1] - t < args.edge)
        radar = d[f"{key}|radar"]
        one_radar = np.array([len(set(radar[np.abs(t - ti) <= 30.0])) == 1 for ti in t])
        row = {"flight": key, "plots": len(t), "switches": len(switches),
               "jitter_m": {"median": round(float(np.median(np.hypot(*(truth - smooth).T))), 1),
                            "p90": round(float(np.percentile(np.hypot(*(truth - smooth).T), 90)), 1)},
               "all_plots": {"near_switch": round(float(near.mean()), 2), "turning": round(float(turning.mean()), 2),
                             "at_edges": round(float(edge.mean()), 2), "one_radar": round(float(one_radar.mean()), 2),
                             "ref_acc_median": round(float(np.median(acc)), 1)}}
        for m in args.methods.split(","):
            xy = d[f"{key}|{m}|xy"]
            e = np.hypot(*(xy - truth).T)
            es = np.hypot(*(xy - smooth).T)
            big = e >= np.percentile(e, 90)
            row[m] = {"vs_reference": [round(float(np.median(e)), 1), round(float(np.percentile(e, 90)), 1)],
                      "vs_smoothed": [round(float(np.median(es)), 1), round(float(np.percentile(es, 90)), 1)],
                      "p90_straight_turning": [round(float(np.percentile(e[~turning], 90)), 1),
                                               round(float(np.percentile(e[turning], 90)), 1) if turning.any() else None],
                      "p90_interior_edges": [round(float(np.percentile(e[~edge], 90)), 1),
                                             round(float(np.percentile(e[edge], 90)), 1)],
                      "largest_10pct": {"near_switch": round(float(near[big].mean()), 2),
                                        "turning": round(float(turning[big].mean()), 2),
                                        "at_edges": round(float(edge[big].mean()), 2),
                                        "one_radar": round(float(one_radar[big].mean()), 2),
                                        "ref_acc_median": round(float(np.median(acc[big])), 1)}}
        print(json.dumps(row))


if __name__ == "__main__":
    main()
