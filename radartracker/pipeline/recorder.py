"""The one recorder both associations feed: track events (with state, covariance and identity),
bias estimates over time and innovation statistics, collected as columns.

Track estimates are the events of kind ``confirmed`` and ``updated`` (:data:`TRACK_KINDS`): the state
just after a measurement was used. Each radar's bias is recorded after one of its plots at most once
per ``bias_log_interval_s``.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import attrs
import numpy as np

from radartracker.domain import BiasState
from radartracker.tracking.events import ENDS
from radartracker.tracking.track import NO_COVARIANCE

TRACK_KINDS = ("confirmed", "updated")


def _obj(values: list) -> np.ndarray:
    arr = np.empty(len(values), object)
    arr[:] = values
    return arr


@attrs.frozen
class Events:
    """Track events as columns: time (s), track id (int), kind, status, state χ = [x, y, vx, vy] (N, 4),
    covariance (N, 4, 4; NaN where not known), altitude (m: the last reported, or the estimated height; NaN
    if none) and its σ (m, NaN if none), Mode S address, Mode 3/A code, and the evaluation target (truth
    label on the labelled path, else ``None``)."""

    time: np.ndarray
    track: np.ndarray
    kind: np.ndarray
    status: np.ndarray
    state: np.ndarray
    cov: np.ndarray
    altitude_m: np.ndarray
    altitude_sd_m: np.ndarray
    mode_s: np.ndarray
    mode_3a: np.ndarray
    target: np.ndarray

    def __len__(self) -> int:
        return len(self.time)

    def take(self, mask: np.ndarray) -> Events:
        return Events(**{f.name: getattr(self, f.name)[mask] for f in attrs.fields(Events)})

    def estimate_mask(self) -> np.ndarray:
        """Which events are track estimates (``confirmed`` and ``updated``)."""
        return (self.kind == TRACK_KINDS[0]) | (self.kind == TRACK_KINDS[1])

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


FLUSH_EVERY = 8192  # rows made columns (and handed to the sink) at a time


class _Head(NamedTuple):
    """What :meth:`Recorder.event` records of an event besides its covariance and identity: the fields of
    a :class:`~radartracker.tracking.events.TrackEvent`, in its order."""

    time: float
    track: int
    kind: str
    status: str
    state: tuple


def _floats(values: tuple) -> np.ndarray:
    """Numbers or ``None`` as floats, NaN for ``None``."""
    return np.array([math.nan if v is None else v for v in values], float)


def _events_of(rows: list[tuple]) -> Events:
    """Rows (event, covariance bytes, altitude, its σ, Mode S, Mode 3/A, target) as columns."""
    heads, covs, altitude_m, altitude_sd_m, mode_s, mode_3a, target = zip(*rows)
    time, track, kind, status, state = zip(*heads)
    n = len(time)
    cov = np.frombuffer(b"".join(covs), float)
    if len(cov) != 16 * n:
        raise ValueError("an event's covariance is not a 4×4 array of floats")
    return Events(time=np.array(time, float), track=np.array(track, int), kind=_obj(kind), status=_obj(status),
                  state=np.column_stack([np.array(c, float) for c in zip(*state)]).reshape(n, 4),
                  cov=cov.reshape(n, 4, 4), altitude_m=_floats(altitude_m), altitude_sd_m=_floats(altitude_sd_m),
                  mode_s=_obj(mode_s), mode_3a=_obj(mode_3a), target=_obj(target))


def _concatenate(chunks: list[Events]) -> Events:
    """The events of ``chunks`` in order (none: no event)."""
    if not chunks:
        return Events(time=np.zeros(0), track=np.zeros(0, int), kind=_obj([]), status=_obj([]), state=np.zeros((0, 4)),
                      cov=np.zeros((0, 4, 4)), altitude_m=np.zeros(0), altitude_sd_m=np.zeros(0), mode_s=_obj([]), mode_3a=_obj([]),
                      target=_obj([]))
    return Events(**{f.name: np.concatenate([getattr(c, f.name) for c in chunks]) for f in attrs.fields(Events)})


class Recorder:
    """Collects a run's events, bias estimates and NIS values (see the module docstring).

    An event is kept as one row (its immutable TrackEvent or fields, its covariance's bytes, its identity)
    until ``flush_every`` of them are made columns at once (:class:`Events`, 8 bytes a number): a
    national-scale run records millions of events.
    A TrackManager's events come through :meth:`listen`, subscribed to its event sink.
    With a ``sink`` (:class:`radartracker.pipeline.writer.OutputStream`) events and biases are handed on
    as they are made columns; ``keep=False`` then drops them once handed on, so that memory does not grow
    with the recording's length (what :attr:`track_ids` keeps, one integer per track with an estimate,
    grows with the number of tracks).
    """

    def __init__(self, bias_log_interval_s: float = 1.0, *, sink=None, keep: bool = True,
                 flush_every: int | None = None) -> None:
        self.bias_log_interval_s = bias_log_interval_s
        self.sink, self.keep, self.flush_every = sink, keep or sink is None, flush_every or FLUSH_EVERY
        self._rows: list[tuple] = []  # events not yet made columns: (head, covariance bytes, *identity)
        self._chunks: list[Events] = []  # events made columns and kept
        self._bias: list[tuple] = []  # (time, radar, the bytes of ς̂ and P_ς: 6 floats)
        self._bias_last: dict[str, float] = {}
        self._bias_sent = 0  # bias rows already handed to the sink
        self._track_ids: set[int] = set()
        self._nis = [0, 0.0]  # count and sum of the NIS values: a run's memory does not grow with them

    def event(self, time: float, track: int, kind: str, status: str, state, cov: np.ndarray | None,
              altitude_m: float | None, mode_s: str | None, mode_3a: str | None, target: object = None, *,
              altitude_sd_m: float | None = None) -> None:
        """Record one event: ``state`` a tuple of four floats or an array (its first four values), ``cov``
        a 4×4 array or ``None`` (recorded as NaN). Both are copied now."""
        if type(state) is not tuple:
            state = tuple(np.asarray(state, float).ravel()[:4].tolist())
        self.track_event(_Head(time, track, kind, status, state[:4]), None if cov is None else np.asarray(cov, float),
                         (altitude_m, altitude_sd_m, mode_s, mode_3a, target))

    def track_event(self, ev, cov: np.ndarray | None, ident: tuple) -> None:
        """Record a :class:`~radartracker.tracking.manager.TrackEvent` (a named tuple of time, track, kind,
        status and state of four floats, kept as it is: it is immutable) with ``cov``, the 4×4 float array of the
        track's estimate at the event's time or ``None``, copied now, and ``ident``, the track's
        (altitude_m, altitude_sd_m, mode_s, mode_3a, target)."""
        self._append((ev, NO_COVARIANCE if cov is None else cov.tobytes(), *ident))

    def listen(self, event, track) -> None:
        """Record a TrackManager's ``event`` of ``track`` (subscribe this method to the manager's
        :class:`~radartracker.tracking.events.EventSink`), as :meth:`track_event` does: with the filter's
        covariance (a float64 4×4 array, the motion-model contract) when the event's state is the track's
        estimate (not extrapolated; never for a deletion), and the track's identity."""
        cov = NO_COVARIANCE if event.kind in ENDS else track.covariance_bytes(event.time)
        self._append((event, cov, track.altitude_m, track.altitude_sd_m, track.mode_s, track.mode_3a, track.target))

    def _append(self, row: tuple) -> None:
        """Keep one event row; every ``flush_every`` rows are made columns."""
        self._rows.append(row)
        if len(self._rows) >= self.flush_every:
            self._columns()

    def add_nis(self, values: np.ndarray) -> None:
        """Take the estimator's NIS values of a batch into the run's mean."""
        self._nis[0] += len(values)
        self._nis[1] += float(np.sum(values))

    @property
    def mean_nis(self) -> float:
        """The mean NIS so far (NaN before any)."""
        return self._nis[1] / self._nis[0] if self._nis[0] else math.nan

    def bias_due(self, radar: str, time: float) -> bool:
        """Whether :meth:`bias` would record ``radar``'s bias at ``time`` (ask before building the state)."""
        return time - self._bias_last.get(radar, -math.inf) >= self.bias_log_interval_s

    def bias(self, time: float, state: BiasState) -> None:
        """Record ``state`` (copied) unless its radar was recorded less than the interval before ``time``."""
        if self.bias_due(state.radar, time):
            bias, cov = np.asarray(state.bias, float), np.asarray(state.cov, float)
            if bias.size != 2 or cov.size != 4:
                raise ValueError(f"radar {state.radar!r}: a bias is 2 floats and its covariance 2×2, got shapes "
                                 f"{bias.shape} and {cov.shape}")
            self._bias.append((float(time), state.radar, bias.tobytes() + cov.tobytes()))  # 6 floats, copied
            self._bias_last[state.radar] = time
            if self.sink is not None and len(self._bias) - self._bias_sent >= self.flush_every:
                self.flush()

    def _columns(self) -> None:
        """The event rows made columns: handed to the sink, kept unless they were handed on and not ``keep``."""
        if self._rows:
            ev = _events_of(self._rows)
            self._rows = []
            self._handle(ev)

    def _handle(self, ev: Events) -> None:
        self._track_ids.update(ev.track[ev.estimate_mask()].tolist())
        if self.sink is not None:
            self.sink.events(ev)
        if self.keep:
            self._chunks.append(ev)

    def flush(self) -> None:
        """Hand the events and bias rows not yet handed on to the sink (dropping them unless ``keep``)."""
        self._columns()
        if self.sink is None:
            return
        self.sink.biases(self.biases(self._bias_sent))
        if self.keep:
            self._bias_sent = len(self._bias)
        else:
            self._bias.clear()

    def events(self) -> Events:
        """The events recorded (those kept, and those not yet made columns)."""
        chunks = self._chunks + ([_events_of(self._rows)] if self._rows else [])
        return chunks[0] if len(chunks) == 1 else _concatenate(chunks)

    @property
    def track_ids(self) -> set[int]:
        """The tracks with an estimate (a ``confirmed`` or ``updated`` event) so far."""
        return self._track_ids | {r[0].track for r in self._rows if r[0].kind in TRACK_KINDS}

    def biases(self, start: int = 0) -> BiasLog:
        rows = self._bias[start:]
        time, radar, values = zip(*rows) if rows else ((), (), ())
        v = np.frombuffer(b"".join(values), float).reshape(-1, 6)
        return BiasLog(np.array(time, float), _obj(list(radar)), v[:, :2].copy(), v[:, 2:].reshape(-1, 2, 2).copy())
