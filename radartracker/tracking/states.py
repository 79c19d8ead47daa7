"""The live tracks' times and states [x, y, vx, vy] as one array, written as their estimates change.

Each frame the TrackManager extrapolates every live track (search, misses, coverage). Read from the
tracks themselves, that meant ~2 000 track objects, estimate tuples and small arrays scattered over the
heap: ~1.8 ms a frame at national scale, most of it waiting for memory, for tracks of which only a third
had changed. :class:`StateTable` keeps one row per live track, in the manager's order of its tracks (the
order they started in), and writes only the rows of the tracks marked changed since the last read.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from operator import itemgetter
from typing import Any

import numpy as np
from numba import njit

_TIME, _STATE = itemgetter(0), itemgetter(1)  # of an estimate (t, x, P)


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
        self._refresh(live, estimate_of)
        rows = self._rows[:self._used][self._alive[:self._used]]
        return rows[:, 0], rows[:, 1:]

    def positions(self, live: list[Any], estimate_of: Callable[[Any], tuple], t: float) -> np.ndarray:
        """The positions (n, 2) of ``live`` extrapolated in a straight line to ``t`` (not backwards):
        (x, y) + (vx, vy) max(t − t_k, 0), as :meth:`read`'s rows give them, in one compiled pass
        (:func:`_extrapolate`: the numpy expression's operations, so the same bits, without its dozen
        array calls a frame)."""
        self._refresh(live, estimate_of)
        pos = np.empty((len(live), 2))
        _extrapolate(self._rows, self._alive, self._used, float(t), pos)
        return pos

    def _refresh(self, live: list[Any], estimate_of: Callable[[Any], tuple]) -> None:
        """Write the rows of the tracks changed since the last refresh (all of them if the table is not the
        tracks of ``live``), then drop removed rows when they outnumber the live ones."""
        if len(live) != len(self._row) or (live and live[-1].id not in self._row):
            self.__init__(live)
        if self._changed:
            changed, self._changed = self._changed, {}
            est = list(map(estimate_of, changed.values()))
            rows = np.fromiter(map(self._row.__getitem__, changed), np.int64, len(est))  # (changed: by id)
            self._rows[rows, 0] = np.fromiter(map(_TIME, est), float, len(est))
            xs = list(map(_STATE, est))
            if len(set(map(len, xs))) == 1:
                self._rows[rows, 1:] = np.concatenate(xs).reshape(len(xs), -1)[:, :4]
            else:
                self._rows[rows, 1:] = np.array([v[:4] for v in xs], float).reshape(len(xs), 4)
        if self._used > 2 * len(self._row) + 1024:
            self._compact(grow=False)

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


@njit(cache=True)
def _extrapolate(rows: np.ndarray, alive: np.ndarray, used: int, t: float, pos: np.ndarray) -> None:
    """``pos[k]`` ← (x, y) + (vx, vy) max(t − t₀, 0) of the k-th live row (t₀, x, y, vx, vy) of ``rows``
    (max as numpy's: NaN kept, −0 kept against +0)."""
    k = 0
    for i in range(used):
        if alive[i]:
            dt = t - rows[i, 0]
            if not (dt >= 0.0 or dt != dt):
                dt = 0.0
            pos[k, 0] = rows[i, 1] + rows[i, 3] * dt
            pos[k, 1] = rows[i, 2] + rows[i, 4] * dt
            k += 1
