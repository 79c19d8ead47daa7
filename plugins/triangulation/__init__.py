"""Triangulation: target position and motion from bearings of passive direction finders (seed 001).

* :class:`DirectionFinder`, :class:`Bearing` — stations and their azimuth/elevation measurements.
* :class:`TriangulationFrame` — a common local ENU frame (pyproj) and the exact bearing model.
* :func:`locate` — static ML position (line-of-sight intersection start, then weighted NLS).
* :func:`track` — dynamic ML motion x(t) = Aᵀq(t), y(t) = Bᵀq(t), z(t) = Cᵀq(t).
* :class:`StationWeights` — a free weight matrix W for the seed's LSQ estimate (both cases).
* :mod:`.crlb` — Cramér–Rao bounds; :mod:`.feed` — fixes as tracker measurements;
  :mod:`.io` — file formats; :mod:`.simulate` — simulated bearings.

A library package, not an estimator or reconstructor plugin: it registers no entry point and is
used by ``radartracker triangulate`` and by scripts.
"""

from ._lsq import GeometryError
from .dynamic import PolynomialBasis, TrackFix, track
from .feed import fix_measurement, plane_measurement
from .frame import TriangulationFrame
from .sensors import Bearing, DirectionFinder
from .static import Fix, locate
from .weights import StationWeights, read_weights

__all__ = ["Bearing", "DirectionFinder", "Fix", "GeometryError", "PolynomialBasis", "TrackFix",
           "StationWeights", "TriangulationFrame", "fix_measurement", "locate", "plane_measurement", "read_weights",
           "track"]
