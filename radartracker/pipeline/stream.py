"""A scenario as the time-ordered stream of domain inputs a TrackManager (or the service) consumes."""

from __future__ import annotations

import math

from radartracker.domain import AdsbReport, Plot
from radartracker.io.tables import ScenarioData


def scenario_stream(data: ScenarioData) -> list[Plot | AdsbReport]:
    """The scenario's plots and ADS-B reports as :class:`Plot` / :class:`AdsbReport`, in time order
    (stable: plots before ADS-B reports at equal times, each in file order).

    ``mgr.process_many(scenario_stream(data))`` runs a whole scenario through a TrackManager.
    """
    p, a = data.plots, data.adsb
    items: list[Plot | AdsbReport] = [
        Plot(float(p.time[i]), p.radar[i], float(p.range_m[i]), float(p.azimuth_rad[i]),
             None if math.isnan(p.altitude_m[i]) else float(p.altitude_m[i]), p.mode_s[i], p.mode_3a[i], p.target[i])
        for i in range(len(p))]
    items += [AdsbReport(float(a.time[i]), a.icao24[i], float(a.lat[i]), float(a.lon[i]),
                         None if math.isnan(a.altitude_m[i]) else float(a.altitude_m[i]), int(a.nacp[i]))
              for i in range(len(a))]
    items.sort(key=lambda x: x.time)
    return items
