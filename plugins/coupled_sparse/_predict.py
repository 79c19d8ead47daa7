"""Prediction of one aircraft in information form, keeping the arrowhead (package docstring)::

    Y_ii' = (A Y_ii⁻¹ Aᵀ + Q)⁻¹,   Y_ib' = Y_ii' A G_i,   η_i' = Y_ii' A m_i,
    Y_bb' = Y_bb − G_iᵀ (Y_ii − Aᵀ Y_ii' A) G_i,   η_b' = η_b − G_iᵀ (Y_ii − Aᵀ Y_ii' A) m_i

and without process noise Y_ii' = A⁻ᵀ Y_ii A⁻¹, Y_ib' = A⁻ᵀ Y_ib, η_i' = A⁻ᵀ η_i, Y_bb' = Y_bb.
"""

from __future__ import annotations

from radartracker.api import kernel

from ._layout import ERR_YII, OK
from ._linalg import chol, conditional, gram, inverse_factor, multiply, transition


@kernel
def predict(Yxx, Yxb, ex, Ybb, eb, s, nK, idx, dt, q, f4, V, G, W, v4):
    """Predict aircraft s by dt (its nK bias columns at positions idx); returns OK or ERR_YII."""
    L, A, Q, Sg, T, Yn, Ln = f4[0], f4[1], f4[2], f4[3], f4[4], f4[5], f4[6]
    u, mx = v4[0], v4[1]
    transition(dt, q, A, Q)
    if q == 0.0 or dt == 0.0:
        _shift_without_noise(Yxx[s], Yxb[s], ex[s], nK, dt)
        return OK
    if not conditional(Yxx, Yxb, ex, s, nK, L, V, u, G, mx):
        return ERR_YII
    if not _predicted_information(L, A, Q, Sg, T, Yn, Ln):
        return ERR_YII
    _remove_old_bias_term(Yxx[s], A, T, Sg, G, W, mx, Ybb, eb, idx, nK)
    _write_predicted_blocks(Yxx[s], Yxb[s], ex[s], nK, A, T, G, W, u, mx)
    return OK


@kernel
def _shift_without_noise(Y, Yb, e, nK, dt):
    """Y ← A⁻ᵀ Y A⁻¹, Y_ib ← A⁻ᵀ Y_ib, η ← A⁻ᵀ η with A⁻¹ = A(−dt): (A⁻ᵀ M)[2+r] = M[2+r] − dt·M[r]."""
    for c in range(4):
        for r in range(2):
            Y[2 + r, c] -= dt * Y[r, c]
    for r in range(4):
        for c in range(2):
            Y[r, 2 + c] -= dt * Y[r, c]
    for c in range(nK):
        for r in range(2):
            Yb[2 + r, c] -= dt * Yb[r, c]
    for r in range(2):
        e[2 + r] -= dt * e[r]
    for r in range(4):  # the two passes round differently: restore exact symmetry
        for c in range(r):
            y = 0.5 * (Y[r, c] + Y[c, r])
            Y[r, c] = y
            Y[c, r] = y


@kernel
def _predicted_information(L, A, Q, Sg, T, Yn, Ln):
    """T = Y' = (A Σ Aᵀ + Q)⁻¹ with Σ = L⁻ᵀ L⁻¹ (L Lᵀ = Y_ii); False if A Σ Aᵀ + Q is not positive definite.
    Sg, Yn, Ln: scratch."""
    inverse_factor(L, T, Yn)  # Yn = L⁻¹
    gram(Yn, Sg)  # Σ
    multiply(A, Sg, T, 4)
    for i in range(4):
        for j in range(i + 1):
            acc = Q[i, j]
            for k in range(4):
                acc += T[i, k] * A[j, k]
            Sg[i, j] = acc
            Sg[j, i] = acc
    if not chol(Sg, Ln, 4):
        return False
    inverse_factor(Ln, T, Yn)
    gram(Yn, T)
    return True


@kernel
def _remove_old_bias_term(Y, A, Yp, M, G, W, mx, Ybb, eb, idx, nK):
    """Y_bb −= Gᵀ M G and η_b −= Gᵀ M m with M = Y − Aᵀ Y' A (the change c_i' − c_i of the aircraft's
    Schur term); M, W: scratch."""
    for i in range(4):
        for j in range(i + 1):
            acc = Y[i, j]
            for k in range(4):
                for l in range(4):
                    acc -= A[k, i] * Yp[k, l] * A[l, j]
            M[i, j] = acc
            M[j, i] = acc
    multiply(M, G, W, nK)
    for a in range(nK):
        acc = 0.0
        for r in range(4):
            for k in range(4):
                acc += G[r, a] * M[r, k] * mx[k, 0]
        eb[idx[a]] -= acc
        for b in range(a + 1):
            acc = 0.0
            for r in range(4):
                acc += G[r, a] * W[r, b]
            Ybb[idx[a], idx[b]] -= acc
            if b != a:
                Ybb[idx[b], idx[a]] -= acc


@kernel
def _write_predicted_blocks(Y, Yb, e, nK, A, Yp, G, W, u, mx):
    """Y_ii ← Y', Y_ib ← Y' A G, η_i ← Y' A m; W, u: scratch."""
    multiply(A, G, W, nK)
    multiply(A, mx, u, 1)
    for i in range(4):
        for j in range(4):
            Y[i, j] = Yp[i, j]
    multiply(Yp, W, Yb, nK)
    multiply(Yp, u, e.reshape(4, 1), 1)
