"""Bounds on what an input file may hold, so that no file can make a reader run without end.

Every reader checks its file with these before it parses it; each refusal is an
:class:`~radartracker.errors.InputError` (a :class:`~radartracker.errors.FormatError` where a line or
field is known) naming the file, the line and the field. The numbers are documented in
docs/reliability.md ("Bounds on inputs"):

* **Regular files only** (:func:`regular_file`): a device, a pipe or a socket (a ``plots.csv``
  symlinked to ``/dev/zero``) has no end and is refused before it is read.
* **Lines** of a line-oriented file (CSV, tab-separated, ``.new4``, ``.plt``) at most
  :data:`MAX_LINE_BYTES` (1 MiB: a row of any of our formats is under 300 bytes); a longer line is
  refused with its number (:func:`check_lines`, :class:`LineMeter`), found in one pass over the
  bytes, never by growing a buffer line by line (which is quadratic in the length of the line).
* **JSON** (``scenario.json``, ``config.json``; :func:`read_json`): at most
  :data:`MAX_JSON_BYTES`, nested at most :data:`MAX_JSON_DEPTH` deep (deeper JSON ends Python's
  parser in a RecursionError), numbers of at most :data:`MAX_NUMBER_CHARS` characters (a
  5 000-digit integer ends in Python's integer-conversion limit).
* **Physical values** (:data:`BOUNDS`): σ, heights, periods, ranges and times in the ranges a real
  sensor or recording can have; beyond them arithmetic on the value overflows (σ = 1e308 squared)
  or a conversion fails (a time of 1e308 as a date).
"""

from __future__ import annotations

import json
import os
import re
import stat
from pathlib import Path
from typing import Any

import numpy as np

from radartracker.errors import FormatError, InputError

MAX_LINE_BYTES = 1 << 20
MAX_JSON_BYTES = 256 << 20
MAX_JSON_DEPTH = 64
MAX_NUMBER_CHARS = 100

# name: (low, high, unit) — inclusive; what a sensor on or above the Earth and a recording can have
BOUNDS: dict[str, tuple[float, float, str]] = {
    "height_m": (-1_000.0, 100_000.0, "m"),  # a site from below the Dead Sea to a stratospheric balloon
    "sigma_range_m": (0.0, 10_000.0, "m"),
    "sigma_deg": (0.0, 10.0, "deg"),
    "period_s": (1e-3, 3_600.0, "s"),
    "max_range_m": (1.0, 5_000_000.0, "m"),  # beyond the horizon of any radar, over-the-horizon included
    # seconds since 1970 that are dates (years 1 to 9999: what the .plt date fields can hold)
    "unix_time_s": (-62_135_596_800.0, 253_402_300_799.0, "s"),
}


def bound(name: str, value: float) -> str | None:
    """Why ``value`` is outside the physical bounds :data:`BOUNDS` ``[name]``, or ``None`` if inside."""
    lo, hi, unit = BOUNDS[name]
    return None if lo <= value <= hi else f"outside the physical bounds [{lo:g}, {hi:g}] {unit}"


def regular_file(path: Path | str) -> Path:
    """``path`` if it is a regular file (symbolic links followed); else an InputError saying what it is.
    A missing file raises FileNotFoundError (an OSError: one line and exit 2 at the command line)."""
    path = Path(path)
    mode = os.stat(path).st_mode
    if not stat.S_ISREG(mode):
        what = ("a folder" if stat.S_ISDIR(mode) else "a character device" if stat.S_ISCHR(mode)
                else "a block device" if stat.S_ISBLK(mode) else "a pipe" if stat.S_ISFIFO(mode)
                else "a socket" if stat.S_ISSOCK(mode) else "not a regular file")
        raise InputError(f"{path}: is {what}, not a regular file; refused (it may have no end)")
    return path


def check_lines(name: str, data: bytes | memoryview, first_line: int = 1, carried: int = 0) -> int:
    """Refuse a line of ``data`` longer than :data:`MAX_LINE_BYTES` (FormatError with its number).
    ``carried``: bytes of the line ``data`` begins within, read before; returns the bytes of the
    last, unfinished line (``carried`` for the next piece). The lines within a piece no longer than the
    limit cannot exceed it: only the first and the last are measured then (two byte searches)."""
    data = bytes(data) if isinstance(data, memoryview) else data
    first = data.find(b"\n")
    if first < 0:
        if carried + len(data) > MAX_LINE_BYTES:
            _too_long(name, first_line)
        return carried + len(data)
    if carried + first > MAX_LINE_BYTES:
        _too_long(name, first_line)
    if len(data) > MAX_LINE_BYTES:
        ends = np.flatnonzero(np.frombuffer(data, np.uint8) == 10)
        lengths = np.diff(ends) - 1
        if len(lengths) and lengths.max() > MAX_LINE_BYTES:
            _too_long(name, first_line + 1 + int(np.argmax(lengths > MAX_LINE_BYTES)))
    tail = len(data) - data.rfind(b"\n") - 1
    if tail > MAX_LINE_BYTES:
        _too_long(name, first_line + data.count(b"\n"))
    return tail


def _too_long(name: str, line: int) -> None:
    raise FormatError(name, line, None, f"line longer than {MAX_LINE_BYTES:,} bytes (the limit of a line; "
                      "not a file of this format)", "line_too_long")


class LineMeter:
    """:func:`check_lines` over a file read piece by piece: ``meter(piece)`` checks it, counting lines."""

    def __init__(self, name: str) -> None:
        self.name, self.line, self.carried = name, 1, 0

    def __call__(self, piece: bytes | memoryview) -> None:
        self.carried = check_lines(self.name, piece, self.line, self.carried)
        self.line += int(np.count_nonzero(np.frombuffer(piece, np.uint8) == 10))


def read_bytes(path: Path | str, *, lines: bool = True, limit: int | None = None) -> bytes:
    """A regular file's bytes (``lines``: each line checked against :data:`MAX_LINE_BYTES`; ``limit``:
    at most that many bytes, else an InputError)."""
    path = regular_file(path)
    if limit is not None and os.stat(path).st_size > limit:
        raise InputError(f"{path.name}: {os.stat(path).st_size:,} bytes, more than this file may hold ({limit:,})")
    data = path.read_bytes()
    if lines:
        check_lines(path.name, data)
    return data


_STRING = re.compile(rb'"(?:[^"\\\n]|\\.)*"')
_LONG_NUMBER = re.compile(rb"[-+0-9.eE]{%d,}" % (MAX_NUMBER_CHARS + 1))


def _check_json(name: str, data: bytes) -> None:
    """Refuse nesting deeper than :data:`MAX_JSON_DEPTH` and numbers longer than :data:`MAX_NUMBER_CHARS`,
    naming the line. Strings are blanked first (a JSON string holds no raw newline: lines are kept)."""
    bare = _STRING.sub(b'""', data)
    if (m := _LONG_NUMBER.search(bare)) is not None:
        raise FormatError(name, bare.count(b"\n", 0, m.start()) + 1, None,
                          f"a number of {len(m.group()):,} characters (at most {MAX_NUMBER_CHARS})", "number_too_long")
    b = np.frombuffer(bare, np.uint8)
    step = (np.isin(b, (91, 123)).astype(np.int32) - np.isin(b, (93, 125)).astype(np.int32))
    depth = np.cumsum(step)
    if len(depth) and depth.max() > MAX_JSON_DEPTH:
        at = int(np.argmax(depth > MAX_JSON_DEPTH))
        raise FormatError(name, bare.count(b"\n", 0, at) + 1, None,
                          f"nested more than {MAX_JSON_DEPTH} levels deep", "too_deep")


def read_json(path: Path | str) -> Any:
    """A JSON file (UTF-8, a byte-order mark allowed) within the bounds of the module docstring;
    a FormatError names the file and the line of what is wrong."""
    path = Path(path)
    data = read_bytes(path, lines=False, limit=MAX_JSON_BYTES)
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise FormatError(path.name, data[:exc.start].count(b"\n") + 1, None,
                          f"not UTF-8 text (byte {exc.start} is {data[exc.start]:#04x})", "encoding") from None
    _check_json(path.name, data)
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise FormatError(path.name, exc.lineno, None, f"not JSON: {exc.msg} (column {exc.colno})") from None
