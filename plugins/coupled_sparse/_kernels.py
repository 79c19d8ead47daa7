"""Numba kernels of the sparse information-form coupled filter (see the package docstring).

Storage, for aircraft slot ``s`` with ``nk[s]`` observing radars ``rk[s, :nk[s]]``:
``Yxx[s]`` = Y_ii (4×4), ``Yxb[s, :, 2c:2c+2]`` = Y_ib for the c-th of those radars, ``ex[s]`` = η_i.
Global: ``Ybb``, ``eb`` (bias information, including what removed aircraft taught), the Schur
complement ``S`` = Y_bb − Σ_i Y_bi Y_ii⁻¹ Y_ib and ``sv`` = η_b − Σ_i Y_bi Y_ii⁻¹ η_i kept
incrementally, and the bias marginal ``Pb`` = S⁻¹, ``bh`` = S⁻¹ sv kept by rank-2 updates and
reset from S every ``refresh_every`` updates.

With L Lᵀ = Y_ii, V = L⁻¹ Y_ib and u = L⁻¹ η_i, aircraft i contributes VᵀV to Y_bb − S and Vᵀu
to η_b − sv (exactly symmetric), and its conditional given the biases is
χ_i | ς ~ N(m_i − G_i ς_K, Y_ii⁻¹) with G_i = L⁻ᵀV, m_i = L⁻ᵀu.

Every kernel returns a status code (``OK`` or one of the ``ERR_*``) instead of producing NaN.
"""

from __future__ import annotations

import numpy as np
from numba import njit

OK = 0
ERR_NONFINITE = 1  # z, C, R or dt not finite
ERR_R = 2  # R not positive definite (the information form needs R⁻¹)
ERR_YII = 3  # an aircraft's information block Y_ii not positive definite
ERR_LAMBDA = 4  # innovation covariance Λ not positive definite
ERR_S = 5  # bias Schur complement S not positive definite
ERR_REBUILD = 6  # recomputing S from the blocks met an aircraft whose Y_ii is not positive definite

# ctr: [updates since refresh, refresh_every, updates since rebuild, rebuild_factor, n alive]
C_SINCE_REFRESH, C_REFRESH_EVERY, C_SINCE_REBUILD, C_REBUILD_FACTOR, C_ALIVE = range(5)


@njit(cache=True)
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


@njit(cache=True)
def _lsolve(L, B, X, n, nc):
    """X[:n, :nc] = L⁻¹ B[:n, :nc] (forward substitution)."""
    for c in range(nc):
        for i in range(n):
            s = B[i, c]
            for k in range(i):
                s -= L[i, k] * X[k, c]
            X[i, c] = s / L[i, i]


@njit(cache=True)
def _ltsolve(L, B, X, n, nc):
    """X[:n, :nc] = L⁻ᵀ B[:n, :nc] (back substitution)."""
    for c in range(nc):
        for i in range(n - 1, -1, -1):
            s = B[i, c]
            for k in range(i + 1, n):
                s -= L[k, i] * X[k, c]
            X[i, c] = s / L[i, i]


@njit(cache=True)
def _identity(T):
    for i in range(T.shape[0]):
        for j in range(T.shape[1]):
            T[i, j] = 1.0 if i == j else 0.0


@njit(cache=True)
def _gram(X, out):
    """out = Xᵀ X for 4×4 X (exactly symmetric)."""
    for i in range(4):
        for j in range(i + 1):
            acc = 0.0
            for k in range(4):
                acc += X[k, i] * X[k, j]
            out[i, j] = acc
            out[j, i] = acc


@njit(cache=True)
def bias_index(rk, s, nk, idx):
    """idx[:2k] = positions in the bias vector of aircraft s's radars, in their storage order."""
    for c in range(nk):
        idx[2 * c] = 2 * rk[s, c]
        idx[2 * c + 1] = 2 * rk[s, c] + 1


@njit(cache=True)
def conditional(Yxx, Yxb, ex, s, nK, L, V, u, G, mx):
    """Factor Y_ii = L Lᵀ and form V = L⁻¹Y_ib, u = L⁻¹η_i, G = L⁻ᵀV, m = L⁻ᵀu; False if Y_ii ⋡ 0."""
    if not chol(Yxx[s], L, 4):
        return False
    _lsolve(L, Yxb[s], V, 4, nK)
    _lsolve(L, ex[s].reshape(4, 1), u, 4, 1)
    _ltsolve(L, V, G, 4, nK)
    _ltsolve(L, u, mx, 4, 1)
    return True


@njit(cache=True)
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


@njit(cache=True)
def _transition(dt, q, A, Q):
    """Constant-velocity A(dt), Q(dt) exactly as radartracker.motion.MotionModel.transition."""
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


# Packed storage: every array of the estimator (and of its scratch) is a view into one float and one
# int buffer, and the int buffer starts with the dimensions, so the single-update kernel takes nine
# arguments instead of 32 (numba's dispatch costs about 0.15 µs per array argument, a tenth of the
# update's arithmetic). carve() is the one layout.

def storage_sizes(cap: int, mm: int, nb: int) -> tuple[int, int]:
    """Lengths of the float and int buffers for ``cap`` aircraft slots, ``mm`` radar columns, ``nb`` biases."""
    return cap * (16 + 8 * mm + 4 + 1) + 3 * nb * nb + 3 * nb, 3 + cap * (1 + mm) + 5 + 2 * mm


@njit(cache=True)
def carve(F, I, cap, mm, nb):
    """(Yxx, Yxb, ex, tx, Ybb, eb, S, sv, Pb, bh, nk, rk, ctr, idx) as views into F and I; I[:3] holds
    (cap, mm, nb), written by the caller; idx is the kernels' scratch of bias positions."""
    o = 0
    Yxx = F[o:o + cap * 16].reshape((cap, 4, 4))
    o += cap * 16
    Yxb = F[o:o + cap * 8 * mm].reshape((cap, 4, 2 * mm))
    o += cap * 8 * mm
    ex = F[o:o + cap * 4].reshape((cap, 4))
    o += cap * 4
    tx = F[o:o + cap]
    o += cap
    Ybb = F[o:o + nb * nb].reshape((nb, nb))
    o += nb * nb
    eb = F[o:o + nb]
    o += nb
    S = F[o:o + nb * nb].reshape((nb, nb))
    o += nb * nb
    sv = F[o:o + nb]
    o += nb
    Pb = F[o:o + nb * nb].reshape((nb, nb))
    o += nb * nb
    bh = F[o:o + nb]
    o = 3
    nk = I[o:o + cap]
    o += cap
    rk = I[o:o + cap * mm].reshape((cap, mm))
    o += cap * mm
    ctr = I[o:o + 5]
    o += 5
    idx = I[o:o + 2 * mm]
    return Yxx, Yxb, ex, tx, Ybb, eb, S, sv, Pb, bh, nk, rk, ctr, idx


def work_size(nbw: int) -> int:
    return 13 * 16 + 3 * 4 * nbw + 24 + 2 * nbw + 2 * nbw * nbw + 8


@njit(cache=True)
def carve_work(WF, nbw):
    """Scratch (f4, V, G, W, v4, Kb, LS, LSi, io) as views into WF; io = [ν (2), Λ (4), NIS, q] of
    :func:`update_packed`."""
    f4 = WF[0:208].reshape((13, 4, 4))  # 4×4 scratch: [0:7] predict, [3:13] update_one
    o = 208
    V = WF[o:o + 4 * nbw].reshape((4, nbw))
    o += 4 * nbw
    G = WF[o:o + 4 * nbw].reshape((4, nbw))
    o += 4 * nbw
    W = WF[o:o + 4 * nbw].reshape((4, nbw))
    o += 4 * nbw
    v4 = WF[o:o + 24].reshape((6, 4, 1))
    o += 24
    Kb = WF[o:o + 2 * nbw].reshape((2, nbw))  # rows: the two columns of K_b, each contiguous
    o += 2 * nbw
    LS = WF[o:o + nbw * nbw].reshape((nbw, nbw))
    o += nbw * nbw
    LSi = WF[o:o + nbw * nbw].reshape((nbw, nbw))
    o += nbw * nbw
    io = WF[o:o + 8]
    return f4, V, G, W, v4, Kb, LS, LSi, io


class Work:
    """Scratch arrays for the kernels (allocated once per estimator, sized for ``m`` radars), views into
    one buffer ``flat`` (:func:`carve_work`) and ``idx`` (in the int storage, :func:`carve`); ``q`` is
    kept in ``io`` for :func:`update_packed`, which leaves there ν, Λ and the NIS of its update."""

    def __init__(self, m: int, idx: np.ndarray, q: float) -> None:
        self.nbw = 2 * max(m, 1)
        self.flat = np.zeros(work_size(self.nbw))
        self.f4, self.V, self.G, self.W, self.v4, self.Kb, self.LS, self.LSi, self.io = carve_work(self.flat,
                                                                                                   self.nbw)
        self.idx = idx
        self.nu, self.lam = self.io[0:2], self.io[2:6].reshape(2, 2)
        self.io[7] = q


@njit(cache=True)
def predict(Yxx, Yxb, ex, Ybb, eb, s, nK, idx, dt, q, f4, V, G, W, v4):
    """Predict aircraft s by dt in information form, keeping the arrowhead (package docstring)."""
    L, A, Q, Sg, T, Yn, Ln = f4[0], f4[1], f4[2], f4[3], f4[4], f4[5], f4[6]
    u, mx = v4[0], v4[1]
    _transition(dt, q, A, Q)
    if q == 0.0 or dt == 0.0:
        # Y' = A⁻ᵀ Y A⁻¹, Y_ib' = A⁻ᵀ Y_ib, η' = A⁻ᵀ η with A⁻¹ = A(−dt): Y_bb, S unchanged
        Y = Yxx[s]
        for c in range(4):  # rows: (A⁻ᵀ M)[2+r] = M[2+r] − dt·M[r] for r = 0, 1
            for r in range(2):
                Y[2 + r, c] -= dt * Y[r, c]
        for r in range(4):
            for c in range(2):
                Y[r, 2 + c] -= dt * Y[r, c]
        for c in range(nK):
            for r in range(2):
                Yxb[s, 2 + r, c] -= dt * Yxb[s, r, c]
        for r in range(2):
            ex[s, 2 + r] -= dt * ex[s, r]
        for r in range(4):  # the two passes round differently: restore exact symmetry
            for c in range(r):
                y = 0.5 * (Y[r, c] + Y[c, r])
                Y[r, c] = y
                Y[c, r] = y
        return OK
    if not conditional(Yxx, Yxb, ex, s, nK, L, V, u, G, mx):
        return ERR_YII
    # Σ = L⁻ᵀL⁻¹;  Σ' = A Σ Aᵀ + Q;  Y' = Σ'⁻¹ (into T)
    _identity(T)
    _lsolve(L, T, Yn, 4, 4)  # Yn = L⁻¹
    _gram(Yn, Sg)  # Σ
    for i in range(4):
        for j in range(4):
            acc = 0.0
            for k in range(4):
                acc += A[i, k] * Sg[k, j]
            T[i, j] = acc
    for i in range(4):
        for j in range(i + 1):
            acc = Q[i, j]
            for k in range(4):
                acc += T[i, k] * A[j, k]
            Sg[i, j] = acc
            Sg[j, i] = acc
    if not chol(Sg, Ln, 4):
        return ERR_YII
    _identity(T)
    _lsolve(Ln, T, Yn, 4, 4)
    _gram(Yn, T)  # T = Y'
    # Y_bb' − Y_bb = c_i' − c_i = −Gᵀ M G with M = Y − Aᵀ Y' A (η_b: −Gᵀ M m)
    for i in range(4):
        for j in range(i + 1):
            acc = Yxx[s, i, j]
            for k in range(4):
                for l in range(4):
                    acc -= A[k, i] * T[k, l] * A[l, j]
            Sg[i, j] = acc
            Sg[j, i] = acc
    for c in range(nK):
        for i in range(4):
            acc = 0.0
            for k in range(4):
                acc += Sg[i, k] * G[k, c]
            W[i, c] = acc
    for a in range(nK):
        acc = 0.0
        for r in range(4):
            for k in range(4):
                acc += G[r, a] * Sg[r, k] * mx[k, 0]
        eb[idx[a]] -= acc
        for b in range(a + 1):
            acc = 0.0
            for r in range(4):
                acc += G[r, a] * W[r, b]
            Ybb[idx[a], idx[b]] -= acc
            if b != a:
                Ybb[idx[b], idx[a]] -= acc
    # Y_ii' = Y', Y_ib' = Y' A G, η_i' = Y' A m
    for c in range(nK):
        for i in range(4):
            acc = 0.0
            for k in range(4):
                acc += A[i, k] * G[k, c]
            W[i, c] = acc
    for i in range(4):
        acc = 0.0
        for k in range(4):
            acc += A[i, k] * mx[k, 0]
        u[i, 0] = acc
    for i in range(4):
        for j in range(4):
            Yxx[s, i, j] = T[i, j]
    for c in range(nK):
        for i in range(4):
            acc = 0.0
            for k in range(4):
                acc += T[i, k] * W[k, c]
            Yxb[s, i, c] = acc
    for i in range(4):
        acc = 0.0
        for k in range(4):
            acc += T[i, k] * u[k, 0]
        ex[s, i] = acc
    return OK


@njit(cache=True)
def update_one(Yxx, Yxb, ex, tx, nk, rk, Ybb, eb, S, sv, Pb, bh, ctr,
               s, j, t, z, C, R, q, out_nu, out_lam, f4, V, G, W, v4, idx, Kb, LS, LSi):
    """Predict aircraft s to t and correct it with plot z of radar j (−1: unbiased). Returns (code, nis)."""
    dt = t - tx[s]
    if not (np.isfinite(dt) and np.isfinite(z[0]) and np.isfinite(z[1])):
        return ERR_NONFINITE, 0.0
    for a in range(2):
        for b in range(2):
            if not (np.isfinite(C[a, b]) and np.isfinite(R[a, b])):
                return ERR_NONFINITE, 0.0
    L, Lr, Ri, Lam, Ll = f4[7], f4[8], f4[9], f4[10], f4[11]
    Rs = f4[12]
    for a in range(2):
        for b in range(2):
            Rs[a, b] = 0.5 * (R[a, b] + R[b, a])
    if not chol(Rs, Lr, 2):
        return ERR_R, 0.0
    # make room for radar j in aircraft s's bias columns
    k = nk[s]
    cj = -1
    if j >= 0:
        for c in range(k):
            if rk[s, c] == j:
                cj = c
        if cj < 0:
            cj = k
            rk[s, k] = j
            for r in range(4):
                Yxb[s, r, 2 * k] = 0.0
                Yxb[s, r, 2 * k + 1] = 0.0
            k += 1
            nk[s] = k
    nK = 2 * k
    bias_index(rk, s, k, idx)
    if dt != 0.0:
        code = predict(Yxx, Yxb, ex, Ybb, eb, s, nK, idx, dt, q, f4, V, G, W, v4)
        if code != OK:
            return code, 0.0
    tx[s] = t
    u, mx = v4[2], v4[3]
    if not conditional(Yxx, Yxb, ex, s, nK, L, V, u, G, mx):
        return ERR_YII, 0.0
    nb = Pb.shape[0]
    # x̄ = m − G ς̂_K; Kbᵀ = Cov(ς, h) = −Pb[:, K] G[:2]ᵀ + Pb[:, j] Cᵀ  (h = C_x χ + C ς_j)
    xb0 = mx[0, 0]
    xb1 = mx[1, 0]
    for c in range(nK):
        xb0 -= G[0, c] * bh[idx[c]]
        xb1 -= G[1, c] * bh[idx[c]]
    zh0, zh1 = xb0, xb1
    if j >= 0:
        zh0 += C[0, 0] * bh[2 * j] + C[0, 1] * bh[2 * j + 1]
        zh1 += C[1, 0] * bh[2 * j] + C[1, 1] * bh[2 * j + 1]
    # Pb is exactly symmetric (refresh writes both halves, the downdate's (p, r) and (r, p) terms are the
    # same products), so its column c is its row c: contiguous loops over p, each K_b entry summed in the
    # same order as the column-wise sum
    K0, K1 = Kb[0], Kb[1]
    for p in range(nb):
        K0[p] = 0.0
        K1[p] = 0.0
    for c in range(nK):
        row = Pb[idx[c]]
        g0 = G[0, c]
        g1 = G[1, c]
        for p in range(nb):
            K0[p] -= row[p] * g0
            K1[p] -= row[p] * g1
    if j >= 0:
        r0 = Pb[2 * j]
        r1 = Pb[2 * j + 1]
        c00, c01, c10, c11 = C[0, 0], C[0, 1], C[1, 0], C[1, 1]
        for p in range(nb):
            K0[p] += r0[p] * c00 + r1[p] * c01
            K1[p] += r0[p] * c10 + r1[p] * c11
    # Λ = C_x Cov(χ, h) + C_s Cov(ς_j, h) + R with Cov(χ, h) = Σ[:, :2] − G Kb[K] (χ = m − Gς_K + e)
    Sg = f4[3]
    for a in range(4):
        for b in range(4):
            Sg[a, b] = 1.0 if a == b else 0.0
    _lsolve(L, Sg, f4[5], 4, 4)
    Li = f4[5]
    for a in range(2):
        for b in range(2):
            acc = 0.0
            for r in range(4):
                acc += Li[r, a] * Li[r, b]
            for c in range(nK):
                acc -= G[a, c] * Kb[b, idx[c]]
            Lam[a, b] = acc + Rs[a, b]
    if j >= 0:  # + C Cov(ς_j, h)
        for a in range(2):
            for b in range(2):
                Lam[a, b] += C[a, 0] * Kb[b, 2 * j] + C[a, 1] * Kb[b, 2 * j + 1]
    l01 = 0.5 * (Lam[0, 1] + Lam[1, 0])
    Lam[0, 1] = l01
    Lam[1, 0] = l01
    if not chol(Lam, Ll, 2):
        return ERR_LAMBDA, 0.0
    nu0 = z[0] - zh0
    nu1 = z[1] - zh1
    w0 = nu0 / Ll[0, 0]
    w1 = (nu1 - Ll[1, 0] * w0) / Ll[1, 1]
    out_nu[0] = nu0
    out_nu[1] = nu1
    for a in range(2):
        for b in range(2):
            out_lam[a, b] = Lam[a, b]
    # --- commit. S: eliminating χ_i from its conditional χ_i | ς ~ N(m − Gς_K, Σ) turns the plot into
    # z − C_x m = H_b ς_K + noise(Ω), H_b = C_s E_j − C_x G, Ω = R + C_x Σ C_xᵀ, so
    # ΔS = ΔY_bb − (c_i' − c_i) = H_bᵀ Ω⁻¹ H_b and Δs = H_bᵀ Ω⁻¹ (z − C_x m): a PSD rank-2 term.
    Lo = f4[6]
    for a in range(2):
        for b in range(2):
            Lam[a, b] = Rs[a, b]
            for r in range(4):
                Lam[a, b] += Li[r, a] * Li[r, b]
    if not chol(Lam, Lo, 2):
        return ERR_R, 0.0
    o0 = (z[0] - mx[0, 0]) / Lo[0, 0]
    o1 = (z[1] - mx[1, 0] - Lo[1, 0] * o0) / Lo[1, 1]
    for c in range(nK):  # W[:2] = L_Ω⁻¹ H_b
        h0 = -G[0, c]
        h1 = -G[1, c]
        if c // 2 == cj:
            h0 += C[0, c % 2]
            h1 += C[1, c % 2]
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
    # information update of the blocks: Y += Hᵀ R⁻¹ H, η += Hᵀ R⁻¹ z
    i00 = 1.0 / Lr[0, 0]
    i11 = 1.0 / Lr[1, 1]
    i10 = -Lr[1, 0] * i00 * i11
    Ri[0, 0] = i00 * i00 + i10 * i10
    Ri[0, 1] = Ri[1, 0] = i10 * i11
    Ri[1, 1] = i11 * i11
    rz0 = Ri[0, 0] * z[0] + Ri[0, 1] * z[1]
    rz1 = Ri[1, 0] * z[0] + Ri[1, 1] * z[1]
    for a in range(2):
        for b in range(2):
            Yxx[s, a, b] += Ri[a, b]
    ex[s, 0] += rz0
    ex[s, 1] += rz1
    if j >= 0:
        RC = f4[4]  # R⁻¹ C
        for a in range(2):
            for b in range(2):
                RC[a, b] = Ri[a, 0] * C[0, b] + Ri[a, 1] * C[1, b]
        for a in range(2):
            for b in range(2):
                Yxb[s, a, 2 * cj + b] += RC[a, b]
        for a in range(2):
            for b in range(a + 1):
                d = C[0, a] * RC[0, b] + C[1, a] * RC[1, b]  # Cᵀ R⁻¹ C
                Ybb[2 * j + a, 2 * j + b] += d
                if a != b:
                    Ybb[2 * j + b, 2 * j + a] += d
            eb[2 * j + a] += C[0, a] * rz0 + C[1, a] * rz1  # Cᵀ R⁻¹ z
    # Pb −= U Uᵀ, ς̂ += U w with U = Kb L_Λ⁻ᵀ
    l00, l10, l11 = Ll[0, 0], Ll[1, 0], Ll[1, 1]
    for p in range(nb):
        a0 = K0[p] / l00
        K1[p] = (K1[p] - l10 * a0) / l11
        K0[p] = a0
    for p in range(nb):
        up0 = K0[p]
        up1 = K1[p]
        bh[p] += up0 * w0 + up1 * w1
        row = Pb[p]
        for r in range(nb):
            row[r] -= up0 * K0[r] + up1 * K1[r]
    nis = w0 * w0 + w1 * w1
    ctr[C_SINCE_REFRESH] += 1
    ctr[C_SINCE_REBUILD] += 1
    if ctr[C_SINCE_REBUILD] >= ctr[C_REBUILD_FACTOR] * (ctr[C_ALIVE] + 1):
        if not rebuild(Yxx, Yxb, ex, nk, rk, Ybb, eb, S, sv, ctr, f4, V, G, v4, idx, LSi, K0):
            return ERR_REBUILD, nis
    if ctr[C_SINCE_REFRESH] >= ctr[C_REFRESH_EVERY]:
        if not refresh(S, sv, Pb, bh, ctr, LS, LSi):
            return ERR_S, nis
    return OK, nis


@njit(cache=True)
def rebuild(Yxx, Yxb, ex, nk, rk, Ybb, eb, S, sv, ctr, f4, V, G, v4, idx, S_new, sv_new):
    """S = Y_bb − Σ_i Y_bi Y_ii⁻¹ Y_ib and sv from the blocks, from scratch; S, sv untouched on failure."""
    nb = Ybb.shape[0]
    for a in range(nb):  # copies as loops: slice assignment needs the runtime
        sv_new[a] = eb[a]
        for b in range(nb):
            S_new[a, b] = Ybb[a, b]
    for s in range(nk.shape[0]):
        k = nk[s]
        if k <= 0:  # free slot (−1) or no radar yet: no term
            continue
        bias_index(rk, s, k, idx)
        if not conditional(Yxx, Yxb, ex, s, 2 * k, f4[0], V, v4[0], G, v4[1]):
            return False
        add_contribution(S_new, sv_new, idx, V, v4[0], 2 * k, -1.0)
    for a in range(nb):
        sv[a] = sv_new[a]
        for b in range(nb):
            S[a, b] = S_new[a, b]
    ctr[C_SINCE_REBUILD] = 0
    return True


@njit(cache=True)
def refresh(S, sv, Pb, bh, ctr, LS, LSi):
    """Pb = S⁻¹ and ς̂ = S⁻¹ sv through the Cholesky factor S = L Lᵀ; False if S is not positive definite.

    Every entry is summed in the order of the textbook loops (:func:`chol`, then forward substitution and
    the product Pb = L⁻ᵀ L⁻¹, all over k ascending), but the loops run over independent entries along
    contiguous rows, so they vectorise: LS holds Lᵀ (its row j is L's column j), LSi holds L⁻¹."""
    n = S.shape[0]
    Lt, Li = LS, LSi
    for j in range(n):  # column j of L: L[i, j] = (S[i, j] − Σ_{k<j} L[i, k] L[j, k]) / L[j, j], i ≥ j
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
    for i in range(n):  # row i of L⁻¹: (δ_ic − Σ_{c≤k<i} L[i, k] L⁻¹[k, c]) / L[i, i], c ≤ i
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
    for i in range(n):  # Pb[i, j] = Σ_{k≥i} L⁻¹[k, i] L⁻¹[k, j] for j ≤ i (row i), mirrored
        for j in range(i + 1):
            Pb[i, j] = 0.0
        for k in range(i, n):
            lki = Li[k, i]
            for j in range(i + 1):
                Pb[i, j] += lki * Li[k, j]
        for j in range(i):
            Pb[j, i] = Pb[i, j]
    for i in range(n):  # ς̂ = Pb sv, each entry summed over k ascending (Pb is exactly symmetric: row k)
        bh[i] = 0.0
    for k in range(n):
        svk = sv[k]
        for i in range(n):
            bh[i] += Pb[k, i] * svk
    ctr[C_SINCE_REFRESH] = 0
    return True


@njit(cache=True)
def update_batch(F, I, WF, slots, radars, times, Z, Cs, Rs, out):
    """update_one over a batch in order on the packed storage, ν, Λ and the NIS of plot i into ``out[i]``
    (2 + 4 + 1 values); returns (code, index of the failing plot or len, the latest time of the plots applied
    or predicted: −inf if none)."""
    cap, mm, nb = I[0], I[1], I[2]
    Yxx, Yxb, ex, tx, Ybb, eb, S, sv, Pb, bh, nk, rk, ctr, idx = carve(F, I, cap, mm, nb)
    f4, V, G, W, v4, Kb, LS, LSi, io = carve_work(WF, 2 * mm)
    latest = -np.inf
    for i in range(slots.shape[0]):
        row = out[i]
        code, nis = update_one(Yxx, Yxb, ex, tx, nk, rk, Ybb, eb, S, sv, Pb, bh, ctr,
                               slots[i], radars[i], times[i], Z[i], Cs[i], Rs[i], io[7], row[0:2],
                               row[2:6].reshape((2, 2)), f4, V, G, W, v4, idx, Kb, LS, LSi)
        row[6] = nis
        if code == OK or code == ERR_LAMBDA or code == ERR_S or code == ERR_REBUILD:  # applied or predicted
            if times[i] > latest:
                latest = times[i]
        if code != OK:
            return code, i, latest
    return OK, slots.shape[0], latest


@njit(cache=True)
def update_packed(F, I, WF, s, j, t, z, C, R):
    """update_one on the packed storage (:func:`carve`, :func:`carve_work`): one call, few arguments.
    Returns the status code; ν, Λ, NIS in the scratch ``io``."""
    cap, mm, nb = I[0], I[1], I[2]
    Yxx, Yxb, ex, tx, Ybb, eb, S, sv, Pb, bh, nk, rk, ctr, idx = carve(F, I, cap, mm, nb)
    f4, V, G, W, v4, Kb, LS, LSi, io = carve_work(WF, 2 * mm)
    code, nis = update_one(Yxx, Yxb, ex, tx, nk, rk, Ybb, eb, S, sv, Pb, bh, ctr, s, j, t, z, C, R, io[7], io[0:2],
                           io[2:6].reshape((2, 2)), f4, V, G, W, v4, idx, Kb, LS, LSi)
    io[6] = nis
    return code


@njit(cache=True)
def read_aircraft(Yxx, Yxb, ex, nk, rk, Pb, bh, s, out_x, out_P, f4, V, G, v4, idx):
    """χ̂_i = m − G ς̂_K and P_i = Y_ii⁻¹ + G Pb[K, K] Gᵀ (no dense matrix formed)."""
    k = max(nk[s], 0)
    nK = 2 * k
    bias_index(rk, s, k, idx)
    L, Li, T = f4[0], f4[1], f4[2]
    if not conditional(Yxx, Yxb, ex, s, nK, L, V, v4[0], G, v4[1]):
        return False
    for a in range(4):
        acc = v4[1][a, 0]
        for c in range(nK):
            acc -= G[a, c] * bh[idx[c]]
        out_x[a] = acc
    for a in range(4):
        for b in range(4):
            T[a, b] = 1.0 if a == b else 0.0
    _lsolve(L, T, Li, 4, 4)
    for a in range(4):
        for c in range(nK):  # W = G Pb[K, K] stored in V (no longer needed)
            acc = 0.0
            for d in range(nK):
                acc += G[a, d] * Pb[idx[d], idx[c]]
            V[a, c] = acc
    for a in range(4):
        for b in range(a + 1):
            acc = 0.0
            for r in range(4):
                acc += Li[r, a] * Li[r, b]
            for c in range(nK):
                acc += V[a, c] * G[b, c]
            out_P[a, b] = acc
            out_P[b, a] = acc
    return True
