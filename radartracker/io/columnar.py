"""Plain blocks of ``plots.csv`` and ``adsb.csv`` converted column by column with pyarrow.

A block (whole lines, no quote or blank line: :mod:`radartracker.io.csvblocks`) is converted here only
when every one of its rows would be kept, with the same values, by the row-by-row checks of
:class:`~radartracker.io.scenario.PlotReader` / :class:`~radartracker.io.scenario.AdsbReader`, whose
state (latest times, duplicate keys, stream clock) is then carried on as they would carry it. Otherwise
the functions return ``None`` and the block is read row by row, which names the file, line and field of
each bad row and counts it under ``--skip-bad``: the columnar path only ever accepts. What it asks:

* numbers match a plain decimal syntax (:data:`DECIMAL`: ``-12.5``, ``1e3``), a subset of what ``float()``
  reads, checked by pyarrow's regular expression match, and are finite; pyarrow's cast converts them (it
  rounds decimal text correctly, as ``float()`` does, so to the same double); the codes' digits are checked
  by a compiled loop on the column's bytes;
* ranges, codes (hex Mode S / ICAO, octal Mode 3/A, already lower case or not) and radar ids as the
  row checks ask, with no space around a field (the row checks strip it);
* plots: times in order within the block and not before any radar's latest time, so the per-radar
  order holds, and the stream clock (median of the last rows) admits each time: for sorted times the
  median of a window is its middle element;
* no row equal to another row of the block, nor to a kept row it would be a duplicate of. Equal rows have
  equal times, so in a block whose times are in order only the lines of a run of equal times are compared,
  byte by byte by a compiled loop (:func:`_repeats`), and only the few lines the readers keep as keys are
  made strings.
"""

from __future__ import annotations

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.csv as pacsv
from numba import njit

from radartracker.io.tables import AdsbTable, PlotTable

DECIMAL = r"-?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?"  # the plain decimal syntax (\d: [0-9]), checked by _numbers
_WHOLE_DECIMAL = f"^{DECIMAL}$"  # RE2 (pyarrow): \d is [0-9] there too


def _byte_set(chars: str) -> np.ndarray:
    table = np.zeros(256, np.bool_)
    table[list(chars.encode("ascii"))] = True
    return table


_HEX, _OCT = _byte_set("0123456789abcdefABCDEF"), _byte_set("01234567")
_LABEL = _byte_set("".join(map(chr, range(33, 127))))  # printable ASCII without space: nothing for strip()
_NO_TEXT = pa.scalar(None, pa.string())


def _read(header: list[str], raw: bytes) -> pa.Table | None:
    """The block's fields (``raw``: its UTF-8 text) as strings, or ``None`` if a row has the wrong number of
    fields."""
    try:
        return pacsv.read_csv(
            pa.py_buffer(raw),
            read_options=pacsv.ReadOptions(column_names=header, use_threads=False),
            parse_options=pacsv.ParseOptions(quote_char=False, newlines_in_values=False, ignore_empty_lines=False),
            convert_options=pacsv.ConvertOptions(column_types={c: pa.string() for c in header},
                                                 strings_can_be_null=False, quoted_strings_can_be_null=False,
                                                 check_utf8=False))  # raw: a str's encoding, UTF-8 already
    except pa.ArrowInvalid:
        return None


def _all(mask: pa.Array) -> bool:
    return bool(pc.all(mask).as_py()) if len(mask) else True


def _bytes(col: pa.ChunkedArray) -> tuple[np.ndarray, np.ndarray]:
    """A string column's value offsets (n + 1) and UTF-8 bytes: value i is bytes[offsets[i]:offsets[i + 1]]."""
    arr = col.combine_chunks()
    _, offsets, data = arr.buffers()
    off = np.frombuffer(offsets, np.int32)[arr.offset:arr.offset + len(arr) + 1]
    return off, np.frombuffer(data if data is not None else b"", np.uint8)  # read-only either way: one signature


def warm_up() -> None:
    """Compile (or load from numba's cache) the checks' kernels on a tiny column, so that a replay's first
    block does not wait for them (:func:`radartracker.pipeline.warmup.warm_up`)."""
    for values in (["1.5", ""], [""]):  # the second: no bytes at all
        _digits(*_bytes(pa.chunked_array([pa.array(values, pa.string())])), _HEX, 6, True)
    _Lines(b"1\n1\n").repeats(_numbers(pa.chunked_array([pa.array(["1", "1"])])))  # as a block's times are


@njit(cache=True)
def _digits(off, data, allowed, length, optional):  # pragma: no cover (compiled)
    """Whether every value is bytes of the set ``allowed`` (a table of 256), ``length`` of them (any number if
    negative), or is empty, if ``optional``."""
    for i in range(len(off) - 1):
        j, end = off[i], off[i + 1]
        if j == end and optional:
            continue
        if length >= 0 and end - j != length:
            return False
        while j < end:
            if not allowed[data[j]]:
                return False
            j += 1
    return True


LONGEST_RUN = 64  # lines of equal times compared pair by pair; a longer run goes to a set of strings


@njit(cache=True)
def _repeats(t, starts, data, longest):  # pragma: no cover (compiled)
    """For lines in time order (line i: ``data[starts[i]:starts[i + 1]]``, times ``t``): 1 if two lines of a run
    of equal times are the same bytes, else 0; -1 (not looked at further) at a run longer than ``longest``."""
    n, i = len(t), 0
    while i < n:
        j = i + 1
        while j < n and t[j] == t[i]:
            j += 1
        if j - i > longest:
            return -1
        for a in range(i + 1, j):
            a0, size = starts[a], starts[a + 1] - starts[a]
            for b in range(i, a):
                b0 = starts[b]
                if starts[b + 1] - b0 == size:
                    k = 0
                    while k < size and data[a0 + k] == data[b0 + k]:
                        k += 1
                    if k == size:
                        return 1
        i = j
    return 0


class _Lines:
    """A block's lines (``raw``: UTF-8 text of whole lines, each ending with its newline), each made a str only
    when asked for: line ``i`` is ``raw.decode().split("\\n")[i]``."""

    def __init__(self, raw: bytes):
        self.raw = raw
        self.data = np.frombuffer(raw, np.uint8)
        self.starts = np.concatenate([[0], np.flatnonzero(self.data == 10) + 1])

    def __getitem__(self, i: int) -> str:
        return self.raw[self.starts[i]:self.starts[i + 1] - 1].decode()

    def every(self) -> list[str]:
        return self.raw.decode().split("\n")[:-1]

    def repeats(self, t: np.ndarray) -> bool:
        """Whether two lines are the same text (``t``: their times)."""
        if len(t) < 2 or not np.any(t[1:] < t[:-1]):
            found = _repeats(t, self.starts, self.data, LONGEST_RUN)
            if found >= 0:
                return bool(found)
        lines = self.every()
        return len(set(lines)) != len(lines)


def _numbers(col: pa.ChunkedArray, *, optional: bool = False) -> np.ndarray | None:
    """The column as floats (NaN where empty, if ``optional``; read-only, as pyarrow's column without nulls is,
    so that the kernels given it see one type), or ``None`` unless every value is a finite plain decimal."""
    if optional:
        col = pc.if_else(pc.equal(col, ""), _NO_TEXT, col)
    if not pc.all(pc.match_substring_regex(col, _WHOLE_DECIMAL), min_count=0).as_py():  # nulls skipped
        return None
    v = pc.cast(col, pa.float64()).to_numpy(zero_copy_only=False)
    if not np.isfinite(v[~np.isnan(v)] if optional else v).all():  # beyond the largest double, e.g. 1e400
        return None
    v.flags.writeable = False
    return v


def _codes(col: pa.ChunkedArray, digits: int, length: int, *, optional: bool = True) -> np.ndarray | None:
    """Lower-case codes (``None`` where empty, if ``optional``), or ``None`` unless every value is ``length``
    digits of base ``digits`` (16: either case, or 8)."""
    if not _digits(*_bytes(col), _HEX if digits == 16 else _OCT, length, optional):
        return None
    return _objects(col, lower=True)[0]


def _objects(col: pa.ChunkedArray, *, lower: bool = False) -> tuple[np.ndarray, np.ndarray, list]:
    """The column as an object array (lower case if ``lower``, ``None`` where empty), its values' indices in
    the list of its distinct values, and that list: one str object per distinct value, not per row."""
    enc = pc.dictionary_encode(col.combine_chunks())
    values = [v or None for v in (pc.utf8_lower(enc.dictionary) if lower else enc.dictionary).to_pylist()]
    code = enc.indices.to_numpy(zero_copy_only=False)
    return np.array(values, object)[code], code, values


def plots(reader, first: int, text: str) -> PlotTable | None:
    """``text`` (a plain block of ``plots.csv`` whose first line is ``first``) as a table, with ``reader``'s
    state carried on; ``None`` (``reader`` untouched) where it must be read row by row."""
    raw = text.encode()
    tab = _read(reader.rows.header, raw)
    if tab is None or not len(tab):
        return None
    t = _numbers(tab["time"])
    if t is None or np.any(t[1:] < t[:-1]):
        return None
    if reader.last_time and t[0] < max(v[0] for v in reader.last_time.values()):
        return None
    radar = tab["radar"]
    if not _all(pc.is_in(radar, value_set=pa.array(sorted(reader.radar_ids), pa.string()))):
        return None
    rng, az = _numbers(tab["range_m"]), _numbers(tab["azimuth_deg"])
    alt = _numbers(tab["altitude_m"], optional=True)
    ms, m3a = _codes(tab["mode_s"], 16, 6), _codes(tab["mode_3a"], 8, 4)
    if any(v is None for v in (rng, az, alt, ms, m3a)) or not ((rng >= 0).all() and ((az >= 0) & (az < 360)).all()):
        return None
    if reader.has_target:
        if not _digits(*_bytes(tab["target"]), _LABEL, -1, True):
            return None
        target = _objects(tab["target"])[0]
    else:
        target = np.full(len(t), None, object)
    lines = _Lines(raw)
    rid, code, names = _objects(radar)
    if lines.repeats(t) or not _clock_admits(reader.clock, t):
        return None
    for i in np.flatnonzero(t == t[0]).tolist():  # only the first time can equal a radar's latest time
        last = reader.last_time.get(rid[i])
        if last is not None and last[0] == t[i] and lines[i] in reader.same_time[rid[i]]:
            return None
    # accepted: carry the state on as the row checks would: each radar's last row, and its rows at that
    # row's time (within the stretch of the sorted times equal to it)
    _clock_take(reader.clock, t)
    last_rows = len(t) - 1 - np.unique(code[::-1], return_index=True)[1]  # distinct codes: 0, 1, …
    for k, (r, il) in enumerate(zip(names, last_rows.tolist())):
        tl = t[il]
        lo = int(np.searchsorted(t, tl, side="left"))
        keys = {lines[i] for i in (lo + np.flatnonzero(code[lo:il + 1] == k)).tolist()}
        if r in reader.last_time and reader.last_time[r][0] == tl:
            keys |= reader.same_time[r]
        reader.same_time[r], reader.last_time[r] = keys, (float(tl), first + il)
    reader.kept += len(t)
    return PlotTable(time=t, radar=rid, range_m=rng, azimuth_rad=np.radians(az), altitude_m=alt, mode_s=ms,
                     mode_3a=m3a, target=target)


def _clock_admits(clock, t: np.ndarray) -> bool:
    """Whether the stream clock admits every time of the sorted ``t`` directly (no pending run)."""
    state = clock.state_dict()
    recent = np.asarray(state["recent"], float)
    if state["run"] or np.any(recent[1:] < recent[:-1]) or (len(recent) and recent[-1] > t[0]):
        return False
    arr = np.concatenate([recent, t])
    before = np.arange(len(recent), len(arr))  # how many times precede each of t
    m = np.minimum(before, clock.config.window)
    ok = m == 0
    mid = before - m + (m - 1) // 2  # the median_low of the last m times (sorted)
    ok[~ok] = t[~ok] <= arr[mid[~ok]] + clock.config.max_ahead_s
    return bool(ok.all())


def _clock_take(clock, t: np.ndarray) -> None:
    state = clock.state_dict()
    window = clock.config.window
    clock.load_state_dict({"recent": (state["recent"] + t[-window:].tolist())[-window:], "run": []})


def adsb(reader, first: int, text: str) -> AdsbTable | None:
    """``text`` (a plain block of ``adsb.csv``) as a table, with ``reader``'s state carried on; ``None``
    (``reader`` untouched) where it must be read row by row."""
    raw = text.encode()
    tab = _read(reader.rows.header, raw)
    if tab is None or not len(tab):
        return None
    t, lat, lon = _numbers(tab["time"]), _numbers(tab["lat"]), _numbers(tab["lon"])
    alt, nacp = _numbers(tab["altitude_m"], optional=True), _numbers(tab["nacp"])
    icao = _codes(tab["icao24"], 16, 6, optional=False)
    if any(v is None for v in (t, lat, lon, alt, nacp, icao)):
        return None
    if not ((np.abs(lat) <= 90).all() and (np.abs(lon) <= 180).all() and ((nacp >= 1) & (nacp <= 11)).all()
            and (nacp == np.floor(nacp)).all()):
        return None
    lines = _Lines(raw)
    if reader.latest_only:
        # the keys kept are rows at seen_time: only lines of that time can be among them
        if lines.repeats(t) or any(lines[i] in reader.seen for i in np.flatnonzero(t == reader.seen_time).tolist()):
            return None
        # the keys of the last run of equal times, as the row checks keep them
        j = len(t) - 1
        while j > 0 and t[j - 1] == t[-1]:
            j -= 1
        keys = {lines[i] for i in range(j, len(t))}
        reader.seen = keys | reader.seen if j == 0 and reader.seen_time == t[-1] else keys
        reader.seen_time = float(t[-1])
    else:
        every = lines.every()
        if len(distinct := set(every)) != len(every) or not distinct.isdisjoint(reader.seen):
            return None
        reader.seen.update(every)
    reader.kept += len(t)
    return AdsbTable(time=t, icao24=icao, lat=lat, lon=lon, altitude_m=alt, nacp=nacp.astype(int))
