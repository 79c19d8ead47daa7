"""The plot's measurement model in the sparse coupled filter, linearised exactly as ``coupled`` does.

A plot z of aircraft i by radar j with the sensor model's components (radartracker.estimation.sensor)::

    z = p_i − τ_j v_i + B ς_j + v,   B = [c_ρ, c_θ, ρ c_ρ, −v]  (the columns radar j has),  v ~ N(0, R)

is linearised at the predicted velocity v̄ and time offset τ̄ (an extended Kalman step with the
second-order terms of the product τ v), as the dense filter does::

    H = [C_x at i, C_s at j],   C_x = [I, −τ̄ I],   C_s = B(v̄),
    ẑ = p̄ + B ς̄_j − P_vτ = H ξ̄ + d,   d = τ̄ v̄ − P_vτ,   R_eff = R + P_ττ P_vv + P_vτ P_vτᵀ

with the moments of the joint prior read from the conditional (1)–(2) of the package docstring::

    v̄ = m_v − G_v ς̂_K,   P_vτ = −G_v P_ς[K, τ],   P_vv = Σ_vv + G_v P_ς[K, K] G_vᵀ,   P_ττ = P_ς[τ, τ].

That step is exactly the linear update of z − d = H ξ + v', v' ~ N(0, R_eff): the information form adds
Hᵀ R_eff⁻¹ H and Hᵀ R_eff⁻¹ (z − d), and everything stays O(k²) per plot. Without a time offset C_x = [I, 0],
d = 0 and R_eff = R: the linear filter of the two offsets and the range gain.
"""

from __future__ import annotations

from radartracker.api import kernel


@kernel
def linearise(G, mx, Li, bh, Pb, idx, nK, rt, j, C, rho, z, Cx, Cs, Rs, ze):
    """C_x (2×4) and C_s (2×m_j) of the plot (C = ∂p/∂(ρ, θ), ``rho`` its slant range), R_eff into ``Rs``
    (which holds R) and ze = z − d (module docstring; G, mx: aircraft i's conditional, Li = L⁻¹ of
    Y_ii = L Lᵀ, idx[:nK] its bias positions). Returns m_j, 0 for an unbiased plot (j = −1)."""
    for a in range(2):
        ze[a, 0] = z[a]
        for b in range(4):
            Cx[a, b] = 1.0 if a == b else 0.0
    if j < 0:
        return 0
    o, w, g, tk = rt[j, 0], rt[j, 1], rt[j, 2], rt[j, 3]
    for a in range(2):
        Cs[a, 0] = C[a, 0]
        Cs[a, 1] = C[a, 1]
        if g >= 0:
            Cs[a, g] = rho * C[a, 0]
    if tk < 0:
        return w
    t = o + tk
    tau, ptt = bh[t], Pb[t, t]
    c0, c1 = _velocity_moments(G, mx, bh, Pb, idx, nK, t, Cs, tk)
    for a in range(2):
        Cx[a, 2 + a] = -tau
    ze[0, 0] -= -tau * Cs[0, tk] - c0  # d = τ̄ v̄ − P_vτ, v̄ = −(the column)
    ze[1, 0] -= -tau * Cs[1, tk] - c1
    for a in range(2):
        for b in range(a + 1):
            pvv = 0.0
            for r in range(4):
                pvv += Li[r, 2 + a] * Li[r, 2 + b]
            for k in range(nK):
                for l in range(nK):
                    pvv += G[2 + a, k] * Pb[idx[k], idx[l]] * G[2 + b, l]
            extra = ptt * pvv + (c0 if a == 0 else c1) * (c0 if b == 0 else c1)
            Rs[a, b] += extra
            if b != a:
                Rs[b, a] += extra
    return w


@kernel
def _velocity_moments(G, mx, bh, Pb, idx, nK, t, Cs, tk):
    """The time offset's column −v̄ = −(m_v − G_v ς̂_K) into Cs[:, tk]; returns P_vτ = −G_v P_ς[K, t]."""
    c0, c1 = 0.0, 0.0
    v0, v1 = mx[2, 0], mx[3, 0]
    for k in range(nK):
        v0 -= G[2, k] * bh[idx[k]]
        v1 -= G[3, k] * bh[idx[k]]
        c0 -= G[2, k] * Pb[idx[k], t]
        c1 -= G[3, k] * Pb[idx[k], t]
    Cs[0, tk] = -v0
    Cs[1, tk] = -v1
    return c0, c1


@kernel
def project(Cx, G, Li, nK, CG, M):
    """CG = C_x G (2×nK) and M = L⁻¹ C_xᵀ (4×2), so that C_x Σ C_xᵀ = MᵀM with Σ = Y_ii⁻¹ = L⁻ᵀ L⁻¹."""
    for a in range(2):
        for c in range(nK):
            acc = 0.0
            for r in range(4):
                acc += Cx[a, r] * G[r, c]
            CG[a, c] = acc
        for r in range(4):
            acc = 0.0
            for k in range(4):
                acc += Li[r, k] * Cx[a, k]
            M[r, a] = acc
