"""Admission to the TrackManager: what enters (:class:`Admission`) and in which order it leaves
(:class:`ReorderWindow`). Far-off time stamps are judged by the stream's robust clock
(:class:`radartracker.clock.StreamClock`)."""

from __future__ import annotations

import heapq
import logging
import math
from collections import Counter, deque
from collections.abc import Iterable, Iterator

import numpy as np

from radartracker.clock import ClockConfig, StreamClock
from radartracker.domain import AdsbReport, Plot
from radartracker.estimation.base import PlaneMeasurement

log = logging.getLogger(__name__)
INPUT_KINDS = {"p": "plots", "a": "adsb", "m": "positions"}  # admission key tag → counting name


def finite_position(m: PlaneMeasurement) -> bool:
    """An unbiased position measurement the manager can use: finite time and z (2), R (2×2) finite,
    symmetric and positive definite."""
    z, R = np.asarray(m.z, float), np.asarray(m.R, float)
    return (math.isfinite(m.time) and z.shape == (2,) and R.shape == (2, 2) and bool(np.isfinite(z).all())
            and bool(np.isfinite(R).all()) and bool(np.allclose(R, R.T)) and bool(np.all(np.linalg.eigvalsh(R) > 0)))


class Admission:
    """Which inputs enter the TrackManager; every other one is counted under its reason.

    Rejected: an input that is not a :class:`Plot`, an :class:`AdsbReport` or a usable unbiased
    :class:`PlaneMeasurement` (``invalid_input``); a plot of an unknown radar; one at or before the reordering
    horizon (``*_late``); one equal in source, time and position to an admitted one after the horizon
    (``*_duplicate``); one ahead of the robust :class:`StreamClock` (``*_time_jump``). An input ahead of the
    clock that may start a genuine jump of the stream (a recording resuming after a pause) is *held*: when
    ``step_after`` consecutive consistent inputs step the clock, all of them are admitted; when the run
    breaks, the held ones are counted ``*_time_jump``. So a pause of any length costs no input, and one
    spoofed time stamp costs only itself.
    """

    def __init__(self, radars: Iterable[str], clock: ClockConfig, counts: Counter) -> None:
        self.radars = frozenset(radars)
        self.clock = StreamClock(clock)
        self.counts = counts
        self.keys: dict[tuple, float] = {}  # (kind, source, time, position) of admitted inputs → time
        self.keys_limit = 10_000  # the size at which the keys at or before the horizon are forgotten
        self.held: list[tuple[tuple, object]] = []  # (key, input) of a run that may step the clock

    def admit(self, item: object, horizon: float) -> tuple[tuple[float, object], ...]:
        """The inputs admitted by ``item``'s arrival, with their times: itself, or none (held or counted), or
        the inputs held with it when it completes a clock step."""
        key = self._key(item)
        if key is None:
            return ()
        t = key[2]
        if t <= horizon:
            return self.reject(f"{INPUT_KINDS[key[0]]}_late", item)
        if key in self.keys or (self.held and any(key == k for k, _ in self.held)):
            return self.reject(f"{INPUT_KINDS[key[0]]}_duplicate", item)
        clock = self.clock
        run, steps = clock.run_length, clock.steps
        if not clock.admit(t):
            return self._ahead(key, item, run)
        if clock.steps > steps:  # a clock step: the run held so far is admitted with this input
            admitted, self.held = [*self.held, (key, item)], []
        else:  # an input at the stream's time: a run held ahead of it broke
            self.drop_held()
            admitted = [(key, item)]
        for k, _ in admitted:
            self.keys[k] = k[2]
        self.forget(horizon)
        return tuple((k[2], it) for k, it in admitted)

    def _ahead(self, key: tuple, item: object, run: int) -> tuple:
        """``item`` (``key``) is ahead of the stream clock, whose run of inputs ahead was ``run`` long before
        it: held if it joined that run or started a new one (the old run broke), else counted ``*_time_jump``."""
        t, length = key[2], self.clock.run_length
        if length == run + 1:  # it joined the run of inputs ahead of the clock
            self.held.append((key, item))
        elif length == 1 and math.isfinite(t):  # it started a new run: the old one broke
            self.drop_held()
            self.held.append((key, item))
        else:
            self.reject(f"{INPUT_KINDS[key[0]]}_time_jump", item)
        return ()

    def drop_held(self) -> None:
        """Count the held inputs ``*_time_jump`` (their run broke, or the stream ended)."""
        for key, item in self.held:
            self.reject(f"{INPUT_KINDS[key[0]]}_time_jump", item)
        self.held = []

    def withdraw(self, item: object, why: str) -> None:
        """An admitted ``item`` left the reordering window unused: counted ``*_<why>`` and forgotten (sent
        again, it is judged again, not called a duplicate). ``reorder_overflow``: dropped from a full
        window; ``time_jump``: the stream ended before reaching its time."""
        key = self._key(item)
        self.keys.pop(key, None)
        self.reject(f"{INPUT_KINDS[key[0]]}_{why}", item)

    def _key(self, item: object) -> tuple | None:
        if isinstance(item, Plot):
            if item.radar not in self.radars:
                self.reject("plots_unknown_radar", item)
                return None
            return ("p", item.radar, item.time, item.range_m, item.azimuth_rad)
        if isinstance(item, AdsbReport):
            return ("a", item.icao24, item.time, item.lat, item.lon)
        if isinstance(item, PlaneMeasurement) and item.radar is None and finite_position(item):
            return ("m", item.aircraft, item.time, float(item.z[0]), float(item.z[1]))
        self.reject("invalid_input", item)
        return None

    def reject(self, reason: str, item: object) -> tuple:
        """Count ``item`` under ``reason`` (the first five of each reason logged); nothing admitted."""
        if self.counts[reason] < 5:
            log.warning("rejected (%s): %r", reason, item)
        self.counts[reason] += 1
        return ()

    def forget(self, horizon: float) -> None:
        """Forget the keys at or before ``horizon`` (such an input is late anyway) once they pass the limit,
        which then becomes twice what is left: a long reordering window is not swept every few inputs."""
        if len(self.keys) > self.keys_limit:
            self.keys = {k: t for k, t in self.keys.items() if t > horizon}
            self.keys_limit = max(10_000, 2 * len(self.keys))


class ReorderWindow:
    """Admitted inputs wait until the stream's *confirmed* time is ``window_s`` ahead of them, then leave
    in (time, arrival) order. Most inputs come in time order and wait in a queue; one that came after a
    later one waits in a heap, so at equal times an input of the queue leaves first.

    The confirmed time is the ``confirm``-th newest of the last ``memory`` times pushed (the stream
    clock's ``step_after`` and ``window``): a time that ``confirm`` recent inputs have reached. So one input
    far ahead of the others (a spoofed time stamp inside the clock's ``max_ahead_s``) moves neither the
    window nor the horizon behind it: it waits, alone, until the stream reaches its time, and no good
    input becomes late because of it; and a few inputs far ahead that made a clock step (three spoofed
    records) stop counting once ``memory`` later inputs have come at the stream's own time (a stale time
    above the confirmed one only makes the window release against a newer recent time). The caller
    bounds the window's length with :meth:`drop_newest` and :meth:`pop_oldest`
    (:meth:`~radartracker.tracking.manager.TrackManager._overfull` says when each)."""

    def __init__(self, window_s: float, confirm: int = 3, memory: int = 9) -> None:
        self.window_s = window_s
        self.queue: deque = deque()
        self.heap: list[tuple[float, int, object]] = []
        self.arrivals = 0  # inputs that waited in the heap so far (their order at equal times)
        self.newest: float | None = None
        self.recent: deque[float] = deque(maxlen=max(memory, confirm))  # the last times pushed, in order
        self.pushes = 0  # inputs pushed so far
        self.latest = [-math.inf] * confirm  # the ``confirm`` newest of ``recent``, newest first
        self._pushed_as = [math.inf] * confirm  # the push number of each (∞: none yet)
        self.horizon = -math.inf  # every input at or before it has left

    def __len__(self) -> int:
        return len(self.queue) + len(self.heap)

    @property
    def confirmed(self) -> float:
        """The newest time that ``confirm`` recent inputs have reached (−∞ before that many)."""
        return self.latest[-1]

    def push(self, item: object, t: float) -> None:
        """Add ``item`` (time ``t``)."""
        if self.newest is None or t >= self.newest:
            self.queue.append(item)
            self.newest = t
        else:
            heapq.heappush(self.heap, (t, self.arrivals, item))
            self.arrivals += 1
        self.pushes += 1
        self.recent.append(t)
        latest = self.latest
        if t > latest[-1]:
            i = 0
            while latest[i] >= t:
                i += 1
            latest.insert(i, t)
            latest.pop()
            self._pushed_as.insert(i, self.pushes)
            self._pushed_as.pop()
        if self.pushes - self._pushed_as[-1] >= self.recent.maxlen:  # the confirmed time is no longer recent
            self.recount()

    def recount(self) -> None:
        """``latest`` taken again from ``recent`` (the older first among equal times, as :meth:`push` keeps
        them). ``latest`` is a cache of ``recent`` kept by :meth:`push` in a few comparisons: taking it
        again for every input would cost a sort per input on the national replay's hot path."""
        n, k = len(self.recent), len(self.latest)
        order = sorted(range(n), key=self.recent.__getitem__, reverse=True)[:k]
        self.latest = [self.recent[j] for j in order] + [-math.inf] * (k - len(order))
        self._pushed_as = [self.pushes - n + 1 + j for j in order] + [math.inf] * (k - len(order))

    @property
    def until(self) -> float:
        """The time up to which inputs may leave: ``window_s`` before the confirmed time."""
        return self.latest[-1] - self.window_s

    def settled(self, slack_s: float) -> float:
        """Where a stream's end may be released to: the confirmed time, extended through the newer times
        pushed each at most ``slack_s`` after the one before (a sparse stream's last inputs), never to an
        input alone far ahead."""
        t = self.latest[-1]
        for x in reversed(self.latest[:-1]):
            if x - t > slack_s:
                break
            t = x
        return t

    def drop_newest(self) -> object:
        """Remove and return the input with the newest time (the last of the queue: an input waits in the
        heap only when it is older than the newest time at its arrival)."""
        return self.queue.pop()

    def pop_oldest(self) -> tuple[float, object]:
        """The oldest input (time, input), out of the window before its time (the horizon moves to it)."""
        queue, heap = self.queue, self.heap
        if heap and (not queue or heap[0][0] < queue[0].time):
            t, _, item = heapq.heappop(heap)
        else:
            item = queue.popleft()
            t = item.time
        self.horizon = t
        return t, item

    def due(self, until: float) -> bool:
        """Whether an input waits at or before ``until`` (:meth:`release` would yield one)."""
        queue, heap = self.queue, self.heap
        return bool(queue and queue[0].time <= until or heap and heap[0][0] <= until)

    def release(self, until: float) -> Iterator[tuple[float, object]]:
        """The inputs at or before ``until``, in order, with their times."""
        queue, heap = self.queue, self.heap
        while True:
            if heap and (not queue or heap[0][0] < queue[0].time):
                if heap[0][0] > until:
                    return
                t, _, item = heapq.heappop(heap)
            elif queue and (t := queue[0].time) <= until:
                item = queue.popleft()
            else:
                return
            self.horizon = t
            yield t, item
