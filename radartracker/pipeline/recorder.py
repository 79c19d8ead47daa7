"""The one recorder both associations feed: track events (with state, covariance and identity),
bias estimates over time and innovation statistics, collected as columns.

Track estimates are the events of kind ``confirmed`` and ``updated`` (:data:`TRACK_KINDS`): the state
just after a measurement was used. Each radar's bias is recorded after one of its plots at most once
per ``bias_log_interval_s``.
"""

from __future__ import annotations

import math
import struct
from itertools import chain
from typing import NamedTuple

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


_NAN16 = np.full(16, math.nan).tobytes()  # the covariance of an event without one
_NAN44 = np.full((4, 4), math.nan)
_NO_IDENT = (math.nan, None, None)  # altitude, Mode S, Mode 3/A
_CHUNK = 1024  # rows of an event_log read at a time (_log_events_of)
FLUSH_EVERY = 8192  # rows made columns (and handed to the sink) at a time


class _Head(NamedTuple):
    """What :meth:`Recorder.event` records of an event besides its covariance and identity: the fields of
    a :class:`~radartracker.tracking.manager.TrackEvent`, in its order."""

    time: float
    track: int
    kind: str
    status: str
    state: tuple


def _events(time, track, kind, status, state, cov: np.ndarray, altitude_m, mode_s, mode_3a, target) -> Events:
    """:class:`Events` of n events from their fields (sequences of n; ``state`` of 4-tuples, ``cov`` the
    16 n covariance values)."""
    n = len(time)
    if len(cov) != 16 * n:
        raise ValueError("an event's covariance is not a 4×4 array of floats")
    return Events(time=np.array(time, float), track=np.array(track, int), kind=_obj(kind), status=_obj(status),
                  state=np.fromiter(chain.from_iterable(state), float, 4 * n).reshape(n, 4), cov=cov.reshape(n, 4, 4),
                  altitude_m=np.array(altitude_m, float), mode_s=_obj(mode_s), mode_3a=_obj(mode_3a),
                  target=_obj(target))


def _events_of(rows: list[tuple]) -> Events:
    """Rows of :meth:`Recorder.event` / :meth:`Recorder.track_event` as columns."""
    heads, covs, idents = zip(*rows)
    return _events(*zip(*heads), np.frombuffer(bytearray(b"".join(covs)), float), *zip(*idents))


class _Idents(NamedTuple):
    """Each track's identity at its last row that was not its deletion (:func:`_log_events_of`): track ids,
    altitude (m, NaN if none), Mode S and Mode 3/A, as columns."""

    track: np.ndarray
    altitude_m: np.ndarray
    mode_s: np.ndarray
    mode_3a: np.ndarray


_NO_IDENTS = _Idents(np.zeros(0, np.int64), np.zeros(0), _obj([]), _obj([]))


def _log_events_of(rows: list[tuple], idents: _Idents, *, drain: bool = False) -> tuple[Events, _Idents]:
    """Rows of a TrackManager's ``event_log`` (event, P, altitude_m, mode_s, mode_3a) as columns, and
    ``idents`` after them. A deleted event is recorded without covariance and with the identity of its
    track's previous event, as on the replay's record of it (the track is gone from the manager);
    ``idents`` holds, for each track whose last row was not its deletion, the identity of that row.

    The rows are read :data:`_CHUNK` at a time, every column of a chunk while its objects are in the cache
    (a national run's 8 192 rows, spread over the heap, are not); with ``drain`` each chunk is removed
    from ``rows`` once read, its objects freed while still in the cache."""
    n = len(rows)
    time, track, state, cov, alt = np.empty(n), np.empty(n, np.int64), np.empty((n, 4)), np.empty((n, 16)), np.empty(n)
    texts = np.empty((4, n), object)  # kind, status, Mode S, Mode 3/A
    for a in reversed(range(0, n, _CHUNK)):  # the last chunk first: drained, it is cut off the list's end
        evs, covs, alts, modes_s, modes_3a = zip(*rows[a:a + _CHUNK])
        if drain:
            del rows[a:]
        times, ids, kinds, statuses, x = zip(*evs)
        b = a + len(times)
        time[a:b] = _packed("d", times)
        track[a:b] = _packed("q", ids)
        state[a:b] = _packed("d", chain.from_iterable(x)).reshape(b - a, 4)
        cov[a:b] = _covariances([_NAN44 if P is None else P for P in covs])
        alt[a:b] = alts  # None: NaN
        for col, values in zip(texts, (kinds, statuses, modes_s, modes_3a)):
            col[a:b] = values
    kind, status, mode_s, mode_3a = texts
    gone = kind == "deleted"
    cov[gone] = math.nan
    live = np.flatnonzero(~gone)
    tracks, later = np.unique(track[live][::-1], return_index=True)
    lasts = live[len(live) - 1 - later]  # each track's last row here that is not a deletion
    dead = np.flatnonzero(gone)
    ended = np.unique(track[dead])
    last, before = _where(tracks, ended), _where(idents.track, ended)  # of the few tracks deleted here
    for j in dead.tolist():
        t = int(track[j])
        i, k = last.pop(t, None), before.pop(t, None)
        if i is not None:
            i = lasts[i]
            alt[j], mode_s[j], mode_3a[j] = alt[i], mode_s[i], mode_3a[i]
        else:
            alt[j], mode_s[j], mode_3a[j] = _NO_IDENT if k is None else (
                idents.altitude_m[k], idents.mode_s[k], idents.mode_3a[k])
    new = np.flatnonzero(~np.isin(tracks, ended))
    old = np.flatnonzero(~np.isin(idents.track, np.concatenate([tracks, ended])))
    i = lasts[new]
    idents = _Idents(*(np.concatenate([c[old], now]) for c, now in zip(
        idents, (tracks[new], alt[i], mode_s[i], mode_3a[i]))))
    return Events(time=time, track=track, kind=kind, status=status, state=state, cov=cov.reshape(n, 4, 4),
                  altitude_m=alt, mode_s=mode_s, mode_3a=mode_3a, target=np.empty(n, object)), idents  # target: None


def _where(tracks: np.ndarray, ended: np.ndarray) -> dict[int, int]:
    """Where each of ``ended`` is in ``tracks`` (those that are)."""
    i = np.flatnonzero(np.isin(tracks, ended))
    return dict(zip(tracks[i].tolist(), i.tolist()))


def _packed(code: str, values) -> np.ndarray:
    """Python numbers (float ``d``, integer ``q``) as an array, through one ``struct.pack``: faster than
    ``np.array`` or ``np.fromiter`` on a sequence."""
    values = tuple(values)
    return np.frombuffer(struct.pack(f"{len(values)}{code}", *values), np.dtype(code))


def _covariances(covs: list) -> np.ndarray:
    """4×4 covariances as rows of 16 floats: the arrays' bytes in one join, unless one is not 16 contiguous
    float64 (then by value); :class:`ValueError` if one is not 4×4."""
    try:
        cov = np.frombuffer(bytearray().join(covs), float)
    except (BufferError, TypeError):
        cov = None
    if cov is None or len(cov) != 16 * len(covs):  # as track_event checks the bytes
        try:
            cov = np.array(covs, float)
        except ValueError:
            cov = None
    if cov is None or cov.size != 16 * len(covs):
        raise ValueError("an event's covariance is not a 4×4 array of floats")
    return cov.reshape(-1, 16)


def _concatenate(chunks: list[Events]) -> Events:
    """The events of ``chunks`` in order (none: no event)."""
    if not chunks:
        return Events(time=np.zeros(0), track=np.zeros(0, int), kind=_obj([]), status=_obj([]), state=np.zeros((0, 4)),
                      cov=np.zeros((0, 4, 4)), altitude_m=np.zeros(0), mode_s=_obj([]), mode_3a=_obj([]),
                      target=_obj([]))
    return Events(**{f.name: np.concatenate([getattr(c, f.name) for c in chunks]) for f in attrs.fields(Events)})


class Recorder:
    """Collects a run's events, bias estimates and NIS values (see the module docstring).

    An event is kept as one row (its immutable TrackEvent or fields, its covariance's bytes, its identity)
    until ``flush_every`` of them are made columns at once (:class:`Events`, 8 bytes a number): a
    national-scale run records millions of events.
    A TrackManager records its events without a call per event by appending rows to :attr:`manager_log`
    (its ``event_log``); whoever feeds it calls :meth:`flush` once that holds ``flush_every`` rows. They are
    made columns after those of :meth:`event` and :meth:`track_event`: feed a recorder one way or the other.
    With a ``sink`` (:class:`radartracker.pipeline.writer.OutputStream`) events and biases are handed on
    as they are made columns; ``keep=False`` then drops them once handed on, so that memory does not grow
    with the recording's length (what :attr:`track_ids` keeps, one integer per track with an estimate,
    grows with the number of tracks).
    """

    def __init__(self, bias_log_interval_s: float = 1.0, *, sink=None, keep: bool = True,
                 flush_every: int | None = None) -> None:
        self.bias_log_interval_s = bias_log_interval_s
        self.sink, self.keep, self.flush_every = sink, keep or sink is None, flush_every or FLUSH_EVERY
        self._rows: list[tuple] = []  # events not yet made columns: (head, covariance bytes, identity)
        self.manager_log: list[tuple] = []  # a TrackManager's event_log: (event, P, altitude_m, mode_s, mode_3a)
        self._idents = _NO_IDENTS  # _log_events_of: identity of each track at its last row
        self._chunks: list[Events] = []  # events made columns and kept
        self._bias: list[tuple] = []  # (time, radar, the bytes of ς̂ and P_ς: 6 floats)
        self._bias_last: dict[str, float] = {}
        self._bias_sent = 0  # bias rows already handed to the sink
        self._track_ids: set[int] = set()
        self.nis: list[float] = []

    def event(self, time: float, track: int, kind: str, status: str, state, cov: np.ndarray | None,
              altitude_m: float | None, mode_s: str | None, mode_3a: str | None, target: object = None) -> None:
        """Record one event: ``state`` a tuple of four floats or an array (its first four values), ``cov``
        a 4×4 array or ``None`` (recorded as NaN). Both are copied now."""
        if type(state) is not tuple:
            state = tuple(np.asarray(state, float).ravel()[:4].tolist())
        self.track_event(_Head(time, track, kind, status, state[:4]), None if cov is None else np.asarray(cov, float),
                         (altitude_m, mode_s, mode_3a, target))

    def track_event(self, ev, cov: np.ndarray | None, ident: tuple) -> None:
        """Record a :class:`~radartracker.tracking.manager.TrackEvent` (a named tuple of time, track, kind,
        status and state of four floats, kept as it is: it is immutable) with ``cov``, the 4×4 float array of the
        track's estimate at the event's time or ``None``, copied now, and ``ident``, the track's
        (altitude_m, mode_s, mode_3a, target)."""
        self._rows.append((ev, _NAN16 if cov is None else cov.tobytes(), ident))
        if len(self._rows) >= self.flush_every:
            self._columns()

    def bias_due(self, radar: str, time: float) -> bool:
        """Whether :meth:`bias` would record ``radar``'s bias at ``time`` (ask before building the state)."""
        return time - self._bias_last.get(radar, -math.inf) >= self.bias_log_interval_s

    def bias(self, time: float, state: BiasState) -> None:
        """Record ``state`` unless this radar was recorded less than the interval before ``time``."""
        self.bias_arrays(time, state.radar, state.bias, state.cov)

    def bias_arrays(self, time: float, radar: str, bias: np.ndarray, cov: np.ndarray) -> None:
        """Record ``radar``'s bias ``bias`` (ς̂) and its covariance ``cov`` (P_ς), copied now, unless this radar
        was recorded less than the interval before ``time``: what :meth:`bias` records of a BiasState, from
        an estimator's ``bias_arrays`` (its own arrays, changing with its next update) without making one."""
        if self.bias_due(radar, time):
            bias, cov = np.asarray(bias, float), np.asarray(cov, float)
            if bias.size != 2 or cov.size != 4:
                raise ValueError(f"radar {radar!r}: a bias is 2 floats and its covariance 2×2, got shapes "
                                 f"{bias.shape} and {cov.shape}")
            self._bias.append((float(time), radar, bias.tobytes() + cov.tobytes()))  # 6 floats, copied
            self._bias_last[radar] = time
            if self.sink is not None and len(self._bias) - self._bias_sent >= self.flush_every:
                self.flush()

    def _columns(self) -> None:
        """The event rows made columns: handed to the sink, kept unless they were handed on and not ``keep``."""
        if self._rows:
            ev = _events_of(self._rows)
            self._rows = []
            self._handle(ev)
        if self.manager_log:
            ev, self._idents = _log_events_of(self.manager_log, self._idents, drain=True)  # the list emptied
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
        chunks = self._chunks + ([_events_of(self._rows)] if self._rows else []) + (
            [_log_events_of(self.manager_log, self._idents)[0]] if self.manager_log else [])
        return chunks[0] if len(chunks) == 1 else _concatenate(chunks)

    @property
    def track_ids(self) -> set[int]:
        """The tracks with an estimate (a ``confirmed`` or ``updated`` event) so far."""
        return self._track_ids | {r[0].track for rows in (self._rows, self.manager_log) for r in rows
                                  if r[0].kind in TRACK_KINDS}

    def biases(self, start: int = 0) -> BiasLog:
        rows = self._bias[start:]
        time, radar, values = zip(*rows) if rows else ((), (), ())
        v = np.frombuffer(b"".join(values), float).reshape(-1, 6)
        return BiasLog(np.array(time, float), _obj(list(radar)), v[:, :2].copy(), v[:, 2:].reshape(-1, 2, 2).copy())
