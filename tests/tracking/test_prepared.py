"""A frame's plots of every radar converted in one pass equal RadarFrame's conversion radar by radar; its compiled
phase recurrence equals the Python loop it replaces."""

import math

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
        np.testing.assert_allclose(z[k], zr, rtol=0, atol=1e-9)
        np.testing.assert_allclose(C[k], Cr, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(R[k], Rr, rtol=1e-12, atol=1e-9)
        assert list(ok[k]) == list(okr)
    for r, p in zip(reports, xy):
        assert tuple(p) == tuple(float(v) for v in plane.to_plane(r.lat, r.lon))
    # R within rounding of numpy's C W Cᵀ (bit for bit where numpy's BLAS fuses multiply-adds, as OpenBLAS
    # does here; its own rounding is the next test's)
    np.testing.assert_allclose(R, C @ conv.W[rows] @ np.swapaxes(C, 1, 2), rtol=1e-14, atol=1e-9)
    # the frame's rows: plots radar by radar from (radar row, count) runs, then the ADS-B reports
    order = np.argsort(rows, kind="stable")
    radars, counts = np.unique(rows[order], return_counts=True)
    nacp = rng.integers(1, 12, len(reports))
    lat, lon = np.array([r.lat for r in reports]), np.array([r.lon for r in reports])
    zf, Cf, Rf, rf, okf = conv.convert_frame(radars, counts, rho[order], theta[order], alt[order], lat, lon, nacp)
    n = len(plots)
    assert list(rf) == list(rows[order]) + [-1] * len(reports) and list(okf) == list(ok[order])
    assert zf[:n].tobytes() == z[order].tobytes() and Cf[:n].tobytes() == C[order].tobytes()
    assert Rf[:n].tobytes() == R[order].tobytes() and zf[n:].tobytes() == xy.tobytes()
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


def test_compiled_products_round_as_fused_multiply_adds_from_zero():
    """_dot2(a0, a1, b0, b1) = fma(a1, b1, fma(a0, b0, +0)) + 0 (oracle: exact rational arithmetic, rounded
    once per step), on values of all magnitudes and zeros of either sign; never −0."""
    from fractions import Fraction

    from radartracker.tracking.prepared import _dot2

    def fma(a: float, b: float, c: float) -> float:  # correctly rounded a·b + c (a zero result: +0 here)
        return float(Fraction(a) * Fraction(b) + Fraction(c))

    rng = np.random.default_rng(5)
    values = rng.normal(size=(4000, 4)) * 10.0 ** rng.integers(-160, 150, (4000, 4))
    values[:200] = rng.choice([0.0, -0.0, 1e-170, -1e-170, 1.0, -3.0], (200, 4))
    for a0, a1, b0, b1 in values.tolist():
        got, want = _dot2(a0, a1, b0, b1), fma(a1, b1, fma(a0, b0, 0.0)) + 0.0
        assert got == want and math.copysign(1, got) == math.copysign(1, want)
        assert not (got == 0 and math.copysign(1, got) < 0)
