"""Figures of a run (matplotlib, non-interactive backend), written atomically."""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from radartracker.io.atomic import atomic_path  # noqa: E402
from radartracker.pipeline.result import RunResult  # noqa: E402


def save(fig, path: Path | str, dpi: int = 110) -> None:
    """Save ``fig`` as PNG at ``path`` atomically and close it."""
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=dpi, format="png")
    plt.close(fig)


def plot_biases(result: RunResult, path: Path) -> None:
    """Range and azimuth bias estimates of every radar over time with ±2σ bands and the truth."""
    radars = list(result.final_biases)
    b = result.biases
    fig, axes = plt.subplots(2, len(radars), figsize=(4 * len(radars), 6), sharex=True, squeeze=False)
    truth = result.data.truth_biases or {}
    for j, rid in enumerate(radars):
        idx = b.radar == rid
        t = b.time[idx] - (b.time[0] if len(b.time) else 0.0)
        for row, (scale, unit) in enumerate(((1.0, "m"), (math.degrees(1.0), "deg"))):
            ax = axes[row, j]
            v = b.value[idx, row] * scale
            sd = np.sqrt(b.cov[idx, row, row]) * scale
            ax.fill_between(t, v - 2 * sd, v + 2 * sd, alpha=0.3, label="±2σ")
            ax.plot(t, v, lw=1, label="estimate")
            if rid in truth:
                ax.axhline(truth[rid][row] * scale, color="k", ls="--", lw=1, label="truth")
            ax.set_title(f"{rid}: {'range' if row == 0 else 'azimuth'} bias ({unit})")
            if row == 1:
                ax.set_xlabel("time since start (s)")
    axes[0, 0].legend(loc="best", fontsize=8)
    fig.suptitle(f"{result.data.name}: bias estimates, estimator '{result.estimator_name}'")
    fig.tight_layout()
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
    for tid, h in histories.items():
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
