"""Plot tracks from a scenario folder's radar plots or from ``.new4`` files.

Scenario plots are grouped per aircraft by the truth label ``target`` where the file has one, else
by Mode S address; plots with neither (false plots, primary-only) are skipped and counted. Each
plot is converted exactly to the plane with C = D and R = D W Dᵀ (:func:`radartracker.measurement.convert_plots`).
A ``.new4`` file holds positions already (time, lat, lon, altitude): its plots get an isotropic
R = σ² I (``sigma_m``) and no bias Jacobian, on a plane centred on the file's mean position —
unless it holds a radar's plots (``<radar>_r.new4`` from ``radartracker convert``) and that radar
is known (:func:`new4_set_tracks`): then each point is taken back to the radar's polar frame and
gets the exact R = D W Dᵀ and C = D of a scenario plot, and the plots of every radar in one
aircraft folder are fused into one track.
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np

from radartracker.api import (InputError, Radar, RadarFrame, ScenarioData, SystemPlane, convert_plots, fill_altitudes,
                              plot_keys, read_new4)
from radartracker_plugins.reconstruction.objects import PlotTrack

DEFAULT_ALTITUDE_M = 3000.0


def scenario_tracks(data: ScenarioData, min_plots: int = 10, keys: np.ndarray | None = None
                    ) -> tuple[list[PlotTrack], SystemPlane, Counter]:
    """One plot track per aircraft of a scenario, the system plane, and counts of skipped plots; ``keys``: each
    plot's aircraft key (None: none) when the caller groups the plots, else the truth label or Mode S address."""
    plane = SystemPlane(*data.reference)
    plots = data.plots
    if keys is None:
        keys = plot_keys(plots, any(t is not None for t in plots.target))
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
        tracks.append(PlotTrack(str(key), m.time[idx], m.z[idx], h, m.radar[idx], m.R[idx], m.C[idx],
                                plots.range_m[idx]))
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


def new4_set_tracks(paths: list[Path], radars: list[Radar], sigma_m: float) -> tuple[list[PlotTrack], dict, Counter]:
    """Plot tracks of ``.new4`` files: the ``<radar>_r.new4`` files of known radars are fused per
    aircraft folder (key: the folder name) with each plot's polar R and C; any other file is one
    track with R = σ² I (:func:`new4_track`). Returns (tracks, plane per key, counts of skipped points)."""
    by_id = {r.id: r for r in radars}
    groups: dict[Path, list[tuple[Radar, Path]]] = {}
    tracks, planes, skipped = [], {}, Counter()
    for p in paths:
        stem = Path(p).stem
        if stem.endswith("_r") and stem[:-2] in by_id:
            groups.setdefault(Path(p).parent, []).append((by_id[stem[:-2]], Path(p)))
            continue
        pt, plane = new4_track(p, sigma_m)
        tracks.append(pt)
        planes[pt.key] = plane
    for folder, files in sorted(groups.items()):
        pts = [(r, read_new4(f)) for r, f in files]
        lat = np.concatenate([q.lat for _, q in pts])
        lon = np.concatenate([q.lon for _, q in pts])
        plane = SystemPlane(float(np.mean(lat)), float(np.mean(lon)))
        parts = []
        for radar, q in pts:
            alt = np.where(np.isfinite(q.altitude_m), q.altitude_m, DEFAULT_ALTITUDE_M)
            frame = RadarFrame(radar.lat, radar.lon, radar.height_m, plane)
            rho, _, _ = frame.polar(q.lat, q.lon, alt)
            x, y = plane.to_plane(q.lat, q.lon)
            z = np.column_stack([x, y])
            C = frame.bias_jacobian(z, rho, alt)
            R = C @ radar.W @ C.transpose(0, 2, 1)
            ok = np.isfinite(z).all(axis=1) & (np.linalg.eigvalsh(R)[:, 0] > 0)
            skipped["bad geometry"] += int((~ok).sum())
            parts.append((q.time[ok], z[ok], q.altitude_m[ok], np.full(ok.sum(), radar.id, dtype=object), R[ok], C[ok]))
        t, z, h, rid, R, C = (np.concatenate(c) for c in zip(*parts))
        order = np.argsort(t, kind="stable")
        key = folder.name or "aircraft"
        if len(order) < 2:
            skipped["aircraft with < 2 plots"] += len(order)
            continue
        tracks.append(PlotTrack(key, t[order], z[order], h[order], rid[order], R[order], C[order]))
        planes[key] = plane
    return tracks, planes, +skipped


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
