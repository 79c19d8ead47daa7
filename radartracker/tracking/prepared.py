"""A frame's plots and ADS-B positions converted to the plane in one pass over every radar.

The manager converts the plots of one frame (a few dozen, from many radars) and its ADS-B reports.
:class:`PlaneConverter` evaluates the equations of :class:`~radartracker.geometry.plane.RadarFrame` for
all radars together, as numpy expressions over the frame's plots (each plot with its radar's constants),
with one pyproj call per step instead of one per radar and step:

* z = the plot's plane position at altitude h (:meth:`RadarFrame.locate`): the elevation ε that puts
  (ρ, θ) at h by Newton's method on the ellipsoidal height, ε ← ε − (h(ε) − h)/max(ρ cos ε, 1), from the
  spherical law of cosines sin ε = (b² − a² − ρ²)/(2aρ); the radar's east-north-up point
  (ρ cos ε sin θ, ρ cos ε cos θ, ρ sin ε) → ECEF by the site's rotation plus its ECEF position (PROJ's
  ``topocentric`` inverse), ECEF → WGS84 by pyproj (``cart``), then WGS84 → plane;
* C_s = ∂z/∂(ρ, θ) (:func:`radartracker.geometry.plane.bias_jacobian`) and R = C_s W_j C_sᵀ.
"""

from __future__ import annotations

import numpy as np
from pyproj import Transformer
from pyproj.enums import TransformDirection

from radartracker.domain import Radar, nacp_sigma_m
from radartracker.geometry.plane import RadarFrame, SystemPlane, bias_jacobian, locate_polar

_CART = ("+proj=pipeline +step +proj=unitconvert +xy_in=deg +xy_out=rad +step +proj=cart +ellps=WGS84")
_NACP_SD = np.array([np.nan] + [nacp_sigma_m(k) for k in range(1, 12)])  # an ADS-B position's σ by its NACp


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
        # each site in ECEF and the rotation from its east-north-up axes to ECEF's (columns: e, n, u)
        self.ecef = np.array(self._cart.transform([f.lon for f in fr], [f.lat for f in fr],
                                                  [f.height_m for f in fr]), float).T.reshape(len(fr), 3)
        phi, lam = np.radians([f.lat for f in fr]), np.radians([f.lon for f in fr])
        sp, cp, sl, cl = np.sin(phi), np.cos(phi), np.sin(lam), np.cos(lam)
        zero = np.zeros(len(fr))
        self.rotation = np.stack([np.stack([-sl, -sp * cl, cp * cl], -1), np.stack([cl, -sp * sl, cp * sl], -1),
                                  np.stack([zero, cp, sp], -1)], 1).reshape(len(fr), 3, 3)

    def convert_frame(self, radars: np.ndarray, counts: np.ndarray, rho: np.ndarray, theta: np.ndarray,
                      alt: np.ndarray, lat: np.ndarray, lon: np.ndarray, nacp: np.ndarray,
                      iterations: int = 4, at: np.ndarray | None = None) -> tuple[np.ndarray, ...]:
        """A frame's n plots radar by radar (``counts[k]`` plots of the radar in row ``radars[k]``, after
        those of the radars before it), then its m ADS-B positions (``lat``, ``lon``, NACp ``nacp``), as
        rows of z (n+m, 2), C_s (n+m, 2, 2), R (n+m, 2, 2) and the radar's row (n+m; −1: ADS-B), and the
        plots' validity (n): a plot's row as :meth:`RadarFrame.to_plane` and :meth:`RadarFrame.bias_jacobian`
        give it (valid where its height after Newton's steps is within 1 cm of its altitude), an ADS-B row
        its plane position with C = 0 and R = σ² I, σ = :func:`~radartracker.domain.nacp_sigma_m` of its
        NACp (ValueError if not 1 … 11).

        ``at`` (n, 2): the bias estimate ς̂ = (Δr̂, Δθ̂) each plot is linearised at — converted at
        (ρ − Δr̂, θ − Δθ̂), C_s taken there, and z = f(ρ − Δr̂, θ − Δθ̂) + C_s ς̂, so that z − C_s ς is exact at
        ς = ς̂ (an EKF's relinearisation; :mod:`radartracker.tracking.frame`). None: at ς̂ = 0."""
        radars, counts = np.asarray(radars, np.int64), np.asarray(counts, np.int64)
        rho, theta, alt, lat, lon = (np.asarray(v, float) for v in (rho, theta, alt, lat, lon))
        if at is not None:
            rho, theta = rho - at[:, 0], theta - at[:, 1]
        nacp = np.asarray(nacp, np.int64)
        if len(radars) != len(counts) or np.any(counts < 0) or counts.sum() != len(rho):
            raise ValueError("counts: one per radar, not negative, adding up to the plots")
        if np.any((nacp < 1) | (nacp > 11)):
            raise ValueError("nacp: must be 1..11 (0 means unknown accuracy, unusable)")
        rows = np.repeat(radars, counts)
        plon, plat, valid = self._locate(rows, rho, theta, alt, iterations)
        x, y = self.plane.to_plane(np.concatenate([plat, lat]), np.concatenate([plon, lon]))
        z = np.column_stack([x, y]).reshape(-1, 2)
        n = len(rho)
        C = np.zeros((len(z), 2, 2))
        C[:n] = bias_jacobian(self.xy[rows], self.height[rows], z[:n], rho, alt)
        if at is not None:
            z[:n] += np.einsum("nij,nj->ni", C[:n], at)
        R = np.empty_like(C)
        R[:n] = C[:n] @ self.W[rows] @ np.swapaxes(C[:n], 1, 2)
        R[n:] = _NACP_SD[nacp][:, None, None] ** 2 * np.eye(2)
        return z, C, R, np.concatenate([rows, np.full(len(lat), -1, np.int64)]), valid

    def _locate(self, rows: np.ndarray, rho: np.ndarray, theta: np.ndarray, alt: np.ndarray,
                iterations: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(lon, lat, valid) of plots (ρ, θ) at altitudes ``alt`` of the radars in ``rows``
        (:meth:`RadarFrame.locate` for every radar at once)."""
        return locate_polar(rho, alt, self.height[rows], lambda elev: self._geodetic(rows, rho, theta, elev),
                            iterations)

    def _geodetic(self, rows: np.ndarray, rho: np.ndarray, theta: np.ndarray,
                  elev: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """WGS84 (lon, lat, h) of the polar points (ρ, θ, ε) of the radars in ``rows``: east-north-up → ECEF
        (rotation plus the site), then pyproj's ECEF → WGS84."""
        ce = np.cos(elev)
        enu = np.stack([rho * ce * np.sin(theta), rho * ce * np.cos(theta), rho * np.sin(elev)], -1)
        xyz = self.ecef[rows] + np.einsum("nij,nj->ni", self.rotation[rows], enu)
        lon, lat, h = self._cart.transform(xyz[:, 0], xyz[:, 1], xyz[:, 2], direction=TransformDirection.INVERSE)
        return np.asarray(lon, float), np.asarray(lat, float), np.asarray(h, float)

    def convert(self, rows: np.ndarray, rho: np.ndarray, theta: np.ndarray, alt: np.ndarray,
                lat: np.ndarray | None = None, lon: np.ndarray | None = None,
                at: np.ndarray | None = None) -> tuple[np.ndarray, ...]:
        """Plots → (z (n, 2), C_s (n, 2, 2), R (n, 2, 2), valid (n)), linearised at ``at`` where given; with
        ``lat``/``lon`` given (ADS-B positions), also their plane positions (m, 2) from the same pyproj call
        (:meth:`convert_frame`)."""
        m = 0 if lat is None else len(lat)
        ll = (np.zeros(0), np.zeros(0)) if lat is None else (lat, lon)
        z, C, R, _, valid = self.convert_frame(rows, np.ones(len(rows), np.int64), rho, theta, alt, *ll,
                                               np.full(m, 8, np.int64), at=at)
        n = len(valid)
        return (z[:n], C[:n], R[:n], valid) + ((z[n:],) if lat is not None else ())
