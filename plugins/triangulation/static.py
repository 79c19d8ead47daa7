"""Static triangulation: the position of a stationary target from M ≥ 2 direction finders.

Seed 001 §2–3: the Gaussian ML estimate r* = argmin Σ_m Δγ_mᵀ K_m⁻¹ Δγ_m (eq. 2.3), equal to the
nonlinear weighted LS estimate with W = K⁻¹ (eq. 3.1–3.2), started from the least-squares
intersection of the lines of sight; cov r* = (Hᵀ K⁻¹ H)⁻¹, the inverse Fisher information. With
``weights`` the seed's LSQ estimate argmin Σ_m Δγ_mᵀ W_m Δγ_m (eq. 3.1) for a free W (e.g. W = I),
with the sandwich covariance under the stated noise. See
:mod:`radartracker_plugins.triangulation._lsq` for the algorithm and the refusal rules.
"""

from __future__ import annotations

from collections.abc import Sequence

import attrs
import numpy as np

from ._lsq import BearingSet, solve
from .frame import TriangulationFrame
from .sensors import Bearing
from .weights import StationWeights


@attrs.frozen
class Fix:
    """A triangulated position r* (frame ENU, m) with covariance (m²), at the bearings' mean time.

    ``gdop`` (see ``_lsq``), ``chi2`` the weighted residual sum with ``dof`` = 2N − 3 degrees of
    freedom (χ²-distributed when the noise model holds), ``poor_geometry`` when GDOP > warn_gdop,
    ``start`` the line-of-sight intersection the search began from; ``estimator`` "ml" or "lsq".
    """

    time: float
    position: np.ndarray
    cov: np.ndarray
    gdop: float
    chi2: float
    dof: int
    n_bearings: int
    stations: tuple[str, ...]
    poor_geometry: bool
    start: np.ndarray
    estimator: str = "ml"


def locate(frame: TriangulationFrame, bearings: Sequence[Bearing], *, warn_gdop: float = 10.0,
           max_gdop: float | None = None, weights: StationWeights | None = None) -> Fix:
    """ML position (or, with ``weights``, the LSQ position) of a stationary target from its
    bearings (any number per station).

    Raises :class:`GeometryError` (a ``ValueError`` carrying ``.gdop``) for degenerate geometry or
    GDOP above ``max_gdop`` (default 0.5/σ_rms: RMS error above half the range).
    """
    bs = BearingSet(frame, bearings)
    W = None if weights is None else weights.for_bearings(bs)
    sol = solve(bs, np.ones((len(bs), 1)), warn_gdop=warn_gdop, max_gdop=max_gdop, weights=W)
    return Fix(time=float(np.mean(bs.time)), position=sol.theta[:, 0], cov=sol.cov,
               gdop=sol.gdop, chi2=sol.chi2, dof=sol.dof, n_bearings=len(bs),
               stations=tuple(s for s, _ in bs.groups), poor_geometry=sol.poor,
               start=sol.start[:, 0], estimator="ml" if weights is None else "lsq")
