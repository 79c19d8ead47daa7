"""The compiled measurement update, removal and read of the sparse coupled filter (package docstring).

A plot z of aircraft i by radar j (−1: unbiased) is applied in named steps: predict aircraft i to the
plot's time, linearise the plot's model (C_x, C_s of radar j's m_j components, R_eff, d: module
``_measurement``), form the innovation ν = z − ẑ, ẑ = C_x x̄ + C_s ς̂_j + d, and its covariance Λ from the
conditional (1)–(2) of the package docstring, add the plot's rank-2 term to S, sv, add Hᵀ R_eff⁻¹ H and
Hᵀ R_eff⁻¹ (z − d) to the information blocks, and downdate the bias marginal P_ς −= K_b Λ⁻¹ K_bᵀ,
ς̂ += K_b Λ⁻¹ ν. Every kernel returns a status code (``OK`` or one of the ``ERR_*`` of :mod:`._layout`)
instead of producing NaN.
"""

from __future__ import annotations

import numpy as np

from radartracker.api import kernel

from ._layout import (C_ALIVE, C_REBUILD_FACTOR, C_REFRESH_EVERY, C_SINCE_REBUILD, C_SINCE_REFRESH, ERR_LAMBDA,
                      ERR_NONFINITE, ERR_R, ERR_REBUILD, ERR_S, ERR_YII, OK, carve, carve_work)
from ._linalg import add_contribution, bias_index, chol, conditional, inverse_factor
from ._measurement import linearise, project
from ._predict import predict
from ._refresh import rebuild, refresh


@kernel
def update_rows(F, I, WF, slots, radars, times, z, C, R, rho, out):
    """:func:`update_one` of rows 0, 1, … in order (aircraft slot, radar index −1 for unbiased, time, z, C,
    R, slant range ρ), each row's ν, Λ and NIS into ``out[k]`` ([0:2], [2:6], [6]); returns (status code, the
    row it stopped at: the number of rows when every one was applied, the latest time applied or NaN)."""
    nb = I[2]
    st, wk = carve(F, I), carve_work(WF, max(nb, 1))
    io = wk[8]
    latest = np.nan
    for k in range(len(slots)):
        code = update_one(st, wk, slots[k], radars[k], times[k], z[k], C[k], R[k], rho[k])
        if code == OK or code == ERR_LAMBDA or code == ERR_S or code == ERR_REBUILD:  # applied or predicted
            if not times[k] <= latest:
                latest = times[k]
        if code != OK:
            return code, k, latest
        for a in range(7):
            out[k, a] = io[a]
    return OK, len(slots), latest


@kernel
def update_one(st, wk, s, j, t, z, C, R, rho):
    """Predict aircraft slot s to t and correct it with plot z (base Jacobian C = ∂p/∂(ρ, θ), noise R, slant
    range ρ) of radar j (−1: unbiased), linearised by :func:`~._measurement.linearise`. ν, Λ and the NIS go
    to ``io`` = wk[8] ([0:2], [2:6], [6]); returns the status code."""
    Yxx, Yxb, ex, tx, Ybb, eb, S, sv, Pb, bh, nk, rk, ctr, rt, idx = st
    f4, V, G, W, v4, Kb, LS, LSi, io = wk
    dt = t - tx[s]
    if not _finite(dt, z, C, R) or (j >= 0 and rt[j, 2] >= 0 and not np.isfinite(rho)):
        return ERR_NONFINITE
    Rs, Lr = f4[12], f4[8]
    for a in range(2):
        for b in range(2):
            Rs[a, b] = 0.5 * (R[a, b] + R[b, a])
    if not chol(Rs, Lr, 2):
        return ERR_R
    cj = _radar_column(nk, rk, rt, Yxb, s, j)
    nK = bias_index(rk, rt, s, max(nk[s], 0), idx)
    if dt != 0.0:
        code = predict(Yxx, Yxb, ex, Ybb, eb, s, nK, idx, dt, io[7], f4, V, G, W, v4)
        if code != OK:
            return code
    tx[s] = t
    L, Li, mx, ze = f4[7], f4[5], v4[3], v4[4]
    if not conditional(Yxx, Yxb, ex, s, nK, L, V, v4[2], G, mx):
        return ERR_YII
    inverse_factor(L, f4[3], Li)
    Cx, Cs, M, CG = f4[13], f4[14], f4[15], W[2:4]
    w = linearise(G, mx, Li, bh, Pb, idx, nK, rt, j, C, rho, z, Cx, Cs, Rs, ze)
    if not chol(Rs, Lr, 2):
        return ERR_R
    project(Cx, G, Li, nK, CG, M)
    o = rt[j, 0] if j >= 0 else 0
    zh0, zh1 = _predicted_measurement(mx, G, bh, idx, nK, Cx, Cs, o, w, z, ze)
    _bias_gain(Pb, CG, idx, nK, Cs, o, w, Kb)
    Lam, Ll = f4[10], f4[11]
    _innovation_covariance(M, CG, Kb, idx, nK, Rs, Cs, o, w, Lam)
    if not chol(Lam, Ll, 2):
        return ERR_LAMBDA
    nu0, nu1 = z[0] - zh0, z[1] - zh1
    w0 = nu0 / Ll[0, 0]
    w1 = (nu1 - Ll[1, 0] * w0) / Ll[1, 1]
    io[0], io[1] = nu0, nu1
    io[2], io[3], io[4], io[5] = Lam[0, 0], Lam[0, 1], Lam[1, 0], Lam[1, 1]
    if not _schur_update(S, sv, M, Rs, mx, Cx, CG, Cs, ze, cj, w, nK, idx, W, Lam, f4[6]):
        return ERR_R
    _information_update(Yxx[s], Yxb[s], ex[s], Ybb, eb, o, w, cj, ze, Cx, Cs, Lr, f4[9], f4[4], f4[3])
    _bias_downdate(Pb, bh, Kb, Ll, w0, w1)
    io[6] = w0 * w0 + w1 * w1
    return _maintain(st, wk)


@kernel
def _finite(dt, z, C, R):
    """Whether dt, z, C and R are all finite."""
    if not (np.isfinite(dt) and np.isfinite(z[0]) and np.isfinite(z[1])):
        return False
    for a in range(2):
        for b in range(2):
            if not (np.isfinite(C[a, b]) and np.isfinite(R[a, b])):
                return False
    return True


@kernel
def _radar_column(nk, rk, rt, Yxb, s, j):
    """The first of radar j's columns among aircraft s's bias columns, given them (zero Y_ib) if new; −1 for
    j = −1. The caller guarantees rk[s, :nk[s]] distinct radars, so a new one fits in the row."""
    if j < 0:
        return -1
    k = nk[s]
    col = 0
    for c in range(k):
        if rk[s, c] == j:
            return col
        col += rt[rk[s, c], 1]
    rk[s, k] = j
    for r in range(4):
        for e in range(rt[j, 1]):
            Yxb[s, r, col + e] = 0.0
    nk[s] = k + 1
    return col


@kernel
def _predicted_measurement(mx, G, bh, idx, nK, Cx, Cs, o, w, z, ze):
    """ẑ = C_x x̄ + C_s ς̂_j + d with x̄ = m − G ς̂_K and d = z − ze (radar j's w entries from o)."""
    zh0, zh1 = z[0] - ze[0, 0], z[1] - ze[1, 0]
    for r in range(4):
        xr = mx[r, 0]
        for c in range(nK):
            xr -= G[r, c] * bh[idx[c]]
        zh0 += Cx[0, r] * xr
        zh1 += Cx[1, r] * xr
    for e in range(w):
        zh0 += Cs[0, e] * bh[o + e]
        zh1 += Cs[1, e] * bh[o + e]
    return zh0, zh1


@kernel
def _bias_gain(Pb, CG, idx, nK, Cs, o, w, Kb):
    """Kbᵀ = Cov(ς, h) = −Pb[:, K] (C_x G)ᵀ + Pb[:, J] C_sᵀ (h = H ξ, J radar j's w entries from o), one row
    of Kb per column.

    Pb is exactly symmetric (refresh writes both halves, the downdate's (p, r) and (r, p) terms are the same
    products), so its column c is its row c: contiguous loops over p."""
    nb = Pb.shape[0]
    K0, K1 = Kb[0], Kb[1]
    for p in range(nb):
        K0[p] = 0.0
        K1[p] = 0.0
    for c in range(nK):
        row = Pb[idx[c]]
        g0, g1 = CG[0, c], CG[1, c]
        for p in range(nb):
            K0[p] -= row[p] * g0
            K1[p] -= row[p] * g1
    for e in range(w):
        row = Pb[o + e]
        c0, c1 = Cs[0, e], Cs[1, e]
        for p in range(nb):
            K0[p] += row[p] * c0
            K1[p] += row[p] * c1


@kernel
def _innovation_covariance(M, CG, Kb, idx, nK, Rs, Cs, o, w, Lam):
    """Λ = C_x Cov(χ, h) + C_s Cov(ς_j, h) + R_eff with Cov(χ, h) = Σ C_xᵀ − G Kb[K] (χ = m − Gς_K + e,
    C_x Σ C_xᵀ = MᵀM), exactly symmetric."""
    for a in range(2):
        for b in range(2):
            acc = 0.0
            for r in range(4):
                acc += M[r, a] * M[r, b]
            for c in range(nK):
                acc -= CG[a, c] * Kb[b, idx[c]]
            for e in range(w):
                acc += Cs[a, e] * Kb[b, o + e]
            Lam[a, b] = acc + Rs[a, b]
    l01 = 0.5 * (Lam[0, 1] + Lam[1, 0])
    Lam[0, 1] = l01
    Lam[1, 0] = l01


@kernel
def _schur_update(S, sv, M, Rs, mx, Cx, CG, Cs, ze, cj, w, nK, idx, W, Om, Lo):
    """S += H_bᵀ Ω⁻¹ H_b, sv += H_bᵀ Ω⁻¹ (ze − C_x m) with H_b = C_s E_j − C_x G, Ω = R_eff + C_x Σ C_xᵀ: the
    plot with χ_i eliminated through its conditional (a PSD rank-2 term; radar j's w columns from cj).
    False if Ω is not positive definite. W[:2], Om, Lo: scratch (W[2:4] holds CG)."""
    for a in range(2):
        for b in range(2):
            Om[a, b] = Rs[a, b]
            for r in range(4):
                Om[a, b] += M[r, a] * M[r, b]
    if not chol(Om, Lo, 2):
        return False
    r0, r1 = ze[0, 0], ze[1, 0]
    for r in range(4):
        r0 -= Cx[0, r] * mx[r, 0]
        r1 -= Cx[1, r] * mx[r, 0]
    o0 = r0 / Lo[0, 0]
    o1 = (r1 - Lo[1, 0] * o0) / Lo[1, 1]
    for c in range(nK):  # W[:2] = L_Ω⁻¹ H_b
        h0, h1 = -CG[0, c], -CG[1, c]
        if cj <= c < cj + w:
            h0 += Cs[0, c - cj]
            h1 += Cs[1, c - cj]
        f0 = h0 / Lo[0, 0]
        W[0, c] = f0
        W[1, c] = (h1 - Lo[1, 0] * f0) / Lo[1, 1]
    for a in range(nK):
        sv[idx[a]] += W[0, a] * o0 + W[1, a] * o1
        for b in range(a + 1):
            d = W[0, a] * W[0, b] + W[1, a] * W[1, b]
            S[idx[a], idx[b]] += d
            if b != a:
                S[idx[b], idx[a]] += d
    return True


@kernel
def _information_update(Y, Yb, e, Ybb, eb, o, w, cj, ze, Cx, Cs, Lr, Ri, RC, RCs):
    """Y += Hᵀ R_eff⁻¹ H, η += Hᵀ R_eff⁻¹ ze with H = [C_x at the aircraft, C_s at radar j] (R_eff⁻¹ from its
    factor Lr): the aircraft's Y_ii, η_i, its columns cj … cj + w − 1 of Y_ib, and radar j's w entries from o
    of Y_bb, η_b. Ri, RC, RCs: scratch."""
    i00 = 1.0 / Lr[0, 0]
    i11 = 1.0 / Lr[1, 1]
    i10 = -Lr[1, 0] * i00 * i11
    Ri[0, 0] = i00 * i00 + i10 * i10
    Ri[0, 1] = Ri[1, 0] = i10 * i11
    Ri[1, 1] = i11 * i11
    rz0 = Ri[0, 0] * ze[0, 0] + Ri[0, 1] * ze[1, 0]
    rz1 = Ri[1, 0] * ze[0, 0] + Ri[1, 1] * ze[1, 0]
    _gram_update(Cx, Cx, Ri, RC, 4, Y, 0, True)  # C_xᵀ R⁻¹ C_x
    for a in range(4):
        e[a] += Cx[0, a] * rz0 + Cx[1, a] * rz1
    if w == 0:
        return
    _gram_update(Cs, Cx, Ri, RCs, w, Yb, cj, False)  # C_xᵀ R⁻¹ C_s
    _gram_update(Cs, Cs, Ri, RCs, w, Ybb[o:o + w], o, True)  # C_sᵀ R⁻¹ C_s
    for a in range(w):
        eb[o + a] += Cs[0, a] * rz0 + Cs[1, a] * rz1


@kernel
def _gram_update(B, A, Ri, RB, nc, out, col, symmetric):
    """out[a, col + b] += (Aᵀ R⁻¹ B)[a, b] for the rows a of ``out`` and b < nc (RB = R⁻¹ B: scratch); when
    ``symmetric`` (A = B, out square from ``col``) the lower triangle is computed and mirrored."""
    for a in range(2):
        for b in range(nc):
            RB[a, b] = Ri[a, 0] * B[0, b] + Ri[a, 1] * B[1, b]
    for a in range(out.shape[0]):
        for b in range(a + 1 if symmetric else nc):
            d = A[0, a] * RB[0, b] + A[1, a] * RB[1, b]
            out[a, col + b] += d
            if symmetric and b != a:
                out[b, col + a] += d


@kernel
def _bias_downdate(Pb, bh, Kb, Ll, w0, w1):
    """Pb −= U Uᵀ, ς̂ += U w with U = Kb L_Λ⁻ᵀ (Kb's rows overwritten by U's columns) and w = L_Λ⁻¹ ν."""
    nb = Pb.shape[0]
    K0, K1 = Kb[0], Kb[1]
    l00, l10, l11 = Ll[0, 0], Ll[1, 0], Ll[1, 1]
    for p in range(nb):
        a0 = K0[p] / l00
        K1[p] = (K1[p] - l10 * a0) / l11
        K0[p] = a0
    for p in range(nb):
        up0, up1 = K0[p], K1[p]
        bh[p] += up0 * w0 + up1 * w1
        row = Pb[p]
        for r in range(nb):
            row[r] -= up0 * K0[r] + up1 * K1[r]


@kernel
def _maintain(st, wk):
    """Count the update; rebuild S from the blocks every rebuild_factor × (n + 1) updates and reset P_ς, ς̂
    from S every refresh_every updates (ERR_REBUILD, ERR_S if that fails; the update itself stands)."""
    S, sv, Pb, bh, ctr = st[6], st[7], st[8], st[9], st[12]
    ctr[C_SINCE_REFRESH] += 1
    ctr[C_SINCE_REBUILD] += 1
    if ctr[C_SINCE_REBUILD] >= ctr[C_REBUILD_FACTOR] * (ctr[C_ALIVE] + 1):
        if not rebuild(st, wk):
            return ERR_REBUILD
    if ctr[C_SINCE_REFRESH] >= ctr[C_REFRESH_EVERY]:
        if not refresh(S, sv, Pb, bh, ctr, wk[6], wk[7]):
            return ERR_S
    return OK


@kernel
def marginalise(st, wk, s):
    """Remove aircraft slot s: Y_bb −= Y_bi Y_ii⁻¹ Y_ib, η_b −= Y_bi Y_ii⁻¹ η_i (S unchanged), slot freed.
    Returns OK, or ERR_YII (nothing changed) if its Y_ii is not positive definite."""
    Yxx, Yxb, ex, tx, Ybb, eb, S, sv, Pb, bh, nk, rk, ctr, rt, idx = st
    f4, V, G, W, v4, Kb, LS, LSi, io = wk
    k = nk[s]
    if k > 0:
        nK = bias_index(rk, rt, s, k, idx)
        if not conditional(Yxx, Yxb, ex, s, nK, f4[0], V, v4[0], G, v4[1]):
            return ERR_YII
        add_contribution(Ybb, eb, idx, V, v4[0], nK, -1.0)
    nk[s] = -1
    ctr[C_ALIVE] -= 1
    return OK


@kernel
def read_aircraft(st, wk, s, out_x, out_P):
    """χ̂_i = m − G ς̂_K and P_i = Y_ii⁻¹ + G Pb[K, K] Gᵀ (no dense matrix formed); False if Y_ii ⋡ 0."""
    Yxx, Yxb, ex, tx, Ybb, eb, S, sv, Pb, bh, nk, rk, ctr, rt, idx = st
    f4, V, G, W, v4, Kb, LS, LSi, io = wk
    nK = bias_index(rk, rt, s, max(nk[s], 0), idx)
    L, Li = f4[0], f4[1]
    if not conditional(Yxx, Yxb, ex, s, nK, L, V, v4[0], G, v4[1]):
        return False
    for a in range(4):
        acc = v4[1][a, 0]
        for c in range(nK):
            acc -= G[a, c] * bh[idx[c]]
        out_x[a] = acc
    inverse_factor(L, f4[2], Li)
    for a in range(4):
        for c in range(nK):  # W = G Pb[K, K]
            acc = 0.0
            for d in range(nK):
                acc += G[a, d] * Pb[idx[d], idx[c]]
            W[a, c] = acc
    for a in range(4):
        for b in range(a + 1):
            acc = 0.0
            for r in range(4):
                acc += Li[r, a] * Li[r, b]
            for c in range(nK):
                acc += W[a, c] * G[b, c]
            out_P[a, b] = acc
            out_P[b, a] = acc
    return True
