"""Flights with known truth for tests and benchmarks, through the project's radar simulator.

:func:`simulate_flight` flies a trajectory (a :class:`radartracker.simulate.KinematicTrajectory`
with known controls, or a recorded flight) past rotating radars with the given noise and periods,
using :class:`radartracker.simulate.Simulator`, and returns the aircraft's plot track and its
true positions at the plot times.
"""

from __future__ import annotations

import math

import numpy as np

from radartracker.api import Aircraft, Radar, SimAircraft, SimRadar, Simulator, SystemPlane
from radartracker_plugins.reconstruction.objects import PlotTrack
from radartracker_plugins.reconstruction.tracks import scenario_tracks

REFERENCE = (48.85, 2.35)


def radars_around(plane: SystemPlane, sites_km, periods_s, sigma_range_m: float = 70.0,
                  sigma_azimuth_deg: float = 0.08, max_range_km: float = 400.0) -> list[Radar]:
    """Radars at plane sites (km) with the given rotation periods and noise."""
    out = []
    for i, ((x, y), T) in enumerate(zip(sites_km, periods_s)):
        lat, lon = plane.to_geodetic(x * 1e3, y * 1e3)
        out.append(Radar(f"R{i}", float(lat), float(lon), 50.0, sigma_range_m, math.radians(sigma_azimuth_deg),
                         float(T), max_range_km * 1e3))
    return out


def simulate_flight(trajectory, radars: list[Radar], seed: int = 0, reference=REFERENCE,
                    biases=None, pd: float = 1.0) -> tuple[PlotTrack, np.ndarray]:
    """(plot track, true plane positions (n, 2) at the plot times) of one flight.

    ``biases`` are per-radar (Δr m, Δθ rad), zero by default.
    """
    biases = biases or [(0.0, 0.0)] * len(radars)
    sims = [SimRadar(r, b[0], b[1], pd=pd, phase_rad=float(np.random.default_rng([seed, j]).uniform(0, 2 * np.pi)))
            for j, (r, b) in enumerate(zip(radars, biases))]
    ac = SimAircraft(Aircraft("abc123"), trajectory)
    data = Simulator(reference, sims, [ac], trajectory.t_start, trajectory.t_end, seed=seed).run()
    tracks, _, _ = scenario_tracks(data, min_plots=2)
    pt = tracks[0]
    x, y, _ = trajectory.position(pt.t)
    return pt, np.column_stack([x, y])
