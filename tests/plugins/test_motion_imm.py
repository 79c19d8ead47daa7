"""IMM and the coordinated-turn model against FilterPy's IMMEstimator, finite differences, the
closed-form kinematic integration, the plain CV filter, a 3°/s turn, and (in the TrackManager) a
plain-numpy IMM."""

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
from radartracker.tracking.manager import ManagerConfig, TrackManager
from radartracker.simulation.simulator import KinematicTrajectory, Leg
from radartracker_plugins.motion import CTMode, CVConfig, CVFilter, CVMode, IMMConfig, IMMFilter
from radartracker_plugins.motion.ct import ct_noise, ct_transition
from tests.plugins.test_motion import assert_close, cv_track, manoeuvre_track, run
from tests.tracking.test_kernels import imm_correction, imm_prediction, switching_matrix


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
    """The default IMM (CV + CT, sojourn-time chain) in plain numpy: the equations of the module
    docstring as written in tests/tracking/test_kernels.py, none of the plugin's code."""

    name = "numpy-imm"

    def __init__(self, config: IMMConfig) -> None:
        self.config_class = type(config)
        super().__init__(config)
        self.modes = [("cv", config.q), ("ct", config.q_turn, config.turn_rate_sd)]
        self.tau = np.array([120.0, 30.0])
        self.entry_var = config.turn_rate_entry_sd**2
        self.time = None

    def start(self, time, z, R):
        x, P = np.array([z[0], z[1], 0.0, 0.0]), np.zeros((4, 4))
        P[:2, :2], P[2:, 2:] = R, self.config.prior_sd_velocity_mps**2 * np.eye(2)
        self.time, self.mu = float(time), self.tau / self.tau.sum()
        self.xs, self.Ps = [x, np.append(x, 0.0)], [P, np.pad(P, (0, 1))]
        self.Ps[1][4, 4] = self.entry_var

    def _prediction(self, time):
        if abs(time - self.time) > self.config.max_gap_s:
            raise ValueError("gap")
        dt = time - self.time
        return imm_prediction(self.mu, self.xs, self.Ps, switching_matrix(self.tau, dt), self.modes, dt, self.entry_var)

    def predict(self, time):
        return self._prediction(time)[2:]

    def update(self, time, z, R):
        mu, states, _, _, nis = imm_correction(*self._prediction(time), np.asarray(z, float), np.asarray(R, float))
        self.time, self.mu = float(time), mu
        self.xs, self.Ps = [s[0] for s in states], [s[1] for s in states]
        return nis

    def estimate(self):
        x = sum(m * s[:4] for m, s in zip(self.mu, self.xs))
        P = sum(m * (C[:4, :4] + np.outer(s[:4] - x, s[:4] - x)) for m, s, C in zip(self.mu, self.xs, self.Ps))
        return self.time, x, P


def test_manager_events_and_biases_with_imm_equal_a_numpy_imm():
    """The TrackManager with the compiled IMM (one prediction per input shared by screening and
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


def test_prediction_kept_for_the_update_and_python_modes_equal_the_compiled_cycle():
    """Predicting first (as screening does, and at other times) leaves the update bit for bit what
    the one-call cycle gives; a mode called in Python gives the compiled cycle's results."""
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
        for a, b in zip(got[1:3], want[1:3]):
            np.testing.assert_array_equal(a, b)
        zc, Rc = z - C @ bias, Rs[k] + C @ bias_cov @ C.T
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
            assert not np.shares_memory(fast.X, old.X) and np.shares_memory(fast.X, fast._buf)
    assert rejected >= 5


def test_screen_refuses_a_step_as_the_default_does():
    """A step beyond max_gap_s (either way), a nan or infinite time, or a filter not started: IMMFilter.screen
    (its compiled call checks the step) raises the ValueError TrackFilter.screen's default raises and leaves
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


def test_screen_many_equals_the_default_loop_and_keeps_predictions_right():
    """IMMFilter.screen_many (one compiled loop over the packed buffers) gives bit for bit what
    TrackFilter.screen_many's default gives through ``screen`` on copies of the filters: a filter's later
    measurements after one outside the gate are not done, a filter not started or of modes called in Python
    is left to ``screen``, and each filter ends with the same epoch, state and predictions, at the time of a
    prediction kept before the call (which a screening not done has overwritten) and at the times screened."""
    t, _, zs, Rs = manoeuvre_track(np.random.default_rng(3), n=12)
    filters = [IMMFilter() for _ in range(3)] + [IMMFilter(), IMMFilter(IMMConfig(modes=(CVMode(), PythonCT())))]
    for k, f in enumerate(filters[:3] + filters[4:]):
        f.start(t[k], zs[k], Rs[k])
        f.update(t[k + 1], zs[k + 1], Rs[k + 1])
    for f in filters[:3]:
        f.predict(t[5])  # a prediction kept at another time than the frame's
    order = [(0, 6), (1, 7), (0, 7), (1, 8), (2, 5), (3, 6), (2, 6), (4, 6), (0, 8)]
    pick = [filters[i] for i, _ in order]
    k = np.array([j for _, j in order])
    C, bias, bias_cov = np.array([[0.8, 2e4], [-0.6, 3e4]]), np.array([30.0, -4e-4]), np.diag([50.0, 2e-8])
    z = zs[k] + C @ bias
    z[1, 0] += 5e3  # filter 1's first measurement: a gross error
    args = (t[k], z, np.repeat(C[None], len(k), 0), Rs[k], np.repeat(bias[None], len(k), 0),
            np.repeat(bias_cov[None], len(k), 0), np.full(len(k), 30.0))
    refs = copy.deepcopy(filters)
    default = {id(f): r for f, r in zip(filters, refs)}
    got = IMMFilter.screen_many(pick, *args)
    want = TrackFilter.screen_many([default[id(f)] for f in pick], *args)
    assert got[3].tolist() == [True, False, True, False, True, False, True, False, True]
    want[3][[5, 7]] = False  # not started, modes in Python: the default screens them, screen_many leaves them
    np.testing.assert_array_equal(got[3], want[3])
    for i in np.flatnonzero(got[3]):
        np.testing.assert_array_equal(got[4][i], want[4][i])
        np.testing.assert_array_equal(got[5][i], want[5][i])
    for a, b in zip(got[:3], want[:3]):
        np.testing.assert_array_equal(a[:5], b[:5])
    assert math.isnan(got[0][5]) and math.isnan(got[0][7])
    for f, r in zip(filters[:3], refs[:3]):
        assert f.time == r.time
        for a, b in zip(f.estimate(), r.estimate()):
            np.testing.assert_array_equal(a, b)
        for time in (t[5], t[7], t[9]):
            for a, b in zip(f.predict(time), r.predict(time)):
                np.testing.assert_array_equal(a, b)
    assert filters[3].time is None and filters[4].time == t[4]  # left as they were
