"""A CSV table read block by block, with the line number of every row and field errors naming the place.

The file is first decoded once without keeping it (a bad byte is a :class:`FormatError` naming its
line, before any row is read), then read in blocks of whole lines (``block_bytes``, 1 MiB by
default). A *plain* block — no quote, carriage return, NUL or blank line, ending with its newline —
splits exactly as Python's ``csv`` module would split it, with consecutive line numbers: a reader
may convert it column by column (:mod:`radartracker.io.columnar`). From the first block that is not
plain to the end of the file, rows come from ``csv.reader`` over the remaining lines, which handles
quoted fields spanning lines. Either way the rows, their line numbers and the errors are those of
reading the whole text with ``csv.reader``.
"""

from __future__ import annotations

import codecs
import csv
import io
import itertools
import math
from collections import Counter
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import Protocol, runtime_checkable

import numpy as np

from radartracker.errors import FormatError
from radartracker.io.limits import LineMeter, read_bytes, regular_file

BLOCK_BYTES = 1 << 20
ROWS_PER_BATCH = 8192  # rows handed on at a time once a file is read by csv.reader


def read_text(path: Path) -> str:
    """A regular file's text: UTF-8 with or without a byte-order mark; a FormatError names the line of a bad
    byte or of a line longer than :data:`radartracker.io.limits.MAX_LINE_BYTES`."""
    path = Path(path)
    data = read_bytes(path)
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data[:exc.start].count(b"\n") + 1
        raise FormatError(path.name, line, None, f"not UTF-8 text (byte {exc.start} is {data[exc.start]:#04x})",
                          "encoding") from None


def newlines(data: bytes | memoryview) -> int:
    """How many ``\\n`` bytes ``data`` holds (one vectorised comparison of the bytes, counted by numpy)."""
    return int(np.count_nonzero(np.frombuffer(data, np.uint8) == 10))


def _survey(path: Path, block_bytes: int) -> tuple[int, bool]:
    """Decode ``path`` block by block: its number of newlines and whether its text ends with a line end.
    A bad byte raises read_text's error (the whole file is read only then); a file that is not regular, or
    a line too long (:mod:`radartracker.io.limits`), a FormatError naming it, before any row is read."""
    decoder = codecs.getincrementaldecoder("utf-8-sig")()
    count, chars, last = 0, 0, b""
    meter = LineMeter(path.name)
    with regular_file(path).open("rb") as f:
        try:
            while data := f.read(block_bytes):
                meter(data)
                chars += len(decoder.decode(data))
                count += newlines(data)
                last = data[-1:]
            decoder.decode(b"", final=True)
        except UnicodeDecodeError:
            read_text(path)  # raises the error with the place of the first bad byte
            raise
    return count, chars == 0 or last in (b"\n", b"\r")


def _plain(text: str) -> bool:
    if not text.endswith("\n") or text.startswith("\n") or '"' in text or "\r" in text or "\x00" in text:
        return False
    # a blank line: two line ends in a row (one vectorised pass over the bytes, not a search per line end)
    ends = np.frombuffer(text.encode(), np.uint8) == 10
    return not np.any(ends[1:] & ends[:-1])


class Skipper:
    """Raise, or count and log, bad rows; count duplicate rows (always used once). Counts are keyed
    ``<file>:<reason>``."""

    def __init__(self, skip_bad: bool, log=None):
        self.skip_bad = skip_bad
        self.counts: Counter[str] = Counter()
        self._log = log

    def __call__(self, err: FormatError) -> None:
        if not self.skip_bad:
            raise err
        self.count(err.file, err.reason, err)

    def count(self, file: str, reason: str, what: object) -> None:
        key = f"{file}:{reason}"
        if self.counts[key] < 5 and self._log is not None:
            self._log.warning("skipped (%s) %s", reason, what)
        self.counts[key] += 1


@runtime_checkable
class TextTable(Protocol):
    """A table given as CSV text instead of a file (a Parquet file or a DataFrame rendered by pyarrow:
    :mod:`radartracker.io.arrowsource`): its ``name`` for messages and ``chunks()``, the UTF-8 bytes of whole
    lines, header first. The header is line 0, so that a row's line number is its row number."""

    name: str

    def chunks(self) -> Iterator[bytes]: ...


class Rows:
    """Iterate a CSV file's rows with line numbers; parse fields with errors naming the place.

    The header must name each column once. A row with the wrong number of fields goes to ``skip``
    (reason ``wrong_field_count``, or ``truncated_last_line`` for a last line without its newline).
    ``for line, row in rows`` gives each row as a dict; :meth:`blocks` gives them block by block.
    """

    def __init__(self, path: Path | TextTable, required: tuple[str, ...], skip: Skipper | None = None, *,
                 block_bytes: int = BLOCK_BYTES):
        self.skip = skip if skip is not None else Skipper(False)
        self.block_bytes = block_bytes
        if isinstance(path, TextTable):  # rendered by a library from a table: whole lines, valid UTF-8
            self.path, self.name, self.cut_line = None, path.name, None
            self._raw = self._read_blocks(path.chunks(), 0)
        else:
            self.path = Path(path)
            self.name = self.path.name
            count, ends = _survey(self.path, block_bytes)
            # a last line without its newline may have been cut short: its errors say so
            self.cut_line = None if ends else count + 1
            self._raw = self._read_blocks(self._file_chunks(), 1)
        start, first = next(self._raw, (1, ""))
        if _plain(first):
            head, _, rest = first.partition("\n")
            header = head.split(",")
            self._pending: tuple[int, str] | None = (start + 1, rest) if rest else None
            self._reader = None
        else:  # csv.reader from the first line on
            self._pending = None
            self._reader, self._base = csv.reader(self._lines(first)), start - 1
            try:
                header = next(self._reader, None)
            except csv.Error as exc:
                raise FormatError(self.name, 1, None, f"bad header: {exc}") from None
        if not header:
            raise FormatError(self.name, 1, None, "empty file: expected a header line")
        header = [h.strip() for h in header]
        twice = sorted({h for h in header if header.count(h) > 1})
        if twice:
            raise FormatError(self.name, 1, None, f"column(s) {', '.join(map(repr, twice))} appear more than once")
        missing = [c for c in required if c not in header]
        if missing:
            raise FormatError(self.name, 1, None, f"missing column(s) {', '.join(missing)}; header is {header}")
        self.header = header
        self.optional = set(header)

    def _file_chunks(self) -> Iterator[bytes]:
        with self.path.open("rb") as f:
            yield from iter(lambda: f.read(self.block_bytes), b"")

    @staticmethod
    def _read_blocks(chunks: Iterable[bytes], line: int) -> Iterator[tuple[int, str]]:
        """(line number of the block's first line, text of whole lines) of the bytes ``chunks``, the first line
        numbered ``line``; the last block may lack its newline."""
        first, tail = line, b""
        for data in itertools.chain(chunks, [b""]):
            buf = tail + data
            cut = len(buf) if not data else buf.rfind(b"\n") + 1
            if cut:
                text = buf[:cut].decode("utf-8-sig" if line == first else "utf-8")
                yield line, text
                line += newlines(memoryview(buf)[:cut])
            tail = buf[cut:]

    def _lines(self, first: str) -> Iterator[str]:
        """The text's lines as ``io.StringIO(text, newline="")`` splits them, from ``first`` to the end."""
        yield from io.StringIO(first, newline="")
        for _, text in self._raw:
            yield from io.StringIO(text, newline="")

    def blocks(self) -> Iterator[tuple[int | None, str | None, Iterable[tuple[int, dict]]]]:
        """``(first line, text, rows)`` per block: ``text`` (whole lines, none blank) is given for a plain
        block only, else ``None``; ``rows`` are the block's ``(line, row)`` pairs, made lazily (use them
        all before asking for the next block)."""
        if self._reader is None:
            while True:
                if self._pending is not None:
                    (line, text), self._pending = self._pending, None
                else:
                    nxt = next(self._raw, None)
                    if nxt is None:
                        return
                    line, text = nxt
                if _plain(text):
                    yield line, text, self._split(line, text)
                    continue
                self._reader, self._base = csv.reader(self._lines(text)), line - 1
                break
        rows = self._csv_rows()  # batches made lazily: a row's error comes after the rows before it are used
        while (head := next(rows, None)) is not None:
            yield None, None, itertools.chain([head], itertools.islice(rows, ROWS_PER_BATCH - 1))

    def _split(self, first: int, text: str) -> Iterator[tuple[int, dict]]:
        header, n = self.header, len(self.header)
        for i, line in enumerate(text.split("\n")[:-1]):
            fields = line.split(",")
            if len(fields) != n:
                self.reject(FormatError(self.name, first + i, None, f"{len(fields)} fields, header has {n}",
                                        "wrong_field_count"))
                continue
            yield first + i, dict(zip(header, fields))

    def _csv_rows(self) -> Iterator[tuple[int, dict]]:
        n, reader, base = len(self.header), self._reader, self._base
        while True:
            try:
                fields = next(reader, None)
            except csv.Error as exc:  # e.g. a quote left open at the end of the file
                fields = exc
            if fields is None:
                return
            if not fields:
                continue  # a blank line
            line = base + reader.line_num
            if isinstance(fields, csv.Error) or len(fields) != n:
                got = f"unreadable ({fields})" if isinstance(fields, csv.Error) else f"{len(fields)} fields"
                self.reject(FormatError(self.name, line, None, f"{got}, header has {n}", "wrong_field_count"))
                continue
            yield line, dict(zip(self.header, fields))

    def __iter__(self) -> Iterator[tuple[int, dict]]:
        for _, _, rows in self.blocks():
            yield from rows

    def reject(self, err: FormatError) -> None:
        """Raise ``err``, or skip and count it (skip_bad); on a cut last line, under ``truncated_last_line``."""
        if err.line is not None and err.line == self.cut_line:
            err = FormatError(err.file, err.line, err.field, f"{err.message} (the file ends in the middle of this "
                              "line: cut short?)", "truncated_last_line")
        self.skip(err)

    def number(self, row: dict, line: int, field: str, *, optional: bool = False,
               check: Callable[[float], str | None] | None = None) -> float:
        text = (row.get(field) or "").strip()
        if not text:
            if optional:
                return math.nan
            raise FormatError(self.name, line, field, "empty")
        try:
            value = float(text)
        except ValueError:
            raise FormatError(self.name, line, field, f"{text!r} is not a number") from None
        if not math.isfinite(value):
            raise FormatError(self.name, line, field, f"{text!r} is not finite")
        if check is not None and (why := check(value)) is not None:
            raise FormatError(self.name, line, field, f"{value!r} {why}")
        return value

    @staticmethod
    def text(row: dict, field: str) -> str | None:
        text = (row.get(field) or "").strip()
        return text or None
