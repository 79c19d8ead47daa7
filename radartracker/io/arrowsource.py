"""Scenario tables as Arrow record batches — a Parquet file, a fragment of a Parquet dataset, a DataFrame —
checked by the same readers as a CSV file.

A table's schema is checked first: each column the reader needs is there, once, of a type its
:data:`~radartracker.io.tables.SCHEMAS` entry allows (a number: any integer, floating or decimal type, and
for ``time`` also a timestamp, read as seconds UTC; a text: a string type, dictionary-encoded or not);
otherwise a :class:`FormatError` names the table and the field. A file that is not Parquet, or that breaks
while it is read, is a FormatError naming the file.

Then its batches are rendered as CSV text by pyarrow — a number as the shortest decimal that reads back as
the same double, a null as an empty field — and read by :class:`~radartracker.io.csvblocks.Rows` and the
readers of :mod:`radartracker.io.scenario` as a file is, row numbers for line numbers: every row passes
the one set of checks (ranges, codes, order, duplicates, the stream clock) and the rows kept, hence the
tracks, are those of the same table written as CSV. The rendering costs about 0.5 µs a row
(docs/performance.md, "Parquet"); the checks are not written twice.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from pathlib import Path

import attrs
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.csv as pacsv
import pyarrow.parquet as pq

from radartracker.errors import FormatError, TableName
from radartracker.io.limits import MAX_LINE_BYTES, regular_file
from radartracker.io.tables import OPTIONAL_COLUMNS, SCHEMAS

ROW_BYTES = 64  # about a plots.csv line: a block of B bytes is B // ROW_BYTES rows rendered at a time
MIN_BATCH_ROWS = 256
READ_BUFFER = 1 << 20  # bytes read from a Parquet file at a time (a column chunk is not read whole first)
_PLAIN = pacsv.WriteOptions(include_header=False, quoting_style="none")
_QUOTED = pacsv.WriteOptions(include_header=False, quoting_style="needed")
_TIME_UNITS = {"s": 1.0, "ms": 1e3, "us": 1e6, "ns": 1e9}

#: ``batches(columns, batch_rows)``: the table's record batches holding ``columns``
Batches = Callable[[list[str], int], Iterator[pa.RecordBatch]]


@attrs.frozen
class ArrowSource:
    """A table as record batches: ``name`` (a :class:`TableName`: its errors count rows), ``schema``,
    ``num_rows`` and ``batches``, which opens it anew at each call."""

    name: TableName
    schema: pa.Schema
    num_rows: int
    batches: Batches


#: what pyarrow raises on a damaged Parquet file: its own errors, the system's, and a ValueError where a name or
#: metadata in the footer is not UTF-8 (pyarrow decodes them in Python: a UnicodeDecodeError)
UNREADABLE = (pa.ArrowException, OSError, ValueError)


def parquet_source(path: Path, name: str | None = None) -> ArrowSource:
    """A Parquet file (its footer read now, its rows batch by batch when asked for); ``name`` for messages
    (default: the file's)."""
    label = TableName(name or path.name)
    try:
        with pq.ParquetFile(regular_file(path)) as f:
            schema, rows = f.schema_arrow, f.metadata.num_rows
    except UNREADABLE as exc:
        raise FormatError(label, None, None, f"not a readable Parquet file ({exc})") from None

    def batches(columns: list[str], batch_rows: int) -> Iterator[pa.RecordBatch]:
        with pq.ParquetFile(path, pre_buffer=False, buffer_size=READ_BUFFER) as f:  # no row group held whole
            yield from f.iter_batches(batch_size=batch_rows, columns=columns, use_threads=False)

    return ArrowSource(label, schema, rows, batches)


def table_source(table: pa.Table, name: str) -> ArrowSource:
    """An Arrow table in memory (a DataFrame's: :func:`radartracker.io.frames.scenario_from_frames`)."""
    return ArrowSource(TableName(name), table.schema, table.num_rows,
                       lambda columns, batch_rows: iter(table.select(columns).to_batches(batch_rows)))


def _kind(t: pa.DataType) -> str:
    if pa.types.is_dictionary(t):
        t = t.value_type
    if pa.types.is_integer(t) or pa.types.is_floating(t) or pa.types.is_decimal(t):
        return "number"
    if pa.types.is_string(t) or pa.types.is_large_string(t):
        return "text"
    return "timestamp" if pa.types.is_timestamp(t) else str(t)


def check_schema(source: ArrowSource, table: str) -> list[str]:
    """The columns of ``source`` the reader of ``table`` (a key of :data:`SCHEMAS`) reads, in its order; a
    FormatError for a column missing, given twice, or of a type the table's schema does not allow."""
    names = source.schema.names
    if twice := sorted({n for n in names if names.count(n) > 1}):
        raise FormatError(source.name, None, None, f"column(s) {', '.join(map(repr, twice))} appear more than once")
    optional = OPTIONAL_COLUMNS.get(table, ())
    if missing := [c.name for c in SCHEMAS[table] if c.name not in names and c.name not in optional]:
        raise FormatError(source.name, None, None, f"missing column(s) {', '.join(missing)}; it has {names}")
    out = []
    for col in (c for c in SCHEMAS[table] if c.name in names):
        want, given = "text" if pa.types.is_string(col.type) else "number", source.schema.field(col.name).type
        got = _kind(given)
        if got != want and not (col.name == "time" and got == "timestamp"):
            expected = "text (a string type)" if want == "text" else "a number (an integer or floating type)"
            raise FormatError(source.name, None, col.name, f"type {given}, expected {expected}")
        out.append(col.name)
    return out


def _plain_column(source: ArrowSource, name: str, col: pa.Array) -> pa.Array:
    """``col`` as pyarrow writes it to CSV: a timestamp as float seconds, a dictionary as its values; a text
    checked to be UTF-8 and no longer than a CSV line may be."""
    if pa.types.is_dictionary(col.type):
        col = col.cast(col.type.value_type)
    if pa.types.is_timestamp(col.type):
        return pc.divide(col.cast(pa.int64()).cast(pa.float64()), _TIME_UNITS[col.type.unit])
    if pa.types.is_string(col.type) or pa.types.is_large_string(col.type):
        try:
            col.validate(full=True)
        except pa.ArrowInvalid:
            raise FormatError(source.name, None, name, "a value is not UTF-8 text") from None
        longest = pc.max(pc.binary_length(col)).as_py() or 0
        if longest > MAX_LINE_BYTES:
            raise FormatError(source.name, None, name, f"a value of {longest} bytes (at most {MAX_LINE_BYTES})")
    return col


@attrs.frozen
class CsvText:
    """A checked table rendered as CSV text (a :class:`~radartracker.io.csvblocks.TextTable`)."""

    source: ArrowSource
    columns: list[str]
    batch_rows: int

    @property
    def name(self) -> TableName:
        return self.source.name

    def chunks(self) -> Iterator[bytes]:
        yield (",".join(self.columns) + "\n").encode()
        for batch in _read(self.source, self.columns, self.batch_rows):
            if not batch.num_rows:
                continue
            batch = pa.RecordBatch.from_arrays([_plain_column(self.source, n, batch.column(n)) for n in self.columns],
                                               names=self.columns)
            sink = pa.BufferOutputStream()
            try:  # bare fields, a block the columnar reading takes; quoted where a text holds a comma or quote
                pacsv.write_csv(batch, sink, _PLAIN)
            except pa.ArrowInvalid:
                sink = pa.BufferOutputStream()
                pacsv.write_csv(batch, sink, _QUOTED)
            yield sink.getvalue().to_pybytes()


def _read(source: ArrowSource, columns: list[str], batch_rows: int) -> Iterator[pa.RecordBatch]:
    """``source``'s batches; a file that breaks while it is read is a FormatError naming it."""
    try:
        yield from source.batches(columns, batch_rows)
    except UNREADABLE as exc:
        raise FormatError(source.name, None, None, f"cannot be read ({exc})") from None


def text_table(source: ArrowSource, table: str, block_bytes: int) -> CsvText:
    """``source`` checked as the scenario table ``table`` and rendered as CSV text for its reader, in blocks of
    about ``block_bytes``."""
    return CsvText(source, check_schema(source, table), max(block_bytes // ROW_BYTES, MIN_BATCH_ROWS))


def first_times(source: ArrowSource, n: int) -> list[float]:
    """The finite ``time`` values of the first ``n`` rows (the look ahead of
    :class:`~radartracker.io.rowchecks.PlotReader`, after :func:`check_schema`; the checks are the reader's)."""
    for batch in _read(source, ["time"], n):
        times = _plain_column(source, "time", batch.column(0)).cast(pa.float64()).to_pylist()
        return [t for t in times if t is not None and math.isfinite(t)]
    return []
