"""The cone of silence and the coverage a radar achieved, measured against a simulator told the true ones:
radar A's cone is 35° and it sees its whole configured 120 km; radar B's cone is the default 45°, it sees
75 km, and 45 km in the sector 90°–180° (SimRadar.cone_of_silence_deg, SimRadar.screening). The true
values below are the simulator's settings; the true coverage share is computed here, from the geometry of
crossings drawn over a disc with a known reach; the intervals against scipy's binomtest."""

from __future__ import annotations

import math

import numpy as np
import pytest

from radartracker.assessment.coverage import CoverageConfig, achieved_coverage, measure_cone
from radartracker.assessment.matching import MatchConfig
from radartracker.assessment.radar import RadarConfig, assess_radar
from radartracker.assessment.reference import build_reference
from radartracker.assessment.slices import SliceConfig, tally_radars
from radartracker.domain import Aircraft, BiasState, Radar
from radartracker.geometry.plane import SystemPlane
from radartracker.simulation.simulator import KinematicTrajectory, Leg, SimAircraft, SimRadar, Simulator

CONE_A, CONE_B = 35.0, 45.0
REACH_B, SCREENED_B, SECTOR_B = 75.0, 45.0, (90.0, 180.0)  # km, km, deg
CONFIGURED_KM = 120.0
BIN_KM = CoverageConfig().range_bin_km


def simulator(seed: int = 3, duration: float = 900.0) -> Simulator:
    """Radars A and B at the centre; 14 aircraft passing within 14 km of it (the cone's crossings), at
    4–11 km, and 30 crossing the 120 km disc on chords at 15–110 km (the coverage's), all at 240 m/s."""
    reference = (48.0, 2.0)
    plane = SystemPlane(*reference)
    lat, lon = plane.to_geodetic(0.0, 0.0)

    def radar(rid: str, period: float) -> Radar:
        return Radar(rid, float(lat), float(lon), 50.0, 50.0, math.radians(0.08), period, CONFIGURED_KM * 1e3)

    radars = [SimRadar(radar("A", 4.0), pd=0.9, cone_of_silence_deg=CONE_A),
              SimRadar(radar("B", 5.0), pd=0.9, screening=((0.0, 0.0, REACH_B * 1e3), (*SECTOR_B, SCREENED_B * 1e3)))]
    rng = np.random.default_rng(seed)
    offsets = np.concatenate([np.linspace(0.5e3, 14e3, 14), rng.uniform(15e3, 110e3, 30)])
    aircraft = []
    for i, d in enumerate(offsets):
        heading, speed = rng.uniform(0, 2 * math.pi), 240.0
        along = rng.uniform(-0.5, 0.5) * speed * duration  # where on its chord the aircraft is at mid-run
        ux, uy = math.sin(heading), math.cos(heading)
        x0 = d * uy - (along + 0.5 * speed * duration) * ux
        y0 = -d * ux - (along + 0.5 * speed * duration) * uy
        h = rng.uniform(4e3, 11e3)
        traj = KinematicTrajectory(0.0, x0, y0, h, heading, speed, [Leg(duration)])
        aircraft.append(SimAircraft(Aircraft(f"{0x3c0000 + i:06x}", f"T{i}", f"{1000 + i:04o}"), traj))
    return Simulator(reference, radars, aircraft, 0.0, duration, seed=seed, name="cone")


def assess_radars(data, slice_s: float = 3600.0):
    """Each radar's figures from its sums over the slices of ``slice_s`` (zero biases: the simulator has none)."""
    reference = build_reference(data)
    biases = {r.id: (0.0, 0.0) for r in data.radars}
    tallies = tally_radars(data, reference, biases, MatchConfig(), 300.0, SliceConfig(slice_s), progress=False)
    return {r.id: assess_radar(r, tallies[r.id], (0, np.zeros(0)), BiasState(r.id, 0.0, np.zeros(2), np.eye(2)), {}, {},
                               "truth", RadarConfig()) for r in data.radars}


@pytest.fixture(scope="module")
def assessed():
    data = simulator().run()
    return data, assess_radars(data)


def test_measured_cone_holds_the_true_cone(assessed):
    _, radars = assessed
    for rid, true in (("A", CONE_A), ("B", CONE_B)):
        cone = radars[rid].figures["cone_of_silence_deg"]
        print(f"radar {rid}: true cone {true}°, measured {cone.value:.2f}° [{cone.low:.2f}, {cone.high:.2f}] "
              f"from {cone.n} crossings")
        assert cone.contains(true) and abs(cone.value - true) < 1.5 and cone.method == "step-fit-lr"
    a = radars["A"]  # Pd still counts only the crossings below the assumed 45°; the elevation bins all of them
    above = sum(b["crossings"] for b in a.pd_bins if b["variable"] == "elevation_deg" and b["bin_low"] >= 45.0)
    assert above > 0 and sum(b["crossings"] for b in a.pd_bins if b["variable"] == "elevation_deg") == \
        a.figures["pd"].n + above


def test_achieved_range_is_the_true_range(assessed):
    _, radars = assessed
    for rid, true in (("A", CONFIGURED_KM), ("B", REACH_B)):
        r = radars[rid].figures["detection_range_km"]
        print(f"radar {rid}: true detection range {true} km, measured {r.value} km [{r.low}, {r.high}]")
        assert r.contains(true) and abs(r.value - true) <= BIN_KM


def test_coverage_diagram_shows_the_screened_sector(assessed):
    """Radar B's sectors: 45 km in 90°–180°, 75 km elsewhere, each within a bin of the truth and inside its
    interval, limited by the detection; radar A's limited by its configured range or the traffic."""
    _, radars = assessed
    judged = 0
    for s in radars["B"].coverage:
        true = SCREENED_B if SECTOR_B[0] <= s["azimuth_low"] < SECTOR_B[1] else REACH_B
        print(f"B sector {s['azimuth_low']:.0f}–{s['azimuth_high']:.0f}°: true {true} km, measured "
              f"{s['range_km']} km [{s['range_low_km']}, {s['range_high_km']}] from {s['crossings']} crossings, "
              f"limited by {s['limited_by']}")
        if math.isfinite(s["range_km"]):
            judged += 1
            assert abs(s["range_km"] - true) <= BIN_KM and s["range_low_km"] <= true <= s["range_high_km"]
            assert s["limited_by"] == "detection"
    assert judged >= 9
    assert {s["limited_by"] for s in radars["A"].coverage} <= {"configured range", "traffic", ""}
    shares = {rid: radars[rid].figures["coverage_share"] for rid in "AB"}
    print("coverage share: " + ", ".join(f"{k} {e.value:.3f} [{e.low:.3f}, {e.high:.3f}]" for k, e in shares.items()))
    assert shares["A"].low > 0.9 and shares["B"].high < 0.8


def test_coverage_share_is_the_area_where_pd_meets_the_level():
    """Crossings uniform over a 120 km disc, Pd 0.9 within 73 km, 0.02 beyond: each 10 km × 30° cell meets 0.5
    when its true Pd, 0.9 × its area within 73 km + 0.02 × the rest, does (here: the rings out to 70 km), so
    the true share of the coverage is the area of the cells that meet, (70/120)², and the detection range's
    interval holds 73 km."""
    rng = np.random.default_rng(5)
    n, reach, r_max = 60_000, 73e3, 120e3
    rho, az = r_max * np.sqrt(rng.uniform(0.0, 1.0, n)), rng.uniform(0.0, 360.0, n)
    detected = rng.random(n) < np.where(rho <= reach, 0.9, 0.02)
    edges = np.arange(0.0, 121.0, 10.0)
    ring = np.pi * (edges[1:] ** 2 - edges[:-1] ** 2)
    inside = np.pi * (np.clip(reach / 1e3, edges[:-1], edges[1:]) ** 2 - edges[:-1] ** 2) / ring
    true_share = ring[0.9 * inside + 0.02 * (1 - inside) >= 0.5].sum() / ring.sum()
    figures, missing, rows = achieved_coverage(rho, az, detected, r_max, CoverageConfig())
    share, r = figures["coverage_share"], figures["detection_range_km"]
    print(f"share: true {true_share:.4f}, measured {share.value:.4f} [{share.low:.4f}, {share.high:.4f}]; "
          f"range: true 73 km, measured {r.value} [{r.low}, {r.high}]")
    assert not missing and len(rows) == 12 and share.contains(true_share) and r.contains(73.0)
    assert math.isclose(true_share, (70 / 120) ** 2)


def test_slices_add_up_to_one_pass(assessed):
    """Slices of 97 s give every cone and coverage figure, the diagram and the elevation bins of one pass."""
    data, whole = assessed
    cut = assess_radars(data, 97.0)
    for rid, a in whole.items():
        for name in ("cone_of_silence_deg", "detection_range_km", "coverage_share", "pd"):
            assert cut[rid].figures[name] == a.figures[name], (rid, name)
        assert cut[rid].coverage == a.coverage
        assert [b for b in cut[rid].pd_bins if b["variable"] == "elevation_deg"] == \
            [b for b in a.pd_bins if b["variable"] == "elevation_deg"]


def test_cone_not_assessable_without_close_crossings_or_a_drop():
    rng = np.random.default_rng(0)
    low = rng.uniform(0.0, 9.0, 300)
    est, why = measure_cone(low, rng.random(300) < 0.9, CoverageConfig())
    assert est is None and "10° elevation or above" in why
    high = rng.uniform(10.0, 80.0, 300)
    est, why = measure_cone(high, rng.random(300) < 0.9, CoverageConfig())  # Pd 0.9 at every elevation
    assert est is None and "no cone of silence seen" in why


def test_cone_interval_coverage_over_draws():
    """Of 200 draws of 150 crossings (elevations uniform 10°–70°, Pd 0.8 below a true cone of 40°, 0.03
    above), the 95 % interval holds 40° at least as often as the binomial band's lower end, 186 of 200."""
    rng = np.random.default_rng(7)
    held = 0
    for _ in range(200):
        e = rng.uniform(10.0, 70.0, 150)
        est, _ = measure_cone(e, rng.random(150) < np.where(e <= 40.0, 0.8, 0.03), CoverageConfig())
        held += est is not None and est.contains(40.0)
    print(f"cone interval held the truth in {held} of 200 draws")
    assert held >= 186


def test_no_range_bin_with_enough_crossings_is_not_assessable():
    figures, missing, rows = achieved_coverage(np.array([5e3, 50e3]), np.array([10.0, 200.0]),
                                               np.array([True, False]), 120e3, CoverageConfig())
    assert not figures and set(missing) == {"detection_range_km", "coverage_share"} and rows == []


def test_vectorised_intervals_are_binomtests():
    """stats.proportions (one call for every bin) gives scipy.stats.binomtest's Wilson and Clopper–Pearson
    intervals, as stats.proportion does one bin at a time."""
    from scipy.stats import binomtest

    from radartracker.assessment.stats import proportions

    n = np.array([1, 2, 6, 6, 11, 11, 37, 200, 5000, 5000])
    k = np.array([0, 2, 3, 6, 5, 6, 20, 190, 4990, 2500])
    p, low, high = proportions(k, n)
    for i in range(len(n)):
        exact = min(k[i], n[i] - k[i]) <= 5
        ci = binomtest(int(k[i]), int(n[i])).proportion_ci(0.95, method="exact" if exact else "wilson")
        assert p[i] == k[i] / n[i] and math.isclose(low[i], ci.low, abs_tol=1e-9) \
            and math.isclose(high[i], ci.high, abs_tol=1e-9), (k[i], n[i])
