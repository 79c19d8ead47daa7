"""Association by truth label, for evaluation on simulated data (the labelled replay).

A plot carrying a truth label (``Plot.target``) goes to the live track started from that label's plots,
else starts one; a plot without a label goes by its Mode S address, else it is refused
(``plots_unassociated``). The tracker is the same TrackManager: screening, filters, confirmation and
deletion apply exactly as with any other associator, so a labelled run measures the tracker with perfect
association.
"""

from __future__ import annotations

import numpy as np

from radartracker.api import NEW_TRACK, REFUSED, Association, Associator, Prediction, RadarPlots


class LabelAssociator(Associator):
    """Each plot to the track of its truth label (module docstring)."""

    name = "labels"
    labels = True  # the tracks it starts carry their first plot's truth label (Track.target)

    def associate(self, plots: RadarPlots, tracks: Prediction) -> Association:
        by_label = {tr.target: i for i, tr in enumerate(tracks.tracks) if tr.target is not None}
        out = np.full(len(plots.plots), NEW_TRACK, np.int64)
        reasons: dict[int, str] = {}
        taken: set[int] = set()
        for k, p in enumerate(plots.plots):
            i = by_label.get(p.target) if p.target is not None else tracks.by_mode_s.get(p.mode_s) if p.mode_s else None
            if not plots.valid[k]:
                out[k], reasons[k] = REFUSED, "plots_impossible_geometry"
            elif p.target is None and p.mode_s is None:
                out[k], reasons[k] = REFUSED, "plots_unassociated"
            elif i is not None and i in taken:
                out[k], reasons[k] = REFUSED, "plots_duplicate_in_scan"
            elif i is not None:
                out[k] = i
                taken.add(i)
        return Association(out, reasons)
