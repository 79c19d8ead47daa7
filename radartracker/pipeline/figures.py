"""Figures of replay results (matplotlib, non-interactive backend)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

if TYPE_CHECKING:
    from radartracker.pipeline.replay import ReplayResult


def plot_biases(result: ReplayResult, path: Path) -> None:
    """Range and azimuth bias estimates of every radar over time with ±2σ bands and the truth."""
    radars = list(result.final_biases)
    fig, axes = plt.subplots(2, len(radars), figsize=(4 * len(radars), 6), sharex=True, squeeze=False)
    truth = result.data.truth_biases or {}
    for j, rid in enumerate(radars):
        idx = result.bias_radar == rid
        t = result.bias_time[idx] - (result.bias_time[0] if len(result.bias_time) else 0.0)
        for row, (scale, unit) in enumerate(((1.0, "m"), (math.degrees(1.0), "deg"))):
            ax = axes[row, j]
            v = result.bias_value[idx, row] * scale
            sd = np.sqrt(result.bias_cov[idx, row, row]) * scale
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
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_tracks_over_truth(result, path: Path) -> None:
    """Confirmed tracks (coloured) over the true trajectories (grey) in the system plane (km)."""
    plane = result.manager.plane
    fig, ax = plt.subplots(figsize=(8, 8))
    d = result.data
    if d.truth is not None:
        x, y = plane.to_plane(d.truth.lat, d.truth.lon)
        for tg in np.unique(d.truth.target.astype(str)):
            m = d.truth.target == tg
            ax.plot(x[m] / 1e3, y[m] / 1e3, color="0.6", lw=3, alpha=0.6)
    for tid, h in result.histories().items():
        ax.plot(h.states[:, 0] / 1e3, h.states[:, 1] / 1e3, lw=1, label=f"track {tid}")
    for rid, fr in result.manager.frames.items():
        ax.plot(fr.xy[0] / 1e3, fr.xy[1] / 1e3, "k^")
        ax.annotate(rid, fr.xy / 1e3)
    ax.set_aspect("equal")
    ax.set_xlabel("x east (km)")
    ax.set_ylabel("y north (km)")
    ax.set_title(f"{d.name}: confirmed tracks (colour) over truth (grey)")
    if len(result.histories()) <= 20:
        ax.legend(fontsize=7, loc="best")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
