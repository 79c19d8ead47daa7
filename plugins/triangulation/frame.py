"""The common Cartesian frame of a triangulation system and the exact bearing model.

All stations and the target are expressed in one local east-north-up (ENU) frame at a reference
point (pyproj ``cart`` + ``topocentric``, WGS84). Station m's own ENU frame (true north, local
ellipsoidal horizon) differs from it by a rigid motion, obtained from pyproj as the pipeline
reference-ENU → ECEF → station-ENU::

    v_m(r) = R_m (r − p_m) = [e, n, u]ᵀ,   α_m = atan2(e, n) mod 2π,   β_m = atan2(u, √(e² + n²))

which is seed 001's line of sight e_m = r_m/‖r_m‖ with the azimuth counted clockwise from north
(ATC convention) instead of from the X axis. This is exact 3-D geometry — no flat earth — and a
test holds it to :meth:`radartracker.geometry.RadarFrame.polar` on geodetic points. The Jacobian
H_m = ∂(α, β)/∂r is analytic::

    ∂α/∂v = [n, −e, 0]/h²,   ∂β/∂v = [−e u, −n u, h²]/(h ρ²),   H_m = ∂(α, β)/∂v · R_m

with h = √(e² + n²), ρ = ‖v‖.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np
from pyproj import Transformer

from radartracker.api import RadarFrame, SystemPlane

from .sensors import DirectionFinder
from radartracker.api import InputError

_PROBE_M = 1000.0  # lever arm used to read the rotation R_m off the pyproj pipeline


def _topocentric(lat: float, lon: float, h: float) -> str:
    return f"+proj=topocentric +ellps=WGS84 +lat_0={lat!r} +lon_0={lon!r} +h_0={h!r}"


def _nearest_rotation(M: np.ndarray) -> np.ndarray:
    u, _, vt = np.linalg.svd(M)
    return u @ vt


def wrap_angle(a):
    """Angle wrapped to [−π, π)."""
    return np.mod(np.asarray(a, float) + math.pi, 2 * math.pi) - math.pi


class TriangulationFrame:
    """Local ENU frame at (lat0, lon0, h0) holding the stations' positions p_m and rotations R_m.

    Without a reference point, the stations' mean site is used (circular mean of longitudes).
    """

    def __init__(self, stations: Iterable[DirectionFinder], reference: tuple[float, ...] | None = None):
        self.stations: dict[str, DirectionFinder] = {}
        for s in stations:
            if s.id in self.stations:
                raise InputError(f"station id {s.id!r} appears twice")
            self.stations[s.id] = s
        if not self.stations:
            raise InputError("stations: at least one direction finder is needed")
        sites = list(self.stations.values())
        if reference is None:
            lon = np.radians([s.lon for s in sites])
            reference = (float(np.mean([s.lat for s in sites])),
                         float(np.degrees(np.arctan2(np.mean(np.sin(lon)), np.mean(np.cos(lon))))),
                         float(np.mean([s.height_m for s in sites])))
        lat0, lon0, *rest = reference
        self.reference = (float(lat0), float(lon0), float(rest[0]) if rest else 0.0)
        self._ref = RadarFrame(*self.reference, SystemPlane(self.reference[0], self.reference[1]))
        self.position: dict[str, np.ndarray] = {}
        self.rotation: dict[str, np.ndarray] = {}
        probe = np.vstack([np.zeros(3), _PROBE_M * np.eye(3)])
        for s in sites:
            to_station = Transformer.from_pipeline(
                f"+proj=pipeline +step +inv {_topocentric(*self.reference)} "
                f"+step {_topocentric(s.lat, s.lon, s.height_m)}")
            e, n, u = to_station.transform(probe[:, 0], probe[:, 1], probe[:, 2], direction="INVERSE")
            site_in_ref = np.array([e[0], n[0], u[0]])
            # row k of R_m is the station's k-th unit axis expressed in the reference frame
            axes = (np.stack([e[1:], n[1:], u[1:]], axis=1) - site_in_ref) / _PROBE_M
            self.position[s.id] = site_in_ref
            self.rotation[s.id] = _nearest_rotation(axes)

    # --- geodetic <-> frame -----------------------------------------------------------------------
    def enu(self, lat, lon, height) -> np.ndarray:
        """Frame coordinates (…, 3) of WGS84 points (degrees, metres above the ellipsoid)."""
        return self._ref.enu(lat, lon, height)

    def geodetic(self, enu) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """WGS84 (lat, lon, height) of frame points (…, 3)."""
        return self._ref.geodetic(np.asarray(enu, float))

    # --- bearing model -----------------------------------------------------------------------------
    def local(self, station: str, r) -> np.ndarray:
        """v_m = R_m (r − p_m): points (…, 3) in station m's own ENU frame."""
        return (np.asarray(r, float) - self.position[station]) @ self.rotation[station].T

    def bearings(self, station: str, r) -> np.ndarray:
        """Exact (α, β) (…, 2) of frame points ``r`` (…, 3) seen from ``station``."""
        v = self.local(station, r)
        az = np.mod(np.arctan2(v[..., 0], v[..., 1]), 2 * math.pi)
        el = np.arctan2(v[..., 2], np.hypot(v[..., 0], v[..., 1]))
        return np.stack([az, el], axis=-1)

    def jacobian(self, station: str, r) -> np.ndarray:
        """H_m = ∂(α, β)/∂r (…, 2, 3) at frame points ``r`` (…, 3)."""
        v = self.local(station, r)
        e, n, u = v[..., 0], v[..., 1], v[..., 2]
        h2 = e * e + n * n
        h = np.sqrt(h2)
        rho2 = h2 + u * u
        dv = np.empty(v.shape[:-1] + (2, 3))
        dv[..., 0, :] = np.stack([n, -e, np.zeros_like(e)], axis=-1) / h2[..., None]
        dv[..., 1, :] = np.stack([-e * u, -n * u, h2], axis=-1) / (h * rho2)[..., None]
        return dv @ self.rotation[station]

    def line_of_sight(self, station: str, azimuth, elevation) -> np.ndarray:
        """Unit direction (…, 3) in the frame of the bearing (α, β) from ``station``."""
        ce = np.cos(elevation)
        d = np.stack([ce * np.sin(azimuth), ce * np.cos(azimuth), np.sin(elevation)], axis=-1)
        return d @ self.rotation[station]

    def sigmas(self, station: str) -> np.ndarray:
        s = self.stations[station]
        return np.array([s.sigma_azimuth_rad, s.sigma_elevation_rad])

    def __repr__(self) -> str:
        return f"TriangulationFrame(reference={self.reference}, stations={list(self.stations)})"
