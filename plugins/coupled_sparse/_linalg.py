"""Small dense linear algebra of the sparse coupled filter, compiled (see the package docstring).

With L Lᵀ = Y_ii, V = L⁻¹ Y_ib and u = L⁻¹ η_i, aircraft i contributes VᵀV to Y_bb − S and Vᵀu to
η_b − sv (exactly symmetric), and its conditional given the biases is χ_i | ς ~ N(m_i − G_i ς_K, Y_ii⁻¹)
with G_i = L⁻ᵀV, m_i = L⁻ᵀu. Every function writes into arrays its caller owns and returns a flag
instead of producing NaN.
"""

from __future__ import annotations

import numpy as np

from radartracker.api import kernel


@kernel
def chol(A, L, n):
    """L[:n, :n] = lower Cholesky factor of A[:n, :n]; False (L undefined) unless positive definite."""
    for i in range(n):
        for j in range(i + 1):
            s = A[i, j]
            for k in range(j):
                s -= L[i, k] * L[j, k]
            if i == j:
                if not (0.0 < s < np.inf):
                    return False
                L[i, i] = np.sqrt(s)
            else:
                L[i, j] = s / L[j, j]
        for j in range(i + 1, n):
            L[i, j] = 0.0
    return True


@kernel
def lsolve(L, B, X, n, nc):
    """X[:n, :nc] = L⁻¹ B[:n, :nc] (forward substitution)."""
    for c in range(nc):
        for i in range(n):
            s = B[i, c]
            for k in range(i):
                s -= L[i, k] * X[k, c]
            X[i, c] = s / L[i, i]


@kernel
def ltsolve(L, B, X, n, nc):
    """X[:n, :nc] = L⁻ᵀ B[:n, :nc] (back substitution)."""
    for c in range(nc):
        for i in range(n - 1, -1, -1):
            s = B[i, c]
            for k in range(i + 1, n):
                s -= L[k, i] * X[k, c]
            X[i, c] = s / L[i, i]


@kernel
def multiply(A, B, X, nc):
    """X[:4, :nc] = A B[:4, :nc] for 4×4 A."""
    for c in range(nc):
        for i in range(4):
            acc = 0.0
            for k in range(4):
                acc += A[i, k] * B[k, c]
            X[i, c] = acc


@kernel
def identity(T):
    """T = I."""
    for i in range(T.shape[0]):
        for j in range(T.shape[1]):
            T[i, j] = 1.0 if i == j else 0.0


@kernel
def inverse_factor(L, T, Li):
    """Li = L⁻¹ of a 4×4 lower-triangular L (T: scratch)."""
    identity(T)
    lsolve(L, T, Li, 4, 4)


@kernel
def gram(X, out):
    """out = Xᵀ X for 4×4 X (exactly symmetric)."""
    for i in range(4):
        for j in range(i + 1):
            acc = 0.0
            for k in range(4):
                acc += X[k, i] * X[k, j]
            out[i, j] = acc
            out[j, i] = acc


@kernel
def bias_index(rk, rt, s, nk, idx):
    """idx[:nK] = positions in the bias vector of aircraft s's columns: the blocks of its nk radars
    rk[s, :nk] side by side (radar j's rt[j, 1] entries from rt[j, 0]); returns nK."""
    n = 0
    for c in range(nk):
        j = rk[s, c]
        for e in range(rt[j, 1]):
            idx[n] = rt[j, 0] + e
            n += 1
    return n


@kernel
def conditional(Yxx, Yxb, ex, s, nK, L, V, u, G, mx):
    """Factor Y_ii = L Lᵀ and form V = L⁻¹Y_ib, u = L⁻¹η_i, G = L⁻ᵀV, m = L⁻ᵀu; False if Y_ii ⋡ 0."""
    if not chol(Yxx[s], L, 4):
        return False
    lsolve(L, Yxb[s], V, 4, nK)
    lsolve(L, ex[s].reshape(4, 1), u, 4, 1)
    ltsolve(L, V, G, 4, nK)
    ltsolve(L, u, mx, 4, 1)
    return True


@kernel
def add_contribution(M, vec, idx, V, u, nK, sign):
    """M[idx, idx] += sign·VᵀV and vec[idx] += sign·Vᵀu (aircraft i's Schur term)."""
    for a in range(nK):
        va = 0.0
        for r in range(4):
            va += V[r, a] * u[r, 0]
        vec[idx[a]] += sign * va
        for b in range(a + 1):
            acc = 0.0
            for r in range(4):
                acc += V[r, a] * V[r, b]
            M[idx[a], idx[b]] += sign * acc
            if b != a:
                M[idx[b], idx[a]] += sign * acc


@kernel
def transition(dt, q, A, Q):
    """Constant-velocity A(dt), Q(dt) exactly as radartracker.api.MotionModel.transition."""
    for i in range(4):
        for j in range(4):
            A[i, j] = 1.0 if i == j else 0.0
            Q[i, j] = 0.0
    A[0, 2] = dt
    A[1, 3] = dt
    if q != 0.0 and dt != 0.0:
        adt = abs(dt)
        for i in range(2):
            Q[i, i] = q * adt**3 / 3
            Q[i, i + 2] = Q[i + 2, i] = q * adt**2 / 2
            Q[i + 2, i + 2] = q * adt
