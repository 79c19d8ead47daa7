"""Round-off control of the sparse coupled filter (package docstring): S recomputed from the blocks by

    S = Y_bb − Σ_i Y_bi Y_ii⁻¹ Y_ib,   sv = η_b − Σ_i Y_bi Y_ii⁻¹ η_i                    (rebuild)

and the bias marginal reset from S: P_ς = S⁻¹, ς̂ = S⁻¹ sv (refresh).
"""

from __future__ import annotations

import numpy as np

from radartracker.api import kernel

from ._layout import C_SINCE_REBUILD, C_SINCE_REFRESH
from ._linalg import add_contribution, bias_index, conditional


@kernel
def rebuild(st, wk):
    """S and sv from the blocks, from scratch, on the storage ``st`` (:func:`~._layout.carve`) with the
    scratch ``wk`` (:func:`~._layout.carve_work`); False (S, sv untouched) if an aircraft's Y_ii is not
    positive definite."""
    Yxx, Yxb, ex, tx, Ybb, eb, S, sv, Pb, bh, nk, rk, ctr, rt, idx = st
    f4, V, G, W, v4, Kb, LS, S_new, io = wk
    sv_new = Kb[0]
    nb = Ybb.shape[0]
    for a in range(nb):
        sv_new[a] = eb[a]
        for b in range(nb):
            S_new[a, b] = Ybb[a, b]
    for s in range(nk.shape[0]):
        k = nk[s]
        if k <= 0:  # free slot (−1) or no radar yet: no term
            continue
        nK = bias_index(rk, rt, s, k, idx)
        if not conditional(Yxx, Yxb, ex, s, nK, f4[0], V, v4[0], G, v4[1]):
            return False
        add_contribution(S_new, sv_new, idx, V, v4[0], nK, -1.0)
    for a in range(nb):
        sv[a] = sv_new[a]
        for b in range(nb):
            S[a, b] = S_new[a, b]
    ctr[C_SINCE_REBUILD] = 0
    return True


@kernel
def refresh(S, sv, Pb, bh, ctr, LS, LSi):
    """Pb = S⁻¹ and ς̂ = S⁻¹ sv through the Cholesky factor S = L Lᵀ; False (Pb, ς̂ untouched) if S is not
    positive definite. LS, LSi: scratch at least as large as S.

    Every entry is summed in the order of the textbook loops (Cholesky, then forward substitution and the
    product Pb = L⁻ᵀ L⁻¹, all over k ascending), but the loops run over independent entries along
    contiguous rows: LS holds Lᵀ (its row j is L's column j), LSi holds L⁻¹."""
    n = S.shape[0]
    if not _cholesky_transposed(S, LS, n):
        return False
    _inverse_lower(LS, LSi, n)
    _inverse_gram(LSi, Pb, n)
    for i in range(n):  # ς̂ = Pb sv, each entry summed over k ascending (Pb is exactly symmetric: row k)
        bh[i] = 0.0
    for k in range(n):
        svk = sv[k]
        for i in range(n):
            bh[i] += Pb[k, i] * svk
    ctr[C_SINCE_REFRESH] = 0
    return True


@kernel
def _cholesky_transposed(S, Lt, n):
    """Lt = Lᵀ, L Lᵀ = S: column j of L is L[i, j] = (S[i, j] − Σ_{k<j} L[i, k] L[j, k]) / L[j, j], i ≥ j.
    False unless S is positive definite."""
    for j in range(n):
        for i in range(j, n):
            Lt[j, i] = S[i, j]
        for k in range(j):
            ljk = Lt[k, j]
            for i in range(j, n):
                Lt[j, i] -= Lt[k, i] * ljk
        d = Lt[j, j]
        if not (0.0 < d < np.inf):
            return False
        d = np.sqrt(d)
        Lt[j, j] = d
        for i in range(j + 1, n):
            Lt[j, i] = Lt[j, i] / d
    return True


@kernel
def _inverse_lower(Lt, Li, n):
    """Li = L⁻¹ row by row: L⁻¹[i, c] = (δ_ic − Σ_{c≤k<i} L[i, k] L⁻¹[k, c]) / L[i, i], c ≤ i."""
    for i in range(n):
        for c in range(i):
            Li[i, c] = 0.0
        Li[i, i] = 1.0
        for k in range(i):
            lik = Lt[k, i]
            for c in range(k + 1):
                Li[i, c] -= lik * Li[k, c]
        d = Lt[i, i]
        for c in range(i + 1):
            Li[i, c] = Li[i, c] / d


@kernel
def _inverse_gram(Li, Pb, n):
    """Pb = L⁻ᵀ L⁻¹: Pb[i, j] = Σ_{k≥i} L⁻¹[k, i] L⁻¹[k, j] for j ≤ i (row i), mirrored."""
    for i in range(n):
        for j in range(i + 1):
            Pb[i, j] = 0.0
        for k in range(i, n):
            lki = Li[k, i]
            for j in range(i + 1):
                Pb[i, j] += lki * Li[k, j]
        for j in range(i):
            Pb[j, i] = Pb[i, j]
