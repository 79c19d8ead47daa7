"""Compiled kernels of the track filters' hot path (numba, cached on disk: a first run does not stall).

The equations are those of the numpy code they replace, written out for the small fixed sizes
(4-state CV, 5-state CT) so that one call does what took a dozen numpy calls:

* :func:`cv_predict` — χ̄ = A(Δt) χ̂, P̄ = sym(A P̂ Aᵀ + Q(Δt)), A = [[I, Δt I], [0, I]],
  Q = q [[|Δt|³/3 I, Δt²/2 I], [Δt²/2 I, |Δt| I]] (:class:`radartracker.estimation.motion.MotionModel`).
* :func:`ct_predict` — the extended-Kalman coordinated-turn prediction f(ξ), F P Fᵀ + Q of
  ``radartracker_plugins.motion.ct`` (Taylor series below |ωT| = 10⁻⁴), symmetrised.
* :func:`position_update` — correction by a position z (H = [I₂ 0]): ν = z − Hχ̄, Λ = H P̄ Hᵀ + R,
  G = P̄ Hᵀ Λ⁻¹ (closed-form 2×2 inverse), χ̂ = χ̄ + G ν, P̂ = sym(P̄ − G H P̄), with
  NIS = νᵀΛ⁻¹ν and log N(ν; 0, Λ) from the Cholesky factor of Λ; ``ok`` is False when Λ is not
  positive definite (the caller raises).
* :func:`moment_match` — the Gaussian mixture's mean and covariance, x = Σ wᵢ xᵢ,
  P = sym(Σ wᵢ (Pᵢ + (xᵢ − x)(xᵢ − x)ᵀ)) (the IMM's mixing and its combined estimate), summed in the
  order of the numpy expressions it replaces.
* the IMM cycle of ``radartracker_plugins.motion.imm`` (Blom & Bar-Shalom), one call each:
  :func:`markov_switching` Π(Δt) = exp(G|Δt|); :func:`imm_predict` — c̄ = μΠ, mixing
  ω_ij = Π_ij μ_i / c̄_j with moment-matched initial conditions, each mode's CV or CT prediction and
  the predicted mixture Σ c̄_j N(ξ̄_j, P̄_j); :func:`imm_correct` — each mode's position update,
  μ_j ∝ c̄_j N(ν_j; 0, Λ_j) and the moment-matched output; :func:`imm_cycle` both. These write
  into the caller's arrays: boxing a returned array costs more than the arithmetic.
* :func:`measurement_ok` — the checks of a position measurement: finite time and z, R finite,
  symmetric (``numpy.allclose`` tolerances) and positive definite.
* a filter's IMM state packed in one buffer (:func:`imm_views`, :func:`imm_constants`), so that one
  call passes two arrays instead of fourteen (each array argument costs ~0.15 µs to type and unbox):
  :func:`imm_advance` (prediction), :func:`imm_update` (the measurement checks and the correction,
  from the kept prediction or in one cycle), :func:`imm_screen` (bias correction of a radar
  measurement, prediction, its d² (:mod:`radartracker.estimation.screening`) and the update when
  it passes the gate).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from radartracker.estimation.screening import bias_correct_into, position_d2

_LOG_2PI = math.log(2.0 * math.pi)
_SMALL = 1e-4  # |ωT| below which the CT Taylor series are used (as plugins/motion/ct.py)


@njit(cache=True)
def _symmetrize(P: np.ndarray) -> None:
    n = P.shape[0]
    for i in range(n):
        for j in range(i + 1, n):
            m = 0.5 * (P[i, j] + P[j, i])
            P[i, j] = m
            P[j, i] = m


@njit(cache=True)
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


@njit(cache=True)
def cv_predict(x: np.ndarray, P: np.ndarray, dt: float, q: float) -> tuple[np.ndarray, np.ndarray]:
    """Constant-velocity prediction of (χ, P) by ``dt`` seconds with white-acceleration density ``q``."""
    xp = x.copy()
    xp[0] += dt * x[2]
    xp[1] += dt * x[3]
    AP = P.copy()  # A P: rows 0, 1 gain dt × rows 2, 3
    for j in range(4):
        AP[0, j] += dt * P[2, j]
        AP[1, j] += dt * P[3, j]
    Pp = AP.copy()  # (A P) Aᵀ: columns 0, 1 gain dt × columns 2, 3
    for i in range(4):
        Pp[i, 0] += dt * AP[i, 2]
        Pp[i, 1] += dt * AP[i, 3]
    if q != 0.0 and dt != 0.0:
        adt = abs(dt)
        q3, q2, q1 = q * (adt**3 / 3), q * (adt**2 / 2), q * adt
        for k in range(2):
            Pp[k, k] += q3
            Pp[k, k + 2] += q2
            Pp[k + 2, k] += q2
            Pp[k + 2, k + 2] += q1
    _symmetrize(Pp)
    return xp, Pp


@njit(cache=True)
def ct_predict(x: np.ndarray, P: np.ndarray, T: float, q: float, turn_rate_sd: float
               ) -> tuple[np.ndarray, np.ndarray]:
    """Coordinated-turn EKF prediction of (ξ, P), ξ = [x, y, vx, vy, ω], over ``T`` seconds."""
    vx, vy, w = x[2], x[3], x[4]
    a = w * T
    s, c = math.sin(a), math.cos(a)
    if abs(a) < _SMALL:
        f1 = T * (1 - a * a / 6)
        f2 = T * (a / 2 - a**3 / 24)
        d1 = T * T * (-a / 3 + a**3 / 30)
        d2 = T * T * (0.5 - a * a / 8)
    else:
        f1, f2 = s / w, (1 - c) / w
        d1 = (T * c * w - s) / (w * w)
        d2 = (T * s * w - (1 - c)) / (w * w)
    xp = np.empty(5)
    xp[0] = x[0] + f1 * vx + f2 * vy
    xp[1] = x[1] - f2 * vx + f1 * vy
    xp[2] = c * vx + s * vy
    xp[3] = -s * vx + c * vy
    xp[4] = w
    F = np.eye(5)
    F[0, 2], F[0, 3], F[0, 4] = f1, f2, d1 * vx + d2 * vy
    F[1, 2], F[1, 3], F[1, 4] = -f2, f1, -d2 * vx + d1 * vy
    F[2, 2], F[2, 3], F[2, 4] = c, s, T * (-s * vx + c * vy)
    F[3, 2], F[3, 3], F[3, 4] = -s, c, T * (-c * vx - s * vy)
    FP = np.zeros((5, 5))
    for i in range(5):
        for k in range(5):
            if F[i, k] != 0.0:
                for j in range(5):
                    FP[i, j] += F[i, k] * P[k, j]
    Pp = np.zeros((5, 5))
    for i in range(5):
        for j in range(5):
            acc = 0.0
            for k in range(5):
                acc += FP[i, k] * F[j, k]
            Pp[i, j] = acc
    if q != 0.0 and T != 0.0:
        adt = abs(T)
        q3, q2, q1 = q * (adt**3 / 3), q * (adt**2 / 2), q * adt
        for k in range(2):
            Pp[k, k] += q3
            Pp[k, k + 2] += q2
            Pp[k + 2, k] += q2
            Pp[k + 2, k + 2] += q1
    Pp[4, 4] += turn_rate_sd**2 * abs(T)
    _symmetrize(Pp)
    return xp, Pp


@njit(cache=True)
def position_update(x: np.ndarray, P: np.ndarray, z: np.ndarray, R: np.ndarray):
    """(χ̂, P̂, ν, Λ, NIS, log-likelihood, ok) of the position correction (module docstring)."""
    n = x.shape[0]
    nu = np.empty(2)
    nu[0], nu[1] = z[0] - x[0], z[1] - x[1]
    S = np.empty((2, 2))
    for i in range(2):
        for j in range(2):
            S[i, j] = P[i, j] + R[i, j]
    a, b, d = S[0, 0], 0.5 * (S[0, 1] + S[1, 0]), S[1, 1]
    det = a * d - b * b
    if not (a > 0 and det > 0 and math.isfinite(det)):
        return x.copy(), P.copy(), nu, S, math.nan, math.nan, False
    i00, i01, i11 = d / det, -b / det, a / det
    G = np.empty((n, 2))  # K Λ⁻¹ with K = P Hᵀ = P[:, :2]
    for i in range(n):
        G[i, 0] = P[i, 0] * i00 + P[i, 1] * i01
        G[i, 1] = P[i, 0] * i01 + P[i, 1] * i11
    xn = np.empty(n)
    for i in range(n):
        xn[i] = x[i] + G[i, 0] * nu[0] + G[i, 1] * nu[1]
    Pn = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            Pn[i, j] = P[i, j] - (G[i, 0] * P[j, 0] + G[i, 1] * P[j, 1])
    _symmetrize(Pn)
    # NIS and log-likelihood from the Cholesky factor of Λ (lower triangle, as numpy.linalg.cholesky)
    l00 = math.sqrt(S[0, 0])
    l10 = S[1, 0] / l00
    r = S[1, 1] - l10 * l10
    if not r > 0.0:
        return x.copy(), P.copy(), nu, S, math.nan, math.nan, False
    l11 = math.sqrt(r)
    w0 = nu[0] / l00
    w1 = (nu[1] - l10 * w0) / l11
    nis = w0 * w0 + w1 * w1
    loglik = -0.5 * nis - (math.log(l00) + math.log(l11)) - _LOG_2PI
    return xn, Pn, nu, S, nis, loglik, True


@njit(cache=True)
def _position_nis(x: np.ndarray, P: np.ndarray, z: np.ndarray, R: np.ndarray) -> tuple[float, bool]:
    """(NIS, ok) of :func:`position_update` alone: its operations for these two, nothing else."""
    nu0, nu1 = z[0] - x[0], z[1] - x[1]
    s00, s01, s10, s11 = P[0, 0] + R[0, 0], P[0, 1] + R[0, 1], P[1, 0] + R[1, 0], P[1, 1] + R[1, 1]
    a, b, d = s00, 0.5 * (s01 + s10), s11
    det = a * d - b * b
    if not (a > 0 and det > 0 and math.isfinite(det)):
        return math.nan, False
    l00 = math.sqrt(s00)
    l10 = s10 / l00
    r = s11 - l10 * l10
    if not r > 0.0:
        return math.nan, False
    l11 = math.sqrt(r)
    w0 = nu0 / l00
    w1 = (nu1 - l10 * w0) / l11
    return w0 * w0 + w1 * w1, True


@njit(cache=True)
def _mix(w: np.ndarray, X: np.ndarray, P: np.ndarray, m: int) -> tuple[np.ndarray, np.ndarray]:
    """Mean and covariance of the first ``m`` components of the mixture Σ wᵢ N(Xᵢ, Pᵢ)."""
    n = X.shape[0]
    x = np.zeros(m)
    for i in range(n):
        for a in range(m):
            x[a] += w[i] * X[i, a]
    out = np.zeros((m, m))
    for i in range(n):
        for a in range(m):
            da = X[i, a] - x[a]
            for b in range(m):
                out[a, b] += w[i] * (P[i, a, b] + da * (X[i, b] - x[b]))
    _symmetrize(out)
    return x, out


@njit(cache=True)
def moment_match(w: np.ndarray, X: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean and covariance of the mixture Σ wᵢ N(Xᵢ, Pᵢ) (rows of ``X``, matrices of ``P``)."""
    return _mix(w, X, P, X.shape[1])


# --- the IMM cycle (plugins/motion/imm.py) -------------------------------------------------------------
# Mode states are held padded to the largest mode's size D (rows of X (n×D), matrices of PP (n×D×D)):
# a 4-state CV mode carries ω = 0 with variance σ_e² (``entry_var``) in component 4 when D = 5.
# ``modes`` rows (kind, q, turn_rate_sd): kind 0 = CV (:func:`cv_predict`), 1 = CT (:func:`ct_predict`).


@njit(cache=True)
def markov_switching(lam: np.ndarray, left: np.ndarray, right: np.ndarray, dt: float) -> np.ndarray:
    """Π(Δt) = max(L diag(e^{λ|Δt|}) R, 0): exp(G|Δt|) from G's eigen-decomposition G = L diag(λ) R;
    an empty ``lam`` means the fixed matrix Π = ``left``."""
    n = lam.shape[0]
    if n == 0:
        return left.copy()
    e = np.exp(lam * abs(dt))
    Pi = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            acc = 0.0
            for k in range(n):
                acc += left[i, k] * e[k] * right[k, j]
            Pi[i, j] = max(acc, 0.0)
    return Pi


@njit(cache=True)
def _take(X: np.ndarray, PP: np.ndarray, j: int, d: int) -> tuple[np.ndarray, np.ndarray]:
    """Copies of X[j, :d] and PP[j, :d, :d] (explicit loops: numba compiles slice copies of 3-D arrays
    into a lot of code, seconds of first-run compile for each)."""
    x = np.empty(d)
    P = np.empty((d, d))
    for a in range(d):
        x[a] = X[j, a]
        for b in range(d):
            P[a, b] = PP[j, a, b]
    return x, P


@njit(cache=True)
def _put(X: np.ndarray, PP: np.ndarray, j: int, x: np.ndarray, P: np.ndarray) -> None:
    """X[j, :d] = x and PP[j, :d, :d] = P, d = len(x) (loops, as :func:`_take`)."""
    for a in range(x.shape[0]):
        X[j, a] = x[a]
        for b in range(x.shape[0]):
            PP[j, a, b] = P[a, b]


@njit(cache=True)
def imm_mix(mu: np.ndarray, X: np.ndarray, PP: np.ndarray, Pi: np.ndarray):
    """c̄ = μ Π and each mode's mixed initial condition: ω_ij = Π_ij μ_i / c̄_j (e_j if c̄_j = 0),
    (X⁰_j, P⁰_j) = moment match of Σ_i ω_ij N(X_i, PP_i)."""
    n, D = X.shape
    cbar = np.zeros(n)
    for j in range(n):
        for i in range(n):
            cbar[j] += mu[i] * Pi[i, j]
    X0 = np.empty((n, D))
    P0 = np.empty((n, D, D))
    w = np.empty(n)
    for j in range(n):
        for i in range(n):
            if cbar[j] > 0:
                w[i] = Pi[i, j] * mu[i] / cbar[j]
            else:
                w[i] = 1.0 if i == j else 0.0
        x0, p0 = _mix(w, X, PP, D)
        _put(X0, P0, j, x0, p0)
    return cbar, X0, P0


@njit(cache=True)
def imm_combine(w: np.ndarray, X: np.ndarray, PP: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The IMM output: moment match of Σ_j w_j N(X_j, PP_j) over the four kinematic components."""
    return _mix(w, X, PP, 4)


@njit(cache=True)
def imm_predict(mu: np.ndarray, X: np.ndarray, PP: np.ndarray, lam: np.ndarray, left: np.ndarray, right: np.ndarray,
                modes: np.ndarray, dt: float, cbar: np.ndarray, Xp: np.ndarray, PPp: np.ndarray, x_bar: np.ndarray,
                P_bar: np.ndarray) -> None:
    """Prediction by ``dt`` written into (c̄, X̄, P̄ of every mode, combined χ̄, P̄): switching, mixing,
    each mode's prediction, and the predicted mixture weighed by c̄ (``modes``: block comment above).
    Outputs are written in place: returning arrays from a kernel costs more than computing them."""
    c, X0, P0 = imm_mix(mu, X, PP, markov_switching(lam, left, right, dt))
    n, D = X.shape
    for j in range(n):
        cbar[j] = c[j]
        for a in range(D):
            Xp[j, a] = 0.0
            for b in range(D):
                PPp[j, a, b] = 0.0
        if modes[j, 0] == 0.0:
            x0, p0 = _take(X0, P0, j, 4)
            xp, pp = cv_predict(x0, p0, dt, modes[j, 1])
        else:
            x0, p0 = _take(X0, P0, j, 5)
            xp, pp = ct_predict(x0, p0, dt, modes[j, 1], modes[j, 2])
        _put(Xp, PPp, j, xp, pp)
    x, P = _mix(cbar, Xp, PPp, 4)
    for a in range(4):
        x_bar[a] = x[a]
        for b in range(4):
            P_bar[a, b] = P[a, b]


@njit(cache=True)
def imm_correct(cbar: np.ndarray, Xp: np.ndarray, PPp: np.ndarray, x_bar: np.ndarray, P_bar: np.ndarray,
                dims: np.ndarray, entry_var: float, z: np.ndarray, R: np.ndarray, mu: np.ndarray, X: np.ndarray,
                PP: np.ndarray, x: np.ndarray, P: np.ndarray) -> tuple[float, int]:
    """Correction by position z of the prediction (c̄, X̄, P̄, χ̄, P̄), written into the state (μ, X, PP)
    and output (χ̂, P̂): every mode's :func:`position_update` on its ``dims[j]`` states, μ_j ∝ c̄_j
    N(ν_j; 0, Λ_j), output moment matched. Returns (NIS of the combined prediction, −2), or, leaving
    the state as it was, (nan, −1) when the combined Λ is not positive definite, (nan, j) when mode j's
    is not."""
    n, D = Xp.shape
    nis, ok = _position_nis(x_bar, P_bar, z, R)
    if not ok:
        return math.nan, -1
    Xn = np.zeros((n, D))
    PPn = np.zeros((n, D, D))
    logw = np.empty(n)
    for j in range(n):
        xj, Pj = _take(Xp, PPp, j, dims[j])
        xn, Pn, _, _, _, loglik, okj = position_update(xj, Pj, z, R)
        if not okj:
            return math.nan, j
        _put(Xn, PPn, j, xn, Pn)
        if dims[j] < D:
            PPn[j, 4, 4] = entry_var
        logw[j] = math.log(max(cbar[j], 1e-300)) + loglik
    top = logw.max()
    total = 0.0
    for j in range(n):
        mu[j] = math.exp(logw[j] - top)
        total += mu[j]
    for j in range(n):
        mu[j] /= total
        for a in range(D):
            X[j, a] = Xn[j, a]
            for b in range(D):
                PP[j, a, b] = PPn[j, a, b]
    xo, Po = _mix(mu, X, PP, 4)
    for a in range(4):
        x[a] = xo[a]
        for b in range(4):
            P[a, b] = Po[a, b]
    return nis, -2


@njit(cache=True)
def imm_cycle(mu: np.ndarray, X: np.ndarray, PP: np.ndarray, lam: np.ndarray, left: np.ndarray, right: np.ndarray,
              modes: np.ndarray, dims: np.ndarray, entry_var: float, dt: float, z: np.ndarray, R: np.ndarray,
              x: np.ndarray, P: np.ndarray, cbar: np.ndarray, Xp: np.ndarray, PPp: np.ndarray, x_bar: np.ndarray,
              P_bar: np.ndarray) -> tuple[float, int]:
    """One whole IMM cycle in place: :func:`imm_predict` into (c̄, X̄, P̄, χ̄, P̄), then :func:`imm_correct`."""
    imm_predict(mu, X, PP, lam, left, right, modes, dt, cbar, Xp, PPp, x_bar, P_bar)
    return imm_correct(cbar, Xp, PPp, x_bar, P_bar, dims, entry_var, z, R, mu, X, PP, x, P)


# --- packed IMM state: one buffer per filter (μ, X, PP, χ̂, P̂, then the prediction c̄, X̄, P̄, χ̄, P̄) ----------
@njit(cache=True)
def _imm_block(buf: np.ndarray, o: int, n: int, D: int):
    """Views (weights n, states n×D, covariances n×D×D, χ 4, P 4×4) of ``buf`` from offset ``o``."""
    a = buf[o:o + n]
    o += n
    b = buf[o:o + n * D].reshape((n, D))
    o += n * D
    c = buf[o:o + n * D * D].reshape((n, D, D))
    o += n * D * D
    return a, b, c, buf[o:o + 4], buf[o + 4:o + 20].reshape((4, 4))


@njit(cache=True)
def imm_views(buf: np.ndarray, n: int, D: int):
    """Views of the packed buffer of an IMM with ``n`` modes of padded size ``D``: the state
    (μ, X, PP, χ̂, P̂) and the prediction (c̄, X̄, P̄, χ̄, P̄); ``buf`` must hold
    2 (n + nD + nD² + 20) numbers. Called from Python once per filter to make its attributes."""
    return _imm_block(buf, 0, n, D), _imm_block(buf, n + n * D + n * D * D + 20, n, D)


def imm_constants(modes: np.ndarray, dims: np.ndarray, entry_var: float, lam: np.ndarray, left: np.ndarray,
                  right: np.ndarray) -> np.ndarray:
    """The settings of an IMM in one array for the packed kernels: [n, D, σ_e², len(λ), modes rows
    (kind, q, turn_rate_sd), dims, λ, L, R] (``markov_switching``'s chain; an empty λ: L is the fixed Π)."""
    n = len(dims)
    return np.concatenate([[n, max(dims), entry_var, len(lam)], np.ravel(modes), dims, lam, np.ravel(left),
                           np.ravel(right)]).astype(float)


@njit(cache=True)
def _imm_settings(k: np.ndarray):
    """(n, D, σ_e², modes, dims, λ, L, R) from :func:`imm_constants`."""
    n, D, m = int(k[0]), int(k[1]), int(k[3])
    o = 4
    modes = k[o:o + 3 * n].reshape((n, 3))
    o += 3 * n
    dims = np.empty(n, np.int64)
    for j in range(n):
        dims[j] = int(k[o + j])
    o += n
    lam = k[o:o + m]
    o += m
    left = k[o:o + n * n].reshape((n, n))
    o += n * n
    right = k[o:o + m * m].reshape((m, m))
    return n, D, k[2], modes, dims, lam, left, right


@njit(cache=True)
def imm_advance(buf: np.ndarray, k: np.ndarray, dt: float) -> None:
    """:func:`imm_predict` by ``dt`` of the packed state into its prediction."""
    n, D, _, modes, _, lam, left, right = _imm_settings(k)
    (mu, X, PP, _, _), (cbar, Xp, PPp, x_bar, P_bar) = imm_views(buf, n, D)
    imm_predict(mu, X, PP, lam, left, right, modes, dt, cbar, Xp, PPp, x_bar, P_bar)


@njit(cache=True)
def imm_screen(buf: np.ndarray, k: np.ndarray, dt: float, predicted: bool, z: np.ndarray, C: np.ndarray,
               R: np.ndarray, bias: np.ndarray, bias_cov: np.ndarray, zc: np.ndarray, Rc: np.ndarray,
               gate: float) -> tuple[float, float, int]:
    """Innovation screening, and the update when it passes: the bias-corrected measurement (zc = z − C ς̂,
    Rc = R + C P_ς Cᵀ, written out), its d² against the predicted position (S = P̄_pp + Rc; the
    prediction by ``dt`` made first unless ``predicted``) and, if d² ≤ ``gate``, :func:`imm_update` from
    that prediction. Returns (d², NIS, code): code −4 when not updated, else :func:`imm_update`'s."""
    bias_correct_into(z, C, R, bias, bias_cov, zc, Rc)
    if not predicted:
        imm_advance(buf, k, dt)
    n, D = int(k[0]), int(k[1])
    _, (_, _, _, x_bar, P_bar) = imm_views(buf, n, D)
    d2 = position_d2(zc, Rc, x_bar, P_bar)
    if not d2 <= gate:
        return d2, math.nan, -4
    if measurement_ok(0.0, zc, Rc) != 0:  # as imm_update (not called: its cycle would be compiled in here too)
        return d2, math.nan, -3
    nis, code = _imm_correct_packed(buf, k, zc, Rc)
    return d2, nis, code


@njit(cache=True)
def imm_update(buf: np.ndarray, k: np.ndarray, dt: float, predicted: bool, z: np.ndarray,
               R: np.ndarray) -> tuple[float, int]:
    """Correction of the packed state by position z: from the kept prediction if ``predicted``, else after
    :func:`imm_advance` by ``dt`` (the operations of :func:`imm_cycle`). Returns :func:`imm_correct`'s
    (NIS, code), or (nan, −3), the state untouched, when (z, R) fails :func:`measurement_ok`."""
    if measurement_ok(0.0, z, R) != 0:
        return math.nan, -3
    if not predicted:
        imm_advance(buf, k, dt)
    return _imm_correct_packed(buf, k, z, R)


@njit(cache=True)
def _imm_correct_packed(buf: np.ndarray, k: np.ndarray, z: np.ndarray, R: np.ndarray) -> tuple[float, int]:
    """:func:`imm_correct` of the packed prediction into the packed state."""
    n, D, entry_var, _, dims, _, _, _ = _imm_settings(k)
    (mu, X, PP, x, P), (cbar, Xp, PPp, x_bar, P_bar) = imm_views(buf, n, D)
    return imm_correct(cbar, Xp, PPp, x_bar, P_bar, dims, entry_var, z, R, mu, X, PP, x, P)
