"""The tracking scenario set of ``scripts/tracking_report.py`` (issue 17).

Real flights of ``../shared/data/real_flights.csv.gz`` (OpenSky Network) flown through simulated
radars, plots primary-only with Mode C altitude (no Mode S, no Mode 3/A, no ADS-B) unless
``mode_s=True``; and kinematic crossing / parallel pairs.

* ``approach``: the four radars of the built-in ``paris`` scenario (periods 4, 4, 10, 8 s), the
  Paris flights airborne during the first ``duration`` s of the recording.
* ``enroute``: five long-range radars (250 km, periods 8–12 s, on high sites 100–190 km around
  Paris); the Paris flights that climb above 7000 m, each shifted by a whole number of windows so
  that its start falls in one ``duration`` window (real trajectories, denser traffic); a shifted
  flight that would come within 3 NM and 1000 ft of one already kept is left out (two departures
  30 min apart on one runway would otherwise fly as one), and every flight gets its own address.
* ``crossing``: pairs crossing at 30°, 60°, 90° and head-on, at the same level and 1000 ft apart;
  ``parallel``: pairs 3 NM and 2 NM apart, same level and speed.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from radartracker.domain import Aircraft
from radartracker.geometry.plane import SystemPlane
from radartracker.io.tables import ScenarioData
from radartracker.simulation.flights import load_flights
from radartracker.simulation.scenarios import _radar
from radartracker.simulation.traffic import traffic_scenario
from radartracker.simulation.simulator import (KinematicTrajectory, Leg, RecordedTrajectory, SimAircraft, SimRadar,
                                               Simulator)

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "real_flights.csv.gz"
PARIS = (48.85, 2.35)
FT = 0.3048


def _paris_flights(path: Path | None) -> dict:
    flights = load_flights(path or DATA)
    return {k: f for k, f in sorted(flights.items()) if k.startswith("paris-")}


def _identity(i: int, icao: str, mode_s: bool) -> Aircraft:
    return Aircraft(icao, f"F{i:03d}", f"{(1000 + 37 * i) % 4096:04o}", transponder="mode_s" if mode_s else "mode_a_c")


def primary_only(data: ScenarioData) -> ScenarioData:
    """Strip Mode 3/A codes from the plots (Mode C altitude stays): kinematics must separate aircraft."""
    data.plots.mode_3a[:] = None
    return data


def approach(seed: int = 1, duration: float = 1800.0, mode_s: bool = False, path: Path | None = None) -> ScenarioData:
    plane = SystemPlane(*PARIS)
    radars = [
        SimRadar(_radar(plane, "ORLY", -2, -14, period=4.0), 90.0, math.radians(0.12), pd=0.9),
        SimRadar(_radar(plane, "CDG", 14, 22, period=4.0), -60.0, math.radians(-0.08), pd=0.9),
        SimRadar(_radar(plane, "EVREUX", -100, 10, period=10.0, sr=100.0, sa_deg=0.1), 150.0, math.radians(0.2), pd=0.9),
        SimRadar(_radar(plane, "REIMS", 130, 20, period=8.0), -110.0, math.radians(-0.15), pd=0.9),
    ]
    flights = _paris_flights(path)
    t0 = min(f.time[0] for f in flights.values())
    aircraft = [SimAircraft(_identity(i, f.icao24, mode_s), RecordedTrajectory.from_geodetic(
        plane, f.time, f.lat, f.lon, f.altitude_m)) for i, f in enumerate(flights.values()) if f.time[0] < t0 + duration]
    sim = Simulator(PARIS, radars, aircraft, t0, t0 + duration, seed=seed, name="approach")
    return primary_only(sim.run())


def enroute(seed: int = 1, duration: float = 3600.0, mode_s: bool = False, max_flights: int | None = None,
            path: Path | None = None) -> ScenarioData:
    plane = SystemPlane(*PARIS)
    sites = [("JURA", 180, -120, 8.0, 1500.0), ("VOSGES", 190, 60, 10.0, 1200.0), ("MORVAN", 60, -170, 12.0, 900.0),
             ("PERCHE", -150, -40, 10.0, 300.0), ("ARTOIS", -20, 150, 12.0, 200.0)]
    biases = [(80.0, 0.10), (-60.0, -0.12), (120.0, 0.08), (-90.0, 0.15), (50.0, -0.10)]
    radars = [SimRadar(_radar(plane, rid, x, y, period=T, sr=70.0, sa_deg=0.06, height=h), b[0], math.radians(b[1]),
                       pd=0.9) for (rid, x, y, T, h), b in zip(sites, biases)]
    flights = [f for f in _paris_flights(path).values() if f.altitude_m.max() > 7000.0]
    t0 = min(f.time[0] for f in flights)
    kept: list[RecordedTrajectory] = []
    for f in flights:
        shift = math.floor((f.time[0] - t0) / duration) * duration
        traj = RecordedTrajectory.from_geodetic(plane, f.time - shift, f.lat, f.lon, f.altitude_m)
        if not any(_conflict(traj, other) for other in kept):
            kept.append(traj)
    # one address per flight (an airframe flies several flights of the recording)
    aircraft = [SimAircraft(_identity(i, f"{0x3a0000 + i:06x}", mode_s), traj) for i, traj in enumerate(kept[:max_flights])]
    sim = Simulator(PARIS, radars, aircraft, t0, t0 + duration, seed=seed, name="enroute")
    return primary_only(sim.run())


def cruise(seed: int = 1, duration: float = 1800.0, mode_c: bool = True, aircraft: int = 60) -> ScenarioData:
    """En-route cruise under dense overlapping coverage (issue 29): five 250 km radars 100 km apart (every
    coverage overlaps the others), periods 8–12 s, biases N(0, 50 m) and N(0, 0.06°); flights at FL300–400
    and 170–310 m/s with level turns; plots with Mode C altitude and no identity (``mode_c=False``: no
    altitude either, pure primary), no ADS-B."""
    sim = traffic_scenario(seed=seed, duration=duration, aircraft=aircraft, radars=5, spacing_km=100.0,
                           period_s=(8.0, 12.0), range_bias_sd_m=50.0, azimuth_bias_sd_deg=0.06,
                           altitude_m=(9144.0, 12192.0), speed_mps=(170.0, 310.0), adsb_share=0.0,
                           transponder="mode_c" if mode_c else "none")
    data = sim.run()
    data.name = "cruise" if mode_c else "cruise-no-mode-c"
    return data


SWISS = (46.8, 8.2)
SWISS_DATA = Path(__file__).resolve().parent / "data" / "switzerland_cruise.csv.gz"


def cruise_real(seed: int = 1, mode_c: bool = True, path: Path | None = None) -> ScenarioData:
    """Real en-route cruise (issue 29): the 100 flights at FL350–390 over Switzerland between 09:00 and
    10:00 UTC on 1 August 2018 (``scripts/data/switzerland_cruise.csv.gz``: OpenSky Network state vectors
    every 10 s, from the `traffic` library's ``switzerland`` sample, MIT), 204–263 m/s, seen by five 250 km
    radars whose coverages all overlap (periods 8, 10 and 12 s, range biases up to 100 m, azimuth biases
    up to 0.11°); plots with Mode C altitude and no Mode S or Mode 3/A (``mode_c=False``: no altitude)."""
    plane = SystemPlane(*SWISS)
    sites = [("JURA", -110, 20, 8.0, 1600.0), ("SANTIS", 90, 70, 10.0, 2500.0), ("LEMAN", -140, -110, 12.0, 1000.0),
             ("GOTTHARD", 20, -40, 10.0, 2000.0), ("ENGADIN", 170, -60, 8.0, 1800.0)]
    biases = [(80.0, 0.10), (-60.0, -0.11), (100.0, 0.08), (-90.0, 0.06), (50.0, -0.10)]
    radars = [SimRadar(_radar(plane, rid, x, y, period=T, sr=70.0, sa_deg=0.06, height=h), b[0], math.radians(b[1]),
                       pd=0.9) for (rid, x, y, T, h), b in zip(sites, biases)]
    flights = load_flights(path or SWISS_DATA)
    t0 = min(f.time[0] for f in flights.values())
    t1 = max(f.time[-1] for f in flights.values())
    aircraft = [SimAircraft(Aircraft(f"{0x3c0000 + i:06x}", f.callsign, None,
                                     transponder="mode_a_c" if mode_c else "none"),
                            RecordedTrajectory.from_geodetic(plane, f.time, f.lat, f.lon, f.altitude_m))
                for i, f in enumerate(flights.values())]
    data = Simulator(SWISS, radars, aircraft, t0, t1, seed=seed, name="cruise-real").run()
    data.name = "cruise-real" if mode_c else "cruise-real-no-mode-c"
    return data


def national_primary(seed: int = 1, duration: float = 600.0, aircraft: int = 200, mode_c: bool = False) -> ScenarioData:
    """The built-in national traffic (28 radars 200 km apart, periods 4–12 s), every aircraft primary-only
    (``mode_c``: the same flights with Mode C altitude and no identity, the twin of the comparison)."""
    twin = {"primary_share": 0.0, "transponder": "mode_c"} if mode_c else {"primary_share": 1.0}
    data = traffic_scenario(seed=seed, duration=duration, aircraft=aircraft, adsb_share=0.0, **twin).run()
    data.name = "national-mode-c" if mode_c else "national-primary"
    return data


def _conflict(a: RecordedTrajectory, b: RecordedTrajectory) -> bool:
    """Whether two time-shifted flights ever come within 3 NM and 1000 ft of each other (a loss of
    separation no controlled traffic has: such a pair is an artefact of moving flights in time)."""
    lo, hi = max(a.t_start, b.t_start), min(a.t_end, b.t_end)
    if hi <= lo:
        return False
    t = np.arange(lo, hi, 5.0)
    (xa, ya, ha), (xb, yb, hb) = a.position(t), b.position(t)
    return bool(np.any((np.hypot(xa - xb, ya - yb) < 3 * 1852.0) & (np.abs(ha - hb) < 1000 * FT)))


def pairs(seed: int = 1, duration: float = 900.0) -> ScenarioData:
    """Crossing pairs (30°, 60°, 90°, 180°; same level and 1000 ft apart) and parallel pairs (3 NM, 2 NM)."""
    plane = SystemPlane(*PARIS)
    radars = [SimRadar(_radar(plane, "A", -60, -40, period=4.0), 80.0, math.radians(0.1), pd=0.9, false_per_scan=2.0),
              SimRadar(_radar(plane, "B", 70, -20, period=8.0), -50.0, math.radians(-0.12), pd=0.9, false_per_scan=2.0,
                       phase_rad=2.0)]
    half, v = duration / 2, 220.0
    aircraft: list[SimAircraft] = []

    def add(x, y, h, heading, speed=v):
        i = len(aircraft)
        traj = KinematicTrajectory(0.0, x, y, h, heading, speed, [Leg(duration)])
        aircraft.append(SimAircraft(_identity(i, f"{0x4c0000 + 11 * i:06x}", False), traj))

    for k, angle in enumerate((30.0, 60.0, 90.0, 180.0)):
        for dz in (0.0, 1000 * FT):
            cx, cy = -45e3 + 30e3 * k, 40e3 if dz else -10e3
            for heading in (math.radians(45.0), math.radians(45.0 + angle)):  # both pass (cx, cy) at mid-time
                add(cx - v * half * math.sin(heading), cy - v * half * math.cos(heading),
                    9000.0 + (dz if heading != math.radians(45.0) else 0.0), heading)
    for k, sep_nm in enumerate((3.0, 2.0)):
        hd, sep = math.radians(80.0), sep_nm * 1852.0
        x0, y0 = -60e3, -60e3 + 30e3 * k
        add(x0, y0, 8000.0, hd, 230.0)
        add(x0 + sep * math.cos(hd), y0 - sep * math.sin(hd), 8000.0, hd, 230.0)
    sim = Simulator(PARIS, radars, aircraft, 0.0, duration, seed=seed, name="pairs")
    return primary_only(sim.run())
