"""The ``imm`` plugin against a plain, FilterPy-shaped IMM (tests/plugins/imm_oracle.py) on a simulated
manoeuvring flight: state, covariance, mode probabilities and NIS at every step, through the public
filter API (``start``, ``update``, ``screen``, ``predict``, ``estimate``, ``probabilities``).

Stated tolerance: the two differ only by the order of floating-point operations (closed-form 2×2
inverses and fused loops against numpy's and FilterPy's matrix products), so every step agrees to
|Δx| ≤ 1e-7 m (m/s), |ΔP| ≤ 1e-9 max|P|, |Δμ| ≤ 1e-10 and NIS to a relative 1e-8 over 120 steps
(the largest differences seen: 3e-9 m, 6e-11 max|P|, 1e-11, 1e-10).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from radartracker.simulation.simulator import KinematicTrajectory, Leg
from radartracker_plugins.motion import CTMode, CVMode, IMMConfig, IMMFilter
from tests.plugins.imm_oracle import (CTExtendedKalman, CVKalman, PlainIMM, ct_jacobian, ct_mean, cv_matrices,
                                      sojourn_generator)

X_ATOL, P_SCALED, MU_ATOL, NIS_RTOL = 1e-7, 1e-9, 1e-10, 1e-8


def manoeuvring_flight(seed: int, n: int = 120):
    """A 230 m/s flight: straight, a 3°/s turn, straight, a −2°/s turn, straight; plots 2–8 s apart
    with a correlated noise covariance R of 60–150 m."""
    rng = np.random.default_rng(seed)
    v = 230.0
    legs = [Leg(80.0), Leg.turn(60.0, 3.0, v), Leg(100.0), Leg.turn(90.0, -2.0, v), Leg(400.0)]
    traj = KinematicTrajectory(0.0, 2e4, -1e4, 9000.0, 0.7, v, legs)
    t = np.cumsum(rng.uniform(2.0, 8.0, n))
    t = t[t < 700.0]
    x, y, _ = traj.position(t)
    Rs, zs = [], []
    for k in range(len(t)):
        sd, rho = rng.uniform(60.0, 150.0, 2), rng.uniform(-0.5, 0.5)
        R = np.array([[sd[0] ** 2, rho * sd[0] * sd[1]], [rho * sd[0] * sd[1], sd[1] ** 2]])
        Rs.append(R)
        zs.append(np.array([x[k], y[k]]) + rng.multivariate_normal(np.zeros(2), R))
    return t, np.array(zs), np.array(Rs)


def oracle_modes(specs, z0, R0, sd_v, entry_var):
    """The oracle's mode objects started as the plugin starts: χ = [z, 0, 0], P = diag(R, σ_v² I), and a
    CT mode with ω = 0 ± σ_e."""
    x, P = np.concatenate([z0, [0.0, 0.0]]), np.zeros((4, 4))
    P[:2, :2], P[2:, 2:] = R0, sd_v**2 * np.eye(2)
    modes = []
    for spec in specs:
        if spec[0] == "cv":
            modes.append(CVKalman(spec[1], x, P))
        else:
            P5 = np.zeros((5, 5))
            P5[:4, :4], P5[4, 4] = P, entry_var
            modes.append(CTExtendedKalman(spec[1], spec[2], np.append(x, 0.0), P5))
    return modes


class EKFMode:
    """The oracle's coordinated turn offered to the plugin as a mode filter it calls in Python."""

    dim = 5

    def __init__(self, q: float, turn_rate_sd: float) -> None:
        self.q, self.turn_rate_sd = q, turn_rate_sd

    def predict(self, x, P, dt):
        F = ct_jacobian(x, dt)
        Q = np.zeros((5, 5))
        Q[:4, :4] = cv_matrices(dt, self.q)[1]
        Q[4, 4] = self.turn_rate_sd**2 * abs(dt)
        return ct_mean(x, dt), F @ P @ F.T + Q


CASES = {
    "default": ([("cv", 1.0), ("ct", 1.0, math.radians(0.5))], None),
    "three-modes-fixed": ([("cv", 0.5), ("ct", 3.0, 0.02), ("cv", 80.0)],
                          np.array([[0.90, 0.06, 0.04], [0.10, 0.85, 0.05], [0.2, 0.1, 0.7]])),
    "ct-in-python": ([("cv", 2.0), ("ekf", 1.5, 0.01)], None),
}


def build(case: str):
    """(the plugin's filter, the oracle IMM) for a case: default settings, or modes and a fixed Π."""
    specs, M = CASES[case]
    if case == "default":
        f = IMMFilter()
    else:
        modes = [CVMode(s[1]) if s[0] == "cv" else CTMode(s[1], s[2]) if s[0] == "ct" else EKFMode(s[1], s[2])
                 for s in specs]
        f = IMMFilter(IMMConfig(modes=tuple(modes), transition=M)) if M is not None else \
            IMMFilter(IMMConfig(modes=tuple(modes)))
    c = f.config
    entry_var = c.turn_rate_entry_sd**2
    dims = [4 if s[0] == "cv" else 5 for s in specs]
    tau = np.array([120.0 if d == 4 else 30.0 for d in dims])
    mu0 = np.full(len(specs), 1 / len(specs)) if M is not None else tau / tau.sum()
    return f, lambda z0, R0: PlainIMM(oracle_modes(specs, z0, R0, c.prior_sd_velocity_mps, entry_var), mu0,
                                      entry_var, G=sojourn_generator(tau), M=M)


def assert_agree(f: IMMFilter, oracle: PlainIMM, step: int) -> None:
    _, x, P = f.estimate()
    xr, Pr = oracle.estimate()
    np.testing.assert_allclose(x, xr, rtol=0, atol=X_ATOL, err_msg=f"state at step {step}")
    np.testing.assert_allclose(P, Pr, rtol=0, atol=P_SCALED * np.abs(Pr).max(), err_msg=f"covariance at step {step}")
    np.testing.assert_allclose(f.probabilities, oracle.mu, rtol=0, atol=MU_ATOL, err_msg=f"μ at step {step}")


@pytest.mark.parametrize("case", CASES)
@pytest.mark.parametrize("seed", [1, 2])
def test_update_equals_the_plain_imm_at_every_step(case, seed):
    t, zs, Rs = manoeuvring_flight(seed)
    f, make_oracle = build(case)
    f.start(t[0], zs[0], Rs[0])
    oracle = make_oracle(zs[0], Rs[0])
    assert_agree(f, oracle, 0)
    turned = []
    for k in range(1, len(t)):
        xb, Pb = oracle.predict(t[k] - t[k - 1])
        x_bar, P_bar = f.predict(t[k])
        np.testing.assert_allclose(x_bar, xb, rtol=0, atol=X_ATOL)
        np.testing.assert_allclose(P_bar, Pb, rtol=0, atol=P_SCALED * np.abs(Pb).max())
        assert f.update(t[k], zs[k], Rs[k]) == pytest.approx(oracle.update(zs[k], Rs[k]), rel=NIS_RTOL)
        assert_agree(f, oracle, k)
        turned.append(oracle.mu[1])
    if case != "three-modes-fixed":  # the turns move the probability to the CT mode and back
        assert max(turned) > 0.8 and turned[-1] < 0.3


def test_screen_equals_the_plain_imm_with_bias_correction_and_gate():
    """``screen``: z_c = z − C ς̂, R_c = R + C P_ς Cᵀ, d² against the oracle's predicted mixture, the
    update only inside the gate (a gross error every 9th plot is refused and changes nothing)."""
    t, zs, Rs = manoeuvring_flight(3)
    f, make_oracle = build("default")
    f.start(t[0], zs[0], Rs[0])
    oracle = make_oracle(zs[0], Rs[0])
    C, bias, bias_cov = np.array([[0.8, 2e4], [-0.6, 3e4]]), np.array([30.0, -4e-4]), np.diag([50.0, 2e-8])
    refused, epoch = 0, t[0]
    for k in range(1, len(t)):
        z = zs[k] + C @ bias + (np.array([3e3, -2e3]) if k % 9 == 0 else 0.0)
        zc, Rc = z - C @ bias, Rs[k] + C @ bias_cov @ C.T
        oracle_mu, oracle_modes_before = oracle.mu.copy(), [(m.x.copy(), m.P.copy()) for m in oracle.modes]
        xb, Pb = oracle.predict(t[k] - epoch)
        nu = zc - xb[:2]
        d2_ref = float(nu @ np.linalg.solve(Pb[:2, :2] + Rc, nu))
        d2, got_zc, got_Rc, updated = f.screen(t[k], z, C, Rs[k], bias, bias_cov, 50.0)
        if not updated:  # handed back to update with later; used and not handed back when updated
            np.testing.assert_allclose(got_zc, zc, rtol=1e-13)
            np.testing.assert_allclose(got_Rc, Rc, rtol=1e-13)
        assert d2 == pytest.approx(d2_ref, rel=1e-8) and updated == (d2_ref <= 50.0)
        if updated:
            oracle.update(zc, Rc)
            epoch = t[k]
        else:
            refused += 1
            oracle.mu = oracle_mu
            for m, (x, P) in zip(oracle.modes, oracle_modes_before):
                m.x, m.P = x, P
        assert_agree(f, oracle, k)
    assert refused >= len(t) // 9

