"""Monte Carlo of static and dynamic triangulation against the Cramér–Rao bound (seed 001).

For each configuration: true bearings from pyproj (geodetic → station ENU), Gaussian errors,
the ML estimate, and RMSE = √(mean ‖r̂ − r‖²) over the runs (dynamic: also over the bearing
times) against CRLB = √(mean tr bound). Prints one JSON line per configuration, then the table
of the headline cases, and writes docs/figures/triangulation_noise.png and
docs/figures/triangulation_geometry.png.

    python scripts/triangulation_montecarlo.py [--runs 500] [--seed 1] [--no-figures]
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import sys
from pathlib import Path

import numpy as np
from scipy import stats

from radartracker_plugins.triangulation import (DirectionFinder, GeometryError, PolynomialBasis, StationWeights,
                                                TriangulationFrame, locate, track)
from radartracker_plugins.triangulation import crlb
from radartracker_plugins.triangulation.simulate import (noisy_bearings, schedule, sites_around,
                                                         true_bearings)

LAT, LON, ALT = 46.0, 6.0, 8000.0
FIGURES = Path(__file__).resolve().parent.parent / "docs" / "figures"


class Case:
    """A geometry: stations (sites, grids), true motion, and the estimator's basis (None: static)."""

    def __init__(self, name, sites, positions_of, grids=None, order=None, reference=(LAT, LON, 0.0)):
        self.name, self.sites, self.grids, self.order = name, sites, grids, order
        self.reference, self.positions_of = reference, positions_of
        frame = self.frame(1e-3)
        if grids is None:
            self.ids, self.times = np.array(list(frame.stations)), np.zeros(len(sites))
        else:
            self.ids, self.times = schedule(frame)
        self.pos = positions_of(frame, self.times)
        self.truth = true_bearings(frame, self.ids, self.pos)

    def frame(self, sigma, spread=False):
        """Stations with σ_α = σ_β = σ, or with ``spread`` station i at σ·(1 + i) in azimuth and
        twice that in elevation (unequal noise: where W = I and W = K⁻¹ part ways)."""
        def sig(i):
            return (sigma * (1 + i), 2 * sigma * (1 + i)) if spread else (sigma, sigma)
        return TriangulationFrame([DirectionFinder(f"s{i}", la, lo, 200.0, *sig(i),
                                                   None if self.grids is None else self.grids[i])
                                   for i, (la, lo) in enumerate(self.sites)], self.reference)

    def bound(self, frame):
        """(N, 3, 3) position bounds at the bearing times, and the eigenvalues λ of the bound on
        the per-run mean squared error (a quadratic form δθᵀ G δθ, G = mean_n Φ_nᵀΦ_n)."""
        if self.order is None:
            B = crlb.static_crlb(frame, self.ids, self.pos[0])
            return B[None], np.linalg.eigvalsh(B)
        t0, t1 = self.times.min(), self.times.max()
        basis = PolynomialBasis(self.order, 0.5 * (t0 + t1), 0.5 * (t1 - t0))
        Q = basis(self.times)
        theta = np.linalg.lstsq(Q, self.pos, rcond=None)[0].T  # exact: the truth is in the model
        B = crlb.dynamic_crlb(frame, self.ids, self.times, basis, theta)
        G = np.kron(np.eye(3), Q.T @ Q / len(Q))
        return crlb.position_bound(Q, B), np.linalg.eigvals(G @ B).real


def run(case: Case, sigma: float, runs: int, rng) -> dict:
    frame = case.frame(sigma)
    bound, lam = case.bound(frame)
    sq, refused, poor, gdops = [], 0, 0, []
    for _ in range(runs):
        bs = noisy_bearings(frame, case.ids, case.times, case.truth, rng)
        try:
            if case.order is None:
                fit = locate(frame, bs)
                err = fit.position[None] - case.pos[:1]
            else:
                fit = track(frame, bs, order=case.order)
                err = fit.position(case.times) - case.pos
        except GeometryError:
            refused += 1
            continue
        sq.append(np.mean(np.sum(err**2, axis=1)))
        poor += fit.poor_geometry
        gdops.append(fit.gdop)
    ref = case.pos[:1] if case.order is None else case.pos
    rho = np.linalg.norm(ref[:, None, :] - np.array([frame.position[s] for s in case.ids])[None], axis=2)
    crlb_m = math.sqrt(np.mean(np.trace(bound, axis1=1, axis2=2)))
    gdop = crlb_m / (sigma * math.sqrt(np.mean(rho**2)))
    rmse = math.sqrt(np.mean(sq)) if sq else math.nan
    # 95 % range of RMSE/CRLB for an efficient estimator: Σλχ²₁ ≈ c·χ²_ν (Satterthwaite)
    nu = max(len(sq), 1) * lam.sum() ** 2 / np.sum(lam**2)
    ci = [round(math.sqrt(v), 3) for v in stats.chi2.ppf([0.025, 0.975], nu) / nu]
    return {"case": case.name, "sigma_mrad": sigma * 1e3, "runs": runs, "solved": len(sq),
            "refused": refused, "flagged_poor": int(poor), "gdop": round(gdop, 3),
            "gdop_estimated_median": round(float(np.median(gdops)), 3) if gdops else None,
            "crlb_m": round(crlb_m, 3), "rmse_m": round(rmse, 3),
            "ratio": round(rmse / crlb_m, 4), "ratio_ci95_if_efficient": ci}


def run_lsq(case: Case, sigma: float, runs: int, rng) -> dict:
    """ML and LSQ(W = I) on the same bearings with unequal station noise, against the CRLB."""
    frame = case.frame(sigma, spread=True)
    bound, _ = case.bound(frame)
    crlb_m = math.sqrt(np.mean(np.trace(bound, axis1=1, axis2=2)))
    sq = {"ml": [], "lsq": []}
    sandwich, refused = [], 0
    for _ in range(runs):
        bs = noisy_bearings(frame, case.ids, case.times, case.truth, rng)
        try:
            fits = {}
            for name, w in (("ml", None), ("lsq", StationWeights.identity())):
                if case.order is None:
                    fits[name] = locate(frame, bs, weights=w)
                else:
                    fits[name] = track(frame, bs, order=case.order, weights=w)
        except GeometryError:
            refused += 1
            continue
        for name, fit in fits.items():
            if case.order is None:
                err, cov = fit.position[None] - case.pos[:1], fit.cov[None]
            else:
                err, cov = fit.position(case.times) - case.pos, fit.covariance(case.times)
            sq[name].append(np.mean(np.sum(err**2, axis=1)))
            if name == "lsq":
                sandwich.append(np.mean(np.trace(cov, axis1=1, axis2=2)))
    rm = {k: math.sqrt(np.mean(v)) if v else math.nan for k, v in sq.items()}
    return {"case": case.name, "sigma_mrad": sigma * 1e3, "runs": runs, "solved": len(sq["ml"]),
            "refused": refused, "crlb_m": round(crlb_m, 3), "ml_rmse_m": round(rm["ml"], 3),
            "lsq_rmse_m": round(rm["lsq"], 3), "ml_ratio": round(rm["ml"] / crlb_m, 4),
            "lsq_ratio": round(rm["lsq"] / crlb_m, 4),
            "lsq_sandwich_ratio": round(math.sqrt(np.mean(sandwich)) / crlb_m, 4) if sandwich else None}


def _two_stations(baseline_m, distance_m, off_axis_deg, alt=3000.0):
    """Stations ±baseline/2 east–west of the centre; the target ``distance_m`` from the centre,
    ``off_axis_deg`` from the baseline axis (90: broadside, 0: on the axis, collinear)."""
    sites = sites_around(LAT, LON, baseline_m / 2, [90.0, 270.0])
    tgt = sites_around(LAT, LON, distance_m, [90.0 - off_axis_deg])[0]
    return sites, tgt, alt


def build_cases():
    ring = sites_around(LAT, LON, 40e3, [15.0, 105.0, 195.0, 285.0])
    ring3 = ring[:3]
    grids = [np.arange(0.0, 120.0, 4.0), np.arange(1.3, 120.0, 5.0), np.arange(2.6, 120.0, 6.0)]
    vel = np.array([200.0, 60.0, 5.0])

    def fixed(lat, lon, alt):
        return lambda frame, t: np.tile(frame.enu(lat, lon, alt), (len(t), 1))

    def moving(lat, lon, alt, v, acc=np.zeros(3)):
        def f(frame, t):
            tau = t[:, None] - 60.0
            return frame.enu(lat, lon, alt) + tau * v + 0.5 * tau**2 * acc
        return f

    poor_sites, poor_tgt, poor_alt = _two_stations(20e3, 80e3, 8.0)
    far_sites, far_tgt, far_alt = _two_stations(20e3, 100e3, 5.0)
    cases = {
        "static good": Case("static good", ring, fixed(LAT, LON, ALT)),
        "static poor": Case("static poor", poor_sites, fixed(*poor_tgt, poor_alt)),
        "dynamic good": Case("dynamic good", ring3, moving(LAT, LON, ALT, vel), grids, order=1),
        "dynamic good (order 2)": Case("dynamic good (order 2)", ring3,
                                       moving(LAT, LON, ALT, vel, np.array([-1.5, 2.0, 0.0])), grids, order=2),
        "dynamic poor": Case("dynamic poor", far_sites, moving(*far_tgt, far_alt, np.array([-150.0, 20.0, 0.0])),
                             grids[:2], order=1),
    }
    return cases, fixed


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=500, help="Monte Carlo runs per configuration (default 500)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--sigma-mrad", type=float, default=1.0, help="bearing noise of the table (default 1 mrad)")
    ap.add_argument("--no-figures", action="store_true")
    ap.add_argument("--lsq-only", action="store_true", help="only the ML vs LSQ(W = I) study")
    args = ap.parse_args(argv)
    logging.getLogger("radartracker.triangulation").setLevel(logging.ERROR)  # counted, not logged
    rng = np.random.default_rng(args.seed)
    cases, fixed = build_cases()

    lsq_sigmas = np.array([0.5, 1.0, 2.0, 4.0]) * 1e-3
    lsq = [run_lsq(c, s, args.runs, rng) for c in cases.values() for s in lsq_sigmas]
    for row in lsq:
        print(json.dumps({"study": "lsq", **row}))
    print()
    print(f"ML vs LSQ(W = I) vs CRLB, unequal station noise (station i: σ·(1+i), elevation 2×), {args.runs} runs")
    print("| case | σ (mrad) | CRLB (m) | ML RMSE/CRLB | LSQ(W=I) RMSE/CRLB | LSQ stated σ/CRLB | refused |")
    print("|---|---|---|---|---|---|---|")
    for r in lsq:
        print(f"| {r['case']} | {r['sigma_mrad']:g} | {r['crlb_m']:.1f} | {r['ml_ratio']:.3f} | {r['lsq_ratio']:.3f} | "
              f"{r['lsq_sandwich_ratio']:.3f} | {r['refused']} |")
    if args.lsq_only:
        return 0

    table = [run(c, args.sigma_mrad * 1e-3, args.runs, rng) for c in cases.values()]
    for row in table:
        print(json.dumps({"study": "table", **row}))

    sigmas = np.array([0.25, 0.5, 1.0, 2.0, 4.0, 8.0]) * 1e-3
    noise = {name: [run(cases[name], s, args.runs, rng) for s in sigmas]
             for name in ("static good", "static poor", "dynamic good", "dynamic poor")}
    for rows in noise.values():
        for row in rows:
            print(json.dumps({"study": "noise", **row}))

    angles = np.array([90.0, 60.0, 40.0, 25.0, 15.0, 10.0, 6.0, 4.0, 2.0, 1.0, 0.0])
    geometry = []
    for a in angles:
        sites, tgt, alt = _two_stations(40e3, 60e3, a)
        row = run(Case(f"static 2 stations, {a:g} deg off axis", sites, fixed(*tgt, alt)),
                  args.sigma_mrad * 1e-3, args.runs, rng)
        geometry.append(row)
        print(json.dumps({"study": "geometry", "off_axis_deg": a, **row}))

    print()
    print(f"RMSE vs CRLB, σ = {args.sigma_mrad:g} mrad, {args.runs} runs each (seed {args.seed})")
    head = (f"| {'case':<24} | runs solved | flagged poor | GDOP  | CRLB (m) | RMSE (m) | RMSE/CRLB "
            "| 95 % range if efficient |")
    print(head)
    print("|" + "|".join("-" * (len(c)) for c in head.split("|")[1:-1]) + "|")
    for r in table:
        lo, hi = r["ratio_ci95_if_efficient"]
        print(f"| {r['case']:<24} | {r['solved']:>4}/{r['runs']:<6} | {r['flagged_poor']:>12} | "
              f"{r['gdop']:>5.3g} | {r['crlb_m']:>8.1f} | {r['rmse_m']:>8.1f} | {r['ratio']:>9.3f} "
              f"| {f'{lo:.3f} – {hi:.3f}':<23} |")
    print()
    print("RMSE/CRLB vs bearing noise σ (mrad); [n] = runs refused")
    print(f"| {'case':<14} | GDOP  | " + " | ".join(f"{s * 1e3:>10g}" for s in sigmas) + " |")
    print("|" + "-" * 16 + "|-------|" + "|".join("-" * 12 for _ in sigmas) + "|")
    for name, rows in noise.items():
        cells = [f"{r['ratio']:.3f}" + (f" [{r['refused']}]" if r["refused"] else "") for r in rows]
        print(f"| {name:<14} | {rows[0]['gdop']:>5.3g} | " + " | ".join(f"{c:>10}" for c in cells) + " |")
    print()
    print(f"Two stations 40 km apart, target 60 km from their mid-point, σ = {args.sigma_mrad:g} mrad")
    print("| off axis (deg) | GDOP  | CRLB (m) | RMSE (m) | RMSE/CRLB | flagged poor | refused |")
    print("|----------------|-------|----------|----------|-----------|--------------|---------|")
    for a, r in zip(angles, geometry):
        print(f"| {a:>14g} | {r['gdop']:>5.3g} | {r['crlb_m']:>8.1f} | {r['rmse_m']:>8.1f} | "
              f"{r['ratio']:>9.3f} | {r['flagged_poor']:>12} | {r['refused']:>7} |")
    if not args.no_figures:
        _figures(noise, sigmas, geometry, angles, args)
    return 0


def _ratio_panel(ax, x, rows, colour, label):
    ax.plot(x, [r["ratio"] for r in rows], "o-", color=colour, ms=4, label=label)


def _figures(noise, sigmas, geometry, angles, args) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import NullFormatter, ScalarFormatter

    FIGURES.mkdir(parents=True, exist_ok=True)
    x = sigmas * 1e3
    fig, (ax, axr) = plt.subplots(2, 1, figsize=(7, 7), sharex=True, gridspec_kw={"height_ratios": [2, 1]})
    for (name, rows), colour in zip(noise.items(), ("C0", "C1", "C2", "C3")):
        ax.loglog(x, [r["crlb_m"] for r in rows], "-", color=colour, label=f"{name}: CRLB")
        ax.loglog(x, [r["rmse_m"] for r in rows], "o", color=colour, label=f"{name}: RMSE")
        _ratio_panel(axr, x, rows, colour, name)
    ax.set_ylabel("position error (m)")
    ax.set_title(f"Triangulation RMSE vs Cramér–Rao bound ({args.runs} runs per point)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    axr.axhspan(0.9, 1.1, color="grey", alpha=0.15, label="±10 %")
    axr.set_ylabel("RMSE / CRLB")
    axr.set_xlabel("bearing noise σ_α = σ_β (mrad)")
    axr.set_xticks(x)
    axr.xaxis.set_major_formatter(ScalarFormatter())
    axr.xaxis.set_minor_formatter(NullFormatter())
    axr.grid(True, alpha=0.3)
    axr.legend(fontsize=7, ncol=3)
    fig.tight_layout()
    fig.savefig(FIGURES / "triangulation_noise.png", dpi=120)
    plt.close(fig)

    fig, (ax, axr) = plt.subplots(2, 1, figsize=(7, 7), sharex=True, gridspec_kw={"height_ratios": [2, 1]})
    ax.semilogy(angles, [r["crlb_m"] for r in geometry], "-", label="CRLB")
    ax.semilogy(angles, [r["rmse_m"] for r in geometry], "o", label="RMSE")
    ax2 = ax.twinx()
    ax2.semilogy(angles, [r["gdop"] for r in geometry], "k:", label="GDOP (right axis)")
    ax2.axhline(10.0, color="red", lw=0.8, ls="--", label="GDOP 10: flagged as poor above")
    ax2.set_ylabel("GDOP")
    ax.set_ylabel("position error (m)")
    ax.set_title(f"Two stations 40 km apart, target 60 km away at 3 km, σ = {args.sigma_mrad:g} mrad")
    h1, l1 = ax.get_legend_handles_labels()
    h2, l2 = ax2.get_legend_handles_labels()
    ax.legend(h1 + h2, l1 + l2, fontsize=8)
    ax.grid(True, which="both", alpha=0.3)
    _ratio_panel(axr, angles, geometry, "C1", "RMSE / CRLB")
    axr.fill_between(angles, [r["ratio_ci95_if_efficient"][0] for r in geometry],
                     [r["ratio_ci95_if_efficient"][1] for r in geometry], color="C0", alpha=0.2,
                     label="95 % range of an efficient estimator")
    axr.set_ylabel("RMSE / CRLB")
    axr.set_xlabel("target direction off the baseline axis (deg; 0 = on the axis, horizontally collinear)")
    axr.grid(True, alpha=0.3)
    axr.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(FIGURES / "triangulation_geometry.png", dpi=120)
    plt.close(fig)
    print(f"figures in {FIGURES}", file=sys.stderr)


if __name__ == "__main__":
    sys.exit(main())
