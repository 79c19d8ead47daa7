"""Closed-form integration of the kinematic model against a fine numerical solution."""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from radartracker.geometry.kinematics import propagate


def numeric(x0, y0, phi0, v0, u, w, tau):
    def f(t, s):
        x, y, phi, v = s
        return [v * math.sin(phi), v * math.cos(phi), u / v, w]
    sol = solve_ivp(f, (0, tau[-1]), [x0, y0, phi0, v0], t_eval=tau, rtol=1e-11, atol=1e-8, method="DOP853")
    return sol.y


@pytest.mark.parametrize("u,w", [(0.0, 0.0), (3.0, 0.0), (-2.5, 0.0), (0.0, 1.5), (2.0, 0.8), (-4.0, -0.5),
                                 (1.0, 1e-8), (1e-10, 0.3)])
def test_closed_form_matches_numerical_integration(u, w):
    tau = np.linspace(0, 200, 41)
    x, y, phi, v = propagate(1000.0, -500.0, 0.7, 180.0, u, w, tau)
    ref = numeric(1000.0, -500.0, 0.7, 180.0, u, w, tau)
    np.testing.assert_allclose(x, ref[0], atol=1e-3)
    np.testing.assert_allclose(y, ref[1], atol=1e-3)
    np.testing.assert_allclose(phi, ref[2], atol=1e-9)
    np.testing.assert_allclose(v, ref[3], atol=1e-9)


def test_heading_is_clockwise_from_north():
    x, y, _, _ = propagate(0, 0, math.pi / 2, 100.0, 0.0, 0.0, np.array([10.0]))
    assert x[0] == pytest.approx(1000.0) and y[0] == pytest.approx(0.0, abs=1e-9)
    _, _, phi, _ = propagate(0, 0, 0.0, 100.0, 5.0, 0.0, np.array([10.0]))
    assert phi[0] == pytest.approx(0.5)  # positive u turns right (clockwise)


def test_speed_reaching_zero_is_refused():
    with pytest.raises(ValueError, match="speed"):
        propagate(0, 0, 0, 10.0, 0.0, -1.0, np.array([20.0]))
