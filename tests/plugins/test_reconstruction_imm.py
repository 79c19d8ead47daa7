"""The IMM (CV + coordinated turns) smoother used as a baseline.

Oracles: the matrix exponential of the continuous coordinated-turn generator (scipy.linalg.expm);
FilterPy's IMMEstimator running the same modes (the forward pass); the RTS smoother of the
reconstruction plugin (an IMM of two identical CV modes is a Kalman filter, and its two-filter
smoother must then equal RTS).
"""

import math

import numpy as np
import pytest
from filterpy.kalman import IMMEstimator, KalmanFilter
from scipy.linalg import expm

from radartracker.geometry.plane import SystemPlane
from radartracker.simulation.simulator import KinematicTrajectory, Leg
from radartracker_plugins.reconstruction.imm import OMEGA, P_STAY, imm_pass, imm_smooth, noise, transition
from radartracker_plugins.reconstruction.sim import REFERENCE, radars_around, simulate_flight
from radartracker_plugins.reconstruction.smoother import rts_smooth


@pytest.fixture(scope="module")
def flight():
    plane = SystemPlane(*REFERENCE)
    traj = KinematicTrajectory(0.0, -20e3, 10e3, 6000.0, 1.2, 170.0, [Leg(100.0), Leg(60.0, u=5.0), Leg(80.0)])
    return simulate_flight(traj, radars_around(plane, [(-60, -40), (50, 60)], [4.0, 6.0]), seed=3)


@pytest.mark.parametrize("omega,dt", [(0.0, 4.0), (OMEGA, 4.0), (-OMEGA, 7.5), (OMEGA, -5.0)])
def test_transition_is_the_exponential_of_the_turn_generator(omega, dt):
    A = np.zeros((4, 4))
    A[0, 2] = A[1, 3] = 1.0
    A[2, 3], A[3, 2] = -omega, omega
    np.testing.assert_allclose(transition(dt, omega), expm(A * dt), atol=1e-12)


def test_forward_pass_equals_filterpy_imm(flight):
    pt, _ = flight
    t, z, R = pt.t[:40], pt.z[:40], pt.R[:40]
    omegas, q = (0.0, OMEGA, -OMEGA), 2.0
    xf, Pf, _, _, _ = imm_pass(t, z, R, q, omegas)
    filters = []
    for _ in omegas:
        kf = KalmanFilter(dim_x=4, dim_z=2)
        kf.x = np.array([z[0, 0], z[0, 1], 0.0, 0.0])
        kf.P = np.zeros((4, 4))
        kf.P[:2, :2] = R[0]
        kf.P[2:, 2:] = np.eye(2) * 300.0**2
        kf.H = np.hstack([np.eye(2), np.zeros((2, 2))])
        filters.append(kf)
    M = np.full((3, 3), (1 - P_STAY) / 2)
    np.fill_diagonal(M, P_STAY)
    imm = IMMEstimator(filters, np.full(3, 1 / 3), M)
    for k in range(1, len(t)):
        for f, om in zip(filters, omegas):
            f.F, f.Q, f.R = transition(t[k] - t[k - 1], om), noise(t[k] - t[k - 1], q), R[k]
        imm.predict()
        imm.update(z[k])
        np.testing.assert_allclose(xf[k], imm.x, rtol=1e-7, atol=1e-6)
        np.testing.assert_allclose(Pf[k], imm.P, rtol=1e-6, atol=1e-6)


def test_two_filter_smoother_of_one_model_equals_rts(flight):
    pt, _ = flight
    xs, q = imm_smooth(pt.t, pt.z, pt.R, q_grid=(3.0,), omegas=(0.0, 0.0))
    xr, _, _ = rts_smooth(pt.t, pt.z, pt.R, 3.0)
    assert q == 3.0
    np.testing.assert_allclose(xs[:, :2], xr[:, :2], atol=0.5)  # metres; the two differ only in the end priors
    np.testing.assert_allclose(xs[:, 2:], xr[:, 2:], atol=0.1)
    assert math.isfinite(imm_smooth(pt.t, pt.z, pt.R)[1])
