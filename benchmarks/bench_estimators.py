"""Benchmark: time per plot of each estimator vs aircraft and radars; single-target KF vs FilterPy and Stone Soup.

    python benchmarks/bench_estimators.py [--aircraft 10 100 500 2000] [--radars 3 10 28] [--budget 2.0]

Data: the seed's linear toy model (radartracker.simulation.linsim), every radar seeing every aircraft. For
each (estimator, n aircraft, m radars) all aircraft are added, then plots are fed until ``budget``
seconds have passed (at least 10 plots); coupled runs only where its dense covariance fits in
``--max-coupled-gib``. Then, on the same constant-velocity single-target data (unbiased position
measurements, q = 1), our estimators (a plain KF for one unbiased aircraft), FilterPy's
``KalmanFilter`` and Stone Soup's ``KalmanPredictor``/``KalmanUpdater`` run predict + update per
measurement; the script checks they agree before timing. One JSON line per measurement, then
the ratio tables. Needs the ``bench`` extra (filterpy, stonesoup).
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import platform
import sys
import time

import numpy as np

from radartracker.simulation.linsim import make_linear_scenario
from radartracker.estimation.motion import MotionModel
from radartracker.estimation.base import EstimatorConfig
from radartracker.registry import make_estimator

ESTIMATORS = ("decoupled", "blom", "coupled")
P0 = np.diag([500.0**2, 500.0**2, 50.0**2, 50.0**2])


def time_estimator(name: str, n: int, m: int, budget: float, seed: int = 0) -> dict:
    # enough plots for the budget at any speed: one turn of every radar over every aircraft
    sc = make_linear_scenario(n_aircraft=n, n_radars=m, duration=4.0 * max(1, 3000 // (n * m) + 1),
                              period=4.0, rng=seed, adsb_aircraft=n // 10)
    est = make_estimator(name, EstimatorConfig(motion=MotionModel(1.0)), sc.radar_ids)
    for k, x in sc.initial.items():
        est.add_aircraft(k, 0.0, x, P0)
    plots, t0 = 0, time.perf_counter()
    for meas in sc.measurements:
        est.update(meas)
        plots += 1
        if plots >= 10 and time.perf_counter() - t0 > budget:
            break
    sec = time.perf_counter() - t0
    return {"bench": "scaling", "estimator": name, "aircraft": n, "radars": m, "plots": plots,
            "us_per_plot": 1e6 * sec / plots}


def single_target_data(steps: int, q: float, seed: int = 7):
    sc = make_linear_scenario(n_aircraft=1, n_radars=0, duration=4.0 * steps, period=4.0, rng=seed,
                              adsb_aircraft=1, adsb_sigma_m=50.0, q=q)
    x0 = sc.initial["A0000"] + np.array([200.0, -150.0, 10.0, -5.0])
    return sc.measurements, x0


def run_ours(name: str, meas, x0, q: float):
    est = make_estimator(name, EstimatorConfig(motion=MotionModel(q)), [])
    est.add_aircraft("A0000", 0.0, x0, P0)
    t0 = time.perf_counter()
    for m in meas:
        est.update(m)
    sec = time.perf_counter() - t0
    a = est.aircraft("A0000")
    return sec, a.state, a.cov


def run_filterpy(meas, x0, q: float):
    from filterpy.kalman import KalmanFilter

    kf = KalmanFilter(dim_x=4, dim_z=2)
    kf.x, kf.P = x0.copy(), P0.copy()
    kf.H = np.hstack([np.eye(2), np.zeros((2, 2))])
    motion = MotionModel(q)
    t, t0 = 0.0, time.perf_counter()
    for m in meas:
        A, Q = motion.transition(m.time - t)
        t = m.time
        kf.predict(F=A, Q=Q)
        kf.update(m.z, R=m.R)
    return time.perf_counter() - t0, kf.x.copy(), kf.P.copy()


def run_stonesoup(meas, x0, q: float):
    from stonesoup.models.measurement.linear import LinearGaussian
    from stonesoup.models.transition.linear import CombinedLinearGaussianTransitionModel, ConstantVelocity
    from stonesoup.predictor.kalman import KalmanPredictor
    from stonesoup.types.detection import Detection
    from stonesoup.types.hypothesis import SingleHypothesis
    from stonesoup.types.state import GaussianState
    from stonesoup.updater.kalman import KalmanUpdater

    perm = [0, 2, 1, 3]  # Stone Soup orders [x, vx, y, vy]
    start = dt.datetime(2024, 1, 1)
    predictor = KalmanPredictor(CombinedLinearGaussianTransitionModel([ConstantVelocity(q), ConstantVelocity(q)]))
    updater = KalmanUpdater(measurement_model=None)
    dets = [Detection(m.z.reshape(2, 1), timestamp=start + dt.timedelta(seconds=m.time),
                      measurement_model=LinearGaussian(ndim_state=4, mapping=(0, 2), noise_covar=m.R)) for m in meas]
    state = GaussianState(x0[perm].reshape(4, 1), P0[np.ix_(perm, perm)], timestamp=start)
    t0 = time.perf_counter()
    for det in dets:
        pred = predictor.predict(state, timestamp=det.timestamp)
        state = updater.update(SingleHypothesis(pred, det))
    sec = time.perf_counter() - t0
    inv = np.argsort(perm)
    x = np.asarray(state.state_vector, float).ravel()[inv]
    return sec, x, np.asarray(state.covar, float)[np.ix_(inv, inv)]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--aircraft", type=int, nargs="+", default=[10, 100, 500, 2000])
    ap.add_argument("--radars", type=int, nargs="+", default=[3, 10, 28])
    ap.add_argument("--budget", type=float, default=2.0, help="seconds of plots per configuration")
    ap.add_argument("--max-coupled-gib", type=float, default=1.0, help="largest dense covariance to try")
    ap.add_argument("--steps", type=int, default=3000, help="single-target measurements")
    args = ap.parse_args(argv)
    print(json.dumps({"bench": "environment", "cpus": os.cpu_count(), "loadavg_1min": os.getloadavg()[0],
                      "python": platform.python_version(), "numpy": np.__version__,
                      "openblas_threads": os.environ.get("OPENBLAS_NUM_THREADS")}), flush=True)

    rows = []
    for m in args.radars:
        for n in args.aircraft:
            for name in ESTIMATORS:
                if name == "coupled" and 8 * (4 * n + 2 * m) ** 2 / 2**30 > args.max_coupled_gib:
                    print(json.dumps({"bench": "scaling", "estimator": name, "aircraft": n, "radars": m,
                                      "skipped": "dense covariance above --max-coupled-gib"}), flush=True)
                    continue
                row = time_estimator(name, n, m, args.budget)
                rows.append(row)
                print(json.dumps(row), flush=True)

    q = 1.0
    meas, x0 = single_target_data(args.steps, q)
    ref = run_filterpy(meas, x0, q)
    single = {}
    for impl, fn in [("filterpy.KalmanFilter", lambda: run_filterpy(meas, x0, q)),
                     ("stonesoup.KalmanPredictor/Updater", lambda: run_stonesoup(meas, x0, q)),
                     *[(f"radartracker.{e}", (lambda e=e: run_ours(e, meas, x0, q))) for e in ESTIMATORS]]:
        sec, x, P = min((fn() for _ in range(3)), key=lambda r: r[0])
        agree = float(max(np.max(np.abs(x - ref[1]) / (1 + np.abs(ref[1]))), np.max(np.abs(P - ref[2]) / (1 + np.abs(ref[2])))))
        single[impl] = 1e6 * sec / len(meas)
        print(json.dumps({"bench": "single_target", "impl": impl, "measurements": len(meas),
                          "us_per_update": single[impl], "max_rel_diff_vs_filterpy": agree}), flush=True)
        if agree > 1e-6:
            raise SystemExit(f"{impl} disagrees with FilterPy: {agree}")

    print("\nTime per plot (µs) and ratio to decoupled")
    print(f"{'radars':>6} {'aircraft':>8} " + " ".join(f"{e:>10}" for e in ESTIMATORS) + "   blom/dec  coupled/dec")
    by = {(r["estimator"], r["aircraft"], r["radars"]): r["us_per_plot"] for r in rows}
    for m in args.radars:
        for n in args.aircraft:
            t = [by.get((e, n, m), float("nan")) for e in ESTIMATORS]
            print(f"{m:>6} {n:>8} " + " ".join(f"{v:>10.1f}" for v in t) + f"   {t[1] / t[0]:>8.2f}  {t[2] / t[0]:>11.2f}")
    print("\nSingle-target constant-velocity KF, predict + update (µs) and ratio to radartracker.decoupled")
    base = single["radartracker.decoupled"]
    for impl, us in single.items():
        print(f"{impl:<36} {us:>9.1f}  {us / base:>6.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
