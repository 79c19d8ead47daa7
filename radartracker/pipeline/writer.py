"""The one writer of a run's outputs (schema: docs/formats.md), each file written atomically.

``tracks.csv`` (the track estimates), ``events.csv`` (every track event), ``biases.csv``,
``coupling.graphml``, figures on request, then ``summary.json`` and ``config.json`` last: a folder
with a ``config.json`` holds a complete run. The folder is prepared (checked for writing, earlier
results refused or removed) by :func:`prepare` before the computation starts.

The three tables are written either at the end (:func:`write_outputs`) or as the run goes
(:class:`OutputStream`, fed by the recorder), with the same bytes.
"""

from __future__ import annotations

import json
import logging
from contextlib import ExitStack
from pathlib import Path

import numpy as np

from radartracker.io.atomic import atomic_open, atomic_path, prepare_output_folder, write_text
from radartracker.pipeline.csvtext import Table
from radartracker.pipeline.recorder import BiasLog, Events
from radartracker.pipeline.result import RunResult

OUTPUT_FILES = ("tracks.csv", "events.csv", "biases.csv", "coupling.graphml", "biases.png", "tracks.png",
                "summary.json", "config.json")
TRACK_COLUMNS = ("time", "track", "lat", "lon", "x_m", "y_m", "vx_mps", "vy_mps", "sd_x_m", "sd_y_m", "altitude_m",
                 "mode_s", "mode_3a")
EVENT_COLUMNS = ("time", "track", "event", "status", "lat", "lon", "x_m", "y_m", "vx_mps", "vy_mps", "sd_x_m",
                 "sd_y_m", "altitude_m", "mode_s", "mode_3a")
log = logging.getLogger(__name__)
BIAS_COLUMNS = ("time", "radar", "range_bias_m", "azimuth_bias_deg", "sd_range_m", "sd_azimuth_deg")


def prepare(out: Path | str, *, overwrite: bool = False) -> Path:
    """The output folder, created and writable; earlier results are refused, or with ``overwrite`` kept
    until this run's files replace them (:func:`retire_earlier`): a run that fails leaves them intact."""
    return prepare_output_folder(out, OUTPUT_FILES, overwrite=overwrite, keep_earlier=True)


def retire_earlier(out: Path) -> None:
    """Mark the folder as not holding a finished run before this run's first file replaces an earlier
    one: ``config.json``, written last, goes first (a kill while files are replaced leaves no folder
    that looks complete)."""
    (out / "config.json").unlink(missing_ok=True)


def _code(v: object) -> str:
    """An identity code's field: empty for none."""
    return str(v) if v else ""


def _rows(ev: Events, plane) -> tuple[memoryview, memoryview]:
    """The rows of ``events.csv`` and of ``tracks.csv`` (the track estimates among them, without kind
    and status) for ``ev``, UTF-8 encoded: the columns made once, the rows written by one compiled pass
    (:mod:`radartracker.pipeline.csvtext`, the bytes of Python's ``%.<d>f``)."""
    if not len(ev):
        return memoryview(b""), memoryview(b"")
    lat, lon = plane.to_geodetic(ev.state[:, 0], ev.state[:, 1])
    s = ev.state
    with np.errstate(invalid="ignore"):  # a negative variance: no standard deviation, an empty field
        sd_x, sd_y = np.sqrt(ev.cov[:, 0, 0]), np.sqrt(ev.cov[:, 1, 1])
    t = (Table(len(ev)).number(ev.time, 3).integer(ev.track).labels(ev.kind.tolist()).labels(ev.status.tolist())
         .number(lat, 8).number(lon, 8).number(s[:, 0], 2).number(s[:, 1], 2).number(s[:, 2], 3)
         .number(s[:, 3], 3).number(sd_x, 2, optional=True).number(sd_y, 2, optional=True)
         .number(ev.altitude_m, 1, optional=True).labels(ev.mode_s.tolist(), _code)
         .labels(ev.mode_3a.tolist(), _code))
    return t.rows_and_part(ev.estimate_mask(), [0, 1, *range(4, 15)])


def _bias_rows(b: BiasLog) -> bytes:
    if not len(b.time):
        return b""
    with np.errstate(invalid="ignore"):
        sd = np.sqrt(b.cov[:, [0, 1], [0, 1]])
    return (Table(len(b.time)).number(b.time, 3).text(list(map(str, b.radar.tolist()))).number(b.value[:, 0], 3)
            .number(np.degrees(b.value[:, 1]), 6).number(sd[:, 0], 3).number(np.degrees(sd[:, 1]), 6).rows()
            .encode("utf-8"))


def table_rows(ev: Events, biases: BiasLog, plane) -> tuple[memoryview, memoryview, bytes]:
    """The rows (without header, UTF-8 encoded) of ``events.csv``, ``tracks.csv`` and ``biases.csv``."""
    return (*_rows(ev, plane), _bias_rows(biases))


class OutputStream:
    """``tracks.csv``, ``events.csv`` and ``biases.csv`` written as a run goes: each to a temporary file in
    the output folder, renamed over its name by :meth:`close` once complete (as every output file is,
    :mod:`radartracker.io.atomic`); :meth:`abort` removes them. Rows as :func:`write_outputs` writes them."""

    def __init__(self, out: Path | str, plane) -> None:
        self.out, self.plane = Path(out), plane
        out = self.out
        out.mkdir(parents=True, exist_ok=True)
        self._stack = ExitStack()
        self._tracks, self._events, self._biases = (
            self._stack.enter_context(atomic_open(out / name, "wb"))
            for name in ("tracks.csv", "events.csv", "biases.csv"))
        for f, cols in ((self._tracks, TRACK_COLUMNS), (self._events, EVENT_COLUMNS), (self._biases, BIAS_COLUMNS)):
            f.write(_header(cols))

    def events(self, ev: Events) -> None:
        events, tracks = _rows(ev, self.plane)
        self._events.write(events)
        self._tracks.write(tracks)

    def biases(self, b: BiasLog) -> None:
        self._biases.write(_bias_rows(b))

    def close(self) -> None:
        retire_earlier(self.out)
        self._stack.close()

    def abort(self, exc: BaseException) -> None:
        self._stack.__exit__(type(exc), exc, exc.__traceback__)


def _header(columns: tuple[str, ...]) -> bytes:
    return (",".join(columns) + "\n").encode("utf-8")


def write_outputs(result: RunResult, out: Path | str, *, figures: bool = False, summary: dict | None = None) -> None:
    """Write the run's files into ``out`` (prepared by :func:`prepare`; created if missing), each replacing
    the earlier run's atomically, ``config.json`` last; the three tables only if the run did not write
    them as it went (``result.streamed``). ``summary``: ``result.summary()``, when the caller made it
    already (a streamed run, before its tables replaced the earlier run's)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    if summary is None:  # the evaluation and the rows, before any earlier file is replaced
        summary = result.summary()
    rows = None if result.streamed else table_rows(result.events, result.biases, result.plane)
    retire_earlier(out)
    if rows is not None:
        events, tracks, biases = rows
        for name, cols, text in (("tracks.csv", TRACK_COLUMNS, tracks), ("events.csv", EVENT_COLUMNS, events),
                                 ("biases.csv", BIAS_COLUMNS, biases)):
            with atomic_open(out / name, "wb") as f:
                f.write(_header(cols))
                f.write(text)
    with atomic_path(out / "coupling.graphml") as tmp:
        result.coupling.write_graphml(tmp)
    if figures:
        from radartracker.pipeline.figures import plot_biases, plot_tracks_over_truth

        plot_biases(result, out / "biases.png")
        plot_tracks_over_truth(result, out / "tracks.png")
    else:  # an earlier run's figures would pass for this run's
        for name in ("biases.png", "tracks.png"):
            (out / name).unlink(missing_ok=True)
    for w in summary["consistency"]["warnings"]:
        log.warning("%s: %s", result.data.name or "run", w)
    write_text(out / "summary.json", json.dumps(summary, indent=1, allow_nan=False) + "\n")
    write_config(result, out / "config.json")


def write_config(result: RunResult, path: Path | str) -> None:
    """``config.json``: the effective settings (read back by ``replay --config``) and, for the record,
    the plugins' effective typed settings."""
    doc = json.loads(result.config.to_json())
    doc["plugins"] = result.plugins
    write_text(path, json.dumps(doc, indent=1, allow_nan=False, default=str) + "\n")
