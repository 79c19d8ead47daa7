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
five plus one per frame instead of six per radar. The arithmetic between those calls (Newton's start and
steps, east-north-up → ECEF, C_s) runs in compiled loops, plot by plot, with RadarFrame's operations in
the same order (a frame of ~50 plots paid ~40 numpy calls of a few µs each, whatever its size: the
200-aircraft replay's cost per input). ``tests/tracking/test_prepared.py`` holds it to RadarFrame radar
by radar.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from pyproj import Transformer
from pyproj.enums import TransformDirection

from radartracker.domain import Radar
from radartracker.geometry.plane import _EARTH_RADIUS_M, RadarFrame, SystemPlane

_CART = ("+proj=pipeline +step +proj=unitconvert +xy_in=deg +xy_out=rad +step +proj=cart +ellps=WGS84")


class PlaneConverter:
    """Plots (ρ, θ, h) of any radars → plane z, C_s, R and validity, in one vectorised pass.

    ``rows``: the radar of each plot as its position in ``radars``. Equal to
    :meth:`RadarFrame.to_plane` and :meth:`RadarFrame.bias_jacobian` of each plot's radar.
    """

    def __init__(self, radars: list[Radar], frames: dict[str, RadarFrame], plane: SystemPlane) -> None:
        self.plane = plane
        self.row = {r.id: k for k, r in enumerate(radars)}
        self.ids = [r.id for r in radars]  # radar id by row
        fr = [frames[r.id] for r in radars]
        self.height = np.array([f.height_m for f in fr], float)
        self.xy = np.array([f.xy for f in fr], float).reshape(len(fr), 2)
        self.W = np.array([r.W for r in radars], float).reshape(len(fr), 2, 2)
        self._cart = Transformer.from_pipeline(_CART)
        # PROJ topocentric's constants: the site in ECEF (what its inverse gives for (0, 0, 0): the same bits
        # as cart's forward, checked on 3 000 random sites; one call, not one transformer per radar) and the
        # sines and cosines of its latitude and longitude
        X0, Y0, Z0 = self._cart.transform([f.lon for f in fr], [f.lat for f in fr], [f.height_m for f in fr])
        self.origin = np.array([X0, Y0, Z0], float).T.reshape(len(fr), 3)
        site = [(math.radians(f.lat), math.radians(f.lon)) for f in fr]
        self.trig = np.array([[math.sin(p), math.cos(p), math.sin(q), math.cos(q)] for p, q in site],
                             float).reshape(len(fr), 4)

    def locate(self, rows: np.ndarray, rho: np.ndarray, theta: np.ndarray, alt: np.ndarray,
               iterations: int = 4) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """WGS84 (lat, lon) and validity of plots at altitude ``alt`` (RadarFrame.locate, same steps): the
        arithmetic between pyproj's calls in compiled loops (:func:`_newton_start`, :func:`_ecef`,
        :func:`_newton_step`), the same operations in the same order as the numpy expressions of RadarFrame."""
        n = len(rows)
        polar, elev, valid, xyz = np.empty((9, n)), np.empty(n), np.empty(n, bool), np.empty((3, n))
        _newton_start(rows, rho, theta, alt, self.height, self.trig, self.origin, polar, elev, valid, xyz)
        for _ in range(iterations):
            _, _, h = self._cart.transform(xyz[0], xyz[1], xyz[2], direction=TransformDirection.INVERSE)
            _newton_step(elev, np.asarray(h, float), alt, rho, polar, xyz)
        lon, lat, h = self._cart.transform(xyz[0], xyz[1], xyz[2], direction=TransformDirection.INVERSE)
        valid &= np.abs(np.asarray(h) - alt) < 0.01
        return np.asarray(lat), np.asarray(lon), valid

    def bias_jacobian(self, rows: np.ndarray, p: np.ndarray, rho: np.ndarray, alt: np.ndarray) -> np.ndarray:
        """C_s (n, 2, 2) at plane positions ``p`` (RadarFrame.bias_jacobian, same steps, compiled)."""
        J = np.empty((len(rows), 2, 2))
        _bias_jacobian(rows, self.xy, self.height, np.ascontiguousarray(p), rho, alt, J)
        return J

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


@njit(cache=True)
def _nan_max(x: float, floor: float) -> float:
    """np.maximum(x, floor) of one number (NaN propagates)."""
    return x if x > floor or x != x else floor


@njit(cache=True)
def _clip1(x: float) -> float:
    """np.clip(x, -1, 1) of one number (NaN propagates)."""
    return -1.0 if x < -1.0 else (1.0 if x > 1.0 else x)


@njit(cache=True)
def _newton_start(rows, rho, theta, alt, height, trig, origin, polar, elev, valid, xyz) -> None:
    """Newton's start (spherical law of cosines: sin ε = (b² − a² − ρ²)/(2aρ)), its point in ECEF (``xyz``)
    and what the iterations share: ``polar`` rows sin θ, cos θ, the radar's sin φ, cos φ, sin λ, cos λ and
    its site in ECEF."""
    for i in range(rows.shape[0]):
        r = rows[i]
        a = _EARTH_RADIUS_M + height[r]
        b = _EARTH_RADIUS_M + alt[i]
        sin_e = (b * b - a * a - rho[i] * rho[i]) / (2 * a * _nan_max(rho[i], 1e-9))
        valid[i] = abs(sin_e) < 1.0
        elev[i] = math.asin(_clip1(sin_e))
        polar[0, i], polar[1, i] = math.sin(theta[i]), math.cos(theta[i])
        for k in range(4):
            polar[2 + k, i] = trig[r, k]
        for k in range(3):
            polar[6 + k, i] = origin[r, k]
    _ecef(polar, rho, elev, xyz)


@njit(cache=True)
def _ecef(polar, rho, elev, xyz) -> None:
    """ECEF of polar points (ρ, θ, ε): east-north-up of the radar, then PROJ topocentric's inverse."""
    for i in range(rho.shape[0]):
        st, ct, sp, cp, sl, cl, X0, Y0, Z0 = polar[:, i]
        ce = math.cos(elev[i])
        e, n, u = rho[i] * ce * st, rho[i] * ce * ct, rho[i] * math.sin(elev[i])
        xyz[0, i] = X0 - e * sl - n * sp * cl + u * cp * cl
        xyz[1, i] = Y0 + e * cl - n * sp * sl + u * cp * sl
        xyz[2, i] = Z0 + n * cp + u * sp


@njit(cache=True)
def _newton_step(elev, h, alt, rho, polar, xyz) -> None:
    """ε ← ε − (h − h_target)/max(ρ cos ε, 1), and the new point in ECEF (``xyz``)."""
    for i in range(elev.shape[0]):
        elev[i] = elev[i] - (h[i] - alt[i]) / _nan_max(rho[i] * math.cos(elev[i]), 1.0)
    _ecef(polar, rho, elev, xyz)


@njit(cache=True)
def _bias_jacobian(rows, radar_xy, height, p, rho, alt, J) -> None:
    """C_s of :func:`radartracker.geometry.plane.bias_jacobian`, plot by plot (its radar: ``rows``)."""
    for i in range(rows.shape[0]):
        r = rows[i]
        dx, dy = p[i, 0] - radar_xy[r, 0], p[i, 1] - radar_xy[r, 1]
        d = math.sqrt(dx * dx + dy * dy)
        a = _EARTH_RADIUS_M + height[r]
        b = _EARTH_RADIUS_M + alt[i]
        c = math.acos(_clip1((a * a + b * b - rho[i] * rho[i]) / (2 * a * b)))
        safe_c = _nan_max(c, 1e-12)
        dd_drho = (d / safe_c) * rho[i] / (a * b * math.sin(safe_c)) if c > 1e-9 else 1.0
        dn = _nan_max(d, 1e-9)
        J[i, 0, 0], J[i, 1, 0] = dx / dn * dd_drho, dy / dn * dd_drho
        J[i, 0, 1], J[i, 1, 1] = dy, -dx
