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
    :class:`PlaneMeasurement` (``invalid_input``); a plot of an unknown radar; an input more than
    ``max_time_jump_s`` after the newest admitted one or ahead of the :class:`StreamClock`
    (``*_time_jump``); one at or before the reordering horizon (``*_late``); one equal in source, time
    and position to an admitted one after the horizon (``*_duplicate``).
    """

    def __init__(self, radars: Iterable[str], max_time_jump_s: float, clock: ClockConfig, counts: Counter) -> None:
        self.radars = frozenset(radars)
        self.max_time_jump_s = max_time_jump_s
        self.clock = StreamClock(clock)
        self.counts = counts
        self.keys: dict[tuple, float] = {}  # (kind, source, time, position) of admitted inputs → time
        self.keys_limit = 10_000  # the size at which the keys at or before the horizon are forgotten

    def admit(self, item: object, newest: float | None, horizon: float) -> float | None:
        """``item``'s time if it is admitted (its key kept for duplicates), else None (counted)."""
        key = self._key(item)
        if key is None:
            return None
        t, kind = key[2], INPUT_KINDS[key[0]]
        if newest is not None and t > newest + self.max_time_jump_s:
            return self.reject(f"{kind}_time_jump", item)
        if t <= horizon:
            return self.reject(f"{kind}_late", item)
        if key in self.keys:
            return self.reject(f"{kind}_duplicate", item)
        if not self.clock.admit(t):
            return self.reject(f"{kind}_time_jump", item)
        self.keys[key] = t
        return t

    def _key(self, item: object) -> tuple | None:
        if isinstance(item, Plot):
            if item.radar not in self.radars:
                return self.reject("plots_unknown_radar", item)
            return ("p", item.radar, item.time, item.range_m, item.azimuth_rad)
        if isinstance(item, AdsbReport):
            return ("a", item.icao24, item.time, item.lat, item.lon)
        if isinstance(item, PlaneMeasurement) and item.radar is None and finite_position(item):
            return ("m", item.aircraft, item.time, float(item.z[0]), float(item.z[1]))
        return self.reject("invalid_input", item)

    def reject(self, reason: str, item: object) -> None:
        if self.counts[reason] < 5:
            log.warning("rejected (%s): %r", reason, item)
        self.counts[reason] += 1

    def forget(self, horizon: float) -> None:
        """Forget the keys at or before ``horizon`` (such an input is late anyway) once they pass the limit,
        which then becomes twice what is left: a long reordering window is not swept every few inputs."""
        if len(self.keys) > self.keys_limit:
            self.keys = {k: t for k, t in self.keys.items() if t > horizon}
            self.keys_limit = max(10_000, 2 * len(self.keys))


class ReorderWindow:
    """Admitted inputs wait until the newest time is ``window_s`` ahead of them, then leave in (time,
    arrival) order. Most inputs come in time order and wait in a queue; one that came after a later one
    waits in a heap, so at equal times an input of the queue leaves first."""

    def __init__(self, window_s: float) -> None:
        self.window_s = window_s
        self.queue: deque = deque()
        self.heap: list[tuple[float, int, object]] = []
        self.arrivals = 0  # inputs that waited in the heap so far (their order at equal times)
        self.newest: float | None = None
        self.horizon = -math.inf  # every input at or before it has left

    def __len__(self) -> int:
        return len(self.queue) + len(self.heap)

    def push(self, item: object, t: float) -> float:
        """Add ``item`` (time ``t``); returns the time up to which inputs may leave."""
        if self.newest is None or t >= self.newest:
            self.queue.append(item)
            self.newest = t
        else:
            heapq.heappush(self.heap, (t, self.arrivals, item))
            self.arrivals += 1
        return self.newest - self.window_s

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
