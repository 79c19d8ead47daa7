"""IMM fixed-interval smoother (CV + coordinated turns): the stronger baseline for the reconstruction.

Modes on the state χ = [x, y, vx, vy]: constant velocity, and coordinated turns at ±ω (a
standard-rate 3°/s by default) — all linear, so the IMM (Blom & Bar-Shalom 1988) is exact per mode. For a turn at rate ω over Δt::

    F = [[1, 0, s/ω, −(1−c)/ω], [0, 1, (1−c)/ω, s/ω], [0, 0, c, −s], [0, 0, s, c]],  s = sin ωΔt, c = cos ωΔt

(ω > 0 turns left, counter-clockwise in the x-east, y-north plane); every mode adds white-acceleration
noise Q(|Δt|) of density q. The filter is written with the modes in arrays (FilterPy's loop over
Kalman-filter objects is about 30× slower; the tests hold this one to it). Smoothing is two-filter (Helmick, Blair & Hoffman 1995, in its simple
Gaussian form): the same IMM runs backwards in time (F(−Δt) = F⁻¹ and noise F⁻¹ Q F⁻ᵀ, exact for these
linear modes), and at
each plot the forward filtered estimate (with z_k) is fused with the backward predicted one (without
z_k), both moment-matched over the modes::

    P_s = (P_f⁻¹ + P_b⁻¹)⁻¹,   χ_s = P_s (P_f⁻¹ χ_f + P_b⁻¹ χ_b)

q is chosen per flight from a grid by the forward innovation likelihood Σ log Σ_j c̄_j N(ν_j; 0, S_j),
as for the CV smoother (:mod:`.smoother`) — it uses only the plots.
"""

from __future__ import annotations

import math

import numpy as np

Q_GRID = (0.1, 1.0, 10.0)
OMEGA = math.radians(3.0)
P_STAY = 0.95


def transition(dt: float, omega: float) -> np.ndarray:
    """F of a coordinated turn at ``omega`` rad/s (constant velocity at 0) over ``dt`` (may be negative)."""
    if omega == 0.0:
        s_w, c_w, c, s = dt, 0.0, 1.0, 0.0
    else:
        s, c = math.sin(omega * dt), math.cos(omega * dt)
        s_w, c_w = s / omega, (1 - c) / omega
    return np.array([[1, 0, s_w, -c_w], [0, 1, c_w, s_w], [0, 0, c, -s], [0, 0, s, c]], float)


def noise(dt: float, q: float) -> np.ndarray:
    """White-acceleration process noise of density q over |dt|."""
    d = abs(dt)
    Q = np.zeros((4, 4))
    Q[:2, :2] = np.eye(2) * d**3 / 3
    Q[:2, 2:] = Q[2:, :2] = np.eye(2) * d**2 / 2
    Q[2:, 2:] = np.eye(2) * d
    return q * Q


def imm_pass(t: np.ndarray, z: np.ndarray, R: np.ndarray, q: float, omegas=(0.0, OMEGA, -OMEGA)):
    """One IMM pass in the order of ``t`` (decreasing times run it backwards); the modes in arrays.

    Per plot: mixing μ_{i|j} = M_ij μ_i / c̄_j, c̄ = Mᵀμ; mixed start per mode; predict with (F_j, Q);
    Kalman update with R_k; μ_j ∝ c̄_j N(ν_j; 0, S_j). Returns filtered (χ, P) after each plot,
    predicted (χ, P) before each plot (moment-matched with c̄; NaN at the first), and the innovation
    log-likelihood Σ log Σ_j c̄_j N(ν_j; 0, S_j).
    """
    n, m = len(t), len(omegas)
    M = np.full((m, m), (1 - P_STAY) / max(m - 1, 1))
    np.fill_diagonal(M, P_STAY)
    x = np.tile([z[0, 0], z[0, 1], 0.0, 0.0], (m, 1))
    P = np.zeros((m, 4, 4))
    P[:, :2, :2] = R[0]
    P[:, 2:, 2:] = np.eye(2) * 300.0**2
    mu = np.full(m, 1.0 / m)
    xf, Pf = np.empty((n, 4)), np.empty((n, 4, 4))
    xp, Pp = np.full((n, 4), np.nan), np.full((n, 4, 4), np.nan)
    xf[0], Pf[0] = x[0], P[0]
    ll = 0.0
    for k in range(1, n):
        dt = t[k] - t[k - 1]
        cbar = M.T @ mu
        w = M * mu[:, None] / cbar[None, :]  # w[i, j] = μ_{i|j}
        x0 = w.T @ x
        d = x[None, :, :] - x0[:, None, :]  # (j, i, 4)
        P0 = np.einsum("ij,iab->jab", w, P) + np.einsum("ij,jia,jib->jab", w, d, d)
        F = np.array([transition(dt, om) for om in omegas])
        Q = noise(dt, q)
        if dt < 0:  # backwards, χ_k = F⁻¹ χ_{k+1} − F⁻¹ w_k: the noise is F⁻¹ Q F⁻ᵀ, F⁻¹ = F(−Δt)
            Q = F @ Q @ F.transpose(0, 2, 1)
        x = np.einsum("jab,jb->ja", F, x0)
        P = F @ P0 @ F.transpose(0, 2, 1) + Q
        xp[k] = cbar @ x
        e = x - xp[k]
        Pp[k] = np.einsum("j,jab->ab", cbar, P + np.einsum("ja,jb->jab", e, e))
        nu = z[k] - x[:, :2]
        S = P[:, :2, :2] + R[k]
        K = np.linalg.solve(S, P[:, :2, :]).transpose(0, 2, 1)  # P Hᵀ S⁻¹ (S symmetric)
        x = x + np.einsum("jab,jb->ja", K, nu)
        IKH = np.eye(4) - np.concatenate([K, np.zeros((m, 4, 2))], axis=2)
        P = IKH @ P @ IKH.transpose(0, 2, 1) + K @ R[k] @ K.transpose(0, 2, 1)
        lik = np.exp(-0.5 * np.einsum("ja,ja->j", nu, np.linalg.solve(S, nu[..., None])[..., 0])) / (
            2 * np.pi * np.sqrt(np.linalg.det(S)))
        tot = float(cbar @ lik)
        mu = cbar * lik / tot if tot > 0 else cbar
        if k > 2:  # the first plots only initialise the velocity
            ll += math.log(max(tot, 1e-300))
        xf[k] = mu @ x
        e = x - xf[k]
        Pf[k] = np.einsum("j,jab->ab", mu, P + np.einsum("ja,jb->jab", e, e))
    return xf, Pf, xp, Pp, ll


def imm_smooth(t: np.ndarray, z: np.ndarray, R: np.ndarray, q_grid=Q_GRID,
               omegas=(0.0, OMEGA, -OMEGA)) -> tuple[np.ndarray, float]:
    """Smoothed states (n, 4) at the plot times by the two-filter IMM smoother, and the q chosen."""
    best = None
    for q in q_grid:
        xf, Pf, _, _, ll = imm_pass(t, z, R, q, omegas)
        if best is None or ll > best[2]:
            best = (xf, Pf, ll, q)
    xf, Pf, _, q = best
    rev = slice(None, None, -1)
    _, _, xb, Pb, _ = imm_pass(t[rev], z[rev], R[rev], q, omegas)
    xb, Pb = xb[rev], Pb[rev]
    xs = xf.copy()
    for k in range(len(t) - 1):  # the last plot has no backward prediction: its filtered estimate stands
        If, Ib = np.linalg.inv(Pf[k]), np.linalg.inv(Pb[k])
        xs[k] = np.linalg.solve(If + Ib, If @ xf[k] + Ib @ xb[k])
    return xs, float(q)
