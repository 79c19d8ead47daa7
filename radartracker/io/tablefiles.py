"""Where a scenario table lives and how its rows reach its reader, whatever its format.

A table of a scenario folder is ``NAME.csv`` or ``NAME.parquet`` (chosen by the extension; two for one
table are refused), and plots and ADS-B reports may also be a Parquet dataset folder ``NAME/``
(:mod:`radartracker.io.datasets`). In Python a table may also be an Arrow table or a DataFrame
(:class:`~radartracker.io.arrowsource.ArrowSource`). Every one reaches the readers of
:mod:`radartracker.io.scenario` as :class:`~radartracker.io.csvblocks.Rows`: a CSV file as it is, the others
rendered (:mod:`radartracker.io.arrowsource`).
"""

from __future__ import annotations

import csv
from pathlib import Path

import pyarrow.dataset as ds

from radartracker.errors import InputError
from radartracker.io import rowchecks
from radartracker.io.arrowsource import ArrowSource, first_times as source_first_times, parquet_source, text_table
from radartracker.io.csvblocks import BLOCK_BYTES, Rows, Skipper, newlines
from radartracker.io.datasets import PARTITIONS, count_rows
from radartracker.io.limits import regular_file
from radartracker.io.tables import SCHEMAS, required_columns

#: a table given to a reader: a file or dataset folder, or a table in memory
Table = Path | ArrowSource
SUFFIXES = (".csv", ".parquet")


def find_table(folder: Path, name: str) -> Path | None:
    """The file of the scenario table ``name`` (a key of :data:`~radartracker.io.tables.SCHEMAS`) in
    ``folder``, or (plots, ADS-B) its dataset folder; ``None`` if there is none; an InputError if two."""
    found = [folder / f"{name}{s}" for s in SUFFIXES if (folder / f"{name}{s}").exists()]
    if name in PARTITIONS and (folder / name).is_dir():
        found.append(folder / name)
    if len(found) > 1:
        raise InputError(f"{folder}: {' and '.join(p.name for p in found)} are the same table {name!r}: keep one")
    return found[0] if found else None


def table_files(folder: Path) -> list[Path]:
    """The files a scenario folder may hold under its tables' names (each to be a regular file)."""
    return [folder / f"{name}{s}" for name in SCHEMAS for s in SUFFIXES]


def as_source(table: Table) -> Table:
    """A Parquet file as an :class:`ArrowSource` (its footer read and checked now); anything else as it is."""
    if isinstance(table, Path) and table.suffix == ".parquet":
        return parquet_source(table)
    return table


def open_rows(table: Table, name: str, skip: Skipper | None = None, *, block_bytes: int = BLOCK_BYTES) -> Rows:
    """The rows of ``table`` (a CSV path or an :class:`ArrowSource`, see :func:`as_source`) read as the scenario
    table ``name``."""
    if isinstance(table, ArrowSource):
        return Rows(text_table(table, name, block_bytes), required_columns(name), skip)
    return Rows(table, required_columns(name), skip, block_bytes=block_bytes)


def first_times(table: Table, n: int) -> list[float]:
    """The first ``n`` finite times of ``table`` (the plots' look ahead, see :class:`rowchecks.PlotReader`)."""
    if isinstance(table, ArrowSource):
        return source_first_times(table, n)
    return rowchecks.first_times(table, n)


def columns(table: Path) -> list[str]:
    """The column names of a table file or dataset (a CSV file's header as written)."""
    if table.is_dir():
        return ds.dataset(table, format="parquet", partitioning="hive").schema.names
    if table.suffix == ".parquet":
        return parquet_source(table).schema.names
    with regular_file(table).open(encoding="utf-8-sig", newline="") as f:
        return [h.strip() for h in next(csv.reader([f.readline()]), [])]


def data_rows(table: Path | None) -> int:
    """The number of data rows of a table file or dataset (0 for none): for a progress bar."""
    if table is None:
        return 0
    if table.is_dir():
        return count_rows(table)
    if table.suffix == ".parquet":
        return parquet_source(table).num_rows
    with regular_file(table).open("rb") as f:
        return max(sum(map(newlines, iter(lambda: f.read(BLOCK_BYTES), b""))) - 1, 0)
