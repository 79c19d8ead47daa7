"""The TrackManager's fast path gives the results of an independent implementation.

The manager runs a built-in scenario twice: with the ``cv`` plugin (compiled kernels, batched
conversion) and with a CV track filter written on FilterPy's functional Kalman steps, fed the same
way. Events (time, track, kind, status, state) and the final bias estimates must agree to tight
tolerances — any change of the hot path that changes a result fails here.
"""

import numpy as np
import pytest
from filterpy.kalman import predict as kf_predict
from filterpy.kalman import update as kf_update

from radartracker.api import TrackFilter
from radartracker.estimation.motion import MotionModel
from radartracker.pipeline.stream import scenario_stream
from radartracker.registry import make_filter_factory
from radartracker.simulation.scenarios import build_scenario
from radartracker.tracking.manager import ManagerConfig, TrackManager
from radartracker_plugins.motion.cv import CVConfig

H = np.eye(2, 4)


class FilterPyCV(TrackFilter):
    """CV track filter on filterpy.kalman.predict/update with the plugin's settings."""

    name = "filterpy-cv"

    def __init__(self, config) -> None:
        self.config_class = type(config)
        super().__init__(config)
        self.model = MotionModel(config.q)
        self.time = None

    def start(self, time, z, R):
        self.time = float(time)
        self.x = np.array([z[0], z[1], 0.0, 0.0])
        self.P = np.zeros((4, 4))
        self.P[:2, :2] = R
        self.P[2:, 2:] = self.config.prior_sd_velocity_mps**2 * np.eye(2)

    def predict(self, time):
        if abs(time - self.time) > self.config.max_gap_s:
            raise ValueError("gap")
        A, Q = self.model.transition(time - self.time)
        return kf_predict(self.x, self.P, A, Q)

    def update(self, time, z, R):
        x, P = self.predict(time)
        nu = z - x[:2]
        S = P[:2, :2] + R
        self.x, self.P = kf_update(x, P, np.asarray(z, float), np.asarray(R, float), H)
        self.time = float(time)
        return float(nu @ np.linalg.solve(S, nu))

    def estimate(self):
        return self.time, self.x.copy(), self.P.copy()


def replay(data, config, factory=None):
    mgr = TrackManager(data.radars, data.reference, config, filter_factory=factory)
    events = mgr.process_many(scenario_stream(data))
    return events, {rid: mgr.estimator.bias(rid) for rid in mgr.radars}, mgr.accounting()


@pytest.mark.parametrize("name", ["tracking", "manoeuvres"])
def test_events_and_biases_equal_an_independent_filter(name):
    data = build_scenario(name, seed=4, duration=400.0).run()
    config = ManagerConfig(motion_model="cv", motion=CVConfig(q=5.0))
    cv_config = make_filter_factory("cv", config.motion_options, config.motion).config
    assert cv_config.q == 5.0
    fast, fast_b, fast_n = replay(data, config)
    ref, ref_b, ref_n = replay(data, config, lambda: FilterPyCV(cv_config))
    assert len(fast) > 300 and fast_n == ref_n
    assert [(e.time, e.track, e.kind, e.status) for e in fast] == [(e.time, e.track, e.kind, e.status) for e in ref]
    np.testing.assert_allclose([e.state for e in fast], [e.state for e in ref], rtol=1e-9, atol=1e-6)
    for rid in ref_b:
        np.testing.assert_allclose(fast_b[rid].bias, ref_b[rid].bias, rtol=1e-8, atol=1e-12)
        np.testing.assert_allclose(fast_b[rid].cov, ref_b[rid].cov, rtol=1e-8, atol=1e-18)
