"""Rauch–Tung–Striebel smoother over the constant-velocity model: the baseline and the start.

State χ = [x, y, vx, vy], χ_k = A χ_{k−1} + v, v ~ N(0, Q(Δt)) from
:class:`radartracker.motion.MotionModel` (white acceleration of density q), plots z_k = [x, y] + e_k,
e_k ~ N(0, R_k). Kalman filter forward, then (Rauch, Tung & Striebel 1965)::

    G_k = P_k Aᵀ P̄_{k+1}⁻¹,   χ^s_k = χ_k + G_k (χ^s_{k+1} − χ̄_{k+1}),   P^s_k = P_k + G_k (P^s_{k+1} − P̄_{k+1}) G_kᵀ

The filter and the smoother are compiled kernels (:func:`rts_into`: A = [[I, ΔtI], [0, I]] and
Q = q [[|Δt|³/3 I, Δt²/2 I], [Δt²/2 I, |Δt| I]] written out, a 4×4 Cholesky solve for the gain); the tests
hold them to filterpy and to the numpy loop they replaced. q is tuned per flight by maximising the
innovation log-likelihood Σ log N(ν_k; 0, Λ_k) over a logarithmic grid — it uses only the plots, so it is a fair tuning on real data. The smoothed
track seeds the hypotheses (:mod:`.hypotheses`) and is the baseline the reconstruction is
compared with in docs/reconstruction.md.
"""

from __future__ import annotations

import math

import numpy as np

from radartracker.api import kernel

Q_GRID = tuple(np.logspace(-3, 2, 11))
_V0_SD = 300.0  # m/s, prior velocity spread of the first plot (diffuse for aircraft)


def rts_smooth(t: np.ndarray, z: np.ndarray, R: np.ndarray, q: float) -> tuple[np.ndarray, np.ndarray, float]:
    """Smoothed states (n, 4), covariances (n, 4, 4) and the innovation log-likelihood (:func:`rts_into`)."""
    n = len(t)
    xs, Ps = np.empty((n, 4)), np.empty((n, 4, 4))
    xp, Pp = np.empty((n, 4)), np.empty((n, 4, 4))
    loglik = rts_into(np.ascontiguousarray(t, float), np.ascontiguousarray(z, float), np.ascontiguousarray(R, float),
                      float(q), xs, Ps, xp, Pp, np.empty((3, 4, 4)))
    return xs, Ps, loglik


@kernel(inline="always")
def _predict_cov(P: np.ndarray, dt: float, q: float, out: np.ndarray) -> None:
    """out = A P Aᵀ + Q with A = [[I, Δt I], [0, I]], Q = q [[|Δt|³/3 I, Δt²/2 I], [Δt²/2 I, |Δt| I]]."""
    for i in range(4):
        for j in range(4):
            out[i, j] = P[i, j] + (dt * P[i + 2, j] if i < 2 else 0.0)
    for i in range(4):
        for j in range(2):
            out[i, j] += dt * out[i, j + 2]
    d = abs(dt)
    for i in range(2):
        out[i, i] += q * d**3 / 3
        out[i, i + 2] += q * d * d / 2
        out[i + 2, i] += q * d * d / 2
        out[i + 2, i + 2] += q * d


@kernel(inline="always")
def _update(x: np.ndarray, P: np.ndarray, z0: float, z1: float, Rk: np.ndarray, W: np.ndarray) -> float:
    """Kalman update of (x, P) with a position plot z (covariance R) in place, Joseph form
    P ← (I − KH) P (I − KH)ᵀ + K R Kᵀ, K = P Hᵀ S⁻¹, S = H P Hᵀ + R; returns ν S⁻¹ ν + ln det(2πS)."""
    s00, s01, s11 = P[0, 0] + Rk[0, 0], P[0, 1] + Rk[0, 1], P[1, 1] + Rk[1, 1]
    det = s00 * s11 - s01 * s01
    i00, i01, i11 = s11 / det, -s01 / det, s00 / det
    n0, n1 = z0 - x[0], z1 - x[1]
    K = W[0]
    for i in range(4):
        K[i, 0] = P[i, 0] * i00 + P[i, 1] * i01
        K[i, 1] = P[i, 0] * i01 + P[i, 1] * i11
        x[i] += K[i, 0] * n0 + K[i, 1] * n1
    IKH = W[1]
    for i in range(4):
        for j in range(4):
            IKH[i, j] = (1.0 if i == j else 0.0) - (K[i, j] if j < 2 else 0.0)
    T = W[2]
    for i in range(4):
        for j in range(4):
            T[i, j] = IKH[i, 0] * P[0, j] + IKH[i, 1] * P[1, j] + IKH[i, 2] * P[2, j] + IKH[i, 3] * P[3, j]
    for i in range(4):
        for j in range(4):
            P[i, j] = (T[i, 0] * IKH[j, 0] + T[i, 1] * IKH[j, 1] + T[i, 2] * IKH[j, 2] + T[i, 3] * IKH[j, 3]
                       + K[i, 0] * (Rk[0, 0] * K[j, 0] + Rk[0, 1] * K[j, 1])
                       + K[i, 1] * (Rk[1, 0] * K[j, 0] + Rk[1, 1] * K[j, 1]))
    return n0 * (i00 * n0 + i01 * n1) + n1 * (i01 * n0 + i11 * n1) + math.log(4 * math.pi * math.pi * det)


@kernel
def _filter(t: np.ndarray, z: np.ndarray, R: np.ndarray, q: float, xf: np.ndarray, Pf: np.ndarray, xp: np.ndarray,
            Pp: np.ndarray, W: np.ndarray) -> float:
    """Forward Kalman filter: predictions (xp, Pp) and filtered (xf, Pf) at every plot; returns the innovation
    log-likelihood −½ Σ_{k>1} (ν_k S_k⁻¹ ν_k + ln det(2πS_k)) (the first two plots only initialise)."""
    loglik = 0.0
    for k in range(len(t)):
        if k == 0:
            for i in range(4):
                xp[0, i] = 0.0
                for j in range(4):
                    Pp[0, i, j] = 0.0
            xp[0, 0], xp[0, 1] = z[0, 0], z[0, 1]
            for i in range(2):
                for j in range(2):
                    Pp[0, i, j] = R[0, i, j] * 1e6
                Pp[0, i + 2, i + 2] = _V0_SD**2
        else:
            dt = t[k] - t[k - 1]
            for i in range(4):
                xp[k, i] = xf[k - 1, i] + (dt * xf[k - 1, i + 2] if i < 2 else 0.0)
            _predict_cov(Pf[k - 1], dt, q, Pp[k])
        for i in range(4):
            xf[k, i] = xp[k, i]
            for j in range(4):
                Pf[k, i, j] = Pp[k, i, j]
        m = _update(xf[k], Pf[k], z[k, 0], z[k, 1], R[k], W)
        if k > 1:
            loglik -= 0.5 * m
    return loglik


@kernel
def rts_into(t: np.ndarray, z: np.ndarray, R: np.ndarray, q: float, xs: np.ndarray, Ps: np.ndarray, xp: np.ndarray,
             Pp: np.ndarray, W: np.ndarray) -> float:
    """Kalman filter forward into (xs, Ps), then the RTS pass backwards in place:
    G_k = P_k Aᵀ P̄_{k+1}⁻¹ (by a 4×4 Cholesky solve of P̄_{k+1} Gᵀ = A P_k), χ^s_k = χ_k + G_k (χ^s_{k+1} − χ̄_{k+1}),
    P^s_k = P_k + G_k (P^s_{k+1} − P̄_{k+1}) G_kᵀ. Returns the innovation log-likelihood."""
    loglik = _filter(t, z, R, q, xs, Ps, xp, Pp, W)
    L, G, T = W[0], W[1], W[2]
    for k in range(len(t) - 2, -1, -1):
        dt = t[k + 1] - t[k]
        _cholesky4(Pp[k + 1], L)
        for c in range(4):  # column c of A P_k, solved for row c of G
            for i in range(4):
                T[0, i] = Ps[k, i, c] + (dt * Ps[k, i + 2, c] if i < 2 else 0.0)
            _cho_solve4(L, T[0], T[1])
            for i in range(4):
                G[c, i] = T[1, i]
        for i in range(4):
            s = 0.0
            for j in range(4):
                s += G[i, j] * (xs[k + 1, j] - xp[k + 1, j])
            T[2, i] = s
        for i in range(4):
            xs[k, i] += T[2, i]
        for i in range(4):
            for j in range(4):
                s = 0.0
                for a in range(4):
                    s += G[i, a] * (Ps[k + 1, a, j] - Pp[k + 1, a, j])
                T[3, j] = s
            for j in range(4):
                T[1, j] = 0.0
                for a in range(4):
                    T[1, j] += T[3, a] * G[j, a]
            for j in range(4):
                Ps[k, i, j] += T[1, j]
    return loglik


@kernel(inline="always")
def _cholesky4(A: np.ndarray, L: np.ndarray) -> None:
    """L Lᵀ = A (4×4, symmetric positive definite), lower triangle of L."""
    for j in range(4):
        s = A[j, j]
        for k in range(j):
            s -= L[j, k] * L[j, k]
        L[j, j] = math.sqrt(s)
        for i in range(j + 1, 4):
            s = A[i, j]
            for k in range(j):
                s -= L[i, k] * L[j, k]
            L[i, j] = s / L[j, j]


@kernel(inline="always")
def _cho_solve4(L: np.ndarray, b: np.ndarray, x: np.ndarray) -> None:
    """x solving L Lᵀ x = b."""
    for i in range(4):
        s = b[i]
        for k in range(i):
            s -= L[i, k] * x[k]
        x[i] = s / L[i, i]
    for i in range(3, -1, -1):
        s = x[i]
        for k in range(i + 1, 4):
            s -= L[k, i] * x[k]
        x[i] = s / L[i, i]


def tuned_rts(t: np.ndarray, z: np.ndarray, R: np.ndarray, q_grid=Q_GRID) -> tuple[np.ndarray, float]:
    """Smoothed states with the q of ``q_grid`` that maximises the innovation likelihood, and that q."""
    best = None
    for q in q_grid:
        xs, _, ll = rts_smooth(t, z, R, q)
        if best is None or ll > best[2]:
            best = (xs, q, ll)
    return best[0], float(best[1])


def gated_rts(t: np.ndarray, z: np.ndarray, R: np.ndarray, gate: float = 16.0,
              passes: int = 2) -> tuple[np.ndarray, float, np.ndarray]:
    """:func:`tuned_rts` that drops outliers: plots whose squared Mahalanobis distance from the
    smoothed position (under R) exceeds ``gate`` (χ²₂ tail 3·10⁻⁴ at 16) are left out and the
    rest smoothed again. Returns states at the kept plots, q, and the mask of kept plots."""
    keep = np.ones(len(t), bool)
    for _ in range(passes):
        xs, q = tuned_rts(t[keep], z[keep], R[keep])
        p = np.column_stack([np.interp(t, t[keep], xs[:, 0]), np.interp(t, t[keep], xs[:, 1])])
        r = z - p
        d2 = np.einsum("ni,ni->n", r, np.linalg.solve(R, r[..., None])[..., 0])
        new = d2 <= gate
        if new.sum() < 4 or np.array_equal(new, keep):
            break
        keep = new
    xs, q = tuned_rts(t[keep], z[keep], R[keep])
    return xs, q, keep
