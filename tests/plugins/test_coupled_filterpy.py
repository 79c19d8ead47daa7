"""Single aircraft, zero bias: every estimator equals FilterPy's KalmanFilter to 1e-9 (DESIGN §9)."""

from __future__ import annotations

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter

from radartracker.simulation.linsim import make_linear_scenario
from radartracker.estimation.motion import MotionModel
from radartracker.estimation.base import EstimatorConfig
from radartracker.registry import make_estimator


@pytest.mark.parametrize("name", ["decoupled", "blom", "coupled"])
@pytest.mark.parametrize("q", [0.0, 2.0])
def test_single_aircraft_zero_bias_equals_filterpy(name, q):
    """Radar plots (C_s ≠ 0 but a zero bias prior) and ADS-B reports of one aircraft."""
    sc = make_linear_scenario(n_aircraft=1, n_radars=3, duration=200.0, rng=21, adsb_aircraft=1,
                              bias_sd_range_m=0.0, bias_sd_azimuth_rad=0.0, q=q)
    cfg = EstimatorConfig(motion=MotionModel(q), bias_sd_range_m=0.0, bias_sd_azimuth_rad=0.0)
    x0 = sc.initial["A0000"] + np.array([300.0, -200.0, 10.0, -5.0])
    P0 = np.diag([1e3**2, 1e3**2, 100.0**2, 100.0**2])
    est = make_estimator(name, cfg, sc.radar_ids)
    est.add_aircraft("A0000", 0.0, x0, P0)
    kf = KalmanFilter(dim_x=4, dim_z=2)
    kf.x, kf.P = x0.copy(), P0.copy()
    kf.H = np.hstack([np.eye(2), np.zeros((2, 2))])
    t = 0.0
    for m in sc.measurements:
        A, Q = cfg.motion.transition(m.time - t)
        t = m.time
        kf.predict(F=A, Q=Q)
        kf.update(m.z, R=m.R)
        est.update(m)
        got = est.aircraft("A0000")
        assert got.time == m.time
        np.testing.assert_allclose(got.state, kf.x, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(got.cov, kf.P, rtol=1e-9, atol=1e-12)
    assert {m.radar for m in sc.measurements} == {None, *sc.radar_ids}
    for r in sc.radar_ids:
        assert np.all(est.bias(r).bias == 0.0) and np.all(est.bias(r).cov == 0.0)
