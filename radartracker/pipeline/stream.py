"""A scenario as the time-ordered stream of domain inputs a TrackManager (or the service) consumes:
from tables in memory (:func:`iter_scenario`), or from the files block by block (:func:`iter_files`)."""

from __future__ import annotations

import itertools
import math
import queue
import threading
from collections.abc import Iterable, Iterator

import numpy as np

from radartracker.domain import AdsbReport, Plot, RowMaker, plot_rows, report_rows
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


CHUNK = 4096  # items made at a time as the stream is used, just before they are taken (see _merged)


def _plots(p: PlotTable, idx: slice | np.ndarray = slice(None)) -> RowMaker:
    """The rows ``idx`` (default: all) of ``p`` checked column by column, as :class:`Plot` items on demand."""
    return plot_rows(p.time[idx], p.radar[idx], p.range_m[idx], p.azimuth_rad[idx], p.altitude_m[idx],
                     p.mode_s[idx], p.mode_3a[idx], p.target[idx])


def _reports(a: AdsbTable, idx: slice | np.ndarray = slice(None)) -> RowMaker:
    """The rows ``idx`` (default: all) of ``a`` checked column by column, as :class:`AdsbReport` items on demand."""
    return report_rows(a.time[idx], a.icao24[idx], a.lat[idx], a.lon[idx], a.altitude_m[idx], a.nacp[idx])


def _interleaved(plots: RowMaker | None, reports: RowMaker | None,
                 is_report: np.ndarray) -> Iterator[list[Plot | AdsbReport]]:
    """The items of ``plots`` and ``reports`` (each in its order; ``None``: no rows) where ``is_report`` is False /
    True, made and given CHUNK at a time."""
    i = j = 0
    for start in range(0, len(is_report), CHUNK):
        piece = is_report[start:start + CHUNK]
        n_report = int(np.count_nonzero(piece))
        n_plot = len(piece) - n_report
        if not n_report or not n_plot:
            yield plots(i, i + n_plot) if n_plot else reports(j, j + n_report)
        else:
            # plots first in the concatenation, each kind in order: its k-th item goes where its k-th flag is
            pick = np.empty(len(piece), np.intp)
            pick[~piece] = np.arange(n_plot)
            pick[piece] = np.arange(n_plot, len(piece))
            yield list(map((plots(i, i + n_plot) + reports(j, j + n_report)).__getitem__, pick.tolist()))
        i, j = i + n_plot, j + n_report


def iter_scenario(data: ScenarioData) -> Iterator[Plot | AdsbReport]:
    """The items of :func:`scenario_stream`, in the same order, made a slice at a time as they are consumed
    (a list of every input would grow with the recording's length)."""
    p, a = data.plots, data.adsb
    n = len(p)
    order = np.argsort(np.concatenate([p.time, a.time]), kind="stable")

    def chunks() -> Iterator[list]:
        for start in range(0, len(order), 8192):
            sl = order[start:start + 8192]
            is_report = sl >= n
            yield from _interleaved(_plots(p, sl[~is_report]), _reports(a, sl[is_report] - n), is_report)

    return itertools.chain.from_iterable(chunks())


def _ordered(blocks: Iterable, name: str) -> Iterator:
    """The non-empty blocks, each checked to be in time order after the ones before."""
    last = -math.inf
    for table in blocks:
        t = table.time
        if len(t) and (t[0] < last or np.any(t[1:] < t[:-1])):
            raise NotTimeOrdered(f"{name} is not in time order")
        if len(t):
            last = t[-1]
            yield table


def _merged(plot_tables: Iterator[PlotTable], adsb_tables: Iterator[AdsbTable]) -> Iterator[list]:
    """The rows of two time-ordered streams of non-empty tables as lists of items, in the order of a stable
    merge by time (a plot before a report at the same time), a pair of blocks at a time.

    The last time of the block at hand bounds what its file may still give (+inf once it has ended): a plot
    can go once its time is <= that of the ADS-B file, a report once its time is < that of the plot file.
    The rows that can go are checked and merged by one stable sort, which uses up at least one of the two
    blocks; their items are made CHUNK at a time as the stream is used: a block's worth made at once would
    outlive several young collections of the cyclic garbage collector, each of which looks at them again."""
    p, a = next(plot_tables, None), next(adsb_tables, None)
    i = j = 0
    while p is not None or a is not None:
        p_last = p.time[-1] if p is not None else math.inf
        a_last = a.time[-1] if a is not None else math.inf
        i2 = i + int(np.searchsorted(p.time[i:], a_last, side="right")) if p is not None else 0
        j2 = j + int(np.searchsorted(a.time[j:], p_last, side="left")) if a is not None else 0
        plots = _plots(p, slice(i, i2)) if i2 > i else None
        reports = _reports(a, slice(j, j2)) if j2 > j else None
        if plots is not None and reports is not None:
            is_report = np.argsort(np.concatenate([p.time[i:i2], a.time[j:j2]]), kind="stable") >= i2 - i
        else:
            is_report = np.full(i2 - i + j2 - j, reports is not None)
        yield from _interleaved(plots, reports, is_report)
        i, j = i2, j2
        if p is not None and i == len(p):
            p, i = next(plot_tables, None), 0
        if a is not None and j == len(a):
            a, j = next(adsb_tables, None), 0


def iter_files(files: ScenarioFiles, *, prefetch: bool = False) -> Iterator[Plot | AdsbReport]:
    """The items of :func:`scenario_stream` for the opened folder ``files``, in the same order, read block by
    block: both files must have their kept rows in time order (:class:`NotTimeOrdered` otherwise, raised
    before any item out of order is given). Plots come before ADS-B reports at equal times.

    ``prefetch`` reads and converts the next blocks in a background thread while the current ones are
    used (measured in docs/performance.md: it does not pay, so it is off by default)."""
    plots, adsb = files.plot_blocks(), files.adsb_blocks()
    if prefetch:
        plots, adsb = _prefetch(plots), _prefetch(adsb)
    return itertools.chain.from_iterable(_merged(_ordered(plots, "the plots table"), _ordered(adsb, "the ADS-B table")))


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

