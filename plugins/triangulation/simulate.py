"""Simulated bearings for tests and Monte Carlo studies.

True bearings are computed from geodetic target positions with
:meth:`radartracker.geometry.RadarFrame.polar` (pyproj, geodetic → station ENU), a path that
does not use the triangulation frame's rotations, so simulations also check the model.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from pyproj import Geod

from radartracker.api import RadarFrame, SystemPlane

from .frame import TriangulationFrame
from .sensors import Bearing


def sites_around(lat: float, lon: float, distance_m: float, azimuths_deg: Sequence[float]
                 ) -> list[tuple[float, float]]:
    """WGS84 (lat, lon) of points ``distance_m`` away from (lat, lon) along the geodesic azimuths."""
    n = len(azimuths_deg)
    lons, lats, _ = Geod(ellps="WGS84").fwd([lon] * n, [lat] * n, list(azimuths_deg), [distance_m] * n)
    return list(zip(map(float, lats), map(float, lons)))


def schedule(frame: TriangulationFrame) -> tuple[np.ndarray, np.ndarray]:
    """(station ids, times) of all stations' own time grids, sorted by time."""
    ids, times = [], []
    for s in frame.stations.values():
        if s.times is None:
            raise ValueError(f"times: station {s.id!r} has no time grid")
        ids += [s.id] * len(s.times)
        times += list(s.times)
    order = np.argsort(times, kind="stable")
    return np.asarray(ids)[order], np.asarray(times, float)[order]


def true_bearings(frame: TriangulationFrame, stations: Sequence[str], positions) -> np.ndarray:
    """Exact (α, β) (N, 2) of frame ``positions`` (N, 3) seen from ``stations[n]``."""
    positions = np.atleast_2d(np.asarray(positions, float))
    lat, lon, h = frame.geodetic(positions)
    plane = SystemPlane(*frame.reference[:2])
    stations = np.asarray(stations)
    out = np.empty((len(stations), 2))
    for sid in np.unique(stations):
        s = frame.stations[sid]
        idx = np.flatnonzero(stations == sid)
        _, az, el = RadarFrame(s.lat, s.lon, s.height_m, plane).polar(lat[idx], lon[idx], h[idx])
        out[idx, 0], out[idx, 1] = az, el
    return out


def noisy_bearings(frame: TriangulationFrame, stations: Sequence[str], times, truth: np.ndarray,
                   rng: np.random.Generator, target: str = "1") -> list[Bearing]:
    """Bearings with N(0, σ²) errors added to ``truth`` (N, 2) from :func:`true_bearings`."""
    sigma = np.array([frame.sigmas(s) for s in stations])
    g = truth + sigma * rng.standard_normal(truth.shape)
    az = np.mod(g[:, 0], 2 * np.pi)
    az[az >= 2 * np.pi] = 0.0  # np.mod(−tiny, 2π) rounds to 2π
    el = np.clip(g[:, 1], -np.pi / 2, np.pi / 2)
    return [Bearing(float(t), str(s), float(a), float(e), target)
            for t, s, a, e in zip(times, stations, az, el)]
