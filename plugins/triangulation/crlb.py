"""Cramér–Rao bounds of the static and dynamic triangulation problems (seed 001).

With independent Gaussian bearing errors K_n = diag(σ_α², σ_β²) the Fisher information of the
parameters is I = Σ_n J_nᵀ K_n⁻¹ J_n, J_n = ∂(α_n, β_n)/∂params at the *true* parameters, and any
unbiased estimator has cov ≥ I⁻¹. Static: params = r, J_n = H_n. Dynamic: params = vec Θ
(Θ = [A B C]ᵀ, 3×K), J_n = H_n (I₃ ⊗ q(t_n)ᵀ), and the bound on the position at t is
(I₃ ⊗ q(t)ᵀ) I⁻¹ (I₃ ⊗ q(t)). The RMSE bound of a position is √tr of its bound.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .frame import TriangulationFrame


def fisher_information(frame: TriangulationFrame, stations: Sequence[str], basis_rows: np.ndarray,
                       theta: np.ndarray) -> np.ndarray:
    """I = Σ_n J_nᵀ K_n⁻¹ J_n for bearings from ``stations[n]`` with basis rows q_n (N, K)."""
    Q = np.asarray(basis_rows, float)
    K = Q.shape[1]
    info = np.zeros((3 * K, 3 * K))
    for n, s in enumerate(stations):
        r = theta @ Q[n]
        J = np.kron(frame.jacobian(s, r), Q[n][None, :])  # H_n (I₃ ⊗ q_nᵀ), column order (i, k)
        info += J.T @ np.diag(1.0 / frame.sigmas(s) ** 2) @ J
    return info


def static_crlb(frame: TriangulationFrame, stations: Sequence[str], position) -> np.ndarray:
    """CRLB (3×3, m²) of a stationary target at frame ``position`` seen once per entry of ``stations``."""
    theta = np.asarray(position, float).reshape(3, 1)
    return np.linalg.inv(fisher_information(frame, stations, np.ones((len(stations), 1)), theta))


def dynamic_crlb(frame: TriangulationFrame, stations: Sequence[str], times, basis,
                 theta: np.ndarray) -> np.ndarray:
    """CRLB (3K×3K) of vec Θ for bearings from ``stations[n]`` at ``times[n]`` under ``basis``."""
    return np.linalg.inv(fisher_information(frame, stations, basis(np.asarray(times, float)), theta))


def position_bound(basis_rows: np.ndarray, bound: np.ndarray) -> np.ndarray:
    """Position bounds (N, 3, 3) (I₃ ⊗ q_nᵀ) B (I₃ ⊗ q_n) from a parameter bound B (3K×3K)."""
    Q = np.asarray(basis_rows, float)
    out = np.empty((len(Q), 3, 3))
    for n, q in enumerate(Q):
        G = np.kron(np.eye(3), q[None, :])
        out[n] = G @ bound @ G.T
    return out
