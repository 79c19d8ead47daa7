"""The seed's kinematic model with piecewise-constant controls (seed 000 eq. 2.1, DESIGN §7).

In plane coordinates with heading φ clockwise from north::

    ẋ = v sin φ,   ẏ = v cos φ,   φ̇ = u / v,   v̇ = w

``u`` is the lateral (centripetal) acceleration and ``w`` the longitudinal one, both m/s². With
constant controls the motion integrates in closed form (no numerical integrator needed):

* w = 0, u = 0: straight line;
* w = 0, u ≠ 0: circular arc of radius v²/u;
* w ≠ 0: with a = u/w, ψ(v) = φ₀ + a ln(v/v₀) and v = v₀ + w τ,
  x = x₀ + [v²(2 sin ψ − a cos ψ) − v₀²(2 sin φ₀ − a cos φ₀)] / (w (4 + a²)),
  y = y₀ + [v²(2 cos ψ + a sin ψ) − v₀²(2 cos φ₀ + a sin φ₀)] / (w (4 + a²)).

The speed must stay positive within a segment (the model is singular at v = 0).
"""

from __future__ import annotations

import numpy as np

# Below this |w| (m/s²) the w = 0 formulas are used: their error w·τ²/2 stays under 5 cm for
# τ ≤ 1000 s, while the general formula would lose digits to cancellation.
_W_EPS = 1e-7
_U_EPS = 1e-9


def propagate(
    x0: float, y0: float, phi0: float, v0: float, u: float, w: float, tau: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """State (x, y, φ, v) after ``tau`` seconds (array, ≥ 0) of constant controls (u, w)."""
    tau = np.asarray(tau, dtype=float)
    v = v0 + w * tau
    if np.any(v <= 0.0):
        raise ValueError(f"speed reaches zero within the segment (v0={v0}, w={w})")
    if abs(w) < _W_EPS:
        v = np.full_like(tau, v0)
        if abs(u) < _U_EPS:
            phi = np.full_like(tau, phi0)
            return x0 + v0 * tau * np.sin(phi0), y0 + v0 * tau * np.cos(phi0), phi, v
        phi = phi0 + u / v0 * tau
        r = v0 * v0 / u
        return x0 - r * (np.cos(phi) - np.cos(phi0)), y0 + r * (np.sin(phi) - np.sin(phi0)), phi, v
    a = u / w
    psi = phi0 + a * np.log(v / v0)
    k = 1.0 / (w * (4.0 + a * a))
    x = x0 + k * (v * v * (2 * np.sin(psi) - a * np.cos(psi)) - v0 * v0 * (2 * np.sin(phi0) - a * np.cos(phi0)))
    y = y0 + k * (v * v * (2 * np.cos(psi) + a * np.sin(psi)) - v0 * v0 * (2 * np.cos(phi0) + a * np.sin(phi0)))
    return x, y, psi, v
