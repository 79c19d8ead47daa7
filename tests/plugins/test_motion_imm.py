"""IMM and the coordinated-turn model against FilterPy's IMMEstimator, finite differences, the
closed-form kinematic integration, the plain CV filter, a 3°/s turn, and (in the TrackManager) the
plain IMM of tests/plugins/imm_oracle.py."""

from __future__ import annotations

import copy
import math

import attrs
import numpy as np
import pytest
from filterpy.kalman import IMMEstimator, KalmanFilter
from scipy.linalg import expm

from radartracker.registry import make_manager
from radartracker.geometry.kinematics import propagate
from radartracker.estimation.motion import MotionModel
from radartracker.api import ConfigurationError, TrackFilter
from radartracker.pipeline.stream import scenario_stream
from radartracker.registry import make_filter_factory
from radartracker.simulation.scenarios import build_scenario
from radartracker.registry import motion_q
from radartracker.tracking.config import ManagerConfig
from radartracker.simulation.simulator import KinematicTrajectory, Leg
from radartracker_plugins.motion import CTMode, CVConfig, CVFilter, CVMode, IMMConfig, IMMFilter
from radartracker_plugins.motion.ct import ct_noise, ct_transition
from tests.plugins.test_motion import assert_close, cv_track, manoeuvre_track, run
from tests.plugins.imm_oracle import PlainIMM, sojourn_generator
from tests.plugins.test_motion_imm_oracle import oracle_modes


@pytest.mark.parametrize("w", [0.0, 1e-7, -3e-6, math.radians(3.0), -math.radians(6.0), 0.4])
@pytest.mark.parametrize("T", [0.3, 4.0, 12.0])
def test_ct_jacobian_finite_differences(w, T):
    xi = np.array([1e4, -5e3, 180.0, -120.0, w])
    _, F = ct_transition(xi, T)
    J = np.empty((5, 5))
    for k in range(5):
        h = 1e-6 if k == 4 else 1e-3
        e = np.zeros(5)
        e[k] = h
        J[:, k] = (ct_transition(xi + e, T)[0] - ct_transition(xi - e, T)[0]) / (2 * h)
    np.testing.assert_allclose(F, J, rtol=1e-6, atol=1e-6 * T)


@pytest.mark.parametrize("w", [0.0, 1e-6, math.radians(3.0), -math.radians(4.5)])
def test_ct_matches_closed_form_kinematics(w):
    """f(ξ) is the seed's kinematic model (DESIGN §7) with lateral acceleration u = v ω, w = 0."""
    phi, v = math.radians(35.0), 210.0
    xi = np.array([2e3, 7e3, v * math.sin(phi), v * math.cos(phi), w])
    tau = np.array([0.5, 4.0, 30.0, 90.0])
    x, y, p, _ = propagate(xi[0], xi[1], phi, v, v * w, 0.0, tau)
    for k, T in enumerate(tau):
        f, _ = ct_transition(xi, T)
        np.testing.assert_allclose(f[:4], [x[k], y[k], v * math.sin(p[k]), v * math.cos(p[k])], rtol=1e-10, atol=1e-6)
    np.linalg.cholesky(ct_noise(4.0, 1.0, math.radians(0.5)))


def test_imm_single_model_and_identical_models_equal_cv():
    t, _, zs, Rs = cv_track(np.random.default_rng(11), q=3.0)
    cv = run(CVFilter(CVConfig(q=3.0)), t, zs, Rs)
    one = run(IMMFilter(IMMConfig(modes=(CVMode(3.0),))), t, zs, Rs)
    two = run(IMMFilter(IMMConfig(modes=(CVMode(3.0), CVMode(3.0)), sojourn_s=(50.0, 20.0))), t, zs, Rs)
    assert_close(one, cv)
    assert_close(two, cv)


def filterpy_imm(t, zs, Rs, qs, mu0, M=None, G=None):
    """FilterPy's IMMEstimator with CV filters of densities ``qs``; M fixed or exp(G Δt) per step."""
    filters = []
    for _ in qs:
        kf = KalmanFilter(dim_x=4, dim_z=2)
        kf.x = np.concatenate([zs[0], [0.0, 0.0]])
        kf.P = np.diag([0.0, 0.0, 300.0**2, 300.0**2])
        kf.P[:2, :2] = Rs[0]
        kf.H = np.hstack([np.eye(2), np.zeros((2, 2))])
        filters.append(kf)
    imm = IMMEstimator(filters, np.asarray(mu0), M if M is not None else expm(G * (t[1] - t[0])))
    xs, Ps, mus, nis = [], [], [], []
    for k in range(1, len(t)):
        dt = t[k] - t[k - 1]
        if G is not None:
            imm.M = expm(G * dt)
            imm._compute_mixing_probabilities()  # c̄ and ω from the new M (FilterPy caches them)
        for kf, q in zip(filters, qs):
            kf.F, kf.Q = MotionModel(q).transition(dt)
            kf.R = Rs[k]
        imm.predict()
        # the predicted mixture weighs the mode priors by c̄ = μ Π (FilterPy's x_prior uses μ instead)
        xb = sum(c * kf.x for c, kf in zip(imm.cbar, filters))
        Pb = sum(c * (kf.P + np.outer(kf.x - xb, kf.x - xb)) for c, kf in zip(imm.cbar, filters))
        nu = zs[k] - xb[:2]
        nis.append(float(nu @ np.linalg.solve(Pb[:2, :2] + Rs[k], nu)))
        imm.update(zs[k])
        xs.append(imm.x.copy())
        Ps.append(imm.P.copy())
        mus.append(imm.mu.copy())
    return np.array(xs), np.array(Ps), np.array(nis), np.array(mus)




@pytest.mark.parametrize("switching", ["fixed", "sojourn"])
def test_imm_equals_filterpy_on_linear_models(switching):
    """Two CV modes (quiet and manoeuvring densities): the IMM recursion itself against FilterPy."""
    t, _, zs, Rs = manoeuvre_track(np.random.default_rng(12))
    qs, mu0 = [0.5, 150.0], [0.7, 0.3]
    modes = [CVMode(q) for q in qs]
    if switching == "fixed":  # composed as FilterPy's IMMEstimator(filters, mu, M)
        M = np.array([[0.95, 0.05], [0.15, 0.85]])
        f = IMMFilter.from_modes(modes, M, mu0)
        ref = filterpy_imm(t, zs, Rs, qs, mu0, M=M)
    else:
        tau = np.array([90.0, 25.0])
        G = np.array([[-1 / tau[0], 1 / tau[0]], [1 / tau[1], -1 / tau[1]]])
        f = IMMFilter(IMMConfig(modes=tuple(modes), sojourn_s=tau, initial_probabilities=mu0))
        ref = filterpy_imm(t, zs, Rs, qs, mu0, G=G)
    f.start(t[0], zs[0], Rs[0])
    mus = []
    xs, Ps, nis = [], [], []
    for k in range(1, len(t)):
        nis.append(f.update(t[k], zs[k], Rs[k]))
        _, x, P = f.estimate()
        xs.append(x)
        Ps.append(P)
        mus.append(f.probabilities)
    assert_close((np.array(xs), np.array(Ps), np.array(nis), np.array(mus)), ref)
    # the manoeuvre (steps 30–40) moves the probability to the manoeuvring mode and back
    mus = np.array(mus)
    assert mus[33:40, 1].max() > 0.9 and mus[:28, 1].max() < 0.5 and mus[-1, 1] < 0.5


def turn_run(seed: int, filters: dict) -> dict:
    """200 m/s, 60 s straight, 90 s at 3°/s, 60 s straight; plots every 4 s with σ = 80 m.

    Returns the position RMSE over the turn (and the 20 s after it) for each filter."""
    rng = np.random.default_rng(seed)
    v = 200.0
    traj = KinematicTrajectory(0.0, 0.0, 0.0, 9000.0, rng.uniform(0, 2 * np.pi), v,
                               [Leg(60.0), Leg.turn(90.0, 3.0 * rng.choice([-1, 1]), v), Leg(60.0)])
    t = np.arange(0.0, 210.0, 4.0) + rng.uniform(0, 4)
    x, y, _ = traj.position(t)
    R = 80.0**2 * np.eye(2)
    zs = np.stack([x, y], axis=-1) + rng.normal(0, 80.0, (len(t), 2))
    in_turn = (t >= 60.0) & (t <= 170.0)
    out = {}
    for name, f in filters.items():
        f.start(t[0], zs[0], R)
        err = [0.0]
        for k in range(1, len(t)):
            f.update(t[k], zs[k], R)
            err.append(float(np.hypot(*(f.estimate()[1][:2] - [x[k], y[k]]))))
        out[name] = float(np.sqrt(np.mean(np.square(err)[in_turn])))
    return out


def test_imm_beats_cv_on_a_3deg_turn():
    """Against the same CV density (q = 1) and against a CV tuned for the turn (q = 100, a²T ≈ 110)."""
    res = [turn_run(s, {"cv": CVFilter(CVConfig(q=1.0)), "cv100": CVFilter(CVConfig(q=100.0)),
                        "imm": IMMFilter(IMMConfig(q=1.0))}) for s in range(8)]
    mean = {k: np.mean([r[k] for r in res]) for k in res[0]}
    assert mean["imm"] < 0.3 * mean["cv"], mean
    assert mean["imm"] < mean["cv100"], mean
    assert sum(r["imm"] < r["cv"] for r in res) == len(res)


@pytest.mark.parametrize("bad", [{"modes": ("ca",)}, {"modes": ()}, {"modes": (CVMode(),), "q": 5.0},
                                 {"transition": [[0.5, 0.6], [0.5, 0.5]]}, {"sojourn_s": [10.0]},
                                 {"transition": [[0.9, 0.1], [0.1, 0.9]], "sojourn_s": [10.0, 10.0]},
                                 {"initial_probabilities": [-1.0, 1.0]}])
def test_imm_bad_config(bad):
    key = next(k for k in bad if k != "q")
    with pytest.raises(ConfigurationError, match=key):
        IMMConfig(**bad)


def test_switching_matrix_equals_scipy_expm():
    """Π(Δt) = exp(G Δt) for three modes (G: leaving rate 1/τ_i shared equally), against scipy."""
    from scipy.linalg import expm

    tau = np.array([100.0, 30.0, 20.0])
    f = IMMFilter(IMMConfig(modes=(CVMode(), CTMode(), CVMode(50.0)), sojourn_s=tau))
    G = np.ones((3, 3)) / (2 * tau[:, None])
    np.fill_diagonal(G, -1 / tau)
    for dt in (0.0, 0.7, 7.3, 400.0):
        np.testing.assert_allclose(f.switching(dt), expm(G * dt), atol=1e-12)


class NumpyIMM(TrackFilter):
    """The default IMM (CV + CT, sojourn-time chain) as the plain IMM of mode filter objects
    (tests/plugins/imm_oracle.py), none of the plugin's code."""

    name = "numpy-imm"

    def __init__(self, config: IMMConfig) -> None:
        self.config_class = type(config)
        super().__init__(config)
        self.specs = [("cv", config.q), ("ct", config.q_turn, config.turn_rate_sd)]
        self.tau = np.array([120.0, 30.0])
        self.time = None

    def start(self, time, z, R):
        c = self.config
        modes = oracle_modes(self.specs, np.asarray(z, float), np.asarray(R, float), c.prior_sd_velocity_mps,
                             c.turn_rate_entry_sd**2)
        self.imm = PlainIMM(modes, self.tau / self.tau.sum(), c.turn_rate_entry_sd**2, G=sojourn_generator(self.tau))
        self.time = float(time)

    def _stepped(self, time):
        if abs(time - self.time) > self.config.max_gap_s:
            raise ValueError("gap")
        imm = copy.deepcopy(self.imm)
        return imm, imm.predict(time - self.time)

    def predict(self, time):
        return self._stepped(time)[1]

    def update(self, time, z, R):
        self.imm = self._stepped(time)[0]
        self.time = float(time)
        return self.imm.update(np.asarray(z, float), np.asarray(R, float))

    def estimate(self):
        return (self.time, *self.imm.estimate())


def test_manager_events_and_biases_with_imm_equal_a_numpy_imm():
    """The TrackManager with the plugin's IMM (one prediction per input shared by screening and
    update) and with :class:`NumpyIMM`: the same events and biases on a scenario with manoeuvres."""
    data = build_scenario("manoeuvres", seed=4, duration=150.0).run()
    config = ManagerConfig(motion_model="imm")
    imm_config = make_filter_factory("imm", motion_q(config), config.motion).config  # the manager's own
    assert imm_config.q == config.estimator_config.motion.q

    def replay(factory=None):
        mgr = make_manager(data.radars, data.reference, config, filter_factory=factory)
        events = mgr.process_many(scenario_stream(data))
        return events, {rid: mgr.estimator.bias(rid) for rid in mgr.radars}, mgr.accounting()

    fast, fast_b, fast_n = replay()
    ref, ref_b, ref_n = replay(lambda: NumpyIMM(imm_config))
    assert len(fast) > 200 and fast_n == ref_n
    assert [(e.time, e.track, e.kind, e.status) for e in fast] == [(e.time, e.track, e.kind, e.status) for e in ref]
    np.testing.assert_allclose([e.state for e in fast], [e.state for e in ref], rtol=1e-9, atol=1e-6)
    for rid in ref_b:
        np.testing.assert_allclose(fast_b[rid].bias, ref_b[rid].bias, rtol=1e-8, atol=1e-12)
        np.testing.assert_allclose(fast_b[rid].cov, ref_b[rid].cov, rtol=1e-8, atol=1e-18)


@attrs.frozen
class PythonCT:
    """A mode filter the IMM calls through ``predict`` (the same CT model, in numpy)."""

    q: float = 1.0
    turn_rate_sd: float = math.radians(0.5)
    dim = 5

    def predict(self, x, P, dt):
        f, F = ct_transition(x, dt)
        return f, F @ P @ F.T + ct_noise(dt, self.q, self.turn_rate_sd)


def test_prediction_kept_for_the_update_and_python_modes_equal_the_built_in_ones():
    """Predicting first (as screening does, and at other times) leaves the update bit for bit what an
    update without a kept prediction gives; a mode called in Python gives the built-in modes' results."""
    t, _, zs, Rs = manoeuvre_track(np.random.default_rng(21))
    plain, screened = IMMFilter(), IMMFilter()
    python = IMMFilter(IMMConfig(modes=(CVMode(), PythonCT())))
    for f in (plain, screened, python):
        f.start(t[0], zs[0], Rs[0])
    for k in range(1, len(t)):
        screened.predict(t[k] - 1.5)
        x, P = screened.predict(t[k])
        x[:] = 0.0  # the caller's copy: changing it changes nothing
        nis = [f.update(t[k], zs[k], Rs[k]) for f in (plain, screened, python)]
        assert nis[0] == nis[1] and nis[2] == pytest.approx(nis[0], rel=1e-7)
        for a, b in zip(plain.estimate(), screened.estimate()):
            np.testing.assert_array_equal(a, b)
        np.testing.assert_allclose(python.estimate()[1], plain.estimate()[1], rtol=1e-10, atol=1e-7)
        np.testing.assert_allclose(python.probabilities, plain.probabilities, rtol=1e-8, atol=1e-12)
    restored = IMMFilter()
    restored.load_state_dict(screened.state_dict())
    for a, b in zip(restored.estimate(), screened.estimate()):
        np.testing.assert_array_equal(a, b)
    for a, b in zip(restored.predict(t[-1] + 4.0), screened.predict(t[-1] + 4.0)):
        np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("modes", [None, (CVMode(), PythonCT())])
def test_screen_in_one_call_equals_the_default_on_predict_and_update(modes):
    """IMMFilter.screen (one compiled call: bias correction, prediction, d², update in the gate) gives
    bit for bit what TrackFilter.screen's default gives through predict and update, and the d² of
    screening's equations on numpy (solve); outside the gate the filter is unchanged, and the
    measurement it returns updates it later as in one call. A deep copy (pickle state) continues
    identically on its own buffer."""
    rng = np.random.default_rng(5)
    t, _, zs, Rs = manoeuvre_track(rng)
    config = IMMConfig() if modes is None else IMMConfig(modes=modes)
    fast, ref = IMMFilter(config), IMMFilter(config)
    for f in (fast, ref):
        f.start(t[0], zs[0], Rs[0])
    C, bias, bias_cov = np.array([[0.8, 2e4], [-0.6, 3e4]]), np.array([30.0, -4e-4]), np.diag([50.0, 2e-8])
    rejected = 0
    for k in range(1, len(t)):
        z = zs[k] + C @ bias + (rng.normal(size=2) * 2e3 if k % 7 == 0 else 0.0)  # every 7th: a gross error
        gate = 30.0 if k % 3 else None
        got = fast.screen(t[k], z, C, Rs[k], bias, bias_cov, gate)
        want = TrackFilter.screen(ref, t[k], z, C, Rs[k], bias, bias_cov, gate)
        assert got[0] == want[0] and got[3] == want[3]
        zc, Rc = z - C @ bias, Rs[k] + C @ bias_cov @ C.T
        if got[3]:  # updated: the corrected measurement is not handed back
            assert got[1] is None and got[2] is None
        else:
            for a, b in zip(got[1:3], want[1:3]):
                np.testing.assert_array_equal(a, b)
            np.testing.assert_allclose(got[1], zc, rtol=1e-13)
            np.testing.assert_allclose(got[2], Rc, rtol=1e-13)
        x, P = ref.predict(t[k]) if not got[3] else (None, None)
        if x is not None:
            nu = zc - x[:2]
            assert got[0] == pytest.approx(float(nu @ np.linalg.solve(P[:2, :2] + Rc, nu)), rel=1e-9)
            rejected += gate is not None
            if got[0] < 500.0:  # not a gross error: used after screening, at the same time
                assert fast.update(t[k], got[1], got[2]) == ref.update(t[k], want[1], want[2])
        assert fast.time == ref.time
        for a, b in zip(fast.estimate(), ref.estimate()):
            np.testing.assert_array_equal(a, b)
        if k == 40:
            old, fast = fast, copy.deepcopy(fast)
            assert not np.shares_memory(fast.X, old.X)
    assert rejected >= 5


def test_screen_refuses_a_step_as_the_default_does():
    """A step beyond max_gap_s (either way), a nan or infinite time, or a filter not started: IMMFilter.screen
    raises the ValueError TrackFilter.screen's default raises and leaves
    the filter as it was; a step just within the gap is screened as the default screens it."""
    t, _, zs, Rs = manoeuvre_track(np.random.default_rng(8))
    config = IMMConfig(max_gap_s=20.0)
    C, bias, bias_cov = np.zeros((2, 2)), np.zeros(2), np.zeros((2, 2))
    with pytest.raises(ValueError) as want:
        TrackFilter.screen(IMMFilter(config), t[0], zs[0], C, Rs[0], bias, bias_cov, 1e9)
    with pytest.raises(ValueError) as got:
        IMMFilter(config).screen(t[0], zs[0], C, Rs[0], bias, bias_cov, 1e9)
    assert str(got.value) == str(want.value)
    fast, ref = IMMFilter(config), IMMFilter(config)
    for f in (fast, ref):
        f.start(t[0], zs[0], Rs[0])
        f.update(t[1], zs[1], Rs[1])
    before = copy.deepcopy(fast.state_dict())
    for time in (t[1] + 20.5, t[1] - 20.5, math.nan, math.inf):
        with pytest.raises(ValueError) as want:
            TrackFilter.screen(ref, time, zs[2], C, Rs[2], bias, bias_cov, 1e9)
        with pytest.raises(ValueError) as got:
            fast.screen(time, zs[2], C, Rs[2], bias, bias_cov, 1e9)
        assert str(got.value) == str(want.value)
        state = fast.state_dict()
        assert state["time"] == before["time"] and np.array_equal(state["mu"], before["mu"])
        for a, b in zip(state["xs"] + state["Ps"], before["xs"] + before["Ps"]):
            np.testing.assert_array_equal(a, b)
    got = fast.screen(t[1] + 19.5, zs[2], C, Rs[2], bias, bias_cov, 1e9)
    want = TrackFilter.screen(ref, t[1] + 19.5, zs[2], C, Rs[2], bias, bias_cov, 1e9)
    assert got[0] == want[0] and got[3] is want[3] is True
    for a, b in zip(fast.estimate(), ref.estimate()):
        np.testing.assert_array_equal(a, b)
