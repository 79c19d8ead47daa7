"""A scenario as the time-ordered stream of domain inputs a TrackManager (or the service) consumes."""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np

from radartracker.domain import AdsbReport, Plot
from radartracker.io.tables import ScenarioData


def scenario_stream(data: ScenarioData) -> list[Plot | AdsbReport]:
    """The scenario's plots and ADS-B reports as :class:`Plot` / :class:`AdsbReport`, in time order
    (stable: plots before ADS-B reports at equal times, each in file order).

    ``mgr.process_many(scenario_stream(data))`` runs a whole scenario through a TrackManager.
    """
    return list(iter_scenario(data))


def iter_scenario(data: ScenarioData) -> Iterator[Plot | AdsbReport]:
    """The items of :func:`scenario_stream`, in the same order, made one at a time as they are consumed
    (a list of every input would grow with the recording's length)."""
    p, a = data.plots, data.adsb
    n = len(p)
    for i in np.argsort(np.concatenate([p.time, a.time]), kind="stable").tolist():
        if i < n:
            yield Plot(float(p.time[i]), p.radar[i], float(p.range_m[i]), float(p.azimuth_rad[i]),
                       None if math.isnan(p.altitude_m[i]) else float(p.altitude_m[i]), p.mode_s[i], p.mode_3a[i],
                       p.target[i])
        else:
            i -= n
            yield AdsbReport(float(a.time[i]), a.icao24[i], float(a.lat[i]), float(a.lon[i]),
                             None if math.isnan(a.altitude_m[i]) else float(a.altitude_m[i]), int(a.nacp[i]))
