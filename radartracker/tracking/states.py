"""The live tracks' times and states [x, y, vx, vy] as one array, written as their estimates change.

Each frame the TrackManager extrapolates every live track (search, misses, coverage). Read from the
tracks themselves, that meant ~2 000 track objects, estimate tuples and small arrays scattered over the
heap: ~1.8 ms a frame at national scale, most of it waiting for memory, for tracks of which only a third
had changed. :class:`StateTable` keeps one row per live track, in the manager's order of its tracks (the
order they started in), and writes only the rows of the tracks marked changed since the last read.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from typing import Any

import numpy as np


class StateTable:
    """Rows (t, x, y, vx, vy) of the live tracks, in the order they were added.

    ``add`` a track when it starts, ``changed`` when its estimate may have changed, ``remove`` when it
    ends; :meth:`read` gives the rows of the live tracks, the changed ones first read again through
    ``estimate_of`` (a track's ``(t, x, P)``, ``x`` a float vector of length ≥ 4).
    """

    def __init__(self, tracks: Iterable[Any] = ()) -> None:
        self._row: dict[int, int] = {}  # track id → row
        self._rows = np.zeros((64, 5))
        self._alive = np.zeros(64, bool)
        self._used = 0  # rows handed out (live or not)
        self._changed: dict[int, Any] = {}  # tracks to read again, by id
        for tr in tracks:
            self.add(tr)

    def add(self, tr: Any) -> None:
        if self._used == len(self._alive):
            self._compact(grow=True)
        self._row[tr.id] = self._used
        self._alive[self._used] = True
        self._used += 1
        self._changed[tr.id] = tr

    def changed(self, tr: Any) -> None:
        self._changed[tr.id] = tr

    def remove(self, track_id: int) -> None:
        self._alive[self._row.pop(track_id)] = False
        self._changed.pop(track_id, None)

    def read(self, live: list[Any], estimate_of: Callable[[Any], tuple]) -> tuple[np.ndarray, np.ndarray]:
        """(t of each estimate, its x[:4]) of ``live``, the manager's live tracks in order (rebuilt from
        them should they not be the tracks added and not removed)."""
        if len(live) != len(self._row) or (live and live[-1].id not in self._row):
            self.__init__(live)
        if self._changed:
            tracks, self._changed = list(self._changed.values()), {}
            est = [estimate_of(tr) for tr in tracks]
            rows = np.fromiter([self._row[tr.id] for tr in tracks], np.int64, len(tracks))
            self._rows[rows, 0] = np.fromiter([e[0] for e in est], float, len(est))
            xs = [np.asarray(e[1], float) for e in est]
            if len(set(map(len, xs))) == 1:
                self._rows[rows, 1:] = np.concatenate(xs).reshape(len(xs), -1)[:, :4]
            else:
                self._rows[rows, 1:] = np.array([v[:4] for v in xs], float).reshape(len(xs), 4)
        if self._used > 2 * len(self._row) + 1024:
            self._compact(grow=False)
        rows = self._rows[:self._used][self._alive[:self._used]]
        return rows[:, 0], rows[:, 1:]

    def _compact(self, grow: bool) -> None:
        """Drop the rows of removed tracks (keeping the order), and double the capacity if ``grow``."""
        keep = np.flatnonzero(self._alive[:self._used])
        size = max(64, 2 * len(keep)) if grow else len(self._alive)
        rows, alive = np.zeros((size, 5)), np.zeros(size, bool)
        rows[:len(keep)] = self._rows[keep]
        alive[:len(keep)] = True
        order = sorted(self._row, key=self._row.__getitem__)
        self._row = {tid: k for k, tid in enumerate(order)}
        self._rows, self._alive, self._used = rows, alive, len(keep)
