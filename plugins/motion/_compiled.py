"""Compiled mode-filter steps of the motion plugins (numba, cached on disk: a first run does not stall).

The equations of the numpy code of :mod:`radartracker_plugins.motion.ct` and
:class:`radartracker.api.MotionModel`, written out for the small fixed sizes (4-state CV, 5-state CT)
so that one call does what takes a dozen numpy calls:

* :func:`cv_predict` — χ̄ = A(Δt) χ̂, P̄ = sym(A P̂ Aᵀ + Q(Δt)), A = [[I, Δt I], [0, I]],
  Q = q [[|Δt|³/3 I, Δt²/2 I], [Δt²/2 I, |Δt| I]].
* :func:`ct_predict` — the extended-Kalman coordinated-turn prediction f(ξ), F P Fᵀ + Q of
  :mod:`radartracker_plugins.motion.ct` (Taylor series below |ωT| = 10⁻⁴), symmetrised.
* :func:`position_update` — correction by a position z (H = [I₂ 0]): ν = z − Hχ̄, Λ = H P̄ Hᵀ + R,
  G = P̄ Hᵀ Λ⁻¹ (closed-form 2×2 inverse), χ̂ = χ̄ + G ν, P̂ = sym(P̄ − G H P̄), with
  NIS = νᵀΛ⁻¹ν and log N(ν; 0, Λ) from the Cholesky factor of Λ; ``ok`` is False when Λ is not
  positive definite (the caller raises).
* :func:`mixture_into` — a Gaussian mixture's mean and covariance, x = Σ wᵢ xᵢ,
  P = sym(Σ wᵢ (Pᵢ + (xᵢ − x)(xᵢ − x)ᵀ)) (the IMM's mixing, prediction and output).
* :func:`measurement_ok` — the checks of a position measurement: finite time and z, R finite,
  symmetric (``numpy.allclose`` tolerances) and positive definite.

The ``*_into`` steps write into the caller's arrays (the IMM's state and prediction); the others
allocate their results.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

_LOG_2PI = math.log(2.0 * math.pi)
_SMALL = 1e-4  # |ωT| below which the CT Taylor series are used (as ct.py)


@njit(cache=True, inline="always")
def symmetrize_into(P: np.ndarray, n: int) -> None:
    """P[:n, :n] = (P + Pᵀ) / 2 in place."""
    for i in range(n):
        for j in range(i + 1, n):
            m = 0.5 * (P[i, j] + P[j, i])
            P[i, j] = m
            P[j, i] = m


@njit(cache=True, inline="always")
def measurement_ok(time: float, z: np.ndarray, R: np.ndarray) -> int:
    """0 if (time, z, R) is a valid position measurement, else 1 (time), 2 (z) or 3 (R)."""
    if not math.isfinite(time):
        return 1
    if z.shape[0] != 2 or not (math.isfinite(z[0]) and math.isfinite(z[1])):
        return 2
    if R.shape[0] != 2 or R.shape[1] != 2:
        return 3
    for i in range(2):
        for j in range(2):
            if not math.isfinite(R[i, j]):
                return 3
    d = abs(R[0, 1] - R[1, 0])  # numpy.allclose(R, R.T) checks both orders
    if d > 1e-8 + 1e-5 * abs(R[1, 0]) or d > 1e-8 + 1e-5 * abs(R[0, 1]):
        return 3
    a = R[0, 0]
    if not a > 0.0:
        return 3
    if not R[1, 1] - R[1, 0] * R[1, 0] / a > 0.0:
        return 3
    return 0


@njit(cache=True, inline="always")
def _add_white_acceleration(P: np.ndarray, dt: float, q: float) -> None:
    """P[:4, :4] += Q(Δt) of white acceleration of density q (module docstring)."""
    if q == 0.0 or dt == 0.0:
        return
    adt = abs(dt)
    q3, q2, q1 = q * (adt**3 / 3), q * (adt**2 / 2), q * adt
    for k in range(2):
        P[k, k] += q3
        P[k, k + 2] += q2
        P[k + 2, k] += q2
        P[k + 2, k + 2] += q1


@njit(cache=True, inline="always")
def cv_predict_into(x: np.ndarray, P: np.ndarray, dt: float, q: float) -> None:
    """:func:`cv_predict` of (x[:4], P[:4, :4]) in place: the rows of A P, then its columns (each step
    reads only entries it does not write), plus Q, symmetrised."""
    x[0] += dt * x[2]
    x[1] += dt * x[3]
    for j in range(4):  # A P: rows 0, 1 gain dt × rows 2, 3
        P[0, j] += dt * P[2, j]
        P[1, j] += dt * P[3, j]
    for i in range(4):  # (A P) Aᵀ: columns 0, 1 gain dt × columns 2, 3
        P[i, 0] += dt * P[i, 2]
        P[i, 1] += dt * P[i, 3]
    _add_white_acceleration(P, dt, q)
    symmetrize_into(P, 4)


@njit(cache=True, inline="always")
def cv_predict(x: np.ndarray, P: np.ndarray, dt: float, q: float) -> tuple[np.ndarray, np.ndarray]:
    """Constant-velocity prediction of (χ, P) by ``dt`` seconds with white-acceleration density ``q``."""
    xp, Pp = x.copy(), P.copy()
    cv_predict_into(xp, Pp, dt, q)
    return xp, Pp


@njit(cache=True, inline="always")
def _ct_mean_and_jacobian(x: np.ndarray, T: float, xp: np.ndarray, F: np.ndarray) -> None:
    """f(ξ) into xp[:5] and ∂f/∂ξ into F (5×5) of the coordinated turn over T (ct.py's ct_transition)."""
    vx, vy, w = x[2], x[3], x[4]
    a = w * T
    s, c = math.sin(a), math.cos(a)
    if abs(a) < _SMALL:  # series to O(a⁴): s/ω = T(1 − a²/6), (1−c)/ω = T(a/2 − a³/24)
        f1, f2 = T * (1 - a * a / 6), T * (a / 2 - a**3 / 24)
        d1, d2 = T * T * (-a / 3 + a**3 / 30), T * T * (0.5 - a * a / 8)
    else:
        f1, f2 = s / w, (1 - c) / w
        d1, d2 = (T * c * w - s) / (w * w), (T * s * w - (1 - c)) / (w * w)
    xp[0] = x[0] + f1 * vx + f2 * vy
    xp[1] = x[1] - f2 * vx + f1 * vy
    xp[2] = c * vx + s * vy
    xp[3] = -s * vx + c * vy
    xp[4] = w
    F[:, :] = 0.0
    for i in range(5):
        F[i, i] = 1.0
    F[0, 2], F[0, 3], F[0, 4] = f1, f2, d1 * vx + d2 * vy
    F[1, 2], F[1, 3], F[1, 4] = -f2, f1, -d2 * vx + d1 * vy
    F[2, 2], F[2, 3], F[2, 4] = c, s, T * (-s * vx + c * vy)
    F[3, 2], F[3, 3], F[3, 4] = -s, c, T * (-c * vx - s * vy)


@njit(cache=True, inline="always")
def _congruence_into(F: np.ndarray, P: np.ndarray, out: np.ndarray) -> None:
    """out[:5, :5] = F P Fᵀ for the 5×5 Jacobian F: Σ_k F_ik (Σ_l P_kl F_jl), F's zeros skipped."""
    for i in range(5):
        for j in range(5):
            out[i, j] = 0.0
    for k in range(5):
        for j in range(5):
            pf = 0.0  # (P Fᵀ)_kj
            for l in range(5):
                pf += P[k, l] * F[j, l]
            for i in range(5):
                if F[i, k] != 0.0:
                    out[i, j] += F[i, k] * pf


@njit(cache=True, inline="always")
def ct_predict_into(x: np.ndarray, P: np.ndarray, T: float, q: float, turn_rate_sd: float, F: np.ndarray,
                    xp: np.ndarray, Pp: np.ndarray) -> None:
    """:func:`ct_predict` of (x[:5], P[:5, :5]) into (xp, Pp): f(ξ), sym(F P Fᵀ + Q) with
    Q = the white-acceleration block of density q and σ_ω² |T| on ω; the Jacobian F (5×5) is written
    into the caller's ``F``."""
    _ct_mean_and_jacobian(x, T, xp, F)
    _congruence_into(F, P, Pp)
    _add_white_acceleration(Pp, T, q)
    Pp[4, 4] += turn_rate_sd**2 * abs(T)
    symmetrize_into(Pp, 5)


@njit(cache=True, inline="always")
def ct_predict(x: np.ndarray, P: np.ndarray, T: float, q: float, turn_rate_sd: float
               ) -> tuple[np.ndarray, np.ndarray]:
    """Coordinated-turn EKF prediction of (ξ, P), ξ = [x, y, vx, vy, ω], over ``T`` seconds."""
    xp, Pp = np.empty(5), np.empty((5, 5))
    ct_predict_into(x, P, T, q, turn_rate_sd, np.empty((5, 5)), xp, Pp)
    return xp, Pp


@njit(cache=True, inline="always")
def innovation_nis(x: np.ndarray, P: np.ndarray, z: np.ndarray, R: np.ndarray) -> tuple[float, float, bool]:
    """(NIS = νᵀΛ⁻¹ν, log N(ν; 0, Λ), ok) of position z against (x, P): ν = z − x[:2], Λ = P[:2, :2] + R,
    from Λ's Cholesky factor (lower triangle, as numpy.linalg.cholesky); ok False unless Λ is positive
    definite."""
    nu0, nu1 = z[0] - x[0], z[1] - x[1]
    s00, s10, s11 = P[0, 0] + R[0, 0], P[1, 0] + R[1, 0], P[1, 1] + R[1, 1]
    if not s00 > 0.0:
        return math.nan, math.nan, False
    l00 = math.sqrt(s00)
    l10 = s10 / l00
    r = s11 - l10 * l10
    if not r > 0.0:
        return math.nan, math.nan, False
    l11 = math.sqrt(r)
    w0 = nu0 / l00
    w1 = (nu1 - l10 * w0) / l11
    nis = w0 * w0 + w1 * w1
    return nis, -0.5 * nis - (math.log(l00) + math.log(l11)) - _LOG_2PI, True


@njit(cache=True, inline="always")
def position_update_into(x: np.ndarray, P: np.ndarray, z: np.ndarray, R: np.ndarray, n: int, xn: np.ndarray,
                         Pn: np.ndarray) -> tuple[float, float, bool]:
    """:func:`position_update` of (x[:n], P[:n, :n]) into (xn[:n], Pn[:n, :n]): (NIS, log-likelihood,
    ok); when not ok, xn and Pn are not written."""
    nis, loglik, ok = innovation_nis(x, P, z, R)
    a, b, d = P[0, 0] + R[0, 0], 0.5 * ((P[0, 1] + R[0, 1]) + (P[1, 0] + R[1, 0])), P[1, 1] + R[1, 1]
    det = a * d - b * b
    if not (ok and det > 0 and math.isfinite(det)):
        return math.nan, math.nan, False
    nu0, nu1 = z[0] - x[0], z[1] - x[1]
    i00, i01, i11 = d / det, -b / det, a / det
    for i in range(n):
        g0 = P[i, 0] * i00 + P[i, 1] * i01  # row i of G = K Λ⁻¹, K = P Hᵀ = P[:, :2]
        g1 = P[i, 0] * i01 + P[i, 1] * i11
        xn[i] = x[i] + g0 * nu0 + g1 * nu1
        for j in range(n):
            Pn[i, j] = P[i, j] - (g0 * P[j, 0] + g1 * P[j, 1])
    symmetrize_into(Pn, n)
    return nis, loglik, True


@njit(cache=True, inline="always")
def position_update(x: np.ndarray, P: np.ndarray, z: np.ndarray, R: np.ndarray):
    """(χ̂, P̂, ν, Λ, NIS, log-likelihood, ok) of the position correction (module docstring); when not ok,
    copies of (x, P) and nan."""
    n = x.shape[0]
    nu = np.empty(2)
    nu[0], nu[1] = z[0] - x[0], z[1] - x[1]
    S = np.empty((2, 2))
    for i in range(2):
        for j in range(2):
            S[i, j] = P[i, j] + R[i, j]
    xn, Pn = x.copy(), P.copy()
    nis, loglik, ok = position_update_into(x, P, z, R, n, xn, Pn)
    return xn, Pn, nu, S, nis, loglik, ok


@njit(cache=True, inline="always")
def mixture_into(w: np.ndarray, X: np.ndarray, P: np.ndarray, m: int, x: np.ndarray, out: np.ndarray) -> None:
    """Mean (into x[:m]) and covariance (into out[:m, :m]) of the first ``m`` components of the mixture
    Σ wᵢ N(Xᵢ, Pᵢ); x and out must not share memory with X, P."""
    n = X.shape[0]
    for a in range(m):
        x[a] = 0.0
        for b in range(m):
            out[a, b] = 0.0
    for i in range(n):
        for a in range(m):
            x[a] += w[i] * X[i, a]
    for i in range(n):
        for a in range(m):
            da = X[i, a] - x[a]
            for b in range(m):
                out[a, b] += w[i] * (P[i, a, b] + da * (X[i, b] - x[b]))
    symmetrize_into(out, m)


@njit(cache=True, inline="always")
def moment_match(w: np.ndarray, X: np.ndarray, P: np.ndarray, m: int) -> tuple[np.ndarray, np.ndarray]:
    """Mean and covariance of the first ``m`` components of the mixture Σ wᵢ N(Xᵢ, Pᵢ)."""
    x, out = np.empty(m), np.empty((m, m))
    mixture_into(w, X, P, m, x, out)
    return x, out
