"""Track filters cv / adaptive / fading against FilterPy, a root-finder, χ² bounds and pickling."""

from __future__ import annotations

import pickle

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter
from scipy.optimize import brentq
from scipy.stats import chi2

from radartracker.estimation.motion import MotionModel
from radartracker.registry import available_motion_models, load_motion_model
from radartracker_plugins.motion import (AdaptiveConfig, AdaptiveFilter, CVConfig, CVFilter, FadingConfig, FadingFilter,
                                         IMMConfig, IMMFilter)


def cv_track(rng, n=60, q=1.0, x0=(1e4, -2e4, 150.0, -80.0)):
    """CV truth with white-acceleration density q, irregular Δt, and noisy positions with varying R."""
    t = np.cumsum(rng.uniform(0.5, 8.0, n))
    t -= t[0]
    x = np.array(x0, float)
    truth, zs, Rs = [x.copy()], [], []
    for k in range(1, n):
        A, Q = MotionModel(q).transition(t[k] - t[k - 1])
        x = A @ x + rng.multivariate_normal(np.zeros(4), Q)
        truth.append(x.copy())
    for x in truth:
        L = rng.normal(0, 1, (2, 2)) * 60.0
        R = L @ L.T + 30.0**2 * np.eye(2)
        Rs.append(R)
        zs.append(rng.multivariate_normal(x[:2], R))
    return t, np.array(truth), np.array(zs), np.array(Rs)


def filterpy_run(t, zs, Rs, q, prior_sd_v=300.0, alpha_sq=1.0):
    """FilterPy's KalmanFilter on the same data; (states, covariances, NIS) after each update."""
    kf = KalmanFilter(dim_x=4, dim_z=2)
    kf.x = np.concatenate([zs[0], [0.0, 0.0]])
    kf.P = np.diag([0.0, 0.0, prior_sd_v**2, prior_sd_v**2])
    kf.P[:2, :2] = Rs[0]
    kf.H = np.hstack([np.eye(2), np.zeros((2, 2))])
    kf._alpha_sq = alpha_sq  # FilterPy's setter refuses α < 1; predict uses P = α² F P Fᵀ + Q
    xs, Ps, nis = [], [], []
    for k in range(1, len(t)):
        kf.F, Q = MotionModel(q).transition(t[k] - t[k - 1])
        kf.Q = Q
        kf.predict()
        kf.R = Rs[k]
        kf.update(zs[k])
        xs.append(kf.x.copy())
        Ps.append(kf.P.copy())
        nis.append(float(kf.y @ np.linalg.solve(kf.S, kf.y)))
    return np.array(xs), np.array(Ps), np.array(nis)


def run(f, t, zs, Rs):
    f.start(t[0], zs[0], Rs[0])
    xs, Ps, nis = [], [], []
    for k in range(1, len(t)):
        nis.append(f.update(t[k], zs[k], Rs[k]))
        _, x, P = f.estimate()
        xs.append(x)
        Ps.append(P)
    return np.array(xs), np.array(Ps), np.array(nis)


def assert_close(a, b):
    for u, v in zip(a, b):
        np.testing.assert_allclose(u, v, rtol=1e-9, atol=1e-9)


def test_plugins_registered():
    assert {"cv", "imm", "adaptive", "fading"} <= set(available_motion_models())
    assert load_motion_model("cv") is CVFilter and load_motion_model("imm") is IMMFilter
    assert load_motion_model("adaptive") is AdaptiveFilter and load_motion_model("fading") is FadingFilter


@pytest.mark.parametrize("q", [0.0, 1.0, 25.0])
def test_cv_equals_filterpy(q):
    t, _, zs, Rs = cv_track(np.random.default_rng(1), q=q)
    ours = run(CVFilter(CVConfig(q=q)), t, zs, Rs)
    assert_close(ours, filterpy_run(t, zs, Rs, q))


def test_predict_does_not_change_state_and_matches_update_prior():
    t, _, zs, Rs = cv_track(np.random.default_rng(2), n=10)
    for name in available_motion_models():
        f = load_motion_model(name)()
        f.start(t[0], zs[0], Rs[0])
        f.update(t[1], zs[1], Rs[1])
        before = pickle.dumps(f)
        x1, P1 = f.predict(t[2])
        x2, P2 = f.predict(t[2])
        assert pickle.dumps(f) == before
        np.testing.assert_array_equal(x1, x2)
        np.testing.assert_array_equal(P1, P2)
        nu = zs[2] - x1[:2]
        assert f.update(t[2], zs[2], Rs[2]) == pytest.approx(nu @ np.linalg.solve(P1[:2, :2] + Rs[2], nu), rel=1e-9)


@pytest.mark.parametrize("alpha", [1.0, 0.7])
def test_adaptive_fixed_alpha_equals_filterpy(alpha):
    """P̄ = α P_a + (1−α) Q_m is FilterPy's fading-memory predict with alpha² = α and Q = (1−α) Q_m."""
    qm = 40.0
    t, _, zs, Rs = cv_track(np.random.default_rng(3), q=2.0)
    f = AdaptiveFilter(AdaptiveConfig(fixed_alpha=alpha, q_manoeuvre=qm))
    ours = run(f, t, zs, Rs)
    assert_close(ours, filterpy_run(t, zs, Rs, (1 - alpha) * qm, alpha_sq=alpha))
    if alpha == 1.0:  # α = 1, β = 0: constant velocity without process noise
        assert_close(ours, run(CVFilter(CVConfig(q=0.0)), t, zs, Rs))


def test_fading_fixed_lambda_equals_filterpy():
    t, _, zs, Rs = cv_track(np.random.default_rng(4), q=2.0)
    ours = run(FadingFilter(FadingConfig(q=2.0, fixed_lambda=1.08)), t, zs, Rs)
    assert_close(ours, filterpy_run(t, zs, Rs, 2.0, alpha_sq=1.08))


def manoeuvre_track(rng, n=80):
    """Straight, then a 2 g sideways acceleration for 40 s, then straight; Δt 4 s, σ 50 m."""
    t = 4.0 * np.arange(n)
    x = np.array([0.0, 0.0, 200.0, 0.0])
    truth = []
    for k in range(n):
        truth.append(x.copy())
        acc = np.array([0.0, 20.0]) if 30 <= k < 40 else np.zeros(2)
        x = x + np.concatenate([4.0 * x[2:] + 8.0 * acc, 4.0 * acc])
    R = 50.0**2 * np.eye(2)
    zs = np.array([rng.multivariate_normal(s[:2], R) for s in truth])
    return t, np.array(truth), zs, np.repeat(R[None], n, axis=0)


def reference_scaled(kind, params, t, zs, Rs, q_nominal):
    """The documented NIS-window rule, with θ found by brentq and the filtering done by FilterPy."""
    N, p = params["window"], params["significance"]
    lo, hi = chi2.ppf(p / 2, 2 * N), chi2.ppf(1 - p / 2, 2 * N)
    kf = KalmanFilter(dim_x=4, dim_z=2)
    kf.x = np.concatenate([zs[0], [0.0, 0.0]])
    kf.P = np.diag([Rs[0][0, 0], Rs[0][1, 1], 300.0**2, 300.0**2])
    kf.H = np.hstack([np.eye(2), np.zeros((2, 2))])
    kappa, window, thetas, xs = 1.0, [], [], []
    for k in range(1, len(t)):
        A, Q = MotionModel(q_nominal).transition(t[k] - t[k - 1])
        Pa = A @ kf.P @ A.T
        if kind == "adaptive":
            lo_th, hi_th, nominal = params["beta_min"], 1.0, params["beta_min"]
            fam = lambda th: (1 - th) * Pa + th * Q  # noqa: E731
        else:
            lo_th, hi_th, nominal = 1.0, 1e6, 1.0
            fam = lambda th: th * Pa + Q  # noqa: E731
        r = np.trace(Rs[k - 1])
        target = kappa * (np.trace(fam(nominal)[:2, :2]) + r)
        g = lambda th: np.trace(fam(th)[:2, :2]) + r - target  # noqa: E731
        if kappa == 1.0:
            th = nominal
        elif g(lo_th) * g(hi_th) > 0:
            th = lo_th if abs(g(lo_th)) < abs(g(hi_th)) else hi_th
        else:
            th = brentq(g, lo_th, hi_th, xtol=1e-14, rtol=1e-14)
        thetas.append(th)
        kf.F = A
        kf._alpha_sq, kf.Q = (1 - th, th * Q) if kind == "adaptive" else (th, Q)
        kf.predict()
        kf.R = Rs[k]
        kf.update(zs[k])
        xs.append(kf.x.copy())
        window.append(float(kf.y @ np.linalg.solve(kf.S, kf.y)))
        if len(window) == N:
            s = sum(window)
            window = []
            if not lo <= s <= hi:
                kappa = min(max(kappa * s / (2 * N), 1.0), 100.0)
    return np.array(thetas), np.array(xs)


@pytest.mark.parametrize("kind", ["adaptive", "fading"])
def test_window_rule_matches_reference(kind):
    t, _, zs, Rs = manoeuvre_track(np.random.default_rng(5))
    params = {"window": 4, "significance": 0.05, "beta_min": 0.02, "q_manoeuvre": 400.0}
    window = {k: params[k] for k in ("window", "significance")}
    f = (AdaptiveFilter(AdaptiveConfig(beta_min=params["beta_min"], q_manoeuvre=params["q_manoeuvre"], **window))
         if kind == "adaptive" else FadingFilter(FadingConfig(q=1.0, **window)))
    f.start(t[0], zs[0], Rs[0])
    thetas, xs = [], []
    for k in range(1, len(t)):
        f.update(t[k], zs[k], Rs[k])
        thetas.append(f.theta)
        xs.append(f.estimate()[1])
    ref_th, ref_x = reference_scaled(kind, params, t, zs, Rs, 400.0 if kind == "adaptive" else 1.0)
    np.testing.assert_allclose(thetas, ref_th, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(xs, ref_x, rtol=1e-9, atol=1e-6)
    # the manoeuvre is detected: the parameter leaves its nominal value during it, not before
    assert np.all(np.array(thetas[:28]) == (0.02 if kind == "adaptive" else 1.0))
    assert (np.max(thetas) > 0.5) if kind == "adaptive" else (np.max(thetas) > 1.5)


def test_negative_beta_keeps_covariance_positive_definite():
    """With β < 0 allowed, inflation comes from α > 1 and P̄ must stay positive definite."""
    t, _, zs, Rs = manoeuvre_track(np.random.default_rng(6))
    f = AdaptiveFilter(AdaptiveConfig(allow_negative_beta=True, q_manoeuvre=5.0, window=3))
    f.start(t[0], zs[0], Rs[0])
    betas = []
    for k in range(1, len(t)):
        f.update(t[k], zs[k], Rs[k])
        a, b = f.alpha_beta
        assert a + b == pytest.approx(1.0)
        betas.append(b)
        np.linalg.cholesky(f.predict(t[k] + 4.0)[1])
        np.linalg.cholesky(f.estimate()[2])
    assert min(betas) < 0.0


def nees_nis_runs(runs, n, seed):
    """CV filter on CV truth (matched q): per-step NEES and NIS over ``runs`` Monte Carlo runs."""
    nees, nis = np.zeros((runs, n - 1)), np.zeros((runs, n - 1))
    for r in range(runs):
        rng = np.random.default_rng([seed, r])
        # the initial velocity is drawn from the filter's prior N(0, σ_v² I), so NEES is χ² from the start
        t, truth, zs, Rs = cv_track(rng, n=n, q=4.0, x0=(1e4, -2e4, *rng.normal(0.0, 300.0, 2)))
        xs, Ps, ni = run(CVFilter(CVConfig(q=4.0)), t, zs, Rs)
        e = xs - truth[1:]
        nees[r] = np.einsum("ni,ni->n", e, np.linalg.solve(Ps, e[..., None])[..., 0])
        nis[r] = ni
    return nees, nis


def check_consistency(nees, nis, min_inside):
    runs = len(nees)
    for values, dof in ((nees, 4), (nis, 2)):
        total = values.sum(axis=0)
        lo, hi = chi2.ppf(0.025, dof * runs), chi2.ppf(0.975, dof * runs)
        inside = np.mean((total >= lo) & (total <= hi))
        assert inside >= min_inside, (dof, inside)
        # the grand total over all steps is inside its own 99 % interval
        g = values.sum()
        assert chi2.ppf(0.005, dof * values.size) <= g <= chi2.ppf(0.995, dof * values.size)


def test_cv_nees_nis_consistent():
    nees, nis = nees_nis_runs(runs=12, n=40, seed=7)
    check_consistency(nees, nis, min_inside=0.85)


@pytest.mark.slow
def test_cv_nees_nis_consistent_long():
    nees, nis = nees_nis_runs(runs=200, n=80, seed=8)
    check_consistency(nees, nis, min_inside=0.9)


@pytest.mark.parametrize("name", ["cv", "imm", "adaptive", "fading"])
def test_hygiene_and_pickle(name):
    """Covariances stay symmetric positive definite and finite; a pickled filter continues identically."""
    t, _, zs, Rs = manoeuvre_track(np.random.default_rng(9))
    f = load_motion_model(name)()
    f.start(t[0], zs[0], Rs[0])
    for k in range(1, len(t)):
        if k == len(t) // 2:
            g = pickle.loads(pickle.dumps(f))
        nis = f.update(t[k], zs[k], Rs[k])
        assert np.isfinite(nis)
        _, x, P = f.estimate()
        assert np.all(np.isfinite(x)) and np.array_equal(P, P.T)
        np.linalg.cholesky(P)
    for k in range(len(t) // 2, len(t)):
        g.update(t[k], zs[k], Rs[k])
    assert all(np.array_equal(a, b) for a, b in zip(f.estimate(), g.estimate()))
    # repeated plots at one time (two radars in the same instant) are fine
    f.update(t[-1], zs[-1], Rs[-1])
    np.linalg.cholesky(f.estimate()[2])


@pytest.mark.parametrize("name", ["cv", "imm", "adaptive", "fading"])
def test_bad_input_raises(name):
    f = load_motion_model(name)()
    with pytest.raises(ValueError, match="not started"):
        f.predict(1.0)
    f.start(0.0, np.zeros(2), np.eye(2))
    for z, R in ((np.array([np.nan, 0.0]), np.eye(2)), (np.zeros(3), np.eye(2)),
                 (np.zeros(2), -np.eye(2)), (np.zeros(2), np.array([[1.0, 2.0], [0.0, 1.0]]))):
        with pytest.raises(ValueError):
            f.update(1.0, z, R)
    before = pickle.dumps(f)
    for t in (float("inf"), float("nan"), 1e12, -1e12):
        with pytest.raises(ValueError, match="time"):
            f.update(t, np.zeros(2), np.eye(2))
    assert pickle.dumps(f) == before
    np.linalg.cholesky(f.estimate()[2])


@pytest.mark.parametrize("name", ["cv", "imm", "adaptive", "fading"])
def test_longest_accepted_gap_keeps_covariance_positive_definite(name):
    """An update max_gap_s (one hour) after the last, then normal updates: P stays PD and finite."""
    config = {"cv": CVConfig(q=400.0), "imm": IMMConfig(q=400.0, q_turn=400.0), "adaptive": AdaptiveConfig(),
              "fading": FadingConfig(q=400.0)}[name]
    f = load_motion_model(name)(config)
    f.start(0.0, np.zeros(2), 50.0**2 * np.eye(2))
    f.update(4.0, np.array([800.0, 0.0]), 50.0**2 * np.eye(2))
    for t in (3604.0, 3608.0, 3612.0, 7212.0):
        f.update(t, np.array([7e5, 1e3]), 50.0**2 * np.eye(2))
        _, x, P = f.estimate()
        assert np.all(np.isfinite(x))
        np.linalg.cholesky(P)
