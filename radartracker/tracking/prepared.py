"""A frame's plots and ADS-B positions converted to the plane in one pass over every radar.

The manager converts the plots of one frame (a few dozen, from many radars) and its ADS-B reports;
pyproj's per-call cost, not the arithmetic, dominated when this was done radar by radar (six calls per
radar per frame) and report by report. :class:`PlaneConverter` evaluates exactly the equations of
:class:`~radartracker.geometry.plane.RadarFrame` for all radars together:

* z = the plot's plane position at altitude h (:meth:`RadarFrame.to_plane`): the elevation that puts
  (ρ, θ) at h by Newton's method on the ellipsoidal height, then WGS84 → plane;
* C_s = ∂z/∂(ρ, θ) (:meth:`RadarFrame.bias_jacobian`) and R = C_s W_j C_sᵀ.

The radar-local east-north-up → ECEF step is a rotation plus the site's ECEF position, written as
PROJ's ``topocentric`` inverse (same operations in the same order, so the same bits); the ECEF → WGS84
step (``cart``) and the stereographic plane are pyproj calls over all the frame's points at once:
five plus one per frame instead of six per radar. ``tests/tracking/test_prepared.py`` holds it to
RadarFrame radar by radar.
"""

from __future__ import annotations

import math

import numpy as np
from pyproj import Transformer

from radartracker.domain import Radar
from radartracker.geometry.plane import _EARTH_RADIUS_M, RadarFrame, SystemPlane, bias_jacobian

_CART = ("+proj=pipeline +step +proj=unitconvert +xy_in=deg +xy_out=rad +step +proj=cart +ellps=WGS84")


class PlaneConverter:
    """Plots (ρ, θ, h) of any radars → plane z, C_s, R and validity, in one vectorised pass.

    ``rows``: the radar of each plot as its position in ``radars``. Equal to
    :meth:`RadarFrame.to_plane` and :meth:`RadarFrame.bias_jacobian` of each plot's radar.
    """

    def __init__(self, radars: list[Radar], frames: dict[str, RadarFrame], plane: SystemPlane) -> None:
        self.plane = plane
        self.row = {r.id: k for k, r in enumerate(radars)}
        fr = [frames[r.id] for r in radars]
        self.height = np.array([f.height_m for f in fr], float)
        self.xy = np.array([f.xy for f in fr], float).reshape(len(fr), 2)
        self.W = np.array([r.W for r in radars], float).reshape(len(fr), 2, 2)
        origin, trig = [], []
        for f in fr:  # PROJ topocentric's constants: the site in ECEF, sin/cos of its latitude and longitude
            topo = Transformer.from_pipeline(f"+proj=topocentric +ellps=WGS84 +lat_0={f.lat} +lon_0={f.lon} "
                                             f"+h_0={f.height_m}")
            origin.append([float(v) for v in topo.transform(0.0, 0.0, 0.0, direction="INVERSE")])
            phi, lam = math.radians(f.lat), math.radians(f.lon)
            trig.append([math.sin(phi), math.cos(phi), math.sin(lam), math.cos(lam)])
        self.origin = np.array(origin, float).reshape(len(fr), 3)
        self.trig = np.array(trig, float).reshape(len(fr), 4)
        self._cart = Transformer.from_pipeline(_CART)

    def _polar(self, rows: np.ndarray, theta: np.ndarray) -> tuple[np.ndarray, ...]:
        """What does not change along Newton's iterations: sin θ, cos θ and the radars' constants by plot."""
        return (np.sin(theta), np.cos(theta), *self.trig[rows].T, *self.origin[rows].T)

    def geodetic(self, polar: tuple[np.ndarray, ...], rho: np.ndarray, elev: np.ndarray) -> tuple:
        """WGS84 (lat, lon, h) of polar points (ρ, θ, ε) (``polar``: :meth:`_polar` of the radars and θ;
        RadarFrame.geodetic of RadarFrame._enu_from_polar)."""
        st, ct, sp, cp, sl, cl, X0, Y0, Z0 = polar
        ce = np.cos(elev)
        e, n, u = rho * ce * st, rho * ce * ct, rho * np.sin(elev)
        X = X0 - e * sl - n * sp * cl + u * cp * cl
        Y = Y0 + e * cl - n * sp * sl + u * cp * sl
        Z = Z0 + n * cp + u * sp
        lon, lat, h = self._cart.transform(X, Y, Z, direction="INVERSE")
        return np.asarray(lat), np.asarray(lon), np.asarray(h)

    def locate(self, rows: np.ndarray, rho: np.ndarray, theta: np.ndarray, alt: np.ndarray,
               iterations: int = 4) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """WGS84 (lat, lon) and validity of plots at altitude ``alt`` (RadarFrame.locate, same steps)."""
        a = _EARTH_RADIUS_M + self.height[rows]
        b = _EARTH_RADIUS_M + alt
        sin_e = (b * b - a * a - rho * rho) / (2 * a * np.maximum(rho, 1e-9))
        valid = np.abs(sin_e) < 1.0
        elev = np.arcsin(np.clip(sin_e, -1.0, 1.0))
        polar = self._polar(rows, theta)
        for _ in range(iterations):
            _, _, h = self.geodetic(polar, rho, elev)
            elev = elev - (h - alt) / np.maximum(rho * np.cos(elev), 1.0)
        lat, lon, h = self.geodetic(polar, rho, elev)
        valid &= np.abs(h - alt) < 0.01
        return lat, lon, valid

    def bias_jacobian(self, rows: np.ndarray, p: np.ndarray, rho: np.ndarray, alt: np.ndarray) -> np.ndarray:
        """C_s (n, 2, 2) at plane positions ``p`` (RadarFrame.bias_jacobian, same steps)."""
        return bias_jacobian(self.xy[rows], self.height[rows], p, rho, alt)

    def convert(self, rows: np.ndarray, rho: np.ndarray, theta: np.ndarray, alt: np.ndarray,
                lat: np.ndarray | None = None, lon: np.ndarray | None = None) -> tuple[np.ndarray, ...]:
        """Plots → (z (n, 2), C_s (n, 2, 2), R (n, 2, 2), valid (n)); with ``lat``/``lon`` given (ADS-B
        positions), also their plane positions (m, 2) from the same pyproj call."""
        rows = np.asarray(rows, np.int64)
        rho, theta, alt = (np.asarray(v, float) for v in (rho, theta, alt))
        if len(rows):
            plat, plon, valid = self.locate(rows, rho, theta, alt)
        else:
            plat, plon, valid = np.zeros(0), np.zeros(0), np.zeros(0, bool)
        extra = 0 if lat is None else len(lat)
        if extra:
            plat, plon = np.concatenate([plat, lat]), np.concatenate([plon, lon])
        x, y = self.plane.to_plane(plat, plon)
        xy = np.stack([x, y], axis=-1).reshape(-1, 2)
        z = xy[:len(rows)]
        C = self.bias_jacobian(rows, z, rho, alt)
        R = C @ self.W[rows] @ np.swapaxes(C, 1, 2)
        return (z, C, R, valid) + ((xy[len(rows):],) if lat is not None else ())
