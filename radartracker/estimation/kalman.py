"""Kalman-filter building blocks shared by the estimator plugins (DESIGN §5).

With K = P̄ Cᵀ the cross-covariance of state and measurement and Λ = C P̄ Cᵀ + R::

    ξ̂ = ξ̄ + K Λ⁻¹ ν,    P̂ = P̄ − K Λ⁻¹ Kᵀ

(the seed writes Λ where Λ⁻¹ is meant). Λ is factorised once by Cholesky; a Λ that is not
positive definite raises :class:`SingularInnovation` instead of producing NaN.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import cho_factor, cho_solve, LinAlgError

from radartracker.errors import NumericalError


class SingularInnovation(NumericalError):
    """The innovation covariance Λ is not positive definite (degenerate measurement or state)."""


def symmetrize(P: np.ndarray) -> np.ndarray:
    """(P + Pᵀ)/2: removes the round-off asymmetry of a covariance update."""
    return 0.5 * (P + P.T)


def gain(K: np.ndarray, S: np.ndarray) -> np.ndarray:
    """G = K Λ⁻¹ via a Cholesky factorisation of Λ (``S``); closed form for the usual 2×2."""
    if S.shape == (2, 2):  # LAPACK's call overhead dominates at this size
        a, b, d = S[0, 0], 0.5 * (S[0, 1] + S[1, 0]), S[1, 1]
        det = a * d - b * b
        if not (a > 0 and det > 0 and np.isfinite(det)):
            raise SingularInnovation(f"innovation covariance not positive definite: {S.tolist()}")
        return K @ (np.array([[d, -b], [-b, a]]) / det)
    try:
        c = cho_factor(S, lower=True, check_finite=True)
    except (LinAlgError, ValueError) as exc:
        raise SingularInnovation(f"innovation covariance not positive definite: {S.tolist()}") from exc
    return cho_solve(c, K.T).T


def nis(nu: np.ndarray, S: np.ndarray) -> float:
    """Normalised innovation squared νᵀ Λ⁻¹ ν."""
    return float(nu @ np.linalg.solve(S, nu))


def correct(x: np.ndarray, P: np.ndarray, K: np.ndarray, S: np.ndarray, nu: np.ndarray
            ) -> tuple[np.ndarray, np.ndarray]:
    """ξ̂ = ξ̄ + K Λ⁻¹ ν, P̂ = P̄ − K Λ⁻¹ Kᵀ (symmetrised)."""
    G = gain(K, S)
    return x + G @ nu, symmetrize(P - G @ K.T)
