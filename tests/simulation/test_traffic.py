"""Vectorised national traffic: the same plots as the per-aircraft simulator, sizes and shares, CLI."""

import math

import attrs
import numpy as np
import pytest

from radartracker.cli import main
from radartracker.errors import ConfigurationError
from radartracker.io.scenario import read_scenario
from radartracker.simulation.traffic import TrafficConfig, TrafficSimulator, traffic_scenario


def noiseless(sim: TrafficSimulator) -> TrafficSimulator:
    sim.radars = [attrs.evolve(sr, radar=attrs.evolve(sr.radar, sigma_range_m=0.0, sigma_azimuth_rad=0.0))
                  for sr in sim.radars]
    return sim


@pytest.fixture(scope="module")
def small():
    sim = noiseless(TrafficSimulator(TrafficConfig(aircraft=25, radars=4, duration_s=400.0, pd=1.0,
                                                   primary_share=0.2, seed=3)))
    return sim, sim.run(), sim.simulator().run()


def test_same_plots_as_the_per_aircraft_simulator(small):
    _, fast, slow = small
    a, b = fast.plots, slow.plots
    assert len(a) == len(b) > 1000
    np.testing.assert_allclose(a.time, b.time, rtol=0, atol=1e-9)
    np.testing.assert_allclose(a.range_m, b.range_m, rtol=0, atol=1e-6)
    np.testing.assert_allclose(a.azimuth_rad, b.azimuth_rad, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(a.altitude_m, b.altitude_m)
    for col in ("radar", "mode_s", "mode_3a", "target"):
        assert list(getattr(a, col)) == list(getattr(b, col)), col
    assert fast.truth_biases == slow.truth_biases


def test_same_adsb_and_truth_as_the_per_aircraft_simulator(small):
    _, fast, slow = small
    assert list(fast.adsb.icao24) == list(slow.adsb.icao24)
    for col in ("time", "lat", "lon", "altitude_m"):
        np.testing.assert_allclose(getattr(fast.adsb, col), getattr(slow.adsb, col), rtol=0, atol=1e-9)
    i = np.lexsort((fast.truth.target.astype(str), fast.truth.time))
    j = np.lexsort((slow.truth.target.astype(str), slow.truth.time))
    assert list(fast.truth.target[i]) == list(slow.truth.target[j])
    for col in ("time", "lat", "lon", "altitude_m"):
        np.testing.assert_allclose(getattr(fast.truth, col)[i], getattr(slow.truth, col)[j], rtol=0, atol=1e-9)


def test_noise_and_bias_statistics():
    cfg = TrafficConfig(aircraft=60, radars=3, duration_s=300.0, pd=1.0, seed=5)
    clean, noisy = noiseless(TrafficSimulator(cfg)).run().plots, TrafficSimulator(cfg).run().plots
    sim = TrafficSimulator(cfg)
    assert np.array_equal(clean.time, noisy.time)
    for sr in sim.radars:
        m = noisy.radar == sr.radar.id
        e_r = noisy.range_m[m] - clean.range_m[m]
        e_a = np.mod(noisy.azimuth_rad[m] - clean.azimuth_rad[m] + np.pi, 2 * np.pi) - np.pi
        n = int(m.sum())
        assert abs(e_r.mean()) < 4 * sr.radar.sigma_range_m / math.sqrt(n)
        assert e_r.std() == pytest.approx(sr.radar.sigma_range_m, rel=4 / math.sqrt(2 * n))
        assert e_a.std() == pytest.approx(sr.radar.sigma_azimuth_rad, rel=4 / math.sqrt(2 * n))


def test_size_and_shares():
    cfg = TrafficConfig(aircraft=800, radars=9, duration_s=600.0, adsb_share=0.3, primary_share=0.1, seed=2)
    sim = TrafficSimulator(cfg)
    f = sim.flights
    airborne = [np.sum((f.t_start <= t) & (f.t_end >= t)) for t in (0.0, 300.0, 600.0)]
    # flights start as a Poisson-like process: the count airborne is within a few √N of N
    assert all(abs(a - 800) < 4 * math.sqrt(800) for a in airborne)
    n = len(sim.aircraft)
    primary = np.array([a.transponder == "none" for a in sim.aircraft])
    adsb = np.array([a.adsb for a in sim.aircraft])
    assert abs(primary.mean() - 0.1) < 4 * math.sqrt(0.09 / n)
    assert abs(adsb.mean() - 0.3) < 4 * math.sqrt(0.21 / n)
    assert not (primary & adsb).any()
    assert len(sim.radars) == 9 and len({a.icao24 for a in sim.aircraft}) == n


def test_the_airspace_options_shape_radars_flights_and_plots():
    """Periods, biases, altitudes, speeds and what the plots carry follow the options (checked on the
    simulated radars, flights and plots themselves)."""
    cfg = dict(aircraft=40, radars=5, duration_s=120.0, spacing_km=100.0, period_s=(8.0, 12.0), range_bias_sd_m=0.0,
               azimuth_bias_sd_deg=0.0, altitude_m=(9144.0, 12192.0), speed_mps=(170.0, 310.0), adsb_share=0.0)
    runs = {tp: TrafficSimulator(TrafficConfig(transponder=tp, **cfg)) for tp in ("mode_s", "mode_c", "none")}
    sim = runs["mode_c"]
    assert all(8.0 <= sr.radar.period_s <= 12.0 for sr in sim.radars)
    assert all(sr.range_bias_m == 0.0 and sr.azimuth_bias_rad == 0.0 for sr in sim.radars)
    assert (9144.0 <= sim.flights.altitude).all() and (sim.flights.altitude <= 12192.0).all()
    assert (170.0 <= sim.flights.speed).all() and (sim.flights.speed <= 310.0).all()
    xy = np.array([sim.plane.to_plane(sr.radar.lat, sr.radar.lon) for sr in sim.radars])
    assert np.hypot(*(xy[:, None] - xy[None]).transpose(2, 0, 1)).max() < 250e3  # every coverage holds every radar
    plots = {tp: s.run().plots for tp, s in runs.items()}
    carried = {tp: (np.isfinite(p.altitude_m.astype(float)).mean(), np.mean([c is not None for c in p.mode_s]),
                    np.mean([c is not None for c in p.mode_3a])) for tp, p in plots.items()}
    assert carried == {"mode_s": (1.0, 1.0, 1.0), "mode_c": (1.0, 0.0, 0.0), "none": (0.0, 0.0, 0.0)}
    np.testing.assert_array_equal(plots["mode_c"].range_m, plots["none"].range_m)  # the same plots otherwise


@pytest.mark.parametrize("bad", [dict(aircraft=0), dict(adsb_share=1.5), dict(adsb_share=0.7, primary_share=0.5),
                                 dict(duration_s=-1.0), dict(period_s=(12.0, 8.0)), dict(speed_mps=(0.0, 10.0)),
                                 dict(altitude_m=(1.0,)), dict(transponder="mode_x"), dict(range_bias_sd_m=-1.0)])
def test_bad_configuration(bad):
    with pytest.raises(ConfigurationError):
        TrafficConfig(**bad)


def test_cli_writes_traffic(tmp_path, capsys):
    out = tmp_path / "t"
    assert main(["simulate", str(out), "--scenario", "traffic", "--aircraft", "20", "--radars", "3",
                 "--duration", "60", "--adsb-share", "0.5"]) == 0
    data = read_scenario(out)
    same = traffic_scenario(seed=1, duration=60.0, aircraft=20, radars=3, adsb_share=0.5).run()
    assert len(data.radars) == 3 and len(data.plots) == len(same.plots) > 0 and len(data.adsb) == len(same.adsb) > 0
    np.testing.assert_allclose(data.plots.range_m, same.plots.range_m, atol=1e-3)
    assert main(["simulate", str(tmp_path / "c"), "--scenario", "traffic", "--aircraft", "10", "--radars", "2",
                 "--duration", "60", "--period-s", "8", "12", "--transponder", "mode_c"]) == 0
    assert all(8.0 <= r.period_s <= 12.0 for r in read_scenario(tmp_path / "c").radars)
    assert main(["simulate", str(tmp_path / "d"), "--scenario", "traffic", "--period-s", "12", "8"]) == 2
    assert main(["simulate", str(tmp_path / "u"), "--scenario", "seed", "--aircraft", "20"]) == 2
    assert "--aircraft applies to --scenario traffic only" in capsys.readouterr().err
