"""Figures of a run (matplotlib, non-interactive backend), written atomically, with a progress bar on stderr
once one takes 2 s (off with --quiet)."""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from radartracker.io.atomic import atomic_path  # noqa: E402
from radartracker.pipeline.result import RunResult  # noqa: E402
from radartracker.progress import progress_bar  # noqa: E402


def save(fig, path: Path | str, dpi: int = 110) -> None:
    """Save ``fig`` as PNG at ``path`` atomically and close it."""
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=dpi, format="png")
    plt.close(fig)


MAX_COLUMNS = 6  # radars side by side in biases.png; more radars go to more rows
MAX_HEIGHT_IN = 24.0  # biases.png's cells get lower with more rows, down to MIN_CELL_IN, within this height
MIN_CELL_IN = 2.6  # the lowest cell (two panels, titles and ticks) that stays legible


def bias_grid(radars: int) -> tuple[int, int, tuple[float, float]]:
    """(rows, columns, figure size in inches) of biases.png for this many radars: small multiples, one cell
    of two panels (range over azimuth) per radar, at most :data:`MAX_COLUMNS` cells a row, the whole at most
    :data:`MAX_HEIGHT_IN` high up to 54 radars (28 radars: 5 rows of 6, 19.2 × 18.5 in, 2112 × 2035 px at
    110 dpi); beyond, :data:`MIN_CELL_IN` more per row."""
    cols = max(1, min(radars, MAX_COLUMNS))
    rows = max(1, math.ceil(radars / cols))
    cell_height = max(MIN_CELL_IN, min(3.6, (MAX_HEIGHT_IN - 0.5) / rows))
    return rows, cols, (max(3.2 * cols, 6.4), cell_height * rows + 0.5)  # at least the title's width


def plot_biases(result: RunResult, path: Path) -> None:
    """Range and azimuth bias estimates of every radar over time with ±2σ bands and the truth, a cell of two
    panels per radar in a grid (:func:`bias_grid`)."""
    radars = list(result.final_biases)
    rows, cols, size = bias_grid(len(radars))
    fig, axes = plt.subplots(2 * rows, cols, figsize=size, sharex=True, squeeze=False)
    b = result.biases
    truth = result.data.truth_biases or {}
    t0 = b.time[0] if len(b.time) else 0.0
    for k, rid in enumerate(progress_bar(radars, desc=f"figure {Path(path).name}", unit="radar")):
        idx = b.radar == rid
        for row, (scale, unit, what) in enumerate(((1.0, "m", "range"), (math.degrees(1.0), "deg", "azimuth"))):
            ax = axes[2 * (k // cols) + row, k % cols]
            v = b.value[idx, row] * scale
            sd = np.sqrt(b.cov[idx, row, row]) * scale
            ax.fill_between(b.time[idx] - t0, v - 2 * sd, v + 2 * sd, alpha=0.3, label="±2σ")
            ax.plot(b.time[idx] - t0, v, lw=1, label="estimate")
            if rid in truth:
                ax.axhline(truth[rid][row] * scale, color="k", ls="--", lw=1, label="truth")
            ax.set_title(f"{rid}: {what} bias ({unit})" if row == 0 else f"{what} bias ({unit})", fontsize=9)
            ax.tick_params(labelsize=7)
    for k in range(len(radars), rows * cols):  # the last row's empty cells
        axes[2 * (k // cols), k % cols].set_axis_off()
        axes[2 * (k // cols) + 1, k % cols].set_axis_off()
    for c in range(min(cols, len(radars))):  # the lowest panel of each column: below it, cells may be empty
        ax = axes[2 * ((len(radars) - 1 - c) // cols) + 1, c]
        ax.xaxis.set_tick_params(labelbottom=True)
        ax.set_xlabel("time since start (s)", fontsize=8)
    axes[0, 0].legend(loc="best", fontsize=7)
    fig.suptitle(f"{result.data.name}: bias estimates, estimator '{result.estimator_name}'")
    fig.tight_layout(rect=(0.0, 0.0, 1.0, 1.0 - 0.4 / size[1]))  # the title's 0.4 in kept free
    save(fig, path)


def plot_tracks_over_truth(result: RunResult, path: Path) -> None:
    """Track estimates (coloured) over the true trajectories (grey) in the system plane (km)."""
    plane = result.plane
    fig, ax = plt.subplots(figsize=(8, 8))
    d = result.data
    if d.truth is not None:
        x, y = plane.to_plane(d.truth.lat, d.truth.lon)
        for tg in np.unique(d.truth.target.astype(str)):
            m = d.truth.target == tg
            ax.plot(x[m] / 1e3, y[m] / 1e3, color="0.6", lw=3, alpha=0.6)
    histories = result.histories()
    for tid, h in progress_bar(histories.items(), desc=f"figure {Path(path).name}", unit="track",
                               total=len(histories)):
        ax.plot(h.states[:, 0] / 1e3, h.states[:, 1] / 1e3, lw=1, label=f"track {tid}")
    for r in d.radars:
        xy = np.array(plane.to_plane(r.lat, r.lon), float) / 1e3
        ax.plot(xy[0], xy[1], "k^")
        ax.annotate(r.id, xy)
    ax.set_aspect("equal")
    ax.set_xlabel("x east (km)")
    ax.set_ylabel("y north (km)")
    ax.set_title(f"{d.name}: tracks (colour) over truth (grey)")
    if len(histories) <= 20:
        ax.legend(fontsize=7, loc="best")
    fig.tight_layout()
    save(fig, path)
