"""Plots converted in bulk equal the manager's per-frame conversion of a few plots at a time."""

import numpy as np

from radartracker.geometry.plane import RadarFrame, SystemPlane
from radartracker.pipeline.stream import scenario_stream
from radartracker.simulation.scenarios import build_scenario
from radartracker.tracking.prepared import PreparedPlot, prepare
from radartracker.domain import Plot


def test_bulk_conversion_equals_small_groups():
    data = build_scenario("tracking", seed=2, duration=120.0).run()
    plots = [p for p in scenario_stream(data) if isinstance(p, Plot)]
    plots.append(Plot(50.0, "A", 30e3, 1.0, None, "abcdef"))  # no altitude, Mode S: its track's altitude
    plane = SystemPlane(*data.reference)
    frames = {r.id: RadarFrame(r.lat, r.lon, r.height_m, plane) for r in data.radars}
    radars = {r.id: r for r in data.radars}
    done = prepare(plots, frames, radars, 6000.0)
    assert type(done[-1]) is Plot and all(isinstance(p, PreparedPlot) for p in done[:-1])
    assert any(p.altitude_m is None for p in done[:-1])  # primary plots are converted at the default altitude
    for k in range(0, len(plots) - 1, 3):  # groups of three, as a frame would see them
        ks = [j for j in range(k, min(k + 3, len(plots) - 1)) if plots[j].radar == plots[k].radar]
        group = [plots[j] for j in ks]
        rho = np.array([p.range_m for p in group])
        theta = np.array([p.azimuth_rad for p in group])
        alt = np.array([6000.0 if p.altitude_m is None else p.altitude_m for p in group])
        frame = frames[plots[k].radar]
        z, ok = frame.to_plane(rho, theta, alt)
        C = frame.bias_jacobian(z, rho, alt)
        R = C @ radars[plots[k].radar].W @ np.swapaxes(C, 1, 2)
        got = [done[j] for j in ks]
        assert [p.time for p in got] == [p.time for p in group]
        np.testing.assert_allclose([p.z for p in got], z, rtol=0, atol=1e-9)
        np.testing.assert_allclose([p.C for p in got], C, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose([p.R for p in got], R, rtol=1e-12, atol=1e-9)
        assert [p.valid for p in got] == list(ok)
        assert all(p.assumed_altitude_m == a for p, a in zip(got, alt))
