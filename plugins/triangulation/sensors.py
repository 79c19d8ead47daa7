"""Passive direction finders and their bearings (seed 001 §1).

A direction finder П_m at a WGS84 site measures the azimuth α (clockwise from true north at
the site) and the elevation β (above the site's local ellipsoidal horizon) of the line of sight
to the target, with independent Gaussian errors of standard deviations σ_α, σ_β::

    α̃_mn = α⁰(t_mn) + Δα_mn,   β̃_mn = β⁰(t_mn) + Δβ_mn,   Δ ~ N(0, diag(σ_α², σ_β²))

Each finder may report on its own time grid t_mn (an asynchronous system, seed 001 eq. 1.2).
Construction validates every field and raises ``ValueError`` naming the field, like
:class:`radartracker.domain.Plot`.
"""

from __future__ import annotations

import math
from typing import Any

import attrs
import numpy as np

TWO_PI = 2.0 * math.pi


def _finite(inst: Any, attr: attrs.Attribute, value: Any) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
            or not math.isfinite(value):
        raise ValueError(f"{attr.name}: expected a finite number, got {value!r}")


def _range(lo: float, hi: float, unit: str, closed_hi: bool = True):
    def check(inst: Any, attr: attrs.Attribute, value: Any) -> None:
        _finite(inst, attr, value)
        scale = 180.0 / math.pi if unit == "rad" else 1.0
        if not (lo <= value <= hi if closed_hi else lo <= value < hi):
            bracket = "]" if closed_hi else ")"
            raise ValueError(f"{attr.name}: must be in [{lo * scale:g}, {hi * scale:g}{bracket} degrees, "
                             f"got {value * scale!r} deg")
    return check


# physical bounds (as radartracker.io.limits.BOUNDS): beyond them the geometry overflows a double
HEIGHT_M = (-1_000.0, 100_000.0)  # a site from below the Dead Sea to a stratospheric balloon
SIGMA_RAD = (1e-9, math.radians(10.0))  # 0.2 milli-arcseconds to 10°: no direction finder lies outside


def _bounded(lo: float, hi: float, unit: str):
    def check(inst: Any, attr: attrs.Attribute, value: Any) -> None:
        _finite(inst, attr, value)
        if not lo <= value <= hi:
            raise ValueError(f"{attr.name}: {value!r} outside the physical bounds [{lo:g}, {hi:g}] {unit}")
    return check


def _nonempty(inst: Any, attr: attrs.Attribute, value: Any) -> None:
    if not isinstance(value, str) or not value.strip():
        raise ValueError(f"{attr.name}: must be a non-empty string, got {value!r}")


def _time_grid(value: Any) -> tuple[float, ...] | None:
    return None if value is None else tuple(float(t) for t in value)


def _increasing(inst: Any, attr: attrs.Attribute, value: tuple[float, ...] | None) -> None:
    if value is None:
        return
    t = np.asarray(value, float)
    if t.size == 0 or not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
        raise ValueError(f"{attr.name}: must be a non-empty, finite, strictly increasing time grid")


@attrs.frozen
class DirectionFinder:
    """A passive direction-finding station П_m: site, bearing noise σ_α, σ_β and its own time grid.

    ``height_m`` is the height above the WGS84 ellipsoid; ``times`` (seconds, optional) are the
    instants t_mn at which it reports (seed 001 eq. 1.2), used when simulating.
    """

    id: str = attrs.field(validator=_nonempty)
    lat: float = attrs.field(validator=_range(-90.0, 90.0, "deg"))
    lon: float = attrs.field(validator=_range(-180.0, 180.0, "deg"))
    height_m: float = attrs.field(validator=_bounded(*HEIGHT_M, "m"))
    sigma_azimuth_rad: float = attrs.field(validator=_bounded(*SIGMA_RAD, "rad"))
    sigma_elevation_rad: float = attrs.field(validator=_bounded(*SIGMA_RAD, "rad"))
    times: tuple[float, ...] | None = attrs.field(default=None, converter=_time_grid,
                                                  validator=_increasing, eq=False)

    @property
    def W(self) -> np.ndarray:
        """Bearing noise covariance K_m = diag(σ_α², σ_β²) (seed 001 eq. 2.3 uses C_m = K_m⁻¹)."""
        return np.diag([self.sigma_azimuth_rad**2, self.sigma_elevation_rad**2])


@attrs.frozen(slots=True)
class Bearing:
    """One bearing: time (s), station id, azimuth α ∈ [0, 2π) and elevation β ∈ [−π/2, π/2] (rad).

    ``target`` groups bearings of one target (files with several targets).
    """

    time: float = attrs.field(validator=_finite)
    station: str = attrs.field(validator=_nonempty)
    azimuth_rad: float = attrs.field(validator=_range(0.0, TWO_PI, "rad", closed_hi=False))
    elevation_rad: float = attrs.field(validator=_range(-math.pi / 2, math.pi / 2, "rad"))
    target: str = "1"
