"""Reconstruction against two smoothers on the same plots, scored against a model-neutral reference.

Baselines: the CV RTS smoother (q by innovation likelihood, :mod:`radartracker_plugins.reconstruction.smoother`)
and an IMM fixed-interval smoother over CV and ±3°/s coordinated turns (q by likelihood,
:mod:`radartracker_plugins.reconstruction.imm`).

Flights:
* real flights (The OpenSky Network, ``shared/data/real_flights.csv.gz``, else the subset shipped in
  radartracker): Paris flights whole, calibration flights as random windows. The reference is
  model-neutral: a cubic Hermite curve through the recorded ADS-B positions with the recorded ground
  speed and track as its velocities (no smoother, no motion model). Plots are simulated from it by
  two radars 40–90 km away (σ 70 m / 0.08°, periods 4–12 s) through radartracker's simulator.
* ``--cruise N``: real en-route flights at FL350–390 over Switzerland (``scripts/data/switzerland_cruise.csv.gz``,
  the ``cruise-real`` set of issue 29; OpenSky reports every 10 s), one ``--window`` each, same radars and reference.
* simulated manoeuvring flights of the seed's model (random legs with turns up to 3.5 m/s²), truth known.

``--biases``: the radars have biases, and every method gets the same estimates of them. The Paris flights
are seen by the ``paris`` scenario's four radars (ORLY, CDG, EVREUX, REIMS, with its biases of 60–150 m and
0.08–0.2°), shared by all of them; each calibration window by three radars of its own with biases drawn in
±[50, 150] m and ±[0.05, 0.15]°. The reconstruction estimates them jointly with every flight's trajectory
(``joint.estimate_jointly``: one criterion over all flights and radars); the CV RTS and IMM smoothers are given
those estimates (the plots corrected, z̃ = z − C ς̂, R̃ = R + C Σ Cᵀ: ``biases.debias``). The Paris flights are
split into approaches and departures by their altitude (down or up by more than 1000 m over the flight).

Errors are horizontal distances from the reference at the plot times; velocity errors are against
the recorded ground speed and track (linearly interpolated between reports) or the simulated truth. Prints one JSON line per flight
and method, one per group (pooled), the cost per flight-hour, and a Markdown table (per flight and
pooled), and how hard each real reference curve accelerates (its |d²p/dt²|: OpenSky positions hold
and jump, so the curve through them is not always flyable). ``--jump-sd 0,1,3`` runs the reconstruction once per prior strength (0 = no prior; the
column of the configuration's default strength is ``rec``).
Usage: nice python scripts/reconstruction_baselines.py [--paris N] [--cal N] [--cruise N] [--sim N] [--window S]
       [--workers W] [--max-u A] [--max-w A] [--jump-sd LIST] [--seed S] [--dump OUT.npz] [--biases]
"""

from __future__ import annotations

import argparse
import csv
import gzip
import json
import math
import sys
import time

import attrs
from pathlib import Path

import numpy as np
from scipy.interpolate import CubicHermiteSpline

from radartracker.geometry.plane import SystemPlane
from radartracker.simulation.scenarios import paris_scenario
from radartracker_plugins.reconstruction import ReconstructionConfig
from radartracker_plugins.reconstruction.biases import BiasEstimate, debias
from radartracker_plugins.reconstruction.engine import Failure, executor, run_many
from radartracker_plugins.reconstruction.imm import imm_smooth
from radartracker_plugins.reconstruction.joint import estimate_jointly
from radartracker_plugins.reconstruction.integrate import sample
from radartracker_plugins.reconstruction.quality import assess
from radartracker_plugins.reconstruction.sim import radars_around, simulate_flight
from radartracker_plugins.reconstruction.smoother import tuned_rts

sys.path.insert(0, str(Path(__file__).resolve().parent))
from reconstruction_simulated import random_flight  # noqa: E402

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data" / "real_flights.csv.gz"
SUBSET = Path(__file__).resolve().parents[1] / "radartracker" / "data" / "flights_subset.csv.gz"
CRUISE = Path(__file__).resolve().parent / "data" / "switzerland_cruise.csv.gz"
KT, FT = 1852.0 / 3600.0, 0.3048
REFERENCE_ACCELERATION: dict[str, dict] = {}  # per real flight: how hard the reference curve accelerates
VELOCITY: dict[str, np.ndarray] = {}  # per flight: the reference ground velocity at the plot times
SERIES: dict[str, np.ndarray] = {}  # '--dump': per-plot series (errors, reference acceleration, switch times)
GROUP: dict[str, str] = {}  # per flight: approach, departure, paris (neither), calibration, cruise, simulated
ESTIMATES: dict[str, BiasEstimate] = {}  # '--biases': the reconstruction's joint bias estimates, per radar


class AdsbReference:
    """Cubic Hermite curve through ADS-B positions with the recorded ground velocity at each.

    x(t), y(t) interpolate the positions exactly and have derivative (gs·sin χ, gs·cos χ) at each
    report (gs ground speed, χ track); the altitude is linear. ``position(t)`` as the simulator needs.
    """

    def __init__(self, plane: SystemPlane, t, lat, lon, alt_m, gs_mps, track_deg) -> None:
        x, y = plane.to_plane(lat, lon)
        chi = np.radians(track_deg)
        self.t, self.h = np.asarray(t, float), np.asarray(alt_m, float)
        self.vx, self.vy = gs_mps * np.sin(chi), gs_mps * np.cos(chi)
        self._x = CubicHermiteSpline(self.t, x, self.vx)
        self._y = CubicHermiteSpline(self.t, y, self.vy)
        self.t_start, self.t_end = float(self.t[0]), float(self.t[-1])

    def position(self, t):
        t = np.asarray(t, float)
        return self._x(t), self._y(t), np.interp(t, self.t, self.h)

    def velocity(self, t) -> np.ndarray:
        """The recorded ground velocity (gs, track) linearly interpolated between reports (n, 2)."""
        return np.column_stack([np.interp(t, self.t, self.vx), np.interp(t, self.t, self.vy)])

    def acceleration(self, t) -> np.ndarray:
        """|d²(x, y)/dt²| of the curve (m/s²): what a model of the flight would have to follow."""
        return np.hypot(self._x(t, 2), self._y(t, 2))


def load_adsb(path: Path) -> dict[str, dict[str, np.ndarray]]:
    """Per flight: time, lat, lon, altitude (m), ground speed (m/s), track (deg); rows without speed or
    track, and repeated times, are dropped (counted on stderr)."""
    rows: dict[str, list] = {}
    dropped = 0
    with gzip.open(path, "rt", newline="") as f:
        for r in csv.DictReader(f):
            try:
                vals = [float(r[k]) for k in ("timestamp", "latitude", "longitude", "altitude", "groundspeed", "track")]
            except ValueError:
                dropped += 1
                continue
            if not all(map(math.isfinite, vals)):
                dropped += 1
                continue
            rows.setdefault(r["flight_id"], []).append(vals)
    out = {}
    for fid, rs in rows.items():
        a = np.array(sorted(rs))
        keep = np.concatenate([[True], np.diff(a[:, 0]) > 0])
        dropped += int((~keep).sum())
        a = a[keep]
        out[fid] = {"t": a[:, 0], "lat": a[:, 1], "lon": a[:, 2], "alt": a[:, 3] * FT, "gs": a[:, 4] * KT, "track": a[:, 5]}
    print(json.dumps({"adsb_rows_dropped": dropped, "source": str(path)}), file=sys.stderr)
    return out


def radars_for(plane, rng):
    ang = rng.uniform(0, 2 * np.pi) + np.array([0.0, rng.uniform(1.5, 4.5)])
    dist = rng.uniform(40, 90, 2)
    return radars_around(plane, np.column_stack([dist * np.sin(ang), dist * np.cos(ang)]), rng.uniform(4, 12, 2))


def biased_radars(fid, plane, rng):
    """``--biases``: (radars, their true [Δr m, Δθ rad]): the ``paris`` scenario's four for a Paris flight, three
    of the flight's own (ids prefixed by it) with random biases for a calibration window."""
    if fid.startswith("paris-"):
        sims = paris_scenario().radars
        return [s.radar for s in sims], [(s.range_bias_m, s.azimuth_bias_rad) for s in sims]
    ang = rng.uniform(0, 2 * np.pi) + np.array([0.0, 2.1, 4.2]) + rng.uniform(-0.4, 0.4, 3)
    dist = rng.uniform(40, 90, 3)
    radars = radars_around(plane, np.column_stack([dist * np.sin(ang), dist * np.cos(ang)]), rng.uniform(4, 12, 3))
    signs = rng.choice([-1.0, 1.0], (3, 2))
    biases = [(sr * rng.uniform(50, 150), sa * math.radians(rng.uniform(0.05, 0.15))) for sr, sa in signs]
    return [attrs.evolve(r, id=f"{fid}/{r.id}") for r in radars], biases


def group_of_flight(fid, alt):
    """calibration, cruise, or a Paris flight's kind by its altitude: approach (down by > 1000 m), departure (up)."""
    if fid.startswith("cal_"):
        return "calibration"
    if fid.startswith("ch-"):
        return "cruise"
    climb = float(alt[-1] - alt[0])
    return "approach" if climb < -1000.0 else "departure" if climb > 1000.0 else "paris"


def real_tracks(flights, ids, window, rng, biased=False):
    tracks, truth = [], {}
    for fid in ids:
        f = flights[fid]
        sel = np.ones(len(f["t"]), bool)
        if fid.startswith(("cal_", "ch-")) and window:
            start = f["t"][0] + rng.uniform(0, max(f["t"][-1] - f["t"][0] - window, 0))
            sel = (f["t"] >= start) & (f["t"] <= start + window)
        if sel.sum() < 20:
            continue
        ref = (float(np.mean(f["lat"][sel])), float(np.mean(f["lon"][sel])))
        plane = SystemPlane(*ref)
        traj = AdsbReference(plane, *(f[k][sel] for k in ("t", "lat", "lon", "alt", "gs", "track")))
        radars, biases = biased_radars(fid, plane, rng) if biased else (radars_for(plane, rng), None)
        pt, true = simulate_flight(traj, radars, seed=int(rng.integers(1 << 30)), reference=ref, biases=biases)
        GROUP[fid] = group_of_flight(fid, f["alt"][sel])
        tracks.append(type(pt)(fid, pt.t, pt.z, pt.h, pt.radar, pt.R, pt.C))
        truth[fid] = true
        VELOCITY[fid] = traj.velocity(pt.t)
        SERIES[f"{fid}|ref_acc"] = traj.acceleration(pt.t)
        SERIES[f"{fid}|since_report"] = pt.t - traj.t[np.maximum(np.searchsorted(traj.t, pt.t, side="right") - 1, 0)]
        acc = traj.acceleration(np.arange(traj.t_start, traj.t_end, 1.0))
        # do the recorded velocity fields agree with the positions? bearing and speed between reports
        x, y = plane.to_plane(f["lat"][sel], f["lon"][sel])
        dt = np.diff(f["t"][sel])
        bearing = np.degrees(np.arctan2(np.diff(x), np.diff(y)))
        off = np.abs((bearing - f["track"][sel][1:] + 180) % 360 - 180)
        ratio = np.hypot(np.diff(x), np.diff(y)) / dt / np.maximum(f["gs"][sel][1:], 1.0)
        REFERENCE_ACCELERATION[fid] = {"p50_mps2": round(float(np.median(acc)), 2),
                                       "p90_mps2": round(float(np.percentile(acc, 90)), 2),
                                       "share_above_9.5": round(float(np.mean(acc > 9.5)), 3),
                                       "report_interval_s": round(float(np.median(dt)), 1),
                                       "track_vs_bearing_deg_median": round(float(np.median(off)), 1),
                                       "position_speed_over_gs_p10_p90": [round(float(np.percentile(ratio, 10)), 2),
                                                                          round(float(np.percentile(ratio, 90)), 2)]}
    return tracks, truth


def sim_tracks(n, rng):
    from radartracker_plugins.reconstruction.sim import REFERENCE

    plane = SystemPlane(*REFERENCE)
    tracks, truth = [], {}
    for i in range(n):
        while True:  # a draw whose speed would fall below 60 m/s (or reach zero) is drawn again
            try:
                traj = random_flight(rng)
                if np.min(traj.state(np.linspace(traj.t_start, traj.t_end, 200))[4]) > 60.0:
                    break
            except ValueError:
                continue
        pt, true = simulate_flight(traj, radars_for(plane, rng), seed=1000 + i)
        key = f"sim{i:02d}"
        _, _, _, phi, v = traj.state(pt.t)
        VELOCITY[key] = np.column_stack([v * np.sin(phi), v * np.cos(phi)])
        tracks.append(type(pt)(key, pt.t, pt.z, pt.h, pt.radar, pt.R, pt.C))
        truth[key] = true
    return tracks, truth


def stats(e):
    return {"median_m": round(float(np.median(e)), 1), "p90_m": round(float(np.percentile(e, 90)), 1)}


def vstats(e):
    return {"median": round(float(np.median(e)), 2), "p90": round(float(np.percentile(e, 90)), 2)}


def group_of(key):
    return GROUP.get(key, "simulated")


def _arguments() -> argparse.Namespace:
    """The command line (see the module docstring)."""
    ap = argparse.ArgumentParser()
    ap.add_argument("--paris", type=int, default=6)
    ap.add_argument("--cal", type=int, default=4)
    ap.add_argument("--cruise", type=int, default=0, help="real en-route flights over Switzerland, one window each")
    ap.add_argument("--sim", type=int, default=6)
    ap.add_argument("--window", type=float, default=1200.0, help="calibration and cruise window (s)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--max-u", type=float, default=ReconstructionConfig().max_u)
    ap.add_argument("--max-w", type=float, default=ReconstructionConfig().max_w)
    ap.add_argument("--jump-sd", default=f"{ReconstructionConfig().jump_sd:g}",
                    help="comma-separated prior strengths (m/s²; 0 = no prior; default: the configuration's)")
    ap.add_argument("--dump", type=Path, default=None,
                    help="write per-plot series (times, plots, reference, estimates and errors per method, radar, "
                         "reference acceleration, switch times) to this .npz for analysis")
    ap.add_argument("--biases", action="store_true",
                    help="radars with biases, estimated jointly by the reconstruction and given to every method")
    ap.add_argument("--reference-only", action="store_true",
                    help="print how hard each real flight's reference accelerates, and stop")
    return ap.parse_args()


def _real_flights(args: argparse.Namespace) -> tuple[dict[str, dict[str, np.ndarray]], list[str]]:
    """(ADS-B per flight, the ids asked for: the first ``--paris`` Paris flights, ``--cal`` calibration flights
    and ``--cruise`` Swiss cruise flights, each set in sorted order)."""
    flights = load_adsb(SHARED if SHARED.exists() else SUBSET)
    paris = sorted(k for k in flights if k.startswith("paris-"))[: args.paris]
    cal = sorted(k for k in flights if k.startswith("cal_"))[: args.cal]
    cruise: list[str] = []
    if args.cruise:
        swiss = load_adsb(CRUISE)
        cruise = sorted(swiss)[: args.cruise]
        flights.update({k: swiss[k] for k in cruise})
    return flights, paris + cal + cruise


def _reconstruct(tracks, truth, args: argparse.Namespace, errs, verrs, extra, hours: float) -> None:
    """Every flight reconstructed once per ``--jump-sd`` (the biases estimated jointly with ``--biases``), its
    position and velocity errors into ``errs``/``verrs`` and its fit quality into ``extra``; prints the cost."""
    for js in (float(v) for v in args.jump_sd.split(",")):
        name = "rec" if js == ReconstructionConfig().jump_sd else f"rec_jump{js:g}"  # "rec": the default
        cfg = ReconstructionConfig(max_u=args.max_u, max_w=args.max_w, jump_sd=js)
        t0 = time.perf_counter()
        with executor("process", args.workers) as ex:
            if args.biases:  # the biases estimated with the trajectories; the smoothers get the same below
                results, joint = estimate_jointly(tracks, cfg, ex, batch_plots=400)
                ESTIMATES.update({r: BiasEstimate([b["range_bias_m"], math.radians(b["azimuth_bias_deg"])],
                                                  np.diag([b["sd_range_m"], math.radians(b["sd_azimuth_deg"])]) ** 2)
                                  for r, b in joint["biases"].items()})
                print(json.dumps({"joint_biases": joint}))
            else:
                results = run_many(tracks, cfg, ex, batch_plots=400, progress=False)
            for r in results:
                if isinstance(r, Failure):
                    print(json.dumps({"flight": r.key, "method": name, "failed": r.reason}))
                    continue
                st = sample(r.control, r.plots.t)
                SERIES[f"{r.key}|{name}|switches"] = np.array([s.t_start for s in r.control][1:])
                SERIES[f"{r.key}|{name}|xy"] = st[:, :2]
                errs[r.key][name] = np.hypot(*(st[:, :2] - truth[r.key]).T)
                if r.key in VELOCITY:
                    verrs[r.key][name] = np.hypot(*(np.column_stack([st[:, 3] * np.sin(st[:, 2]), st[:, 3] * np.cos(st[:, 2])])
                                                    - VELOCITY[r.key]).T)
                q = assess(r, cfg)
                extra[r.key][name] = {"segments": len(r.control), "chi2": q["chi2"], "plausible": q["plausible"],
                                      "pinned_s": sum(p["seconds"] for p in q["pinned"]),
                                      "score": round(r.best.score, 1)}
        wall = time.perf_counter() - t0
        print(json.dumps({"cost": name, "wall_s": round(wall, 1), "workers": args.workers,
                          "flight_hours": round(hours, 2), "wall_s_per_flight_hour": round(wall / hours, 1)}))


def main() -> None:
    args = _arguments()
    rng = np.random.default_rng(args.seed)
    flights, ids = _real_flights(args)
    tracks, truth = real_tracks(flights, ids, args.window, rng, biased=args.biases)
    for fid, acc in REFERENCE_ACCELERATION.items():
        print(json.dumps({"flight": fid, "reference_acceleration": acc}))
    if args.reference_only:
        return
    st, sv = sim_tracks(args.sim, rng)
    tracks += st
    truth.update(sv)
    hours = sum(pt.duration for pt in tracks) / 3600
    errs: dict[str, dict[str, np.ndarray]] = {pt.key: {} for pt in tracks}
    verrs: dict[str, dict[str, np.ndarray]] = {pt.key: {} for pt in tracks}  # ground-velocity errors (m/s)
    extra: dict[str, dict] = {pt.key: {} for pt in tracks}
    _reconstruct(tracks, truth, args, errs, verrs, extra, hours)
    for raw in tracks:
        pt = debias(raw, ESTIMATES) if ESTIMATES else raw  # the same bias estimates as the reconstruction's
        for name, xs in (("cv_rts", tuned_rts(pt.t, pt.z, pt.R)[0]), ("imm", imm_smooth(pt.t, pt.z, pt.R)[0])):
            errs[pt.key][name] = np.hypot(*(xs[:, :2] - truth[pt.key]).T)
            SERIES[f"{pt.key}|{name}|xy"] = xs[:, :2]
            if pt.key in VELOCITY:
                verrs[pt.key][name] = np.hypot(*(xs[:, 2:] - VELOCITY[pt.key]).T)
        errs[pt.key]["plots"] = np.hypot(*(pt.z - truth[pt.key]).T)
    methods = [m for m in errs[tracks[0].key] if m != "plots"] + ["plots"]
    rows = []
    for pt in tracks:
        row = {"group": group_of(pt.key), "flight": pt.key, "n_plots": len(pt), "minutes": round(pt.duration / 60, 1),
               **{m: stats(errs[pt.key][m]) for m in methods if m in errs[pt.key]}, "fit": extra[pt.key],
               "velocity_error_mps": {m: vstats(v) for m, v in verrs[pt.key].items()}}
        rows.append(row)
        print(json.dumps(row))
    pooled = {}
    for g in ("approach", "departure", "paris", "calibration", "cruise", "simulated"):
        keys = [pt.key for pt in tracks if group_of(pt.key) == g]
        if not keys:
            continue
        pooled[g] = {"flights": len(keys), **{m: stats(np.concatenate([errs[k][m] for k in keys if m in errs[k]]))
                                              for m in methods},
                     "velocity_error_mps": {m: vstats(np.concatenate([verrs[k][m] for k in keys if m in verrs[k]]))
                                            for m in methods if any(m in verrs[k] for k in keys)}}
        print(json.dumps({"group": g, "pooled": True, **pooled[g]}))
    _table(rows, pooled, methods)
    if args.dump:
        for pt in tracks:
            SERIES[f"{pt.key}|t"], SERIES[f"{pt.key}|radar"] = pt.t, np.asarray(pt.radar, str)
            SERIES[f"{pt.key}|truth"], SERIES[f"{pt.key}|z"] = truth[pt.key], pt.z
            for m, e in errs[pt.key].items():
                SERIES[f"{pt.key}|{m}|err"] = e
        np.savez_compressed(args.dump, **SERIES)


def _table(rows, pooled, methods) -> None:
    head = "| flight | min | " + " | ".join(f"{m} med / p90" for m in methods) + " |"
    print("\n" + head + "\n|" + " --- |" * (2 + len(methods)))
    for r in rows:
        print(f"| {r['flight']} | {r['minutes']} | " + " | ".join(
            f"{r[m]['median_m']} / {r[m]['p90_m']}" if m in r else "–" for m in methods) + " |")
    for g, s in pooled.items():
        print(f"| **{g} pooled ({s['flights']})** | | " + " | ".join(
            f"**{s[m]['median_m']} / {s[m]['p90_m']}**" for m in methods) + " |")


if __name__ == "__main__":
    main()
