"""Blom–van Doorn macro bias filter (seed 000 §1.3.1, DESIGN §5 item 3): equation-level oracles."""

from __future__ import annotations

import numpy as np
import pytest

from radartracker.simulation.linsim import bias_jacobian, make_linear_scenario
from radartracker.estimation.base import EstimatorConfig, PlaneMeasurement
from radartracker.registry import make_estimator

CFG = EstimatorConfig()
RADAR_XY = {"R1": np.array([-80e3, 0.0]), "R2": np.array([60e3, 70e3])}
SIGMA = np.diag([50.0**2, np.radians(0.1) ** 2])


def _plot(t, radar, p, z_offset=(0.0, 0.0)):
    C = bias_jacobian(p, RADAR_XY[radar])
    return PlaneMeasurement(t, "A", radar, p + np.asarray(z_offset), C, C @ SIGMA @ C.T)


def _fresh():
    est = make_estimator("blom", CFG, list(RADAR_XY))
    est.add_aircraft("A", 0.0, np.array([0.0, 0.0, 150.0, 0.0]), np.diag([200.0**2] * 2 + [20.0**2] * 2))
    return est


def test_single_radar_aircraft_teaches_no_bias():
    """One radar alone cannot separate its bias from the position: G = C_s, K_s = 0."""
    est = _fresh()
    for k in range(20):
        p = np.array([150.0 * 4 * k, 0.0])
        est.update(_plot(4.0 * k, "R1", p, (30.0, -40.0)))
    b = est.bias("R1")
    assert np.all(np.abs(b.bias) <= 1e-9 * np.sqrt(np.diag(CFG.bias_prior())))
    np.testing.assert_allclose(b.cov, CFG.bias_prior(), rtol=1e-9)
    assert est.aircraft("A").cov[0, 0] < 50.0**2  # the aircraft filter did converge


def test_two_radar_update_matches_the_seed_equations():
    """The second radar's plot updates ς exactly as §1.3.1 prescribes, computed here from scratch.

    F_x = Σ R_i⁻¹, F_s = Σ R_i⁻¹ C_{s,i} (placed in radar i's columns), H = −(F_xᵀF_x)⁻¹F_xᵀF_sP̄_s
    (by least squares), K_s = P̄_sC_sᵀ + Hᵀ, and Λ_s of the seed plus the documented G P̄_s Gᵀ term,
    written with the seed's H as H P̄_s⁻¹ Hᵀ.
    """
    est = _fresh()
    m1 = _plot(0.0, "R1", np.array([0.0, 0.0]), (20.0, 10.0))
    est.update(m1)
    prior = est.aircraft("A")
    m2 = _plot(2.0, "R2", np.array([300.0, 0.0]), (-60.0, 25.0))
    est.update(m2)

    A = np.eye(4)
    A[0, 2] = A[1, 3] = 2.0
    Px = A @ prior.cov @ A.T
    xbar = A @ prior.state
    Ps = np.zeros((4, 4))
    Ps[:2, :2] = Ps[2:, 2:] = CFG.bias_prior()
    Fx = np.linalg.inv(m1.R) + np.linalg.inv(m2.R)
    Fs = np.hstack([np.linalg.solve(m1.R, m1.C), np.linalg.solve(m2.R, m2.C)])
    H = -np.linalg.lstsq(Fx.T @ Fx, Fx.T @ Fs @ Ps, rcond=None)[0]
    Cs = np.hstack([np.zeros((2, 2)), m2.C])
    Ks = Ps @ Cs.T + H.T
    Ls = Px[:2, :2] + Cs @ Ps @ Cs.T + H @ Cs.T + Cs @ H.T + m2.R + H @ np.linalg.solve(Ps, H.T)
    nu = m2.z - xbar[:2]
    s_hat = Ks @ np.linalg.solve(Ls, nu)
    P_hat = Ps - Ks @ np.linalg.solve(Ls, Ks.T)
    for j, r in enumerate(RADAR_XY):
        b = est.bias(r)
        np.testing.assert_allclose(b.bias, s_hat[2 * j:2 * j + 2], rtol=1e-9)
        np.testing.assert_allclose(b.cov, P_hat[2 * j:2 * j + 2, 2 * j:2 * j + 2], rtol=1e-9)
    assert abs(est.bias("R1").range_m) > 1.0  # the bias filter did move


def test_seed_lambda_read_literally_is_indefinite():
    """Why the G P̄_s Gᵀ term: the literal Λ_s for a converged single-radar track is not a covariance."""
    est = _fresh()
    for k in range(20):
        est.update(_plot(4.0 * k, "R1", np.array([600.0 * k, 0.0])))
    m = _plot(80.0, "R1", np.array([12e3, 0.0]))
    A = np.eye(4)
    A[0, 2] = A[1, 3] = 4.0
    Px = (A @ est.aircraft("A").cov @ A.T)[:2, :2]
    Ps = CFG.bias_prior()
    H = -m.C @ Ps  # G = C_s for one radar, so H = −C_s P̄_s
    literal = Px + m.C @ Ps @ m.C.T + H @ m.C.T + m.C @ H.T + m.R
    assert np.linalg.eigvalsh(literal)[0] < 0.0


def test_adsb_anchors_biases_and_covariances_stay_psd():
    """ADS-B on an aircraft seen by radars moves the biases; no NaN, P̂_s stays PSD on a long run."""
    sc = make_linear_scenario(n_aircraft=20, n_radars=4, duration=400.0, rng=2, adsb_aircraft=5)
    est = make_estimator("blom", CFG, sc.radar_ids)
    for k, x in sc.initial.items():
        est.add_aircraft(k, 0.0, x, np.diag([300.0**2] * 2 + [30.0**2] * 2))
    moved_by_adsb = False
    for m in sc.measurements:
        before = [est.bias(r).bias for r in sc.radar_ids]
        est.update(m)
        if m.radar is None:
            moved_by_adsb |= any(np.any(b != est.bias(r).bias) for b, r in zip(before, sc.radar_ids))
    assert moved_by_adsb
    for j, r in enumerate(sc.radar_ids):
        b = est.bias(r)
        assert np.isfinite(b.bias).all() and np.isfinite(b.cov).all()
        assert np.linalg.eigvalsh(b.cov / np.sqrt(np.outer(np.diag(b.cov), np.diag(b.cov))))[0] > -1e-9
        # learnt: the error is a tenth of the prior standard deviation (500 m, 0.5°) or less
        assert abs(b.range_m - sc.biases[j, 0]) < 0.1 * CFG.bias_sd_range_m
        assert abs(b.azimuth_rad - sc.biases[j, 1]) < 0.1 * CFG.bias_sd_azimuth_rad


def test_adsb_only_aircraft_leaves_biases_alone():
    est = make_estimator("blom", CFG, list(RADAR_XY))
    est.add_aircraft("B", 0.0, np.zeros(4), np.eye(4) * 1e4)
    for k in range(5):
        est.update(PlaneMeasurement(2.0 * k, "B", None, np.array([5.0, -3.0]), np.zeros((2, 2)), 900.0 * np.eye(2)))
    for r in RADAR_XY:
        assert np.all(est.bias(r).bias == 0.0)
        np.testing.assert_array_equal(est.bias(r).cov, CFG.bias_prior())


def test_non_finite_measurement_is_refused_without_touching_the_state():
    for name in ("blom", "coupled"):
        est = make_estimator(name, CFG, list(RADAR_XY))
        est.add_aircraft("A", 0.0, np.zeros(4), np.eye(4) * 1e4)
        bad = PlaneMeasurement(1.0, "A", "R1", np.array([np.nan, 0.0]), np.eye(2), np.eye(2))
        with pytest.raises(ValueError, match="finite"):
            est.update(bad)
        a = est.aircraft("A")
        assert a.time == 0.0 and np.all(a.state == 0.0) and np.all(a.cov == np.eye(4) * 1e4)
        np.testing.assert_array_equal(est.bias("R1").cov, CFG.bias_prior())
