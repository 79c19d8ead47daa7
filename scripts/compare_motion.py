"""Position RMSE of the track motion models on real flights seen by simulated radars.

Each real flight (OpenSky Network ADS-B, ``radartracker.simulation.flights``) is flown through the rotating-radar
simulator with three unbiased radars around it (σ 70 m / 0.08°, periods 4, 8 and 12 s, Pd 0.9), so
the comparison isolates motion modelling. Plots are converted to the plane exactly
(``convert_plots``), associated by their truth label, and fed in time order to each filter. A track
restarts after a gap of more than ``GAP_S`` without plots (as a track manager would re-initiate it);
the first ``SKIP`` updates after each (re)start are left out of the RMSE, the same for every
filter. Errors are filtered positions against the truth interpolated at the plot time
(``TruthPaths``); "turns" are the updates where the truth turns faster than 1°/s.

Prints the Markdown table and one JSON line per filter (RMSE, mean NIS, µs per update), writes the
table into ``docs/tracking.md`` between its markers, and the figures into ``docs/figures/``::

    python scripts/compare_motion.py [--flights ../shared/data/real_flights.csv.gz] [--paris N]
"""

from __future__ import annotations

import argparse
import json
import math
import re
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from radartracker.domain import Aircraft, Radar  # noqa: E402
from radartracker.pipeline.evaluate import TruthPaths  # noqa: E402
from radartracker.simulation.flights import Flight, load_flights  # noqa: E402
from radartracker.geometry.plane import SystemPlane  # noqa: E402
from radartracker.estimation.measurement import convert_plots  # noqa: E402
from radartracker.tracking.filters import MotionConfig  # noqa: E402
from radartracker.registry import load_motion_model  # noqa: E402
from radartracker.simulation.simulator import RecordedTrajectory, SimAircraft, SimRadar, Simulator  # noqa: E402
from radartracker_plugins.motion import AdaptiveConfig, CVConfig, FadingConfig, IMMConfig  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
FULL = ROOT.parent / "shared" / "data" / "real_flights.csv.gz"
DOC = ROOT / "docs" / "tracking.md"
FIG = ROOT / "docs" / "figures"
GAP_S, SKIP, TURN_DEG_S = 60.0, 3, 1.0
# (label, plugin, settings): CV at three densities, IMM with the default (airliner) noises and with
# ten times the densities and 3× the turn-rate noise, the seed-004 filter (β ≥ 0 and β < 0), fading
FILTERS = [
    ("cv q=1", "cv", CVConfig(q=1.0)),
    ("cv q=10", "cv", CVConfig(q=10.0)),
    ("cv q=100", "cv", CVConfig(q=100.0)),
    ("imm", "imm", IMMConfig()),
    ("imm ×10 noise", "imm", IMMConfig(q=10.0, q_turn=10.0, turn_rate_sd=math.radians(1.5))),
    ("adaptive", "adaptive", AdaptiveConfig()),
    ("adaptive β<0 allowed", "adaptive", AdaptiveConfig(allow_negative_beta=True)),
    ("fading", "fading", FadingConfig()),
]
RAW = "plots (no filter)"
RADARS = [("T4", -20.0, -15.0, 4.0), ("E8", 40.0, 10.0, 8.0), ("E12", -10.0, 45.0, 12.0)]


def simulate(fid: str, f: Flight, seed: int):
    """Plots of one flight by three radars around its centroid; (measurements, truth paths, plane)."""
    ref = (float(np.mean(f.lat)), float(np.mean(f.lon)))
    plane = SystemPlane(*ref)
    radars = []
    for rid, x_km, y_km, period in RADARS:
        lat, lon = plane.to_geodetic(x_km * 1e3, y_km * 1e3)
        radars.append(SimRadar(Radar(rid, float(lat), float(lon), 100.0, 70.0, math.radians(0.08), period, 250e3),
                               pd=0.9, phase_rad=seed * 0.7))
    traj = RecordedTrajectory.from_geodetic(plane, f.time, f.lat, f.lon, f.altitude_m)
    sim = Simulator(ref, radars, [SimAircraft(Aircraft(f.icao24, fid, "1000"), traj)],
                    float(f.time[0]), float(f.time[-1]), seed=seed, name=fid)
    data = sim.run()
    alt = np.where(np.isnan(data.plots.altitude_m), np.interp(data.plots.time, f.time, f.altitude_m),
                   data.plots.altitude_m)
    m = convert_plots(data.plots, data.radars, plane, data.plots.target, alt)
    return m, TruthPaths.from_table(data.truth, plane), traj


def turn_rate(traj: RecordedTrajectory, t: np.ndarray) -> np.ndarray:
    """|heading rate| (rad/s) of the truth: change of the 10 s chord heading over 10 s."""
    p = [np.stack(traj.position(t + d)[:2], axis=-1) for d in (-10.0, 0.0, 10.0)]
    h1 = np.arctan2(*(p[1] - p[0]).T)
    h2 = np.arctan2(*(p[2] - p[1]).T)
    return np.abs(np.mod(h2 - h1 + np.pi, 2 * np.pi) - np.pi) / 10.0


def track(name: str, settings: MotionConfig, m, keep_history: bool = False):
    """Run one filter over the measurements; (times, positions, NIS, counted mask, seconds, μ_CT)."""
    idx = np.flatnonzero(m.valid)
    f = None
    last, n_seg = -np.inf, 0
    out_t, out_p, out_nis, counted, mu = [], [], [], [], []
    t0 = time.perf_counter()
    for i in idx:
        t, z, R = float(m.time[i]), m.z[i], m.R[i]
        if t - last > GAP_S:
            f = load_motion_model(name)(settings)
            f.start(t, z, R)
            n_seg, nis = 0, math.nan
        else:
            nis = f.update(t, z, R)
        n_seg += 1
        last = t
        out_t.append(t)
        out_p.append(f.estimate()[1][:2])
        out_nis.append(nis)
        counted.append(n_seg > SKIP)
        if keep_history and hasattr(f, "probabilities"):
            mu.append(f.probabilities[-1])
    seconds = time.perf_counter() - t0
    return (np.array(out_t), np.array(out_p), np.array(out_nis), np.array(counted), seconds,
            np.array(mu))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--flights", default=str(FULL) if FULL.exists() else None,
                    help="real_flights.csv.gz-style file (default: the project's full file, else the shipped subset)")
    ap.add_argument("--paris", type=int, default=40, help="number of paris-* flights (every k-th by id)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--no-doc", action="store_true", help="print only; leave docs/ untouched")
    args = ap.parse_args()
    flights = load_flights(args.flights)
    cal = sorted(k for k in flights if k.startswith("cal_"))
    paris = sorted(k for k in flights if k.startswith("paris-"))
    paris = paris[:: max(1, len(paris) // args.paris)][: args.paris]
    groups = {"calibration": cal, "paris": paris}
    labels = [RAW] + [lab for lab, _, _ in FILTERS]
    sq = {(lab, g, w): [] for lab in labels for g in groups for w in ("all", "turns")}
    nis_all = {lab: [] for lab, _, _ in FILTERS}
    cost = {lab: [0.0, 0] for lab, _, _ in FILTERS}
    example = None
    n_plots = {g: 0 for g in groups}
    for g, ids in groups.items():
        for fid in ids:
            m, paths, traj = simulate(fid, flights[fid], args.seed)
            n_plots[g] += int(m.valid.sum())
            for lab, name, s in FILTERS:
                t, p, nis, counted, sec, mu = track(name, s, m, keep_history=fid == "cal_toulouse-1")
                cost[lab][0] += sec
                cost[lab][1] += len(t)
                truth, inside = paths.state_at(flights[fid].icao24, t)
                use = counted & inside
                e2 = np.sum((p - truth[:, :2]) ** 2, axis=1)
                turning = turn_rate(traj, t) > math.radians(TURN_DEG_S)
                sq[(lab, g, "all")].append(e2[use])
                sq[(lab, g, "turns")].append(e2[use & turning])
                nis_all[lab].append(nis[use])
                if lab == FILTERS[0][0]:  # the plots themselves, over the same updates
                    e2_raw = np.sum((m.z[m.valid] - truth[:, :2]) ** 2, axis=1)
                    sq[(RAW, g, "all")].append(e2_raw[use])
                    sq[(RAW, g, "turns")].append(e2_raw[use & turning])
                if fid == "cal_toulouse-1":
                    example = example or {"truth": traj, "paths": paths, "runs": {}}
                    example["runs"][lab] = (t, p, np.sqrt(e2), mu)
    rmse = {k: float(np.sqrt(np.mean(np.concatenate(v)))) for k, v in sq.items()}
    counts = {k: int(sum(len(a) for a in v)) for k, v in sq.items()}
    for lab in labels:
        for w in ("all", "turns"):
            allv = np.concatenate([np.concatenate(sq[(lab, g, w)]) for g in groups])
            rmse[(lab, "overall", w)] = float(np.sqrt(np.mean(allv)))
            counts[(lab, "overall", w)] = len(allv)
    lines = [
        f"Position RMSE (m) of the filtered position at each plot, {len(cal)} calibration and {len(paris)} "
        f"Paris flights ({n_plots['calibration']} + {n_plots['paris']} plots from 3 unbiased radars, "
        f"σ 70 m / 0.08°, periods 4/8/12 s, Pd 0.9; seed {args.seed}). \"turns\": truth turning > "
        f"{TURN_DEG_S:g}°/s ({counts[(FILTERS[0][0], 'calibration', 'turns')]} and "
        f"{counts[(FILTERS[0][0], 'paris', 'turns')]} updates). Mean NIS: 2 if consistent.",
        "",
        "| filter | calibration | calibration, turns | paris | paris, turns | overall | overall, turns | mean NIS | µs/update |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    cells = [f"{rmse[(RAW, g, w)]:.1f}" for g in ("calibration", "paris", "overall") for w in ("all", "turns")]
    lines.append(f"| {RAW} | " + " | ".join(cells) + " | | |")
    for lab, _, _ in FILTERS:
        cells = [f"{rmse[(lab, g, w)]:.1f}" for g in ("calibration", "paris", "overall") for w in ("all", "turns")]
        mean_nis = float(np.nanmean(np.concatenate(nis_all[lab])))
        us = 1e6 * cost[lab][0] / cost[lab][1]
        lines.append(f"| {lab} | " + " | ".join(cells) + f" | {mean_nis:.2f} | {us:.0f} |")
        print(json.dumps({"filter": lab, **{f"rmse_{g}_{w}": round(rmse[(lab, g, w)], 2)
                                            for g in ("calibration", "paris", "overall") for w in ("all", "turns")},
                          "mean_nis": round(mean_nis, 3), "us_per_update": round(us, 1)}))
    table = "\n".join(lines)
    print(table)
    if args.no_doc:
        return
    FIG.mkdir(parents=True, exist_ok=True)
    figure_bars(rmse, FIG / "tracking_motion_rmse.png")
    if example is not None:
        figure_example(example, FIG / "tracking_motion_example.png")
    text = DOC.read_text()
    new = re.sub(r"(<!-- motion-table:start -->\n).*?(<!-- motion-table:end -->)",
                 lambda mt: mt.group(1) + table + "\n" + mt.group(2), text, flags=re.S)
    DOC.write_text(new)


def figure_bars(rmse: dict, path: Path) -> None:
    labels = [RAW] + [lab for lab, _, _ in FILTERS]
    cols = [("calibration", "all"), ("calibration", "turns"), ("paris", "all"), ("paris", "turns")]
    fig, ax = plt.subplots(figsize=(10, 5.2))
    w = 0.8 / len(labels)
    for k, lab in enumerate(labels):
        ax.bar(np.arange(len(cols)) + (k - len(labels) / 2 + 0.5) * w, [rmse[(lab, g, c)] for g, c in cols], w,
               label=lab)
    ax.set_xticks(range(len(cols)), [f"{g}\n{c}" for g, c in cols])
    ax.set_ylabel("position RMSE (m)")
    ax.set_yscale("log")
    ax.grid(axis="y", alpha=0.3, which="both")
    ax.legend(fontsize=8, ncol=5, loc="upper center", bbox_to_anchor=(0.5, -0.14))
    ax.set_title("Track filters on real flights (The OpenSky Network) seen by 3 simulated radars")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def figure_example(ex: dict, path: Path) -> None:
    """cal_toulouse-1: the hardest 15 minutes (largest CV error), map, error and IMM μ_CT."""
    t, _, e, _ = ex["runs"]["cv q=10"]
    k = np.convolve(e, np.ones(50), "same").argmax()
    lo, hi = t[k] - 450.0, t[k] + 450.0
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.8))
    tt = np.linspace(lo, hi, 900)
    x, y, _ = ex["truth"].position(tt)
    axes[0].plot(x / 1e3, y / 1e3, color="0.5", lw=3, alpha=0.6, label="truth (ADS-B)")
    for lab in ("cv q=10", "imm", "adaptive", "fading"):
        t, p, e, mu = ex["runs"][lab]
        w = (t >= lo) & (t <= hi)
        axes[0].plot(p[w, 0] / 1e3, p[w, 1] / 1e3, lw=1, label=lab)
        rms = np.sqrt(np.convolve(e**2, np.ones(9) / 9, "same"))
        axes[1].plot(t[w] - lo, rms[w], lw=1, label=lab)
        if lab == "imm" and len(mu):
            axes[2].plot(t[w] - lo, mu[w], lw=1, color="C1")
    axes[0].set_aspect("equal")
    axes[0].set_xlabel("x east (km)")
    axes[0].set_ylabel("y north (km)")
    axes[0].legend(fontsize=8)
    axes[1].set_xlabel("time (s)")
    axes[1].set_ylabel("position error, running RMS of 9 updates (m)")
    axes[2].set_xlabel("time (s)")
    axes[2].set_ylabel("IMM probability of the coordinated-turn mode")
    axes[2].set_ylim(0, 1)
    fig.suptitle("cal_toulouse-1 (The OpenSky Network), 15 minutes around the largest CV error")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    main()
