"""Rauch–Tung–Striebel smoother over the constant-velocity model: the baseline and the start.

State χ = [x, y, vx, vy], χ_k = A χ_{k−1} + v, v ~ N(0, Q(Δt)) from
:class:`radartracker.motion.MotionModel` (white acceleration of density q), plots z_k = [x, y] + e_k,
e_k ~ N(0, R_k). Kalman filter forward, then (Rauch, Tung & Striebel 1965)::

    G_k = P_k Aᵀ P̄_{k+1}⁻¹,   χ^s_k = χ_k + G_k (χ^s_{k+1} − χ̄_{k+1}),   P^s_k = P_k + G_k (P^s_{k+1} − P̄_{k+1}) G_kᵀ

q is tuned per flight by maximising the innovation log-likelihood Σ log N(ν_k; 0, Λ_k) over a
logarithmic grid — it uses only the plots, so it is a fair tuning on real data. The smoothed
track seeds the hypotheses (:mod:`.hypotheses`) and is the baseline the reconstruction is
compared with in docs/reconstruction.md.
"""

from __future__ import annotations

import numpy as np

from radartracker.api import MotionModel

Q_GRID = tuple(np.logspace(-3, 2, 11))
_V0_SD = 300.0  # m/s, prior velocity spread of the first plot (diffuse for aircraft)


def rts_smooth(t: np.ndarray, z: np.ndarray, R: np.ndarray, q: float) -> tuple[np.ndarray, np.ndarray, float]:
    """Smoothed states (n, 4), covariances (n, 4, 4) and the innovation log-likelihood."""
    n = len(t)
    model = MotionModel(q)
    H = np.hstack([np.eye(2), np.zeros((2, 2))])
    xf = np.empty((n, 4))
    Pf = np.empty((n, 4, 4))
    xp = np.empty((n, 4))
    Pp = np.empty((n, 4, 4))
    As = np.empty((n, 4, 4))
    x = np.array([z[0, 0], z[0, 1], 0.0, 0.0])
    P = np.zeros((4, 4))
    P[:2, :2] = R[0] * 1e6
    P[2:, 2:] = np.eye(2) * _V0_SD**2
    loglik = 0.0
    for k in range(n):
        if k > 0:
            A, Q = model.transition(t[k] - t[k - 1])
            x, P = A @ x, A @ P @ A.T + Q
        else:
            A = np.eye(4)
        As[k], xp[k], Pp[k] = A, x, P
        nu = z[k] - x[:2]
        S = P[:2, :2] + R[k]
        K = np.linalg.solve(S, H @ P).T
        x = x + K @ nu
        IKH = np.eye(4) - K @ H
        P = IKH @ P @ IKH.T + K @ R[k] @ K.T
        if k > 1:  # the first two plots only initialise position and velocity
            loglik -= 0.5 * (nu @ np.linalg.solve(S, nu) + np.log(np.linalg.det(2 * np.pi * S)))
        xf[k], Pf[k] = x, P
    xs, Ps = xf.copy(), Pf.copy()
    for k in range(n - 2, -1, -1):
        G = np.linalg.solve(Pp[k + 1], As[k + 1] @ Pf[k]).T
        xs[k] = xf[k] + G @ (xs[k + 1] - xp[k + 1])
        Ps[k] = Pf[k] + G @ (Ps[k + 1] - Pp[k + 1]) @ G.T
    return xs, Ps, loglik


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
