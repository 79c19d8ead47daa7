"""The one writer of a run's outputs (schema: docs/formats.md), each file written atomically.

``tracks.csv`` (the track estimates), ``events.csv`` (every track event), ``biases.csv``,
``coupling.graphml``, figures on request, then ``summary.json`` and ``config.json`` last: a folder
with a ``config.json`` holds a complete run. The folder is prepared (checked for writing, earlier
results refused or removed) by :func:`prepare` before the computation starts.
"""

from __future__ import annotations

import json
import logging
import math
from pathlib import Path

import numpy as np

from radartracker.io.atomic import atomic_open, atomic_path, prepare_output_folder, write_text
from radartracker.pipeline.recorder import Events
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


def write_outputs(result: RunResult, out: Path | str, *, figures: bool = False) -> None:
    """Write the run's files into ``out`` (prepared by :func:`prepare`; created if missing)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    with atomic_open(out / "tracks.csv", "w", encoding="utf-8") as f:
        f.write(",".join(TRACK_COLUMNS) + "\n")
        f.writelines(_rows(result.tracks, result.plane, False))
    with atomic_open(out / "events.csv", "w", encoding="utf-8") as f:
        f.write(",".join(EVENT_COLUMNS) + "\n")
        f.writelines(_rows(result.events, result.plane, True))
    b = result.biases
    with atomic_open(out / "biases.csv", "w", encoding="utf-8") as f:
        f.write(",".join(BIAS_COLUMNS) + "\n")
        for t, r, v, P in zip(b.time, b.radar, b.value, b.cov):
            f.write(f"{t:.3f},{r},{v[0]:.3f},{math.degrees(v[1]):.6f},{math.sqrt(P[0, 0]):.3f},"
                    f"{math.degrees(math.sqrt(P[1, 1])):.6f}\n")
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
