"""Flights of the ``traffic`` library's sample set become a scenario, which replays into tracks that go back as
a ``Traffic``: compared with the sample flights themselves (positions, ground speed, course, altitude in
``traffic``'s units), interpolated here at the tracks' times."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from pyproj import Geod

pytest.importorskip("traffic.core", reason="the optional extra radartracker[traffic] is not installed")

from traffic.core import Traffic  # noqa: E402

from radartracker.domain import Radar  # noqa: E402
from radartracker.errors import InputError  # noqa: E402
from radartracker.geometry.plane import SystemPlane  # noqa: E402
from radartracker.interop.traffic import scenario_from_traffic, traffic_from_tracks  # noqa: E402
from radartracker.pipeline.config import RunConfig  # noqa: E402
from radartracker.pipeline.run import run  # noqa: E402
from radartracker.simulation.simulator import SimRadar  # noqa: E402

REFERENCE = (48.85, 2.35)
GEOD = Geod(ellps="WGS84")


def _radars() -> list[SimRadar]:
    plane = SystemPlane(*REFERENCE)
    out = []
    for rid, x, y, period, dr, da in (("A", -30e3, -20e3, 4.0, 80.0, 0.1), ("B", 40e3, 10e3, 5.0, -50.0, -0.12)):
        lat, lon = plane.to_geodetic(x, y)
        radar = Radar(rid, float(lat), float(lon), 100.0, 60.0, math.radians(0.08), period, 250e3)
        out.append(SimRadar(radar, dr, math.radians(da)))
    return out


def _seconds(ts) -> np.ndarray:
    return ((pd.to_datetime(ts, utc=True) - pd.Timestamp(0, tz="UTC")) / pd.Timedelta(seconds=1)).to_numpy(float)


@pytest.fixture(scope="module")
def flights():
    """Eight airborne flights of the sample ``quickstart`` (OpenSky, around Paris) over ten minutes."""
    from traffic.data.samples import quickstart

    window = quickstart.between("2021-10-07 13:00", "2021-10-07 13:10")
    airborne = [f for f in window if not f.data["onground"].any() and len(f.data) > 300]
    return sorted(airborne, key=lambda f: f.icao24)[:8]


def test_sample_flights_replay_into_tracks_that_follow_them(flights):
    data = scenario_from_traffic(Traffic.from_flights(flights), _radars(), reference=REFERENCE)
    assert set(data.truth.target) == {f.icao24 for f in flights} and len(data.adsb) > 1000 and len(data.plots) > 1000
    result = run(data, RunConfig(association="manager"), progress=False)
    tracks = traffic_from_tracks(result.tracks_frame(), result.data.reference)
    assert isinstance(tracks, Traffic) and len(tracks) == len(flights)
    for f in flights:
        mine = [g for g in tracks if g.icao24 == f.icao24]
        assert len(mine) == 1, f.icao24  # one track per flight, never broken
        g, d = mine[0].data, f.data
        t, ts = _seconds(g["timestamp"]), _seconds(d["timestamp"])
        assert ts[0] - 1 <= t.min() and t.max() <= ts[-1] + 1 and len(t) > 300
        lat, lon = (np.interp(t, ts, d[c].to_numpy(float)) for c in ("latitude", "longitude"))
        _, _, dist = GEOD.inv(lon, lat, g["longitude"].to_numpy(float), g["latitude"].to_numpy(float))
        course = np.interp(t, ts, np.unwrap(d["track"].to_numpy(float), period=360.0))
        turn = np.abs((g["track"].to_numpy(float) - course + 180.0) % 360.0 - 180.0)
        speed = np.abs(g["groundspeed"].to_numpy(float) - np.interp(t, ts, d["groundspeed"].to_numpy(float)))
        climb = np.abs(g["altitude"].to_numpy(float) - np.interp(t, ts, d["altitude"].to_numpy(float)))
        assert np.median(dist) < 60.0 and np.median(speed) < 10.0 and np.median(turn) < 3.0, f.icao24
        assert np.nanmedian(climb) < 30.0  # feet: ADS-B altitudes, Mode C in 25 ft steps
        assert set(g["squawk"].dropna()) == {f"{int(d['squawk'].dropna().iloc[0]):04d}"}


def test_a_track_goes_back_in_traffic_units():
    """A track at the reference flying east at 100 m/s at 3048 m: 194.38 kt, course 90°, 10 000 ft."""
    frame = pd.DataFrame({"time": [1.6e9, 1.6e9 + 4], "track": [7, 7], "lat": [REFERENCE[0]] * 2,
                          "lon": [REFERENCE[1]] * 2, "x_m": [0.0, 400.0], "y_m": [0.0, 0.0], "vx_mps": [100.0] * 2,
                          "vy_mps": [0.0] * 2, "sd_x_m": [5.0] * 2, "sd_y_m": [5.0] * 2, "altitude_m": [3048.0, None],
                          "mode_s": ["3c4a5b", None], "mode_3a": ["0741", "0741"]})
    (flight,) = traffic_from_tracks(frame, REFERENCE)
    d = flight.data
    assert flight.flight_id == "7" and flight.icao24 == "3c4a5b"
    assert d["groundspeed"].tolist() == pytest.approx([100 * 3600 / 1852] * 2, rel=1e-3)
    assert d["track"].tolist() == pytest.approx([90.0, 90.0], abs=0.01)
    assert d["altitude"].iloc[0] == pytest.approx(10000.0) and math.isnan(d["altitude"].iloc[1])
    assert d["timestamp"].iloc[0] == pd.Timestamp(1.6e9, unit="s", tz="UTC")


def test_two_flights_of_one_aircraft_are_refused(flights):
    f = flights[0]
    later = f.assign(timestamp=lambda df: df.timestamp + pd.Timedelta(hours=2))
    with pytest.raises(InputError, match=f"two flights of aircraft {f.icao24}"):
        scenario_from_traffic([f, later], _radars(), reference=REFERENCE)
