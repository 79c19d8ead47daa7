"""Compiled filter kernels against FilterPy and against the numpy equations they replace."""

import math

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter

from radartracker.estimation.motion import MotionModel
from radartracker.tracking import kernels
from radartracker_plugins.motion.ct import ct_noise, ct_transition


def spd(rng, n, scale):
    A = rng.normal(size=(n, n)) * scale
    return A @ A.T + np.eye(n) * scale**2


@pytest.mark.parametrize("seed", range(5))
def test_cv_predict_update_match_filterpy(seed):
    rng = np.random.default_rng(seed)
    x, P = rng.normal(size=4) * [1e4, 1e4, 200, 200], spd(rng, 4, 50.0)
    z, R = x[:2] + rng.normal(size=2) * 100, spd(rng, 2, 80.0)
    dt, q = float(rng.uniform(-2, 12)), float(rng.uniform(0, 20))
    kf = KalmanFilter(dim_x=4, dim_z=2)
    A, Q = MotionModel(q).transition(dt)
    kf.x, kf.P, kf.F, kf.Q, kf.R = x.copy(), P.copy(), A, Q, R
    kf.H = np.eye(2, 4)
    kf.predict()
    xp, Pp = kernels.cv_predict(x, P, dt, q)
    np.testing.assert_allclose(xp, kf.x, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(Pp, kf.P, rtol=1e-12, atol=1e-9)
    kf.update(z)
    xn, Pn, nu, S, nis, loglik, ok = kernels.position_update(xp, Pp, z, R)
    assert ok
    np.testing.assert_allclose(xn, kf.x, rtol=1e-10, atol=1e-8)
    np.testing.assert_allclose(Pn, kf.P, rtol=1e-9, atol=1e-8)
    np.testing.assert_allclose(S, kf.S, rtol=1e-12)
    assert nis == pytest.approx(float(kf.y @ np.linalg.solve(kf.S, kf.y)), rel=1e-10)
    assert loglik == pytest.approx(kf.log_likelihood, rel=1e-10)


@pytest.mark.parametrize("w", [0.0, 3e-6, 0.03, -0.05])
def test_ct_predict_matches_numpy(w):
    rng = np.random.default_rng(7)
    x = np.array([1e4, -2e4, 150.0, -180.0, w])
    P = spd(rng, 5, 1.0) + np.diag([1e4, 1e4, 100, 100, 0])
    for T in (0.0, 0.5, 4.0, -3.0):
        f, F = ct_transition(x, T)
        xp, Pp = kernels.ct_predict(x, P, T, 5.0, 0.01)
        np.testing.assert_allclose(xp, f, rtol=1e-13, atol=1e-9)
        np.testing.assert_allclose(Pp, F @ P @ F.T + ct_noise(T, 5.0, 0.01), rtol=1e-11, atol=1e-9)


def test_singular_innovation_and_bad_measurements_are_flagged():
    P = np.zeros((4, 4))
    assert not kernels.position_update(np.zeros(4), P, np.zeros(2), np.zeros((2, 2)))[-1]
    ok = np.eye(2)
    assert kernels.measurement_ok(1.0, np.zeros(2), ok) == 0
    assert kernels.measurement_ok(math.nan, np.zeros(2), ok) == 1
    assert kernels.measurement_ok(1.0, np.array([0.0, math.inf]), ok) == 2
    assert kernels.measurement_ok(1.0, np.zeros(2), np.array([[1.0, 0.5], [0.0, 1.0]])) == 3
    assert kernels.measurement_ok(1.0, np.zeros(2), np.array([[1.0, 2.0], [2.0, 1.0]])) == 3
    assert kernels.measurement_ok(1.0, np.zeros(2), -ok) == 3


def test_moment_match_equals_the_numpy_sums():
    rng = np.random.default_rng(3)
    w = rng.dirichlet(np.ones(3))
    X = rng.normal(size=(3, 5)) * 100
    P = np.array([spd(rng, 5, 10.0) for _ in range(3)])
    x, C = kernels.moment_match(w, X, P)
    x_ref = sum(wi * xi for wi, xi in zip(w, X))
    C_ref = sum(wi * (Pi + np.outer(xi - x_ref, xi - x_ref)) for wi, xi, Pi in zip(w, X, P))
    np.testing.assert_allclose(x, x_ref, rtol=1e-14, atol=1e-12)
    np.testing.assert_allclose(C, 0.5 * (C_ref + C_ref.T), rtol=1e-13, atol=1e-10)
