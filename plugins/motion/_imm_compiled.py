"""Compiled IMM cycle of plugin ``imm`` (the equations of :mod:`radartracker_plugins.motion.imm`), in named steps.

A filter's numbers live in plain float arrays cut into views by ordinary slicing (no reshape, no copy),
so that a call passes a filter as two arrays and allocates nothing:

* the settings, a 2-D array per configuration shared by its filters (:func:`settings_views`):
  row 0 ``[n, D, m, σ_e²]``; n rows (kind, q, σ_ω), one per mode; a row of the modes' own dimensions;
  a row λ (m); L (n×n); R (m×m) — n modes, states padded to the largest mode's size D, kind 0 = CV
  (:func:`cv_predict_into`), 1 = CT (:func:`ct_predict_into`), −1 = a mode filter called in Python;
  the Markov chain Π(Δt) = max(L diag(e^{λ|Δt|}) R, 0) (m = 0: L is the fixed Π);
* the work array of one filter, M×M slabs (M = max(n, D, 5), :func:`work_shape`) holding two blocks of
  the same layout (:func:`block_views`: weights w (n), χ (4), P (4×4), X (n×D), PP (n×D×D)) — block 0
  the state (μ, mode states, combined output χ̂, P̂), block 1 the prediction (c̄, predicted mode
  states, predicted mixture χ̄, P̄) — and the scratch of one cycle (:func:`scratch_views`: mixing
  weights, log weights, the bias-corrected zc, Rc, Π, mixed and corrected mode states, the CT
  Jacobian), so that every step writes into memory the filter owns.

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

from radartracker.api import bias_correct_into, kernel, position_d2
from radartracker_plugins.motion._compiled import (ct_predict_into, cv_predict_into, innovation_nis, measurement_ok,
                                                   mixture_into, position_update_into)

CV, CT, PYTHON = 0.0, 1.0, -1.0  # the kinds of a mode's row
STATE, PREDICTION = 0, 1  # the blocks of a work array


def settings_array(modes: np.ndarray, dims: np.ndarray, entry_var: float, lam: np.ndarray, left: np.ndarray,
                   right: np.ndarray) -> np.ndarray:
    """The settings array of an IMM (module docstring)."""
    n, m = len(dims), len(lam)
    s = np.zeros((2 * n + m + 3, max(n, 4)))
    s[0, :4] = n, max(dims), m, entry_var
    s[1:n + 1, :3] = modes
    s[n + 1, :n] = dims
    s[n + 2, :m] = lam
    s[n + 3:2 * n + 3, :n] = left
    s[2 * n + 3:, :m] = right
    return s


def work_shape(n: int, D: int) -> tuple[int, int, int]:
    """Shape of the work array of n modes of size D: two blocks of n + 3 slabs and 2n + 5 of scratch."""
    M = max(n, D, 5)
    return 4 * n + 11, M, M


@njit(cache=True, inline="always")
def settings_views(s: np.ndarray):
    """(n, D, σ_e², modes, dims, λ, L, R) of a settings array."""
    n, D, m = int(s[0, 0]), int(s[0, 1]), int(s[0, 2])
    return (n, D, s[0, 3], s[1:n + 1, :3], s[n + 1, :n], s[n + 2, :m], s[n + 3:2 * n + 3, :n],
            s[2 * n + 3:2 * n + 3 + m, :m])


@njit(cache=True, inline="always")
def block_views(work: np.ndarray, n: int, D: int, block: int):
    """Views (weights n, states n×D, covariances n×D×D, χ 4, P 4×4) of block ``block`` (STATE or
    PREDICTION) of a work array."""
    b = block * (n + 3)
    return work[b, 0, :n], work[b + 2, :n, :D], work[b + 3:b + 3 + n, :D, :D], work[b, 1, :4], work[b + 1, :4, :4]


@njit(cache=True, inline="always")
def scratch_views(work: np.ndarray, n: int, D: int):
    """Views of a work array's scratch: (mixing weights n, log weights n, zc 2, Rc 2×2, Π n×n, mixed
    states X⁰ n×D, corrected states n×D, CT Jacobian 5×5, mixed covariances P⁰ n×D×D, corrected
    covariances n×D×D)."""
    o = 2 * (n + 3)
    return (work[o, 0, :n], work[o, 1, :n], work[o, 2, :2], work[o, 3:5, :2], work[o + 1, :n, :n],
            work[o + 2, :n, :D], work[o + 3, :n, :D], work[o + 4, :5, :5], work[o + 5:o + 5 + n, :D, :D],
            work[o + 5 + n:o + 5 + 2 * n, :D, :D])


@njit(cache=True, inline="always")
def switching_into(lam: np.ndarray, left: np.ndarray, right: np.ndarray, dt: float, Pi: np.ndarray) -> None:
    """Π(Δt) = max(L diag(e^{λ|Δt|}) R, 0) into ``Pi``: exp(G|Δt|) from G's eigen-decomposition
    G = L diag(λ) R (each sum accumulated over k in order, one e^{λ_k|Δt|} per k); an empty λ means the
    fixed matrix Π = L."""
    m = lam.shape[0]
    if m == 0:
        for i in range(left.shape[0]):
            for j in range(left.shape[1]):
                Pi[i, j] = left[i, j]
        return
    Pi[:, :] = 0.0
    for k in range(m):
        e = math.exp(lam[k] * abs(dt))
        for i in range(m):
            for j in range(m):
                Pi[i, j] += left[i, k] * e * right[k, j]
    for i in range(m):
        for j in range(m):
            Pi[i, j] = max(Pi[i, j], 0.0)


@njit(cache=True, inline="always")
def markov_switching(settings: np.ndarray, dt: float) -> np.ndarray:
    """Π(Δt) of an IMM's settings (:func:`switching_into`)."""
    n, _, _, _, _, lam, left, right = settings_views(settings)
    Pi = np.empty((n, n))
    switching_into(lam, left, right, dt, Pi)
    return Pi


@njit(cache=True, inline="always")
def mix_into(mu: np.ndarray, X: np.ndarray, PP: np.ndarray, Pi: np.ndarray, w: np.ndarray, cbar: np.ndarray,
             X0: np.ndarray, P0: np.ndarray) -> None:
    """c̄ = μ Π and each mode's mixed initial condition: ω_ij = Π_ij μ_i / c̄_j (e_j if c̄_j = 0; one
    column at a time in ``w``), (X⁰_j, P⁰_j) = moment match of Σ_i ω_ij N(X_i, PP_i)."""
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
        mixture_into(w, X, PP, D, X0[j], P0[j])


@kernel(inline="always")
def mix(settings: np.ndarray, work: np.ndarray, dt: float) -> None:
    """:func:`mix_into` for a step of ``dt`` from the state block: c̄ into the prediction block, (X⁰, P⁰)
    into the scratch (:func:`scratch_views`), the modes' inputs when they are called in Python."""
    n, D, _, _, _, lam, left, right = settings_views(settings)
    mu, X, PP, _, _ = block_views(work, n, D, STATE)
    cbar = block_views(work, n, D, PREDICTION)[0]
    w, _, _, _, Pi, X0, _, _, P0, _ = scratch_views(work, n, D)
    switching_into(lam, left, right, dt, Pi)
    mix_into(mu, X, PP, Pi, w, cbar, X0, P0)


@njit(cache=True, inline="always")
def predict_modes_into(modes: np.ndarray, X0: np.ndarray, P0: np.ndarray, dt: float, F: np.ndarray, Xp: np.ndarray,
                       PPp: np.ndarray) -> None:
    """Each built-in mode's prediction of its mixed initial condition by ``dt`` into (Xp[j], PPp[j]):
    a CV mode on the 4 kinematic states with zero padding up to D, a CT mode on all 5 (Jacobian in F)."""
    n, D = X0.shape
    for j in range(n):
        if modes[j, 0] == CV:
            for a in range(D):
                Xp[j, a] = X0[j, a] if a < 4 else 0.0
                for b in range(D):
                    PPp[j, a, b] = P0[j, a, b] if a < 4 and b < 4 else 0.0
            cv_predict_into(Xp[j], PPp[j], dt, modes[j, 1])
        else:
            ct_predict_into(X0[j], P0[j], dt, modes[j, 1], modes[j, 2], F, Xp[j], PPp[j])


@kernel(inline="always")
def advance(settings: np.ndarray, work: np.ndarray, dt: float) -> None:
    """The prediction by ``dt`` of the state block into the prediction block: switching, mixing, each
    built-in mode's prediction and the predicted mixture weighed by c̄."""
    n, D, _, modes, _, _, _, _ = settings_views(settings)
    mix(settings, work, dt)
    cbar, Xp, PPp, x_bar, P_bar = block_views(work, n, D, PREDICTION)
    _, _, _, _, _, X0, _, F, P0, _ = scratch_views(work, n, D)
    predict_modes_into(modes, X0, P0, dt, F, Xp, PPp)
    mixture_into(cbar, Xp, PPp, 4, x_bar, P_bar)


@njit(cache=True, inline="always")
def _correct_modes_into(cbar: np.ndarray, Xp: np.ndarray, PPp: np.ndarray, dims: np.ndarray, entry_var: float,
                        z: np.ndarray, R: np.ndarray, Xn: np.ndarray, PPn: np.ndarray, v: np.ndarray) -> int:
    """Each mode's position update on its own ``dims[j]`` states into (Xn[j], PPn[j]) (zeroed first;
    a 4-state mode gets ω = 0 ± σ_e back in the padding) and v_j = log c̄_j + log N(ν_j; 0, Λ_j).
    Returns −1, or the first mode j whose Λ_j is not positive definite."""
    n, D = Xp.shape
    Xn[:, :] = 0.0
    PPn[:, :, :] = 0.0
    for j in range(n):
        d = int(dims[j])
        _, loglik, ok = position_update_into(Xp[j], PPp[j], z, R, d, Xn[j], PPn[j])
        if not ok:
            return j
        if d < D:
            PPn[j, 4, 4] = entry_var
        v[j] = math.log(max(cbar[j], 1e-300)) + loglik
    return -1


@njit(cache=True, inline="always")
def _normalised_exp_into(v: np.ndarray, mu: np.ndarray) -> None:
    """μ_j = e^{v_j − max v} / Σ_k e^{v_k − max v}: probabilities from log weights without overflow."""
    top = v[0]
    for j in range(1, v.shape[0]):
        top = max(top, v[j])
    total = 0.0
    for j in range(v.shape[0]):
        mu[j] = math.exp(v[j] - top)
        total += mu[j]
    for j in range(v.shape[0]):
        mu[j] = mu[j] / total


@kernel(inline="always")
def correct(settings: np.ndarray, work: np.ndarray, z: np.ndarray, R: np.ndarray) -> tuple[float, int]:
    """Correction of the prediction block by position z into the state block: each mode's update,
    μ_j ∝ c̄_j N(ν_j; 0, Λ_j) (normalised from the largest log weight), output moment matched.
    Returns (NIS of the predicted mixture, −2), or, leaving the state as it was, (nan, −1) when the
    mixture's Λ is not positive definite, (nan, j) when mode j's is not."""
    n, D, entry_var, _, dims, _, _, _ = settings_views(settings)
    mu, X, PP, x, P = block_views(work, n, D, STATE)
    cbar, Xp, PPp, x_bar, P_bar = block_views(work, n, D, PREDICTION)
    _, v, _, _, _, _, Xn, _, _, PPn = scratch_views(work, n, D)
    nis, _, ok = innovation_nis(x_bar, P_bar, z, R)
    if not ok:
        return math.nan, -1
    failed = _correct_modes_into(cbar, Xp, PPp, dims, entry_var, z, R, Xn, PPn, v)
    if failed >= 0:
        return math.nan, failed
    _normalised_exp_into(v, mu)
    for j in range(n):
        for a in range(D):
            X[j, a] = Xn[j, a]
            for b in range(D):
                PP[j, a, b] = PPn[j, a, b]
    mixture_into(mu, X, PP, 4, x, P)
    return nis, -2


@kernel(inline="always")
def screen(settings: np.ndarray, work: np.ndarray, dt: float, z: np.ndarray, C: np.ndarray, R: np.ndarray,
           bias: np.ndarray, bias_cov: np.ndarray, gate: float) -> tuple[float, float, int]:
    """Innovation screening of a radar measurement and the correction when it passes: zc = z − C ς̂,
    Rc = R + C P_ς Cᵀ (written into the scratch, :func:`scratch_views`), the prediction by ``dt`` into
    the prediction block (:func:`advance`; a nan ``dt``: the block already holds the prediction),
    d² = (zc − p̄)ᵀ(P̄_pp + Rc)⁻¹(zc − p̄) against the predicted mixture (the core's screening equations)
    and, if d² ≤ ``gate``, :func:`correct` by (zc, Rc). Returns (d², NIS, code): code −4 when d² is
    outside the gate, −3 when (zc, Rc) is not a valid measurement (the state untouched in both), else
    :func:`correct`'s."""
    n, D = int(settings[0, 0]), int(settings[0, 1])
    _, _, zc, Rc, _, _, _, _, _, _ = scratch_views(work, n, D)
    bias_correct_into(z, C, R, bias, bias_cov, zc, Rc)
    if not math.isnan(dt):
        advance(settings, work, dt)
    _, _, _, x_bar, P_bar = block_views(work, n, D, PREDICTION)
    d2 = position_d2(zc, Rc, x_bar, P_bar)
    if not d2 <= gate:
        return d2, math.nan, -4
    if measurement_ok(0.0, zc, Rc) != 0:
        return d2, math.nan, -3
    nis, code = correct(settings, work, zc, Rc)
    return d2, nis, code
