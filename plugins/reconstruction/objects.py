"""The seed's data structures for trajectory reconstruction (seed 000 §2.3, DESIGN §7).

The seed links everything with doubly linked lists (``.Prd``/``.Sld``) and pointers from a
control segment to the geometric-track points it produced (``.nTr``/``.kTr``). Here the lists are
ordinary sequences and arrays; every relation stays reachable:

* segment k's neighbours: ``control[k - 1]``, ``control[k + 1]`` (or :meth:`ControlTrack.neighbours`);
* segment → geometric points (nTr/kTr): ``segment.geo_span`` (a ``slice`` of the geometric track,
  set by :func:`~radartracker_plugins.reconstruction.integrate.geo_track`) and
  :meth:`GeoTrack.segment_points`;
* geometric point → segment: ``GeoTrack.segment`` (index of the producing segment per point);
* a point's time from its position in the track: ``GeoTrack.time`` (``t0 + i·dt``);
* plot neighbours: ``plots[i - 1]``, ``plots[i + 1]``.

Model (seed eq. 2.1, plane x east, y north, φ clockwise from north):
ẋ = v sin φ, ẏ = v cos φ, φ̇ = u / v, v̇ = w, with |u| ≤ u_max, |w| ≤ w_max.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence

import attrs
import numpy as np


def _finite(inst, attr, value) -> None:
    if not math.isfinite(value):
        raise ValueError(f"{attr.name}: expected a finite number, got {value!r}")


@attrs.frozen
class GeoPoint:
    """One point of a geometric track: plane position (m), height (m), heading φ (rad), speed v (m/s).

    Also the initial state of a control track (the seed's ``.nTr`` start point), with its time.
    """

    t: float = attrs.field(converter=float, validator=_finite)
    x: float = attrs.field(converter=float, validator=_finite)
    y: float = attrs.field(converter=float, validator=_finite)
    phi: float = attrs.field(converter=float, validator=_finite)
    v: float = attrs.field(converter=float, validator=_finite)
    h: float = attrs.field(default=0.0, converter=float)

    def __attrs_post_init__(self) -> None:
        if self.v <= 0.0:
            raise ValueError(f"v: speed must be > 0, got {self.v!r}")


@attrs.frozen
class ControlSegment:
    """A constant-control segment (seed ``.Upr``, ``.Wpr``, ``.UTr``, ``.UTk``; ``.nTr``/``.kTr``).

    ``u`` lateral and ``w`` longitudinal acceleration (m/s²) held over [t_start, t_end);
    ``geo_span`` is the slice of the geometric track this segment produced (None until integrated).
    """

    u: float = attrs.field(converter=float, validator=_finite)
    w: float = attrs.field(converter=float, validator=_finite)
    t_start: float = attrs.field(converter=float, validator=_finite)
    t_end: float = attrs.field(converter=float, validator=_finite)
    geo_span: slice | None = attrs.field(default=None, eq=False)

    def __attrs_post_init__(self) -> None:
        if not self.t_end > self.t_start:
            raise ValueError(f"t_end: must be after t_start ({self.t_start!r}), got {self.t_end!r}")

    @property
    def duration(self) -> float:
        return self.t_end - self.t_start


@attrs.frozen
class ControlTrack(Sequence):
    """The control track: the initial point and ordered segments with t_end[k−1] == t_start[k].

    Validates itself: at least one segment, the first starts at the initial point's time, and
    consecutive boundary times match (to 1e-9 s).
    """

    initial: GeoPoint
    segments: tuple[ControlSegment, ...] = attrs.field(converter=tuple)

    def __attrs_post_init__(self) -> None:
        if not self.segments:
            raise ValueError("segments: a control track needs at least one segment")
        if abs(self.segments[0].t_start - self.initial.t) > 1e-9:
            raise ValueError(
                f"segments[0].t_start: {self.segments[0].t_start!r} != initial time {self.initial.t!r}"
            )
        for k in range(1, len(self.segments)):
            if abs(self.segments[k].t_start - self.segments[k - 1].t_end) > 1e-9:
                raise ValueError(
                    f"segments[{k}].t_start: {self.segments[k].t_start!r} != "
                    f"segments[{k - 1}].t_end {self.segments[k - 1].t_end!r}"
                )

    def __getitem__(self, k):  # type: ignore[override]
        return self.segments[k]

    def __len__(self) -> int:
        return len(self.segments)

    def __iter__(self) -> Iterator[ControlSegment]:
        return iter(self.segments)

    def neighbours(self, k: int) -> tuple[ControlSegment | None, ControlSegment | None]:
        """The seed's (.Prd, .Sld) of segment k: previous and next segment, None at the ends."""
        return (self.segments[k - 1] if k > 0 else None,
                self.segments[k + 1] if k + 1 < len(self.segments) else None)

    @property
    def t_start(self) -> float:
        return self.segments[0].t_start

    @property
    def t_end(self) -> float:
        return self.segments[-1].t_end

    @property
    def switch_times(self) -> np.ndarray:
        """Interior switch times t_start[1:], the times the controls change."""
        return np.array([s.t_start for s in self.segments[1:]])

    @property
    def u(self) -> np.ndarray:
        return np.array([s.u for s in self.segments])

    @property
    def w(self) -> np.ndarray:
        return np.array([s.w for s in self.segments])

    def shifted(self, dt: float) -> "ControlTrack":
        """The same track with every time moved by ``dt`` seconds."""
        return ControlTrack(attrs.evolve(self.initial, t=self.initial.t + dt),
                            [attrs.evolve(s, t_start=s.t_start + dt, t_end=s.t_end + dt) for s in self])

    def segment_index(self, t) -> np.ndarray:
        """Index of the segment in force at each time ``t`` (times past the end go to the last)."""
        return np.clip(np.searchsorted(self.switch_times, np.asarray(t, float), side="right"),
                       0, len(self.segments) - 1)


@attrs.frozen
class PlotTrack(Sequence):
    """One aircraft's plots in the system plane, time-ordered (seed "трек замеров").

    ``z`` (n, 2) plane positions, ``h`` heights (NaN where unknown), ``radar`` ids, and per plot
    the plane noise covariance ``R`` (n, 2, 2) = D W Dᵀ and bias Jacobian ``C`` (n, 2, 2) = D
    (seed 000 eq. 1.11), so that a known radar bias ς can be removed as z − C ς; ``rho`` the measured slant
    range (m; NaN where not known), which a range gain's column ρ c_ρ needs.
    """

    key: str
    t: np.ndarray = attrs.field(converter=lambda a: np.asarray(a, float))
    z: np.ndarray = attrs.field(converter=lambda a: np.asarray(a, float))
    h: np.ndarray = attrs.field(converter=lambda a: np.asarray(a, float))
    radar: np.ndarray = attrs.field(converter=lambda a: np.asarray(a, dtype=object))
    R: np.ndarray = attrs.field(converter=lambda a: np.asarray(a, float))
    C: np.ndarray = attrs.field(converter=lambda a: np.asarray(a, float))
    rho: np.ndarray = attrs.field(converter=lambda a: np.asarray(a, float),
                                  default=attrs.Factory(lambda self: np.full(len(self.t), np.nan), takes_self=True))

    def __attrs_post_init__(self) -> None:
        n = len(self.t)
        shapes = {"z": (n, 2), "h": (n,), "radar": (n,), "R": (n, 2, 2), "C": (n, 2, 2), "rho": (n,)}
        for name, shape in shapes.items():
            if getattr(self, name).shape != shape:
                raise ValueError(f"{name}: expected shape {shape}, got {getattr(self, name).shape}")
        if n < 2:
            raise ValueError(f"t: a plot track needs at least 2 plots, got {n}")
        if not np.all(np.isfinite(self.t)) or np.any(np.diff(self.t) < 0):
            raise ValueError("t: plot times must be finite and sorted")
        if not np.all(np.isfinite(self.z)):
            raise ValueError("z: plot positions must be finite")
        if np.any(np.linalg.eigvalsh(self.R)[:, 0] <= 0):
            raise ValueError("R: every noise covariance must be positive definite")

    def __getitem__(self, i):  # type: ignore[override]
        return {"t": self.t[i], "x": self.z[i, 0], "y": self.z[i, 1], "h": self.h[i],
                "radar": self.radar[i], "R": self.R[i]}

    def __len__(self) -> int:
        return len(self.t)

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0])


@attrs.frozen(eq=False)
class GeoTrack(Sequence):
    """A geometric track on the uniform grid t0 + i·dt (seed "геометрический трек").

    Arrays x, y, h, phi, v per point; ``segment[i]`` is the index of the control segment that
    produced point i, and ``control`` the control track it was built from.
    """

    t0: float
    dt: float
    x: np.ndarray
    y: np.ndarray
    h: np.ndarray
    phi: np.ndarray
    v: np.ndarray
    segment: np.ndarray
    control: ControlTrack

    @property
    def time(self) -> np.ndarray:
        """Each point's time from its position in the track (the seed's convention)."""
        return self.t0 + self.dt * np.arange(len(self.x))

    def __len__(self) -> int:
        return len(self.x)

    def __getitem__(self, i):  # type: ignore[override]
        if isinstance(i, slice):
            return [self[j] for j in range(*i.indices(len(self)))]
        return GeoPoint(self.t0 + self.dt * (i % len(self)), self.x[i], self.y[i], self.phi[i], self.v[i], self.h[i])

    def segment_points(self, k: int) -> list[GeoPoint]:
        """The points produced by control segment k (the seed's .nTr … .kTr)."""
        return self[self.control[k].geo_span]
