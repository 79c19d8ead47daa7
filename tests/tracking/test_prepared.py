"""A frame's plots of every radar converted in one pass equal RadarFrame's conversion radar by radar (its own
pyproj topocentric pipeline per radar: an independent computation), within 1 µm for positions (and C_s's
azimuth column, in metres) and 1e-9 relative for C_s and R; ADS-B rows equal pyproj's plane projection."""

import numpy as np
import pytest

from radartracker.domain import AdsbReport, Plot, nacp_sigma_m
from radartracker.geometry.plane import RadarFrame, SystemPlane
from radartracker.pipeline.stream import scenario_stream
from radartracker.simulation.scenarios import build_scenario
from radartracker.tracking.prepared import PlaneConverter


def test_one_pass_over_all_radars_equals_radar_frame_per_radar():
    data = build_scenario("tracking", seed=2, duration=120.0).run()
    items = list(scenario_stream(data))
    plots = [p for p in items if isinstance(p, Plot)]
    reports = [r for r in items if isinstance(r, AdsbReport)]
    plots.append(Plot(50.0, data.radars[0].id, 300.0, 1.0, 9000.0))  # no point at 300 m slant range and 9 km: invalid
    assert len({p.radar for p in plots}) > 1 and reports and any(p.altitude_m is None for p in plots)
    plane = SystemPlane(*data.reference)
    frames = {r.id: RadarFrame(r.lat, r.lon, r.height_m, plane) for r in data.radars}
    conv = PlaneConverter(data.radars, frames, plane)
    rng = np.random.default_rng(0)
    alt = np.array([6000.0 if p.altitude_m is None else p.altitude_m for p in plots]) + rng.uniform(-50, 50, len(plots))
    rows = np.array([conv.row[p.radar] for p in plots])
    rho = np.array([p.range_m for p in plots])
    theta = np.array([p.azimuth_rad for p in plots])
    z, C, R, ok, xy = conv.convert(rows, rho, theta, alt, np.array([r.lat for r in reports]),
                                   np.array([r.lon for r in reports]))
    assert not ok[-1] and ok[:-1].all()
    for radar in data.radars:  # the straightforward way: RadarFrame, one radar at a time
        k = np.flatnonzero(rows == conv.row[radar.id])
        frame = frames[radar.id]
        zr, okr = frame.to_plane(rho[k], theta[k], alt[k])
        Cr = frame.bias_jacobian(zr, rho[k], alt[k])
        Rr = Cr @ radar.W @ np.swapaxes(Cr, 1, 2)
        np.testing.assert_allclose(z[k], zr, rtol=0, atol=1e-6)
        np.testing.assert_allclose(C[k], Cr, rtol=1e-9, atol=1e-6)  # azimuth column in metres: 1 µm
        np.testing.assert_allclose(R[k], Rr, rtol=1e-9, atol=1e-6)
        assert list(ok[k]) == list(okr)
    for r, p in zip(reports, xy):
        np.testing.assert_allclose(p, [float(v) for v in plane.to_plane(r.lat, r.lon)], rtol=0, atol=1e-6)
    # the frame's rows: plots radar by radar from (radar row, count) runs, then the ADS-B reports
    order = np.argsort(rows, kind="stable")
    radars, counts = np.unique(rows[order], return_counts=True)
    nacp = rng.integers(1, 12, len(reports))
    lat, lon = np.array([r.lat for r in reports]), np.array([r.lon for r in reports])
    zf, Cf, Rf, rf, okf = conv.convert_frame(radars, counts, rho[order], theta[order], alt[order], lat, lon, nacp)
    n = len(plots)
    assert list(rf) == list(rows[order]) + [-1] * len(reports) and list(okf) == list(ok[order])
    np.testing.assert_allclose(zf[:n], z[order], rtol=0, atol=1e-6)
    np.testing.assert_allclose(Cf[:n], C[order], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(Rf[:n], R[order], rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(zf[n:], xy, rtol=0, atol=1e-6)
    sd = np.array([nacp_sigma_m(int(a)) for a in nacp])
    assert (Cf[n:] == 0).all() and (Rf[n:] == (sd**2)[:, None, None] * np.eye(2)).all()
    for bad in (0, 12):
        with pytest.raises(ValueError, match="nacp"):
            conv.convert_frame(radars, counts, rho[order], theta[order], alt[order], lat, lon, np.full(len(lat), bad))
    with pytest.raises(ValueError, match="counts"):
        conv.convert_frame(radars, counts + 1, rho[order], theta[order], alt[order], lat, lon, nacp)
    # no plots, only ADS-B: nothing to locate
    z0, C0, R0, ok0, xy0 = conv.convert(rows[:0], rho[:0], theta[:0], alt[:0], np.array([reports[0].lat]),
                                        np.array([reports[0].lon]))
    assert z0.shape == (0, 2) and C0.shape == (0, 2, 2) and ok0.shape == (0,) and tuple(xy0[0]) == tuple(xy[0])
