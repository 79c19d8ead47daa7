"""The one recorder both associations feed: track events (with state, covariance and identity),
bias estimates over time and innovation statistics, collected as columns.

Track estimates are the events of kind ``confirmed`` and ``updated`` (:data:`TRACK_KINDS`): the state
just after a measurement was used. Each radar's bias is recorded after one of its plots at most once
per ``bias_log_interval_s``.
"""

from __future__ import annotations

import math

import attrs
import numpy as np

from radartracker.domain import BiasState

TRACK_KINDS = ("confirmed", "updated")


def _obj(values: list) -> np.ndarray:
    arr = np.empty(len(values), object)
    arr[:] = values
    return arr


@attrs.frozen
class Events:
    """Track events as columns: time (s), track id (int), kind, status, state χ = [x, y, vx, vy] (N, 4),
    covariance (N, 4, 4; NaN where not known), last reported altitude (m, NaN if none), Mode S address,
    Mode 3/A code, and the evaluation target (truth label on the labelled path, else ``None``)."""

    time: np.ndarray
    track: np.ndarray
    kind: np.ndarray
    status: np.ndarray
    state: np.ndarray
    cov: np.ndarray
    altitude_m: np.ndarray
    mode_s: np.ndarray
    mode_3a: np.ndarray
    target: np.ndarray

    def __len__(self) -> int:
        return len(self.time)

    def take(self, mask: np.ndarray) -> Events:
        return Events(**{f.name: getattr(self, f.name)[mask] for f in attrs.fields(Events)})

    def estimates(self) -> Events:
        """The track estimates (``confirmed`` and ``updated`` events)."""
        return self.take(np.isin(self.kind.astype(str), TRACK_KINDS))


@attrs.frozen
class BiasLog:
    """Bias estimates over time: time (s), radar, ς = [Δr m, Δθ rad] (N, 2), covariance (N, 2, 2)."""

    time: np.ndarray
    radar: np.ndarray
    value: np.ndarray
    cov: np.ndarray


class Recorder:
    """Collects a run's events, bias estimates and NIS values (see the module docstring)."""

    def __init__(self, bias_log_interval_s: float = 1.0) -> None:
        self.bias_log_interval_s = bias_log_interval_s
        self._ev: list[tuple] = []
        self._bias: list[tuple] = []
        self._bias_last: dict[str, float] = {}
        self.nis: list[float] = []

    def event(self, time: float, track: int, kind: str, status: str, state: np.ndarray, cov: np.ndarray | None,
              altitude_m: float | None, mode_s: str | None, mode_3a: str | None, target: object = None) -> None:
        self._ev.append((float(time), int(track), kind, status, np.asarray(state, float),
                         np.full((4, 4), np.nan) if cov is None else np.asarray(cov, float),
                         math.nan if altitude_m is None else float(altitude_m), mode_s, mode_3a, target))

    def bias(self, time: float, state: BiasState) -> None:
        """Record ``state`` unless this radar was recorded less than the interval before ``time``."""
        if time - self._bias_last.get(state.radar, -math.inf) >= self.bias_log_interval_s:
            self._bias.append((float(time), state.radar, np.asarray(state.bias, float), np.asarray(state.cov, float)))
            self._bias_last[state.radar] = time

    def events(self) -> Events:
        cols = list(zip(*self._ev)) if self._ev else [[]] * 10
        return Events(time=np.array(cols[0], float), track=np.array(cols[1], int), kind=_obj(list(cols[2])),
                      status=_obj(list(cols[3])), state=np.array(cols[4], float).reshape(-1, 4),
                      cov=np.array(cols[5], float).reshape(-1, 4, 4), altitude_m=np.array(cols[6], float),
                      mode_s=_obj(list(cols[7])), mode_3a=_obj(list(cols[8])), target=_obj(list(cols[9])))

    def biases(self) -> BiasLog:
        cols = list(zip(*self._bias)) if self._bias else [[]] * 4
        return BiasLog(np.array(cols[0], float), _obj(list(cols[1])), np.array(cols[2], float).reshape(-1, 2),
                       np.array(cols[3], float).reshape(-1, 2, 2))
