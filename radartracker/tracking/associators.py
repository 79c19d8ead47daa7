"""The associator contract: which track each of a radar's plots in a frame belongs to.

An associator is a ``radartracker.associators`` plugin (entry points, like estimators and motion
models). The TrackManager calls :meth:`Associator.associate` once per radar with plots in the frame, in
the radars' order, with that radar's plots in the plane (:class:`RadarPlots`) and the live tracks
predicted to the frame (:class:`~radartracker.tracking.frame.Prediction`); the answer
(:class:`Association`) gives, per plot, the index of its track, :data:`NEW_TRACK` (start a tentative
track) or :data:`REFUSED` with a named reason (counted by the manager). A track takes at most one plot of
a radar in a frame (one antenna sweep). Screening, the filters and the life cycle are the manager's: the
associator only decides where each plot goes.
"""

from __future__ import annotations

import abc
from typing import ClassVar, NamedTuple

import attrs
import numpy as np

from radartracker.domain import Plot
from radartracker.estimation.base import PlaneMeasurement
from radartracker.tracking.association import assign, candidate_pairs, gate_costs
from radartracker.tracking.frame import Prediction

NEW_TRACK = -1
REFUSED = -2


@attrs.frozen
class AssociationSettings:
    """What every associator is given: ``gate`` (χ²₂ quantile of d² for a plot-track pair),
    ``search_radius_m`` (candidates within it of a track's predicted position) and
    ``new_track_exclusion`` (χ²₂: a plot this close to a confirmed track that is not its plot starts no
    track)."""

    gate: float = 13.82
    search_radius_m: float = 25_000.0
    new_track_exclusion: float = 27.63


@attrs.frozen
class RadarPlots:
    """One radar's plots of a frame: the inputs ``plots`` and, row for row, their plane measurement z (n×2)
    with C_s (n×2×2) and R (n×2×2), ``valid`` (a possible geometry), and the radar's bias estimate
    (``bias`` ς̂, ``bias_cov`` P_ς) as the frame reads it. Times are the plots' own."""

    radar: str
    plots: list[Plot]
    z: np.ndarray
    C: np.ndarray
    R: np.ndarray
    valid: np.ndarray
    bias: np.ndarray
    bias_cov: np.ndarray

    @property
    def time(self) -> np.ndarray:
        return np.array([p.time for p in self.plots], float)


class Association(NamedTuple):
    """Per plot: ``track[k]`` the index of its track in the prediction, :data:`NEW_TRACK` or :data:`REFUSED`
    (then ``reasons[k]`` names why, e.g. ``plots_near_confirmed_track``)."""

    track: np.ndarray
    reasons: dict[int, str]


class Associator(abc.ABC):
    """Assigns a radar's plots of a frame to tracks (module docstring). Subclasses set ``name`` and
    implement :meth:`associate`; they are built with the run's :class:`AssociationSettings`."""

    name: ClassVar[str] = "?"
    labels: ClassVar[bool] = False  # True: tracks carry their first plot's truth label, recorded as events' target

    def __init__(self, settings: AssociationSettings | None = None) -> None:
        self.settings = settings or AssociationSettings()

    @abc.abstractmethod
    def associate(self, plots: RadarPlots, tracks: Prediction) -> Association:
        """Where each of ``plots`` goes among ``tracks`` (see :class:`Association`)."""


def associate_position(m: PlaneMeasurement, tracks: Prediction, gate: float, search_radius_m: float) -> int | None:
    """The track of an unbiased position (e.g. a triangulated fix): by its Mode S key when it has one,
    else the nearest track in gate by d² against the filters' predictions; None: a new track."""
    if m.aircraft is not None:
        return tracks.by_mode_s.get(m.aircraft) if isinstance(m.aircraft, str) else None
    pairs = candidate_pairs(np.asarray(m.z, float)[None, :], tracks.position, search_radius_m)
    if not len(pairs):
        return None
    pos, vel, cov = tracks.exact(pairs[:, 1])
    n = len(pairs)
    d2, cost = gate_costs(np.repeat(np.asarray(m.z, float)[None], n, 0), np.zeros((n, 2, 2)),
                          np.repeat(np.asarray(m.R, float)[None], n, 0), np.zeros(2), np.zeros((2, 2)),
                          pos + vel * (m.time - tracks.time), cov)
    best = dict(assign(pairs, d2, cost, gate))
    return best.get(0)
