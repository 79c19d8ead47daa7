"""Construction of domain objects validates every field and names it."""

import math

import numpy as np
import pytest

from radartracker.domain import AdsbReport, Aircraft, BiasState, Plot, Radar, Track, nacp_sigma_m


def radar(**kw):
    args = dict(id="R1", lat=48.0, lon=2.0, height_m=100.0, sigma_range_m=70.0,
                sigma_azimuth_rad=math.radians(0.08), period_s=4.0, max_range_m=250e3)
    args.update(kw)
    return Radar(**args)


@pytest.mark.parametrize("field,value,words", [
    ("lat", math.nan, "lat: expected a finite number"),
    ("lat", 91.0, "lat: latitude"),
    ("lon", math.inf, "lon: expected a finite number"),
    ("sigma_range_m", -1.0, "sigma_range_m: must be >= 0"),
    ("sigma_azimuth_rad", -1e-3, "sigma_azimuth_rad: must be >= 0"),
    ("period_s", 0.0, "period_s: must be > 0"),
    ("id", " ", "id: must be a non-empty string"),
])
def test_radar_rejects_bad_fields(field, value, words):
    with pytest.raises(ValueError, match=words):
        radar(**{field: value})


def test_radar_noise_matrix():
    r = radar()
    np.testing.assert_allclose(r.W, np.diag([70.0**2, math.radians(0.08) ** 2]))


@pytest.mark.parametrize("kw,words", [
    (dict(azimuth_rad=2 * math.pi), "azimuth_rad: azimuth must be in \\[0, 360\\)"),
    (dict(azimuth_rad=-0.1), "azimuth_rad"),
    (dict(range_m=math.nan), "range_m: expected a finite number"),
    (dict(range_m=-5.0), "range_m: must be >= 0"),
    (dict(time=math.inf), "time: expected a finite number"),
    (dict(mode_s="xyz123"), "mode_s: Mode S address"),
    (dict(mode_3a="7778"), "mode_3a: Mode 3/A code"),
    (dict(altitude_m=math.nan), "altitude_m"),
])
def test_plot_rejects_bad_fields(kw, words):
    args = dict(time=0.0, radar="R1", range_m=1e5, azimuth_rad=1.0)
    args.update(kw)
    with pytest.raises(ValueError, match=words):
        Plot(**args)


def test_plot_normalises_mode_s_case():
    assert Plot(0.0, "R1", 1e5, 1.0, mode_s="4B1A2C").mode_s == "4b1a2c"


def test_adsb_and_aircraft_validate():
    with pytest.raises(ValueError, match="lat"):
        AdsbReport(0.0, "4b1a2c", 100.0, 2.0)
    with pytest.raises(ValueError, match="nacp"):
        AdsbReport(0.0, "4b1a2c", 48.0, 2.0, nacp=0)
    with pytest.raises(ValueError, match="icao24"):
        Aircraft("zz")


def test_nacp_sigma_is_95_percent_radius():
    # a circular 2-D Gaussian holds 95 % inside 2.448 σ: P(r < kσ) = 1 − exp(−k²/2)
    assert 1 - math.exp(-(2.448**2) / 2) == pytest.approx(0.95, abs=1e-3)
    assert nacp_sigma_m(8) == pytest.approx(92.6 / 2.448)
    with pytest.raises(ValueError, match="nacp"):
        nacp_sigma_m(0)


def test_bias_state_and_track():
    b = BiasState("R1", 10.0, [50.0, 0.001], np.diag([4.0, 1e-8]))
    assert (b.range_m, b.sd_range_m, b.sd_azimuth_rad) == (50.0, 2.0, pytest.approx(1e-4))
    tr = Track("abc")
    tr.record(1.0, np.arange(4.0), np.diag([9.0, 16.0, 1.0, 1.0]))
    assert tr.last_time == 1.0 and tr.sd == [(3.0, 4.0)]
    with pytest.raises(ValueError):
        Track("x", status="lost")
