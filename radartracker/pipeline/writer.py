"""The one writer of a run's outputs (schema: docs/formats.md), each file written atomically.

``tracks.csv`` (the track estimates), ``events.csv`` (every track event), ``biases.csv``,
``coupling.graphml``, figures on request, then ``summary.json`` and ``config.json`` last: a folder
with a ``config.json`` holds a complete run. The folder is prepared (checked for writing, earlier
results refused or removed) by :func:`prepare` before the computation starts.

The three tables are pyarrow tables written by ``pyarrow.csv`` (RFC 4180: texts quoted, a missing value
an empty field), each number rounded to its column's decimals (:data:`DECIMALS`) and written as the
shortest text that reads back as the rounded double. They are written either at the end
(:func:`write_outputs`) or as the run goes (:class:`OutputStream`, fed by the recorder), alike.
"""

from __future__ import annotations

import json
import logging
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.csv as pacsv

from radartracker.io.atomic import prepare_output_folder, replace_outputs, staging_path, write_text
from radartracker.pipeline.recorder import BiasLog, Events
from radartracker.pipeline.result import RunResult

OUTPUT_FILES = ("tracks.csv", "events.csv", "biases.csv", "coupling.graphml", "biases.png", "tracks.png",
                "summary.json", "config.json")
TRACK_COLUMNS = ("time", "track", "lat", "lon", "x_m", "y_m", "vx_mps", "vy_mps", "sd_x_m", "sd_y_m", "altitude_m",
                 "mode_s", "mode_3a")
EVENT_COLUMNS = ("time", "track", "event", "status", "lat", "lon", "x_m", "y_m", "vx_mps", "vy_mps", "sd_x_m",
                 "sd_y_m", "altitude_m", "mode_s", "mode_3a")
BIAS_COLUMNS = ("time", "radar", "range_bias_m", "azimuth_bias_deg", "sd_range_m", "sd_azimuth_deg")
# the decimals each number column is rounded to (docs/formats.md)
DECIMALS = {"time": 3, "lat": 8, "lon": 8, "x_m": 2, "y_m": 2, "vx_mps": 3, "vy_mps": 3, "sd_x_m": 2, "sd_y_m": 2,
            "altitude_m": 1, "range_bias_m": 3, "azimuth_bias_deg": 6, "sd_range_m": 3, "sd_azimuth_deg": 6}
_CSV = pacsv.WriteOptions(include_header=False, quoting_style="needed")  # texts quoted: a radar id may hold a comma
# events.csv and tracks.csv hold numbers and codes (kinds, statuses, hexadecimal and octal codes): never a
# comma or a quote, so nothing is quoted
_CSV_CODES = pacsv.WriteOptions(include_header=False, quoting_style="none")
_NO_TEXT = pa.scalar(None, pa.string())
log = logging.getLogger(__name__)


def prepare(out: Path | str, *, overwrite: bool = False) -> Path:
    """The output folder, created and writable; earlier results are refused, or with ``overwrite`` kept
    until this run's files replace them (:func:`write_outputs`): a run that fails leaves them intact."""
    return prepare_output_folder(out, OUTPUT_FILES, overwrite=overwrite, keep_earlier=True)


def _numbers(x, column: str, *, optional: bool = False) -> pa.Array:
    """The column's numbers rounded to its decimals d (:data:`DECIMALS`; ``numpy.round``: rint(x·10^d) / 10^d,
    half to even, within an ulp of the decimal; x itself where x·10^d overflows, as it then has no digit
    below 10^-d); ``optional``: null (an empty field) where not finite, else written ``nan``, ``inf``."""
    x = np.asarray(x, float)
    with np.errstate(over="ignore", invalid="ignore"):
        r = np.round(x, DECIMALS[column])
    v = np.where(np.isinf(r), x, r)
    return pa.array(v, pa.float64(), mask=~np.isfinite(v) if optional else None)


def _texts(values) -> pa.Array:
    """Texts (``str`` or ``None`` each), null (an empty field) where ``None`` or empty."""
    a = pa.array(values, pa.string())
    return pc.if_else(pc.equal(a, ""), _NO_TEXT, a)


def _rows(ev: Events, plane) -> tuple[pa.Table, pa.Table]:
    """The rows of ``events.csv`` and of ``tracks.csv`` (the track estimates among them, without event and
    status) for ``ev``, as tables of the files' columns."""
    lat, lon = plane.to_geodetic(ev.state[:, 0], ev.state[:, 1])
    s = ev.state
    with np.errstate(invalid="ignore"):  # a negative variance: no standard deviation, an empty field
        sd_x, sd_y = np.sqrt(ev.cov[:, 0, 0]), np.sqrt(ev.cov[:, 1, 1])
    columns = [_numbers(ev.time, "time"), pa.array(ev.track, pa.int64()), _texts(ev.kind), _texts(ev.status),
               _numbers(lat, "lat"), _numbers(lon, "lon"), _numbers(s[:, 0], "x_m"), _numbers(s[:, 1], "y_m"),
               _numbers(s[:, 2], "vx_mps"), _numbers(s[:, 3], "vy_mps"), _numbers(sd_x, "sd_x_m", optional=True),
               _numbers(sd_y, "sd_y_m", optional=True), _numbers(ev.altitude_m, "altitude_m", optional=True),
               _texts(ev.mode_s), _texts(ev.mode_3a)]
    # numbers to text once: tracks.csv's rows are events.csv's estimates, the same texts
    columns = [c if pa.types.is_string(c.type) else pc.cast(c, pa.string()) for c in columns]
    events = pa.Table.from_arrays(columns, names=list(EVENT_COLUMNS))
    return events, events.filter(pa.array(ev.estimate_mask(), pa.bool_())).select(list(TRACK_COLUMNS))


def _bias_rows(b: BiasLog) -> pa.Table:
    """The rows of ``biases.csv`` for ``b``: Δr (m) and Δθ (degrees) with their standard deviations."""
    with np.errstate(invalid="ignore"):
        sd = np.sqrt(b.cov[:, [0, 1], [0, 1]])
    columns = [_numbers(b.time, "time"), _texts([str(r) for r in b.radar.tolist()]),
               _numbers(b.value[:, 0], "range_bias_m"), _numbers(np.degrees(b.value[:, 1]), "azimuth_bias_deg"),
               _numbers(sd[:, 0], "sd_range_m"), _numbers(np.degrees(sd[:, 1]), "sd_azimuth_deg")]
    return pa.Table.from_arrays(columns, names=list(BIAS_COLUMNS))


def table_rows(ev: Events, biases: BiasLog, plane) -> tuple[pa.Table, pa.Table, pa.Table]:
    """The rows of ``events.csv``, ``tracks.csv`` and ``biases.csv``."""
    return (*_rows(ev, plane), _bias_rows(biases))


def _write_rows(f, table: pa.Table, options: pacsv.WriteOptions = _CSV) -> None:
    """``table``'s rows (no header) as CSV onto the binary file ``f``."""
    if table.num_rows:
        pacsv.write_csv(table, f, options)


class OutputStream:
    """``tracks.csv``, ``events.csv`` and ``biases.csv`` written as a run goes, each to a temporary file in the
    output folder; :func:`write_outputs` puts them in place with the run's other files once all are complete
    (:meth:`finish`), :meth:`abort` removes them. Rows as :func:`write_outputs` writes them."""

    def __init__(self, out: Path | str, plane) -> None:
        self.out, self.plane = Path(out), plane
        self.out.mkdir(parents=True, exist_ok=True)
        self.paths = {name: staging_path(self.out, name) for name in ("tracks.csv", "events.csv", "biases.csv")}
        self._files = {name: open(path, "wb") for name, path in self.paths.items()}  # noqa: SIM115 (closed in finish)
        for name, cols in (("tracks.csv", TRACK_COLUMNS), ("events.csv", EVENT_COLUMNS), ("biases.csv", BIAS_COLUMNS)):
            self._files[name].write(_header(cols))

    def events(self, ev: Events) -> None:
        events, tracks = _rows(ev, self.plane)
        _write_rows(self._files["events.csv"], events, _CSV_CODES)
        _write_rows(self._files["tracks.csv"], tracks, _CSV_CODES)

    def biases(self, b: BiasLog) -> None:
        _write_rows(self._files["biases.csv"], _bias_rows(b))

    def finish(self) -> dict[str, Path]:
        """The three files, complete and closed: name → temporary path."""
        for f in self._files.values():
            f.close()
        return dict(self.paths)

    def abort(self, exc: BaseException | None = None) -> None:
        for f in self._files.values():
            f.close()
        for path in self.paths.values():
            path.unlink(missing_ok=True)


def _header(columns: tuple[str, ...]) -> bytes:
    return (",".join(columns) + "\n").encode("utf-8")


def write_outputs(result: RunResult, out: Path | str, *, figures: bool = False, summary: dict | None = None,
                  streamed: OutputStream | None = None) -> None:
    """Write the run's files into ``out`` (prepared by :func:`prepare`; created if missing). They replace the
    earlier run's together once all are written (:func:`radartracker.io.atomic.replace_outputs`,
    ``config.json`` last): a failure, a full disk included, leaves the earlier run as it was. The three tables
    come from ``streamed`` when the run wrote them as it went. ``summary``: ``result.summary()``, when the
    caller made it already (a streamed run, before its tables replaced the earlier run's)."""
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
                _write_tables(result, stage)
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


def _write_tables(result: RunResult, stage) -> None:
    events, tracks, biases = table_rows(result.events, result.biases, result.plane)
    for name, cols, table, options in (("tracks.csv", TRACK_COLUMNS, tracks, _CSV_CODES),
                                       ("events.csv", EVENT_COLUMNS, events, _CSV_CODES),
                                       ("biases.csv", BIAS_COLUMNS, biases, _CSV)):
        with open(stage(name), "wb") as f:
            f.write(_header(cols))
            _write_rows(f, table, options)


def _config_text(result: RunResult) -> str:
    """``config.json``: the effective settings (read back by ``replay --config``) and, for the record,
    the plugins' effective typed settings."""
    doc = json.loads(result.config.to_json())
    doc["plugins"] = result.plugins
    return json.dumps(doc, indent=1, allow_nan=False, default=str) + "\n"


def write_config(result: RunResult, path: Path | str) -> None:
    """``config.json`` of ``result`` at ``path``, atomically."""
    write_text(path, _config_text(result))
