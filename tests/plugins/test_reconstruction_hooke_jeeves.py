"""Hooke–Jeeves on test functions with known minima, cross-checked against scipy's Powell."""

import numpy as np
import pytest
from scipy.optimize import minimize, rosen

from radartracker_plugins.reconstruction.hooke_jeeves import hooke_jeeves


def _quadratic(x):
    A = np.array([[4.0, 1.0, 0.0], [1.0, 3.0, 0.5], [0.0, 0.5, 2.0]])
    d = x - np.array([1.0, -2.0, 0.5])
    return float(d @ A @ d) + 3.0


def _himmelblau(x):
    return (x[0] ** 2 + x[1] - 11) ** 2 + (x[0] + x[1] ** 2 - 7) ** 2


def _beale(x):
    a, b = x
    return (1.5 - a + a * b) ** 2 + (2.25 - a + a * b**2) ** 2 + (2.625 - a + a * b**3) ** 2


HIMMELBLAU_MINIMA = np.array([[3.0, 2.0], [-2.805118, 3.131312], [-3.779310, -3.283186], [3.584428, -1.848126]])


@pytest.mark.parametrize("f,x0,fmin,xmin", [
    (_quadratic, [5.0, 5.0, 5.0], 3.0, [1.0, -2.0, 0.5]),
    (rosen, [-1.2, 1.0], 0.0, [1.0, 1.0]),
    (rosen, [0.0, 0.0, 0.0, 0.0], 0.0, [1.0, 1.0, 1.0, 1.0]),
    (_beale, [1.0, 1.0], 0.0, [3.0, 0.5]),
])
def test_known_minima_and_powell_agree(f, x0, fmin, xmin):
    res = hooke_jeeves(f, x0, 0.5, 1e-7)
    ref = minimize(f, x0, method="Powell", options={"xtol": 1e-10, "ftol": 1e-14})
    assert res.converged
    assert res.fun == pytest.approx(fmin, abs=1e-8)
    np.testing.assert_allclose(res.x, xmin, atol=1e-3)
    np.testing.assert_allclose(res.x, ref.x, atol=1e-3)
    assert res.fun <= ref.fun + 1e-8


def test_multimodal_lands_on_a_known_minimum():
    res = hooke_jeeves(_himmelblau, [0.0, 0.0], 1.0, 1e-8)
    assert res.fun < 1e-10
    assert np.min(np.linalg.norm(HIMMELBLAU_MINIMA - res.x, axis=1)) < 1e-4


def test_stops_when_all_steps_are_below_their_finals():
    calls = []
    res = hooke_jeeves(lambda x: calls.append(1) or float(np.sum((x - 0.3) ** 2)), [0.0, 0.0], [1.0, 0.5], [0.1, 0.01])
    # steps 1 → 0.0625 (< 0.1) and 0.5 → 0.0078 (< 0.01): exactly the steps needed, then stop
    assert res.converged and res.nfev == len(calls)
    assert abs(res.x[1] - 0.3) <= 0.01
    capped = hooke_jeeves(rosen, [-1.2, 1.0], 0.5, 1e-12, max_evals=200)
    assert not capped.converged and capped.nfev <= 200 + 4


@pytest.mark.parametrize("kw", [dict(dh=1.0), dict(dh=0.0), dict(steps=0.0), dict(final_steps=-1.0)])
def test_rejects_bad_settings(kw):
    args = dict(steps=0.5, final_steps=0.01, dh=0.5) | kw
    with pytest.raises(ValueError):
        hooke_jeeves(rosen, [0.0, 0.0], **args)
