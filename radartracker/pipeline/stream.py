"""A scenario as the time-ordered stream of domain inputs a TrackManager (or the service) consumes:
from tables in memory (:func:`iter_scenario`), or from the files block by block (:func:`iter_files`)."""

from __future__ import annotations

import heapq
import math
import operator
import queue
import threading
from collections.abc import Iterable, Iterator

import numpy as np

from radartracker.domain import AdsbReport, Plot
from radartracker.io.scenario import ScenarioFiles
from radartracker.io.tables import AdsbTable, PlotTable, ScenarioData


class NotTimeOrdered(Exception):
    """A file's kept rows are not in time order: it cannot be merged block by block (read it whole)."""


def scenario_stream(data: ScenarioData) -> list[Plot | AdsbReport]:
    """The scenario's plots and ADS-B reports as :class:`Plot` / :class:`AdsbReport`, in time order
    (stable: plots before ADS-B reports at equal times, each in file order).

    ``mgr.process_many(scenario_stream(data))`` runs a whole scenario through a TrackManager.
    """
    return list(iter_scenario(data))


def _plots(p: PlotTable, idx: Iterable[int] | None = None) -> Iterator[Plot]:
    """The rows ``idx`` (default: all) of ``p`` as :class:`Plot` items."""
    cols = [c.tolist() if idx is None else c[idx].tolist() for c in
            (p.time, p.radar, p.range_m, p.azimuth_rad, p.altitude_m, p.mode_s, p.mode_3a, p.target)]
    for t, r, rng, az, alt, ms, m3a, tg in zip(*cols):
        yield Plot(t, r, rng, az, None if alt != alt else alt, ms, m3a, tg)


def _reports(a: AdsbTable, idx: Iterable[int] | None = None) -> Iterator[AdsbReport]:
    """The rows ``idx`` (default: all) of ``a`` as :class:`AdsbReport` items."""
    cols = [c.tolist() if idx is None else c[idx].tolist() for c in
            (a.time, a.icao24, a.lat, a.lon, a.altitude_m, a.nacp)]
    for t, icao, lat, lon, alt, nacp in zip(*cols):
        yield AdsbReport(t, icao, lat, lon, None if alt != alt else alt, int(nacp))


def iter_scenario(data: ScenarioData) -> Iterator[Plot | AdsbReport]:
    """The items of :func:`scenario_stream`, in the same order, made one at a time as they are consumed
    (a list of every input would grow with the recording's length)."""
    p, a = data.plots, data.adsb
    n = len(p)
    order = np.argsort(np.concatenate([p.time, a.time]), kind="stable")
    for start in range(0, len(order), 8192):  # converted a slice at a time, never a list of every item
        sl = order[start:start + 8192]
        is_plot = sl < n
        plots, reports = _plots(p, sl[is_plot]), _reports(a, sl[~is_plot] - n)
        for k in is_plot.tolist():
            yield next(plots) if k else next(reports)


def _ordered(blocks: Iterable, make, name: str) -> Iterator[Plot | AdsbReport]:
    """The blocks' rows as items, checked to be in time order."""
    last = -math.inf
    for table in blocks:
        t = table.time
        if len(t) and (t[0] < last or (len(t) > 1 and np.any(t[1:] < t[:-1]))):
            raise NotTimeOrdered(f"{name} is not in time order")
        last = t[-1] if len(t) else last
        yield from make(table)


def iter_files(files: ScenarioFiles, *, prefetch: bool = False) -> Iterator[Plot | AdsbReport]:
    """The items of :func:`scenario_stream` for the opened folder ``files``, in the same order, read block by
    block: both files must have their kept rows in time order (:class:`NotTimeOrdered` otherwise, raised
    before any item out of order is given). Plots come before ADS-B reports at equal times.

    ``prefetch`` reads and converts the next blocks in a background thread while the current ones are
    used (measured in docs/performance.md: it does not pay, so it is off by default)."""
    plots, adsb = files.plot_blocks(), files.adsb_blocks()
    if prefetch:
        plots, adsb = _prefetch(plots), _prefetch(adsb)
    return heapq.merge(_ordered(plots, _plots, "plots.csv"), _ordered(adsb, _reports, "adsb.csv"),
                       key=operator.attrgetter("time"))


_END = object()


def _prefetch(blocks: Iterator, depth: int = 2) -> Iterator:
    """``blocks`` made by a background thread, at most ``depth`` ahead; an error is raised where it came."""
    q: queue.Queue = queue.Queue(depth)
    stop = threading.Event()

    def work() -> None:
        try:
            for b in blocks:
                while not stop.is_set():
                    try:
                        q.put((b, None), timeout=0.1)
                        break
                    except queue.Full:
                        continue
                if stop.is_set():
                    return
            q.put((_END, None))
        except BaseException as exc:  # handed to the consumer, raised there in order
            q.put((_END, exc))

    thread = threading.Thread(target=work, name="prefetch", daemon=True)
    thread.start()
    try:
        while True:
            b, exc = q.get()
            if exc is not None:
                raise exc
            if b is _END:
                return
            yield b
    finally:
        stop.set()

