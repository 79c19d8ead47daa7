"""The simulator: antenna-sweep plot times, exact geometry, noise statistics, determinism."""

import math

import numpy as np
import pytest

from radartracker.domain import Aircraft, Radar
from radartracker.geometry.plane import RadarFrame, SystemPlane
from radartracker.simulation.scenarios import build_scenario
from radartracker.simulation.simulator import KinematicTrajectory, Leg, SimAircraft, SimRadar, Simulator


def single(pd=1.0, false_per_scan=0.0, sr=0.0, sa=0.0, bias=(0.0, 0.0), drift=0.0):
    plane = SystemPlane(50.0, 10.0)
    lat, lon = plane.to_geodetic(-30e3, 10e3)
    radar = Radar("R", float(lat), float(lon), 50.0, sr, sa, 5.0, 200e3)
    traj = KinematicTrajectory(0.0, 20e3, -60e3, 9000.0, 0.3, 230.0, [Leg(200.0), Leg.turn(60.0, 3.0, 230.0), Leg(340.0)])
    sim = Simulator((50.0, 10.0), [SimRadar(radar, bias[0], bias[1], drift_range=drift, pd=pd,
                                            false_per_scan=false_per_scan, phase_rad=1.0)],
                    [SimAircraft(Aircraft("abcdef", adsb=True), traj)], 0.0, 600.0, seed=7)
    return sim, radar, traj


def test_each_plot_is_where_the_antenna_points():
    sim, radar, traj = single()
    data = sim.run()
    t = data.plots.time
    assert len(t) == pytest.approx(600 / 5, abs=1)
    antenna = np.mod(1.0 + 2 * np.pi * t / radar.period_s, 2 * np.pi)
    frame = RadarFrame(radar.lat, radar.lon, radar.height_m, sim.plane)
    x, y, h = traj.position(t)
    lat, lon = sim.plane.to_geodetic(x, y)
    rho, theta, _ = frame.polar(lat, lon, h)
    assert np.max(np.abs(np.mod(theta - antenna + np.pi, 2 * np.pi) - np.pi)) < 1e-9
    np.testing.assert_allclose(data.plots.range_m, rho, atol=1e-6)  # noiseless, unbiased
    np.testing.assert_allclose(np.diff(t), 5.0, atol=0.2)  # one plot per revolution


def test_noise_and_bias_statistics():
    sim, radar, _ = single(sr=50.0, sa=math.radians(0.1), bias=(100.0, math.radians(0.2)))
    sim.t1 = 600.0
    clean, _, _ = single()
    d, c = sim.run(), clean.run()
    assert np.array_equal(d.plots.time, c.plots.time)
    e_r = d.plots.range_m - c.plots.range_m
    e_a = np.mod(d.plots.azimuth_rad - c.plots.azimuth_rad + np.pi, 2 * np.pi) - np.pi
    n = len(e_r)
    assert abs(e_r.mean() - 100.0) < 4 * 50.0 / math.sqrt(n)
    assert abs(e_a.mean() - math.radians(0.2)) < 4 * math.radians(0.1) / math.sqrt(n)
    assert e_r.std() == pytest.approx(50.0, rel=0.25)


def test_one_plot_per_scan_per_aircraft(seed_data):
    p = seed_data.plots
    for radar in seed_data.radars:
        for target in {a.icao24 for a in seed_data.aircraft}:
            t = np.sort(p.time[(p.radar == radar.id) & (p.target == target)])
            assert np.all(np.diff(t) > 0.5 * radar.period_s)


def test_detection_probability_and_false_plots():
    sim, _, _ = single(pd=0.5, false_per_scan=3.0)
    d = sim.run()
    real = np.array([t is not None for t in d.plots.target])
    assert 40 <= real.sum() <= 80  # binomial(120, 0.5) within ±3.6σ
    assert 240 <= (~real).sum() <= 480  # Poisson(360)
    assert all(m is None for m in d.plots.mode_s[~real]) and np.isnan(d.plots.altitude_m[~real]).all()


def test_drifting_bias_reported_at_end():
    sim, _, _ = single(bias=(10.0, 0.0), drift=4.0)
    d = sim.run()
    assert d.truth_biases["R"][0] != 10.0


def test_deterministic_for_a_seed_and_different_across_seeds():
    a = build_scenario("paris", seed=2, duration=300).run()
    b = build_scenario("paris", seed=2, duration=300).run()
    c = build_scenario("paris", seed=3, duration=300).run()
    assert np.array_equal(a.plots.range_m, b.plots.range_m) and np.array_equal(a.adsb.lat, b.adsb.lat)
    assert not np.array_equal(a.plots.range_m[:50], c.plots.range_m[:50])


def test_adsb_noise_matches_nacp():
    sim, _, traj = single()
    d = sim.run()
    x, y = sim.plane.to_plane(d.adsb.lat, d.adsb.lon)
    tx, ty, _ = traj.position(d.adsb.time)
    err = np.concatenate([x - tx, y - ty])
    assert err.std() == pytest.approx(92.6 / 2.448, rel=0.1)


def test_plots_are_time_ordered_and_truth_present(seed_data):
    assert np.all(np.diff(seed_data.plots.time) >= 0)
    assert set(seed_data.truth.target) == {a.icao24 for a in seed_data.aircraft}


def test_cone_of_silence_and_screening_set_what_a_radar_sees():
    """SimRadar.visible: nothing above its own cone; in a screened sector (here one across north, 350°–10°,
    and every azimuth cut to 90 km) nothing beyond the sector's range; elsewhere the configured range."""
    radar = Radar("R", 48.0, 2.0, 50.0, 50.0, 0.001, 4.0, 120e3)
    sr = SimRadar(radar, cone_of_silence_deg=30.0, screening=((350.0, 10.0, 40e3), (0.0, 360.0, 90e3)))
    rho = np.array([10e3, 10e3, 50e3, 50e3, 50e3, 100e3, 100e3])
    az = np.radians([90.0, 90.0, 355.0, 5.0, 20.0, 200.0, 200.0])
    elev = np.radians([29.0, 31.0, 1.0, 1.0, 1.0, 1.0, -30.0])
    assert sr.visible(rho, az, elev).tolist() == [True, False, False, False, True, False, False]
    assert SimRadar(radar).visible(rho, az, elev).tolist() == [True, True, True, True, True, True, False]
