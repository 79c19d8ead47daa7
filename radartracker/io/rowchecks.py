"""The row checks of ``plots.csv`` and ``adsb.csv`` (:class:`PlotReader`, :class:`AdsbReader`) and the
field checks they share with the other scenario tables (:mod:`radartracker.io.scenario`).

A malformed row raises :class:`FormatError` naming file, line and field, or (``--skip-bad``) is counted
under its reason; :mod:`radartracker.io.columnar` converts a plain block column by column with the same
results and carries these readers' state on.
"""

from __future__ import annotations

import csv
import math
import statistics
from collections.abc import Callable, Iterable
from pathlib import Path

from radartracker.errors import FormatError
from radartracker.io.csvblocks import Rows
from radartracker.io.limits import bound, regular_file
from radartracker.io.tables import ADSB_COLUMNS, AdsbTable, PlotTable
from radartracker.clock import StreamClock


def _range(lo: float, hi: float, *, hi_open: bool = False) -> Callable[[float], str | None]:
    def check(v: float) -> str | None:
        ok = lo <= v < hi if hi_open else lo <= v <= hi
        return None if ok else f"outside [{lo}, {hi}{')' if hi_open else ']'}"
    return check


def _nonneg(v: float) -> str | None:
    return None if v >= 0 else "is negative"


def _physical(name: str) -> Callable[[float], str | None]:
    """The check of a physical bound (:data:`radartracker.io.limits.BOUNDS`): beyond it, arithmetic on
    the value overflows (σ = 1e308 squared) long before it could mean anything."""
    return lambda v: bound(name, v)


def _code(rows: Rows, row: dict, line: int, field: str, digits: str, n: int) -> str | None:
    value = rows.text(row, field)
    if value is None:
        return None
    value = value.lower()
    if len(value) != n or any(c not in digits for c in value):
        raise FormatError(rows.name, line, field, f"{value!r} is not {n} characters of {digits!r}")
    return value


_HEX, _OCT = "0123456789abcdef", "01234567"


def _key(row: dict) -> str | tuple[str, ...]:
    """An exact duplicate has the same text in every field. The key is the fields joined by commas
    (a plain line's own text) when no field holds a comma, else the tuple of fields."""
    values = tuple(row.values())
    text = ",".join(values)
    return text if text.count(",") == len(values) - 1 else values


PLOT_FIELDS = ("time", "radar", "range_m", "azimuth_rad", "altitude_m", "mode_s", "mode_3a", "target")


class PlotReader:
    """The rows of ``plots.csv`` validated in file order; the checks' state (each radar's latest time
    and the rows at that time, the stream clock) carries over from one block to the next.

    The stream clock (:class:`~radartracker.tracking.admission.StreamClock`) refuses a row far ahead of
    the rows before it. A file can look ahead where a live stream cannot, and does so twice:

    * ``first_times``, the times of the file's first rows: if one of them lies more than the clock's
      ``max_ahead_s`` beyond their median, the clock starts at that median, so that a first row dated
      far ahead is judged (and costs only itself) instead of becoming the clock that every later row
      of its radar is "backwards" from;
    * rows ahead of the clock are held, not refused: when they form a run that steps the clock (a
      recording resuming after a pause), every row of the run is used; when the run breaks, they are
      refused (``time_jump``, each naming its own line). A pause costs nothing.
    """

    def __init__(self, rows: Rows, radar_ids: set[str], first_times: Iterable[float] = ()):
        self.rows, self.radar_ids = rows, radar_ids
        self.has_target = "target" in rows.optional
        self.cols: dict[str, list] = {k: [] for k in PLOT_FIELDS}
        self.last_time: dict[str, tuple[float, int]] = {}
        self.same_time: dict[str, set] = {}  # rows of a radar at its latest time: duplicates are among them
        self.clock = StreamClock()
        self.held: list[tuple[int, dict, float, str]] = []  # rows ahead of the clock, in a run that may step it
        self.kept = 0
        times = [t for t in first_times if math.isfinite(t)]
        if times and max(times) > statistics.median_low(times) + self.clock.config.max_ahead_s:
            self.clock.load_state_dict({"recent": [statistics.median_low(times)], "run": []})

    def add(self, block: Iterable[tuple[int, dict]]) -> None:
        """Validate ``block``'s rows one by one (bad rows to the skipper)."""
        rows, clock = self.rows, self.clock
        for line, row in block:
            try:
                t = rows.number(row, line, "time")
                rid = rows.text(row, "radar")
                if rid not in self.radar_ids:
                    raise FormatError(rows.name, line, "radar", f"unknown radar {rid!r} (the radars table has "
                                      f"{sorted(self.radar_ids)})", "unknown_radar")
                if not self._in_order(line, row, t, rid):
                    continue
                if not clock.admit(t):  # ahead: held while it may be the start of a clock step
                    run = len(clock.state_dict()["run"])
                    self._refuse_held(len(self.held) - run + 1)
                    self.held.append((line, row, t, rid))
                    continue
            except FormatError as err:
                rows.reject(err)
                continue
            if self.held:
                stepped = clock.state_dict()["recent"] == [h[2] for h in self.held] + [t]
                self._release() if stepped else self._refuse_held(len(self.held))
            self._keep(line, row, t, rid)

    def finish(self) -> None:
        """The end of the file: rows still held never became a clock step (refused, ``time_jump``)."""
        self._refuse_held(len(self.held))

    def _in_order(self, line: int, row: dict, t: float, rid: str) -> bool:
        """False for an exact duplicate (counted); a FormatError for a row before its radar's latest."""
        last = self.last_time.get(rid)
        if last is not None and t == last[0] and _key(row) in self.same_time[rid]:
            self.rows.skip.count(self.rows.name, "duplicate_row", f"{self.rows.name} line {line}")
            return False
        if last is not None and t < last[0]:
            raise FormatError(self.rows.name, line, "time", f"{t} is earlier than {last[0]} on line {last[1]} of the "
                              "same radar", "time_backwards")
        return True

    def _release(self) -> None:
        """The held rows stepped the clock: each is used (in file order), checked as any row."""
        held, self.held = self.held, []
        for line, row, t, rid in held:
            try:
                if self._in_order(line, row, t, rid):
                    self._keep(line, row, t, rid)
            except FormatError as err:
                self.rows.reject(err)

    def _refuse_held(self, n: int) -> None:
        """Refuse the first ``n`` held rows: their run broke before it stepped the clock."""
        refused, self.held = self.held[:max(n, 0)], self.held[max(n, 0):]
        for line, _, t, _ in refused:
            self.rows.reject(FormatError(self.rows.name, line, "time", f"{t} is more than "
                                         f"{self.clock.config.max_ahead_s:g} s ahead of the stream time "
                                         f"{self.clock.now} (median of the last rows read)", "time_jump"))

    def _keep(self, line: int, row: dict, t: float, rid: str) -> None:
        """Check the row's other fields and keep it (a bad field: to the skipper)."""
        rows = self.rows
        try:
            rng = rows.number(row, line, "range_m", check=_nonneg)
            az = rows.number(row, line, "azimuth_deg", check=_range(0, 360, hi_open=True))
            alt = rows.number(row, line, "altitude_m", optional=True)
            ms = _code(rows, row, line, "mode_s", _HEX, 6)
            m3a = _code(rows, row, line, "mode_3a", _OCT, 4)
        except FormatError as err:
            rows.reject(err)
            return
        if rid not in self.last_time or t > self.last_time[rid][0]:
            self.same_time[rid] = set()
        self.same_time[rid].add(_key(row))
        self.last_time[rid] = (t, line)
        for k, v in (("time", t), ("radar", rid), ("range_m", rng), ("azimuth_rad", math.radians(az)),
                     ("altitude_m", alt), ("mode_s", ms), ("mode_3a", m3a),
                     ("target", rows.text(row, "target") if self.has_target else None)):
            self.cols[k].append(v)
        self.kept += 1

    def take(self) -> PlotTable:
        """The rows kept since the last call."""
        cols, self.cols = self.cols, {k: [] for k in PLOT_FIELDS}
        return PlotTable.from_columns(**cols)


def first_times(path: Path, n: int) -> list[float]:
    """The ``time`` field of the first ``n`` rows of a CSV file that hold a number there, from its first
    64 KiB (a look ahead for :class:`PlotReader`; the file's checks are the reader's)."""
    out: list[float] = []
    with regular_file(path).open("rb") as f:
        head = f.read(1 << 16).decode("utf-8-sig", errors="replace").splitlines()
    reader = csv.reader(head[:4 * n + 1])
    header = [h.strip() for h in next(reader, [])]
    if "time" not in header:
        return out
    i = header.index("time")
    for fields in reader:
        try:
            out.append(float(fields[i]))
        except (ValueError, IndexError):
            continue
        if len(out) == n:
            break
    return out


class AdsbReader:
    """The rows of ``adsb.csv`` validated in file order. Exact duplicates are looked for among every
    row kept so far, or (``latest_only``, for a file whose kept rows are in time order, as the
    streaming replay requires) among the rows at the latest time kept: a duplicate has the same time."""

    def __init__(self, rows: Rows, *, latest_only: bool = False):
        self.rows, self.latest_only = rows, latest_only
        self.cols: dict[str, list] = {k: [] for k in ADSB_COLUMNS}
        self.seen: set = set()
        self.seen_time = -math.inf
        self.kept = 0

    def add(self, block: Iterable[tuple[int, dict]]) -> None:
        rows, skip, cols = self.rows, self.rows.skip, self.cols
        for line, row in block:
            try:
                rec = {
                    "time": rows.number(row, line, "time"),
                    "icao24": _code(rows, row, line, "icao24", _HEX, 6),
                    "lat": rows.number(row, line, "lat", check=_range(-90, 90)),
                    "lon": rows.number(row, line, "lon", check=_range(-180, 180)),
                    "altitude_m": rows.number(row, line, "altitude_m", optional=True),
                    "nacp": rows.number(row, line, "nacp", check=_range(1, 11)),
                }
                if rec["icao24"] is None:
                    raise FormatError(rows.name, line, "icao24", "empty")
                if rec["nacp"] != int(rec["nacp"]):
                    raise FormatError(rows.name, line, "nacp", f"{rec['nacp']!r} is not an integer")
            except FormatError as err:
                rows.reject(err)
                continue
            if (key := _key(row)) in self.seen:
                skip.count(rows.name, "duplicate_row", f"{rows.name} line {line}")
                continue
            if self.latest_only and rec["time"] != self.seen_time:
                self.seen, self.seen_time = set(), rec["time"]
            self.seen.add(key)
            for k, v in rec.items():
                cols[k].append(v)
            self.kept += 1

    def take(self) -> AdsbTable:
        cols, self.cols = self.cols, {k: [] for k in ADSB_COLUMNS}
        return AdsbTable.from_columns(**cols)
