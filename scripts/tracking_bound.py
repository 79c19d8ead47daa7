"""What limits the en-route p95 position error (issue 17): a clairvoyant Kalman filter on the plot
noise and revisit times of the en-route geometry, computed independently of the TrackManager.

For every aircraft of the en-route set (``scripts/tracking_scenarios.py``), at the times its plots
were made (the radars' real revisit pattern, Pd 0.9), a measurement is drawn around the *true*
position with the plot's own covariance in the plane, from flat geometry only (no project code):
line of sight u from the radar site to the aircraft, ground range g, slant range ρ,

    R = (σ_ρ ρ/g)² u uᵀ + (g σ_θ)² u⊥ u⊥ᵀ

— no bias, no association, no false plot, no conversion error. FilterPy's ``KalmanFilter`` with the
constant-velocity model of white-acceleration density q (``Q_continuous_white_noise``) filters them;
its state is read on the report's 2 s grid (extrapolated from the last update, as
``TrackHistory.at``) from 20 s after the first plot to the last, and compared with the truth exactly
as ``scripts/tracking_report.py`` compares the tracks. Printed per q: the filter's measured p95 (and
RMSE, p95 straight / turning faster than 1°/s), the p95 its own covariance predicts (mixture of
N(0, P) over the grid times), and the recorded flights' own position jitter (the truth of these
real OpenSky trajectories, 1 s samples: residual to a 61 s quadratic fit), which no filter can
follow and which is in both the plots and the truth.

The same plots through FilterPy's ``IMMEstimator`` of two such filters (``--imm`` q pairs) show what
a manoeuvre-adaptive filter achieves with perfect association and no bias.

Usage: python scripts/tracking_bound.py [--q 0.1 0.3 1 3 10 30] [--imm 0.3 10 1 10 1 30] [--enroute-s 3600]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
from filterpy.common import Q_continuous_white_noise
from filterpy.kalman import IMMEstimator, KalmanFilter

sys.path.insert(0, str(Path(__file__).resolve().parent))
import tracking_scenarios as scenarios  # noqa: E402

from radartracker.geometry.plane import SystemPlane  # noqa: E402
from radartracker.pipeline.evaluate import TruthPaths  # noqa: E402

GRID_S, GRACE_S, HIGH_M = 2.0, 20.0, 7000.0


def plot_covariances(site_xy: np.ndarray, site_h: float, pos: np.ndarray, h: np.ndarray, sr: float,
                     sa: float) -> np.ndarray:
    """R (N, 2, 2) of plots of a radar at ``site_xy`` (height ``site_h``) of aircraft at ``pos`` (N, 2), ``h``."""
    d = pos - site_xy
    g = np.hypot(d[:, 0], d[:, 1])
    rho = np.hypot(g, h - site_h)
    u = d / g[:, None]
    w = np.column_stack([-u[:, 1], u[:, 0]])
    s_along, s_cross = sr * rho / g, g * sa
    return (s_along**2)[:, None, None] * u[:, :, None] * u[:, None, :] + (s_cross**2)[:, None, None] * w[:, :, None] * w[:, None, :]


def clairvoyant(t: np.ndarray, z: np.ndarray, R: np.ndarray, q: float, grid: np.ndarray) -> tuple[np.ndarray, ...]:
    """FilterPy CV Kalman filter over (t, z, R); positions and position covariances at ``grid``
    (extrapolated from the last update at or before each grid time)."""
    kf = KalmanFilter(dim_x=4, dim_z=2)  # state [x, vx, y, vy]
    kf.H = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0]])
    kf.x = np.array([z[0, 0], 0.0, z[0, 1], 0.0])
    kf.P = np.diag([R[0, 0, 0], 300.0**2, R[0, 1, 1], 300.0**2])
    kf.P[0, 2] = kf.P[2, 0] = R[0, 0, 1]
    xs, Ps = [kf.x.copy()], [kf.P.copy()]
    for k in range(1, len(t)):
        dt = t[k] - t[k - 1]
        kf.F = np.array([[1, dt, 0, 0], [0, 1, 0, 0], [0, 0, 1, dt], [0, 0, 0, 1.0]])
        kf.Q = Q_continuous_white_noise(dim=2, dt=dt, spectral_density=q, block_size=2)
        kf.predict()
        kf.update(z[k], R=R[k])
        xs.append(kf.x.copy())
        Ps.append(kf.P.copy())
    xs, Ps = np.array(xs), np.array(Ps)
    i = np.searchsorted(t, grid, side="right") - 1
    dt = grid - t[i]
    pos = xs[i][:, [0, 2]] + xs[i][:, [1, 3]] * dt[:, None]
    F = np.zeros((len(grid), 2, 4))
    F[:, 0, 0] = F[:, 1, 2] = 1.0
    F[:, 0, 1] = F[:, 1, 3] = dt
    Qp = q * dt**3 / 3  # position block of Q(dt)
    cov = F @ Ps[i] @ np.swapaxes(F, 1, 2) + Qp[:, None, None] * np.eye(2)
    return pos, cov


def clairvoyant_imm(t: np.ndarray, z: np.ndarray, R: np.ndarray, q_low: float, q_high: float,
                    grid: np.ndarray) -> np.ndarray:
    """FilterPy's ``IMMEstimator`` of two CV Kalman filters (densities ``q_low``, ``q_high``; Markov
    matrix per update for mean sojourns 120 s and 30 s at the median revisit) over (t, z, R);
    positions at ``grid`` (extrapolated from the last update)."""
    filters = []
    for _ in (q_low, q_high):
        kf = KalmanFilter(dim_x=4, dim_z=2)
        kf.H = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0]])
        kf.x = np.array([z[0, 0], 0.0, z[0, 1], 0.0])
        kf.P = np.diag([R[0, 0, 0], 300.0**2, R[0, 1, 1], 300.0**2])
        filters.append(kf)
    step = float(np.median(np.diff(t))) if len(t) > 1 else 1.0
    leave = np.array([step / 120.0, step / 30.0])
    imm = IMMEstimator(filters, np.array([0.8, 0.2]), np.array([[1 - leave[0], leave[0]], [leave[1], 1 - leave[1]]]))
    xs = [imm.x.copy()]
    for k in range(1, len(t)):
        dt = t[k] - t[k - 1]
        for kf, q in zip(filters, (q_low, q_high)):
            kf.F = np.array([[1, dt, 0, 0], [0, 1, 0, 0], [0, 0, 1, dt], [0, 0, 0, 1.0]])
            kf.Q = Q_continuous_white_noise(dim=2, dt=dt, spectral_density=q, block_size=2)
            kf.R = R[k]
        imm.predict()
        imm.update(z[k])
        xs.append(imm.x.copy())
    xs = np.array(xs)
    i = np.searchsorted(t, grid, side="right") - 1
    return xs[i][:, [0, 2]] + xs[i][:, [1, 3]] * (grid - t[i])[:, None]


def truth_jitter(data) -> float:
    """Per-axis sd of the truth's 1 s samples about a 61 s local quadratic fit (above 7000 m)."""
    plane = SystemPlane(*data.reference)
    x, y = plane.to_plane(data.truth.lat, data.truth.lon)
    res = []
    for tg in np.unique(data.truth.target.astype(str)):
        idx = np.flatnonzero(data.truth.target == tg)
        t, h = data.truth.time[idx], data.truth.altitude_m[idx]
        for i in range(30, len(idx) - 30, 7):
            if h[i] > 7000.0:
                sl = slice(i - 30, i + 31)
                for c in (x[idx], y[idx]):
                    res.append(c[i] - np.polyval(np.polyfit(t[sl] - t[i], c[sl], 2), 0.0))
    return float(np.std(res))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--q", nargs="*", type=float, default=[0.1, 0.3, 1.0, 3.0, 10.0, 30.0])
    ap.add_argument("--imm", nargs="*", type=float, default=[0.3, 10.0, 1.0, 10.0, 1.0, 30.0],
                    help="pairs of q (low, high) of a clairvoyant two-mode IMM")
    ap.add_argument("--enroute-s", type=float, default=3600.0)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    data = scenarios.enroute(args.seed, args.enroute_s, mode_s=True)
    plane = SystemPlane(*data.reference)
    paths = TruthPaths.from_table(data.truth, plane)
    p = data.plots
    site = {r.id: (np.array(plane.to_plane(r.lat, r.lon), float), r.height_m, r.sigma_range_m, r.sigma_azimuth_rad)
            for r in data.radars}
    grid_all = np.arange(data.truth.time.min(), data.truth.time.max(), GRID_S)
    th = data.truth
    rng = np.random.default_rng(args.seed)
    per_target = []
    for tg in np.unique(p.target[p.target != None].astype(str)):  # noqa: E711
        idx = np.flatnonzero(p.target == tg)
        idx = idx[np.argsort(p.time[idx], kind="stable")]
        t = p.time[idx]
        if t[-1] - t[0] <= GRACE_S:
            continue
        truth, _ = paths.state_at(tg, t)
        ti = np.flatnonzero(th.target == tg)
        h = np.interp(t, th.time[ti], th.altitude_m[ti])
        R = np.zeros((len(t), 2, 2))
        for rid, (xy, sh, sr, sa) in site.items():
            m = p.radar[idx] == rid
            if m.any():
                R[m] = plot_covariances(xy, sh, truth[m, :2], h[m], sr, sa)
        z = truth[:, :2] + np.einsum("nij,nj->ni", np.linalg.cholesky(R), rng.standard_normal((len(t), 2)))
        grid = grid_all[(grid_all >= t[0] + GRACE_S) & (grid_all <= t[-1])]
        gtruth, inside = paths.state_at(tg, grid)
        heading = np.unwrap(np.arctan2(gtruth[:, 2], gtruth[:, 3]))
        turning = np.abs(np.gradient(heading, grid)) > np.radians(1.0) if len(grid) > 1 else np.zeros(len(grid), bool)
        radars = len(np.unique(p.radar[idx]))
        high = np.interp(grid, th.time[ti], th.altitude_m[ti]) >= HIGH_M
        per_target.append((t, z, R, grid[inside], gtruth[inside, :2], turning[inside], high[inside], radars,
                           float(np.median(np.sqrt(np.trace(R, axis1=1, axis2=2)))), len(t) / (t[-1] - t[0])))
    jitter = truth_jitter(data)
    radars = np.array([pt[7] for pt in per_target])
    print(json.dumps({"flights": len(per_target), "truth_jitter_sd_per_axis_m": jitter,
                      "radars_per_aircraft": {int(k): int(np.sum(radars == k)) for k in np.unique(radars)},
                      "median_sqrt_trace_R_m": float(np.median([pt[8] for pt in per_target])),
                      "plots_per_s_median": float(np.median([pt[9] for pt in per_target]))}), flush=True)
    rows = []
    for q in args.q:
        err, turn, hi, pred = [], [], [], []
        for t, z, R, grid, gtruth, turning, high, *_ in per_target:
            pos, cov = clairvoyant(t, z, R, q, grid)
            err.append(np.hypot(*(pos - gtruth).T))
            turn.append(turning)
            hi.append(high)
            pred.append(np.einsum("nij,nj->ni", np.linalg.cholesky(cov), rng.standard_normal((len(grid), 2))))
        e, tu, hi, pr = np.concatenate(err), np.concatenate(turn), np.concatenate(hi), np.concatenate(pred)
        row = {"q": q, "rmse_m": float(np.sqrt(np.mean(e**2))), "p95_m": float(np.percentile(e, 95)),
               "p95_straight_m": float(np.percentile(e[~tu], 95)), "p95_turning_m": float(np.percentile(e[tu], 95)),
               "p95_above_7000m_m": float(np.percentile(e[hi], 95)),
               "p95_predicted_m": float(np.percentile(np.hypot(*pr.T), 95)),
               "p95_predicted_above_7000m_m": float(np.percentile(np.hypot(*pr[hi].T), 95)),
               "p95_predicted_with_jitter_m": float(np.percentile(np.hypot(*(pr + jitter * rng.standard_normal(pr.shape)).T), 95))}
        print(json.dumps(row), flush=True)
        rows.append(row)
    imm_rows = []
    for q_low, q_high in zip(args.imm[::2], args.imm[1::2]):
        err, turn, hi = [], [], []
        for t, z, R, grid, gtruth, turning, high, *_ in per_target:
            err.append(np.hypot(*(clairvoyant_imm(t, z, R, q_low, q_high, grid) - gtruth).T))
            turn.append(turning)
            hi.append(high)
        e, tu, hi = np.concatenate(err), np.concatenate(turn), np.concatenate(hi)
        row = {"imm_q": [q_low, q_high], "rmse_m": float(np.sqrt(np.mean(e**2))), "p95_m": float(np.percentile(e, 95)),
               "p95_straight_m": float(np.percentile(e[~tu], 95)), "p95_turning_m": float(np.percentile(e[tu], 95)),
               "p95_above_7000m_m": float(np.percentile(e[hi], 95))}
        print(json.dumps(row), flush=True)
        imm_rows.append(row)
    print()
    print("| q (m²/s³) | RMSE (m) | p95 (m) | p95 straight / turning (m) | p95 above 7000 m (m) | p95 predicted by P "
          "(all / above 7000 m) | predicted with the truth's jitter (all) |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['q']:g} | {r['rmse_m']:.1f} | {r['p95_m']:.1f} | {r['p95_straight_m']:.0f} / {r['p95_turning_m']:.0f} | "
              f"{r['p95_above_7000m_m']:.0f} | {r['p95_predicted_m']:.1f} / {r['p95_predicted_above_7000m_m']:.1f} | "
              f"{r['p95_predicted_with_jitter_m']:.1f} |")
    for r in imm_rows:
        print(f"| IMM {r['imm_q'][0]:g} / {r['imm_q'][1]:g} | {r['rmse_m']:.1f} | {r['p95_m']:.1f} | "
              f"{r['p95_straight_m']:.0f} / {r['p95_turning_m']:.0f} | {r['p95_above_7000m_m']:.0f} | — | — |")


if __name__ == "__main__":
    main()
