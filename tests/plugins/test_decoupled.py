"""The decoupled estimator (seed §1.3.2) against FilterPy and against its own equations."""

import math

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter

from radartracker.estimation.motion import MotionModel
from radartracker.estimation.base import EstimatorConfig, PlaneMeasurement
from radartracker.registry import load_estimator
from radartracker.estimation.measurement import convert_adsb, convert_plots, fill_altitudes, merge, plot_keys
from radartracker.geometry.plane import SystemPlane
from radartracker.pipeline.config import RunConfig
from radartracker.pipeline.run import run


def single_aircraft_measurements(n=120, seed=0):
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.5, 6.0, n))
    truth = np.array([1000.0, -2000.0, 180.0, -60.0])
    z = truth[:2] + np.outer(t, truth[2:]) + rng.normal(0, 50, (n, 2))
    R = [np.array([[2500.0, 300.0], [300.0, 1600.0]]) * rng.uniform(0.5, 2) for _ in range(n)]
    C = [rng.normal(0, 1, (2, 2)) * [1, 1e5] for _ in range(n)]
    return t, z, R, C


@pytest.mark.parametrize("radar", [None, "R1"])
def test_single_aircraft_without_bias_equals_filterpy(radar):
    """With no bias (ADS-B, or a radar whose bias prior is exactly zero) it is the plain KF."""
    t, z, R, C = single_aircraft_measurements()
    q = 0.5
    config = EstimatorConfig(motion=MotionModel(q), bias_sd_range_m=0.0, bias_sd_azimuth_rad=0.0)
    est = load_estimator("decoupled")(config)
    est.add_radar("R1")
    x0, P0 = np.array([z[0, 0], z[0, 1], 0.0, 0.0]), np.diag([1e6, 1e6, 9e4, 9e4])
    est.add_aircraft("a", t[0], x0, P0)

    kf = KalmanFilter(dim_x=4, dim_z=2)
    kf.x, kf.P, kf.H = x0.copy(), P0.copy(), np.hstack([np.eye(2), np.zeros((2, 2))])
    last = t[0]
    for k in range(len(t)):
        dt = t[k] - last
        kf.F = np.array([[1, 0, dt, 0], [0, 1, 0, dt], [0, 0, 1, 0], [0, 0, 0, 1.0]])
        kf.Q = q * np.block([[dt**3 / 3 * np.eye(2), dt**2 / 2 * np.eye(2)], [dt**2 / 2 * np.eye(2), dt * np.eye(2)]])
        kf.predict()
        kf.update(z[k], R=R[k])
        last = t[k]
        est.update(PlaneMeasurement(t[k], "a", radar, z[k], C[k] if radar else np.zeros((2, 2)), R[k]))
        a = est.aircraft("a")
        np.testing.assert_allclose(a.state, kf.x, rtol=1e-9, atol=1e-9 * np.abs(kf.x).max())
        np.testing.assert_allclose(a.cov, kf.P, rtol=1e-9, atol=1e-9 * np.abs(kf.P).max())
    if radar:
        np.testing.assert_array_equal(est.bias("R1").bias, 0.0)


def test_bias_filter_follows_its_equations():
    """One update: ς̂ = K_s Λ_s⁻¹ ν with K_s = P_s Cᵀ, Λ_s = C P_s Cᵀ + R, ν = z − x̄ (independent algebra)."""
    config = EstimatorConfig()
    est = load_estimator("decoupled")(config)
    est.add_radar("R1")
    x0, P0 = np.array([1e4, 2e4, 100.0, 0.0]), np.diag([400.0, 400.0, 100.0, 100.0])
    est.add_aircraft("a", 0.0, x0, P0)
    C = np.array([[0.6, 8e4], [0.8, -6e4]])
    R = np.diag([4900.0, 2500.0])
    z = np.array([1e4 + 1000 + 90, 2e4 + 130])
    est.update(PlaneMeasurement(10.0, "a", "R1", z, C, R))
    Ps = config.bias_prior()
    nu = z - np.array([1e4 + 1000, 2e4])
    s_expected = Ps @ C.T @ np.linalg.inv(C @ Ps @ C.T + R) @ nu
    np.testing.assert_allclose(est.bias("R1").bias, s_expected, rtol=1e-10)
    P = est.bias("R1").cov
    np.testing.assert_allclose(P, P.T, rtol=0, atol=0)
    assert np.all(np.linalg.eigvalsh(P) > 0)


def test_replay_beats_raw_plots(demo_data):
    """Tracks are closer to the truth than the converted plots themselves (independent truth)."""
    from radartracker.pipeline.evaluate import TruthPaths, state_errors

    result = run(demo_data, RunConfig(estimator="decoupled"), progress=False)
    plane = SystemPlane(*demo_data.reference)
    keys = plot_keys(demo_data.plots, True)
    alt, _ = fill_altitudes(demo_data.plots, keys, 0.0)
    meas = merge(convert_plots(demo_data.plots, demo_data.radars, plane, keys, alt), convert_adsb(demo_data.adsb, plane))
    paths = TruthPaths.from_table(demo_data.truth, plane)
    raw = np.zeros((len(meas), 4))
    raw[:, :2] = meas.z
    err, ok = state_errors(paths, meas.key, meas.time, raw)
    plots = np.array([r is not None for r in meas.radar]) & ok
    raw_rmse = math.sqrt(np.mean(np.sum(err[plots, :2] ** 2, axis=1)))
    s = result.summary()
    assert s["truth"]["position_rmse_m"] < 0.6 * raw_rmse
    assert s["counts"]["plots_used"] == len(demo_data.plots)
    assert s["counts"]["adsb_used"] == len(demo_data.adsb)
    for P in result.tracks.cov[:: 97]:
        np.testing.assert_array_equal(P, P.T)
        assert np.all(np.isfinite(P))
