"""Plots converted to the plane ahead of the TrackManager, in bulk.

The manager associates the plots of one radar in one frame together — a handful of plots, so pyproj's
per-call cost dominated their conversion. :func:`prepare` converts a whole batch (the manager passes
every plot waiting in its reorder window, ≈ 2 s of traffic) in one call per radar: z = the plot's plane
position at its altitude (:meth:`RadarFrame.to_plane`), C_s = ∂z/∂(ρ, θ)
(:meth:`RadarFrame.bias_jacobian`) and R = C_s W C_sᵀ, exactly what the manager computes per frame.
A :class:`PreparedPlot` remembers the altitude it was converted at; the manager uses the prepared
values only when that is the altitude it would use (a reported altitude, or ``primary_altitude_m``
for a plot without altitude or Mode S address).
"""

from __future__ import annotations

import attrs
import numpy as np

from radartracker.domain import Plot, Radar
from radartracker.geometry.plane import RadarFrame


@attrs.frozen(slots=True, eq=False)
class PreparedPlot(Plot):
    """A :class:`Plot` with its conversion at ``assumed_altitude_m``: z (2), C_s (2×2), R (2×2), ``valid``."""

    assumed_altitude_m: float = 0.0
    z: np.ndarray = attrs.field(factory=lambda: np.zeros(2))
    C: np.ndarray = attrs.field(factory=lambda: np.zeros((2, 2)))
    R: np.ndarray = attrs.field(factory=lambda: np.zeros((2, 2)))
    valid: bool = False


def prepare(plots: list[Plot], frames: dict[str, RadarFrame], radars: dict[str, Radar],
            primary_altitude_m: float) -> list[Plot]:
    """``plots`` with each convertible one replaced by its :class:`PreparedPlot` (one call per radar).

    Left as they are: plots of unknown radars, already prepared ones, and plots without altitude but
    with a Mode S address (they take their track's altitude, not known ahead).
    """
    todo = [k for k, p in enumerate(plots) if type(p) is Plot and p.radar in frames
            and not (p.altitude_m is None and p.mode_s is not None)]
    out = list(plots)
    by_radar: dict[str, list[int]] = {}
    for k in todo:
        by_radar.setdefault(plots[k].radar, []).append(k)
    for rid, ks in by_radar.items():
        rho = np.array([plots[k].range_m for k in ks])
        theta = np.array([plots[k].azimuth_rad for k in ks])
        alt = np.array([primary_altitude_m if plots[k].altitude_m is None else plots[k].altitude_m for k in ks])
        frame = frames[rid]
        z, ok = frame.to_plane(rho, theta, alt)
        C = frame.bias_jacobian(z, rho, alt)
        R = C @ radars[rid].W @ np.swapaxes(C, 1, 2)
        for m, k in enumerate(ks):
            p = plots[k]
            out[k] = PreparedPlot(p.time, p.radar, p.range_m, p.azimuth_rad, p.altitude_m, p.mode_s, p.mode_3a,
                                  p.target, float(alt[m]), z[m], C[m], R[m], bool(ok[m]))
    return out
