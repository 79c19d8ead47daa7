"""Triangulated positions as tracker measurements (passive and active sensors mixed).

A fix r* (frame ENU) with covariance Σ becomes an unbiased plane measurement like an ADS-B report
(seed 000 eq. 1.5 with C_s = 0)::

    z = g(r*),   R = G Σ Gᵀ,   C = 0,   radar = None

where g maps the frame point to the system plane (frame ENU → WGS84 → stereographic plane, all
pyproj) and G = ∂g/∂r (2×3) is taken by central differences of that exact map. The height
component of Σ enters R only through G's (small) third column.

Positions from one dynamic track at different times are correlated through the shared
coefficients; feed static fixes (or one point per track) to keep the measurements independent.
"""

from __future__ import annotations

from collections.abc import Hashable

import numpy as np

from radartracker.api import PlaneMeasurement, SystemPlane

from .frame import TriangulationFrame
from .static import Fix

_STEP_M = 1.0


def plane_map(frame: TriangulationFrame, plane: SystemPlane, position) -> tuple[np.ndarray, np.ndarray]:
    """Plane (x, y) of a frame point and G = ∂(x, y)/∂(e, n, u) (2×3)."""
    r = np.asarray(position, float)
    pts = np.vstack([r, r + _STEP_M * np.eye(3), r - _STEP_M * np.eye(3)])
    lat, lon, _ = frame.geodetic(pts)
    x, y = plane.to_plane(lat, lon)
    xy = np.stack([x, y], axis=1)
    G = (xy[1:4] - xy[4:7]).T / (2 * _STEP_M)
    return xy[0], G


def plane_measurement(frame: TriangulationFrame, plane: SystemPlane, position, cov, time: float,
                      aircraft: Hashable) -> PlaneMeasurement:
    """An unbiased :class:`PlaneMeasurement` of ``aircraft`` at ``time`` from a frame position."""
    z, G = plane_map(frame, plane, position)
    R = G @ np.asarray(cov, float) @ G.T
    return PlaneMeasurement(time=float(time), aircraft=aircraft, radar=None, z=z,
                            C=np.zeros((2, 2)), R=0.5 * (R + R.T))


def fix_measurement(frame: TriangulationFrame, plane: SystemPlane, fix: Fix,
                    aircraft: Hashable) -> PlaneMeasurement:
    """The plane measurement of a static fix, at the fix's time."""
    return plane_measurement(frame, plane, fix.position, fix.cov, fix.time, aircraft)
