"""The reference trajectories the sensors are judged against: the truth where the scenario has it, else
each aircraft's validated ADS-B and the reconstruction of every other aircraft from its plots
(``ReferenceConfig.reconstruct``, on by default).

* **truth** (``truth.csv``): each target's positions, joined by straight lines in the system plane
  (a conformal projection: over the truth's 1 s steps the chord differs from the path by millimetres).
* **adsb**: each address's reports of NACp ≥ :attr:`ReferenceConfig.min_nacp` (the accuracy bound, EPU,
  of NACp 7 is 0.1 NM), smoothed by the robust cubic smoothing spline of
  :class:`radartracker.simulation.simulator.RecordedTrajectory` (λ = σ²/q: 20 m noise, 4 m²/s³ manoeuvres;
  reports more than 5 σ̂ off it are left out). A reference position exists only at times no farther than
  :attr:`ReferenceConfig.max_gap_s` from a report: a plot in a longer gap has no reference. The smoothed
  ADS-B carries its own error (about 10–20 m at NACp 8): a radar's random error measured against it is
  √(σ_radar² + σ_ref²), which the report says.
* **reconstruction** (:func:`add_reconstructed`): the aircraft without validated ADS-B, their radar plots grouped
  by Mode S address (or truth label) and reconstructed by a reconstructor plugin (``multi-hypothesis`` by
  default: piecewise-constant controls, docs/reconstruction.md) with the replay's joint bias estimates ς̂ removed
  (z̃ = z − C ς̂, R̃ = R + C Σ Cᵀ); a flight its quality flags call implausible, or one that could not be
  reconstructed, is left out and named (:attr:`Reference.left_out`). The reference then holds the radar's own
  plots: its errors correlate with the radar's, so a random σ measured against it is somewhat too small.

Positions come back geodetic (lat, lon, height), so that every comparison with a radar goes through the
radar's exact polar geometry (:class:`radartracker.geometry.plane.RadarFrame`).
"""

from __future__ import annotations

import functools
import re
from collections.abc import Sequence
from concurrent.futures import Executor
from typing import NamedTuple

import attrs
import numpy as np

from radartracker.errors import ConfigurationError, InputError
from radartracker.geometry.plane import RadarFrame, SystemPlane
from radartracker.io.tables import ScenarioData
from radartracker.pipeline.evaluate import TruthPaths
from radartracker.simulation.simulator import RecordedTrajectory

_ADDRESS = re.compile(r"^[0-9a-f]{6}$")
PLANE_SCALE_BOUND = 1.2  # k of the plane out to 5,700 km from its centre, and the chord's c²/24, with room


@attrs.frozen
class ReferenceConfig:
    """How the ADS-B reference is validated: the least NACp kept, the longest gap between reports across
    which a position is interpolated, and the fewest reports an aircraft needs; whether the aircraft without
    it are reconstructed (``reconstruct``: by the reconstructor plugin ``reconstructor``, those with at least
    ``min_plots`` plots)."""

    min_nacp: int = attrs.field(default=7, validator=[attrs.validators.ge(1), attrs.validators.le(11)])
    max_gap_s: float = attrs.field(default=20.0, validator=attrs.validators.gt(0.0))
    min_reports: int = attrs.field(default=10, validator=attrs.validators.ge(2))
    reconstruct: bool = True
    reconstructor: str = "multi-hypothesis"
    min_plots: int = attrs.field(default=10, validator=attrs.validators.ge(2))


class _Vertices(NamedTuple):
    """:attr:`Reference._vertices`."""

    x: np.ndarray
    y: np.ndarray
    h: np.ndarray
    first: np.ndarray
    step: np.ndarray


@attrs.frozen
class ReferenceTrack:
    """One aircraft's reference: its sample times, a plane trajectory through them, and its identity
    (Mode S address where its key is one; Mode 3/A code where the scenario's aircraft list gives it)."""

    times: np.ndarray
    trajectory: RecordedTrajectory
    icao24: str | None
    mode_3a: str | None
    max_gap_s: float

    def covered(self, t: np.ndarray) -> np.ndarray:
        """Whether each time lies within the span and at most ``max_gap_s`` from a sample."""
        t = np.asarray(t, float)
        i = np.clip(np.searchsorted(self.times, t), 1, len(self.times) - 1)
        gap = np.minimum(np.abs(t - self.times[i - 1]), np.abs(self.times[i] - t))
        return (t >= self.times[0]) & (t <= self.times[-1]) & (gap <= self.max_gap_s)


@attrs.frozen
class Reference:
    """Every aircraft's reference trajectory in ``plane`` (``kind``: ``"truth"``, ``"adsb"``,
    ``"adsb+reconstruction"`` or ``"reconstruction"``); ``left_out``: the aircraft a reconstruction did not give
    a reference, and why."""

    kind: str
    plane: SystemPlane
    tracks: dict[str, ReferenceTrack]
    left_out: dict[str, str] = attrs.field(factory=dict)

    def geodetic(self, keys: Sequence[str], times: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """WGS84 (lat, lon, height m) of each aircraft ``keys[i]`` at its times ``times[i]`` (inside its span),
        concatenated in that order: many aircraft in one projection, whose fixed cost per call outweighs its
        cost per point for the few points of one aircraft."""
        if not len(keys):
            return np.empty(0), np.empty(0), np.empty(0)
        x, y, h = (np.concatenate(v) for v in zip(*(self.tracks[k].trajectory.position(np.asarray(t, float))
                                                    for k, t in zip(keys, times))))
        lat, lon = self.plane.to_geodetic(x, y)
        return lat, lon, h

    def near(self, site_xy: np.ndarray, reach_m: float) -> Reference:
        """The aircraft whose reference may come within slant range ``reach_m`` of a site at plane position
        ``site_xy`` (the others can neither match its plots nor be expected of it): those with a sample at a
        plane distance d ≤ :data:`PLANE_SCALE_BOUND` · reach + L from the site, L their longest step between
        samples. Between two samples the path stays within L of one of them (straight lines; a smoothed one
        departs from its chords by metres); the slant range is at least the ground chord, ρ² = (b − a)² +
        4ab sin²(c/2) ≥ (2R sin(c/2))² for heights ≥ 0 (a, b the geocentric radii, c the central angle),
        which is the ground distance s to 1 − c²/24; and s ≥ d/k, k the stereographic plane's scale, 1 + r²/4R²
        at r from its centre: below the bound out to 5,700 km. Same order of aircraft as ``tracks``."""
        v = self._vertices
        if not len(v.first):
            return self
        closest = np.minimum.reduceat(np.hypot(v.x - site_xy[0], v.y - site_xy[1]), v.first)
        keys = list(self.tracks)
        keep = np.flatnonzero(closest <= PLANE_SCALE_BOUND * reach_m + v.step).tolist()
        return Reference(self.kind, self.plane, {keys[i]: self.tracks[keys[i]] for i in keep})

    def slant_range_bounds(self, frame: RadarFrame, times: Sequence[np.ndarray]) -> list[tuple[np.ndarray, np.ndarray]]:
        """Per aircraft (in the order of ``tracks``), bounds [lo, hi] of the exact slant range from ``frame``'s
        site at each of its ``times`` (inside its span), from the exact ρ at the two samples around it and no
        projection at those times: ρ moves by no more than the path, so ρ(t) lies within min(ρᵢ, ρᵢ₊₁) − Lᵢ
        and max(ρᵢ, ρᵢ₊₁) + Lᵢ, Lᵢ = :data:`PLANE_SCALE_BOUND` · dᵢ + |Δhᵢ| bounding the length of the
        straight step between the samples (dᵢ its plane length, :meth:`near`). A smoothed track's path
        between samples is no straight line: (−∞, ∞)."""
        v = self._vertices
        lat, lon = self.plane.to_geodetic(v.x, v.y)
        rho, _, _ = frame.polar(lat, lon, v.h)
        out = []
        for first, tr, t in zip(v.first.tolist(), self.tracks.values(), times):
            if tr.trajectory.smoothed:
                out.append((np.full(len(t), -np.inf), np.full(len(t), np.inf)))
                continue
            i = first + np.clip(np.searchsorted(tr.times, t), 1, len(tr.times) - 1)
            step = PLANE_SCALE_BOUND * np.hypot(v.x[i] - v.x[i - 1], v.y[i] - v.y[i - 1]) + np.abs(v.h[i] - v.h[i - 1])
            out.append((np.minimum(rho[i - 1], rho[i]) - step, np.maximum(rho[i - 1], rho[i]) + step))
        return out

    @functools.cached_property
    def _vertices(self) -> _Vertices:
        """Every track's position at its sample times (plane x, y and height, m), stacked in the order of
        ``tracks``; the index of each track's first; each track's longest plane step between samples (m):
        what :meth:`near` and :meth:`slant_range_bounds` use, made once per reference."""
        if not self.tracks:
            return _Vertices(np.empty(0), np.empty(0), np.empty(0), np.zeros(0, np.int64), np.empty(0))
        xyh = [tr.trajectory.position(tr.times) for tr in self.tracks.values()]
        step = np.array([float(np.hypot(np.diff(x), np.diff(y)).max()) for x, y, _ in xyh])
        sizes = np.array([len(x) for x, _, _ in xyh])
        x, y, h = (np.concatenate(c) for c in zip(*xyh))
        return _Vertices(x, y, h, np.concatenate([[0], np.cumsum(sizes)[:-1]]), step)

    def window(self, lo: float, hi: float) -> Reference:
        """The aircraft flying during [lo, hi], each cut to its samples there and one either side: the same
        positions and coverage inside [lo, hi] as the whole (straight lines between the same two samples; a
        smoothing spline is kept whole), at a fraction of the size to send to a time slice's task."""
        tracks = {}
        for key, tr in self.tracks.items():
            if tr.times[-1] < lo or tr.times[0] > hi:
                continue
            a = max(int(np.searchsorted(tr.times, lo, "right")) - 1, 0)
            b = min(int(np.searchsorted(tr.times, hi, "left")) + 1, len(tr.times) - 1)
            traj = tr.trajectory
            if not traj.smoothed and b > a:
                traj = RecordedTrajectory(traj.t[a:b + 1], traj.x[a:b + 1], traj.y[a:b + 1], traj.h[a:b + 1],
                                          smooth=False)
            tracks[key] = attrs.evolve(tr, times=tr.times[a:b + 1], trajectory=traj) if b > a else tr
        return Reference(self.kind, self.plane, tracks)

    def paths(self, step_s: float = 1.0) -> TruthPaths:
        """The reference as :class:`TruthPaths` (plane positions and velocities every ``step_s``), for the
        track indicators of :func:`radartracker.pipeline.evaluate.track_metrics`."""
        out = {}
        for key, tr in self.tracks.items():
            grid = np.arange(tr.times[0], tr.times[-1], step_s)  # may end on the last time, or a hair before it
            t = np.append(grid[grid < tr.times[-1] - 0.5 * step_s], tr.times[-1])
            x, y, _ = tr.trajectory.position(t)
            p = np.stack([x, y], axis=-1)
            out[key] = (t, p, np.gradient(p, t, axis=0) if len(t) > 1 else np.zeros_like(p))
        return TruthPaths(out)


def build_reference(data: ScenarioData, config: ReferenceConfig | None = None) -> Reference:
    """The truth of ``data`` where it has one, else its validated ADS-B (module docstring); an InputError
    when it has neither."""
    config = config or ReferenceConfig()
    plane = SystemPlane(*data.reference)
    codes = {a.icao24: a.mode_3a for a in data.aircraft}
    if data.truth is not None and len(data.truth):
        tr = data.truth
        x, y = plane.to_plane(tr.lat, tr.lon)
        tracks = _tracks(tr.target.astype(str), tr.time, x, y, tr.altitude_m, codes, np.inf, smooth=False)
        return Reference("truth", plane, tracks)
    a = data.adsb
    keep = (a.nacp >= config.min_nacp) & np.isfinite(a.altitude_m)
    if config.reconstruct and not keep.any():  # every aircraft to be reconstructed (add_reconstructed)
        return Reference("adsb", plane, {})
    if not keep.any():
        raise InputError(f"scenario {data.name!r}: no truth.csv and no ADS-B report of NACp ≥ {config.min_nacp} "
                         "with an altitude: nothing to judge the radars against")
    x, y = plane.to_plane(a.lat[keep], a.lon[keep])
    tracks = _tracks(a.icao24[keep].astype(str), a.time[keep], x, y, a.altitude_m[keep], codes, config.max_gap_s,
                     smooth=True, min_reports=config.min_reports)
    return Reference("adsb", plane, tracks)


def reconstructor(config: ReferenceConfig):
    """The reconstructor plugin ``config.reconstructor``, made with its defaults; a ConfigurationError when it is not
    installed or cannot reconstruct a scenario's flights (it has no ``flights(data, biases, *, exclude, min_plots,
    progress)``, docs/plugins.md)."""
    from radartracker.registry import load_reconstructor

    made = load_reconstructor(config.reconstructor)()
    if not callable(getattr(made, "flights", None)):
        raise ConfigurationError(f"reconstructor {config.reconstructor!r} has no flights(): it cannot give an "
                                 "assessment its reference")
    return made


def add_reconstructed(reference: Reference, data: ScenarioData, biases: dict[str, tuple[np.ndarray, np.ndarray]],
                      config: ReferenceConfig, progress: bool = False, executor: Executor | None = None,
                      groups: np.ndarray | None = None) -> Reference:
    """``reference`` and the reconstruction of every other aircraft of ``data`` (module docstring), the radar
    biases ``biases`` (radar → (ς̂ = [Δr m, Δθ rad], 2×2 covariance)) removed, the flights on ``executor`` (this
    process when None), the plots grouped into aircraft by ``groups`` (each plot's key,
    :func:`radartracker.assessment.grouping.plot_groups`) when given, else by Mode S address or truth label; an InputError when no aircraft has a reference then. Each reconstruction's geometric
    track (1 s apart) is joined by straight lines."""
    codes = {a.icao24: a.mode_3a for a in data.aircraft}
    tracks, left = dict(reference.tracks), {}
    flights = reconstructor(config).flights(data, biases, exclude=set(tracks), min_plots=config.min_plots,
                                            groups=groups, progress=progress, executor=executor)
    for f in flights:
        if f.verdict != "plausible" or len(f.time) < 2:
            left[f.key] = f.verdict
            continue
        address = f.key if _ADDRESS.match(f.key) else None
        tracks[f.key] = ReferenceTrack(f.time, RecordedTrajectory(f.time, f.x, f.y, f.h, smooth=False), address,
                                       codes.get(address), np.inf)
    if not tracks:
        raise InputError(f"scenario {data.name!r}: no validated ADS-B and no aircraft reconstructed "
                         f"({len(left)} left out): nothing to judge the radars against")
    added = len(tracks) - len(reference.tracks)
    kind = reference.kind if not added else "reconstruction" if not reference.tracks else f"{reference.kind}+reconstruction"
    return Reference(kind, reference.plane, dict(sorted(tracks.items())), left)


def _tracks(keys: np.ndarray, t: np.ndarray, x: np.ndarray, y: np.ndarray, h: np.ndarray, codes: dict,
            max_gap_s: float, *, smooth: bool, min_reports: int = 2) -> dict[str, ReferenceTrack]:
    """One :class:`ReferenceTrack` per key with at least ``min_reports`` samples at distinct times."""
    out = {}
    order = np.lexsort((t, keys))
    keys, t, x, y, h = keys[order], t[order], x[order], y[order], h[order]
    names, first = np.unique(keys, return_index=True)
    for name, idx in zip(names.tolist(), np.split(np.arange(len(keys)), first[1:])):
        ti = t[idx]
        distinct = np.concatenate([[True], np.diff(ti) > 0])
        idx = idx[distinct]
        if len(idx) < min_reports:
            continue
        traj = RecordedTrajectory(t[idx], x[idx], y[idx], h[idx], smooth=smooth)
        address = name if _ADDRESS.match(name) else None
        out[name] = ReferenceTrack(t[idx], traj, address, codes.get(address), max_gap_s)
    return out
