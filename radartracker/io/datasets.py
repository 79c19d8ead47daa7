"""A scenario table as a Parquet dataset: a folder of Parquet files in hive partitions, e.g. a recording
of plots partitioned by hour and radar (``plots/hour=475000/radar=LFPG/part-0.parquet``).

``hour`` is ``floor(time / 3600)``, hours since 1970-01-01 UTC; ``radar`` a radar id. Reading is lazy
(:mod:`pyarrow.dataset` finds the files and their partition keys): the files of one hour are read
batch by batch, each checked as a table of its own (:mod:`radartracker.io.arrowsource`; errors name the
file and its row), and their kept rows merged in time order (:func:`merge_blocks`), one hour after the
other. The hour's files share one block's memory (:func:`dataset_blocks`), so a day of recordings streams
in the memory of a few minutes (docs/performance.md, "Parquet").
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import TypeVar

import attrs
import numpy as np
import pyarrow as pa
import pyarrow.dataset as ds

from radartracker.errors import FormatError, TableName
from radartracker.io.arrowsource import UNREADABLE, ArrowSource, parquet_source
from radartracker.io.tables import concat_tables

#: the partition keys a scenario table is written with (:func:`write_partitioned`) and read by
PARTITIONS = {"plots": ("hour", "radar"), "adsb": ("hour",)}
_KEYS = pa.schema([("hour", pa.int64()), ("radar", pa.string())])  # read as written: a radar "001" stays text
HOUR_S = 3600.0
ROWS_PER_GROUP = 16_384  # rows of a row group as written: what a reader decodes of a column at a time

T = TypeVar("T")


def _source(fragment: ds.ParquetFileFragment, root: Path) -> ArrowSource:
    """One file of the dataset (named by its path below ``root``), its partition keys as columns of constant
    value: the file read as :func:`~radartracker.io.arrowsource.parquet_source` reads one."""
    name = TableName(Path(fragment.path).relative_to(root).as_posix())
    file = parquet_source(Path(fragment.path), name)
    keys = {k: v for k, v in ds.get_partition_keys(fragment.partition_expression).items()
            if k not in file.schema.names}
    schema = pa.schema([*file.schema, *(_KEYS.field(k) for k in keys)])

    def batches(columns: list[str], batch_rows: int) -> Iterator[pa.RecordBatch]:
        for b in file.batches([c for c in columns if c not in keys], batch_rows):
            yield pa.RecordBatch.from_arrays([b.column(c) if c not in keys else
                                              pa.array([keys[c]] * b.num_rows, _KEYS.field(c).type) for c in columns],
                                             names=columns)

    return ArrowSource(name, schema, file.num_rows, batches)


def hour_groups(folder: Path, root: Path) -> list[list[ArrowSource]]:
    """The dataset's files as sources, grouped by their ``hour`` key in hour order (one group if the files have
    none), each group in path order; names relative to ``root`` (the scenario folder)."""
    try:
        dataset = ds.dataset(folder, format="parquet", partitioning=ds.partitioning(_KEYS, flavor="hive"))
        fragments = sorted(dataset.get_fragments(), key=lambda f: f.path)
    except UNREADABLE as exc:
        raise FormatError(TableName(folder.relative_to(root).as_posix()), None, None,
                          f"not a readable Parquet dataset ({exc})") from None
    groups: dict[int, list[ArrowSource]] = {}
    for f in fragments:
        hour = ds.get_partition_keys(f.partition_expression).get("hour")
        groups.setdefault(-1 if hour is None else hour, []).append(_source(f, root))
    return [groups[h] for h in sorted(groups)]


def count_rows(folder: Path) -> int:
    """The number of rows of the dataset's files, from their footers."""
    dataset = ds.dataset(folder, format="parquet", partitioning=ds.partitioning(_KEYS, flavor="hive"))
    return sum(f.metadata.num_rows for f in dataset.get_fragments())


def _take(table: T, idx: slice | np.ndarray) -> T:
    return type(table)(**{f.name: getattr(table, f.name)[idx] for f in attrs.fields(type(table))})


def merge_blocks(streams: Iterable[Iterator[T]]) -> Iterator[T]:
    """The rows of several streams of tables (columns of equal length, ``time`` among them; each stream in time
    order, its tables not empty) merged in time order a piece at a time, stably: at equal times in the order
    of ``streams``, each stream's rows in its order.

    Each step takes, of every stream's table at hand, the rows before the earliest of their last times (the
    bound: no stream can still give an earlier row), and the rows at the bound of the streams, in order, up to
    the first whose table ends at it (its next table may hold more). That stream gives its whole table, so
    each step uses one up (a stream out of order is merged in no order; the readers' time checks see it)."""
    heads = [(s, t, 0) for s in streams if (t := next(s, None)) is not None]
    while heads:
        bound = min(t.time[-1] for _, t, _ in heads)
        parts, nxt, at_bound = [], [], True
        for s, t, i in heads:
            if at_bound and t.time[-1] == bound:
                j, at_bound = len(t), False
            else:
                j = i + int(np.searchsorted(t.time[i:], bound, side="right" if at_bound else "left"))
            if j > i:
                parts.append(_take(t, slice(i, j)))
            if j < len(t):
                nxt.append((s, t, j))
            elif (t := next(s, None)) is not None:
                nxt.append((s, t, 0))
        heads = nxt
        merged = concat_tables(parts)
        yield _take(merged, np.argsort(merged.time, kind="stable"))


def dataset_blocks(folder: Path, root: Path, blocks: Callable[[ArrowSource, int], Iterator[T]]) -> Iterator[T]:
    """The kept rows of the dataset ``folder`` in time order: hour after hour, the ``blocks`` of that hour's
    files merged by :func:`merge_blocks`. ``blocks(source, n)`` reads one of ``n`` files read together: each
    takes an n-th of a block's memory, so that a merge step (a block of each) holds about one block whatever
    the number of radars."""
    for group in hour_groups(folder, root):
        yield from merge_blocks([blocks(source, len(group)) for source in group])


def write_partitioned(table: pa.Table, folder: Path, by: tuple[str, ...]) -> None:
    """Write ``table`` (with a ``time`` column, in time order) as a dataset in hive partitions ``by``
    (``hour`` is computed from ``time``), each file's rows in the table's order, the schema's metadata kept."""
    if "hour" in by:
        hour = np.floor(table.column("time").to_numpy() / HOUR_S).astype(np.int64)
        table = table.append_column("hour", pa.array(hour))
    keys = ds.partitioning(pa.schema([_KEYS.field(k) for k in by]), flavor="hive")
    ds.write_dataset(table, folder, format="parquet", partitioning=keys, basename_template="part-{i}.parquet",
                     use_threads=False, preserve_order=True, max_rows_per_group=ROWS_PER_GROUP,
                     existing_data_behavior="error")
