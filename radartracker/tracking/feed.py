"""The estimator feed: a frame's work for the bias estimator plugin and the coupling graph, as typed
operations applied in the order they arose at the frame's end.

The manager's screening, gating and track filters correct every measurement of a frame with the bias
estimate (ς̂, P_ς) as it was at the frame's start (docs/design-notes.md, "The TrackManager reads the bias
estimate once per frame"): :meth:`EstimatorFeed.bias` reads each radar's :class:`BiasState` once per
frame (components the data do not inform held at their prior: :mod:`radartracker.estimation.observability`),
and the estimator changes only in :meth:`EstimatorFeed.flush`. There an aircraft is added when its
track is confirmed (:class:`AddAircraft`), each run of raw measurements z = C_x χ + C_s ς + w of
confirmed tracks goes to ``Estimator.update_many`` (:class:`Measure`), and an aircraft is removed when
its track ends (:class:`RemoveAircraft`).
"""

from __future__ import annotations

import itertools
import logging
from collections import Counter
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from radartracker.domain import BiasState
from radartracker.errors import PluginError
from radartracker.estimation.base import Estimator
from radartracker.estimation.coupling import CouplingGraph
from radartracker.estimation.kalman import SingularInnovation
from radartracker.estimation.observability import held_at_prior

log = logging.getLogger(__name__)
_ZERO2, _ZERO22 = np.zeros(2), np.zeros((2, 2))
_USED = {k: f"{k}_used" for k in ("plots", "adsb", "positions")}


class AddAircraft(NamedTuple):
    time: float
    aircraft: int
    state: np.ndarray
    cov: np.ndarray


class Measure(NamedTuple):
    time: float
    aircraft: int
    radar: str | None
    z: np.ndarray
    C: np.ndarray
    R: np.ndarray
    kind: str  # "plots", "adsb" or "positions": counted as "<kind>_used"


class RemoveAircraft(NamedTuple):
    time: float
    aircraft: int


Operation = AddAircraft | Measure | RemoveAircraft
PluginFailure = Callable[[str, "int | None", float, Exception], PluginError]


class EstimatorFeed:
    """Queues a frame's :data:`Operation` s and applies them to ``estimator`` and ``coupling`` (module
    docstring); measurements used are counted in ``counts``. ``failed(plugin, track, time, exc)`` makes
    the error a plugin's exception ends the run with; ``on_nis``, when set, is given the estimator's
    normalised innovations νᵀΛ⁻¹ν of each batch (for the χ² consistency of a run)."""

    def __init__(self, estimator: Estimator, coupling: CouplingGraph, counts: Counter, failed: PluginFailure) -> None:
        self.estimator = estimator
        self.coupling = coupling
        self.counts = counts
        self.failed = failed
        self.pending: list[Operation] = []
        self.on_nis: Callable[[np.ndarray], None] | None = None  # given each update_many's NIS values
        # each radar's state since the last flush (the estimator and the coupling graph change only there), and
        # its prior covariance (the estimator's config does not change)
        self._states: dict[str, BiasState] = {}
        self._priors: dict[str, np.ndarray] = {}

    def state(self, radar: str) -> BiasState:
        """``radar``'s bias estimate as the manager uses and reports it: the estimator's, with the components
        the data do not inform (the radar isolated in the coupling graph, or a variance still near the prior's)
        held at their prior (:func:`~radartracker.estimation.observability.held_at_prior`)."""
        state = self._states.get(radar)
        if state is None:
            est = self.estimator
            prior = self._priors.get(radar)
            if prior is None:
                prior = self._priors[radar] = est.config.sensor(radar).prior()
            state = self._states[radar] = held_at_prior(est.bias(radar), prior, self.coupling.isolated(radar))
        return state

    def forget(self) -> None:
        """Read the estimator and the coupling graph again at the next :meth:`state` (after a flush, or once
        their state was loaded from a snapshot)."""
        self._states = {}

    def bias(self, radar: str | None) -> tuple[np.ndarray, np.ndarray]:
        """(ς̂, P_ς) of ``radar`` (:meth:`state`) as at the frame's start (zeros for an unbiased source,
        ``None``)."""
        if radar is None:
            return _ZERO2, _ZERO22
        state = self.state(radar)
        return np.asarray(state.bias, float), np.asarray(state.cov, float)

    def add(self, op: Operation) -> None:
        self.pending.append(op)

    def flush(self) -> None:
        """Apply the queued operations in order, each run of measurements in one ``update_many``."""
        ops, self.pending = self.pending, []
        try:
            self._apply(ops)
        finally:  # the estimator and the coupling graph have changed
            self.forget()

    def _apply(self, ops: list[Operation]) -> None:
        """``ops`` in order (:meth:`flush`)."""
        name = f"estimator {self.estimator.name!r}"
        for kind, group in itertools.groupby(ops, type):
            if kind is Measure:
                self._measure(list(group))
                continue
            for op in group:
                try:
                    if kind is AddAircraft:
                        self.estimator.add_aircraft(op.aircraft, op.time, op.state, op.cov)
                    else:
                        self.estimator.remove_aircraft(op.aircraft)
                except Exception as exc:
                    raise self.failed(name, op.aircraft, op.time, exc) from exc
                if kind is AddAircraft:
                    self.coupling.add_aircraft(op.aircraft)
                else:
                    self.coupling.remove_aircraft(op.aircraft)

    def _measure(self, run: list[Measure]) -> None:
        """``run`` to the estimator in one ``update_many``; a measurement it refuses as singular is counted
        (``<kind>_singular``) and the rest of the run goes on after it."""
        while run:
            time, aircraft, radar, z, C, R, kind = zip(*run)
            done = n = len(run)
            try:
                innovation = self.estimator.update_many(time, aircraft, radar, np.array(z, float),
                                                        np.array(C, float), np.array(R, float))
            except SingularInnovation as exc:
                done = getattr(exc, "index", 0)
                log.warning("estimator refused a measurement of track %s: %s", aircraft[done], exc)
            except Exception as exc:
                i = getattr(exc, "index", 0)
                raise self.failed(f"estimator {self.estimator.name!r}", aircraft[i], time[i], exc) from exc
            if done == n and self.on_nis is not None and innovation is not None:
                self.on_nis(np.asarray(innovation.nis, float))
            self.coupling.observe_many(aircraft[:done], radar[:done], time[:done])
            for k, c in Counter(kind[:done]).items():
                self.counts[_USED[k]] += c
            if done < n:
                self.counts[f"{kind[done]}_singular"] += 1
                done += 1
            run = run[done:]
