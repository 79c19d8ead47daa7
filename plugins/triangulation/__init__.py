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

from radartracker.api import lazy_exports

# imported when first used: `radartracker triangulate` registers its command without numpy or pyproj
_EXPORTS = {
    "._lsq": ("GeometryError",),
    ".dynamic": ("PolynomialBasis", "TrackFix", "track"),
    ".feed": ("fix_measurement", "plane_measurement"),
    ".frame": ("TriangulationFrame",),
    ".sensors": ("Bearing", "DirectionFinder"),
    ".static": ("Fix", "locate"),
    ".weights": ("StationWeights", "read_weights"),
}
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)

__all__ = sorted(name for names in _EXPORTS.values() for name in names)
