"""Geodesy with pyproj: the system plane and each radar's exact polar geometry (DESIGN §3–§4).

* :class:`SystemPlane` — conformal stereographic projection of WGS84 centred on the system
  reference point; x east, y north, metres.
* :class:`RadarFrame` — one radar's local east-north-up frame (pyproj ``cart`` + ``topocentric``).
  Slant range ρ and azimuth θ (clockwise from *true* north at the site) relate to an aircraft
  position through exact 3-D geometry using the aircraft altitude and the radar height; no
  flat-earth approximation. Altitudes are treated as heights above the ellipsoid.
* :meth:`RadarFrame.bias_jacobian` — C_s = D = ∂p/∂(ρ, θ) of the plane position (DESIGN §4,
  seed 000 eq. 1.11): the azimuth column is Ω(p − p_R) with Ω = [[0, 1], [−1, 0]] (x east,
  y north, θ clockwise), the range column is u·∂d/∂ρ where u is the plane line of sight and
  ∂d/∂ρ the change of plane distance with slant range at constant altitude (spherical earth,
  scaled by the local projection scale). Tests hold it to finite differences of the exact model.
* :func:`height_gradient` — g = ∂z/∂h of a plot's plane position at fixed (ρ, θ): how far, and along
  which line, a wrong conversion height moves a plot; also held to finite differences.
"""

from __future__ import annotations

import functools
import math

import numpy as np
from pyproj import CRS, Transformer

_EARTH_RADIUS_M = 6_371_008.8  # mean earth radius, only for ∂d/∂ρ and the elevation start value
_OMEGA = np.array([[0.0, 1.0], [-1.0, 0.0]])


@functools.lru_cache(maxsize=32)
def _stereographic(lat0: float, lon0: float) -> tuple[CRS, Transformer]:
    """The plane's CRS and WGS84 → plane transformer, made once per centre in a process: PROJ finds the
    operation by a query of its database, and a replay asks for the same plane twice (the manager's and the
    outputs'). pyproj's CRS and Transformer are safe to share between threads (pyproj ≥ 3.1)."""
    crs = CRS.from_proj4(f"+proj=stere +lat_0={lat0} +lon_0={lon0} +k_0=1 +x_0=0 +y_0=0 +ellps=WGS84 +units=m")
    return crs, Transformer.from_crs("EPSG:4326", crs, always_xy=True)


class SystemPlane:
    """Stereographic system plane centred on (lat0, lon0): x east, y north (metres)."""

    def __init__(self, lat0: float, lon0: float) -> None:
        self.lat0, self.lon0 = float(lat0), float(lon0)
        self.crs, self._fwd = _stereographic(self.lat0, self.lon0)

    def to_plane(self, lat, lon) -> tuple[np.ndarray, np.ndarray]:
        """Plane (x, y) in metres of WGS84 (lat, lon) in degrees."""
        x, y = self._fwd.transform(np.asarray(lon, float), np.asarray(lat, float), errcheck=True)
        return np.asarray(x), np.asarray(y)

    def to_plane_inplace(self, lon, lat) -> tuple:
        """Plane (x, y) of WGS84 ``lon``, ``lat`` (degrees), written over them where they are ``array('d')``
        or C-contiguous float64 arrays (pyproj's ``inplace``; else new arrays), and returned:
        :meth:`to_plane` without its copies."""
        return self._fwd.transform(lon, lat, errcheck=True, inplace=True)

    def to_geodetic(self, x, y) -> tuple[np.ndarray, np.ndarray]:
        """WGS84 (lat, lon) in degrees of plane (x, y) in metres."""
        lon, lat = self._fwd.transform(
            np.asarray(x, float), np.asarray(y, float), direction="INVERSE", errcheck=True
        )
        return np.asarray(lat), np.asarray(lon)

    def __repr__(self) -> str:
        return f"SystemPlane(lat0={self.lat0}, lon0={self.lon0})"


class RadarFrame:
    """Exact polar geometry of one radar site (lat, lon in degrees, height in metres)."""

    def __init__(self, lat: float, lon: float, height_m: float, plane: SystemPlane) -> None:
        self.lat, self.lon, self.height_m = float(lat), float(lon), float(height_m)
        self.plane = plane
        px, py = plane.to_plane(self.lat, self.lon)
        self.xy = np.array([float(px), float(py)])

    @functools.cached_property
    def _enu(self) -> Transformer:
        """WGS84 → the radar's east-north-up, made on first use (the TrackManager converts through
        :class:`~radartracker.tracking.prepared.PlaneConverter` and never uses it)."""
        return Transformer.from_pipeline(
            "+proj=pipeline +step +proj=unitconvert +xy_in=deg +xy_out=rad "
            "+step +proj=cart +ellps=WGS84 "
            f"+step +proj=topocentric +ellps=WGS84 +lat_0={self.lat} +lon_0={self.lon} +h_0={self.height_m}"
        )

    # --- geodetic <-> local east-north-up --------------------------------------------------------
    def enu(self, lat, lon, alt) -> np.ndarray:
        """East-north-up coordinates (…, 3) of WGS84 points relative to the radar."""
        e, n, u = self._enu.transform(
            np.asarray(lon, float), np.asarray(lat, float), np.asarray(alt, float), errcheck=True
        )
        return np.stack([e, n, u], axis=-1)

    def geodetic(self, enu: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """WGS84 (lat, lon, height) of local east-north-up points."""
        lon, lat, h = self._enu.transform(enu[..., 0], enu[..., 1], enu[..., 2], direction="INVERSE")
        return np.asarray(lat), np.asarray(lon), np.asarray(h)

    # --- exact polar model ---------------------------------------------------------------------
    def polar(self, lat, lon, alt) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Slant range ρ (m), azimuth θ ∈ [0, 2π) and elevation ε (rad) of WGS84 points."""
        enu = self.enu(lat, lon, alt)
        rho = np.linalg.norm(enu, axis=-1)
        theta = np.mod(np.arctan2(enu[..., 0], enu[..., 1]), 2 * np.pi)
        elev = np.arcsin(np.clip(enu[..., 2] / np.maximum(rho, 1e-9), -1.0, 1.0))
        return rho, theta, elev

    def locate(self, rho, theta, alt, iterations: int = 4) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """WGS84 (lat, lon) of a plot (ρ, θ) at altitude ``alt``, and a validity mask.

        The elevation ε that puts the point at the given altitude is found by Newton's method on
        the exact ellipsoidal height (start: spherical law of cosines). Invalid where no point at
        that slant range can have that altitude (ρ shorter than the height difference).
        """
        rho, theta, alt = np.broadcast_arrays(*(np.asarray(a, float) for a in (rho, theta, alt)))

        def geodetic(elev: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            lat, lon, h = self.geodetic(self._enu_from_polar(rho, theta, elev))
            return lon, lat, h

        lon, lat, valid = locate_polar(rho, alt, self.height_m, geodetic, iterations)
        return lat, lon, valid

    @staticmethod
    def _enu_from_polar(rho, theta, elev) -> np.ndarray:
        ce = np.cos(elev)
        return np.stack([rho * ce * np.sin(theta), rho * ce * np.cos(theta), rho * np.sin(elev)], axis=-1)

    def to_plane(self, rho, theta, alt) -> tuple[np.ndarray, np.ndarray]:
        """Plane positions (…, 2) of plots (ρ, θ, altitude) and a validity mask."""
        lat, lon, valid = self.locate(rho, theta, alt)
        x, y = self.plane.to_plane(lat, lon)
        return np.stack([x, y], axis=-1), valid

    # --- linearised bias and noise model -------------------------------------------------------
    def bias_jacobian(self, p: np.ndarray, rho, alt) -> np.ndarray:
        """C_s = D = ∂p/∂(ρ, θ) (…, 2, 2) at plane positions ``p`` (…, 2) with slant range ρ.

        Azimuth column Ω(p − p_R); range column u·∂d/∂ρ, where on a sphere
        cos c = (a² + b² − ρ²)/(2ab) gives ∂c/∂ρ = ρ/(ab sin c) and ∂d/∂ρ = (d/c)·∂c/∂ρ
        (d the plane distance, c the central angle, a and b the geocentric radii of radar and
        aircraft).
        """
        return bias_jacobian(self.xy, self.height_m, np.asarray(p, float), np.asarray(rho, float),
                             np.asarray(alt, float))


def in_coverage(rho: np.ndarray, elev: np.ndarray, max_range_m: float, radar_height_m: float,
                cone_of_silence_rad: float) -> np.ndarray:
    """Where a radar at height h_r sees a target at slant range ρ and elevation ε: ρ ≤ ``max_range_m``, ε above
    the geometric radar horizon −arccos(R/(R + h_r)) and below the cone of silence."""
    dip = math.acos(_EARTH_RADIUS_M / (_EARTH_RADIUS_M + max(radar_height_m, 0.0)))
    return (rho <= max_range_m) & (elev >= -dip) & (elev <= cone_of_silence_rad)


NEWTON_TOL_M = 1e-6  # locate_polar stops once every plot is this close to its altitude (1 µm)


def locate_polar(rho: np.ndarray, alt: np.ndarray, site_height_m, geodetic, iterations: int = 4
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(lon, lat, valid) of polar plots (ρ, θ) at altitudes ``alt`` seen from sites at ``site_height_m``
    (one, or one per plot): the elevation ε that puts each at its altitude, by Newton's method on the exact
    ellipsoidal height, ε ← ε − (h(ε) − h)/max(ρ cos ε, 1), from the spherical law of cosines
    sin ε = (b² − a² − ρ²)/(2aρ) (a, b the geocentric radii of site and aircraft). ``geodetic(ε)`` gives
    the WGS84 (lon, lat, h) of the plots at elevations ε. Newton's method converges quadratically from the
    spherical start (metres off, then millimetres, then nothing), so it stops as soon as every possible plot
    is within ``NEWTON_TOL_M`` of its altitude, after at most ``iterations`` steps. Invalid where no point at
    that slant range can have that altitude, or where the steps end more than 1 cm from it."""
    a = _EARTH_RADIUS_M + site_height_m
    b = _EARTH_RADIUS_M + alt
    sin_e = (b * b - a * a - rho * rho) / (2 * a * np.maximum(rho, 1e-9))
    valid = np.abs(sin_e) < 1.0
    elev = np.arcsin(np.clip(sin_e, -1.0, 1.0))
    for step in range(iterations + 1):
        lon, lat, h = geodetic(elev)
        miss = h - alt
        if step == iterations or not np.any(np.abs(miss[valid]) > NEWTON_TOL_M):
            break
        elev = elev - miss / np.maximum(rho * np.cos(elev), 1.0)
    return lon, lat, valid & (np.abs(miss) < 0.01)


def bias_jacobian(radar_xy: np.ndarray, radar_height_m, p: np.ndarray, rho: np.ndarray, alt: np.ndarray) -> np.ndarray:
    """C_s (…, 2, 2) of :meth:`RadarFrame.bias_jacobian` for radars at plane positions ``radar_xy``
    (2 or …, 2) and heights ``radar_height_m`` (one radar, or one per plot)."""
    dp = p - radar_xy
    d = np.linalg.norm(dp, axis=-1)
    a = _EARTH_RADIUS_M + radar_height_m
    b = _EARTH_RADIUS_M + alt
    cos_c = np.clip((a * a + b * b - rho * rho) / (2 * a * b), -1.0, 1.0)
    c = np.arccos(cos_c)
    safe_c = np.maximum(c, 1e-12)
    dd_drho = np.where(c > 1e-9, (d / safe_c) * rho / (a * b * np.sin(safe_c)), 1.0)
    u = dp / np.maximum(d, 1e-9)[..., None]
    J = np.empty(p.shape[:-1] + (2, 2))
    J[..., :, 0] = u * dd_drho[..., None]
    J[..., :, 1] = dp @ _OMEGA.T
    return J


def height_gradient(C: np.ndarray, rho: np.ndarray, alt: np.ndarray, radar_height_m) -> np.ndarray:
    """g = ∂z/∂h (n, 2): the move of plots' plane positions z per metre of the height ``alt`` they were
    converted at, at fixed slant range ρ and azimuth (radars at heights ``radar_height_m``, one or one per plot).

    At fixed ρ, cos c = (a² + b² − ρ²)/(2ab) (c the central angle, a and b the geocentric radii of radar and
    aircraft) gives ∂c/∂b = −(b − a cos c)/(ab sin c); with C_s's range column u·(d/c)·ρ/(ab sin c)
    (:func:`bias_jacobian`), g = −(range column of C_s)·(b − a cos c)/ρ: along the line of sight, towards the
    radar when the height grows.
    """
    a = _EARTH_RADIUS_M + np.asarray(radar_height_m, float)
    b = _EARTH_RADIUS_M + np.asarray(alt, float)
    rho = np.asarray(rho, float)
    cos_c = np.clip((a * a + b * b - rho * rho) / (2 * a * b), -1.0, 1.0)
    return -C[:, :, 0] * ((b - a * cos_c) / np.maximum(rho, 1.0))[:, None]
