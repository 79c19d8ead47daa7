"""Compiled IMM cycle of plugin ``imm`` (the equations of :mod:`radartracker_plugins.motion.imm`), in named steps.

A filter's numbers live in plain float arrays, cut into views by slicing (:func:`settings_views`,
:func:`block_views`), so that a call passes a filter as three arrays instead of fifteen:

* the settings, one array per configuration shared by its filters:
  ``[n, D, m, σ_e² | modes (n×3) | dims (n) | λ (m) | L (n×n) | R (m×m)]`` — n modes, states padded to
  the largest mode's size D, each mode's row (kind, q, σ_ω) with kind 0 = CV (:func:`cv_predict_into`),
  1 = CT (:func:`ct_predict_into`), −1 = a mode filter called in Python; its own dimension; and the
  Markov chain Π(Δt) = max(L diag(e^{λ|Δt|}) R, 0) (m = len(λ) = 0: L is the fixed Π);
* two blocks of the same layout ``[w (n) | X (n×D) | PP (n×D×D) | χ (4) | P (4×4)]``: the state
  (μ, mode states, combined output χ̂, P̂) and the prediction (c̄, predicted mode states, predicted
  mixture χ̄, P̄).

A 4-state CV mode carries ω = 0 with variance σ_e² (``entry_var``) in component 4 when D = 5.
The steps: :func:`switching_into` Π(Δt); :func:`mix_into` c̄ = μΠ, ω_ij = Π_ij μ_i / c̄_j and the
moment-matched initial conditions; :func:`predict_modes_into` each mode's prediction; :func:`advance`
all three and the predicted mixture Σ c̄_j N(ξ̄_j, P̄_j); :func:`correct` each mode's position update,
μ_j ∝ c̄_j N(ν_j; 0, Λ_j) and the moment-matched output; :func:`screen` innovation screening with the
core's equations (``radartracker.api.bias_correct_into``, ``position_d2``) and the correction when it
passes.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from radartracker.api import bias_correct_into, position_d2
from radartracker_plugins.motion._compiled import (ct_predict_into, cv_predict_into, innovation_nis, measurement_ok,
                                                   mixture_into, position_update_into)

HEADER = 4  # n, D, m, σ_e²
CV, CT, PYTHON = 0.0, 1.0, -1.0  # the kinds of a mode's row


def settings_array(modes: np.ndarray, dims: np.ndarray, entry_var: float, lam: np.ndarray, left: np.ndarray,
                   right: np.ndarray) -> np.ndarray:
    """The settings array of an IMM (module docstring)."""
    head = [len(dims), max(dims), len(lam), entry_var]
    return np.concatenate([head, np.ravel(modes), dims, lam, np.ravel(left), np.ravel(right)]).astype(float)


def block_size(n: int, D: int) -> int:
    """Length of a state or prediction block of n modes of size D."""
    return n + n * D + n * D * D + 20


@njit(cache=True, inline="always")
def settings_views(s: np.ndarray):
    """(n, D, σ_e², modes, dims, λ, L, R) of a settings array."""
    n, D, m = int(s[0]), int(s[1]), int(s[2])
    o = HEADER
    modes = s[o:o + 3 * n].reshape((n, 3))
    o += 3 * n
    dims = s[o:o + n]
    o += n
    lam = s[o:o + m]
    o += m
    left = s[o:o + n * n].reshape((n, n))
    o += n * n
    right = s[o:o + m * m].reshape((m, m))
    return n, D, s[3], modes, dims, lam, left, right


@njit(cache=True, inline="always")
def block_views(buf: np.ndarray, n: int, D: int):
    """Views (weights n, states n×D, covariances n×D×D, χ 4, P 4×4) of a state or prediction block."""
    a, b, c = n, n + n * D, n + n * D + n * D * D
    return (buf[:a], buf[a:b].reshape((n, D)), buf[b:c].reshape((n, D, D)), buf[c:c + 4],
            buf[c + 4:c + 20].reshape((4, 4)))


@njit(cache=True)
def switching_into(lam: np.ndarray, left: np.ndarray, right: np.ndarray, dt: float, Pi: np.ndarray) -> None:
    """Π(Δt) = max(L diag(e^{λ|Δt|}) R, 0) into ``Pi``: exp(G|Δt|) from G's eigen-decomposition
    G = L diag(λ) R; an empty λ means the fixed matrix Π = L."""
    m = lam.shape[0]
    if m == 0:
        Pi[:, :] = left
        return
    e = np.exp(lam * abs(dt))
    for i in range(m):
        for j in range(m):
            acc = 0.0
            for k in range(m):
                acc += left[i, k] * e[k] * right[k, j]
            Pi[i, j] = max(acc, 0.0)


@njit(cache=True)
def markov_switching(settings: np.ndarray, dt: float) -> np.ndarray:
    """Π(Δt) of an IMM's settings (:func:`switching_into`)."""
    n, _, _, _, _, lam, left, right = settings_views(settings)
    Pi = np.empty((n, n))
    switching_into(lam, left, right, dt, Pi)
    return Pi


@njit(cache=True)
def mix_into(mu: np.ndarray, X: np.ndarray, PP: np.ndarray, Pi: np.ndarray, cbar: np.ndarray, X0: np.ndarray,
             P0: np.ndarray) -> None:
    """c̄ = μ Π and each mode's mixed initial condition: ω_ij = Π_ij μ_i / c̄_j (e_j if c̄_j = 0),
    (X⁰_j, P⁰_j) = moment match of Σ_i ω_ij N(X_i, PP_i)."""
    n, D = X.shape
    w = np.empty(n)
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
        mixture_into(w, X, PP, D, X0[j], P0[j])


@njit(cache=True)
def mix(settings: np.ndarray, state: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(c̄, X⁰, P⁰) of :func:`mix_into` for a step of ``dt`` from the state block: the modes' inputs when
    they are called in Python."""
    n, D, _, _, _, lam, left, right = settings_views(settings)
    mu, X, PP, _, _ = block_views(state, n, D)
    Pi = np.empty((n, n))
    switching_into(lam, left, right, dt, Pi)
    cbar, X0, P0 = np.empty(n), np.empty((n, D)), np.empty((n, D, D))
    mix_into(mu, X, PP, Pi, cbar, X0, P0)
    return cbar, X0, P0


@njit(cache=True)
def predict_modes_into(modes: np.ndarray, X0: np.ndarray, P0: np.ndarray, dt: float, Xp: np.ndarray,
                       PPp: np.ndarray) -> None:
    """Each built-in mode's prediction of its mixed initial condition by ``dt`` into (Xp[j], PPp[j]):
    a CV mode on the 4 kinematic states with zero padding up to D, a CT mode on all 5."""
    n, D = X0.shape
    for j in range(n):
        if modes[j, 0] == CV:
            for a in range(D):
                Xp[j, a] = X0[j, a] if a < 4 else 0.0
                for b in range(D):
                    PPp[j, a, b] = P0[j, a, b] if a < 4 and b < 4 else 0.0
            cv_predict_into(Xp[j], PPp[j], dt, modes[j, 1])
        else:
            ct_predict_into(X0[j], P0[j], dt, modes[j, 1], modes[j, 2], Xp[j], PPp[j])


@njit(cache=True)
def advance(settings: np.ndarray, state: np.ndarray, pred: np.ndarray, dt: float) -> None:
    """The prediction by ``dt`` of the state block into the prediction block: switching, mixing, each
    built-in mode's prediction and the predicted mixture weighed by c̄."""
    n, D, _, modes, _, lam, left, right = settings_views(settings)
    mu, X, PP, _, _ = block_views(state, n, D)
    cbar, Xp, PPp, x_bar, P_bar = block_views(pred, n, D)
    Pi = np.empty((n, n))
    switching_into(lam, left, right, dt, Pi)
    X0, P0 = np.empty((n, D)), np.empty((n, D, D))
    mix_into(mu, X, PP, Pi, cbar, X0, P0)
    predict_modes_into(modes, X0, P0, dt, Xp, PPp)
    mixture_into(cbar, Xp, PPp, 4, x_bar, P_bar)


@njit(cache=True)
def _correct_modes_into(cbar: np.ndarray, Xp: np.ndarray, PPp: np.ndarray, dims: np.ndarray, entry_var: float,
                        z: np.ndarray, R: np.ndarray, Xn: np.ndarray, PPn: np.ndarray, v: np.ndarray) -> int:
    """Each mode's position update on its own ``dims[j]`` states into (Xn[j], PPn[j]) (zero-initialised;
    a 4-state mode gets ω = 0 ± σ_e back in the padding) and v_j = log c̄_j + log N(ν_j; 0, Λ_j).
    Returns −1, or the first mode j whose Λ_j is not positive definite."""
    n, D = Xp.shape
    for j in range(n):
        d = int(dims[j])
        _, loglik, ok = position_update_into(Xp[j], PPp[j], z, R, d, Xn[j], PPn[j])
        if not ok:
            return j
        if d < D:
            PPn[j, 4, 4] = entry_var
        v[j] = math.log(max(cbar[j], 1e-300)) + loglik
    return -1


@njit(cache=True)
def correct(settings: np.ndarray, state: np.ndarray, pred: np.ndarray, z: np.ndarray, R: np.ndarray
            ) -> tuple[float, int]:
    """Correction of the prediction block by position z into the state block: each mode's update,
    μ_j ∝ c̄_j N(ν_j; 0, Λ_j) (normalised from the largest log weight), output moment matched.
    Returns (NIS of the predicted mixture, −2), or, leaving the state as it was, (nan, −1) when the
    mixture's Λ is not positive definite, (nan, j) when mode j's is not."""
    n, D, entry_var, _, dims, _, _, _ = settings_views(settings)
    mu, X, PP, x, P = block_views(state, n, D)
    cbar, Xp, PPp, x_bar, P_bar = block_views(pred, n, D)
    nis, _, ok = innovation_nis(x_bar, P_bar, z, R)
    if not ok:
        return math.nan, -1
    Xn, PPn, v = np.zeros((n, D)), np.zeros((n, D, D)), np.empty(n)
    failed = _correct_modes_into(cbar, Xp, PPp, dims, entry_var, z, R, Xn, PPn, v)
    if failed >= 0:
        return math.nan, failed
    weights = np.exp(v - np.max(v))
    mu[:] = weights / weights.sum()
    X[:, :] = Xn
    PP[:, :, :] = PPn
    mixture_into(mu, X, PP, 4, x, P)
    return nis, -2


@njit(cache=True)
def screen(settings: np.ndarray, state: np.ndarray, pred: np.ndarray, dt: float, z: np.ndarray, C: np.ndarray,
           R: np.ndarray, bias: np.ndarray, bias_cov: np.ndarray, gate: float, zc: np.ndarray, Rc: np.ndarray
           ) -> tuple[float, float, int]:
    """Innovation screening of a radar measurement and the correction when it passes: zc = z − C ς̂,
    Rc = R + C P_ς Cᵀ (written into ``zc``, ``Rc``), the prediction by ``dt`` into the prediction block
    (:func:`advance`; a nan ``dt``: the block already holds the prediction),
    d² = (zc − p̄)ᵀ(P̄_pp + Rc)⁻¹(zc − p̄) against the predicted mixture (the core's screening equations)
    and, if d² ≤ ``gate``, :func:`correct` by (zc, Rc). Returns (d², NIS, code): code −4 when d² is
    outside the gate, −3 when (zc, Rc) is not a valid measurement (the state untouched in both), else
    :func:`correct`'s."""
    bias_correct_into(z, C, R, bias, bias_cov, zc, Rc)
    if not math.isnan(dt):
        advance(settings, state, pred, dt)
    _, _, _, x_bar, P_bar = block_views(pred, int(settings[0]), int(settings[1]))
    d2 = position_d2(zc, Rc, x_bar, P_bar)
    if not d2 <= gate:
        return d2, math.nan, -4
    if measurement_ok(0.0, zc, Rc) != 0:
        return d2, math.nan, -3
    nis, code = correct(settings, state, pred, zc, Rc)
    return d2, nis, code
