"""The scenario folder format (public contract, documented in docs/formats.md).

A scenario folder holds ``radars.csv``, ``plots.csv`` and optionally ``adsb.csv``, ``truth.csv``,
``truth_biases.csv`` and ``scenario.json`` (reference point, name). Degrees at the edge, SI inside.
Each table may be a Parquet file instead (``plots.parquet``), plots and ADS-B reports also a partitioned
Parquet dataset (``plots/``): :mod:`radartracker.io.tablefiles` finds a table and hands its rows to the
readers here whatever its format.

Reading validates every row. A malformed row raises :class:`FormatError` naming file, line and
field; with ``skip_bad=True`` it is skipped instead and counted under its reason in
``ScenarioData.skipped`` (the replay reports those counts in ``summary.json``).

The plots and ADS-B tables are read block by block (:mod:`radartracker.io.csvblocks`), each plain
block converted column by column (:mod:`radartracker.io.columnar`) and any other row by row, with the
same checks and the same results. :func:`read_scenario` gathers the blocks; :func:`open_scenario`
hands them on one at a time (the streaming replay), so that only one block is in memory.
"""

from __future__ import annotations

import json
import logging
import math
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, TypeVar

import attrs
import numpy as np

from radartracker.domain import Aircraft, Radar
from radartracker.errors import ConfigurationError, FormatError, InputError
from radartracker.io.arrowwrite import write_tables
from radartracker.io import columnar
from radartracker.io.atomic import atomic_folder
from radartracker.io.csvblocks import BLOCK_BYTES, Rows, Skipper
from radartracker.io.datasets import dataset_blocks
from radartracker.io.limits import read_json, regular_file
from radartracker.io.tablefiles import Table, as_source, data_rows, find_table, first_times, open_rows, table_files
from radartracker.io.rowchecks import PLOT_FIELDS, AdsbReader, PlotReader, _key, _physical, _range
from radartracker.io.tables import (ADSB_COLUMNS, SCHEMAS, TRUTH_COLUMNS, AdsbTable, PlotTable, ScenarioData,
                                    TruthTable, concat_tables, label_spans)
from radartracker.clock import ClockConfig

log = logging.getLogger(__name__)
T = TypeVar("T")


# --- reading ----------------------------------------------------------------------------------


def read_radars(path: Table) -> list[Radar]:
    rows = open_rows(as_source(path), "radars")
    radars: dict[str, tuple[Radar, int]] = {}
    for line, row in rows:
        rid = rows.text(row, "radar")
        if rid is None:
            raise FormatError(rows.name, line, "radar", "empty")
        if rid in radars:
            raise FormatError(rows.name, line, "radar", f"duplicate radar id {rid!r} (first on line {radars[rid][1]})")
        radars[rid] = (Radar(
            id=rid,
            lat=rows.number(row, line, "lat", check=_range(-90, 90)),
            lon=rows.number(row, line, "lon", check=_range(-180, 180)),
            height_m=rows.number(row, line, "height_m", check=_physical("height_m")),
            sigma_range_m=rows.number(row, line, "sigma_range_m", check=_physical("sigma_range_m")),
            sigma_azimuth_rad=math.radians(rows.number(row, line, "sigma_azimuth_deg", check=_physical("sigma_deg"))),
            period_s=rows.number(row, line, "period_s", check=_physical("period_s")),
            max_range_m=rows.number(row, line, "max_range_m", check=_physical("max_range_m")),
        ), line)
    if not radars:
        raise FormatError(rows.name, 2, None, "no radars")
    return [r for r, _ in radars.values()]


def _each_file(path: Table, read: Callable[[Table, int], Iterator[T]]) -> Iterator[T]:
    """``read(table, 1)`` of the table, or ``read(file, n)`` of each file of a dataset folder (n of them read
    together), merged in time order (:func:`radartracker.io.datasets.dataset_blocks`; the files named below the
    scenario folder)."""
    if isinstance(path, Path) and path.is_dir():
        return dataset_blocks(path, path.parent, read)
    return read(as_source(path), 1)


def plot_blocks(path: Table, radar_ids: set[str], skip: Skipper, *, block_bytes: int = BLOCK_BYTES,
                fast: bool = True) -> Iterator[PlotTable]:
    """The plots table (a file, a dataset folder or an Arrow source) as tables of the rows kept, block by block,
    in file order (``fast``: plain blocks column by column). A table without a usable row is an error (nothing
    to track)."""
    kept = 0
    for table in _each_file(path, lambda t, n: _plot_file(t, radar_ids, skip, block_bytes // n, fast)):
        kept += len(table)
        yield table
    if not kept:
        name = path.name + ("/" if isinstance(path, Path) and path.is_dir() else "")
        bad = sum(n for k, n in skip.counts.items() if k.startswith(name if name.endswith("/") else f"{name}:"))
        raise FormatError(name, None, None, "no usable plot rows" + (f" ({bad} skipped)" if bad else
                          " after the header") + ": nothing to track", "empty")


def _plot_file(table: Table, radar_ids: set[str], skip: Skipper, block_bytes: int, fast: bool) -> Iterator[PlotTable]:
    rows = open_rows(table, "plots", skip, block_bytes=block_bytes)
    reader = PlotReader(rows, radar_ids, first_times(table, ClockConfig().window))
    yield from _tables(rows, reader, columnar.plots if fast else None)
    reader.finish()  # rows still held at the end of the file never stepped the clock: refused


def adsb_blocks(path: Table, skip: Skipper, *, block_bytes: int = BLOCK_BYTES, fast: bool = True,
                latest_only: bool = False) -> Iterator[AdsbTable]:
    """The ADS-B table as tables of the rows kept, block by block, in file order (see :class:`AdsbReader`)."""
    def read(table: Table, n: int) -> Iterator[AdsbTable]:
        rows = open_rows(table, "adsb", skip, block_bytes=block_bytes // n)
        yield from _tables(rows, AdsbReader(rows, latest_only=latest_only), columnar.adsb if fast else None)

    return _each_file(path, read)


def _tables(rows: Rows, reader, columns) -> Iterator:
    """The non-empty tables of ``rows``' blocks: a plain block through ``columns`` (pyarrow) when it
    takes it, any other block row by row through ``reader``."""
    for first, text, block in rows.blocks():
        table = columns(reader, first, text) if columns is not None and text is not None else None
        if table is None:
            reader.add(block)
            table = reader.take()
        if len(table):
            yield table


def read_plots(path: Table, radar_ids: set[str], skip: Skipper, **kw: Any) -> PlotTable:
    return concat_tables(list(plot_blocks(path, radar_ids, skip, **kw)))


def read_adsb(path: Table, skip: Skipper, **kw: Any) -> AdsbTable:
    tables = list(adsb_blocks(path, skip, **kw)) or [AdsbTable.from_columns(**{k: [] for k in ADSB_COLUMNS})]
    return concat_tables(tables)


def read_truth(path: Table, skip: Skipper) -> TruthTable:
    rows = open_rows(as_source(path), "truth")
    cols: dict[str, list] = {k: [] for k in TRUTH_COLUMNS}
    seen: set = set()
    at: dict[tuple[str, float], int] = {}  # (target, time) → the line of its position
    for line, row in rows:
        rec = (rows.number(row, line, "time"), rows.text(row, "target"),
               rows.number(row, line, "lat", check=_range(-90, 90)),
               rows.number(row, line, "lon", check=_range(-180, 180)), rows.number(row, line, "altitude_m"))
        if (key := _key(row)) in seen:
            skip.count(rows.name, "duplicate_row", f"{rows.name} line {line}")
            continue
        seen.add(key)
        if (first := at.setdefault((rec[1], rec[0]), line)) != line:  # one aircraft in two places at once
            raise FormatError(rows.name, line, "time", f"target {rec[1]!r} already has another position at "
                              f"{rec[0]!r} s (line {first})")
        for k, v in zip(TRUTH_COLUMNS, rec):
            cols[k].append(v)
    return TruthTable.from_columns(**cols)


def read_truth_biases(path: Table, radar_ids: set[str]) -> tuple[dict[str, tuple[float, float]],
                                                                  dict[str, dict[str, float]] | None]:
    """The true (Δr, Δθ) of each radar and, where the optional columns ``range_gain`` and ``time_offset_s``
    are present, its further components (``None`` where no row has them)."""
    rows = open_rows(as_source(path), "truth_biases")
    out: dict[str, tuple[float, float]] = {}
    extra: dict[str, dict[str, float]] = {}
    first: dict[str, int] = {}
    for line, row in rows:
        rid = rows.text(row, "radar")
        if rid not in radar_ids:
            raise FormatError(rows.name, line, "radar", f"unknown radar {rid!r}")
        if rid in first:
            raise FormatError(rows.name, line, "radar", f"radar {rid!r} appears twice (first on line {first[rid]})")
        first[rid] = line
        out[rid] = (rows.number(row, line, "range_bias_m"),
                    math.radians(rows.number(row, line, "azimuth_bias_deg")))
        more = {name: rows.number(row, line, field, optional=True)
                for name, field in (("range_gain", "range_gain"), ("time_offset", "time_offset_s"))}
        if more := {k: v for k, v in more.items() if not math.isnan(v)}:
            extra[rid] = more
    return out, (extra or None)


def _json_number(file: str, obj: dict, field: str, lo: float, hi: float) -> float:
    v = obj.get(field.rsplit(".", 1)[-1])
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise FormatError(file, None, field, f"expected a number, got {json.dumps(v)}")
    if not lo <= v <= hi:  # also refuses NaN and ±Infinity
        raise FormatError(file, None, field, f"{v!r} outside [{lo}, {hi}]")
    return float(v)


def read_meta(path: Path) -> dict[str, Any]:
    """``scenario.json``: ``name``, ``reference`` (lat, lon) and ``aircraft``, each checked; errors name the field."""
    name = path.name
    meta = read_json(path)  # bounded: depth, number sizes, file size (radartracker.io.limits)
    if not isinstance(meta, dict):
        raise FormatError(name, None, None, f"expected a JSON object, got {type(meta).__name__}")
    out: dict[str, Any] = {}
    if "name" in meta:
        if not isinstance(meta["name"], str):
            raise FormatError(name, None, "name", f"expected a string, got {json.dumps(meta['name'])}")
        out["name"] = meta["name"]
    if "reference" in meta:
        ref = meta["reference"]
        if not isinstance(ref, dict):
            raise FormatError(name, None, "reference", f'expected {{"lat": …, "lon": …}}, got {json.dumps(ref)}')
        out["reference"] = (_json_number(name, ref, "reference.lat", -90, 90),
                            _json_number(name, ref, "reference.lon", -180, 180))
    aircraft = meta.get("aircraft", [])
    if not isinstance(aircraft, list):
        raise FormatError(name, None, "aircraft", f"expected a list, got {type(aircraft).__name__}")
    out["aircraft"] = []
    for i, a in enumerate(aircraft):
        try:
            if not isinstance(a, dict):
                raise TypeError(f"expected an object, got {json.dumps(a)}")
            out["aircraft"].append(Aircraft(**a))
        except (TypeError, ValueError) as exc:  # an unknown key, or a value the Aircraft validators refuse
            raise FormatError(name, None, f"aircraft[{i}]", str(exc)) from None
    return out


def check_regular_files(folder: Path | str) -> None:
    """Refuse a scenario folder whose files are not regular files (a ``plots.csv`` linked to ``/dev/zero``
    has no end): an InputError naming the file, before anything reads it."""
    for path in (Path(folder) / "scenario.json", *table_files(Path(folder))):
        if path.exists():
            regular_file(path)


def _meta(folder: Path) -> tuple[dict[str, Any], dict[str, Table | None]]:
    """``scenario.json``'s contents and the folder's tables (:func:`find_table`; radars and plots as their CSV
    names where absent, for the reader to name)."""
    if folder.is_file():  # e.g. `replay plots.csv`: name what a scenario is rather than "does not exist"
        raise InputError(f"{folder} is a file, not a scenario folder (docs/formats.md; an ASTERIX recording "
                         f"ends in .ast, .pcap, .ff or .final)")
    if not folder.is_dir():
        raise FileNotFoundError(f"scenario folder {folder} does not exist")
    check_regular_files(folder)
    meta = read_meta(folder / "scenario.json") if (folder / "scenario.json").exists() else {}
    tables: dict[str, Table | None] = {name: find_table(folder, name) for name in SCHEMAS}
    for name in ("radars", "plots"):
        tables[name] = tables[name] or folder / f"{name}.csv"
    return meta, tables


def _scenario(tables: dict[str, Table | None], meta: dict, radars: list[Radar], plots: PlotTable, adsb: AdsbTable,
              skips: dict[str, Skipper], name: str) -> ScenarioData:
    ids = {r.id for r in radars}
    truth = read_truth(tables["truth"], skips["truth"]) if tables.get("truth") is not None else None
    tb, ts = read_truth_biases(tables["truth_biases"], ids) if tables.get("truth_biases") is not None else (None, None)
    # documented default reference: the centroid of the radar sites
    reference = meta.get("reference") or (float(np.mean([r.lat for r in radars])),
                                           float(np.mean([r.lon for r in radars])))
    return ScenarioData(reference=reference, radars=radars, plots=plots, adsb=adsb, truth=truth,
                        truth_biases=tb, truth_sensor=ts, aircraft=meta.get("aircraft", []), name=meta.get("name", name),
                        skipped=_skipped(skips))


def _skipped(skips: dict[str, Skipper]) -> dict[str, int]:
    """The skip counts of every file, plots first, then ADS-B, then truth."""
    return {k: n for s in skips.values() for k, n in s.counts.items()}


def _skippers(skip_bad: bool) -> dict[str, Skipper]:
    return {name: Skipper(skip_bad, log) for name in ("plots", "adsb", "truth")}


def _no_adsb() -> AdsbTable:
    return AdsbTable.from_columns(**{k: [] for k in ADSB_COLUMNS})


def read_scenario(folder: Path | str, *, skip_bad: bool = False, block_bytes: int = BLOCK_BYTES,
                  fast: bool = True) -> ScenarioData:
    """Read and validate a scenario folder (see docs/formats.md).

    Exact duplicate rows of plots, ADS-B and truth are used once and counted under
    ``<file>:duplicate_row``; a plots table without a usable row is an error (nothing to track).
    ``fast=False`` reads every row one by one (the reference the columnar reading is held to).
    """
    folder = Path(folder)
    meta, tables = _meta(folder)
    return read_tables(tables, meta, folder.name, skip_bad=skip_bad, block_bytes=block_bytes, fast=fast)


def read_tables(tables: dict[str, Table | None], meta: dict[str, Any], name: str, *, skip_bad: bool = False,
                block_bytes: int = BLOCK_BYTES, fast: bool = True) -> ScenarioData:
    """A scenario from its tables (a key of :data:`~radartracker.io.tables.SCHEMAS` each: a file, a dataset
    folder or an Arrow source; radars and plots required, the others ``None`` or absent) and ``meta`` (what
    :func:`read_meta` gives); ``name`` where ``meta`` has none."""
    radars = read_radars(tables["radars"])
    skips = _skippers(skip_bad)
    kw = {"block_bytes": block_bytes, "fast": fast}
    plots = read_plots(tables["plots"], {r.id for r in radars}, skips["plots"], **kw)
    adsb = read_adsb(tables["adsb"], skips["adsb"], **kw) if tables.get("adsb") is not None else _no_adsb()
    return _scenario(tables, meta, radars, plots, adsb, skips, name)


@attrs.define
class ScenarioFiles:
    """A scenario folder opened for streaming: ``data`` holds everything but the plots and ADS-B reports
    (its tables are empty; ``data.skipped`` is complete once both streams are read), which
    :meth:`plot_blocks` and :meth:`adsb_blocks` read block by block in file order. ADS-B duplicates are
    looked for at the latest time only (:class:`AdsbReader`): the streaming replay needs each table in
    time order and checks it. ``rows`` is the number of data rows of both tables (for progress)."""

    tables: dict[str, Table | None]
    data: ScenarioData
    skips: dict[str, Skipper]
    block_bytes: int = BLOCK_BYTES
    fast: bool = True
    rows: int = 0
    label_spans: dict[str, tuple[float, float]] = attrs.field(factory=dict)

    def plot_blocks(self) -> Iterator[PlotTable]:
        """The plots' blocks; with truth, the first and last time of each label are kept
        (:attr:`label_spans`, what the evaluation needs of the plots)."""
        for table in plot_blocks(self.tables["plots"], {r.id for r in self.data.radars}, self.skips["plots"],
                                 block_bytes=self.block_bytes, fast=self.fast):
            if self.data.truth is not None:
                self.label_spans = label_spans(table.time, table.target, self.label_spans)
            yield table
        self.data.skipped = _skipped(self.skips)

    def adsb_blocks(self) -> Iterator[AdsbTable]:
        if self.tables["adsb"] is not None:
            yield from adsb_blocks(self.tables["adsb"], self.skips["adsb"], block_bytes=self.block_bytes,
                                   fast=self.fast, latest_only=True)
        self.data.skipped = _skipped(self.skips)


def open_scenario(folder: Path | str, *, skip_bad: bool = False, block_bytes: int = BLOCK_BYTES,
                  fast: bool = True) -> ScenarioFiles:
    """A scenario folder for streaming (:class:`ScenarioFiles`): ``scenario.json``, radars, truth and true
    biases read and checked now; plots and ADS-B reports when their blocks are asked for."""
    folder = Path(folder)
    meta, tables = _meta(folder)
    radars = read_radars(tables["radars"])
    skips = _skippers(skip_bad)
    data = _scenario(tables, meta, radars, PlotTable.from_columns(**{k: [] for k in PLOT_FIELDS}), _no_adsb(), skips,
                     folder.name)
    rows = sum(data_rows(tables[name]) for name in ("plots", "adsb"))
    return ScenarioFiles(tables, data, skips, block_bytes, fast, rows)


# --- writing ----------------------------------------------------------------------------------


FORMATS = ("csv", "parquet", "dataset")


def write_scenario(folder: Path | str, data: ScenarioData, *, format: str = "csv") -> None:
    """Write ``data`` as a scenario folder (the folder must not exist); it appears complete or not at all.
    ``format``: ``csv`` (the CSV files), ``parquet`` (a Parquet file per table) or ``dataset`` (Parquet, with
    plots and ADS-B reports as datasets partitioned by hour and radar): the same tables either way
    (:mod:`radartracker.io.arrowwrite`)."""
    if format not in FORMATS:
        raise ConfigurationError(f"format {format!r}: one of {', '.join(FORMATS)}")
    with atomic_folder(folder) as tmp:
        write_tables(tmp, data, format)
        _write_meta(tmp, data)


def _write_meta(folder: Path, data: ScenarioData) -> None:
    meta = {"name": data.name, "reference": {"lat": data.reference[0], "lon": data.reference[1]},
            "aircraft": [attrs.asdict(ac) for ac in data.aircraft]}
    (folder / "scenario.json").write_text(json.dumps(meta, indent=1))
