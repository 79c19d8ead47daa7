"""Oracles for the coupled (joint) estimator: batch Gauss–Markov, FilterPy, marginalisation, χ² consistency."""

from __future__ import annotations

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.linalg import block_diag
from scipy.stats import chi2

from radartracker.simulation.linsim import make_linear_scenario
from radartracker.estimation.motion import MotionModel
from radartracker.estimation.base import EstimatorConfig
from radartracker.registry import make_estimator


def _cv(dt: float) -> np.ndarray:
    return np.block([[np.eye(2), dt * np.eye(2)], [np.zeros((2, 2)), np.eye(2)]])


def _run(name, sc, cfg, prior_mean, prior_cov, skip=lambda m: False):
    est = make_estimator(name, cfg, sc.radar_ids)
    for k in sc.initial:
        est.add_aircraft(k, 0.0, prior_mean[k], prior_cov)
    for m in sc.measurements:
        if not skip(m):
            est.update(m)
    return est


def test_coupled_equals_batch_gauss_markov():
    """No process noise, constant biases: the filter is the WLS estimate of all states and biases.

    The batch design matrix is built here from the raw measurements: unknowns are each aircraft's
    state at t = 0 and every bias; a plot at t is z = [I, tI] χ_i(0) + C_s ς_j + noise(R); the priors
    enter as pseudo-measurements. The batch estimate is then mapped to each aircraft's last epoch.
    """
    sc = make_linear_scenario(n_aircraft=6, n_radars=3, duration=90.0, rng=7, adsb_aircraft=2)
    cfg = EstimatorConfig(motion=MotionModel(0.0))
    rng = np.random.default_rng(3)
    P0 = np.diag([1e4**2, 1e4**2, 300.0**2, 300.0**2])  # wide prior
    mean = {k: x + rng.normal(size=4) * np.sqrt(np.diag(P0)) for k, x in sc.initial.items()}
    est = _run("coupled", sc, cfg, mean, P0)

    keys, radars = list(sc.initial), sc.radar_ids
    n, m = len(keys), len(radars)
    dim = 4 * n + 2 * m
    rows, zs, Rs = [], [], []
    for meas in sc.measurements:
        Hrow = np.zeros((2, dim))
        i = keys.index(meas.aircraft)
        Hrow[:, 4 * i:4 * i + 4] = np.hstack([np.eye(2), meas.time * np.eye(2)])
        if meas.radar is not None:
            j = radars.index(meas.radar)
            Hrow[:, 4 * n + 2 * j:4 * n + 2 * j + 2] = meas.C
        rows.append(Hrow), zs.append(meas.z), Rs.append(meas.R)
    for i, k in enumerate(keys):  # priors as pseudo-measurements
        Hp = np.zeros((4, dim))
        Hp[:, 4 * i:4 * i + 4] = np.eye(4)
        rows.append(Hp), zs.append(mean[k]), Rs.append(P0)
    for j in range(m):
        Hp = np.zeros((2, dim))
        Hp[:, 4 * n + 2 * j:4 * n + 2 * j + 2] = np.eye(2)
        rows.append(Hp), zs.append(np.zeros(2)), Rs.append(cfg.bias_prior())
    info = sum(H.T @ np.linalg.solve(R, H) for H, R in zip(rows, Rs))
    vec = sum(H.T @ np.linalg.solve(R, z) for H, z, R in zip(rows, zs, Rs))
    P_b = np.linalg.inv(info)
    x_b = P_b @ vec
    T = np.eye(dim)  # to each aircraft's epoch
    for i, k in enumerate(keys):
        T[4 * i:4 * i + 4, 4 * i:4 * i + 4] = _cv(est.aircraft(k).time)
    x_b, P_b = T @ x_b, T @ P_b @ T.T

    x_f, P_f = est.joint(keys)
    sd = np.sqrt(np.diag(P_b))
    np.testing.assert_allclose(x_f, x_b, rtol=1e-6, atol=1e-6 * sd.min())
    assert np.max(np.abs((x_f - x_b) / sd)) < 1e-6
    np.testing.assert_allclose(P_f / np.outer(sd, sd), P_b / np.outer(sd, sd), atol=1e-6)
    np.testing.assert_allclose(np.diag(P_f), np.diag(P_b), rtol=1e-6)
    # the biases really were learnt (the oracle is not satisfied by an inert filter)
    prior_sd = np.tile(np.sqrt(np.diag(cfg.bias_prior())), m)
    assert np.all(np.sqrt(np.diag(P_f[4 * n:, 4 * n:])) < 0.2 * prior_sd)


def test_coupled_equals_filterpy_joint_kalman_with_drift_and_process_noise():
    """2 aircraft, 2 radars, q > 0, drifting biases: FilterPy's KF on the stacked state is the oracle.

    FilterPy predicts every block to every measurement time; the coupled filter predicts only the
    measured aircraft (own epochs) — exact for the CV model, so the two agree to round-off.
    """
    sc = make_linear_scenario(n_aircraft=2, n_radars=2, duration=60.0, rng=11, adsb_aircraft=1, q=0.5)
    cfg = EstimatorConfig(motion=MotionModel(0.5), bias_drift_range=2.0, bias_drift_azimuth=1e-9)
    P0 = np.diag([1e3**2, 1e3**2, 50.0**2, 50.0**2])
    mean = {k: x + 100.0 for k, x in sc.initial.items()}
    est = make_estimator("coupled", cfg, sc.radar_ids)
    keys = list(sc.initial)
    kf = KalmanFilter(dim_x=12, dim_z=2)
    kf.x = np.concatenate([mean[k] for k in keys] + [np.zeros(4)])
    kf.P = np.zeros((12, 12))
    for i, k in enumerate(keys):
        est.add_aircraft(k, 0.0, mean[k], P0)
        kf.P[4 * i:4 * i + 4, 4 * i:4 * i + 4] = P0
    kf.P[8:10, 8:10] = kf.P[10:12, 10:12] = cfg.bias_prior()
    t = 0.0
    for m in sc.measurements:
        A, Q = cfg.motion.transition(m.time - t)
        F, Qf = np.eye(12), np.zeros((12, 12))
        for i in range(2):
            F[4 * i:4 * i + 4, 4 * i:4 * i + 4] = A
            Qf[4 * i:4 * i + 4, 4 * i:4 * i + 4] = Q
        if t > 0.0:  # the filter's bias epoch starts at its first measurement
            Qf[8:10, 8:10] = Qf[10:12, 10:12] = cfg.bias_drift(m.time - t)
        kf.predict(F=F, Q=Qf)
        t = m.time
        H = np.zeros((2, 12))
        i = keys.index(m.aircraft)
        H[:, 4 * i:4 * i + 2] = np.eye(2)
        if m.radar is not None:
            j = sc.radar_ids.index(m.radar)
            H[:, 8 + 2 * j:10 + 2 * j] = m.C
        kf.update(m.z, R=m.R, H=H)
        est.update(m)
        ac = est.aircraft(m.aircraft)
        np.testing.assert_allclose(ac.state, kf.x[4 * i:4 * i + 4], rtol=1e-9, atol=1e-7)
        np.testing.assert_allclose(ac.cov, kf.P[4 * i:4 * i + 4, 4 * i:4 * i + 4], rtol=1e-9, atol=1e-9)
        for j, r in enumerate(sc.radar_ids):
            b = est.bias(r)
            np.testing.assert_allclose(b.bias, kf.x[8 + 2 * j:10 + 2 * j], rtol=1e-9, atol=1e-12)
            np.testing.assert_allclose(b.cov, kf.P[8 + 2 * j:10 + 2 * j, 8 + 2 * j:10 + 2 * j],
                                       rtol=1e-9, atol=1e-15)


def test_removing_an_aircraft_marginalises_it():
    """Removing aircraft X equals keeping X unobserved; a new aircraft may reuse X's slot."""
    sc = make_linear_scenario(n_aircraft=5, n_radars=3, duration=120.0, rng=5, adsb_aircraft=1)
    cfg = EstimatorConfig()
    P0 = np.diag([500.0**2, 500.0**2, 30.0**2, 30.0**2])
    gone, t_cut = "A0001", 60.0
    kept = make_estimator("coupled", cfg, sc.radar_ids)
    removed = make_estimator("coupled", cfg, sc.radar_ids)
    for est in (kept, removed):
        for k, x in sc.initial.items():
            est.add_aircraft(k, 0.0, x, P0)
    late = np.array([1.0, 2.0, 3.0, 4.0])
    for m in sc.measurements:
        if m.aircraft == gone and m.time >= t_cut:
            if gone in removed.aircraft_keys:
                removed.remove_aircraft(gone)
                for est in (kept, removed):  # a newcomer; in `removed` it takes the freed slot
                    est.add_aircraft("NEW", m.time, sc.truth[gone][m.time] + late, P0)
            continue
        for est in (kept, removed):
            est.update(m)
    assert gone not in removed.aircraft_keys and gone in kept.aircraft_keys
    for r in sc.radar_ids:
        a, b = kept.bias(r), removed.bias(r)
        np.testing.assert_allclose(b.bias, a.bias, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(b.cov, a.cov, rtol=1e-9, atol=1e-15)
    for k in removed.aircraft_keys:
        np.testing.assert_allclose(removed.aircraft(k).state, kept.aircraft(k).state, rtol=1e-9)
        np.testing.assert_allclose(removed.aircraft(k).cov, kept.aircraft(k).cov, rtol=1e-9)


def _nees(e: np.ndarray, P: np.ndarray) -> float:
    return float(e @ np.linalg.solve(P, e))


def monte_carlo_anees(runs: int, seed0: int = 100) -> dict[str, tuple[float, float, int]]:
    """(joint ANEES, bias ANEES, joint dof) per estimator over ``runs`` linear scenarios.

    Priors are drawn consistently: the prior mean is the truth plus a draw from the prior
    covariance, biases come from the bias prior. NEES is taken at the end of each run.
    """
    cfg = EstimatorConfig(motion=MotionModel(0.1))
    P0 = np.diag([300.0**2, 300.0**2, 20.0**2, 20.0**2])
    out = {name: ([], []) for name in ("coupled", "blom", "decoupled")}
    dof = 0
    for r in range(runs):
        sc = make_linear_scenario(n_aircraft=5, n_radars=3, duration=90.0, rng=seed0 + r,
                                  adsb_aircraft=1, q=0.1)
        rng = np.random.default_rng(10_000 + r)
        mean = {k: x + rng.normal(size=4) * np.sqrt(np.diag(P0)) for k, x in sc.initial.items()}
        for name, (joint, bias) in out.items():
            est = _run(name, sc, cfg, mean, P0)
            e_b = np.concatenate([est.bias(rr).bias - sc.biases[j] for j, rr in enumerate(sc.radar_ids)])
            if name == "coupled":
                keys = list(sc.initial)
                x, P = est.joint(keys)
                truth = np.concatenate([sc.truth[k][est.aircraft(k).time] for k in keys] + [sc.biases.ravel()])
                joint.append(_nees(x - truth, P))
                dof = len(truth)
                P_b = P[-e_b.size:, -e_b.size:]
            else:  # these keep no cross-covariances: joint NEES from the diagonal blocks
                nees_x = sum(_nees(est.aircraft(k).state - sc.truth[k][est.aircraft(k).time], est.aircraft(k).cov)
                             for k in sc.initial)
                P_b = block_diag(*[est.bias(rr).cov for rr in sc.radar_ids])
                joint.append(nees_x + _nees(e_b, P_b))
            bias.append(_nees(e_b, P_b))
    return {name: (float(np.mean(j)), float(np.mean(b)), dof) for name, (j, b) in out.items()}


def _assert_consistent(runs: int) -> None:
    res = monte_carlo_anees(runs)
    anees, anees_b, dof = res["coupled"]
    lo, hi = chi2.ppf([0.025, 0.975], runs * dof) / runs
    lo_b, hi_b = chi2.ppf([0.025, 0.975], runs * 6) / runs
    for name, (a, b, _) in res.items():
        print(f"{name:10s} ANEES joint {a:8.2f} (95% [{lo:.2f}, {hi:.2f}] for dof {dof})  "
              f"bias {b:8.2f} (95% [{lo_b:.2f}, {hi_b:.2f}] for dof 6)")
    assert lo <= anees <= hi
    assert lo_b <= anees_b <= hi_b
    # the simplified filters are optimistic about their biases: shown, not hidden
    assert res["decoupled"][1] > hi_b


def test_coupled_anees_within_chi2_bounds_quick():
    _assert_consistent(runs=12)


@pytest.mark.slow
def test_coupled_anees_within_chi2_bounds_monte_carlo():
    _assert_consistent(runs=60)


@settings(max_examples=8, deadline=None)
@given(seed=st.integers(0, 10_000), n=st.integers(1, 6), m=st.integers(1, 4), q=st.sampled_from([0.0, 1.0]))
def test_joint_covariance_stays_symmetric_psd_and_finite(seed, n, m, q):
    sc = make_linear_scenario(n_aircraft=n, n_radars=m, duration=60.0, rng=seed, adsb_aircraft=n // 2, q=q)
    est = make_estimator("coupled", EstimatorConfig(motion=MotionModel(q)), sc.radar_ids)
    for k, x in sc.initial.items():
        est.add_aircraft(k, 0.0, x, np.diag([1e8, 1e8, 1e4, 1e4]))
    for meas in sc.measurements:
        est.update(meas)
    x, P = est.joint()
    assert np.isfinite(x).all() and np.isfinite(P).all()
    d = np.sqrt(np.diag(P))
    corr = P / np.outer(d, d)
    np.testing.assert_allclose(corr, corr.T, atol=1e-12)
    assert np.linalg.eigvalsh(0.5 * (corr + corr.T))[0] > -1e-9
