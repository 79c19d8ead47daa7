"""Compiled numerics of the fit (:mod:`.fit`, :mod:`.shooting`): the closed-form flow over a whole
control track, the Hooke–Jeeves objective in one call, and the residuals and Jacobians of single and
multiple shooting. Kernels (``radartracker.api.kernel``) allocate nothing: they write into arrays
their caller owns and return numbers.

Model (DESIGN §7, x east, y north, φ clockwise from north): ẋ = v sin φ, ẏ = v cos φ, φ̇ = u/v, v̇ = w.
With constant (u, w) over τ (:func:`flow`, the formulas of ``radartracker.api.propagate``)::

    w = 0, u = 0:  x = x₀ + v₀τ sin φ₀,  y = y₀ + v₀τ cos φ₀
    w = 0, u ≠ 0:  φ = φ₀ + uτ/v₀,  x = x₀ − r (cos φ − cos φ₀),  y = y₀ + r (sin φ − sin φ₀),  r = v₀²/u
    w ≠ 0:         v = v₀ + wτ,  a = u/w,  ψ = φ₀ + a ln(v/v₀),
                   x = x₀ + [v²(2 sin ψ − a cos ψ) − v₀²(2 sin φ₀ − a cos φ₀)] / (w (4 + a²)),
                   y = y₀ + [v²(2 cos ψ + a sin ψ) − v₀²(2 cos φ₀ + a sin φ₀)] / (w (4 + a²))

Settings of one objective, the float array ``cs`` (:data:`CS_FIELDS`): the window [t0, t_end], the
bounds and the seed's initial steps (the penalty's units), v_min, the penalty factor, the jump prior's
sd, the loss (0 Gauss, 1 Huber, 2 Cauchy), its scale c and the constant ½ Σ log det(2πR).
A work vector ``wk`` of 4K + 5 holds the projected (x₀, y₀, φ₀, v₀), u (K), w (K), the segment
bounds (K + 1) and the speed-clamped w (K) (:func:`views`).
"""

from __future__ import annotations

import math

import numpy as np

from radartracker.api import kernel

CS_FIELDS = ("t0", "t_end", "max_u", "max_w", "dt_min", "du1", "dw1", "dt1", "dv1", "v_min", "penalty", "jump_sd",
             "loss", "loss_c", "const")
T0, T_END, MAX_U, MAX_W, DT_MIN, DU1, DW1, DT1, DV1, V_MIN, PENALTY, JUMP_SD, LOSS, LOSS_C, CONST = range(15)
# below these |w|, |u| (m/s²) the w = 0 and straight-line forms are used, as in radartracker.api.propagate
_W_EPS, _U_EPS = 1e-7, 1e-9
_H_V, _H_U, _H_W = 1e-4, 1e-5, 1e-5  # central-difference steps for v₀, u, w
# continuity scale (x, y m; φ rad; v m/s) of multiple shooting: gaps this size cost one σ of one plot
SIGMA_CONTINUITY = (1.0, 1.0, 1e-4, 1e-2)


@kernel(inline="always")
def flow(x0: float, y0: float, phi0: float, v0: float, u: float, w: float, tau: float):
    """(x, y, φ, v) after τ s of constant (u, w) from (x₀, y₀, φ₀, v₀) (module docstring)."""
    if abs(w) < _W_EPS:
        if abs(u) < _U_EPS:
            return x0 + v0 * tau * math.sin(phi0), y0 + v0 * tau * math.cos(phi0), phi0, v0
        phi = phi0 + u / v0 * tau
        r = v0 * v0 / u
        return (x0 - r * (math.cos(phi) - math.cos(phi0)), y0 + r * (math.sin(phi) - math.sin(phi0)), phi, v0)
    v = v0 + w * tau
    a = u / w
    psi = phi0 + a * math.log(v / v0)
    k = 1.0 / (w * (4.0 + a * a))
    s, c, s0, c0 = math.sin(psi), math.cos(psi), math.sin(phi0), math.cos(phi0)
    x = x0 + k * (v * v * (2.0 * s - a * c) - v0 * v0 * (2.0 * s0 - a * c0))
    y = y0 + k * (v * v * (2.0 * c + a * s) - v0 * v0 * (2.0 * c0 + a * s0))
    return x, y, psi, v


@kernel(inline="always")
def flow_d(x0: float, y0: float, phi0: float, v0: float, u: float, w: float, tau: float, D: np.ndarray):
    """(x, y, φ, v) after τ, and D (4×6) = ∂(x, y, φ, v)/∂(x₀, y₀, φ₀, v₀, u, w) written into ``D``.

    ∂/∂x₀, ∂/∂y₀ are unit vectors; ∂/∂φ₀ = (y − y₀, −(x − x₀), 1, 0) exactly (a change of the initial
    heading rotates the whole displacement); v₀, u, w by central differences of :func:`flow`.
    """
    x, y, phi, v = flow(x0, y0, phi0, v0, u, w, tau)
    for i in range(4):
        for j in range(6):
            D[i, j] = 0.0
    D[0, 0] = D[1, 1] = D[2, 2] = 1.0
    D[0, 2], D[1, 2] = y - y0, -(x - x0)
    a = flow(x0, y0, phi0, v0 + _H_V, u, w, tau)
    b = flow(x0, y0, phi0, v0 - _H_V, u, w, tau)
    for i in range(4):
        D[i, 3] = (a[i] - b[i]) / (2.0 * _H_V)
    a = flow(x0, y0, phi0, v0, u + _H_U, w, tau)
    b = flow(x0, y0, phi0, v0, u - _H_U, w, tau)
    for i in range(4):
        D[i, 4] = (a[i] - b[i]) / (2.0 * _H_U)
    a = flow(x0, y0, phi0, v0, u, w + _H_W, tau)
    b = flow(x0, y0, phi0, v0, u, w - _H_W, tau)
    for i in range(4):
        D[i, 5] = (a[i] - b[i]) / (2.0 * _H_W)
    return x, y, phi, v


def views(wk: np.ndarray, K: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(initial state, u, w, bounds, speed-clamped w) views of a work vector of 4K + 5."""
    return wk[:4], wk[4:4 + K], wk[4 + K:4 + 2 * K], wk[4 + 2 * K:5 + 3 * K], wk[5 + 3 * K:5 + 4 * K]


@kernel
def project(theta: np.ndarray, off: int, K: int, init_in: np.ndarray, lower: np.ndarray, upper: np.ndarray,
            cs: np.ndarray, wk: np.ndarray) -> float:
    """θ's controls theta[off:] = (u, w, interior switch times) and ``init_in`` projected onto the
    constraints into ``wk``; returns the violation Σ|u − ū|/du₁ + Σ|w − w̄|/dw₁ + Σ|t − t̄|/dt₁
    (+ (v_min − v₀)/dv₁ when v₀ < v_min). Switch times: clipped to [lower, upper], then pushed
    forward and back so consecutive ones are ≥ dt_min apart."""
    viol = 0.0
    for k in range(K):
        uk, wk_ = theta[off + k], theta[off + K + k]
        up, wp = min(max(uk, -cs[MAX_U]), cs[MAX_U]), min(max(wk_, -cs[MAX_W]), cs[MAX_W])
        viol += abs(uk - up) / cs[DU1] + abs(wk_ - wp) / cs[DW1]
        wk[4 + k], wk[4 + K + k] = up, wp
    b = 4 + 2 * K  # bounds[0] = t0, bounds[j + 1] = projected switch j, bounds[K] = t_end
    wk[b], wk[b + K] = cs[T0], cs[T_END]
    for j in range(K - 1):
        wk[b + 1 + j] = min(max(theta[off + 2 * K + j], lower[j]), upper[j])
    for j in range(1, K - 1):
        wk[b + 1 + j] = max(wk[b + 1 + j], wk[b + j] + cs[DT_MIN])
    for j in range(K - 3, -1, -1):
        wk[b + 1 + j] = min(wk[b + 1 + j], wk[b + 2 + j] - cs[DT_MIN])
    for j in range(K - 1):
        viol += abs(theta[off + 2 * K + j] - wk[b + 1 + j]) / cs[DT1]
    for i in range(4):
        wk[i] = init_in[i]
    if wk[3] < cs[V_MIN]:
        viol += (cs[V_MIN] - wk[3]) / cs[DV1]
        wk[3] = cs[V_MIN]
    return viol


@kernel
def positions(K: int, times: np.ndarray, cs: np.ndarray, wk: np.ndarray, p: np.ndarray) -> float:
    """Positions p (n, 2) at the plot times of the projected track in ``wk`` (plots with
    t < bounds[k + 1] belong to segment k, the rest to the last); each segment's w is raised to
    (v_min − v_k)/duration where the speed would fall below v_min (into ``wk``'s clamped w).
    Returns that speed violation in units of dw₁."""
    b, e = 4 + 2 * K, 5 + 3 * K
    x, y, phi, v = wk[0], wk[1], wk[2], wk[3]
    i, n, viol = 0, len(times), 0.0
    for k in range(K):
        t_k, dur, uk = wk[b + k], wk[b + k + 1] - wk[b + k], wk[4 + k]
        wk_ = wk[4 + K + k]
        floor = (cs[V_MIN] - v) / dur
        if wk_ < floor:
            viol += (floor - wk_) / cs[DW1]
            wk_ = floor
        wk[e + k] = wk_
        while i < n and (k == K - 1 or times[i] < wk[b + k + 1]):
            p[i, 0], p[i, 1], _, _ = flow(x, y, phi, v, uk, wk_, times[i] - t_k)
            i += 1
        x, y, phi, v = flow(x, y, phi, v, uk, wk_, dur)
    return viol


@kernel(inline="always")
def whitened(Linv: np.ndarray, z: np.ndarray, p: np.ndarray, i: int):
    """L_i⁻¹ (z_i − p_i) of plot i."""
    dx, dy = z[i, 0] - p[i, 0], z[i, 1] - p[i, 1]
    return Linv[i, 0, 0] * dx + Linv[i, 0, 1] * dy, Linv[i, 1, 0] * dx + Linv[i, 1, 1] * dy


@kernel
def prior_half_square(K: int, cs: np.ndarray, wk: np.ndarray) -> float:
    """½ Σ_k ((u_k − u_{k−1})² + (w_k − w_{k−1})²) / jump_sd² of the projected controls (0 when off)."""
    if cs[JUMP_SD] == 0.0:
        return 0.0
    s = 0.0
    for k in range(1, K):
        s += (wk[4 + k] - wk[3 + k]) ** 2 + (wk[4 + K + k] - wk[3 + K + k]) ** 2
    return 0.5 * s / cs[JUMP_SD] ** 2


@kernel
def objective(theta: np.ndarray, off: int, K: int, init_in: np.ndarray, lower: np.ndarray, upper: np.ndarray,
              cs: np.ndarray, times: np.ndarray, z: np.ndarray, Linv: np.ndarray, wk: np.ndarray,
              p: np.ndarray) -> float:
    """f(θ) = Σ_i ρ(d_i) + ½ Σ log det(2πR_i) + ½ Σ (Δu² + Δw²)/jump_sd² + penalty · violation, with
    d_i² = ‖L_i⁻¹(z_i − p_i)‖² and ρ(d) = d²/2 (Gauss), Huber (d²/2 for d ≤ c, c d − c²/2 beyond) or
    Cauchy ((c²/2) ln(1 + d²/c²)) — the Hooke–Jeeves objective of :class:`~.fit.ControlObjective` in one call."""
    viol = project(theta, off, K, init_in, lower, upper, cs, wk)
    viol += positions(K, times, cs, wk, p)
    c, loss, f = cs[LOSS_C], cs[LOSS], 0.0
    for i in range(len(times)):
        r0, r1 = whitened(Linv, z, p, i)
        d2 = r0 * r0 + r1 * r1
        if loss == 0.0:
            f += 0.5 * d2
        elif loss == 1.0:
            d = math.sqrt(d2)
            f += 0.5 * d2 if d <= c else c * d - 0.5 * c * c
        else:
            f += 0.5 * c * c * math.log1p(d2 / (c * c))
    return f + cs[CONST] + prior_half_square(K, cs, wk) + cs[PENALTY] * viol


@kernel
def ss_residuals(theta: np.ndarray, off: int, K: int, init_in: np.ndarray, lower: np.ndarray, upper: np.ndarray,
                 cs: np.ndarray, times: np.ndarray, z: np.ndarray, Linv: np.ndarray, wk: np.ndarray, p: np.ndarray,
                 r: np.ndarray) -> float:
    """Single-shooting residuals into r: L_i⁻¹(z_i − p_i) (2n), then (Δu, Δw)/jump_sd (2(K − 1), when the
    prior is on), then √(2 · penalty · violation); half their sum of squares is the Gaussian f(θ)
    (without its constant). Returns the violation."""
    viol = project(theta, off, K, init_in, lower, upper, cs, wk)
    viol += positions(K, times, cs, wk, p)
    n = len(times)
    for i in range(n):
        r[2 * i], r[2 * i + 1] = whitened(Linv, z, p, i)
    m = 2 * n
    if cs[JUMP_SD] > 0.0 and K > 1:
        for k in range(1, K):
            r[m + k - 1] = (wk[4 + k] - wk[3 + k]) / cs[JUMP_SD]
            r[m + K - 2 + k] = (wk[4 + K + k] - wk[3 + K + k]) / cs[JUMP_SD]
        m += 2 * (K - 1)
    r[m] = math.sqrt(2.0 * cs[PENALTY] * viol)
    return viol


@kernel
def ss_jacobian(theta: np.ndarray, off: int, K: int, init_in: np.ndarray, lower: np.ndarray, upper: np.ndarray,
                cs: np.ndarray, times: np.ndarray, Linv: np.ndarray, wk: np.ndarray, p: np.ndarray, M: np.ndarray,
                D: np.ndarray, J: np.ndarray) -> None:
    """The plot rows of ∂r/∂θ (2n × P) of :func:`ss_residuals` into J, by the chain rule along the segments.

    With S_k the state at the start of segment k and M = dS_k/dθ (4 × P; the identity on the initial
    state when it is free, ``off`` = 4): a plot at τ = t_i − t_k has dp_i/dθ = D_{:2,:4} M + D_{:2,4} e_{u_k}
    + D_{:2,5} e_{w_k} (D = :func:`flow_d` at τ) and row pair −L_i⁻¹ dp_i/dθ; then
    M ← D_{:,:4} M + D_{:,4} e_{u_k}ᵀ + D_{:,5} e_{w_k}ᵀ with D at the segment's duration. A switch time
    t_k enters as the jump of the right-hand side f(S_k, u_{k−1}, w_{k−1}) − f(S_k, u_k, w_k) =
    (0, 0, (u_{k−1} − u_k)/v, w_{k−1} − w_k) added to M's column of t_k.
    """
    project(theta, off, K, init_in, lower, upper, cs, wk)
    positions(K, times, cs, wk, p)
    P, b, e = J.shape[1], 4 + 2 * K, 5 + 3 * K
    for a in range(4):
        for j in range(P):
            M[a, j] = 1.0 if (off == 4 and a == j) else 0.0
    x, y, phi, v = wk[0], wk[1], wk[2], wk[3]
    i, n = 0, len(times)
    for k in range(K):
        uk, wk_, t_k, dur = wk[4 + k], wk[e + k], wk[b + k], wk[b + k + 1] - wk[b + k]
        cu, cw = off + k, off + K + k
        if k > 0:
            M[2, off + 2 * K + k - 1] += (wk[3 + k] - uk) / v
            M[3, off + 2 * K + k - 1] += wk[e + k - 1] - wk_
        while i < n and (k == K - 1 or times[i] < wk[b + k + 1]):
            flow_d(x, y, phi, v, uk, wk_, times[i] - t_k, D)
            for j in range(P):
                d0 = D[0, 0] * M[0, j] + D[0, 1] * M[1, j] + D[0, 2] * M[2, j] + D[0, 3] * M[3, j]
                d1 = D[1, 0] * M[0, j] + D[1, 1] * M[1, j] + D[1, 2] * M[2, j] + D[1, 3] * M[3, j]
                if j == cu:
                    d0, d1 = d0 + D[0, 4], d1 + D[1, 4]
                elif j == cw:
                    d0, d1 = d0 + D[0, 5], d1 + D[1, 5]
                J[2 * i, j] = -(Linv[i, 0, 0] * d0 + Linv[i, 0, 1] * d1)
                J[2 * i + 1, j] = -(Linv[i, 1, 0] * d0 + Linv[i, 1, 1] * d1)
            i += 1
        x, y, phi, v = flow_d(x, y, phi, v, uk, wk_, dur, D)
        for j in range(P):
            m0, m1, m2, m3 = M[0, j], M[1, j], M[2, j], M[3, j]
            for a in range(4):
                M[a, j] = D[a, 0] * m0 + D[a, 1] * m1 + D[a, 2] * m2 + D[a, 3] * m3
        for a in range(4):
            M[a, cu] += D[a, 4]
            M[a, cw] += D[a, 5]


@kernel(inline="always")
def ms_segment(phi: np.ndarray, K: int, k: int, cs: np.ndarray, wk: np.ndarray):
    """Segment k's free start S_k (speed raised to v_min), u_k, its w raised so the speed stays
    ≥ v_min, its start and end times (multiple shooting)."""
    b = 4 + 2 * K
    v = max(phi[4 * k + 3], cs[V_MIN])
    dur = wk[b + k + 1] - wk[b + k]
    w = max(wk[4 + K + k], (cs[V_MIN] - v) / dur)
    return phi[4 * k], phi[4 * k + 1], phi[4 * k + 2], v, wk[4 + k], w, wk[b + k], wk[b + k + 1]


@kernel
def ms_residuals(phi: np.ndarray, K: int, lower: np.ndarray, upper: np.ndarray, cs: np.ndarray,
                 times: np.ndarray, z: np.ndarray, Linv: np.ndarray, wk: np.ndarray, p: np.ndarray,
                 r: np.ndarray) -> None:
    """Multiple-shooting residuals into r (2n + 4(K − 1)): L_i⁻¹(z_i − p(Flow_k(t_i − t_k, S_k))) per plot of
    segment k, then (Flow_k(t_{k+1} − t_k, S_k) − S_{k+1}) / σ_c per switch (:data:`SIGMA_CONTINUITY`).
    φ = [S_0 … S_{K−1}, u, w, interior switch times]; the controls and times projected as in single shooting."""
    project(phi, 4 * K, K, phi, lower, upper, cs, wk)
    i, n = 0, len(times)
    for k in range(K):
        x, y, ph, v, uk, wk_, t_k, t_next = ms_segment(phi, K, k, cs, wk)
        dur = t_next - t_k
        while i < n and (k == K - 1 or times[i] < t_next):
            p[i, 0], p[i, 1], _, _ = flow(x, y, ph, v, uk, wk_, times[i] - t_k)
            r[2 * i], r[2 * i + 1] = whitened(Linv, z, p, i)
            i += 1
        if k + 1 < K:
            end = flow(x, y, ph, v, uk, wk_, dur)
            for a in range(4):
                r[2 * n + 4 * k + a] = (end[a] - phi[4 * (k + 1) + a]) / SIGMA_CONTINUITY[a]


@kernel
def ms_jacobian(phi: np.ndarray, K: int, lower: np.ndarray, upper: np.ndarray, cs: np.ndarray, times: np.ndarray,
                Linv: np.ndarray, wk: np.ndarray, D: np.ndarray, J: np.ndarray) -> None:
    """∂r/∂φ of :func:`ms_residuals` into J (block-sparse: a plot row depends on its segment's S_k, u_k, w_k
    and start time t_k — moving t_k shortens τ: ∂r_i/∂t_k = L_i⁻¹ ṗ_i —, a continuity row on segment k's
    parameters (D at the duration), −I/σ_c on S_{k+1}, and f(S_end)/σ_c on t_{k+1}, −f(S_end)/σ_c on t_k)."""
    project(phi, 4 * K, K, phi, lower, upper, cs, wk)
    for a in range(J.shape[0]):
        for j in range(J.shape[1]):
            J[a, j] = 0.0
    i, n = 0, len(times)
    for k in range(K):
        x, y, ph, v, uk, wk_, t_k, t_next = ms_segment(phi, K, k, cs, wk)
        dur = t_next - t_k
        c0, tk, tn = 4 * k, 6 * K + k - 1, 6 * K + k
        while i < n and (k == K - 1 or times[i] < t_next):
            _, _, pp, vv = flow_d(x, y, ph, v, uk, wk_, times[i] - t_k, D)
            for j in range(6):
                col = c0 + j if j < 4 else (4 * K + k if j == 4 else 5 * K + k)
                J[2 * i, col] = -(Linv[i, 0, 0] * D[0, j] + Linv[i, 0, 1] * D[1, j])
                J[2 * i + 1, col] = -(Linv[i, 1, 0] * D[0, j] + Linv[i, 1, 1] * D[1, j])
            if k > 0:
                d0, d1 = vv * math.sin(pp), vv * math.cos(pp)
                J[2 * i, tk] = Linv[i, 0, 0] * d0 + Linv[i, 0, 1] * d1
                J[2 * i + 1, tk] = Linv[i, 1, 0] * d0 + Linv[i, 1, 1] * d1
            i += 1
        if k + 1 < K:
            _, _, pe, ve = flow_d(x, y, ph, v, uk, wk_, dur, D)
            f = (ve * math.sin(pe), ve * math.cos(pe), uk / ve, wk_)
            for a in range(4):
                row, s = 2 * n + 4 * k + a, SIGMA_CONTINUITY[a]
                for j in range(6):
                    J[row, c0 + j if j < 4 else (4 * K + k if j == 4 else 5 * K + k)] = D[a, j] / s
                J[row, 4 * (k + 1) + a] = -1.0 / s
                J[row, tn] = f[a] / s
                if k > 0:
                    J[row, tk] = -f[a] / s
