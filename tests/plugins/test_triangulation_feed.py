"""Triangulated fixes as tracker measurements, consumed by an estimator plugin.

Oracles: pyproj (the plane position of a station's own site; Monte Carlo through the exact
map for R), batch weighted least squares over the same measurements, χ² bounds.
"""

import numpy as np
from scipy import stats

from radartracker.geometry.plane import SystemPlane
from radartracker.estimation.motion import MotionModel
from radartracker.estimation.base import EstimatorConfig, PlaneMeasurement
from radartracker.registry import load_estimator
from radartracker_plugins.triangulation import (DirectionFinder, TriangulationFrame, fix_measurement,
                                                locate, plane_measurement)
from radartracker_plugins.triangulation.simulate import noisy_bearings, sites_around, true_bearings

LAT, LON, SIG = 45.0, 10.0, 1e-3


def _frame():
    sites = sites_around(LAT, LON, 50e3, [0, 120, 240])
    return TriangulationFrame([DirectionFinder(f"d{i}", la, lo, 200.0, SIG, SIG)
                               for i, (la, lo) in enumerate(sites)], reference=(45.1, 10.2, 0.0))


def test_plane_measurement_is_unbiased_and_at_the_pyproj_plane_position():
    frame, plane = _frame(), SystemPlane(44.8, 9.7)
    s = frame.stations["d1"]
    m = plane_measurement(frame, plane, frame.position["d1"], np.eye(3), 12.0, "ac1")
    assert np.allclose(m.z, np.ravel(plane.to_plane(s.lat, s.lon)), atol=1e-6)
    assert m.radar is None and m.time == 12.0 and m.aircraft == "ac1"
    assert np.array_equal(m.C, np.zeros((2, 2))) and m.R.shape == (2, 2) and np.allclose(m.R, m.R.T)


def test_plane_covariance_matches_monte_carlo_through_the_exact_map():
    frame, plane = _frame(), SystemPlane(44.8, 9.7)
    r = frame.enu(45.3, 10.1, 9000.0)
    L = np.array([[300.0, 0, 0], [120.0, 80.0, 0], [40.0, -30.0, 150.0]])
    cov = L @ L.T
    m = plane_measurement(frame, plane, r, cov, 0.0, "a")
    samples = r + np.random.default_rng(0).standard_normal((20000, 3)) @ L.T
    lat, lon, _ = frame.geodetic(samples)
    xy = np.column_stack(plane.to_plane(lat, lon))
    emp = np.cov(xy.T)
    # sampling error of a covariance from 20000 draws: ~1.5 % of the scale; use 5 %
    assert np.allclose(m.R, emp, atol=0.05 * np.sqrt(np.outer(np.diag(emp), np.diag(emp))).max())
    assert np.allclose(m.z, xy.mean(axis=0), atol=10.0)


def _flight(frame, plane, times):
    """A constant-velocity flight in the system plane at 9 km; frame positions and plane states."""
    x0, v = np.array([-20e3, 5e3]), np.array([180.0, -60.0])
    xy = x0 + np.outer(times, v)
    lat, lon = plane.to_geodetic(xy[:, 0], xy[:, 1])
    return frame.enu(lat, lon, np.full(len(times), 9000.0)), np.hstack([x0, v])


def _measurements(frame, plane, times, rng):
    r, chi0 = _flight(frame, plane, times)
    ids = list(frame.stations)
    out = []
    for t, p in zip(times, r):
        truth = true_bearings(frame, ids, np.tile(p, (3, 1)))
        fix = locate(frame, noisy_bearings(frame, ids, [t] * 3, truth, rng))
        out.append(fix_measurement(frame, plane, fix, "ac"))
    return out, chi0


def _batch(chi_prior, P0, ms):
    """Weighted LS of the initial state from the prior and all plane measurements (no process noise)."""
    info, vec = np.linalg.inv(P0), np.linalg.solve(P0, chi_prior)
    for m in ms:
        H = np.hstack([np.eye(2), m.time * np.eye(2)])
        info += H.T @ np.linalg.solve(m.R, H)
        vec += H.T @ np.linalg.solve(m.R, m.z)
    return np.linalg.solve(info, vec), np.linalg.inv(info)


def test_estimator_consumes_fixes_like_adsb_and_matches_batch_and_chi2():
    frame, plane = _frame(), SystemPlane(LAT, LON)
    rng = np.random.default_rng(42)
    times = np.arange(0.0, 200.0, 5.0)
    ms, chi0 = _measurements(frame, plane, times, rng)
    # mix in unbiased ADS-B-like position reports of the same aircraft (σ = 50 m)
    adsb_t = np.arange(2.5, 200.0, 20.0)
    xy = chi0[:2] + np.outer(adsb_t, chi0[2:])
    ms += [PlaneMeasurement(float(t), "ac", None, p + 50.0 * rng.standard_normal(2), np.zeros((2, 2)),
                            2500.0 * np.eye(2)) for t, p in zip(adsb_t, xy)]
    ms.sort(key=lambda m: m.time)
    P0 = np.diag([2e3, 2e3, 100.0, 100.0]) ** 2
    prior = chi0 + np.sqrt(np.diag(P0)) * rng.standard_normal(4)

    est = load_estimator("decoupled")(EstimatorConfig(motion=MotionModel(q=0.0)))
    est.add_aircraft("ac", 0.0, prior, P0)
    nis = [est.update(m).nis for m in ms]
    final = est.aircraft("ac")

    x0, P = _batch(prior, P0, ms)
    A, _ = MotionModel().transition(final.time)
    assert np.allclose(final.state, A @ x0, rtol=1e-6, atol=1e-4)
    assert np.allclose(final.cov, A @ P @ A.T, rtol=1e-6)
    err = final.state - A @ chi0
    assert err @ np.linalg.solve(final.cov, err) < stats.chi2.ppf(0.999, 4)
    n = len(nis)
    assert stats.chi2.ppf(0.0005, 2 * n) < sum(nis) < stats.chi2.ppf(0.9995, 2 * n)
