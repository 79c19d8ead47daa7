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
five plus one per frame instead of six per radar, each in place on ``array('d')`` buffers (pyproj's
argument handling copies numpy arrays in and out: at light traffic a third of each call). The arithmetic
between those calls (Newton's start and steps, east-north-up → ECEF, C_s, R) runs in compiled loops, plot
by plot, with RadarFrame's operations in the same order (a frame of ~50 plots paid ~40 numpy calls of a
few µs each, whatever its size: the 200-aircraft replay's cost per input); R = C_s W C_sᵀ as numpy's
``matmul`` rounds it through OpenBLAS (fused multiply-adds, :func:`_dot2`: one BLAS call per 2×2 product
cost ~0.2 µs per plot). ``tests/tracking/test_prepared.py`` holds it to RadarFrame radar by radar and the
products' rounding to exact arithmetic.
"""

from __future__ import annotations

import math
from array import array
from itertools import repeat

import numpy as np
from numba import njit, types
from numba.extending import intrinsic
from pyproj import Transformer
from pyproj.enums import TransformDirection

from radartracker.domain import Radar, nacp_sigma_m
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
        site = [(math.radians(f.lat), math.radians(f.lon)) for f in fr]
        trig = [[math.sin(p), math.cos(p), math.sin(q), math.cos(q)] for p, q in site]
        # what the compiled loops read of a radar, one row each (columns _H … _W below: one argument, not five)
        self._site = np.column_stack([self.height, np.array(trig, float).reshape(len(fr), 4),
                                      np.array([X0, Y0, Z0], float).T.reshape(len(fr), 3), self.xy,
                                      self.W.reshape(len(fr), 4)])

    def convert_frame(self, radars: np.ndarray, counts: np.ndarray, rho: np.ndarray, theta: np.ndarray,
                      alt: np.ndarray, lat: np.ndarray, lon: np.ndarray, nacp: np.ndarray,
                      iterations: int = 4) -> tuple[np.ndarray, ...]:
        """A frame's n plots radar by radar (``counts[k]`` plots of the radar in row ``radars[k]``, after
        those of the radars before it), then its m ADS-B positions (``lat``, ``lon``, NACp ``nacp``), as
        rows of z (n+m, 2), C_s (n+m, 2, 2), R (n+m, 2, 2) and the radar's row (n+m; −1: ADS-B), and the
        plots' validity (n): a plot's row as :meth:`convert`'s, an ADS-B row its plane position with C = 0
        and R = σ² I, σ = :func:`~radartracker.domain.nacp_sigma_m` of its NACp (ValueError if not 1 … 11).

        The frame's points are transformed by pyproj in place, in Python ``array('d')`` buffers (its
        documented ``inplace``, with the input type that its argument handling passes straight through: no
        copy in or out per coordinate, ~1/3 of each of the frame's six calls at light traffic) that the
        compiled loops read and write through numpy views: the plots' ECEF → WGS84 (RadarFrame.locate's
        Newton steps on the height: the arithmetic between the calls in :func:`_newton_start` and
        :func:`_newton_step`, the same operations in the same order as RadarFrame's numpy expressions),
        then the plots' and the reports' WGS84 → plane in one call; :func:`_finish` writes the rows."""
        radars, counts = np.asarray(radars, np.int64), np.asarray(counts, np.int64)
        rho, theta, alt, lat, lon = map(np.asarray, (rho, theta, alt, lat, lon), repeat(float))
        nacp = np.asarray(nacp, np.int64)
        n, m = len(rho), len(lat)
        cx, cy, cz, px, py = _ZERO * n, _ZERO * n, _ZERO * n, _ZERO * (n + m), _ZERO * (n + m)
        x, y, h, X, Y = map(np.frombuffer, (cx, cy, cz, px, py))  # views: ECEF → (lon, lat, h); plane x, y
        work, rows, valid = np.empty((5, n)), np.empty(n + m, np.int64), np.empty(n, bool)
        _newton_start(radars, counts, rho, theta, alt, self._site, work, rows, valid, x, y, h)
        if n:
            for _ in range(iterations):
                self._cart.transform(cx, cy, cz, direction=_INVERSE, inplace=True)
                _newton_step(rows, self._site, work, x, y, h)
            self._cart.transform(cx, cy, cz, direction=_INVERSE, inplace=True)
        _gather(x, y, lon, lat, X, Y)
        self.plane.to_plane_inplace(px, py)
        z, C, R = np.empty((n + m, 2)), np.empty((n + m, 2, 2)), np.empty((n + m, 2, 2))
        _finish(rows, self._site, work, X, Y, h, nacp, _NACP_SD, valid, z, C, R)
        return z, C, R, rows, valid

    def convert(self, rows: np.ndarray, rho: np.ndarray, theta: np.ndarray, alt: np.ndarray,
                lat: np.ndarray | None = None, lon: np.ndarray | None = None) -> tuple[np.ndarray, ...]:
        """Plots → (z (n, 2), C_s (n, 2, 2), R (n, 2, 2), valid (n)); with ``lat``/``lon`` given (ADS-B
        positions), also their plane positions (m, 2) from the same pyproj call (:meth:`convert_frame`)."""
        m = 0 if lat is None else len(lat)
        ll = (np.zeros(0), np.zeros(0)) if lat is None else (lat, lon)
        z, C, R, _, valid = self.convert_frame(rows, np.ones(len(rows), np.int64), rho, theta, alt, *ll,
                                               np.full(m, 8, np.int64))
        n = len(valid)
        return (z[:n], C[:n], R[:n], valid) + ((z[n:],) if lat is not None else ())


_INVERSE = TransformDirection.INVERSE
_ZERO = array("d", [0.0])  # × n: a buffer of n doubles that pyproj transforms in place
# PlaneConverter._site's columns: height, sin φ, cos φ, sin λ, cos λ, the site in ECEF (X0, Y0, Z0), in the
# plane (x, y), W (4); _newton_start's ``work`` rows: ρ, h, sin θ, cos θ, ε
_H, _SP, _CP, _SL, _CL, _X0, _Y0, _Z0, _PX, _PY, _W = range(11)
_RHO, _ALT, _ST, _CT, _EL = range(5)
_NACP_SD = np.array([math.nan] + [nacp_sigma_m(k) for k in range(1, 12)])  # an ADS-B position's σ by its NACp


@njit(cache=True)
def _nan_max(x: float, floor: float) -> float:
    """np.maximum(x, floor) of one number (NaN propagates)."""
    return x if x > floor or x != x else floor


@njit(cache=True)
def _clip1(x: float) -> float:
    """np.clip(x, -1, 1) of one number (NaN propagates)."""
    return -1.0 if x < -1.0 else (1.0 if x > 1.0 else x)


@njit(cache=True)
def _newton_start(radars, counts, rho, theta, alt, site, work, rows, valid, x, y, z) -> None:
    """Each plot's radar row (``rows``, −1 for the reports after them), its ``work`` column (ρ, h, sin θ,
    cos θ, ε), Newton's start (spherical law of cosines: sin ε = (b² − a² − ρ²)/(2aρ)) and its point in
    ECEF (x, y, z)."""
    total = 0
    for k in range(counts.shape[0]):
        total += counts[k] if counts[k] >= 0 else rho.shape[0] + 1
    if radars.shape[0] != counts.shape[0] or total != rho.shape[0]:
        raise ValueError("counts: one per radar, not negative, adding up to the plots")
    i = 0
    for k in range(radars.shape[0]):
        for _ in range(counts[k]):
            rows[i] = radars[k]
            i += 1
    for j in range(i, rows.shape[0]):
        rows[j] = -1
    for i in range(rho.shape[0]):
        a = _EARTH_RADIUS_M + site[rows[i], _H]
        b = _EARTH_RADIUS_M + alt[i]
        sin_e = (b * b - a * a - rho[i] * rho[i]) / (2 * a * _nan_max(rho[i], 1e-9))
        valid[i] = abs(sin_e) < 1.0
        work[_RHO, i], work[_ALT, i] = rho[i], alt[i]
        work[_ST, i], work[_CT, i] = math.sin(theta[i]), math.cos(theta[i])
        work[_EL, i] = math.asin(_clip1(sin_e))
    _ecef(rows, site, work, x, y, z)


@njit(cache=True)
def _ecef(rows, site, work, x, y, z) -> None:
    """ECEF of the polar points (ρ, θ, ε) of ``work``: east-north-up of the radar, then PROJ topocentric's
    inverse."""
    for i in range(work.shape[1]):
        r = rows[i]
        st, ct, rho, elev = work[_ST, i], work[_CT, i], work[_RHO, i], work[_EL, i]
        sp, cp, sl, cl = site[r, _SP], site[r, _CP], site[r, _SL], site[r, _CL]
        ce = math.cos(elev)
        e, n, u = rho * ce * st, rho * ce * ct, rho * math.sin(elev)
        x[i] = site[r, _X0] - e * sl - n * sp * cl + u * cp * cl
        y[i] = site[r, _Y0] + e * cl - n * sp * sl + u * cp * sl
        z[i] = site[r, _Z0] + n * cp + u * sp


@njit(cache=True)
def _newton_step(rows, site, work, x, y, z) -> None:
    """ε ← ε − (h − h_target)/max(ρ cos ε, 1) with h the height that pyproj wrote over ``z``, and the new
    point in ECEF (x, y, z)."""
    for i in range(work.shape[1]):
        elev = work[_EL, i]
        work[_EL, i] = elev - (z[i] - work[_ALT, i]) / _nan_max(work[_RHO, i] * math.cos(elev), 1.0)
    _ecef(rows, site, work, x, y, z)


@njit(cache=True)
def _gather(plon, plat, lon, lat, X, Y) -> None:
    """The plots' (lon, lat), then the reports', into the plane call's buffers ``X``, ``Y``."""
    n = plon.shape[0]
    for i in range(n):
        X[i], Y[i] = plon[i], plat[i]
    for j in range(lon.shape[0]):
        X[n + j], Y[n + j] = lon[j], lat[j]


@intrinsic
def _fma(typingctx, a, b, c):
    """a·b + c rounded once (LLVM's ``fma``: the processor's instruction, else libm's)."""
    def codegen(context, builder, sig, args):
        return builder.fma(*args)
    return types.float64(types.float64, types.float64, types.float64), codegen


@njit(cache=True)
def _dot2(a0, a1, b0, b1):
    """a0 b0 + a1 b1 as numpy's matmul of float64 matrices computes it through OpenBLAS's FMA kernels: an
    accumulator from +0, a0 b0 then a1 b1 fused into it, then added to the zeroed output (so −0 → +0)."""
    return _fma(a1, b1, _fma(a0, b0, 0.0)) + 0.0


@njit(cache=True)
def _finish(rows, site, work, px, py, h, nacp, nacp_sd, valid, z, C, R) -> None:
    """The frame's rows: a plot's validity (its height within 1 cm of its altitude), plane position, C_s
    (:func:`radartracker.geometry.plane.bias_jacobian`, plot by plot) and R = (C_s W) C_sᵀ
    (``C @ W @ C.swapaxes(1, 2)``'s bits, :func:`_dot2`); an ADS-B row's position, C = 0 and R = σ² I
    (σ = ``nacp_sd[nacp]``)."""
    n = work.shape[1]
    for i in range(n):
        r, rho, alt = rows[i], work[_RHO, i], work[_ALT, i]
        valid[i] = valid[i] and abs(h[i] - alt) < 0.01
        z[i, 0], z[i, 1] = px[i], py[i]
        dx, dy = px[i] - site[r, _PX], py[i] - site[r, _PY]
        d = math.sqrt(dx * dx + dy * dy)
        a = _EARTH_RADIUS_M + site[r, _H]
        b = _EARTH_RADIUS_M + alt
        c = math.acos(_clip1((a * a + b * b - rho * rho) / (2 * a * b)))
        safe_c = _nan_max(c, 1e-12)
        dd_drho = (d / safe_c) * rho / (a * b * math.sin(safe_c)) if c > 1e-9 else 1.0
        dn = _nan_max(d, 1e-9)
        c00, c10, c01, c11 = dx / dn * dd_drho, dy / dn * dd_drho, dy, -dx
        C[i, 0, 0], C[i, 1, 0], C[i, 0, 1], C[i, 1, 1] = c00, c10, c01, c11
        w00, w01, w10, w11 = site[r, _W], site[r, _W + 1], site[r, _W + 2], site[r, _W + 3]
        t00, t01 = _dot2(c00, c01, w00, w10), _dot2(c00, c01, w01, w11)
        t10, t11 = _dot2(c10, c11, w00, w10), _dot2(c10, c11, w01, w11)
        R[i, 0, 0], R[i, 0, 1] = _dot2(t00, t01, c00, c01), _dot2(t00, t01, c10, c11)
        R[i, 1, 0], R[i, 1, 1] = _dot2(t10, t11, c00, c01), _dot2(t10, t11, c10, c11)
    for j in range(nacp.shape[0]):
        if not 1 <= nacp[j] < nacp_sd.shape[0]:
            raise ValueError("nacp: must be 1..11 (0 means unknown accuracy, unusable)")
        i, s2 = n + j, nacp_sd[nacp[j]] * nacp_sd[nacp[j]]
        z[i, 0], z[i, 1] = px[i], py[i]
        C[i, 0, 0] = C[i, 0, 1] = C[i, 1, 0] = C[i, 1, 1] = 0.0
        R[i, 0, 0], R[i, 0, 1], R[i, 1, 0], R[i, 1, 1] = s2, 0.0, 0.0, s2
