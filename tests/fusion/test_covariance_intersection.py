"""Fast covariance intersection: the formula from an independent computation, its consistency for any
cross-correlation (analytically and by Monte Carlo on correlated Gaussian pairs), and its price against
the trace-optimal ω found by scipy."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import linalg, optimize, stats

from radartracker.fusion.center import covariance_intersection


def _spd(rng: np.random.Generator, n: int = 4, scale: float = 100.0) -> np.ndarray:
    A = rng.normal(size=(n, n)) * scale
    return A @ A.T + np.eye(n) * scale


def _ci(omega: float, P1: np.ndarray, P2: np.ndarray, x1: np.ndarray, x2: np.ndarray):
    """CI with weight ω on estimate 1 by linear solves (no explicit inverse of the inputs)."""
    I1, I2 = linalg.solve(P1, np.eye(len(x1)), assume_a="pos"), linalg.solve(P2, np.eye(len(x2)), assume_a="pos")
    info = omega * I1 + (1 - omega) * I2
    P = linalg.solve(info, np.eye(len(x1)), assume_a="pos")
    return P @ (omega * I1 @ x1 + (1 - omega) * I2 @ x2), P


def test_fast_ci_equals_the_formula_with_trace_weights():
    rng = np.random.default_rng(1)
    for _ in range(20):
        P1, P2 = _spd(rng), _spd(rng, scale=300.0)
        x1, x2 = rng.normal(size=4) * 50, rng.normal(size=4) * 50
        x, P = covariance_intersection([x1, x2], [P1, P2])
        # ω₁ = (1/tr P₁) / (1/tr P₁ + 1/tr P₂) = tr P₂ / (tr P₁ + tr P₂)
        xe, Pe = _ci(np.trace(P2) / (np.trace(P1) + np.trace(P2)), P1, P2, x1, x2)
        np.testing.assert_allclose(x, xe, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(P, Pe, rtol=1e-9, atol=1e-9)
    x, P = covariance_intersection([x1], [P1])
    assert np.array_equal(x, x1) and np.array_equal(P, P1)


def test_fused_trace_is_no_smaller_than_the_trace_optimal_ci():
    """scipy's ω* minimises tr P(ω) over (0, 1), the end points (one input alone) feasible too; fast CI
    is a cheap approximation of it and can never beat it."""
    rng = np.random.default_rng(2)
    for _ in range(20):
        P1, P2 = _spd(rng), _spd(rng, scale=rng.uniform(50, 500))
        x0 = np.zeros(4)
        best = optimize.minimize_scalar(lambda w: np.trace(_ci(w, P1, P2, x0, x0)[1]), bounds=(0, 1),
                                        method="bounded", options={"xatol": 1e-10})
        _, P = covariance_intersection([x0, x0], [P1, P2])
        optimum = min(best.fun, np.trace(P1), np.trace(P2))
        assert np.trace(P) >= optimum * (1 - 1e-9)


@pytest.mark.parametrize("rho", [-0.95, -0.5, 0.0, 0.5, 0.95, 1.0])
def test_fused_covariance_bounds_the_true_error_for_any_correlation(rho):
    """Errors e₁ = L₁u, e₂ = L₂(ρu + √(1−ρ²)v): cross-covariance ρL₁L₂ᵀ, unknown to the fusion. The fused
    error K₁e₁ + K₂e₂ has covariance KΣKᵀ; CI's P must bound it (P − KΣKᵀ ⪰ 0), and the Monte Carlo
    sample covariance of the fused errors must agree with KΣKᵀ."""
    rng = np.random.default_rng([3, int(100 * rho) + 100])
    P1, P2 = _spd(rng), _spd(rng, scale=200.0)
    L1, L2 = np.linalg.cholesky(P1), np.linalg.cholesky(P2)
    n = 2000
    u, v = rng.normal(size=(n, 4)), rng.normal(size=(n, 4))
    e1 = u @ L1.T
    e2 = (rho * u + np.sqrt(1 - rho * rho) * v) @ L2.T
    fused = np.array([covariance_intersection([a, b], [P1, P2])[0] for a, b in zip(e1, e2)])
    _, P = covariance_intersection([e1[0], e2[0]], [P1, P2])
    # the fusion is linear: K_i = P ω_i P_i⁻¹, recovered from unit inputs
    K1 = np.column_stack([covariance_intersection([c, np.zeros(4)], [P1, P2])[0] for c in np.eye(4)])
    K2 = np.column_stack([covariance_intersection([np.zeros(4), c], [P1, P2])[0] for c in np.eye(4)])
    C12 = rho * L1 @ L2.T
    true = K1 @ P1 @ K1.T + K1 @ C12 @ K2.T + K2 @ C12.T @ K1.T + K2 @ P2 @ K2.T
    assert np.linalg.eigvalsh(P - true).min() >= -1e-9 * np.trace(P)
    sample = np.cov(fused.T)
    # sample covariance against KΣKᵀ: each variance within a 99.9 % χ² band of n − 1 degrees of freedom
    lo, hi = stats.chi2.ppf([0.0005, 0.9995], n - 1) / (n - 1)
    d = np.diag(true)
    assert np.all(np.diag(sample) >= lo * d) and np.all(np.diag(sample) <= hi * d)
    # and the fused errors are consistent: mean NEES ≤ dim (+ Monte Carlo margin)
    nees = np.einsum("ni,ij,nj->n", fused, np.linalg.inv(P), fused).mean()
    assert nees <= 4 * (1 + 4 * np.sqrt(2 / (4 * n)))
