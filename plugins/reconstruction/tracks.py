"""Plot tracks from a scenario folder's radar plots or from ``.new4`` files.

Scenario plots are grouped per aircraft by the truth label ``target`` where the file has one, else
by Mode S address; plots with neither (false plots, primary-only) are skipped and counted. Each
plot is converted exactly to the plane with C = D and R = D W Dᵀ (:func:`radartracker.measurement.convert_plots`).
A ``.new4`` file holds positions already (time, lat, lon, altitude): its plots get an isotropic
R = σ² I (``sigma_m``) and no bias Jacobian, on a plane centred on the file's mean position.
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np

from radartracker.api import ScenarioData, SystemPlane, convert_plots, fill_altitudes, plot_keys, read_new4
from radartracker_plugins.reconstruction.objects import PlotTrack
from radartracker.api import InputError

DEFAULT_ALTITUDE_M = 3000.0


def scenario_tracks(data: ScenarioData, min_plots: int = 10) -> tuple[list[PlotTrack], SystemPlane, Counter]:
    """One plot track per aircraft of a scenario, the system plane, and counts of skipped plots."""
    plane = SystemPlane(*data.reference)
    plots = data.plots
    use_truth = any(t is not None for t in plots.target)
    keys = plot_keys(plots, use_truth)
    alt, _ = fill_altitudes(plots, keys, DEFAULT_ALTITUDE_M)
    m = convert_plots(plots, data.radars, plane, keys, alt)
    skipped: Counter = Counter()
    skipped["no aircraft key"] = int(sum(k is None for k in keys))
    tracks = []
    for key in sorted({k for k in keys if k is not None}):
        idx = np.flatnonzero(keys == key)
        bad = ~m.valid[idx]
        skipped["conversion failed"] += int(bad.sum())
        idx = idx[~bad]
        idx = idx[np.argsort(m.time[idx], kind="stable")]
        if len(idx) < min_plots:
            skipped[f"aircraft with < {min_plots} plots"] += len(idx)
            continue
        h = plots.altitude_m[idx]
        tracks.append(PlotTrack(str(key), m.time[idx], m.z[idx], h, m.radar[idx], m.R[idx], m.C[idx]))
    return tracks, plane, +skipped


def new4_track(path: Path | str, sigma_m: float) -> tuple[PlotTrack, SystemPlane]:
    """The plot track of one ``.new4`` file (key: the file's parent folder and stem)."""
    path = Path(path)
    pts = read_new4(path)
    if len(pts.time) < 2:
        raise InputError(f"{path}: fewer than 2 points")
    order = np.argsort(pts.time, kind="stable")
    plane = SystemPlane(float(np.mean(pts.lat)), float(np.mean(pts.lon)))
    x, y = plane.to_plane(pts.lat[order], pts.lon[order])
    n = len(order)
    R = np.tile(np.eye(2) * sigma_m**2, (n, 1, 1))
    key = f"{path.parent.name}_{path.stem}" if path.parent.name else path.stem
    return PlotTrack(key, pts.time[order], np.column_stack([x, y]), pts.altitude_m[order],
                     np.full(n, path.stem, dtype=object), R, np.zeros((n, 2, 2))), plane


def scenario_truth(data: ScenarioData, plane: SystemPlane) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """True positions per aircraft key: times and plane positions (n, 2); empty without truth."""
    if data.truth is None:
        return {}
    tr = data.truth
    x, y = plane.to_plane(tr.lat, tr.lon)
    out = {}
    for key in set(tr.target):
        sel = tr.target == key
        order = np.argsort(tr.time[sel])
        out[str(key)] = (tr.time[sel][order], np.column_stack([x[sel][order], y[sel][order]]))
    return out
