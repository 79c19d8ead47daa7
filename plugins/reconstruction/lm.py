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

JᵀJ is P × P. It is formed in compiled code over the non-zero entries of J only
(:func:`normal_equations`), and the damped system is solved by a compiled banded Cholesky
factorisation (:func:`damped_solve`), one per trial step, neither with a threaded BLAS. Multiple
shooting orders its parameters segment by segment (S_k, u_k, w_k, t_k), so its JᵀJ is banded with a
bandwidth of 11 whatever the segment count (:meth:`.shooting.MultipleShooting.order`): its
factorisation costs O(P·11²), where MINPACK's QR of the dense m × P Jacobian costs O(m P²).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from radartracker.api import kernel

_MU_MAX = 1e30  # damping beyond which a failed factorisation ends the solve


def levenberg_marquardt(fun: Callable[[np.ndarray], np.ndarray], jac: Callable[[np.ndarray], np.ndarray],
                        x0: np.ndarray, max_nfev: int, pos: np.ndarray | None = None, ftol: float = 1e-8,
                        xtol: float = 1e-12, gtol: float = 1e-8, mu0: float = 1e-3) -> tuple[np.ndarray, int]:
    """(x minimising ½‖fun(x)‖² from ``x0``, evaluations of ``fun`` spent) (module docstring).

    ``pos[j]``: the place of parameter j in the normal equations (default: j); an order that makes JᵀJ
    banded makes its Cholesky factorisation cost P·b² instead of P³/6 (b the bandwidth found in JᵀJ).
    """
    x = np.array(x0, float)
    P = len(x)
    pos = np.arange(P) if pos is None else np.asarray(pos, np.int64)
    r = fun(x)
    F, nfev = 0.5 * float(r @ r), 1
    A, g, L, hs, d = np.empty((P, P)), np.empty(P), np.empty((P, P)), np.empty(P), np.zeros(P)
    nz = np.empty(P, np.int64)
    mu, nu = mu0, 2.0
    while nfev < max_nfev:
        bw = normal_equations(jac(x), r, pos, nz, A, g)
        d = np.maximum(d, np.sqrt(np.diag(A)))
        d2 = np.where(d > 0, d * d, 1.0)
        if F == 0 or np.max(np.abs(g) / np.sqrt(d2)) <= gtol * np.sqrt(2 * F):
            break
        while nfev < max_nfev:
            if not damped_solve(A, g, mu * d2, bw, L, hs):  # not positive definite in floating point
                if not mu < _MU_MAX:  # no damping makes it so (a non-finite Jacobian): stop where we are
                    return x, nfev
                mu, nu = mu * nu, 2 * nu
                continue
            if np.sqrt(np.sum(d2 * hs * hs)) <= xtol * (np.sqrt(np.sum(d2[pos] * x * x)) + xtol):
                return x, nfev
            h = hs[pos]
            r_new = fun(x + h)
            nfev += 1
            F_new = 0.5 * float(r_new @ r_new)
            pred = 0.5 * (mu * float(np.sum(d2 * hs * hs)) - float(hs @ g))
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
def normal_equations(J: np.ndarray, r: np.ndarray, pos: np.ndarray, nz: np.ndarray, A: np.ndarray,
                     g: np.ndarray) -> int:
    """A = ΠJᵀJΠᵀ and g = ΠJᵀr into ``A``, ``g`` (parameter j at place pos[j]), row by row over each
    row's non-zero entries only (listed in the scratch ``nz``; a multiple-shooting row has at most 12,
    so the cost is Σ_rows nnz² instead of m·P²). Returns the bandwidth of A: the largest spread of
    places within one row of J."""
    m, P = J.shape
    for a in range(P):
        g[a] = 0.0
        for b in range(P):
            A[a, b] = 0.0
    bw = 0
    for i in range(m):
        n, lo, hi = 0, P, -1
        for a in range(P):
            if J[i, a] != 0.0:
                nz[n] = a
                n += 1
                lo, hi = min(lo, pos[a]), max(hi, pos[a])
        bw = max(bw, hi - lo)
        for ia in range(n):
            a = nz[ia]
            ja, pa = J[i, a], pos[a]
            g[pa] += ja * r[i]
            for ib in range(ia, n):
                pb = pos[nz[ib]]
                A[max(pa, pb), min(pa, pb)] += ja * J[i, nz[ib]]
    for a in range(P):
        for b in range(a):
            A[b, a] = A[a, b]
    return bw


@kernel
def damped_solve(A: np.ndarray, g: np.ndarray, damp: np.ndarray, bw: int, L: np.ndarray, h: np.ndarray) -> bool:
    """h solving (A + diag(damp)) h = −g by a banded Cholesky factorisation (A zero beyond ``bw`` off the
    diagonal, so is L): L Lᵀ = A + diag(damp) (into ``L``), then L y = −g and Lᵀ h = y.
    False (h not solved) when a pivot is not positive."""
    P = len(g)
    for j in range(P):
        s = A[j, j] + damp[j]
        for k in range(max(0, j - bw), j):
            s -= L[j, k] * L[j, k]
        if not s > 0.0:
            return False
        L[j, j] = math.sqrt(s)
        for i in range(j + 1, min(P, j + bw + 1)):
            t = A[i, j]
            for k in range(max(0, i - bw), j):
                t -= L[i, k] * L[j, k]
            L[i, j] = t / L[j, j]
    for i in range(P):
        t = -g[i]
        for k in range(max(0, i - bw), i):
            t -= L[i, k] * h[k]
        h[i] = t / L[i, i]
    for i in range(P - 1, -1, -1):
        t = h[i]
        for k in range(i + 1, min(P, i + bw + 1)):
            t -= L[k, i] * h[k]
        h[i] = t / L[i, i]
    return True
