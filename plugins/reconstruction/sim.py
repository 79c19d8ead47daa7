"""Flights with known truth for tests and benchmarks, through the project's radar simulator.

:func:`simulate_flight` flies a trajectory (a :class:`radartracker.simulate.KinematicTrajectory`
with known controls, or a recorded flight) past rotating radars with the given noise and periods,
using :class:`radartracker.simulate.Simulator`, and returns the aircraft's plot track and its
true positions at the plot times. :func:`biased_scenario` is the Monte Carlo draw of the joint bias
estimate's consistency check: two biased radars, four flights of the seed's model with one turn each.
"""

from __future__ import annotations

import math

import numpy as np

from radartracker.api import (Aircraft, KinematicTrajectory, Leg, Radar, ScenarioData, SimAircraft, SimRadar, Simulator,
                              SystemPlane)
from radartracker_plugins.reconstruction.objects import ControlSegment, ControlTrack, GeoPoint, PlotTrack
from radartracker_plugins.reconstruction.tracks import scenario_tracks

REFERENCE = (48.85, 2.35)
BIASES = {"R0": (60.0, math.radians(0.08)), "R1": (-40.0, math.radians(-0.1))}  # (Δr m, Δθ rad)


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


def bias_flights(duration: float) -> dict[str, KinematicTrajectory]:
    """Four flights crossing two radars' coverage in different directions, a turn in the middle quarter."""
    q = duration / 4
    return {key: KinematicTrajectory(0.0, x0, y0, 6000.0, math.radians(hdg), v, [Leg(q), Leg(q, u=u), Leg(duration - 2 * q)])
            for key, x0, y0, hdg, v, u in (("b00001", -20e3, -15e3, 45, 180, 2.0), ("b00002", 15e3, -20e3, 330, 160, -1.5),
                                           ("b00003", 20e3, 15e3, 220, 200, 1.0), ("b00004", -15e3, 20e3, 120, 170, -2.0))}


def biased_scenario(seed: int, duration: float = 200.0, sensor: dict[str, dict[str, float]] | None = None
                    ) -> tuple[ScenarioData, dict[str, KinematicTrajectory]]:
    """(scenario, trajectory per aircraft key): :func:`bias_flights` past radars R0, R1 at (−45, −25) and
    (35, 40) km (σ 70 m / 0.08°, periods 4 and 5 s) with the biases :data:`BIASES` and ``sensor``'s further
    errors (radar id → ``range_gain``, ``time_offset_s``); no ADS-B."""
    plane = SystemPlane(*REFERENCE)
    radars = radars_around(plane, [(-45.0, -25.0), (35.0, 40.0)], [4.0, 5.0])
    sims = [SimRadar(r, *BIASES[r.id], phase_rad=float(np.random.default_rng([seed, j]).uniform(0, 2 * np.pi)),
                     **(sensor or {}).get(r.id, {}))
            for j, r in enumerate(radars)]
    flights = bias_flights(duration)
    aircraft = [SimAircraft(Aircraft(key), traj) for key, traj in flights.items()]
    return Simulator(REFERENCE, sims, aircraft, 0.0, duration, seed=seed).run(), flights


def true_control(traj: KinematicTrajectory, t0: float, t1: float) -> ControlTrack:
    """A trajectory's own control track over [t0, t1] (e.g. the span of its plots)."""
    x, y, _, phi, v = (float(a[0]) for a in traj.state(np.array([t0])))
    edges = np.cumsum([traj.t_start] + [leg.duration for leg in traj.legs])
    segs = [ControlSegment(leg.u, leg.w, max(a, t0), min(b, t1))
            for leg, a, b in zip(traj.legs, edges[:-1], edges[1:]) if min(b, t1) - max(a, t0) > 1.0]
    return ControlTrack(GeoPoint(t0, x, y, phi, v), segs)
