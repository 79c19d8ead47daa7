"""Built-in scenarios: the seed's own set-up and scenarios driven by real flights.

* ``seed`` — seed 000 §1's simulation: 8 aircraft in constant-velocity flight, 3 radars with
  constant range and azimuth biases, no process noise, no ADS-B, Pd = 1 (centred near Moscow).
* ``demo`` — ``seed`` plus ADS-B on two aircraft, which anchors the bias estimates.
* ``paris`` — real flights around Paris (OpenSky, shipped subset) with four simulated radars,
  Pd 0.9 and ADS-B on every third aircraft.
* ``manoeuvres`` — kinematic-model aircraft that turn at 3°/s, accelerate and climb.
* ``tracking`` — for association: two aircraft crossing and two flying in parallel 3 NM apart,
  all squawking the same Mode 3/A code (7000) so only kinematics tells them apart, a primary-only
  aircraft, a 3°/s turn and a climb; Pd 0.9 and two false plots per antenna revolution.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping

import attrs
import numpy as np

from radartracker.domain import Aircraft, Radar
from radartracker.errors import ConfigurationError
from radartracker.simulation.flights import load_flights
from radartracker.geometry.plane import SystemPlane
from radartracker.simulation.simulator import (KinematicTrajectory, Leg, RecordedTrajectory, SimAircraft, SimRadar, Simulator)


def _radar(plane: SystemPlane, rid: str, x_km: float, y_km: float, *, period: float, sr: float = 70.0,
           sa_deg: float = 0.08, height: float = 100.0, max_range_km: float = 250.0) -> Radar:
    lat, lon = plane.to_geodetic(x_km * 1e3, y_km * 1e3)
    return Radar(rid, float(lat), float(lon), height, sr, math.radians(sa_deg), period, max_range_km * 1e3)


def _icao(i: int) -> str:
    return f"{0x4b0000 + 17 * i:06x}"


def _squawk(i: int) -> str:
    return f"{(1000 + 37 * i) % 4096:04o}"


def _seed_like(seed: int, duration: float | None, *, adsb: tuple[int, ...], name: str) -> Simulator:
    reference = (55.75, 37.62)
    plane = SystemPlane(*reference)
    biases = [(120.0, 0.15), (-80.0, -0.10), (60.0, 0.20)]
    radars = [
        SimRadar(_radar(plane, "R1", -60, -40, period=4.0), biases[0][0], math.radians(biases[0][1])),
        SimRadar(_radar(plane, "R2", 70, -30, period=6.0), biases[1][0], math.radians(biases[1][1])),
        SimRadar(_radar(plane, "R3", 0, 80, period=10.0), biases[2][0], math.radians(biases[2][1])),
    ]
    rng = np.random.default_rng([seed, 99])
    duration = 1200.0 if duration is None else duration
    aircraft = []
    for i in range(8):
        heading = rng.uniform(0, 2 * np.pi)
        speed = rng.uniform(200.0, 260.0)
        # start on the far side of the centre so that the aircraft crosses the covered area
        start = -0.5 * speed * duration * np.array([math.sin(heading), math.cos(heading)])
        start += rng.uniform(-40e3, 40e3, 2)
        traj = KinematicTrajectory(0.0, start[0], start[1], rng.uniform(8000, 11000), heading, speed,
                                   [Leg(duration)])
        ac = Aircraft(_icao(i), f"SIM{i:03d}", _squawk(i), adsb=i in adsb, nacp=9)
        aircraft.append(SimAircraft(ac, traj))
    return Simulator(reference, radars, aircraft, 0.0, duration, seed=seed, name=name)


def seed_scenario(seed: int = 1, duration: float | None = None) -> Simulator:
    return _seed_like(seed, duration, adsb=(), name="seed")


def demo_scenario(seed: int = 1, duration: float | None = None) -> Simulator:
    return _seed_like(seed, duration, adsb=(0, 1), name="demo")


def paris_scenario(seed: int = 1, duration: float | None = None) -> Simulator:
    reference = (48.85, 2.35)
    plane = SystemPlane(*reference)
    radars = [
        SimRadar(_radar(plane, "ORLY", -2, -14, period=4.0), 90.0, math.radians(0.12), pd=0.9),
        SimRadar(_radar(plane, "CDG", 14, 22, period=4.0), -60.0, math.radians(-0.08), pd=0.9),
        SimRadar(_radar(plane, "EVREUX", -100, 10, period=10.0, sr=100.0, sa_deg=0.1), 150.0,
                 math.radians(0.2), pd=0.9),
        SimRadar(_radar(plane, "REIMS", 130, 20, period=8.0), -110.0, math.radians(-0.15), pd=0.9),
    ]
    flights = {k: f for k, f in load_flights().items() if k.startswith("paris-")}
    t0 = min(f.time[0] for f in flights.values())
    t1 = t0 + (3600.0 if duration is None else duration)
    aircraft = []
    for i, (fid, f) in enumerate(sorted(flights.items())):
        traj = RecordedTrajectory.from_geodetic(plane, f.time, f.lat, f.lon, f.altitude_m)
        ac = Aircraft(f.icao24, f.callsign.strip() or fid, _squawk(i), adsb=i % 3 == 0, nacp=8)
        aircraft.append(SimAircraft(ac, traj))
    return Simulator(reference, radars, aircraft, t0, t1, seed=seed, name="paris")


def manoeuvres_scenario(seed: int = 1, duration: float | None = None) -> Simulator:
    reference = (48.85, 2.35)
    plane = SystemPlane(*reference)
    radars = [
        SimRadar(_radar(plane, "A", -50, -30, period=4.0), 80.0, math.radians(0.1), pd=0.9),
        SimRadar(_radar(plane, "B", 60, 10, period=5.0), -50.0, math.radians(-0.12), pd=0.9),
    ]
    duration = 900.0 if duration is None else duration
    rng = np.random.default_rng([seed, 98])
    aircraft = []
    for i in range(6):
        v = rng.uniform(140, 230)
        legs = [Leg(120.0), Leg.turn(60.0, 3.0 * (-1) ** i, v), Leg(120.0, w=0.5, climb_mps=10.0),
                Leg.turn(45.0, -2.0 * (-1) ** i, v + 60.0), Leg(duration)]
        traj = KinematicTrajectory(0.0, rng.uniform(-40e3, 40e3), rng.uniform(-40e3, 40e3),
                                   rng.uniform(3000, 9000), rng.uniform(0, 2 * np.pi), v, legs)
        aircraft.append(SimAircraft(Aircraft(_icao(100 + i), f"MAN{i}", _squawk(100 + i), adsb=i % 2 == 0, nacp=9), traj))
    return Simulator(reference, radars, aircraft, 0.0, duration, seed=seed, name="manoeuvres")


def tracking_scenario(seed: int = 1, duration: float | None = None) -> Simulator:
    reference = (48.85, 2.35)
    plane = SystemPlane(*reference)
    radars = [
        SimRadar(_radar(plane, "A", -40, -30, period=4.0), 80.0, math.radians(0.1), pd=0.9, false_per_scan=2.0),
        SimRadar(_radar(plane, "B", 50, -10, period=6.0), -50.0, math.radians(-0.12), pd=0.9, false_per_scan=2.0,
                 phase_rad=2.0),
    ]
    duration = 1200.0 if duration is None else duration
    half = duration / 2
    aircraft = []

    def add(i, traj, transponder="mode_a_c", code="7000", adsb=False):
        ac = Aircraft(_icao(200 + i), f"TRK{i}", code if transponder != "none" else None, adsb=adsb,
                      transponder=transponder)
        aircraft.append(SimAircraft(ac, traj))

    # crossing at right angles over the origin at mid-time, same level, same code
    v = 220.0
    add(0, KinematicTrajectory(0.0, -v * half, 0.0, 7000.0, math.pi / 2, v, [Leg(duration)]))
    add(1, KinematicTrajectory(0.0, 0.0, -v * half, 7000.0, 0.0, v, [Leg(duration)]))
    # parallel, 3 NM apart, same speed and level, same code
    sep = 3 * 1852.0
    add(2, KinematicTrajectory(0.0, -60e3, 30e3, 9000.0, math.radians(80), 230.0, [Leg(duration)]))
    add(3, KinematicTrajectory(0.0, -60e3 + sep * math.cos(math.radians(80)), 30e3 - sep * math.sin(math.radians(80)),
                               9000.0, math.radians(80), 230.0, [Leg(duration)]))
    # primary-only aircraft near the default primary altitude
    add(4, KinematicTrajectory(0.0, 20e3, -40e3, 6000.0, math.radians(300), 180.0, [Leg(duration)]), "none")
    # 3°/s turns and a climb, Mode S with ADS-B
    legs = [Leg(200.0), Leg.turn(60.0, 3.0, 200.0), Leg(200.0, climb_mps=15.0), Leg.turn(90.0, -3.0, 200.0),
            Leg(duration)]
    add(5, KinematicTrajectory(0.0, 30e3, 40e3, 5000.0, math.radians(200), 200.0, legs), "mode_s", "2345", adsb=True)
    return Simulator(reference, radars, aircraft, 0.0, duration, seed=seed, name="tracking")


STANDARD_SCENARIOS: dict[str, Callable[..., Simulator]] = {
    "seed": seed_scenario,
    "demo": demo_scenario,
    "paris": paris_scenario,
    "manoeuvres": manoeuvres_scenario,
    "tracking": tracking_scenario,
}


def build_scenario(name: str, seed: int = 1, duration: float | None = None) -> Simulator:
    """A configured :class:`Simulator` for built-in scenario ``name``; call ``.run()`` for its data."""
    if name not in STANDARD_SCENARIOS:
        raise ValueError(f"unknown scenario {name!r}; built-in: {', '.join(sorted(STANDARD_SCENARIOS))}")
    return STANDARD_SCENARIOS[name](seed=seed, duration=duration)


#: the sensor errors a simulated radar can be given beyond its range and azimuth biases (:class:`SimRadar`)
SENSOR_ERRORS = ("range_gain", "time_offset_s", "drift_gain", "drift_time")


def with_sensor_errors(scenario, errors: Mapping[str, Mapping[str, float]]):
    """``scenario`` (a :class:`Simulator` or a ``TrafficSimulator``: anything with ``radars``) with radar ``id``'s
    range gain, time-stamp offset and their drifts set from ``errors[id]`` (keys of :data:`SENSOR_ERRORS`); the
    truth file then holds them (``truth_biases.csv``'s ``range_gain`` and ``time_offset_s``)."""
    ids = {sr.radar.id for sr in scenario.radars}
    if unknown := sorted(set(errors) - ids):
        raise ConfigurationError(f"sensor errors: unknown radar {unknown[0]!r}; the scenario has {', '.join(sorted(ids))}")
    for rid, values in errors.items():
        if bad := sorted(set(values) - set(SENSOR_ERRORS)):
            raise ConfigurationError(f"sensor errors of radar {rid!r}: unknown {bad[0]!r}; known: {', '.join(SENSOR_ERRORS)}")
    try:
        scenario.radars = [attrs.evolve(sr, **{k: float(v) for k, v in errors.get(sr.radar.id, {}).items()})
                           for sr in scenario.radars]
    except ValueError as exc:  # a negative drift
        raise ConfigurationError(f"sensor errors: {exc}") from None
    return scenario
