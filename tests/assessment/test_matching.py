"""Matching a radar's plots looks only at the reference aircraft that may come within its reach
(:meth:`Reference.near`), projects only the (aircraft, plot) pairs whose slant range may fill the gate
(:meth:`Reference.slant_range_bounds`), all in one projection: the same matches and expected crossings as
every pair of every aircraft, and the same association as a brute-force loop over plots and aircraft."""

from __future__ import annotations

import math

import attrs
import numpy as np
import pytest

from radartracker.assessment.matching import MatchConfig, match_radar, north_time, wrap_angle
from radartracker.assessment.reference import Reference, build_reference
from radartracker.geometry.plane import RadarFrame
from radartracker.simulation.traffic import traffic_scenario


@pytest.fixture(scope="module", params=["truth", "adsb"])
def scenario(request):
    """Radars 200 km apart seeing 120 km: each sees a few of the aircraft; false plots fill no gate. Against
    the truth (straight lines) and against smoothed ADS-B (splines: every pair within reach projected)."""
    data = traffic_scenario(seed=2, duration=90.0, aircraft=60, radars=4, max_range_km=120.0,
                            false_per_scan=1.0, adsb_share=0.6).run()
    if request.param == "adsb":
        data = attrs.evolve(data, truth=None)
    reference = build_reference(data)
    assert reference.kind == request.param
    return data, reference


def _match(data, reference: Reference, radar, keep=(-math.inf, math.inf)):
    frame = RadarFrame(radar.lat, radar.lon, radar.height_m, reference.plane)
    p = data.plots.take(np.flatnonzero(data.plots.radar == radar.id))
    antenna = (north_time(p.time, p.azimuth_rad, radar.period_s), (float(p.time.min()), float(p.time.max())))
    return frame, p, match_radar(radar, frame, p.time, p.range_m, p.azimuth_rad, (0.0, 0.0), reference,
                                 MatchConfig(), antenna=antenna, keep=keep)


def test_culled_matching_equals_matching_every_aircraft(scenario, monkeypatch):
    data, reference = scenario
    radars = [r for r in data.radars if (data.plots.radar == r.id).any()]
    culled = {(r.id, keep): _match(data, reference, r, keep)[2] for r in radars
              for keep in ((-math.inf, math.inf), (30.0, 60.0))}
    monkeypatch.setattr(Reference, "near", lambda self, site_xy, reach_m: self)
    monkeypatch.setattr(Reference, "slant_range_bounds",
                        lambda self, frame, times: [(np.full(len(t), -np.inf), np.full(len(t), np.inf)) for t in times])
    for (radar_id, keep), a in culled.items():
        b = _match(data, reference, next(r for r in radars if r.id == radar_id), keep)[2]
        for name in ("aircraft", "d2", "ref_range", "ref_azimuth", "ref_altitude", "scan"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=f"{radar_id} {name}")
        assert a.expected.keys() == b.expected.keys()
        for name, v in a.expected.items():
            np.testing.assert_array_equal(v, b.expected[name], err_msg=f"{radar_id} {keep} expected {name}")
    assert any((a.aircraft != "").sum() > 10 and len(a.expected["time"]) > 10 for a in culled.values())
    assert any((a.aircraft == "").any() for a in culled.values())  # false plots


def test_near_keeps_every_aircraft_within_reach(scenario):
    """Every aircraft whose exact slant range (1 s steps) comes within the reach is kept; some are not."""
    data, reference = scenario
    dropped = 0
    for radar in data.radars:
        frame = RadarFrame(radar.lat, radar.lon, radar.height_m, reference.plane)
        near = reference.near(frame.xy, radar.max_range_m)
        dropped += len(reference.tracks) - len(near.tracks)
        for key, track in reference.tracks.items():
            t = np.arange(track.times[0], track.times[-1], 1.0)
            rho, _, _ = frame.polar(*reference.geodetic([key], [t]))
            if rho.min() <= radar.max_range_m:
                assert key in near.tracks, (radar.id, key, rho.min())
    assert dropped > len(reference.tracks)


def test_slant_range_bounds_hold_the_exact_range(scenario):
    """At 0.25 s steps the exact slant range lies within the bounds, which are tight on straight lines."""
    data, reference = scenario
    frame = RadarFrame(data.radars[0].lat, data.radars[0].lon, data.radars[0].height_m, reference.plane)
    times = [np.arange(tr.times[0], tr.times[-1], 0.25) for tr in reference.tracks.values()]
    rho, _, _ = frame.polar(*reference.geodetic(list(reference.tracks), times))
    lo, hi = (np.concatenate(b) for b in zip(*reference.slant_range_bounds(frame, times)))
    assert np.all((lo <= rho) & (rho <= hi))
    if reference.kind == "truth":
        assert np.max(hi - lo) < 3e3


def test_association_equals_a_brute_force_loop(scenario):
    """Each plot's aircraft is the one of least d² ≤ 1 among every aircraft covering its time, found plot by
    plot and aircraft by aircraft."""
    data, reference = scenario
    config = MatchConfig()
    for radar in data.radars[:2]:
        frame, p, m = _match(data, reference, radar)
        for i in range(len(p.time)):
            best, winner = math.inf, ""
            for key, track in reference.tracks.items():
                if not track.covered(p.time[i:i + 1])[0]:
                    continue
                r, a, _ = frame.polar(*reference.geodetic([key], [p.time[i:i + 1]]))
                d2 = float(((p.range_m[i] - r[0]) / config.gate_range_m) ** 2
                           + (wrap_angle(p.azimuth_rad[i] - a[0]) / math.radians(config.gate_azimuth_deg)) ** 2)
                if d2 <= 1.0 and d2 < best:
                    best, winner = d2, key
            assert m.aircraft[i] == winner and m.d2[i] == pytest.approx(best, rel=1e-12), (radar.id, i)
