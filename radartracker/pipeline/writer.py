"""The one writer of a run's outputs (schema: docs/formats.md), each file written atomically.

``tracks.csv`` (the track estimates), ``events.csv`` (every track event), ``biases.csv``,
``coupling.graphml``, figures on request, then ``summary.json`` and ``config.json`` last: a folder
with a ``config.json`` holds a complete run. The folder is prepared (checked for writing, earlier
results refused or removed) by :func:`prepare` before the computation starts.

The three tables are pyarrow tables (:mod:`radartracker.pipeline.outputs`) written by ``pyarrow.csv``
(RFC 4180: texts quoted, a missing value an empty field), each number rounded to its column's decimals
(``outputs.DECIMALS``) and written as the shortest text that reads back as the rounded double; or, with
``table_format="parquet"``, as ``tracks.parquet``, ``events.parquet`` and ``biases.parquet``, the same values
typed. They are written either at the end (:func:`write_outputs`) or as the run goes (:class:`OutputStream`,
fed by the recorder), alike.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path

import pyarrow as pa
import pyarrow.csv as pacsv

from radartracker.errors import ConfigurationError
from radartracker.io.atomic import prepare_output_folder, replace_outputs, staging_path, write_text
from radartracker.pipeline.outputs import (BIAS_COLUMNS, COLUMNS, EVENT_COLUMNS, TRACK_COLUMNS,  # noqa: F401 (as before)
                                           ParquetSink, bias_table, event_tables)
from radartracker.pipeline.recorder import BiasLog, Events
from radartracker.pipeline.result import RunResult

TABLE_FORMATS = ("csv", "parquet")
OUTPUT_FILES = ("tracks.csv", "events.csv", "biases.csv", "tracks.parquet", "events.parquet", "biases.parquet",
                "coupling.graphml", "biases.png", "tracks.png", "summary.json", "config.json")
_CSV = pacsv.WriteOptions(include_header=False, quoting_style="needed")  # texts quoted: a radar id may hold a comma
# events.csv and tracks.csv hold numbers and codes (kinds, statuses, hexadecimal and octal codes): never a
# comma or a quote, so nothing is quoted
_CSV_CODES = pacsv.WriteOptions(include_header=False, quoting_style="none")
log = logging.getLogger(__name__)


def prepare(out: Path | str, *, overwrite: bool = False) -> Path:
    """The output folder, created and writable; earlier results are refused, or with ``overwrite`` kept
    until this run's files replace them (:func:`write_outputs`): a run that fails leaves them intact."""
    return prepare_output_folder(out, OUTPUT_FILES, overwrite=overwrite, keep_earlier=True)


class CsvSink:
    """One table written as CSV piece by piece: the header, then each piece's rows (their numbers as texts)."""

    def __init__(self, path: Path, table: str) -> None:
        self._file = open(path, "wb")  # noqa: SIM115 (closed in close)
        self._file.write((",".join(COLUMNS[table]) + "\n").encode("utf-8"))
        self._options = _CSV if table == "biases" else _CSV_CODES

    def write(self, table: pa.Table) -> None:
        if table.num_rows:
            pacsv.write_csv(table, self._file, self._options)

    def close(self) -> None:
        self._file.close()


def _open(path: Path, table: str, table_format: str) -> CsvSink | ParquetSink:
    return CsvSink(path, table) if table_format == "csv" else ParquetSink(path, table)


def check_format(table_format: str) -> str:
    """``table_format`` if it is one of :data:`TABLE_FORMATS`, else a ConfigurationError."""
    if table_format not in TABLE_FORMATS:
        raise ConfigurationError(f"table format {table_format!r}: one of {', '.join(TABLE_FORMATS)}")
    return table_format


class OutputStream:
    """The tracks, events and biases tables written as a run goes (``table_format`` csv or parquet), each to a
    temporary file in the output folder; :func:`write_outputs` puts them in place with the run's other files
    once all are complete (:meth:`finish`), :meth:`abort` removes them. Rows as :func:`write_outputs` writes them."""

    def __init__(self, out: Path | str, plane, table_format: str = "csv") -> None:
        self.out, self.plane, self.format = Path(out), plane, check_format(table_format)
        self.out.mkdir(parents=True, exist_ok=True)
        self.paths = {t: staging_path(self.out, f"{t}.{self.format}") for t in ("tracks", "events", "biases")}
        self._sinks = {t: _open(path, t, self.format) for t, path in self.paths.items()}

    def events(self, ev: Events) -> None:
        events, tracks = event_tables(ev, self.plane, text=self.format == "csv")
        self._sinks["events"].write(events)
        self._sinks["tracks"].write(tracks)

    def biases(self, b: BiasLog) -> None:
        self._sinks["biases"].write(bias_table(b))

    def finish(self) -> dict[str, Path]:
        """The three files, complete and closed: name → temporary path."""
        for sink in self._sinks.values():
            sink.close()
        return {f"{t}.{self.format}": path for t, path in self.paths.items()}

    def abort(self, exc: BaseException | None = None) -> None:
        for sink in self._sinks.values():
            sink.close()
        for path in self.paths.values():
            path.unlink(missing_ok=True)


def write_outputs(result: RunResult, out: Path | str, *, figures: bool = False, summary: dict | None = None,
                  streamed: OutputStream | None = None, table_format: str = "csv") -> None:
    """Write the run's files into ``out`` (prepared by :func:`prepare`; created if missing). They replace the
    earlier run's together once all are written (:func:`radartracker.io.atomic.replace_outputs`,
    ``config.json`` last): a failure, a full disk included, leaves the earlier run as it was. The three tables
    come from ``streamed`` when the run wrote them as it went, else are written as ``table_format`` (csv or
    parquet). ``summary``: ``result.summary()``, when the caller made it already (a streamed run, before its
    tables replaced the earlier run's)."""
    check_format(table_format)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    if summary is None:  # the evaluation and the rows, before any earlier file is replaced
        summary = result.summary()
    try:
        with replace_outputs(out, OUTPUT_FILES, last="config.json") as stage:
            if streamed is not None:
                for name, path in streamed.finish().items():
                    stage(name, path)
            else:
                _write_tables(result, stage, table_format)
            result.coupling.write_graphml(stage("coupling.graphml"))
            if figures:
                from radartracker.pipeline.figures import plot_biases, plot_tracks_over_truth

                plot_biases(result, stage("biases.png"))
                plot_tracks_over_truth(result, stage("tracks.png"))
            for w in summary["consistency"]["warnings"]:
                log.warning("%s: %s", result.data.name or "run", w)
            stage("summary.json").write_text(json.dumps(summary, indent=1, allow_nan=False) + "\n", encoding="utf-8")
            stage("config.json").write_text(_config_text(result), encoding="utf-8")
    finally:
        if streamed is not None:
            streamed.abort()  # nothing left of it once adopted; its files if the block failed


def _write_tables(result: RunResult, stage, table_format: str) -> None:
    events, tracks = event_tables(result.events, result.plane, text=table_format == "csv")
    for name, table in (("tracks", tracks), ("events", events), ("biases", bias_table(result.biases))):
        sink = _open(stage(f"{name}.{table_format}"), name, table_format)
        try:
            sink.write(table)
        finally:
            sink.close()


def _config_text(result: RunResult) -> str:
    """``config.json``: the effective settings (read back by ``replay --config``) and, for the record,
    the plugins' effective typed settings."""
    doc = json.loads(result.config.to_json())
    doc["plugins"] = result.plugins
    return json.dumps(doc, indent=1, allow_nan=False, default=str) + "\n"


def write_config(result: RunResult, path: Path | str) -> None:
    """``config.json`` of ``result`` at ``path``, atomically."""
    write_text(path, _config_text(result))
