"""Which plots make one aircraft for the reconstructed reference (:func:`~radartracker.assessment.reference.
add_reconstructed`).

A plot with a Mode S address belongs to that address. A plot without one (a primary or Mode A/C plot) that no
aircraft of the reference so far holds in its gate goes with the system track whose estimate at the plot's time
is nearest to it inside the assessment's gate (:func:`~radartracker.assessment.matching.associate`: d² =
(Δρ/G_ρ)² + (Δθ/G_θ)² ≤ 1, the radar's bias estimate removed), and the plots of one track are one aircraft,
keyed ``track-<id>``; a plot in no gate has no group. The tracker's association only groups the plots: the
reference is then the reconstruction of those plots, not the track. A track's estimate has no height when its
plots carry none; its slant range is taken at :data:`TRACK_HEIGHT_M`, whose error moves ρ by about h δh / ρ
(under 0.4 km for 3 km at 50 km): inside the 1 km gate.
"""

from __future__ import annotations

import numpy as np

from radartracker.assessment.matching import MatchConfig, associate
from radartracker.assessment.reference import Reference, ReferenceTrack
from radartracker.geometry.plane import RadarFrame
from radartracker.io.tables import ScenarioData
from radartracker.pipeline.evaluate import TrackHistory
from radartracker.simulation.simulator import RecordedTrajectory

TRACK_HEIGHT_M = 6000.0  # the height a system track without one is taken at (the manager's assumed height)


def track_reference(reference: Reference, histories: dict[int, TrackHistory]) -> Reference:
    """The system tracks as a reference to associate plots with: each track's estimates joined by straight lines
    (at its distinct times), at :data:`TRACK_HEIGHT_M`, over its life."""
    tracks = {}
    for tid, h in histories.items():
        keep = np.concatenate([[True], np.diff(h.times) > 0])
        t, xy = h.times[keep], h.states[keep, :2]
        if len(t) >= 2:
            traj = RecordedTrajectory(t, xy[:, 0], xy[:, 1], np.full(len(t), TRACK_HEIGHT_M), smooth=False)
            tracks[f"track-{tid}"] = ReferenceTrack(t, traj, None, None, np.inf)
    return Reference("system tracks", reference.plane, tracks)


def plot_groups(data: ScenarioData, reference: Reference, histories: dict[int, TrackHistory],
                biases: dict[str, tuple[float, float]], config: MatchConfig) -> np.ndarray:
    """Each plot's aircraft key for the reconstruction (module docstring): its Mode S address, else ``track-<id>``,
    else None. ``reference``: the aircraft that already have one (validated ADS-B); ``biases``: each radar's
    (Δr m, Δθ rad) estimate."""
    plots = data.plots
    keys = np.array([m if m else None for m in plots.mode_s.tolist()], dtype=object)
    todo = np.array([k is None for k in keys.tolist()], bool)
    systems = track_reference(reference, histories)
    if not todo.any() or not systems.tracks:
        return keys
    for radar in data.radars:
        rows = np.flatnonzero(todo & (plots.radar == radar.id))
        if not len(rows):
            continue
        frame = RadarFrame(radar.lat, radar.lon, radar.height_m, reference.plane)
        t = plots.time[rows]
        dr, dtheta = biases[radar.id]
        polar = (plots.range_m[rows] - dr, plots.azimuth_rad[rows] - dtheta)
        held = associate(frame, t, polar, reference, config)[0] != "" if reference.tracks else np.zeros(len(rows), bool)
        free = np.flatnonzero(~held)
        key = associate(frame, t[free], (polar[0][free], polar[1][free]), systems, config)[0]
        keys[rows[free]] = np.where(key == "", None, key)
    return keys
