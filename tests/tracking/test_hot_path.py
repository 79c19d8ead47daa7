"""The TrackManager's fast path gives the results of an independent implementation.

The manager runs a built-in scenario twice: with the ``cv`` plugin (compiled kernels, batched
conversion) and with a CV track filter written on FilterPy's functional Kalman steps, fed the same
way. Events (time, track, kind, status, state) and the final bias estimates must agree to tight
tolerances — any change of the hot path that changes a result fails here.
"""

import attrs
import numpy as np
import pytest
from filterpy.kalman import predict as kf_predict
from filterpy.kalman import update as kf_update

from radartracker.api import TrackFilter
from radartracker.estimation.motion import MotionModel
from radartracker.pipeline.stream import scenario_stream
from radartracker.registry import make_filter_factory
from radartracker.simulation.scenarios import build_scenario
from radartracker.tracking.association import altitude_spread
from radartracker.domain import AdsbReport, nacp_sigma_m
from radartracker.tracking.manager import FrameMeasurements, ManagerConfig, TrackEvent, TrackManager
from radartracker_plugins.motion.cv import CVConfig
from tests.tracking.reference import OneAtATimeManager

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


class LoopManager(OneAtATimeManager):
    """The per-frame steps written the straightforward way — one track, one radar, one report, one
    measurement at a time, with RadarFrame's own conversion — as the manager did them before they became
    array passes."""

    def _predict(self, live, t):
        pred = super()._predict(live, t)
        pos = np.zeros((len(live), 2))
        for i, tr in enumerate(live):
            t0, x, _ = tr.filter.estimate()
            pos[i] = x[:2] + x[2:] * max(t - t0, 0.0)
        pred["pos"] = pos
        return pred

    def _convert_frame(self, by_radar, reports, positions, live):
        parts = []
        for rid, plots in by_radar.items():
            by_code = {t.mode_s: t for t in live if t.mode_s}
            alt = np.array([p.altitude_m if p.altitude_m is not None else
                            (by_code[p.mode_s].altitude_m if p.mode_s in by_code and by_code[p.mode_s].altitude_m
                             is not None else self.config.primary_altitude_m) for p in plots])
            rho = np.array([p.range_m for p in plots])
            frame = self.frames[rid]
            z, ok = frame.to_plane(rho, np.array([p.azimuth_rad for p in plots]), alt)
            C = frame.bias_jacobian(z, rho, alt)
            R = C @ self.radars[rid].W @ np.swapaxes(C, 1, 2)
            guess = np.array([p.altitude_m is None for p in plots]) & (alt == self.config.primary_altitude_m)
            if guess.any():
                R[guess] += altitude_spread(C[guess], rho[guess], alt[guess], self.radars[rid].height_m,
                                            self.config.primary_altitude_sd_m)
            parts += [(p.time, zk, Ck, Rk, self._converter.row[rid], okk) for p, zk, Ck, Rk, okk in zip(plots, z, C, R, ok)]
        for r in reports:
            sd = nacp_sigma_m(r.nacp)
            xy = np.array([float(v) for v in self.plane.to_plane(r.lat, r.lon)])
            parts.append((r.time, xy, np.zeros((2, 2)), sd * sd * np.eye(2), -1, True))
        for m in positions:
            parts.append((m.time, np.asarray(m.z, float), np.zeros((2, 2)), np.asarray(m.R, float), -1, True))
        azimuth = np.array([p.azimuth_rad for plots in by_radar.values() for p in plots], float)
        if not parts:
            return FrameMeasurements(np.zeros(0), np.zeros((0, 2)), np.zeros((0, 2, 2)), np.zeros((0, 2, 2)),
                                     np.zeros(0, np.int64)), np.zeros(0, bool), azimuth
        t, z, C, R, radar, ok = zip(*parts)
        return (FrameMeasurements(np.array(t, float), np.array(z), np.array(C), np.array(R), np.array(radar, np.int64)),
                np.array(ok, bool), azimuth)

    def _misses(self, live, pred, assigned, t_a, t_b):
        for k, (rid, radar) in enumerate(self.radars.items()):  # phases by radar row
            if not self._phased[k] or not live:
                continue
            d = pred["pos"] - self.frames[rid].xy
            rng = np.hypot(d[:, 0], d[:, 1])
            az = np.mod(np.arctan2(d[:, 0], d[:, 1]) - self._north[rid], 2 * np.pi)
            start = np.angle(self._phase[k]) + 2 * np.pi * t_a / radar.period_s
            swept = np.mod(az - start, 2 * np.pi) < 2 * np.pi * (t_b - t_a) / radar.period_s
            for i in np.flatnonzero(swept & (rng < 0.98 * radar.max_range_m)):
                tr = live[i]
                if i in assigned.get(rid, set()) or tr.id not in self.tracks or tr.created >= t_a:
                    continue
                tr.history.append(False)
                if tr.status == "confirmed":
                    tr.status = "coasting"
                    self._emit(t_b, tr, "coasting")

    def _sweep(self, live, pred, now):
        cfg = self.config
        covered = np.zeros(len(live), bool)
        for rid, r in self.radars.items():
            covered |= np.hypot(*(pred["pos"] - self.frames[rid].xy).T) <= r.max_range_m
        for i, tr in enumerate(live):
            if tr.id not in self.tracks:
                continue
            hopeless = tr.status == "tentative" and len(tr.history) - sum(tr.history) > cfg.confirm_n - cfg.confirm_m
            if hopeless or now - tr.last_update > cfg.delete_after_s or not (covered[i] or tr.n_adsb):
                self._delete(tr, now)

    def _emit(self, time, tr, kind):
        t0, x, _ = tr.filter.estimate()
        if time > t0:
            x = np.concatenate([x[:2] + x[2:] * (time - t0), x[2:]])
        ev = TrackEvent(float(time), tr.id, kind, tr.status, tuple(float(v) for v in x))
        self._events.append(ev)


@pytest.mark.parametrize("name, model", [("tracking", "cv"), ("manoeuvres", "imm")])
def test_array_passes_equal_the_straightforward_loops(name, model):
    """Frame conversion over all radars, prediction, misses and sweep as arrays over the frame's tracks,
    and events from the kept estimate: the same events and biases as one-at-a-time loops."""
    data = build_scenario(name, seed=5, duration=300.0).run()
    config = ManagerConfig(motion_model=model)
    runs = []
    for cls in (TrackManager, LoopManager):
        mgr = cls(data.radars, data.reference, config)
        runs.append((mgr.process_many(scenario_stream(data)), mgr.biases(), mgr.accounting()))
    (fast, fast_b, fast_n), (ref, ref_b, ref_n) = runs
    assert len(fast) > 300 and fast_n == ref_n and any(e.kind == "coasting" for e in ref)
    assert [(e.time, e.track, e.kind, e.status) for e in fast] == [(e.time, e.track, e.kind, e.status) for e in ref]
    np.testing.assert_allclose([e.state for e in fast], [e.state for e in ref], rtol=1e-12, atol=1e-6)  # plot → plane: 1 µm
    for rid in ref_b:
        np.testing.assert_allclose(fast_b[rid].bias, ref_b[rid].bias, rtol=1e-10, atol=1e-15)
        np.testing.assert_allclose(fast_b[rid].cov, ref_b[rid].cov, rtol=1e-10, atol=1e-20)


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


@pytest.mark.parametrize("model", ["cv", "imm"])
def test_screening_in_one_call_equals_one_measurement_at_a_time(model):
    """On a stream with gross errors (rejections, a re-initialised track), the frame's measurements of
    confirmed tracks screened by one ``screen_many`` and the rest one by one give the events, biases and
    counts of screening and updating every measurement at its turn."""
    data = build_scenario("demo", seed=2, duration=300.0).run()
    items = _dirty(data)
    config = ManagerConfig(motion_model=model)
    runs = []
    for cls in (TrackManager, LoopManager):
        mgr = cls(data.radars, data.reference, config)
        runs.append((mgr.process_many(items), mgr.biases(), mgr.accounting()))
    (fast, fast_b, fast_n), (ref, ref_b, ref_n) = runs
    assert fast_n == ref_n
    assert fast_n.get("plots_outlier", 0) > 20 and fast_n.get("adsb_implausible_speed", 0) + fast_n.get("adsb_outlier", 0) > 5
    assert fast_n.get("tracks_reinitialised", 0) >= 1
    assert [(e.time, e.track, e.kind, e.status) for e in fast] == [(e.time, e.track, e.kind, e.status) for e in ref]
    np.testing.assert_allclose([e.state for e in fast], [e.state for e in ref], rtol=1e-12, atol=1e-6)  # plot → plane: 1 µm
    for rid in ref_b:
        np.testing.assert_allclose(fast_b[rid].bias, ref_b[rid].bias, rtol=1e-10, atol=1e-15)
        np.testing.assert_allclose(fast_b[rid].cov, ref_b[rid].cov, rtol=1e-10, atol=1e-20)
