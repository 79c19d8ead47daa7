"""Scoring the service's output: a CAT062 capture (:func:`radartracker.io.asterix.read_cat062`)
against a scenario's truth, with the replay's track metrics (:func:`radartracker.pipeline.evaluate.
track_metrics`: continuity, swaps, breaks, false tracks — CLEAR MOT assignment on a 2 s grid).

Each track's published updates (I070 time, I105 position, I185 velocity) form its history; a track is a
sender's track number from its first update to a TSE record or a gap of more than
:attr:`~radartracker.assessment.systracks.SystemTrackConfig.max_gap_s` (trackers reuse numbers:
:func:`~radartracker.assessment.systracks.split_tracks`, as the assessment reads CAT062). Positions are
read from I105 (WGS-84) and projected onto a plane centred on the radars' mean position, where the truth
is projected too: a capture's I100 plane positions are in the
sending system's own plane, which the capture does not name (scoring I100 as if it were ours gave
1 675 m RMSE and 8 false tracks on a replay whose plane was centred elsewhere, issue 33), so a capture
whose updates lack I105 is refused. I185 is taken as it is, in the sender's axes: between two
stereographic planes a few degrees apart they turn by under a degree, which over the seconds a
position is extrapolated between updates is metres.
A target counts as observed from ``GRACE_S`` after its first labelled plot to its last, as in a
replay's evaluation. Command line: ``radartracker score CAPTURE --scenario DIR`` (one JSON line).
"""

from __future__ import annotations

import numpy as np

from radartracker.assessment.systracks import SystemTrackConfig, split_tracks
from radartracker.errors import InputError
from radartracker.geometry.plane import SystemPlane
from radartracker.io.tables import ScenarioData
from radartracker.pipeline.evaluate import TruthPaths, track_metrics
from radartracker.pipeline.result import GRACE_S


def placed(records: list[dict], plane: SystemPlane) -> list[dict]:
    """The track updates with ``x_m``, ``y_m`` from their I105 position in ``plane`` (module docstring);
    an InputError if any update has none."""
    live = [r for r in records if not r["ended"]]
    missing = sum(1 for r in live if r["lat"] is None or r["lon"] is None)
    if missing:
        raise InputError(f"{missing} of {len(live)} CAT062 track updates have no I105 (WGS-84 position); their "
                         "I100 positions are in the sending system's plane, which the capture does not name")
    if not live:
        return list(records)
    x, y = plane.to_plane(np.array([r["lat"] for r in live], float), np.array([r["lon"] for r in live], float))
    xy = iter(zip(x.tolist(), y.tolist()))  # the live records' positions, in their order
    return [r if r["ended"] else r | dict(zip(("x_m", "y_m"), next(xy))) for r in records]


def score_cat062(records: list[dict], data: ScenarioData, step_s: float = 2.0) -> dict:
    """Track metrics of the published tracks against ``data``'s truth (which must have plot labels), and
    ``positions``: where the positions came from."""
    if data.truth is None:
        raise InputError("the scenario has no truth to score against")
    plane = SystemPlane(float(np.mean([r.lat for r in data.radars])), float(np.mean([r.lon for r in data.radars])))
    records = placed(records, plane)
    labelled = np.array([t is not None for t in data.plots.target], bool)
    if not labelled.any():
        raise InputError("the scenario's plots carry no target labels to score against")
    observed, first = {}, {}
    for tg in np.unique(data.plots.target[labelled].astype(str)):
        t = data.plots.time[data.plots.target == tg]
        if t.max() - t.min() > GRACE_S:
            observed[str(tg)], first[str(tg)] = (float(t.min()) + GRACE_S, float(t.max())), float(t.min())
    grid = np.arange(data.truth.time.min(), data.truth.time.max(), step_s)
    histories, _ = split_tracks(records, SystemTrackConfig().max_gap_s)
    metrics = track_metrics(histories, TruthPaths.from_table(data.truth, plane), observed, grid, first_seen=first)
    metrics.pop("gospa", None)
    return metrics | {"positions": "I105 (WGS-84)"}
