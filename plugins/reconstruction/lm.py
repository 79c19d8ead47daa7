"""Levenberg–Marquardt for the least-squares refinements (:mod:`.fit`, :mod:`.shooting`).

Minimises F(x) = ½‖r(x)‖² with the Jacobian J of r. Each iteration solves the damped normal equations

    (JᵀJ + μ D²) h = −Jᵀr,    D = diag(d),  d_j = max over the iterations of ‖J_{:,j}‖

(Marquardt's scaling as in MINPACK's ``lmder`` with ``mode=1``: the step is invariant to the units
of the parameters; a column that is all zero gets d = 1). The step is taken when the gain ratio
ρ = (F(x) − F(x + h)) / L(h), L(h) = −hᵀJᵀr − ½ hᵀJᵀJ h = ½ (μ hᵀD²h − hᵀJᵀr), is positive, and
μ is updated as in Nielsen (1999): μ ← μ · max(⅓, 1 − (2ρ − 1)³) after a taken step, μ ← μ·ν,
ν ← 2ν after a refused one. It stops like MINPACK: when both the actual and the predicted relative
reduction are ≤ ``ftol``, when the scaled step is ≤ ``xtol`` times the scaled x, when the gradient's
largest cosine with a column of J is ≤ ``gtol``, or after ``max_nfev`` evaluations of r.

JᵀJ is P × P (P ≤ 3·80 + 3 parameters). It is formed in compiled code over the non-zero entries of
J only (:func:`normal_equations`), and the damped system is solved by a compiled Cholesky
factorisation (:func:`damped_solve`), one per trial step: the m × P QR that MINPACK factorises at
each iteration costs m/P times more, and neither needs a threaded BLAS.
"""

from __future__ import annotations

from collections.abc import Callable

import math

import numpy as np

from radartracker.api import kernel


def levenberg_marquardt(fun: Callable[[np.ndarray], np.ndarray], jac: Callable[[np.ndarray], np.ndarray],
                        x0: np.ndarray, max_nfev: int, ftol: float = 1e-8, xtol: float = 1e-12,
                        gtol: float = 1e-8, mu0: float = 1e-3) -> tuple[np.ndarray, int]:
    """(x minimising ½‖fun(x)‖² from ``x0``, evaluations of ``fun`` spent) (module docstring)."""
    x = np.array(x0, float)
    P = len(x)
    r = fun(x)
    F, nfev = 0.5 * float(r @ r), 1
    A, g, L, h, d = np.empty((P, P)), np.empty(P), np.empty((P, P)), np.empty(P), np.zeros(P)
    mu, nu = mu0, 2.0
    while nfev < max_nfev:
        normal_equations(jac(x), r, A, g)
        d = np.maximum(d, np.sqrt(np.diag(A)))
        d2 = np.where(d > 0, d * d, 1.0)
        if F == 0 or np.max(np.abs(g) / np.sqrt(d2)) <= gtol * np.sqrt(2 * F):
            break
        while nfev < max_nfev:
            if not damped_solve(A, g, mu * d2, L, h):  # not positive definite in floating point
                mu, nu = mu * nu, 2 * nu
                continue
            if np.sqrt(np.sum(d2 * h * h)) <= xtol * (np.sqrt(np.sum(d2 * x * x)) + xtol):
                return x, nfev
            r_new = fun(x + h)
            nfev += 1
            F_new = 0.5 * float(r_new @ r_new)
            pred = 0.5 * (mu * float(np.sum(d2 * h * h)) - float(h @ g))
            rho = (F - F_new) / pred if pred > 0 else -1.0
            if rho > 0:
                done = F - F_new <= ftol * F and pred <= ftol * F
                x, r, F = x + h, r_new, F_new
                mu, nu = mu * max(1 / 3, 1 - (2 * rho - 1) ** 3), 2.0
                if done:
                    return x, nfev
                break
            if pred <= ftol * F:
                return x, nfev
            mu, nu = mu * nu, 2 * nu
    return x, nfev


@kernel
def normal_equations(J: np.ndarray, r: np.ndarray, A: np.ndarray, g: np.ndarray) -> None:
    """A = JᵀJ and g = Jᵀr into ``A``, ``g``, row by row over each row's non-zero entries only (a
    multiple-shooting row has at most 12: the cost is Σ_rows nnz² instead of m·P²)."""
    m, P = J.shape
    for a in range(P):
        g[a] = 0.0
        for b in range(P):
            A[a, b] = 0.0
    for i in range(m):
        for a in range(P):
            ja = J[i, a]
            if ja == 0.0:
                continue
            g[a] += ja * r[i]
            for b in range(a, P):
                A[a, b] += ja * J[i, b]
    for a in range(P):
        for b in range(a):
            A[a, b] = A[b, a]


@kernel
def damped_solve(A: np.ndarray, g: np.ndarray, damp: np.ndarray, L: np.ndarray, h: np.ndarray) -> bool:
    """h solving (A + diag(damp)) h = −g by Cholesky, L Lᵀ = A + diag(damp) (into ``L``), then
    L y = −g and Lᵀ h = y. False (h untouched) when a pivot is not positive."""
    P = len(g)
    for j in range(P):
        s = A[j, j] + damp[j]
        for k in range(j):
            s -= L[j, k] * L[j, k]
        if not s > 0.0:
            return False
        L[j, j] = math.sqrt(s)
        for i in range(j + 1, P):
            t = A[i, j]
            for k in range(j):
                t -= L[i, k] * L[j, k]
            L[i, j] = t / L[j, j]
    for i in range(P):
        t = -g[i]
        for k in range(i):
            t -= L[i, k] * h[k]
        h[i] = t / L[i, i]
    for i in range(P - 1, -1, -1):
        t = h[i]
        for k in range(i + 1, P):
            t -= L[k, i] * h[k]
        h[i] = t / L[i, i]
    return True
