"""The sensor error model (issue 30): Jacobians against finite differences of the exact model, the coupled
filter against batch least squares and Gauss–Newton, the bound against the batch Fisher information, and
the estimators that refuse the new components."""

from __future__ import annotations

import numpy as np
import pytest

from radartracker.errors import ConfigurationError
from radartracker.estimation.base import EstimatorConfig, PlaneMeasurement
from radartracker.estimation.bound import BoundInput, bias_bound
from radartracker.estimation.motion import MotionModel
from radartracker.estimation.sensor import BiasComponent, SensorModel
from radartracker.geometry.plane import RadarFrame, SystemPlane
from radartracker.registry import make_estimator, make_manager
from radartracker.simulation.scenarios import build_scenario

OMEGA = np.array([[0.0, 1.0], [-1.0, 0.0]])
SITES = {"A": np.array([-40e3, -30e3]), "B": np.array([50e3, -10e3]), "C": np.array([0.0, 60e3])}
W = np.diag([30.0**2, np.radians(0.05) ** 2])
FULL = ("range_gain", "time_offset")
PRIOR_SD = {"range_gain": 1e-3, "time_offset": 0.5}


def _config(extra: tuple[str, ...] = FULL, q: float = 0.0) -> EstimatorConfig:
    base = EstimatorConfig(motion=MotionModel(q))
    sensors = {r: base.sensor(r).with_components(*(BiasComponent(n, PRIOR_SD[n]) for n in extra)) for r in SITES}
    return EstimatorConfig(motion=MotionModel(q), sensors=sensors)


def _toy(rng: np.random.Generator, truth: dict[str, dict[str, float]], n_aircraft: int = 5, duration: float = 300.0,
         hover: bool = False):
    """A flat-plane scenario: straight flights seen by every radar every 5 s, ADS-B on aircraft 0 every 10 s.
    A plot stamped t of radar j is z = p(t) − τ_j v + c_ρ (Δr + g ρ) + c_θ Δθ + C w (C = [u, Ω(p − p_R)])."""
    x0 = {f"a{i}": np.concatenate([rng.uniform(-30e3, 30e3, 2), np.zeros(2) if hover else rng.uniform(-250, 250, 2)])
          for i in range(n_aircraft)}
    meas = []
    for t in np.arange(1.0, duration, 5.0):
        for key, x in x0.items():
            v = x[2:]
            for j, (rid, site) in enumerate(SITES.items()):
                p = x[:2] + (t + 0.1 * j) * v
                d = p - site
                rho = float(np.linalg.norm(d))
                C = np.column_stack([d / rho, OMEGA @ d])
                e = truth.get(rid, {})
                bias = C[:, 0] * (e.get("range_offset", 0.0) + e.get("range_gain", 0.0) * rho) \
                    + C[:, 1] * e.get("azimuth_offset", 0.0) - e.get("time_offset", 0.0) * v
                R = C @ W @ C.T
                meas.append(PlaneMeasurement(t + 0.1 * j, key, rid, p + bias + rng.multivariate_normal(np.zeros(2), R),
                                             C, R, rho))
            if key == "a0" and round(t) % 10 == 1:
                p = x[:2] + (t + 0.5) * v
                meas.append(PlaneMeasurement(t + 0.5, key, None, p + rng.normal(0, 10.0, 2), np.zeros((2, 2)),
                                             100.0 * np.eye(2)))
    meas.sort(key=lambda m: m.time)
    return x0, meas


P0 = np.diag([1e3**2, 1e3**2, 300.0**2, 300.0**2])


def _filter(config: EstimatorConfig, x0: dict, meas: list, name: str = "coupled"):
    est = make_estimator(name, config, list(SITES))
    for key, x in x0.items():
        est.add_aircraft(key, 0.0, x + np.array([200.0, -150.0, 20.0, -10.0]), P0)
    for m in meas:
        est.update(m)
    return est


def _batch(config: EstimatorConfig, x0: dict, meas: list, velocity=None) -> tuple[np.ndarray, np.ndarray, list]:
    """Batch Gauss–Newton (least squares when there is no time offset) over θ = [χ_i(0) …, ς_A, ς_B, ς_C]
    with the priors as pseudo-measurements; ``velocity`` given: the Fisher information at those velocities
    and zero time offsets instead (returns the information as the covariance's inverse, estimate None)."""
    keys, models = list(x0), {r: config.sensor(r) for r in SITES}
    start, k = {}, 4 * len(keys)
    for r, mdl in models.items():
        start[r], k = k, k + mdl.size
    theta = np.concatenate([x0[a] + np.array([200.0, -150.0, 20.0, -10.0]) for a in keys] + [np.zeros(k - 4 * len(keys))])
    prior_info = np.zeros((k, k))
    prior_mean = theta.copy()
    for i in range(len(keys)):
        prior_info[4 * i:4 * i + 4, 4 * i:4 * i + 4] = np.linalg.inv(P0)
    for r, mdl in models.items():
        prior_info[start[r]:start[r] + mdl.size, start[r]:start[r] + mdl.size] = np.linalg.inv(mdl.prior())
    for _ in range(1 if velocity is not None else 12):
        info, grad = prior_info.copy(), prior_info @ (prior_mean - theta)
        for m in meas:
            i = keys.index(m.aircraft)
            p0, v = theta[4 * i:4 * i + 2], theta[4 * i + 2:4 * i + 4]
            H = np.zeros((2, k))
            H[:, 4 * i:4 * i + 2] = np.eye(2)
            h = p0 + m.time * v
            tau = 0.0
            if m.radar is not None:
                mdl, b = models[m.radar], start[m.radar]
                s = theta[b:b + mdl.size]
                vv = velocity[m.aircraft] if velocity is not None else v
                B = np.column_stack([m.C[:, 0], m.C[:, 1], m.rho * m.C[:, 0], -vv][:mdl.size])
                tau = s[3] if mdl.size == 4 and velocity is None else 0.0
                H[:, b:b + mdl.size] = B
                h = h + B @ s
            H[:, 4 * i + 2:4 * i + 4] = (m.time - tau) * np.eye(2)
            Ri = np.linalg.inv(m.R)
            info += H.T @ Ri @ H
            grad += H.T @ Ri @ (m.z - h)
        theta = theta + np.linalg.solve(info, grad)
    return theta, info, [start[r] for r in SITES]


def test_component_columns_agree_with_finite_differences_of_the_exact_polar_model():
    """B's columns against central differences of the exact 3-D model: a plot stamped t of an aircraft on a
    straight path, measured at t − τ with ρ_meas = ρ (1 + g) + Δr and θ_meas = θ + Δθ, converted to the plane."""
    plane = SystemPlane(48.85, 2.35)
    frame = RadarFrame(48.5, 2.0, 120.0, plane)
    p0, v, alt, t = np.array([30e3, 20e3]), np.array([180.0, -140.0]), 9000.0, 50.0

    def z(s: np.ndarray) -> np.ndarray:
        dr, da, g, tau = s
        lat, lon = plane.to_geodetic(*(p0 + (t - tau) * v))
        rho, theta, _ = frame.polar(lat, lon, alt)
        return frame.to_plane(rho * (1 + g) + dr, theta + da, alt)[0]

    zero = np.zeros(4)
    p = z(zero)
    lat, lon = plane.to_geodetic(*p)
    rho = float(frame.polar(lat, lon, alt)[0])
    model = _config().sensor("A")
    assert model.names == ("range_offset", "azimuth_offset", "range_gain", "time_offset")
    B = model.jacobian(frame.bias_jacobian(p, rho, alt), rho, v)
    for k, step in enumerate((1.0, 1e-5, 1e-5, 1e-3)):
        e = np.zeros(4)
        e[k] = step
        fd = (z(e) - z(-e)) / (2 * step)
        np.testing.assert_allclose(B[:, k], fd, rtol=2e-4, atol=1e-6 * np.abs(fd).max())


def test_default_sensor_model_is_the_two_component_config():
    cfg = EstimatorConfig(bias_drift_range=2.0)
    model = cfg.sensor("anything")
    assert model.names == ("range_offset", "azimuth_offset") and model.extra == ()
    np.testing.assert_array_equal(model.prior(), cfg.bias_prior())
    np.testing.assert_array_equal(model.drift(3.0), cfg.bias_drift(3.0))


def test_coupled_with_range_gain_equals_batch_least_squares():
    truth = {"A": {"range_offset": 80.0, "azimuth_offset": 0.002, "range_gain": 3e-4}}
    x0, meas = _toy(np.random.default_rng(5), truth)
    cfg = _config(("range_gain",))
    est = _filter(cfg, x0, meas)
    theta, info, starts = _batch(cfg, x0, meas)
    cov = np.linalg.inv(info)
    for r, b in zip(SITES, starts):
        state = est.bias(r)
        sd = np.sqrt(np.diag(cov)[b:b + 3])
        assert np.all(np.abs(state.bias - theta[b:b + 3]) < 1e-6 * sd)
        np.testing.assert_allclose(np.sqrt(np.diag(state.cov)), sd, rtol=1e-6)
    gain, sd = est.bias("A").component("range_gain")
    assert abs(gain - 3e-4) < 3 * sd < 3e-4  # learnt, and within 3σ of the truth


def test_time_offset_ekf_agrees_with_gauss_newton_and_the_truth():
    """z = p − τ v + … is bilinear: the filter's second-order EKF step against the batch MAP (Gauss–Newton to
    convergence), within a quarter of a σ, and both within 3.5σ of the truth."""
    truth = {"A": {"range_offset": 80.0, "range_gain": 3e-4, "time_offset": 0.1}, "B": {"time_offset": -0.05}}
    x0, meas = _toy(np.random.default_rng(6), truth)
    cfg = _config()
    est = _filter(cfg, x0, meas)
    theta, info, starts = _batch(cfg, x0, meas)
    sd_all = np.sqrt(np.diag(np.linalg.inv(info)))
    for r, b in zip(SITES, starts):
        state = est.bias(r)
        assert np.all(np.abs(state.bias - theta[b:b + 4]) < 0.25 * sd_all[b:b + 4])  # EKF against the MAP
        np.testing.assert_allclose(np.sqrt(np.diag(state.cov)), sd_all[b:b + 4], rtol=0.02)
        want = [truth.get(r, {}).get(n, 0.0) for n in state.components]
        assert np.all(np.abs(state.bias - want) < 3.5 * np.sqrt(np.diag(state.cov))), (r, state.bias, want)


def test_bound_equals_the_batch_fisher_information():
    """q = 0, constant biases: the bound's recursion is the inverse of Σ Hᵀ R⁻¹ H + priors at the true
    velocities (built here independently, in the batch parameters)."""
    x0, meas = _toy(np.random.default_rng(7), {})
    cfg = _config()
    vel = {k: x[2:] for k, x in x0.items()}
    _, info, starts = _batch(cfg, x0, meas, velocity=vel)
    sd = np.sqrt(np.diag(np.linalg.inv(info)))
    geo = _geometry(x0, meas)
    bound = bias_bound(geo, cfg, list(SITES))
    for r, b in zip(SITES, starts):
        np.testing.assert_allclose([c.sd for c in bound[r]], sd[b:b + 4], rtol=1e-6)
        assert all(c.status == "observable" for c in bound[r])


def _geometry(x0: dict, meas: list) -> BoundInput:
    def col(f):
        return [f(m) for m in meas]

    return BoundInput(np.array(col(lambda m: m.time)), np.array(col(lambda m: m.aircraft), object),
                      np.array(col(lambda m: m.radar), object), np.array(col(lambda m: m.C)),
                      np.array(col(lambda m: m.R)), np.array(col(lambda m: m.rho if m.radar else np.nan)),
                      np.array(col(lambda m: x0[m.aircraft][2:])), {k: P0 for k in x0})


def test_time_offset_of_hovering_traffic_is_unobservable_and_stays_at_its_prior():
    """Hovering aircraft (v = 0): the time offset's column −v is zero, the bound says unobservable at its prior
    σ, and the filter, which linearises at its noisy velocity estimates, keeps most of the prior's σ."""
    x0, meas = _toy(np.random.default_rng(8), {"A": {"range_offset": 50.0}}, hover=True)
    cfg = _config()
    bound = bias_bound(_geometry(x0, meas), cfg, list(SITES))
    est = _filter(cfg, x0, meas)
    for r in SITES:
        tau = next(c for c in bound[r] if c.component == "time_offset")
        assert tau.status == "unobservable" and tau.sd == pytest.approx(PRIOR_SD["time_offset"], rel=1e-3)
        value, sd = est.bias(r).component("time_offset")
        assert sd > 0.8 * PRIOR_SD["time_offset"] and abs(value) < PRIOR_SD["time_offset"]
        assert {c.component: c.status for c in bound[r]}["range_offset"] == "observable"


@pytest.mark.parametrize("name", ["blom", "decoupled"])
def test_estimators_without_the_components_refuse_them(name):
    with pytest.raises(ConfigurationError, match=rf"estimator '{name}' does not support bias component 'range_gain' "
                                                  r"\(radar 'A'\)"):
        make_estimator(name, _config(), list(SITES))
    own = EstimatorConfig(sensors={"A": SensorModel.default(10.0, 1e-3)})
    with pytest.raises(ConfigurationError, match="radar 'A'"):
        make_estimator(name, own, list(SITES))


def test_the_track_manager_refuses_components_it_cannot_carry():
    sim = build_scenario("demo", duration=30.0)
    radars = [sr.radar for sr in sim.radars]
    cfg = EstimatorConfig(sensors={"R1": _config(("time_offset",)).sensor("A")})
    est = make_estimator("coupled", cfg, [r.id for r in radars])
    with pytest.raises(ConfigurationError, match="does not carry bias component 'time_offset' \\(radar 'R1'"):
        make_manager(radars, sim.reference, estimator=est)


def test_sensor_model_configuration_errors():
    with pytest.raises(ConfigurationError, match="unknown bias component 'gain'"):
        BiasComponent("gain", 1.0)
    with pytest.raises(ConfigurationError, match="first components must be"):
        SensorModel((BiasComponent("range_gain", 1e-3),))
    with pytest.raises(ConfigurationError, match="appears twice"):
        SensorModel.default(1.0, 1.0).with_components(BiasComponent("range_offset", 1.0))
    with pytest.raises(ConfigurationError, match="drift must be finite and >= 0"):
        BiasComponent("time_offset", 0.1, -1.0)


def test_coupled_with_drifting_gain_equals_filterpy():
    """Process noise and drifting range gains and offsets: FilterPy's KF on the stacked state, predicting every
    block to every measurement, is the oracle (the coupled filter predicts only the measured aircraft)."""
    from filterpy.kalman import KalmanFilter

    x0, meas = _toy(np.random.default_rng(9), {"A": {"range_gain": 2e-4}}, n_aircraft=2, duration=120.0)
    base = EstimatorConfig(motion=MotionModel(0.5))
    model = SensorModel((BiasComponent("range_offset", 300.0, 2.0), BiasComponent("azimuth_offset", 0.01),
                         BiasComponent("range_gain", 1e-3, 1e-10)))
    cfg = EstimatorConfig(motion=base.motion, sensors={r: model for r in SITES})
    est = _filter(cfg, x0, meas)
    keys, dim = list(x0), 8 + 9
    kf = KalmanFilter(dim_x=dim, dim_z=2)
    kf.x = np.concatenate([x0[k] + np.array([200.0, -150.0, 20.0, -10.0]) for k in keys] + [np.zeros(9)])
    kf.P = np.zeros((dim, dim))
    kf.P[:4, :4] = kf.P[4:8, 4:8] = P0
    for j in range(3):
        kf.P[8 + 3 * j:11 + 3 * j, 8 + 3 * j:11 + 3 * j] = model.prior()
    t = 0.0
    for m in meas:
        A, Q = cfg.motion.transition(m.time - t)
        F, Qf = np.eye(dim), np.zeros((dim, dim))
        for i in range(2):
            F[4 * i:4 * i + 4, 4 * i:4 * i + 4], Qf[4 * i:4 * i + 4, 4 * i:4 * i + 4] = A, Q
        if t > 0.0:  # the filter's bias epoch starts at its first measurement
            for j in range(3):
                Qf[8 + 3 * j:11 + 3 * j, 8 + 3 * j:11 + 3 * j] = model.drift(m.time - t)
        kf.predict(F=F, Q=Qf)
        t = m.time
        H = np.zeros((2, dim))
        i = keys.index(m.aircraft)
        H[:, 4 * i:4 * i + 2] = np.eye(2)
        if m.radar is not None:
            j = list(SITES).index(m.radar)
            H[:, 8 + 3 * j:11 + 3 * j] = np.column_stack([m.C[:, 0], m.C[:, 1], m.rho * m.C[:, 0]])
        kf.update(m.z, R=m.R, H=H)
    x, P = est.joint(keys)
    sd = np.sqrt(np.diag(kf.P))
    np.testing.assert_allclose(x / sd, kf.x / sd, atol=1e-9 * np.abs(kf.x / sd).max())
    np.testing.assert_allclose(P / np.outer(sd, sd), kf.P / np.outer(sd, sd), atol=1e-9)


def test_status_from_the_bound_and_the_prior():
    from radartracker.estimation.bound import ComponentBound

    statuses = [ComponentBound("A", "range_gain", sd, 1e-3).status for sd in (1e-3, 0.95e-3, 0.5e-3, 0.2e-3)]
    assert statuses == ["unobservable", "unobservable", "weak", "observable"]


def test_a_range_gain_without_the_slant_range_is_refused_before_anything_changes():
    x0, meas = _toy(np.random.default_rng(10), {}, n_aircraft=1, duration=20.0)
    est = _filter(_config(("range_gain",)), x0, meas[:3])
    before = est.state_dict()
    m = next(m for m in meas[3:] if m.radar is not None)
    with pytest.raises(ValueError, match="radar 'A' has a range gain, which needs the plot's slant range"):
        est.update(PlaneMeasurement(m.time, m.aircraft, m.radar, m.z, m.C, m.R))
    after = est.state_dict()
    np.testing.assert_array_equal(before["P"], after["P"])
    assert before["aircraft"] == after["aircraft"]


def test_a_coupled_state_with_four_components_reloads_and_continues_the_same():
    x0, meas = _toy(np.random.default_rng(11), {"A": {"time_offset": 0.1}}, n_aircraft=2, duration=60.0)
    cfg = _config()
    half = len(meas) // 2
    est = _filter(cfg, x0, meas[:half])
    again = make_estimator("coupled", cfg, list(SITES))
    again.load_state_dict(est.state_dict())
    for m in meas[half:]:
        est.update(m), again.update(m)
    for r in SITES:
        np.testing.assert_array_equal(est.bias(r).bias, again.bias(r).bias)
        assert est.bias(r).components == ("range_offset", "azimuth_offset", "range_gain", "time_offset")
    bad = est.state_dict()
    bad["radars"] = {r: 0 for r in SITES}
    with pytest.raises(ValueError, match="overlap or leave gaps"):
        again.load_state_dict(bad)
