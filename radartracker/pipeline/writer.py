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
import math
from contextlib import ExitStack
from pathlib import Path

import numpy as np

from radartracker.io.atomic import atomic_open, atomic_path, prepare_output_folder, write_text
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
    """The output folder, created and writable, without earlier results (``overwrite`` removes them)."""
    return prepare_output_folder(out, OUTPUT_FILES, overwrite=overwrite)


def _num(v: float, spec: str) -> str:
    return format(v, spec) if math.isfinite(v) else ""


def _rows(ev: Events, plane, with_kind: bool):
    lat, lon = plane.to_geodetic(ev.state[:, 0], ev.state[:, 1]) if len(ev) else (np.empty(0), np.empty(0))
    sd = np.sqrt(np.stack([ev.cov[:, 0, 0], ev.cov[:, 1, 1]], axis=-1)) if len(ev) else np.empty((0, 2))
    for i in range(len(ev)):
        x = ev.state[i]
        kind = f"{ev.kind[i]},{ev.status[i]}," if with_kind else ""
        yield (f"{ev.time[i]:.3f},{ev.track[i]},{kind}{lat[i]:.8f},{lon[i]:.8f},{x[0]:.2f},{x[1]:.2f},{x[2]:.3f},"
               f"{x[3]:.3f},{_num(sd[i, 0], '.2f')},{_num(sd[i, 1], '.2f')},{_num(ev.altitude_m[i], '.1f')},"
               f"{ev.mode_s[i] or ''},{ev.mode_3a[i] or ''}\n")


def _bias_rows(b: BiasLog):
    for t, r, v, P in zip(b.time, b.radar, b.value, b.cov):
        yield (f"{t:.3f},{r},{v[0]:.3f},{math.degrees(v[1]):.6f},{math.sqrt(P[0, 0]):.3f},"
               f"{math.degrees(math.sqrt(P[1, 1])):.6f}\n")


class OutputStream:
    """``tracks.csv``, ``events.csv`` and ``biases.csv`` written as a run goes: each to a temporary file in
    the output folder, renamed over its name by :meth:`close` once complete (as every output file is,
    :mod:`radartracker.io.atomic`); :meth:`abort` removes them. Rows as :func:`write_outputs` writes them."""

    def __init__(self, out: Path | str, plane) -> None:
        out, self.plane = Path(out), plane
        out.mkdir(parents=True, exist_ok=True)
        self._stack = ExitStack()
        self._tracks, self._events, self._biases = (
            self._stack.enter_context(atomic_open(out / name, "w", encoding="utf-8"))
            for name in ("tracks.csv", "events.csv", "biases.csv"))
        for f, cols in ((self._tracks, TRACK_COLUMNS), (self._events, EVENT_COLUMNS), (self._biases, BIAS_COLUMNS)):
            f.write(",".join(cols) + "\n")

    def events(self, ev: Events) -> None:
        self._events.writelines(_rows(ev, self.plane, True))
        self._tracks.writelines(_rows(ev.estimates(), self.plane, False))

    def biases(self, b: BiasLog) -> None:
        self._biases.writelines(_bias_rows(b))

    def close(self) -> None:
        self._stack.close()

    def abort(self, exc: BaseException) -> None:
        self._stack.__exit__(type(exc), exc, exc.__traceback__)


def write_outputs(result: RunResult, out: Path | str, *, figures: bool = False) -> None:
    """Write the run's files into ``out`` (prepared by :func:`prepare`; created if missing); the three
    tables only if the run did not write them as it went (``result.streamed``)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    if not result.streamed:
        with atomic_open(out / "tracks.csv", "w", encoding="utf-8") as f:
            f.write(",".join(TRACK_COLUMNS) + "\n")
            f.writelines(_rows(result.tracks, result.plane, False))
        with atomic_open(out / "events.csv", "w", encoding="utf-8") as f:
            f.write(",".join(EVENT_COLUMNS) + "\n")
            f.writelines(_rows(result.events, result.plane, True))
        with atomic_open(out / "biases.csv", "w", encoding="utf-8") as f:
            f.write(",".join(BIAS_COLUMNS) + "\n")
            f.writelines(_bias_rows(result.biases))
    with atomic_path(out / "coupling.graphml") as tmp:
        result.coupling.write_graphml(tmp)
    if figures:
        from radartracker.pipeline.figures import plot_biases, plot_tracks_over_truth

        plot_biases(result, out / "biases.png")
        plot_tracks_over_truth(result, out / "tracks.png")
    summary = result.summary()
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
