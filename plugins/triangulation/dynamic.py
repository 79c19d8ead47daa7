"""Dynamic triangulation: a target's motion x(t) = Aᵀq(t), y(t) = Bᵀq(t), z(t) = Cᵀq(t) (seed 001
eq. 1.1) from asynchronous bearings (each station on its own time grid t_mn, eq. 1.2).

Gaussian ML / weighted LS over D = [Aᵀ, Bᵀ, Cᵀ]ᵀ (eq. 2.4–2.6), started from the least-squares
intersection of all lines of sight, which is linear in D; cov D* = (Jᵀ K⁻¹ J)⁻¹ with
J_n = H_n (I₃ ⊗ q(t_n)ᵀ). With ``weights``, the LSQ estimate for a free W (eq. 3.1) with the
sandwich covariance (see ``_lsq``). The basis q is a polynomial of configurable order in normalised time
τ = (t − t_ref)/t_scale (for conditioning), or any callable ``basis(t) -> (N, K)`` array.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import attrs
import numpy as np

from radartracker.api import InputError

from ._lsq import BearingSet, position_cov, solve
from .frame import TriangulationFrame
from .sensors import Bearing
from .weights import StationWeights

Basis = Callable[[np.ndarray], np.ndarray]


@attrs.frozen
class PolynomialBasis:
    """q_k(t) = τᵏ, k = 0..order, τ = (t − t_ref)/t_scale (seed 001: the power basis)."""

    order: int = attrs.field(validator=attrs.validators.ge(0))
    t_ref: float = 0.0
    t_scale: float = attrs.field(default=1.0, validator=attrs.validators.gt(0.0))

    def __call__(self, t) -> np.ndarray:
        tau = (np.atleast_1d(np.asarray(t, float)) - self.t_ref) / self.t_scale
        return tau[:, None] ** np.arange(self.order + 1)


@attrs.frozen
class TrackFix:
    """The estimated motion: coefficients Θ = [A B C]ᵀ (3×K) in ``basis``, their covariance (3K×3K).

    ``gdop``, ``chi2`` (dof = 2N − 3K), ``poor_geometry`` and ``start`` as for a static fix.
    """

    basis: Basis
    theta: np.ndarray
    cov: np.ndarray
    t_min: float
    t_max: float
    gdop: float
    chi2: float
    dof: int
    n_bearings: int
    stations: tuple[str, ...]
    poor_geometry: bool
    start: np.ndarray
    estimator: str = "ml"

    def position(self, t) -> np.ndarray:
        """r(t) (N, 3) in the frame."""
        return self.basis(t) @ self.theta.T

    def covariance(self, t) -> np.ndarray:
        """cov r(t) (N, 3, 3)."""
        return position_cov(self.basis(t), self.cov)


def track(frame: TriangulationFrame, bearings: Sequence[Bearing], *, order: int = 1,
          basis: Basis | None = None, warn_gdop: float = 10.0,
          max_gdop: float | None = None, weights: StationWeights | None = None) -> TrackFix:
    """ML motion (or, with ``weights``, the LSQ motion) of one target from its asynchronous bearings.

    ``basis`` overrides the polynomial of degree ``order`` (then ``order`` is ignored). Raises
    :class:`GeometryError` like :func:`radartracker_plugins.triangulation.static.locate`.
    """
    bs = BearingSet(frame, bearings)
    t0, t1 = float(bs.time.min()), float(bs.time.max())
    if basis is None:
        basis = PolynomialBasis(order, 0.5 * (t0 + t1), max(0.5 * (t1 - t0), 1e-9))
    Q = np.asarray(basis(bs.time), float)
    if Q.ndim != 2 or Q.shape[0] != len(bs):
        raise InputError(f"basis: must return an (N, K) array for N times, got shape {Q.shape}")
    W = None if weights is None else weights.for_bearings(bs)
    sol = solve(bs, Q, warn_gdop=warn_gdop, max_gdop=max_gdop, weights=W)
    return TrackFix(basis=basis, theta=sol.theta, cov=sol.cov, t_min=t0, t_max=t1, gdop=sol.gdop,
                    chi2=sol.chi2, dof=sol.dof, n_bearings=len(bs),
                    stations=tuple(s for s, _ in bs.groups), poor_geometry=sol.poor,
                    start=sol.start, estimator="ml" if weights is None else "lsq")
