"""The estimation engine shared by the static and the dynamic case (seed 001 §2–3).

The target position at bearing n is linear in the parameters: r_n = Θ q_n, with Θ = [A B C]ᵀ
(3×K) and q_n = q(t_n) the basis (K = 1, q = 1 for a static target). Two steps:

1. **Start** — least-squares intersection of the lines of sight (linear in Θ). With d_n the unit
   line of sight of bearing n from station position p_n and P_n = I − d_n d_nᵀ the projector
   across it, minimise Σ w_n ‖P_n (Θ q_n − p_n)‖²; the normal equations are
   Σ w_n (P_n ⊗ q_n q_nᵀ) vec Θ = Σ w_n (P_n p_n) ⊗ q_n. First w_n = 1/σ̄_n², then once more with
   w_n = 1/(σ̄_n ρ_n)² using the ranges ρ_n of the first pass (the perpendicular miss of a line of
   sight grows as ρ σ).
2. **Refine** — nonlinear weighted LS (seed 001 eq. 3.1): min Σ_n Δγ_nᵀ W_n Δγ_n,
   Δγ_n = γ̃_n − h(r_n), by Levenberg–Marquardt (``scipy.optimize.least_squares``) on the
   residuals L_nᵀ Δγ_n (W_n = L_n L_nᵀ) with the analytic Jacobian J_n = H_n (I₃ ⊗ q_nᵀ).
   W_n = K_n⁻¹ is the Gaussian ML estimate (eq. 2.3) and its covariance the inverse Fisher
   information (JᵀK⁻¹J)⁻¹. Any other W (e.g. W = I, which needs no error model) is the seed's
   LSQ estimate; its covariance under the stations' stated noise K is the sandwich
   (JᵀWJ)⁻¹ JᵀWKWJ (JᵀWJ)⁻¹, which is never below the ML one (Gauss–Markov).

Geometry is refused (:class:`GeometryError`) when J̃ has no non-singular 3K×3K minor (seed 001
§3: numerical rank < 3K), or when the GDOP exceeds ``max_gdop``. Before any solver runs,
:func:`precheck` refuses what cannot have such a minor or cannot be computed: fewer than 3K/2
bearings (2N equations for 3K unknowns), every bearing from one site (sites within
:data:`SAME_SITE_M` count as one: the lines of sight meet only there), and non-finite sites,
lines of sight, weights or start residuals (weights are first scaled to a largest entry of 1,
which changes neither estimate nor covariance: both are invariant to a common factor of W).
GDOP = √(mean_n tr cov r_n) / (σ_rms ρ_rms): the RMS position error in units of the angular
noise times the range (≈ 1 for two orthogonal lines of sight, → ∞ as they become parallel).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
from scipy.optimize import least_squares

import radartracker.api as api

from .frame import TriangulationFrame, wrap_angle
from .sensors import Bearing

log = logging.getLogger("radartracker.triangulation")

RANK_RTOL = 1e-9  # singular values below this fraction of the largest count as zero
SAME_SITE_M = 1.0  # stations closer than this are one site: their lines of sight cross only at it


class GeometryError(api.GeometryError):
    """The bearings do not determine the target: degenerate or too poor geometry (GDOP given)."""

    def __init__(self, message: str, gdop: float) -> None:
        super().__init__(message)
        self.gdop = gdop


class BearingSet:
    """Bearings stacked as arrays, grouped per station for the vectorised model."""

    def __init__(self, frame: TriangulationFrame, bearings: Sequence[Bearing]) -> None:
        if not bearings:
            raise api.InputError("bearings: none given")
        unknown = sorted({b.station for b in bearings} - set(frame.stations))
        if unknown:
            raise api.InputError(f"station: unknown station id(s) {unknown}; known: {sorted(frame.stations)}")
        self.frame = frame
        self.time = np.array([b.time for b in bearings])
        self.station = np.array([b.station for b in bearings])
        self.gamma = np.array([[b.azimuth_rad, b.elevation_rad] for b in bearings])
        self.groups = [(s, np.flatnonzero(self.station == s)) for s in np.unique(self.station)]
        self.sigma = np.empty_like(self.gamma)
        self.site = np.empty((len(bearings), 3))
        self.los = np.empty((len(bearings), 3))
        for s, idx in self.groups:
            self.sigma[idx] = frame.sigmas(s)
            self.site[idx] = frame.position[s]
            self.los[idx] = frame.line_of_sight(s, self.gamma[idx, 0], self.gamma[idx, 1])

    def __len__(self) -> int:
        return len(self.time)

    def predict(self, r: np.ndarray) -> np.ndarray:
        out = np.empty((len(self), 2))
        for s, idx in self.groups:
            out[idx] = self.frame.bearings(s, r[idx])
        return out

    def jacobian(self, r: np.ndarray) -> np.ndarray:
        out = np.empty((len(self), 2, 3))
        for s, idx in self.groups:
            out[idx] = self.frame.jacobian(s, r[idx])
        return out

    def residual(self, r: np.ndarray) -> np.ndarray:
        """Residuals γ̃ − h(r) in radians, azimuth wrapped, shape (N, 2)."""
        d = self.gamma - self.predict(r)
        d[:, 0] = wrap_angle(d[:, 0])
        return d

    def ml_weights(self) -> np.ndarray:
        """W_n = K_n⁻¹ = diag(1/σ_az², 1/σ_el²), shape (N, 2, 2): the Gaussian ML weights."""
        W = np.zeros((len(self), 2, 2))
        W[:, 0, 0], W[:, 1, 1] = self.sigma[:, 0] ** -2, self.sigma[:, 1] ** -2
        return W


def root(W: np.ndarray) -> np.ndarray:
    """Lᵀ with W = L Lᵀ for each 2×2 block (symmetric square root; W positive semi-definite)."""
    lam, V = np.linalg.eigh(0.5 * (W + np.swapaxes(W, 1, 2)))
    if np.any(lam < -1e-12 * np.abs(lam).max(initial=1.0)):
        raise api.InputError("weights: every 2×2 weight block must be positive semi-definite")
    return np.sqrt(np.clip(lam, 0.0, None))[:, :, None] * np.swapaxes(V, 1, 2)


class Solution(NamedTuple):
    """Θ (3×K), its covariance (3K×3K, inverse Fisher), the start, GDOP and the fit χ²."""

    theta: np.ndarray
    cov: np.ndarray
    start: np.ndarray
    gdop: float
    chi2: float
    dof: int
    poor: bool


def design(Q: np.ndarray, H: np.ndarray) -> np.ndarray:
    """J_n = H_n (I₃ ⊗ q_nᵀ): (N, 2, 3K) from H (N, 2, 3) and the basis rows Q (N, K)."""
    N, K = Q.shape
    return (H[:, :, :, None] * Q[:, None, None, :]).reshape(N, 2, 3 * K)


def position_cov(Q: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """cov r_n = (I₃ ⊗ q_nᵀ) Σ (I₃ ⊗ q_n): (N, 3, 3)."""
    N, K = Q.shape
    C = cov.reshape(3, K, 3, K)
    return np.einsum("nk,ikjl,nl->nij", Q, C, Q)


def intersect(bs: BearingSet, Q: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Weighted LS intersection of the lines of sight; Θ (3×K). Refuses a singular system."""
    K = Q.shape[1]
    P = np.eye(3) - bs.los[:, :, None] * bs.los[:, None, :]
    M = np.einsum("n,nij,nk,nl->ikjl", w, P, Q, Q).reshape(3 * K, 3 * K)
    b = np.einsum("n,ni,nk->ik", w, np.einsum("nij,nj->ni", P, bs.site), Q).reshape(3 * K)
    lam, V = np.linalg.eigh(M)
    if lam[0] <= lam[-1] * RANK_RTOL**2:
        rank = int(np.sum(lam > lam[-1] * RANK_RTOL**2))
        raise GeometryError(
            f"degenerate geometry: the lines of sight do not intersect in a point (normal matrix of "
            f"rank {rank} < {3 * K}); the bearing Jacobian has no non-singular {3 * K}×{3 * K} minor, "
            "GDOP = inf (a single station, or stations and target collinear)", math.inf)
    return (V @ ((V.T @ b) / lam)).reshape(3, K)


def _degenerate(why: str, K: int) -> GeometryError:
    return GeometryError(f"degenerate geometry: {why}; the bearing Jacobian has no non-singular {3 * K}×{3 * K} "
                         "minor, GDOP = inf", math.inf)


def precheck(bs: BearingSet, Q: np.ndarray, W: np.ndarray) -> None:
    """Refuse, before any solver runs, what cannot give a fix (module docstring): too few bearings, one
    site, non-finite sites, lines of sight or weights."""
    N, K = Q.shape
    if 2 * N < 3 * K:
        raise _degenerate(f"{N} bearing(s) give {2 * N} equations for {3 * K} unknowns (at least "
                          f"{math.ceil(1.5 * K)} bearings needed)", K)
    if not (np.isfinite(bs.site).all() and np.isfinite(bs.los).all() and np.isfinite(Q).all()):
        raise _degenerate("a station site, line of sight or time is not finite", K)
    if not np.isfinite(W).all():
        raise _degenerate("the weights are not finite (a σ too small or a weight too large for a double)", K)
    if np.linalg.norm(bs.site - bs.site[0], axis=1).max() < SAME_SITE_M:
        stations = ", ".join(s for s, _ in bs.groups)
        raise _degenerate(f"every bearing comes from one site (station(s) {stations} within {SAME_SITE_M:g} m of "
                          "each other): the lines of sight meet only there (a single station)", K)


def solve(bs: BearingSet, Q: np.ndarray, *, warn_gdop: float, max_gdop: float | None,
          weights: np.ndarray | None = None) -> Solution:
    """Start by intersection, refine by weighted LS, and report covariance, GDOP and χ².

    ``weights`` (N, 2, 2) are the blocks W_n; ``None`` is ML (W_n = K_n⁻¹). χ² is always the
    ML-weighted residual sum Σ Δγᵀ K⁻¹ Δγ, the statistic that is χ²(2N − 3K) when the noise model
    holds, whatever W was used to fit.
    """
    N, K = Q.shape
    ml = bs.ml_weights()
    W = ml if weights is None else np.asarray(weights, float)
    if weights is not None and np.isfinite(W).all() and np.abs(W).max() > 0:
        W = W / np.abs(W).max()  # only ratios matter; a common scale of 1e300 would overflow the residuals
    precheck(bs, Q, W)
    Lt = root(W)
    s2 = np.mean(bs.sigma**2, axis=1)
    theta = intersect(bs, Q, 1.0 / s2)
    rho = np.linalg.norm(Q @ theta.T - bs.site, axis=1)
    start = intersect(bs, Q, 1.0 / (s2 * np.maximum(rho, 1.0) ** 2))

    def fun(x):
        return np.einsum("nij,nj->ni", Lt, bs.residual(Q @ x.reshape(3, K).T)).ravel()

    if not np.isfinite(fun(start.ravel())).all():
        raise GeometryError("degenerate geometry: the residuals at the start point are not finite (the target "
                            "at a station, or weights out of the range of a double); GDOP = inf", math.inf)

    def jac(x):
        H = Lt @ bs.jacobian(Q @ x.reshape(3, K).T)
        return -design(Q, H).reshape(2 * N, 3 * K)

    fit = least_squares(fun, start.ravel(), jac=jac, method="lm", x_scale="jac",
                        xtol=1e-12, ftol=1e-12, gtol=1e-12)
    theta = fit.x.reshape(3, K)
    _, s, Vt = np.linalg.svd(fit.jac, full_matrices=False)
    if s.size < 3 * K or s[-1] <= s[0] * RANK_RTOL:
        rank = int(np.sum(s > s[0] * RANK_RTOL))
        raise GeometryError(
            f"degenerate geometry: the bearing Jacobian has rank {rank} < {3 * K}, so no non-singular "
            f"{3 * K}×{3 * K} minor; GDOP = inf (a single station, or stations and target collinear)",
            math.inf)
    cov = (Vt.T / s**2) @ Vt  # (JᵀWJ)⁻¹
    if weights is not None:  # sandwich with the stated noise K: Jᵀ (Lᵀ K L) J, J whitened by Lᵀ
        M = Lt @ np.linalg.inv(ml) @ np.swapaxes(Lt, 1, 2)
        Jn = fit.jac.reshape(N, 2, 3 * K)
        cov = cov @ np.einsum("nai,nab,nbj->ij", Jn, M, Jn) @ cov
    r = Q @ theta.T
    rho = np.linalg.norm(r - bs.site, axis=1)
    rms_err = math.sqrt(float(np.mean(np.trace(position_cov(Q, cov), axis1=1, axis2=2))))
    sigma_rms = math.sqrt(float(np.mean(bs.sigma**2)))
    gdop = rms_err / (sigma_rms * math.sqrt(float(np.mean(rho**2))))
    limit = max_gdop if max_gdop is not None else 0.5 / sigma_rms
    if gdop > limit:
        raise GeometryError(
            f"geometry too poor: GDOP = {gdop:.3g} > {limit:.3g} (RMS position error {rms_err:.4g} m at "
            f"RMS range {float(np.sqrt(np.mean(rho**2))):.4g} m); the lines of sight are nearly parallel",
            gdop)
    poor = gdop > warn_gdop
    if poor:
        log.warning("poor triangulation geometry: GDOP = %.3g > %.3g (RMS position error %.4g m)",
                    gdop, warn_gdop, rms_err)
    d = bs.residual(r)
    chi2 = float(np.einsum("ni,nij,nj->", d, ml, d))
    return Solution(theta, cov, start, gdop, chi2, 2 * N - 3 * K, bool(poor))
