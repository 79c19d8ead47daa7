"""A frame: the inputs released for one ``frame_s`` interval, in the plane, and the live tracks' prediction.

:class:`FrameBuilder` turns a frame's inputs into one :class:`Frame`: its plots radar by radar, its ADS-B
reports and its unbiased positions, each a row of one :class:`FrameMeasurements` (time, z, C_s, R, radar
row), converted in one pass (:class:`~radartracker.tracking.prepared.PlaneConverter`). A plot is converted
at its Mode C altitude, else at its Mode S track's, else at ``primary_altitude_m`` with that guess's spread
added to R (:func:`~radartracker.tracking.association.altitude_spread`); an ADS-B report has
R = σ(NACp)² I and C_s = 0; an unbiased position comes with its own R and C_s = 0.

A plot is linearised at its radar's bias estimate of the frame's start ς̂ = (Δr̂, Δθ̂): converted at
(ρ − Δr̂, θ − Δθ̂), with C_s taken there, and given as z = f(ρ − Δr̂, θ − Δθ̂) + C_s ς̂, so that
z − C_s ς = p + C_s (ς̂ − ς) + … is exact at ς = ς̂ and the bias correction z − C_s ς̂ is the plot converted
without its bias. Converting at (ρ, θ) instead (C_s at the biased plot) leaves an error of order
ς² in the model, which a 2 km / 2° bias turns into tens of metres and hundredths of a degree that no
estimator can see (docs/design-notes.md).

:class:`Prediction` is what association, misses and deletion read of the live tracks at the frame's
middle time: their straight-line positions for search and coverage, and the filters' own predictions
(position, velocity, position covariance) computed only for the tracks a plot may go to.
"""

from __future__ import annotations

import functools
import itertools
from collections.abc import Callable
from operator import attrgetter, methodcaller
from typing import NamedTuple

import attrs
import numpy as np

from radartracker.domain import AdsbReport, Plot
from radartracker.estimation.base import PlaneMeasurement
from radartracker.tracking.association import altitude_spread
from radartracker.tracking.prepared import PlaneConverter
from radartracker.tracking.track import Track

_TIME, _RANGE, _AZIMUTH, _ALTITUDE = (attrgetter(f) for f in ("time", "range_m", "azimuth_rad", "altitude_m"))
_LAT, _LON, _NACP = attrgetter("lat"), attrgetter("lon"), attrgetter("nacp")
Input = Plot | AdsbReport | PlaneMeasurement
_ROW_BYTES = methodcaller("estimate_bytes")


class FrameMeasurements(NamedTuple):
    """Measurements in the plane, one row each: time (n), z (n×2), C_s (n×2×2, 0 for an unbiased sensor),
    R (n×2×2) and the radar's row in the manager's radars (−1: unbiased)."""

    time: np.ndarray
    z: np.ndarray
    C: np.ndarray
    R: np.ndarray
    radar: np.ndarray

    def rows(self) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """Each row's (z, C_s, R) as views, made in one pass (the life cycle reads one per update)."""
        return list(zip(self.z, self.C, self.R))


@attrs.frozen
class Frame:
    """The inputs of [``start``, ``end``) and their measurements: rows ``radar_rows[rid]`` are radar
    ``rid``'s plots in arrival order, then come the ADS-B reports, then the unbiased positions.
    ``valid``: which plots have a possible geometry; ``azimuth``: the plots' azimuths (rad); ``height``: the
    height each plot was converted at (m), ``guessed``: which of them were assumed (``primary_altitude_m``);
    ``linearised_at``: the bias estimate (Δr̂ m, Δθ̂ rad) each plot was converted at (module docstring)."""

    start: float
    end: float
    plots: list[Plot]
    radar_rows: dict[str, range]
    reports: list[AdsbReport]
    positions: list[PlaneMeasurement]
    meas: FrameMeasurements
    valid: np.ndarray
    azimuth: np.ndarray
    height: np.ndarray
    guessed: np.ndarray
    linearised_at: np.ndarray

    @property
    def first_report_row(self) -> int:
        return len(self.plots)

    @property
    def first_position_row(self) -> int:
        return len(self.plots) + len(self.reports)


class FrameBuilder:
    """Makes a :class:`Frame` of a frame's inputs (module docstring)."""

    def __init__(self, converter: PlaneConverter, primary_altitude_m: float, primary_altitude_sd_m: float,
                 bias: Callable[[str], tuple[np.ndarray, np.ndarray]] | None = None) -> None:
        self.converter = converter
        self.primary_altitude_m = primary_altitude_m
        self.primary_altitude_sd_m = primary_altitude_sd_m
        self.bias = bias  # a radar's (ς̂, P_ς) of the frame's start; None: plots linearised at ς̂ = 0

    def build(self, start: float, end: float, items: list[Input], tracks: list[Track]) -> Frame:
        by_radar: dict[str, list[Plot]] = {}
        reports: list[AdsbReport] = []
        positions: list[PlaneMeasurement] = []
        for item in items:
            if isinstance(item, Plot):
                by_radar.setdefault(item.radar, []).append(item)
            elif isinstance(item, AdsbReport):
                reports.append(item)
            else:
                positions.append(item)
        plots = list(itertools.chain.from_iterable(by_radar.values()))
        radar_rows, base = {}, 0
        for rid, ps in by_radar.items():
            radar_rows[rid], base = range(base, base + len(ps)), base + len(ps)
        z, C, R, radar, valid, theta, alt, guessed, at = self._convert(by_radar, plots, reports, tracks)
        if positions:
            n = len(positions)
            z = np.concatenate([z, np.array([np.asarray(p.z, float) for p in positions]).reshape(n, 2)])
            C = np.concatenate([C, np.zeros((n, 2, 2))])
            R = np.concatenate([R, np.array([np.asarray(p.R, float) for p in positions]).reshape(n, 2, 2)])
            radar = np.concatenate([radar, np.full(n, -1, np.int64)])
        times = np.fromiter(map(_TIME, itertools.chain(plots, reports, positions)), float, len(z))
        return Frame(start, end, plots, radar_rows, reports, positions, FrameMeasurements(times, z, C, R, radar),
                     valid, theta, alt, guessed, at)

    def _heights(self, plots: list[Plot], tracks: list[Track]) -> tuple[np.ndarray, np.ndarray]:
        """Each plot's height for the conversion, and which were guessed (``primary_altitude_m``)."""
        heights = list(map(_ALTITUDE, plots))
        guessed = np.zeros(len(plots), bool)
        if None in heights:
            by_code = {t.mode_s: h for t in tracks if t.mode_s and (h := t.reported_altitude_m) is not None}
            for k, (h, p) in enumerate(zip(heights, plots)):
                if h is None:
                    h = by_code.get(p.mode_s) if p.mode_s else None
                    heights[k], guessed[k] = (h, False) if h is not None else (self.primary_altitude_m, True)
        return np.array(heights, float), guessed

    def _convert(self, by_radar: dict[str, list[Plot]], plots: list[Plot], reports: list[AdsbReport],
                 tracks: list[Track]) -> tuple[np.ndarray, ...]:
        """(z, C, R, radar row, valid, azimuth, conversion height, guessed, ς̂ each plot is linearised at) of the
        plots and ADS-B reports, in one pass (module docstring)."""
        n, m, k = len(plots), len(reports), len(by_radar)
        alt, guessed = self._heights(plots, tracks)
        counts = np.fromiter(map(len, by_radar.values()), np.int64, k)
        at = np.repeat(np.array([self._estimate(rid) for rid in by_radar], float).reshape(k, 2), counts, axis=0)
        rho = np.fromiter(map(_RANGE, plots), float, n)
        theta = np.fromiter(map(_AZIMUTH, plots), float, n)
        conv = self.converter
        z, C, R, radar, valid = conv.convert_frame(
            np.fromiter(map(conv.row.__getitem__, by_radar), np.int64, k), counts, rho, theta, alt,
            np.fromiter(map(_LAT, reports), float, m), np.fromiter(map(_LON, reports), float, m),
            np.fromiter(map(_NACP, reports), np.int64, m), at=at)
        if guessed.any():  # an assumed altitude is uncertain: near the radar its error moves the plot along the beam
            R[:n][guessed] += altitude_spread(C[:n][guessed], (rho - at[:, 0])[guessed], alt[guessed],
                                              conv.height[radar[:n][guessed]], self.primary_altitude_sd_m)
        return z, C, R, radar, valid, theta, alt, guessed, at

    def _estimate(self, radar: str) -> np.ndarray:
        """ς̂ = (Δr̂, Δθ̂) of ``radar`` a frame's plots are linearised at."""
        return np.zeros(2) if self.bias is None else np.asarray(self.bias(radar)[0], float)[:2]


class Prediction:
    """The live tracks at time ``time`` (module docstring): ``tracks`` in the manager's order,
    ``position`` their straight-line positions (n×2), ``by_mode_s`` the index of each Mode S address."""

    def __init__(self, tracks: list[Track], time: float) -> None:
        self.tracks = tracks
        self.time = time
        n = len(tracks)
        # each track's (t₀, x, y, vx, vy): five float64 each, joined (one object a track, not six)
        table = np.frombuffer(b"".join(map(_ROW_BYTES, tracks)), float).reshape(n, 5)
        # p + v max(t − t₀, 0): the straight line, never backwards
        self.position = table[:, 1:3] + table[:, 3:] * np.maximum(time - table[:, 0], 0.0)[:, None]
        self.by_mode_s = {tr.mode_s: i for i, tr in enumerate(tracks) if tr.mode_s}
        self._exact: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}

    def __len__(self) -> int:
        return len(self.tracks)

    @functools.cached_property
    def mode_3a(self) -> np.ndarray:
        """Each track's Mode 3/A code (object array, None where unknown)."""
        codes = np.empty(len(self.tracks), object)
        codes[:] = [tr.mode_3a for tr in self.tracks]
        return codes

    @functools.cached_property
    def identified(self) -> np.ndarray:
        """Which tracks have a Mode S address."""
        return np.array([tr.mode_s is not None for tr in self.tracks], bool).reshape(len(self.tracks))

    @functools.cached_property
    def tentative(self) -> np.ndarray:
        """Which tracks are tentative (association serves confirmed and coasting tracks first)."""
        return np.array([tr.status == "tentative" for tr in self.tracks], bool).reshape(len(self.tracks))

    def exact(self, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The filters' predictions (position, velocity, position covariance) of tracks ``idx`` to
        :attr:`time` (or to their estimate's time, if later); a filter that refuses the step gives a NaN
        position, so the track gates nothing."""
        cache = self._exact
        for i in np.unique(idx).tolist():
            if i not in cache:
                tr = self.tracks[i]
                try:
                    x, P = tr.filter.predict(max(self.time, tr.estimate()[0]))
                    cache[i] = (x[:2], x[2:4], P[:2, :2])
                except ValueError:
                    cache[i] = (np.full(2, np.nan), np.zeros(2), np.eye(2))
        return tuple(np.array([cache[i][k] for i in idx.tolist()], float).reshape(len(idx), *((2,) if k < 2 else (2, 2)))
                     for k in range(3))
