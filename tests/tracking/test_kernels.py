"""Compiled filter kernels against FilterPy and against the numpy equations they replace (the IMM
cycle against the plain numpy IMM equations, scipy's expm and multivariate normal)."""

import math

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter
from scipy.linalg import expm
from scipy.stats import multivariate_normal

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


# --- the IMM cycle against the plain numpy IMM equations (plugins/motion/imm.py module docstring) ---

def switching_matrix(tau, dt):
    """Π(Δt) = exp(G|Δt|), G_ii = −1/τ_i, the leaving rate shared equally among the other modes."""
    n = len(tau)
    G = np.ones((n, n)) / ((n - 1) * np.asarray(tau, float)[:, None])
    np.fill_diagonal(G, -1.0 / np.asarray(tau, float))
    return expm(G * abs(dt))


def imm_prediction(mu, xs, Ps, Pi, modes, dt, entry_var):
    """c̄, each mode's prediction from its mixed initial condition, and the predicted mixture.
    ``xs``/``Ps``: each mode's own-size state; ``modes``: ("cv", q) or ("ct", q, σ_ω)."""
    n, D = len(mu), max(len(x) for x in xs)
    padded = []
    for x, P in zip(xs, Ps):
        xp, Pp = np.zeros(D), np.zeros((D, D))
        xp[:len(x)], Pp[:len(x), :len(x)] = x, P
        if len(x) < D:
            Pp[4, 4] = entry_var
        padded.append((xp, Pp))
    cbar = mu @ Pi
    preds = []
    for j, mode in enumerate(modes):
        w = Pi[:, j] * mu / cbar[j] if cbar[j] > 0 else np.eye(n)[j]
        x0 = sum(wi * x for wi, (x, _) in zip(w, padded))
        P0 = sum(wi * (P + np.outer(x - x0, x - x0)) for wi, (x, P) in zip(w, padded))
        if mode[0] == "cv":
            A, Q = MotionModel(mode[1]).transition(dt)
            preds.append((A @ x0[:4], A @ P0[:4, :4] @ A.T + Q))
        else:
            f, F = ct_transition(x0, dt)
            preds.append((f, F @ P0 @ F.T + ct_noise(dt, mode[1], mode[2])))
    x_bar = sum(c * x[:4] for c, (x, _) in zip(cbar, preds))
    P_bar = sum(c * (P[:4, :4] + np.outer(x[:4] - x_bar, x[:4] - x_bar)) for c, (x, P) in zip(cbar, preds))
    return cbar, preds, x_bar, P_bar


def imm_correction(cbar, preds, x_bar, P_bar, z, R):
    """Each mode's Kalman correction, μ_j ∝ c̄_j N(ν_j; 0, Λ_j), the moment-matched output and the
    combined prediction's NIS."""
    states, loglik = [], []
    for x, P in preds:
        H = np.eye(2, len(x))
        S = H @ P @ H.T + R
        K = P @ H.T @ np.linalg.inv(S)
        states.append((x + K @ (z - H @ x), (np.eye(len(x)) - K @ H) @ P))
        loglik.append(multivariate_normal(H @ x, S).logpdf(z))
    w = np.log(cbar) + np.array(loglik)
    mu = np.exp(w - w.max()) / np.exp(w - w.max()).sum()
    x = sum(m * s[:4] for m, (s, _) in zip(mu, states))
    P = sum(m * (C[:4, :4] + np.outer(s[:4] - x, s[:4] - x)) for m, (s, C) in zip(mu, states))
    nu = z - x_bar[:2]
    return mu, states, x, P, float(nu @ np.linalg.solve(P_bar[:2, :2] + R, nu))


def correlated(rng, variances):
    """A covariance with these variances and random correlations."""
    C = spd(rng, len(variances), 1.0)
    sd = np.sqrt(variances / np.diag(C))
    return C * sd[:, None] * sd[None, :]


def kernel_chain(tau):
    """(λ, L, R) of G = L diag(λ) R as IMMFilter builds it (symmetric form D^½ B D^½)."""
    n = len(tau)
    B = (np.ones((n, n)) - n * np.eye(n)) / (n - 1)
    d = np.sqrt(1.0 / np.asarray(tau, float))
    lam, U = np.linalg.eigh(d[:, None] * B * d[None, :])
    return np.minimum(lam, 0.0), np.ascontiguousarray(d[:, None] * U), np.ascontiguousarray(U.T / d[None, :])


MODE_SETS = {"cv+ct": [("cv", 2.0), ("ct", 1.5, 0.01)],
             "cv+ct+cv": [("cv", 0.5), ("ct", 3.0, 0.02), ("cv", 80.0)],
             "cv+cv": [("cv", 0.5), ("cv", 150.0)]}


@pytest.mark.parametrize("modes", MODE_SETS)
@pytest.mark.parametrize("seed", range(3))
def test_imm_cycle_equals_the_numpy_equations(modes, seed):
    rng = np.random.default_rng(seed)
    modes = MODE_SETS[modes]
    n, entry_var = len(modes), 0.035**2
    dims = np.array([4 if m[0] == "cv" else 5 for m in modes])
    D = dims.max()
    tau = rng.uniform(10, 150, n)
    mu = rng.dirichlet(np.ones(n))
    xs = [np.concatenate([rng.normal(size=2) * 1e4, rng.normal(size=2) * 200, rng.normal(size=d - 4) * 0.03])
          for d in dims]
    Ps = [correlated(rng, np.array([1e4, 1e4, 400, 400, 1e-4][:d])) for d in dims]
    X, PP = np.zeros((n, D)), np.zeros((n, D, D))
    for j, d in enumerate(dims):
        X[j, :d], PP[j, :d, :d] = xs[j], Ps[j]
        if d < D:
            PP[j, 4, 4] = entry_var
    z, R = xs[0][:2] + rng.normal(size=2) * 300, spd(rng, 2, 80.0)
    dt = float(rng.uniform(0.5, 12))
    chain = kernel_chain(tau)
    np.testing.assert_allclose(kernels.markov_switching(*chain, dt), switching_matrix(tau, dt), rtol=1e-12, atol=1e-14)
    kmodes = np.array([[0.0 if m[0] == "cv" else 1.0, m[1], m[2] if len(m) > 2 else 0.0] for m in modes])
    ref_cbar, ref_preds, ref_xb, ref_Pb = imm_prediction(mu, xs, Ps, switching_matrix(tau, dt), modes, dt, entry_var)
    pred = (np.zeros(n), np.zeros((n, D)), np.zeros((n, D, D)), np.zeros(4), np.zeros((4, 4)))
    kernels.imm_predict(mu, X, PP, *chain, kmodes, dt, *pred)
    np.testing.assert_allclose(pred[0], ref_cbar, rtol=1e-12)
    for j, d in enumerate(dims):
        np.testing.assert_allclose(pred[1][j, :d], ref_preds[j][0], rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose(pred[2][j, :d, :d], ref_preds[j][1], rtol=1e-10, atol=1e-9)
    np.testing.assert_allclose(pred[3], ref_xb, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(pred[4], ref_Pb, rtol=1e-10, atol=1e-9)

    ref_mu, ref_states, ref_x, ref_P, ref_nis = imm_correction(ref_cbar, ref_preds, ref_xb, ref_Pb, z, R)
    out = (mu.copy(), X.copy(), PP.copy(), np.zeros(4), np.zeros((4, 4)))
    nis, bad = kernels.imm_correct(*pred, dims, entry_var, z, R, *out)
    assert bad == -2 and nis == pytest.approx(ref_nis, rel=1e-10)
    np.testing.assert_allclose(out[0], ref_mu, rtol=1e-9, atol=1e-14)
    for j, d in enumerate(dims):
        np.testing.assert_allclose(out[1][j, :d], ref_states[j][0], rtol=1e-12, atol=1e-8)
        np.testing.assert_allclose(out[2][j, :d, :d], ref_states[j][1], rtol=1e-8, atol=1e-8)
        if d < D:  # a 4-state mode carries ω = 0 ± σ_e into the next mixing
            assert out[1][j, 4] == 0.0 and out[2][j, 4, 4] == entry_var and not out[2][j, 4, :4].any()
    np.testing.assert_allclose(out[3], ref_x, rtol=1e-12, atol=1e-8)
    np.testing.assert_allclose(out[4], ref_P, rtol=1e-8, atol=1e-8)

    whole = (mu.copy(), X.copy(), PP.copy())  # imm_cycle: the same in one call
    res = kernels.imm_cycle(*whole, *chain, kmodes, dims, entry_var, dt, z, R, np.zeros(4), np.zeros((4, 4)),
                            *(np.zeros_like(a) for a in pred))
    assert res == (nis, -2)
    for a, b in zip(whole, out):
        np.testing.assert_array_equal(a, b)


def test_imm_mixing_with_an_unreachable_mode_and_a_singular_update():
    """c̄_j = 0 (no mode switches into j): mode j keeps its own state (ω = e_j); a singular Λ leaves
    the state as it was and names the combined prediction (−1)."""
    rng = np.random.default_rng(9)
    mu, Pi = np.array([0.6, 0.4]), np.array([[1.0, 0.0], [1.0, 0.0]])
    X, PP = rng.normal(size=(2, 4)) * 100, np.array([spd(rng, 4, 20.0) for _ in range(2)])
    cbar, X0, P0 = kernels.imm_mix(mu, X, PP, Pi)
    np.testing.assert_allclose(cbar, [1.0, 0.0])
    np.testing.assert_array_equal(X0[1], X[1])
    np.testing.assert_allclose(P0[1], 0.5 * (PP[1] + PP[1].T), rtol=1e-15)
    state = (mu.copy(), X.copy(), PP.copy(), np.ones(4), np.eye(4))
    pred = (np.array([0.5, 0.5]), X.copy(), np.zeros((2, 4, 4)), X[0].copy(), np.zeros((4, 4)))
    nis, bad = kernels.imm_correct(*pred, np.array([4, 4]), 0.0, np.zeros(2), np.zeros((2, 2)), *state)
    assert math.isnan(nis) and bad == -1
    for a, b in zip(state, (mu, X, PP, np.ones(4), np.eye(4))):
        np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("switching", ["sojourn", "fixed"])
@pytest.mark.parametrize("modes", MODE_SETS)
def test_packed_imm_kernels_equal_the_array_kernels(modes, switching):
    """imm_advance / imm_update / imm_screen on one packed buffer give, bit for bit, imm_predict,
    imm_correct, imm_cycle on separate arrays and screening's bias correction and d²; a measurement
    outside the gate or failing the checks leaves the state as it was; the buffer's settings are never
    written (a fixed Π: an empty λ and a 0×0 R)."""
    from radartracker.estimation.screening import bias_corrected, normalised_innovation

    rng = np.random.default_rng(11)
    modes = MODE_SETS[modes]
    n, entry_var = len(modes), 0.035**2
    dims = np.array([4 if m[0] == "cv" else 5 for m in modes])
    D = dims.max()
    if switching == "sojourn":
        chain = kernel_chain(rng.uniform(10, 150, n))
    else:
        Pi = rng.uniform(0.05, 1.0, (n, n))
        chain = (np.zeros(0), Pi / Pi.sum(axis=1, keepdims=True), np.zeros((0, 0)))
    kmodes = np.array([[0.0 if m[0] == "cv" else 1.0, m[1], m[2] if len(m) > 2 else 0.0] for m in modes])
    buf = kernels.imm_buffer(kmodes, dims, entry_var, *chain, 60.0)
    header = [n, D, entry_var, len(chain[0]), 60.0, np.nan, np.nan, 1.0, 0.0]  # not started, compiled
    settings = np.concatenate([header, kmodes.ravel(), dims, *map(np.ravel, chain)])
    np.testing.assert_array_equal(buf[:len(settings)], settings)
    state, pred = kernels.imm_views(buf)
    state[0][:] = rng.dirichlet(np.ones(n))
    state[1][:] = np.concatenate([rng.normal(size=(n, 2)) * 1e4, rng.normal(size=(n, 2)) * 200,
                                  np.zeros((n, D - 4))], axis=1)
    for j in range(n):
        state[2][j] = correlated(rng, np.array([1e4, 1e4, 400, 400, entry_var][:D]))
    state[3][:], state[4][:] = kernels.imm_combine(state[0], state[1], state[2])
    assert all(np.shares_memory(a, buf) for a in (*state, *pred))
    dt = 4.5
    z, R = state[3][:2] + rng.normal(size=2) * 300, spd(rng, 2, 80.0)
    C, bias, bias_cov = rng.normal(size=(2, 2)) * [1.0, 3e4], np.array([40.0, 1e-3]), np.diag([100.0, 1e-7])

    ref_pred = tuple(np.zeros_like(a) for a in pred)
    kernels.imm_predict(*(a.copy() for a in state[:3]), *chain, kmodes, dt, *ref_pred)
    kernels.imm_advance(buf, dt)
    for a, b in zip(pred, ref_pred):
        np.testing.assert_array_equal(a, b)

    def corrected(predicted):
        out = tuple(a.copy() for a in state)
        if predicted:
            res = kernels.imm_correct(*(a.copy() for a in ref_pred), dims, entry_var, zc, Rc, *out)
        else:
            res = kernels.imm_cycle(*out[:3], *chain, kmodes, dims, entry_var, dt, zc, Rc, *out[3:],
                                    *(np.zeros_like(a) for a in pred))
        return res, out

    zc, Rc = bias_corrected(z, C, R, bias, bias_cov)
    d2 = normalised_innovation(zc, np.zeros((2, 2)), Rc, np.zeros(2), np.zeros((2, 2)), ref_pred[3][:2],
                               ref_pred[4][:2, :2])
    def packed():  # the state and prediction (the rest of the buffer is settings and scratch)
        return np.concatenate([np.ravel(a) for a in (*state, *pred)])

    before, before_buf = packed(), buf.copy()
    zk, Rk = np.empty(2), np.empty((2, 2))
    for predicted in (True, False):  # outside the gate: the corrected measurement and d², nothing else
        res = kernels.imm_screen(buf, dt, predicted, z, C, R, bias, bias_cov, zk, Rk, d2 * 0.999)
        assert res[0] == d2 and res[2] == -4
        np.testing.assert_array_equal(zk, zc)
        np.testing.assert_array_equal(Rk, Rc)
        np.testing.assert_array_equal(packed(), before)
    assert kernels.imm_update(buf, dt, True, np.array([np.nan, 0.0]), Rc)[1] == -3
    assert kernels.imm_update(buf, dt, False, zc, -Rc)[1] == -3
    for step in (60.5, -60.5, np.nan):  # beyond max_gap (60 s): nothing done, code −5
        assert kernels.imm_screen(buf, step, False, z, C, R, bias, bias_cov, zk, Rk, 1e9)[2] == -5
    np.testing.assert_array_equal(packed(), before)
    for predicted, call in [(True, lambda: kernels.imm_update(buf, dt, True, zc, Rc)),
                            (False, lambda: kernels.imm_update(buf, dt, False, zc, Rc)),
                            (True, lambda: kernels.imm_screen(buf, dt, True, z, C, R, bias, bias_cov, zk, Rk, d2)[1:]),
                            (False, lambda: kernels.imm_screen(buf, dt, False, z, C, R, bias, bias_cov, zk, Rk,
                                                               d2)[1:])]:
        buf[:] = before_buf
        (nis, bad), out = corrected(predicted)
        assert bad == -2 and call() == (nis, bad)
        for a, b in zip(state, out):
            np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(buf[:len(settings)], settings)
