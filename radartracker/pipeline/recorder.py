"""The one recorder both associations feed: track events (with state, covariance and identity),
bias estimates over time and innovation statistics, collected as columns.

Track estimates are the events of kind ``confirmed`` and ``updated`` (:data:`TRACK_KINDS`): the state
just after a measurement was used. Each radar's bias is recorded after one of its plots at most once
per ``bias_log_interval_s``.
"""

from __future__ import annotations

import math
from array import array

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

    def estimate_mask(self) -> np.ndarray:
        """Which events are track estimates (``confirmed`` and ``updated``)."""
        return np.fromiter((k in TRACK_KINDS for k in self.kind.tolist()), bool, len(self.kind))

    def estimates(self) -> Events:
        """The track estimates (``confirmed`` and ``updated`` events)."""
        return self.take(self.estimate_mask())


@attrs.frozen
class BiasLog:
    """Bias estimates over time: time (s), radar, ς = [Δr m, Δθ rad] (N, 2), covariance (N, 2, 2)."""

    time: np.ndarray
    radar: np.ndarray
    value: np.ndarray
    cov: np.ndarray


_NAN16 = np.full(16, math.nan).tobytes()  # the covariance of an event without one
FLUSH_EVERY = 8192  # rows handed to the sink at a time


class Recorder:
    """Collects a run's events, bias estimates and NIS values (see the module docstring).

    Numbers go to flat ``array('d')`` buffers (8 bytes each, no object per event): a national-scale run
    records millions of events. With a ``sink`` (:class:`radartracker.pipeline.writer.OutputStream`)
    events and biases are handed on every ``flush_every`` rows as they come; ``keep=False`` then drops
    them once handed on, so that memory does not grow with the recording's length (what
    :attr:`track_ids` keeps, one integer per track with an estimate, grows with the number of tracks).
    """

    def __init__(self, bias_log_interval_s: float = 1.0, *, sink=None, keep: bool = True,
                 flush_every: int | None = None) -> None:
        self.bias_log_interval_s = bias_log_interval_s
        self.sink, self.keep, self.flush_every = sink, keep or sink is None, flush_every or FLUSH_EVERY
        self._num = {k: array("d") for k in ("time", "state", "cov", "altitude_m")}
        self._track = array("q")
        self._obj: dict[str, list] = {k: [] for k in ("kind", "status", "mode_s", "mode_3a", "target")}
        self._bias: list[tuple] = []
        self._bias_last: dict[str, float] = {}
        self._sent = [0, 0]  # events and bias rows already handed to the sink
        self.track_ids: set[int] = set()
        self.nis: list[float] = []

    def event(self, time: float, track: int, kind: str, status: str, state, cov: np.ndarray | None,
              altitude_m: float | None, mode_s: str | None, mode_3a: str | None, target: object = None) -> None:
        """Record one event: ``state`` a tuple of four floats or an array (its first four values), ``cov``
        a 4×4 array or ``None`` (recorded as NaN). Numbers are copied as bytes, not one numpy scalar each."""
        n = self._num
        n["time"].append(time)
        if type(state) is tuple:
            n["state"].extend(state[:4])
        else:
            n["state"].frombytes(np.asarray(state, float).ravel()[:4].tobytes())
        n["cov"].frombytes(_NAN16 if cov is None else np.asarray(cov, float).tobytes())
        n["altitude_m"].append(math.nan if altitude_m is None else altitude_m)
        self._track.append(track)
        o = self._obj
        o["kind"].append(kind)
        o["status"].append(status)
        o["mode_s"].append(mode_s)
        o["mode_3a"].append(mode_3a)
        o["target"].append(target)
        if kind in TRACK_KINDS:
            self.track_ids.add(track)
        if self.sink is not None and len(self._track) - self._sent[0] >= self.flush_every:
            self.flush()

    def bias_due(self, radar: str, time: float) -> bool:
        """Whether :meth:`bias` would record ``radar``'s bias at ``time`` (ask before building the state)."""
        return time - self._bias_last.get(radar, -math.inf) >= self.bias_log_interval_s

    def bias(self, time: float, state: BiasState) -> None:
        """Record ``state`` unless this radar was recorded less than the interval before ``time``."""
        if self.bias_due(state.radar, time):
            self._bias.append((float(time), state.radar, np.asarray(state.bias, float), np.asarray(state.cov, float)))
            self._bias_last[state.radar] = time
            if self.sink is not None and len(self._bias) - self._sent[1] >= self.flush_every:
                self.flush()

    def flush(self) -> None:
        """Hand the events and bias rows not yet handed on to the sink (dropping them unless ``keep``)."""
        if self.sink is None:
            return
        self.sink.events(self.events(self._sent[0]))
        self.sink.biases(self.biases(self._sent[1]))
        if self.keep:
            self._sent = [len(self._track), len(self._bias)]
            return
        for buf in (*self._num.values(), self._track):
            del buf[:]
        for col in self._obj.values():
            col.clear()
        self._bias.clear()

    def events(self, start: int = 0) -> Events:
        """The events recorded (from the ``start``-th of those held)."""
        n, o = self._num, self._obj
        return Events(time=np.array(n["time"][start:], float), track=np.array(self._track[start:], int),
                      kind=_obj(o["kind"][start:]), status=_obj(o["status"][start:]),
                      state=np.array(n["state"][4 * start:], float).reshape(-1, 4),
                      cov=np.array(n["cov"][16 * start:], float).reshape(-1, 4, 4),
                      altitude_m=np.array(n["altitude_m"][start:], float), mode_s=_obj(o["mode_s"][start:]),
                      mode_3a=_obj(o["mode_3a"][start:]), target=_obj(o["target"][start:]))

    def biases(self, start: int = 0) -> BiasLog:
        rows = self._bias[start:]
        cols = list(zip(*rows)) if rows else [[]] * 4
        return BiasLog(np.array(cols[0], float), _obj(list(cols[1])), np.array(cols[2], float).reshape(-1, 2),
                       np.array(cols[3], float).reshape(-1, 2, 2))
