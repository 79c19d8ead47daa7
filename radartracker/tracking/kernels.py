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
* a filter's IMM packed in one buffer with its settings and the kernels' scratch (:func:`imm_buffer`,
  :func:`imm_views`), so that a call passes the filter as one array instead of fifteen (each array
  argument costs ~0.15 µs to type and unbox) and allocates nothing: :func:`imm_advance` (prediction),
  :func:`imm_update` (the measurement checks and the correction, from the kept prediction or in one
  cycle), :func:`imm_screen` (bias correction of a radar measurement, prediction, its d²
  (:mod:`radartracker.estimation.screening`) and the update when it passes the gate). Each step is
  written once (``_*_into``, into the caller's arrays); the public array functions allocate and call it.
"""

from __future__ import annotations

import math

import numpy as np
from llvmlite import ir
from numba import carray, njit, types
from numba.core import cgutils
from numba.extending import intrinsic

from radartracker.estimation.screening import bias_correct_into, position_d2

_LOG_2PI = math.log(2.0 * math.pi)
_SMALL = 1e-4  # |ωT| below which the CT Taylor series are used (as plugins/motion/ct.py)


def _probe() -> int:
    return 0


# The kernels that allocate nothing and return no array of their own (the views of a packed buffer have no
# reference) are compiled without numba's runtime and its reference counts (``kernel``: ``_nrt=False``; the
# ``coupled-sparse`` plugin's kernels use it too): with it, every array argument of every call and every view
# taken costs an atomic increment and decrement. A numba without the option compiles them with their counts.
try:
    njit(cache=True, _nrt=False)(_probe)()
    kernel, view = njit(cache=True, _nrt=False), njit(cache=True, _nrt=True)
except KeyError:
    kernel = view = njit(cache=True)


@kernel
def _symmetrize(P: np.ndarray, n: int) -> None:
    """P[:n, :n] = (P + Pᵀ) / 2 in place."""
    for i in range(n):
        for j in range(i + 1, n):
            m = 0.5 * (P[i, j] + P[j, i])
            P[i, j] = m
            P[j, i] = m


@kernel
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


# --- the mode filters: each written once, into the caller's arrays (the public functions allocate) ------------
@kernel
def _cv_predict_inplace(x: np.ndarray, P: np.ndarray, dt: float, q: float) -> None:
    """:func:`cv_predict` of (x[:4], P[:4, :4]) in place: the rows of A P, then its columns (each step reads
    only entries it does not write), Q, symmetrised."""
    x[0] += dt * x[2]
    x[1] += dt * x[3]
    for j in range(4):  # A P: rows 0, 1 gain dt × rows 2, 3
        P[0, j] += dt * P[2, j]
        P[1, j] += dt * P[3, j]
    for i in range(4):  # (A P) Aᵀ: columns 0, 1 gain dt × columns 2, 3
        P[i, 0] += dt * P[i, 2]
        P[i, 1] += dt * P[i, 3]
    if q != 0.0 and dt != 0.0:
        adt = abs(dt)
        q3, q2, q1 = q * (adt**3 / 3), q * (adt**2 / 2), q * adt
        for k in range(2):
            P[k, k] += q3
            P[k, k + 2] += q2
            P[k + 2, k] += q2
            P[k + 2, k + 2] += q1
    _symmetrize(P, 4)


@njit(cache=True)
def cv_predict(x: np.ndarray, P: np.ndarray, dt: float, q: float) -> tuple[np.ndarray, np.ndarray]:
    """Constant-velocity prediction of (χ, P) by ``dt`` seconds with white-acceleration density ``q``."""
    xp, Pp = x.copy(), P.copy()
    _cv_predict_inplace(xp, Pp, dt, q)
    return xp, Pp


@kernel
def _ct_predict_into(x: np.ndarray, P: np.ndarray, T: float, q: float, turn_rate_sd: float, xp: np.ndarray,
                     Pp: np.ndarray, F: np.ndarray, FP: np.ndarray) -> None:
    """:func:`ct_predict` of (x[:5], P[:5, :5]) into (xp, Pp), with F and F P in the 5×5 scratch ``F``, ``FP``."""
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
    xp[0] = x[0] + f1 * vx + f2 * vy
    xp[1] = x[1] - f2 * vx + f1 * vy
    xp[2] = c * vx + s * vy
    xp[3] = -s * vx + c * vy
    xp[4] = w
    for i in range(5):
        for j in range(5):
            F[i, j] = 1.0 if i == j else 0.0
            FP[i, j] = 0.0
    F[0, 2], F[0, 3], F[0, 4] = f1, f2, d1 * vx + d2 * vy
    F[1, 2], F[1, 3], F[1, 4] = -f2, f1, -d2 * vx + d1 * vy
    F[2, 2], F[2, 3], F[2, 4] = c, s, T * (-s * vx + c * vy)
    F[3, 2], F[3, 3], F[3, 4] = -s, c, T * (-c * vx - s * vy)
    for i in range(5):
        for k in range(5):
            if F[i, k] != 0.0:
                for j in range(5):
                    FP[i, j] += F[i, k] * P[k, j]
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
    _symmetrize(Pp, 5)


@njit(cache=True)
def ct_predict(x: np.ndarray, P: np.ndarray, T: float, q: float, turn_rate_sd: float
               ) -> tuple[np.ndarray, np.ndarray]:
    """Coordinated-turn EKF prediction of (ξ, P), ξ = [x, y, vx, vy, ω], over ``T`` seconds."""
    xp, Pp = np.empty(5), np.empty((5, 5))
    _ct_predict_into(x, P, T, q, turn_rate_sd, xp, Pp, np.empty((5, 5)), np.empty((5, 5)))
    return xp, Pp


@kernel
def _position_update_into(x: np.ndarray, P: np.ndarray, z: np.ndarray, R: np.ndarray, n: int, xn: np.ndarray,
                          Pn: np.ndarray) -> tuple[float, float, bool]:
    """:func:`position_update` of (x[:n], P[:n, :n]) into (xn[:n], Pn[:n, :n]): (NIS, log-likelihood, ok);
    when not ok, xn and Pn may be partly written."""
    nu0, nu1 = z[0] - x[0], z[1] - x[1]
    s00, s01, s10, s11 = P[0, 0] + R[0, 0], P[0, 1] + R[0, 1], P[1, 0] + R[1, 0], P[1, 1] + R[1, 1]
    a, b, d = s00, 0.5 * (s01 + s10), s11
    det = a * d - b * b
    if not (a > 0 and det > 0 and math.isfinite(det)):
        return math.nan, math.nan, False
    i00, i01, i11 = d / det, -b / det, a / det
    for i in range(n):
        g0 = P[i, 0] * i00 + P[i, 1] * i01  # row i of G = K Λ⁻¹, K = P Hᵀ = P[:, :2]
        g1 = P[i, 0] * i01 + P[i, 1] * i11
        xn[i] = x[i] + g0 * nu0 + g1 * nu1
        for j in range(n):
            Pn[i, j] = P[i, j] - (g0 * P[j, 0] + g1 * P[j, 1])
    _symmetrize(Pn, n)
    # NIS and log-likelihood from the Cholesky factor of Λ (lower triangle, as numpy.linalg.cholesky)
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
    xn, Pn = np.empty(n), np.empty((n, n))
    nis, loglik, ok = _position_update_into(x, P, z, R, n, xn, Pn)
    if not ok:
        return x.copy(), P.copy(), nu, S, math.nan, math.nan, False
    return xn, Pn, nu, S, nis, loglik, True


@kernel
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


@kernel
def _mix_into(w: np.ndarray, X: np.ndarray, P: np.ndarray, m: int, x: np.ndarray, out: np.ndarray) -> None:
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
    _symmetrize(out, m)


@njit(cache=True)
def moment_match(w: np.ndarray, X: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean and covariance of the mixture Σ wᵢ N(Xᵢ, Pᵢ) (rows of ``X``, matrices of ``P``)."""
    m = X.shape[1]
    x, out = np.empty(m), np.empty((m, m))
    _mix_into(w, X, P, m, x, out)
    return x, out


# --- the IMM cycle (plugins/motion/imm.py) -------------------------------------------------------------
# Mode states are held padded to the largest mode's size D (rows of X (n×D), matrices of PP (n×D×D)):
# a 4-state CV mode carries ω = 0 with variance σ_e² (``entry_var``) in component 4 when D = 5.
# ``modes`` rows (kind, q, turn_rate_sd): kind 0 = CV (:func:`cv_predict`), 1 = CT (:func:`ct_predict`).
# Each step is written once, into the caller's arrays and scratch (``*_into``); the public functions
# allocate what they need and call it, the packed kernels pass views of one buffer.


@kernel
def _switching_into(lam: np.ndarray, left: np.ndarray, right: np.ndarray, dt: float, e: np.ndarray,
                    Pi: np.ndarray) -> None:
    """:func:`markov_switching` into ``Pi`` (``e``: len(λ) scratch)."""
    m = lam.shape[0]
    if m == 0:
        for i in range(left.shape[0]):
            for j in range(left.shape[1]):
                Pi[i, j] = left[i, j]
        return
    for k in range(m):
        e[k] = math.exp(lam[k] * abs(dt))
    for i in range(m):
        for j in range(m):
            acc = 0.0
            for k in range(m):
                acc += left[i, k] * e[k] * right[k, j]
            Pi[i, j] = max(acc, 0.0)


@njit(cache=True)
def markov_switching(lam: np.ndarray, left: np.ndarray, right: np.ndarray, dt: float) -> np.ndarray:
    """Π(Δt) = max(L diag(e^{λ|Δt|}) R, 0): exp(G|Δt|) from G's eigen-decomposition G = L diag(λ) R;
    an empty ``lam`` means the fixed matrix Π = ``left``."""
    if lam.shape[0] == 0:
        return left.copy()
    Pi = np.empty(left.shape)
    _switching_into(lam, left, right, dt, np.empty(lam.shape[0]), Pi)
    return Pi


@kernel
def _imm_mix_into(mu: np.ndarray, X: np.ndarray, PP: np.ndarray, Pi: np.ndarray, cbar: np.ndarray, X0: np.ndarray,
                  P0: np.ndarray, w: np.ndarray) -> None:
    """:func:`imm_mix` into (c̄, X⁰, P⁰), ``w``: n scratch."""
    n, D = X.shape
    for j in range(n):
        cbar[j] = 0.0
        for i in range(n):
            cbar[j] += mu[i] * Pi[i, j]
    for j in range(n):
        for i in range(n):
            if cbar[j] > 0:
                w[i] = Pi[i, j] * mu[i] / cbar[j]
            else:
                w[i] = 1.0 if i == j else 0.0
        _mix_into(w, X, PP, D, X0[j], P0[j])


@njit(cache=True)
def imm_mix(mu: np.ndarray, X: np.ndarray, PP: np.ndarray, Pi: np.ndarray):
    """c̄ = μ Π and each mode's mixed initial condition: ω_ij = Π_ij μ_i / c̄_j (e_j if c̄_j = 0),
    (X⁰_j, P⁰_j) = moment match of Σ_i ω_ij N(X_i, PP_i)."""
    n, D = X.shape
    cbar, X0, P0 = np.empty(n), np.empty((n, D)), np.empty((n, D, D))
    _imm_mix_into(mu, X, PP, Pi, cbar, X0, P0, np.empty(n))
    return cbar, X0, P0


@njit(cache=True)
def imm_combine(w: np.ndarray, X: np.ndarray, PP: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The IMM output: moment match of Σ_j w_j N(X_j, PP_j) over the four kinematic components."""
    x, P = np.empty(4), np.empty((4, 4))
    _mix_into(w, X, PP, 4, x, P)
    return x, P


@kernel
def _clear(x: np.ndarray, P: np.ndarray, D: int) -> None:
    """x[:D] = 0, P[:D, :D] = 0: a mode's padded state before it is written."""
    for a in range(D):
        x[a] = 0.0
        for b in range(D):
            P[a, b] = 0.0


@kernel
def _imm_predict_into(mu, X, PP, lam, left, right, modes, dt, cbar, Xp, PPp, x_bar, P_bar, v, Pi, X0, P0, F, FP):
    """:func:`imm_predict`, with scratch v (n), Π (n×n), the mixed X⁰ (n×D), P⁰ (n×D×D), F and F P (5×5)."""
    _switching_into(lam, left, right, dt, v, Pi)
    _imm_mix_into(mu, X, PP, Pi, cbar, X0, P0, v)
    n, D = X.shape
    for j in range(n):
        xp, pp = Xp[j], PPp[j]
        if modes[j, 0] == 0.0:  # the 4 states, zero padding up to D
            for a in range(D):
                xp[a] = X0[j, a] if a < 4 else 0.0
                for b in range(D):
                    pp[a, b] = P0[j, a, b] if a < 4 and b < 4 else 0.0
            _cv_predict_inplace(xp, pp, dt, modes[j, 1])
        else:  # writes all of xp[:5], pp[:5, :5] (D = 5 when a CT mode is present)
            _ct_predict_into(X0[j], P0[j], dt, modes[j, 1], modes[j, 2], xp, pp, F, FP)
    _mix_into(cbar, Xp, PPp, 4, x_bar, P_bar)


@njit(cache=True)
def imm_predict(mu: np.ndarray, X: np.ndarray, PP: np.ndarray, lam: np.ndarray, left: np.ndarray, right: np.ndarray,
                modes: np.ndarray, dt: float, cbar: np.ndarray, Xp: np.ndarray, PPp: np.ndarray, x_bar: np.ndarray,
                P_bar: np.ndarray) -> None:
    """Prediction by ``dt`` written into (c̄, X̄, P̄ of every mode, combined χ̄, P̄): switching, mixing,
    each mode's prediction, and the predicted mixture weighed by c̄ (``modes``: block comment above).
    Outputs are written in place: returning arrays from a kernel costs more than computing them."""
    n, D = X.shape
    _imm_predict_into(mu, X, PP, lam, left, right, modes, dt, cbar, Xp, PPp, x_bar, P_bar, np.empty(n),
                      np.empty((n, n)), np.empty((n, D)), np.empty((n, D, D)), np.empty((5, 5)), np.empty((5, 5)))


@kernel
def _imm_correct_into(cbar, Xp, PPp, x_bar, P_bar, dims, entry_var, z, R, mu, X, PP, x, P, v, Xn, PPn):
    """:func:`imm_correct`, with scratch v (n) and the corrected modes Xn (n×D), PPn (n×D×D)."""
    n, D = Xp.shape
    nis, ok = _position_nis(x_bar, P_bar, z, R)
    if not ok:
        return math.nan, -1
    for j in range(n):
        xn, Pn = Xn[j], PPn[j]
        d = int(dims[j])
        if d < D:  # the update writes [:d], [:d, :d] only
            _clear(xn, Pn, D)
        _, loglik, okj = _position_update_into(Xp[j], PPp[j], z, R, d, xn, Pn)
        if not okj:
            return math.nan, j
        if d < D:
            Pn[4, 4] = entry_var
        v[j] = math.log(max(cbar[j], 1e-300)) + loglik
    top = v[0]  # v[:n].max() (numpy's: the first nan if any), written out: its compiled form needs the runtime
    for j in range(1, n):
        if math.isnan(top):
            break
        if math.isnan(v[j]) or v[j] > top:
            top = v[j]
    total = 0.0
    for j in range(n):
        mu[j] = math.exp(v[j] - top)
        total += mu[j]
    for j in range(n):
        mu[j] /= total
        for a in range(D):
            X[j, a] = Xn[j, a]
            for b in range(D):
                PP[j, a, b] = PPn[j, a, b]
    _mix_into(mu, X, PP, 4, x, P)
    return nis, -2


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
    return _imm_correct_into(cbar, Xp, PPp, x_bar, P_bar, dims, entry_var, z, R, mu, X, PP, x, P, np.empty(n),
                             np.empty((n, D)), np.empty((n, D, D)))


@njit(cache=True)
def imm_cycle(mu: np.ndarray, X: np.ndarray, PP: np.ndarray, lam: np.ndarray, left: np.ndarray, right: np.ndarray,
              modes: np.ndarray, dims: np.ndarray, entry_var: float, dt: float, z: np.ndarray, R: np.ndarray,
              x: np.ndarray, P: np.ndarray, cbar: np.ndarray, Xp: np.ndarray, PPp: np.ndarray, x_bar: np.ndarray,
              P_bar: np.ndarray) -> tuple[float, int]:
    """One whole IMM cycle in place: :func:`imm_predict` into (c̄, X̄, P̄, χ̄, P̄), then :func:`imm_correct`."""
    imm_predict(mu, X, PP, lam, left, right, modes, dt, cbar, Xp, PPp, x_bar, P_bar)
    return imm_correct(cbar, Xp, PPp, x_bar, P_bar, dims, entry_var, z, R, mu, X, PP, x, P)


# --- packed IMM: one buffer per filter -------------------------------------------------------------------
# [header | settings | state (μ, X, PP, χ̂, P̂) | prediction (c̄, X̄, P̄, χ̄, P̄) | scratch (v, Π, Y, YP, F, FP)],
# the header [n, D, σ_e², m = len(λ), max_gap_s, epoch, prediction's time, compiled, stopped]: the state's
# time (IMM_EPOCH, nan before start) and the time the prediction is for (IMM_PREDICTED, nan: none) are the
# filter's own (its Python attributes read them), so that imm_screen_many reads and moves them where they
# are; compiled is 0 when the modes' rows are unused (modes called in Python); stopped is imm_screen_many's
# scratch. The settings [modes rows (kind, q, turn_rate_sd), dims, λ, L, R] (markov_switching's chain;
# m = 0: L is the fixed Π). No kernel allocates (each small allocation ~40 ns), and inside a kernel
# the parts are numba.carray views of the buffer's memory, which take no reference: an ordinary view
# costs a reference count up and down (atomic, ~10 ns) for itself and each row taken from it, ~0.9 µs
# per predict-and-correct cycle. Such views live only inside the call that made them, whose ``buf``
# argument keeps the memory alive; Python gets ordinary views (:func:`imm_views`).
IMM_EPOCH, IMM_PREDICTED, _COMPILED, _STOPPED, _HEADER = 5, 6, 7, 8, 9  # header slots (above), its length


@njit(cache=True)
def _imm_offsets(n: int, D: int, m: int) -> tuple[int, int, int, int, int, int, int, int, int]:
    """Offsets in the packed buffer of: modes, dims, λ, L, R, the state, the prediction, the scratch, the end."""
    modes = _HEADER
    dims = modes + 3 * n
    lam = dims + n
    left = lam + m
    right = left + n * n
    state = right + m * m
    pred = state + n + n * D + n * D * D + 20
    scratch = pred + n + n * D + n * D * D + 20
    return modes, dims, lam, left, right, state, pred, scratch, scratch + n + n * n + n * D + n * D * D + 50


def imm_buffer(modes: np.ndarray, dims: np.ndarray, entry_var: float, lam: np.ndarray, left: np.ndarray,
               right: np.ndarray, max_gap: float = math.inf, compiled: bool = True) -> np.ndarray:
    """The packed buffer of an IMM (block comment above): its settings written, state and prediction zero,
    not started (epoch and prediction's time nan); ``max_gap``: the longest step :func:`imm_screen` takes
    (the filter's ``max_gap_s``); ``compiled`` False: ``modes`` are not the filter's (imm_screen_many skips it)."""
    n, m = len(dims), len(lam)
    offsets = _imm_offsets(n, int(max(dims)), m)
    buf = np.zeros(offsets[-1])
    buf[:offsets[5]] = np.concatenate([[n, max(dims), entry_var, m, max_gap, math.nan, math.nan, float(compiled), 0.0],
                                       np.ravel(modes), dims, lam, np.ravel(left), np.ravel(right)])
    return buf


def imm_views(buf: np.ndarray) -> tuple[tuple[np.ndarray, ...], tuple[np.ndarray, ...]]:
    """Views (numpy's) of a packed buffer's state (μ, X, PP, χ̂, P̂) and prediction (c̄, X̄, P̄, χ̄, P̄): made
    once per filter for its attributes."""
    n, D, m = int(buf[0]), int(buf[1]), int(buf[3])

    def block(o: int) -> tuple[np.ndarray, ...]:
        a, b, c = o + n, o + n + n * D, o + n + n * D + n * D * D
        return (buf[o:a], buf[a:b].reshape(n, D), buf[b:c].reshape(n, D, D), buf[c:c + 4],
                buf[c + 4:c + 20].reshape(4, 4))
    offsets = _imm_offsets(n, D, m)
    return block(offsets[5]), block(offsets[6])


@intrinsic
def _address(typingctx, arr, offset):
    """Pointer to ``arr[offset]`` (no reference taken; for :func:`numba.carray` views inside one call)."""
    def codegen(context, builder, sig, args):
        return builder.gep(context.make_array(sig.args[0])(context, builder, args[0]).data, [args[1]])
    return types.CPointer(arr.dtype)(arr, offset), codegen


@view
def _vec(buf: np.ndarray, o: int, n: int) -> np.ndarray:
    """buf[o:o + n] (a view without a reference: block comment above)."""
    return carray(_address(buf, o), (n,))


@view
def _mat(buf: np.ndarray, o: int, r: int, c: int) -> np.ndarray:
    """buf[o:o + r c] as an r×c matrix (a view without a reference)."""
    return carray(_address(buf, o), (r, c))


@view
def _cube(buf: np.ndarray, o: int, n: int, D: int) -> np.ndarray:
    """buf[o:o + n D D] as n D×D matrices (a view without a reference)."""
    return carray(_address(buf, o), (n, D, D))


@view
def _imm_block(buf: np.ndarray, o: int, n: int, D: int):
    """Views (weights n, states n×D, covariances n×D×D, χ 4, P 4×4) of ``buf`` from offset ``o``, as
    :func:`imm_views`'s."""
    a, b, c = o + n, o + n + n * D, o + n + n * D + n * D * D
    return _vec(buf, o, n), _mat(buf, a, n, D), _cube(buf, b, n, D), _vec(buf, c, 4), _mat(buf, c + 4, 4, 4)


@view
def _imm_parts(buf: np.ndarray):
    """(n, D, σ_e², modes, dims, (λ, L, R), state, prediction, scratch (v, Π, Y, YP, F, FP)) of a packed buffer."""
    n, D, m = int(buf[0]), int(buf[1]), int(buf[3])
    modes, dims, lam, left, right, state, pred, o, _ = _imm_offsets(n, D, m)
    chain = (_vec(buf, lam, m), _mat(buf, left, n, n), _mat(buf, right, m, m))
    scratch = (_vec(buf, o, n), _mat(buf, o + n, n, n), _mat(buf, o + n + n * n, n, D),
               _cube(buf, o + n + n * n + n * D, n, D), _mat(buf, o + n + n * n + n * D + n * D * D, 5, 5),
               _mat(buf, o + n + n * n + n * D + n * D * D + 25, 5, 5))
    return (n, D, buf[2], _mat(buf, modes, n, 3), _vec(buf, dims, n), chain, _imm_block(buf, state, n, D),
            _imm_block(buf, pred, n, D), scratch)


@kernel
def _advance(parts, dt: float) -> None:
    """:func:`imm_predict` by ``dt`` of the packed state into its prediction."""
    _, _, _, modes, _, (lam, left, right), (mu, X, PP, _, _), pred, (v, Pi, Y, YP, F, FP) = parts
    _imm_predict_into(mu, X, PP, lam, left, right, modes, dt, *pred, v, Pi, Y, YP, F, FP)


@kernel
def _correct(parts, z: np.ndarray, R: np.ndarray) -> tuple[float, int]:
    """:func:`imm_correct` of the packed prediction into the packed state."""
    _, _, entry_var, _, dims, _, state, pred, (v, _, Y, YP, _, _) = parts
    return _imm_correct_into(*pred, dims, entry_var, z, R, *state, v, Y, YP)


@kernel
def imm_advance(buf: np.ndarray, dt: float) -> None:
    """:func:`imm_predict` by ``dt`` of the packed state into its prediction."""
    _advance(_imm_parts(buf), dt)


@kernel
def imm_screen(buf: np.ndarray, dt: float, predicted: bool, z: np.ndarray, C: np.ndarray, R: np.ndarray,
               bias: np.ndarray, bias_cov: np.ndarray, zc: np.ndarray, Rc: np.ndarray,
               gate: float) -> tuple[float, float, int]:
    """Innovation screening, and the update when it passes: the bias-corrected measurement (zc = z − C ς̂,
    Rc = R + C P_ς Cᵀ, written out), its d² against the predicted position (S = P̄_pp + Rc; the
    prediction by ``dt`` made first unless ``predicted``) and, if d² ≤ ``gate``, :func:`imm_update` from
    that prediction. Returns (d², NIS, code): code −4 when not updated, −5 (nothing done) when |dt| is not
    within the settings' max_gap (or nan), else :func:`imm_update`'s."""
    if not abs(dt) <= buf[4]:  # the caller raises, with the messages of the checks in Python
        return math.nan, math.nan, -5
    bias_correct_into(z, C, R, bias, bias_cov, zc, Rc)
    parts = _imm_parts(buf)
    if not predicted:
        _advance(parts, dt)
    x_bar, P_bar = parts[7][3], parts[7][4]
    d2 = position_d2(zc, Rc, x_bar, P_bar)
    if not d2 <= gate:
        return d2, math.nan, -4
    if measurement_ok(0.0, zc, Rc) != 0:  # as imm_update
        return d2, math.nan, -3
    nis, code = _correct(parts, zc, Rc)
    return d2, nis, code


@kernel
def imm_update(buf: np.ndarray, dt: float, predicted: bool, z: np.ndarray, R: np.ndarray) -> tuple[float, int]:
    """Correction of the packed state by position z: from the kept prediction if ``predicted``, else after
    :func:`imm_advance` by ``dt`` (the operations of :func:`imm_cycle`). Returns :func:`imm_correct`'s
    (NIS, code), or (nan, −3), the state untouched, when (z, R) fails :func:`measurement_ok`."""
    if measurement_ok(0.0, z, R) != 0:
        return math.nan, -3
    parts = _imm_parts(buf)
    if not predicted:
        _advance(parts, dt)
    return _correct(parts, z, R)


@intrinsic
def _pointer(typingctx, address):
    """The float64 pointer at integer ``address`` (a buffer the caller keeps alive; :func:`imm_screen_many`)."""
    def codegen(context, builder, sig, args):
        return builder.inttoptr(args[0], context.get_value_type(sig.return_type))
    return types.CPointer(types.float64)(types.int64), codegen


@intrinsic
def _prefetch(typingctx, address):
    """Ask the processor to bring the cache line at integer ``address`` into its caches (llvm.prefetch: for
    reading, kept; the name without its pointer suffix, which LLVM completes for its version)."""
    def codegen(context, builder, sig, args):
        i8p, i32 = ir.IntType(8).as_pointer(), ir.IntType(32)
        fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(ir.VoidType(), [i8p, i32, i32, i32]),
                                            "llvm.prefetch")
        builder.call(fn, [builder.inttoptr(args[0], i8p), i32(0), i32(3), i32(1)])
        return context.get_dummy_value()
    return types.void(types.int64), codegen


@view
def _buffer_at(address: int) -> np.ndarray:
    """The packed buffer whose data start at ``address`` (its length read from its settings)."""
    head = carray(_pointer(address), (5,))
    n, D, m = int(head[0]), int(head[1]), int(head[3])
    return carray(_pointer(address), (_imm_offsets(n, D, m)[-1],))


@kernel
def _fetch_buffer(address: int) -> None:
    """Prefetch the packed buffer at ``address`` line by line (64-byte lines; all of it: a screening reads
    settings, state and prediction and writes the scratch)."""
    for a in range(address, address + 8 * _buffer_at(address).size, 64):
        _prefetch(a)


@kernel
def imm_screen_many(addresses: np.ndarray, times: np.ndarray, z: np.ndarray, C: np.ndarray, R: np.ndarray,
                    bias: np.ndarray, bias_cov: np.ndarray, gate: np.ndarray, d2: np.ndarray, zc: np.ndarray,
                    Rc: np.ndarray, x: np.ndarray, P: np.ndarray, done: np.ndarray) -> None:
    """:func:`imm_screen` of measurement i of the filter whose packed buffer is at ``addresses[i]``, in
    order, while each filter's measurements pass their gate and update it: ``done[i]`` then, with the
    filter's output (χ̂, P̂) after it in ``x[i]``, ``P[i]``. Each steps from its filter's epoch in the buffer,
    from the prediction kept there if it is for ``times[i]``, and moves the epoch to ``times[i]`` when done;
    once one is not done (or its filter has not started, or is not compiled), neither are the filter's later
    ones, and the filter is as before it, keeping the prediction to ``times[i]`` if one was made. The buffers
    are the caller's, alive for the call."""
    for i in range(len(times)):
        _buffer_at(addresses[i])[_STOPPED] = 0.0
    for i in range(len(times)):
        if i + 1 < len(times):  # the next buffer comes from memory while this one is screened (~2 µs)
            _fetch_buffer(addresses[i + 1])
        buf = _buffer_at(addresses[i])
        t0, t = buf[IMM_EPOCH], times[i]
        if buf[_STOPPED] != 0.0 or buf[_COMPILED] == 0.0 or math.isnan(t0):
            buf[_STOPPED] = 1.0
            continue
        d2[i], _, code = imm_screen(buf, t - t0, buf[IMM_PREDICTED] == t, z[i], C[i], R[i], bias[i], bias_cov[i],
                                    zc[i], Rc[i], gate[i])
        if code != -2:
            buf[_STOPPED] = 1.0
            if code != -5:  # the prediction to t was made (or was kept) and the state is unchanged
                buf[IMM_PREDICTED] = t
            continue
        buf[IMM_EPOCH], buf[IMM_PREDICTED] = t, math.nan
        _, _, _, xs, Ps = _imm_parts(buf)[6]
        for a in range(4):
            x[i, a] = xs[a]
            for b in range(4):
                P[i, a, b] = Ps[a, b]
        done[i] = True
