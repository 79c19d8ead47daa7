"""The TrackManager gives the results of independent implementations.

The manager runs built-in scenarios twice: with the ``cv`` plugin and with a CV track filter written on
FilterPy's functional Kalman steps, fed the same way. Events (time, track, kind, status, state) and the
final bias estimates must agree to tight tolerances. The frame's conversion is held to each radar's own.
"""

import attrs
import numpy as np
import pytest
from filterpy.kalman import predict as kf_predict
from filterpy.kalman import update as kf_update

from radartracker.registry import make_manager
from radartracker.api import TrackFilter
from radartracker.estimation.motion import MotionModel
from radartracker.pipeline.stream import scenario_stream
from radartracker.registry import make_filter_factory
from radartracker.simulation.scenarios import build_scenario
from radartracker.tracking.association import altitude_spread
from radartracker.domain import AdsbReport, nacp_sigma_m
from radartracker.domain import Plot
from radartracker.geometry.plane import RadarFrame
from radartracker.tracking.config import ManagerConfig
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
    mgr = make_manager(data.radars, data.reference, config, filter_factory=factory)
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


def test_frame_conversion_equals_each_radars_own_conversion():
    """FrameBuilder converts a frame's plots of every radar and its ADS-B reports in one pass: the same
    z, C_s, R (with the altitude guess's spread where a plot has no altitude) as each radar's RadarFrame
    and the plane's own projection, one input at a time (oracle)."""
    from radartracker.tracking.frame import FrameBuilder

    data = build_scenario("tracking", seed=5, duration=200.0).run()
    mgr = make_manager(data.radars, data.reference, ManagerConfig())
    items = [it for it in scenario_stream(data)][:400]
    items = [attrs.evolve(it, altitude_m=None) if isinstance(it, Plot) and k % 3 == 0 else it
             for k, it in enumerate(items)]
    cfg = mgr.config
    frame = FrameBuilder(mgr.frames.converter, cfg.primary_altitude_m, cfg.primary_altitude_sd_m).build(0.0, 1.0, items, [])
    assert len(frame.plots) > 100 and len(frame.reports) > 10
    for row, p in enumerate(frame.plots):
        rf = RadarFrame(mgr.radars[p.radar].lat, mgr.radars[p.radar].lon, mgr.radars[p.radar].height_m, mgr.plane)
        alt = p.altitude_m if p.altitude_m is not None else cfg.primary_altitude_m
        z, ok = rf.to_plane(np.array([p.range_m]), np.array([p.azimuth_rad]), np.array([alt]))
        C = rf.bias_jacobian(z, np.array([p.range_m]), np.array([alt]))
        R = C @ mgr.radars[p.radar].W @ np.swapaxes(C, 1, 2)
        if p.altitude_m is None:
            R = R + altitude_spread(C, np.array([p.range_m]), np.array([alt]), mgr.radars[p.radar].height_m,
                                    cfg.primary_altitude_sd_m)
        assert bool(ok[0]) == bool(frame.valid[row])
        np.testing.assert_allclose(frame.meas.z[row], z[0], rtol=0, atol=1e-6)
        np.testing.assert_allclose(frame.meas.C[row], C[0], rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(frame.meas.R[row], R[0], rtol=1e-9, atol=1e-6)
    for k, r in enumerate(frame.reports):
        row = frame.first_report_row + k
        sd = nacp_sigma_m(r.nacp)
        np.testing.assert_allclose(frame.meas.z[row], [float(v) for v in mgr.plane.to_plane(r.lat, r.lon)], atol=1e-6)
        np.testing.assert_allclose(frame.meas.R[row], sd * sd * np.eye(2), rtol=1e-12)
        assert not frame.meas.C[row].any() and frame.meas.radar[row] == -1


def _dirty(data, seed=3):
    """The scenario's inputs with gross errors: 3 % of the plots 4 km too far, 3 % of the ADS-B reports
    0.05° off, and one address's reports shifted by 0.03° from the middle on (its track re-initialised)."""
    rng = np.random.default_rng(seed)
    items = list(scenario_stream(data))
    codes = sorted({it.icao24 for it in items if type(it) is AdsbReport})
    t_mid = 0.5 * (items[0].time + items[-1].time)
    out = []
    for it in items:
        if type(it) is AdsbReport:
            if codes and it.icao24 == codes[0] and it.time > t_mid:
                it = attrs.evolve(it, lat=it.lat + 0.03)
            elif rng.random() < 0.03:
                it = attrs.evolve(it, lat=it.lat + 0.05)
        elif rng.random() < 0.03:
            it = attrs.evolve(it, range_m=it.range_m + 4000.0)
        out.append(it)
    return out


def test_screening_of_a_dirty_stream_equals_an_independent_filter():
    """On a stream with gross errors (rejections, a re-initialised track), the manager with the ``cv`` plugin
    and with the FilterPy CV filter (screened by TrackFilter's own predict-then-update ``screen``) give the
    same events, biases and counts."""
    data = build_scenario("demo", seed=2, duration=300.0).run()
    items = _dirty(data)
    config = ManagerConfig(motion_model="cv", motion=CVConfig(q=5.0))
    cv_config = make_filter_factory("cv", config.motion_options, config.motion).config
    runs = []
    for factory in (None, lambda: FilterPyCV(cv_config)):
        mgr = make_manager(data.radars, data.reference, config, filter_factory=factory)
        runs.append((mgr.process_many(items), mgr.biases(), mgr.accounting(), mgr.track_counts()))
    (fast, fast_b, fast_n, fast_t), (ref, ref_b, ref_n, ref_t) = runs
    assert fast_n == ref_n and fast_t == ref_t
    assert fast_n.get("plots_outlier", 0) > 20 and fast_n.get("adsb_implausible_speed", 0) + fast_n.get("adsb_outlier", 0) > 5
    assert fast_t.get("tracks_reinitialised", 0) >= 1 and sum(fast_n.values()) == len(items)
    assert [(e.time, e.track, e.kind, e.status) for e in fast] == [(e.time, e.track, e.kind, e.status) for e in ref]
    np.testing.assert_allclose([e.state for e in fast], [e.state for e in ref], rtol=1e-9, atol=1e-6)
    for rid in ref_b:
        np.testing.assert_allclose(fast_b[rid].bias, ref_b[rid].bias, rtol=1e-8, atol=1e-12)
        np.testing.assert_allclose(fast_b[rid].cov, ref_b[rid].cov, rtol=1e-8, atol=1e-18)
