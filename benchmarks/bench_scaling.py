"""Benchmark: time per plot and memory of ``coupled`` vs ``coupled-sparse``; a one-hour regional real-time run.

    python benchmarks/bench_scaling.py [--aircraft 10 20 100 500 2000] [--radars 3 10 28] [--budget 1.0]
                                    [--repeat 3] [--rt-aircraft 2000] [--rt-radars 28] [--rt-duration 3600]
                                    [--components] [--scaling-only] [--out FILE]

1. *Scaling.* The seed's linearised model (as ``radartracker.simulation.linsim``): m radars on a 100 km ring,
   n aircraft inside it, every radar seeing every aircraft once per turn (periods 4–12 s), so each
   aircraft is coupled to all m biases (the worst case for the sparse filter). All aircraft are added
   and, for ``coupled-sparse``, one full turn is fed first so every aircraft has its m bias blocks;
   then plots are timed one ``update`` call at a time (the plugin API) and, for the sparse filter,
   also as ``update_many`` batches of 1,000: ``--repeat`` consecutive windows of ``--budget`` s (or
   their share of the plots), median reported. ``coupled`` runs where its dense covariance fits in
   ``--max-dense-gib``. Memory = what ``tracemalloc`` traces while a new estimator is built, given
   every aircraft and (sparse) the first turn: its arrays, capacity included. With ``--components`` every
   radar's bias has the sensor error model's four components (range and azimuth offsets, range gain,
   time offset: 4m bias entries, each plot given its slant range), the issue-30 cost check.
2. *Real time.* A region of 28 radars on a jittered 7×4 grid (≈200 km apart, range 250 km, periods
   4–12 s, Pd 0.9, constant biases) and traffic of ≈2,000 airborne aircraft (straight flights of
   20–90 min, 200–250 m/s, starting and ending all hour long) for one hour. Plots are generated here in
   the flat plane with the same linearised model (the rotating-radar simulator of
   ``radartracker.simulation.simulator`` would need ≈9 min for this traffic), sorted by time, and replayed through
   ``coupled-sparse`` with a life cycle by label: a track starts at its first plot z with the prior
   N([z, 0, 0], diag(σ_p², σ_p², σ_v², σ_v²)) (σ_p = 10 km, σ_v = 300 m/s: nothing known but the plot) and
   is marginalised after three antenna periods and 30 s without plots (sweeps every second,
   one ``update_many`` per second of traffic). Reported: plots per wall-clock second and hours of
   traffic per wall-clock second. Estimates are not read back per plot here (the cost of an
   ``aircraft()`` read is reported in part 1).
3. *Conversion.* For scale: the bulk plot-to-plane conversion (``radartracker.estimation.measurement``, pyproj) timed on
   a 5-minute, 100-aircraft run of the real simulator over the same region.
4. *Replay loop.* ``radartracker.pipeline.run.run()`` end to end on the ``paris`` scenario (q = 20) with
   ``coupled`` and ``coupled-sparse``: the per-plot loop of the product, recording every estimate.

One JSON line per measurement (with the 1-minute load average: the machine is shared), then the
tables. One process, pinned to one core.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
import tracemalloc

import attrs
import numpy as np

from radartracker.estimation.motion import MotionModel
from radartracker.estimation.base import EstimatorConfig, PlaneMeasurement
from radartracker.estimation.sensor import BiasComponent
from radartracker.registry import make_estimator
from radartracker.pipeline.config import RunConfig

P0 = np.diag([1e4**2, 1e4**2, 300.0**2, 300.0**2])
SIGMA_R, SIGMA_A = 70.0, math.radians(0.08)
# a track started at its first plot: its position from the plot, its velocity unknown (σ_p, σ_v)
PRIOR_COV = np.diag([10_000.0**2] * 2 + [300.0**2] * 2)


def plane_plots(t: np.ndarray, ac: np.ndarray, src: np.ndarray, p: np.ndarray, rxy: np.ndarray, bias: np.ndarray,
                rng: np.random.Generator):
    """z = p + C_s(ς_j + w), R = C_s W C_sᵀ with C_s = [u, Ω(p − p_R)] (seed eq. 1.11) for radar plots."""
    d = p - rxy[src]
    rho = np.linalg.norm(d, axis=1)
    C = np.stack([np.column_stack([d[:, 0] / rho, d[:, 1]]), np.column_stack([d[:, 1] / rho, -d[:, 0]])], 1)
    W = np.diag([SIGMA_R**2, SIGMA_A**2])
    w = rng.normal(size=(len(t), 2)) * [SIGMA_R, SIGMA_A]
    z = p + np.einsum("nij,nj->ni", C, bias[src] + w)
    return z, C, C @ W @ C.transpose(0, 2, 1)


def sweep_times(p_of_t, rxy: np.ndarray, period: float, phase: float, t_scan: np.ndarray) -> np.ndarray:
    """Times the antenna (clockwise from north) points at the aircraft, per scan start (2 fixed-point steps)."""
    t = t_scan.copy()
    for _ in range(3):
        d = p_of_t(t) - rxy
        theta = np.arctan2(d[..., 0], d[..., 1])
        antenna = phase + 2 * np.pi * t / period
        t = t + period * (np.mod(theta - antenna + np.pi, 2 * np.pi) - np.pi) / (2 * np.pi)
    return t


# --- 1. scaling ----------------------------------------------------------------------------------
def ring_plots(n: int, m: int, n_plots: int, seed: int):
    """Every radar sees every aircraft: the first ``n_plots`` plots in time order (t, aircraft, radar, z, C,
    R, the radar ids, the aircraft's start positions, each plot's slant range)."""
    rng = np.random.default_rng(seed)
    ang = rng.uniform(0, 2 * np.pi, m)
    rxy = 100e3 * np.column_stack([np.sin(ang), np.cos(ang)])
    period, phase = rng.uniform(4.0, 12.0, m), rng.uniform(0, 2 * np.pi, m)
    bias = rng.normal(size=(m, 2)) * [100.0, math.radians(0.1)]
    p0, v = rng.uniform(-40e3, 40e3, (n, 2)), rng.uniform(-200, 200, (n, 2))
    dur = 1.2 * n_plots / (n * np.sum(1 / period)) + 12.0
    cols = []
    for j in range(m):
        k = np.arange(int(dur / period[j]) + 1)
        tt = sweep_times(lambda t: p0[:, None, :] + v[:, None, :] * t[..., None], rxy[j], period[j], phase[j],
                         np.broadcast_to(period[j] * k, (n, len(k))))
        cols.append((tt.ravel(), np.repeat(np.arange(n), len(k)), np.full(tt.size, j)))
    t, a, src = (np.concatenate(c) for c in zip(*cols))
    keep = np.argsort(t, kind="stable")
    keep = keep[t[keep] >= 0][:n_plots]
    t, a, src = t[keep], a[keep], src[keep]
    p = p0[a] + v[a] * t[:, None]
    z, C, R = plane_plots(t, a, src, p, rxy, bias, rng)
    ids = np.array([f"R{j:02d}" for j in range(m)], object)
    return t, a, ids[src], z, C, R, list(ids), p0, np.linalg.norm(p - rxy[src], axis=1)


def scaling_config(ids: list[str], components: bool) -> EstimatorConfig:
    """q = 1; with ``components`` every radar also has a range gain (prior σ 10⁻³) and a time offset (0.5 s)."""
    config = EstimatorConfig(motion=MotionModel(1.0))
    if not components:
        return config
    extra = (BiasComponent("range_gain", 1e-3), BiasComponent("time_offset", 0.5))
    return attrs.evolve(config, sensors={r: config.sensor(r).with_components(*extra) for r in ids})


def state_bytes(name: str, n: int, p0: np.ndarray, ids: list, first_turn: tuple | None, components: bool) -> int:
    """Bytes that ``tracemalloc`` traces while a new ``name`` estimator is built with ``n`` aircraft and fed
    ``first_turn`` (the arguments of one ``update_many``, or None)."""
    tracemalloc.start()
    try:
        est = make_estimator(name, scaling_config(ids, components), ids)
        for i in range(n):
            est.add_aircraft(i, 0.0, np.array([*p0[i], 0.0, 0.0]), P0)
        if first_turn is not None:
            est.update_many(*first_turn)
        return tracemalloc.get_traced_memory()[0]
    finally:
        tracemalloc.stop()


def windows(step, i: int, per_window: int, repeat: int, budget: float) -> tuple[int, int, float, list[float]]:
    """Time ``repeat`` windows of at most ``per_window`` plots or ``budget`` s (at least 10 plots) each.

    ``step(i)`` processes plots from index i and returns how many (0: no plots left, which ends the timing).
    Returns the next index, the plots timed, the median µs per plot over the windows, and each window's µs
    per plot.
    """
    rates, total = [], 0
    for _ in range(repeat):
        done, t0 = 0, time.perf_counter()
        while done < per_window and (done < 10 or time.perf_counter() - t0 < budget):
            took = step(i + done)
            if took == 0:  # out of plots: a window of 1,000-plot batches can overrun its share
                break
            done += took
        if done == 0:
            break
        rates.append(1e6 * (time.perf_counter() - t0) / done)
        i, total = i + done, total + done
    return i, total, float(np.median(rates)), rates


def time_scaling(name: str, n: int, m: int, budget: float, repeat: int, seed: int = 0,
                 components: bool = False) -> dict:
    sparse = name == "coupled-sparse"
    turn = int(n * m * 1.05) + 10  # plots in one turn of every radar
    n_plots = (2 * turn + 40_000) if sparse else 200 + int(2e5 / (n + m))
    t, a, radar, z, C, R, ids, p0, rho = ring_plots(n, m, n_plots, seed)
    est = make_estimator(name, scaling_config(ids, components), ids)
    for i in range(n):
        est.add_aircraft(i, 0.0, np.array([*p0[i], 0.0, 0.0]), P0)
    i0 = i_turn = min(turn, len(t) // 2) if sparse else 0
    if sparse:  # one full turn so that every aircraft carries its m bias blocks
        est.update_many(t[:i0], a[:i0], radar[:i0], z[:i0], C[:i0], R[:i0], rho[:i0])
    out = {"bench": "scaling", "estimator": name, "aircraft": n, "radars": m, "components": 4 if components else 2}

    def one(i: int) -> int:
        est.update(PlaneMeasurement(t[i], a[i], radar[i], z[i], C[i], R[i], rho[i]))
        return 1

    def batch(i: int) -> int:
        j = min(i + 1000, len(t))
        est.update_many(t[i:j], a[i:j], radar[i:j], z[i:j], C[i:j], R[i:j], rho[i:j])
        return j - i

    rest = len(t) - i0
    i0, out["plots"], out["us_per_plot"], out["us_per_plot_windows"] = windows(
        one, i0, (rest // 2 if sparse else rest) // repeat, repeat, budget)
    if sparse:
        _, out["plots_batch"], out["us_per_plot_batch"], out["us_per_plot_batch_windows"] = windows(
            batch, i0, (len(t) - i0) // repeat, repeat, budget)
        reps, t0 = 2000, time.perf_counter()
        for r in range(reps):
            est.aircraft(r % n)
        out["us_per_aircraft_read"] = 1e6 * (time.perf_counter() - t0) / reps
    first = (t[:i_turn], a[:i_turn], radar[:i_turn], z[:i_turn], C[:i_turn], R[:i_turn], rho[:i_turn]) if sparse \
        else None
    out["state_mib"] = state_bytes(name, n, p0, ids, first, components) / 2**20
    return out


# --- 2. real time --------------------------------------------------------------------------------
def region(n_radars: int, seed: int):
    rng = np.random.default_rng([seed, 1])
    cols = 7
    rows = math.ceil(n_radars / cols)
    j = np.arange(n_radars)
    rxy = np.column_stack([(j % cols - (cols - 1) / 2) * 200e3, (j // cols - (rows - 1) / 2) * 220e3])
    rxy += rng.uniform(-30e3, 30e3, rxy.shape)
    period = rng.uniform(4.0, 12.0, n_radars)
    phase = rng.uniform(0, 2 * np.pi, n_radars)
    bias = rng.normal(size=(n_radars, 2)) * [100.0, math.radians(0.1)]
    half = np.abs(rxy).max(axis=0) + 150e3
    return rxy, period, phase, bias, half


def traffic(n_airborne: int, duration: float, half: np.ndarray, seed: int):
    """Straight flights of 20–90 min starting uniformly in [−90 min, duration]: ≈n_airborne in the air."""
    rng = np.random.default_rng([seed, 2])
    mean_life = (1200 + 5400) / 2
    n = int(round(n_airborne * (duration + 5400) / mean_life))
    life = rng.uniform(1200, 5400, n)
    start = rng.uniform(-5400, duration, n)
    keep = start + life > 0
    life, start = life[keep], start[keep]
    n = len(life)
    head, speed = rng.uniform(0, 2 * np.pi, n), rng.uniform(200, 250, n)
    v = speed[:, None] * np.column_stack([np.sin(head), np.cos(head)])
    mid = rng.uniform(-1, 1, (n, 2)) * half  # position at mid-flight, anywhere over the region
    return start, start + life, mid - v * (start + life / 2)[:, None], v


def region_plots(n_airborne: int, n_radars: int, duration: float, seed: int = 0, pd: float = 0.9,
                 max_range: float = 250e3):
    rxy, period, phase, bias, half = region(n_radars, seed)
    t0, t1, p0, v = traffic(n_airborne, duration, half, seed)
    rng = np.random.default_rng([seed, 3])
    cols = []
    for j in range(n_radars):
        k = np.arange(int(duration / period[j]) + 2)
        scan = period[j] * k - period[j]
        # aircraft that come within range of radar j while flying
        a_ = np.clip(((rxy[j] - p0) * v).sum(1) / (v * v).sum(1), np.maximum(t0, 0), np.minimum(t1, duration))
        near = np.flatnonzero(np.linalg.norm(p0 + v * a_[:, None] - rxy[j], axis=1) <= max_range)
        for chunk in np.array_split(near, max(1, len(near) // 400)):
            tt = sweep_times(lambda t: p0[chunk, None, :] + v[chunk, None, :] * t[..., None], rxy[j], period[j],
                             phase[j], np.broadcast_to(scan, (len(chunk), len(scan))))
            aa = np.broadcast_to(chunk[:, None], tt.shape)
            ok = (tt >= np.maximum(t0[chunk], 0)[:, None]) & (tt <= np.minimum(t1[chunk], duration)[:, None])
            tt, aa = tt[ok], aa[ok]
            inr = np.linalg.norm(p0[aa] + v[aa] * tt[:, None] - rxy[j], axis=1) <= max_range
            det = inr & (rng.random(len(tt)) < pd)
            cols.append((tt[det], aa[det], np.full(det.sum(), j)))
    t, a, src = (np.concatenate(c) for c in zip(*cols))
    order = np.argsort(t, kind="stable")
    t, a, src = t[order], a[order], src[order]
    z, C, R = plane_plots(t, a, src, p0[a] + v[a] * t[:, None], rxy, bias, rng)
    ids = np.array([f"R{j:02d}" for j in range(n_radars)], object)
    airborne = np.mean([np.sum((t0 <= s) & (t1 >= s)) for s in np.linspace(0, duration, 13)])
    return t, a, ids[src], z, C, R, list(ids), period, float(airborne)


def time_realtime(n_airborne: int, n_radars: int, duration: float, seed: int = 0) -> dict:
    g0 = time.perf_counter()
    t, a, radar, z, C, R, ids, period, airborne = region_plots(n_airborne, n_radars, duration, seed)
    gen_s = time.perf_counter() - g0
    drop_after_s = 3 * period.max() + 30
    est = make_estimator("coupled-sparse", EstimatorConfig(motion=MotionModel(1.0)), ids)
    last_seen: dict = {}
    started = created = removed = 0
    t_start = time.perf_counter()
    i, N = 0, len(t)
    while i < N:
        now = t[i]
        for k in [k for k, ts in last_seen.items() if now - ts > drop_after_s]:
            est.remove_aircraft(k)
            del last_seen[k]
            removed += 1
        end = int(np.searchsorted(t, now + 1.0, "left"))
        keys = a[i:end]
        uniq, first = np.unique(keys, return_index=True)
        for k, f in zip(uniq.tolist(), first.tolist()):
            if k not in last_seen:
                est.add_aircraft(k, t[i + f], np.array([*z[i + f], 0.0, 0.0]), PRIOR_COV)
                created += 1
        est.update_many(t[i:end], keys, radar[i:end], z[i:end], C[i:end], R[i:end])
        _, last = np.unique(keys[::-1], return_index=True)
        for k, li in zip(uniq.tolist(), (len(keys) - 1 - last).tolist()):
            last_seen[k] = t[i + li]
        i = end
        started += 1
    sec = time.perf_counter() - t_start
    return {"bench": "realtime", "estimator": "coupled-sparse", "radars": n_radars, "aircraft_airborne": airborne,
            "tracks_created": created, "tracks_removed": removed, "duration_s": duration, "plots": N,
            "plots_per_traffic_s": N / duration, "plots_per_aircraft_s": N / duration / airborne,
            "wall_s": sec, "plots_per_wall_s": N / sec,
            "traffic_hours_per_wall_s": duration / 3600 / sec, "real_time_factor": duration / sec,
            "plot_generation_s": gen_s}


# --- 3. conversion -------------------------------------------------------------------------------
def time_conversion(n_radars: int, seed: int = 0) -> dict:
    from radartracker.domain import Aircraft, Radar
    from radartracker.geometry.plane import SystemPlane
    from radartracker.estimation.measurement import convert_plots, fill_altitudes, plot_keys
    from radartracker.simulation.simulator import KinematicTrajectory, Leg, SimAircraft, SimRadar, Simulator

    ref = (47.0, 2.5)
    plane = SystemPlane(*ref)
    rxy, period, phase, bias, half = region(n_radars, seed)
    radars = []
    for j in range(n_radars):
        lat, lon = plane.to_geodetic(*rxy[j])
        radars.append(SimRadar(Radar(f"R{j:02d}", float(lat), float(lon), 100.0, SIGMA_R, SIGMA_A, float(period[j]),
                                     250e3), float(bias[j, 0]), float(bias[j, 1]), pd=0.9, phase_rad=float(phase[j])))
    rng = np.random.default_rng([seed, 4])
    aircraft = [SimAircraft(Aircraft(f"{0x400000 + i:06x}", f"B{i:03d}", "1234", adsb=False, nacp=8),
                            KinematicTrajectory(0.0, *(rng.uniform(-1, 1, 2) * half), 10_000.0,
                                                rng.uniform(0, 2 * np.pi), 230.0, [Leg(300.0)]))
                for i in range(100)]
    data = Simulator(ref, radars, aircraft, 0.0, 300.0, seed=seed).run()
    t0 = time.perf_counter()
    keys = plot_keys(data.plots, True)
    meas = convert_plots(data.plots, data.radars, plane, keys, fill_altitudes(data.plots, keys, 0.0)[0])
    sec = time.perf_counter() - t0
    return {"bench": "convert", "radars": n_radars, "plots": len(meas), "us_per_plot": 1e6 * sec / len(meas)}


# --- 4. the replay loop ----------------------------------------------------------------------------
def time_replay(name: str, scenario: str = "paris", q: float = 20.0) -> dict:
    """radartracker.pipeline.run.run() end to end (per-plot loop, coupling graph, estimates recorded)."""
    from radartracker.pipeline.run import run
    from radartracker.simulation.scenarios import build_scenario

    data = build_scenario(scenario, seed=1).run()
    res = run(data, RunConfig(estimator=name, q=q), progress=False)
    n = res.counts.get("plots_used", 0) + res.counts.get("adsb_used", 0)
    return {"bench": "replay", "estimator": name, "scenario": scenario, "measurements": n,
            "aircraft": len(data.aircraft), "radars": len(data.radars), "seconds": res.seconds,
            "us_per_measurement": 1e6 * res.seconds / n}


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--aircraft", type=int, nargs="+", default=[10, 20, 100, 500, 2000])
    ap.add_argument("--radars", type=int, nargs="+", default=[3, 10, 28])
    ap.add_argument("--budget", type=float, default=1.0, help="seconds per timing window")
    ap.add_argument("--repeat", type=int, default=3, help="timing windows per measurement (median reported)")
    ap.add_argument("--max-dense-gib", type=float, default=0.6)
    ap.add_argument("--rt-aircraft", type=int, default=2000)
    ap.add_argument("--rt-radars", type=int, default=28)
    ap.add_argument("--rt-duration", type=float, default=3600.0)
    ap.add_argument("--scaling-only", action="store_true", help="part 1 only (no real-time, conversion, replay)")
    ap.add_argument("--components", action="store_true",
                    help="scaling with every radar's four bias components (range gain and time offset too)")
    ap.add_argument("--out", help="also append the JSON lines to this file")
    args = ap.parse_args(argv)
    rows = []

    if hasattr(os, "sched_setaffinity"):  # one core, as the target says
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})

    def emit(row: dict) -> None:
        row["load_avg_1min"] = os.getloadavg()[0]
        row["cpus"] = sorted(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else None
        rows.append(row)
        line = json.dumps(row)
        print(line, flush=True)
        if args.out:
            with open(args.out, "a") as f:
                f.write(line + "\n")

    for m in args.radars:
        for n in args.aircraft:
            emit(time_scaling("coupled-sparse", n, m, args.budget, args.repeat, components=args.components))
            if 8 * (4 * n + (4 if args.components else 2) * m) ** 2 / 2**30 <= args.max_dense_gib:
                emit(time_scaling("coupled", n, m, args.budget, args.repeat, components=args.components))
    if args.scaling_only:
        print_tables(rows)
        return
    if args.rt_duration > 0:
        emit(time_realtime(args.rt_aircraft, args.rt_radars, args.rt_duration))
        emit(time_conversion(args.rt_radars))
    for name in ("coupled", "coupled-sparse"):
        emit(time_replay(name))
    print_tables(rows)


def print_tables(rows: list[dict]) -> None:
    sc = [r for r in rows if r["bench"] == "scaling"]
    comps = sorted({r.get("components", 2) for r in sc})
    print("\nTime per plot (µs, median of the timing windows) and estimator storage (MiB); every radar sees "
          f"every aircraft; bias components per radar: {', '.join(map(str, comps))}")
    print(f"{'m':>3} {'n':>5} | {'coupled':>10} {'MiB':>8} | {'sparse update':>13} {'batch':>7} {'MiB':>6} "
          f"{'read':>6} | {'batch / batch(n=20)':>19}")
    for m in sorted({r['radars'] for r in sc}):
        ref = next((r["us_per_plot_batch"] for r in sc if r["radars"] == m and r["aircraft"] == 20
                    and r["estimator"] == "coupled-sparse"), math.nan)
        for n in sorted({r['aircraft'] for r in sc if r["radars"] == m}):
            d = next((r for r in sc if r["radars"] == m and r["aircraft"] == n and r["estimator"] == "coupled"), None)
            s = next(r for r in sc if r["radars"] == m and r["aircraft"] == n and r["estimator"] == "coupled-sparse")
            dense = f"{d['us_per_plot']:10.1f} {d['state_mib']:8.1f}" if d else f"{'—':>10} {'—':>8}"
            print(f"{m:>3} {n:>5} | {dense} | {s['us_per_plot']:13.1f} {s['us_per_plot_batch']:7.2f} "
                  f"{s['state_mib']:6.2f} {s['us_per_aircraft_read']:6.1f} | {s['us_per_plot_batch'] / ref:19.2f}")
    for r in rows:
        if r["bench"] == "realtime":
            print(f"\nReal time: {r['radars']} radars, {r['aircraft_airborne']:.0f} aircraft airborne on average "
                  f"({r['tracks_created']} tracks), {r['duration_s'] / 3600:.2f} h of traffic, {r['plots']} plots "
                  f"({r['plots_per_traffic_s']:.0f}/s of traffic, {r['plots_per_aircraft_s']:.2f}/s per aircraft)\n"
                  f"  coupled-sparse: {r['wall_s']:.1f} s wall, "
                  f"{r['plots_per_wall_s']:.0f} plots/s, {r['traffic_hours_per_wall_s']:.3f} h of traffic per "
                  f"wall-clock second = {r['real_time_factor']:.0f}× real time")
        if r["bench"] == "replay":
            print(f"  run() of '{r['scenario']}' ({r['aircraft']} aircraft, {r['radars']} radars, "
                  f"{r['measurements']} measurements) with {r['estimator']}: {r['us_per_measurement']:.1f} µs each")
        if r["bench"] == "convert":
            print(f"  bulk plot conversion (radartracker.estimation.measurement, pyproj): {r['us_per_plot']:.2f} µs/plot "
                  f"({r['plots']} simulated plots)")


if __name__ == "__main__":
    sys.exit(main())
