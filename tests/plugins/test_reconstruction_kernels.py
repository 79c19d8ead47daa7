"""Compiled numerics of the reconstruction fit, each against an independent oracle.

Oracles: the core's closed form ``radartracker.geometry.kinematics.propagate`` and scipy's ``solve_ivp``
(flow over a whole control track), central differences of ``propagate`` (the flow's derivatives),
``TrackWeight`` (the Hooke–Jeeves objective), numpy's ``J.T @ J`` and ``np.linalg.solve`` (normal
equations, damped Cholesky solve), ``scipy.optimize.least_squares`` (the Levenberg–Marquardt optimum,
on a textbook problem and on the fit's own multiple- and single-shooting problems), and the numpy RTS
smoother the compiled one replaced (its innovation log-likelihood).
"""

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import least_squares

from radartracker.estimation.motion import MotionModel
from radartracker.geometry.kinematics import propagate
from radartracker.geometry.plane import SystemPlane
from radartracker.simulation.simulator import KinematicTrajectory, Leg
from radartracker_plugins.reconstruction import _kernels as kern
from radartracker_plugins.reconstruction.config import ReconstructionConfig
from radartracker_plugins.reconstruction.fit import ControlObjective
from radartracker_plugins.reconstruction.lm import damped_solve, levenberg_marquardt, normal_equations
from radartracker_plugins.reconstruction.shooting import MultipleShooting
from radartracker_plugins.reconstruction.sim import REFERENCE, radars_around, simulate_flight
from radartracker_plugins.reconstruction.smoother import rts_smooth
from radartracker_plugins.reconstruction.weight import TrackWeight

CASES = [(0.0, 0.0), (3.0, 0.0), (-2.5, 0.0), (0.0, 0.8), (2.0, -0.5), (-4.0, 1.5), (1e-10, 5e-8)]


@pytest.fixture(scope="module")
def flight():
    plane = SystemPlane(*REFERENCE)
    legs = [Leg(120.0), Leg(60.0, u=3.0), Leg(100.0, w=0.6), Leg(90.0, u=-2.0, w=-0.3)]
    traj = KinematicTrajectory(0.0, -20e3, 10e3, 6000.0, 1.2, 170.0, legs)
    pt, _ = simulate_flight(traj, radars_around(plane, [(-60, -40), (50, 60)], [4.0, 6.0]), seed=3)
    return pt


def _objective(pt, K, initial=None, **cfg):
    t = pt.t - pt.t[0]
    return ControlObjective(TrackWeight(pt, cfg.pop("loss", "gauss")), t, 0.0, t[-1], K,
                            ReconstructionConfig(**cfg), initial)


def _theta(obj, pt):
    t = obj.times
    bounds = np.linspace(0.0, t[-1], obj.K + 1)
    return obj.pack((pt.z[0, 0] + 40.0, pt.z[0, 1] - 30.0, 1.15, 165.0), np.linspace(0.5, -1.0, obj.K),
                    np.linspace(0.2, -0.2, obj.K), bounds)


@pytest.mark.parametrize("u,w", CASES)
def test_flow_is_the_closed_form_and_its_derivatives_are_central_differences(u, w):
    tau = np.linspace(0.0, 150.0, 11)
    ref = np.array(propagate(1000.0, -500.0, 0.7, 180.0, u, w, tau))
    got = np.array([kern.flow(1000.0, -500.0, 0.7, 180.0, u, w, s) for s in tau]).T
    np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-8)
    D = np.empty((4, 6))
    args = [1000.0, -500.0, 0.7, 180.0, u, w]
    for s in tau[1:]:
        kern.flow_d(*args, s, D)
        for j, h in enumerate((1e-3, 1e-3, 1e-6, 1e-4, 1e-5, 1e-5)):
            hi, lo = list(args), list(args)
            hi[j] += h
            lo[j] -= h
            num = (np.array(propagate(*hi, np.array([s]))) - np.array(propagate(*lo, np.array([s]))))[:, 0] / (2 * h)
            np.testing.assert_allclose(D[:, j], num, rtol=1e-5, atol=1e-5 * max(1.0, s))


def test_track_positions_match_solve_ivp_across_segments(flight):
    obj = _objective(flight, 4)
    init, u, w, bounds, _ = obj.unpack(_theta(obj, flight))
    p, w_eff, viol = obj.positions(init, u, w, bounds)
    assert viol == 0.0 and np.array_equal(w_eff, w)
    ref, y0 = [], list(init)
    for k in range(4):
        t = obj.times
        sel = (t >= bounds[k]) & ((t < bounds[k + 1]) | (k == 3))
        sol = solve_ivp(lambda _, s: [s[3] * np.sin(s[2]), s[3] * np.cos(s[2]), u[k] / s[3], w[k]],
                        (bounds[k], bounds[k + 1]), y0, rtol=1e-12, atol=1e-9, method="DOP853", dense_output=True)
        ref.append(sol.sol(t[sel]).T[:, :2])
        y0 = sol.y[:, -1]
    np.testing.assert_allclose(p, np.vstack(ref), atol=1e-4)


@pytest.mark.parametrize("loss", ["gauss", "huber", "cauchy"])
def test_objective_is_weight_plus_prior_plus_penalty(flight, loss):
    obj = _objective(flight, 3, loss=loss, jump_sd=0.5)
    theta = _theta(obj, flight)
    theta[obj.n_init] = 20.0  # u₁ beyond max_u: projected, with a penalty
    init, u, w, bounds, viol = obj.unpack(theta)
    assert viol == pytest.approx((20.0 - obj.cfg.max_u) / obj.cfg.du1)  # per step unit beyond the bound
    p, _, v2 = obj.positions(init, u, w, bounds)
    prior = 0.5 * (np.sum(np.diff(u) ** 2) + np.sum(np.diff(w) ** 2)) / 0.5**2
    assert obj(theta) == pytest.approx(obj.weight(p) + prior + obj.cfg.penalty * (viol + v2), rel=1e-12)
    if loss == "gauss":
        r = obj.residuals(theta)
        assert 0.5 * r @ r + obj.weight.const == pytest.approx(obj(theta), rel=1e-12)


def test_normal_equations_and_damped_solve_match_numpy():
    rng = np.random.default_rng(2)
    J = rng.normal(size=(60, 12)) * (rng.random((60, 12)) < 0.3)
    r = rng.normal(size=60)
    A, g = np.empty((12, 12)), np.empty(12)
    assert normal_equations(J, r, np.arange(12), np.empty(12, np.int64), A, g) == 11
    np.testing.assert_allclose(A, J.T @ J, atol=1e-12)
    np.testing.assert_allclose(g, J.T @ r, atol=1e-12)
    damp, L, h = rng.random(12) + 0.1, np.empty((12, 12)), np.empty(12)
    assert damped_solve(A, g, damp, 11, L, h)
    np.testing.assert_allclose(h, np.linalg.solve(A + np.diag(damp), -g), rtol=1e-10)
    # a permuted banded problem: rows touching 3 consecutive places of a random order
    pos = rng.permutation(12)
    Jb = np.zeros((40, 12))
    for i in range(40):
        first = i % 10
        Jb[i, np.argsort(pos)[first:first + 3]] = rng.normal(size=3)
    bw = normal_equations(Jb, r[:40], pos, np.empty(12, np.int64), A, g)
    assert bw == 2
    Pm = np.eye(12)[pos]  # Pm[j, pos[j]] = 1: A = Pmᵀ JᵀJ Pm
    np.testing.assert_allclose(A, Pm.T @ Jb.T @ Jb @ Pm, atol=1e-12)
    assert damped_solve(A, g, damp, bw, L, h)
    np.testing.assert_allclose(h, np.linalg.solve(A + np.diag(damp), -g), rtol=1e-10)


def test_levenberg_marquardt_matches_scipy_on_a_textbook_problem():
    t = np.linspace(0, 4, 30)
    y = 2.5 * np.exp(-1.3 * t) + 0.5 + 0.01 * np.sin(7 * t)

    def fun(x):
        return x[0] * np.exp(-x[1] * t) + x[2] - y

    def jac(x):
        e = np.exp(-x[1] * t)
        return np.column_stack([e, -x[0] * t * e, np.ones_like(t)])

    x, _ = levenberg_marquardt(fun, jac, np.array([1.0, 0.5, 0.0]), 200)
    ref = least_squares(fun, [1.0, 0.5, 0.0], jac=jac, method="lm", xtol=1e-12, ftol=1e-12)
    np.testing.assert_allclose(x, ref.x, rtol=1e-7)


def test_levenberg_marquardt_stops_on_a_non_finite_jacobian():
    x, nfev = levenberg_marquardt(lambda x: x - 1.0, lambda x: np.full((2, 2), np.nan), np.zeros(2), 50)
    assert nfev == 1 and np.array_equal(x, np.zeros(2))


def test_levenberg_marquardt_reaches_scipys_optimum_of_the_fit(flight):
    """Same optimum as MINPACK (scipy's ``lm``) on the multiple- and the single-shooting problems."""
    obj = _objective(flight, 4)
    # near the truth (so that both solvers find the same optimum): the legs' controls and switches, perturbed
    theta = obj.pack((-20e3 + 60.0, 10e3 - 40.0, 1.21, 168.0), np.array([0.2, 2.7, -0.3, -1.8]),
                     np.array([0.05, -0.1, 0.5, -0.2]), np.array([0.0, 125.0, 176.0, 284.0, obj.times[-1]]))
    ms = MultipleShooting(obj)
    phi0 = ms.from_single(theta)
    P = len(phi0)
    assert normal_equations(ms.jacobian(phi0), ms.residuals(phi0), ms.order(), np.empty(P, np.int64),
                            np.empty((P, P)), np.empty(P)) == 11
    phi, _ = levenberg_marquardt(ms.residuals, ms.jacobian, phi0, 500, ms.order())
    ref = least_squares(ms.residuals, phi0, jac=ms.jacobian, method="lm", x_scale="jac", ftol=1e-8, xtol=1e-12,
                        max_nfev=500)
    cost = 0.5 * np.sum(ms.residuals(phi) ** 2)
    assert cost == pytest.approx(ref.cost, rel=1e-6)
    np.testing.assert_allclose(ms.to_single(phi), ms.to_single(ref.x), rtol=1e-4, atol=1e-3)
    theta1 = ms.to_single(phi)
    th, _ = levenberg_marquardt(obj.residuals, obj.jacobian, theta1, 500)
    ref = least_squares(obj.residuals, theta1, jac=obj.jacobian, method="lm", x_scale="jac", ftol=1e-8, xtol=1e-12,
                        max_nfev=500)
    assert 0.5 * np.sum(obj.residuals(th) ** 2) == pytest.approx(ref.cost, rel=1e-6)
    np.testing.assert_allclose(th, ref.x, rtol=1e-4, atol=1e-3)


def _rts_numpy(t, z, R, q):
    """The numpy RTS smoother the compiled one replaced (states, covariances, innovation log-likelihood)."""
    n, H = len(t), np.hstack([np.eye(2), np.zeros((2, 2))])
    xf, Pf, xp, Pp, As = np.empty((n, 4)), np.empty((n, 4, 4)), np.empty((n, 4)), np.empty((n, 4, 4)), []
    x, P = np.array([z[0, 0], z[0, 1], 0.0, 0.0]), np.zeros((4, 4))
    P[:2, :2], P[2:, 2:] = R[0] * 1e6, np.eye(2) * 300.0**2
    loglik = 0.0
    for k in range(n):
        A, Q = MotionModel(q).transition(t[k] - t[k - 1]) if k else (np.eye(4), np.zeros((4, 4)))
        x, P = A @ x, A @ P @ A.T + Q
        As.append(A)
        xp[k], Pp[k] = x, P
        nu, S = z[k] - x[:2], P[:2, :2] + R[k]
        K = np.linalg.solve(S, H @ P).T
        x, IKH = x + K @ nu, np.eye(4) - K @ H
        P = IKH @ P @ IKH.T + K @ R[k] @ K.T
        if k > 1:
            loglik -= 0.5 * (nu @ np.linalg.solve(S, nu) + np.log(np.linalg.det(2 * np.pi * S)))
        xf[k], Pf[k] = x, P
    xs, Ps = xf.copy(), Pf.copy()
    for k in range(n - 2, -1, -1):
        G = np.linalg.solve(Pp[k + 1], As[k + 1] @ Pf[k]).T
        xs[k] = xf[k] + G @ (xs[k + 1] - xp[k + 1])
        Ps[k] = Pf[k] + G @ (Ps[k + 1] - Pp[k + 1]) @ G.T
    return xs, Ps, loglik


@pytest.mark.parametrize("q", [0.01, 1.0, 30.0])
def test_compiled_rts_matches_the_numpy_smoother(flight, q):
    xs, Ps, ll = rts_smooth(flight.t, flight.z, flight.R, q)
    ref_x, ref_P, ref_ll = _rts_numpy(flight.t, flight.z, flight.R, q)
    np.testing.assert_allclose(xs, ref_x, rtol=1e-8, atol=1e-6)
    np.testing.assert_allclose(Ps, ref_P, rtol=1e-6, atol=1e-6)
    assert ll == pytest.approx(ref_ll, rel=1e-10)


def test_kernels_return_only_numbers(flight):
    """Compiled without numba's runtime, the kernels write into their arguments and return numbers only."""
    from radartracker.compiled import array_returns
    from radartracker_plugins.reconstruction import lm, smoother

    obj = _objective(flight, 3)
    obj.jacobian(_theta(obj, flight))
    MultipleShooting(obj).jacobian(MultipleShooting(obj).from_single(_theta(obj, flight)))
    rts_smooth(flight.t, flight.z, flight.R, 1.0)
    for module in (kern, lm, smoother):
        bad, seen = array_returns(module)
        assert bad == [] and seen > 0
