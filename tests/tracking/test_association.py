"""Association rules: tiered GNN against brute force, the altitude filter against FilterPy, and the
TrackManager on primary-only plots (identities kept through crossings, tracks kept while plots arrive)."""

import itertools
import math

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter

from radartracker.registry import make_manager
from radartracker.domain import Aircraft
from radartracker.geometry.plane import SystemPlane
from radartracker.simulation.scenarios import _radar
from radartracker.simulation.simulator import KinematicTrajectory, Leg, SimAircraft, SimRadar, Simulator
from radartracker.pipeline.stream import scenario_stream
from radartracker.tracking.association import MODE_C_VAR, VERTICAL_Q, AltitudeTrack, assign_tiers
from radartracker.tracking.config import ManagerConfig

GATE, EXCL = 13.82, 27.63


def _brute_gnn(pairs, d2, cost, allowed_plots):
    """Minimum of Σ cost over matchings of gated pairs (plots in ``allowed_plots``), each plot left
    out priced at the gate plus its smallest ln det S, exactly as ``assign`` prices it."""
    keep = [n for n in range(len(pairs)) if d2[n] <= GATE and pairs[n][0] in allowed_plots]
    plots = sorted({pairs[n][0] for n in keep})
    logdet = {p: min(cost[n] - d2[n] for n in keep if pairs[n][0] == p) for p in plots}
    best, best_m = math.inf, {}
    for r in range(len(keep) + 1):
        for combo in itertools.combinations(keep, r):
            ps, ts = [pairs[n][0] for n in combo], [pairs[n][1] for n in combo]
            if len(set(ps)) < len(ps) or len(set(ts)) < len(ts):
                continue
            total = sum(cost[n] for n in combo) + sum(GATE + logdet[p] for p in plots if p not in ps)
            if total < best - 1e-9:
                best, best_m = total, {pairs[n][0]: pairs[n][1] for n in combo}
    return best_m


@pytest.mark.parametrize("seed", range(30))
def test_tiers_match_brute_force(seed):
    """Confirmed tracks (tier 0) are matched first; tentative ones only get plots outside every
    confirmed track's exclusion region; a plot within it is flagged (it must not start a track)."""
    rng = np.random.default_rng(seed)
    n_p, n_t = 3, 4
    tier = rng.integers(0, 2, n_t)
    pairs = np.array([(p, t) for p in range(n_p) for t in range(n_t) if rng.random() < 0.7], int).reshape(-1, 2)
    d2 = np.array([rng.choice([rng.uniform(0, GATE), rng.uniform(GATE, EXCL), rng.uniform(EXCL, 50)])
                   for _ in range(len(pairs))])
    cost = d2 + rng.uniform(15, 30, len(pairs))
    matches, in_gate = assign_tiers(pairs, d2, cost, GATE, tier, EXCL)
    first = [n for n in range(len(pairs)) if tier[pairs[n][1]] == 0]
    second = [n for n in range(len(pairs)) if tier[pairs[n][1]] == 1]
    excluded = {int(pairs[n][0]) for n in first if d2[n] <= EXCL}
    expect = _brute_gnn([tuple(pairs[n]) for n in first], d2[first], cost[first], set(range(n_p)))
    expect.update(_brute_gnn([tuple(pairs[n]) for n in second], d2[second], cost[second],
                             set(range(n_p)) - excluded))
    assert matches == expect
    assert {p for p in range(len(in_gate)) if in_gate[p]} == excluded


def test_confirmed_beats_tentative_even_at_higher_cost():
    pairs = np.array([[0, 0], [0, 1]])
    d2, cost = np.array([9.0, 0.5]), np.array([9.0 + 17.0, 0.5 + 21.0])  # the tentative track is cheaper
    matches, in_gate = assign_tiers(pairs, d2, cost, GATE, np.array([0, 1]), EXCL)
    assert matches == {0: 0} and in_gate.tolist() == [True]


def test_altitude_filter_equals_filterpy():
    rng = np.random.default_rng(4)
    t = np.cumsum(rng.uniform(0.5, 12.0, 40))
    h = 3000 + 12.0 * t + rng.normal(0, 10, len(t))
    ours = AltitudeTrack.start(t[0], h[0])
    kf = KalmanFilter(dim_x=2, dim_z=1)
    kf.x, kf.P, kf.H, kf.R = np.array([h[0], 0.0]), ours.P.copy(), np.array([[1.0, 0.0]]), np.array([[MODE_C_VAR]])
    for k in range(1, len(t)):
        dt = t[k] - t[k - 1]
        kf.F = np.array([[1.0, dt], [0.0, 1.0]])
        kf.Q = VERTICAL_Q * np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
        kf.predict()
        hp, v, p00, p01, p11 = ours.predicted(t[k])  # what gating uses
        np.testing.assert_allclose([hp, v], kf.x, rtol=1e-12, atol=1e-9)
        np.testing.assert_allclose([[p00, p01], [p01, p11]], kf.P, rtol=1e-12, atol=1e-9)
        kf.update(h[k])
        ours.update(t[k], h[k])
        np.testing.assert_allclose(ours.x, kf.x, rtol=1e-10, atol=1e-8)
        np.testing.assert_allclose(ours.P, kf.P, rtol=1e-9, atol=1e-9)


def _scenario(aircraft_specs, duration=420.0, seed=3, false_per_scan=0.0):
    """Primary-only plots with Mode C (no Mode S, no Mode 3/A) from two radars."""
    plane = SystemPlane(48.85, 2.35)
    radars = [SimRadar(_radar(plane, "A", -50, -40, period=4.0), 80.0, math.radians(0.1), pd=0.9,
                       false_per_scan=false_per_scan),
              SimRadar(_radar(plane, "B", 60, -20, period=6.0), -50.0, math.radians(-0.12), pd=0.9, phase_rad=2.0,
                       false_per_scan=false_per_scan)]
    aircraft = [SimAircraft(Aircraft(f"{0x4d0000 + i:06x}", f"T{i}", transponder="mode_a_c"), traj)
                for i, traj in enumerate(aircraft_specs)]
    data = Simulator((48.85, 2.35), radars, aircraft, 0.0, duration, seed=seed).run()
    data.plots.mode_3a[:] = None
    return data


def _run(data):
    """Every event of the TrackManager (default settings, so the default motion model) over ``data``."""
    mgr = make_manager(data.radars, data.reference, ManagerConfig(estimator="coupled-sparse"))
    return mgr.process_many(scenario_stream(data))


def _crossing(angle_deg, dz_m, v=220.0, duration=420.0):
    half = duration / 2
    out = []
    for k, hd in enumerate((math.radians(45.0), math.radians(45.0 + angle_deg))):
        out.append(KinematicTrajectory(0.0, -v * half * math.sin(hd), -v * half * math.cos(hd), 9000.0 + k * dz_m, hd, v,
                                       [Leg(duration)]))
    return out


def _metrics(data, events):
    """CLEAR-MOT-style track metrics (radartracker.pipeline.evaluate) of the confirmed tracks."""
    from radartracker.pipeline.evaluate import TrackHistory, TruthPaths, track_metrics

    rows: dict[int, list] = {}
    for e in events:
        rows.setdefault(e.track, []).append(e)
    tracks = {}
    for tid, evs in rows.items():
        rep = [e for e in evs if e.kind in ("confirmed", "updated", "coasting")]
        if rep:
            end = next((e.time for e in evs if e.kind == "deleted"), rep[-1].time)
            tracks[tid] = TrackHistory(np.array([e.time for e in rep]), np.array([e.state for e in rep]), rep[0].time, end)
    paths = TruthPaths.from_table(data.truth, SystemPlane(*data.reference))
    observed = {}
    for tg in set(data.plots.target) - {None}:
        t = data.plots.time[data.plots.target == tg]
        observed[tg] = (float(t.min()) + 20.0, float(t.max()))
    return track_metrics(tracks, paths, observed, np.arange(0.0, data.plots.time.max(), 2.0))


@pytest.mark.parametrize("angle,dz", [(30.0, 1000 * 0.3048), (90.0, 0.0)])
def test_crossing_pair_keeps_identities(angle, dz):
    """Primary-only crossing pair (30° at flight levels 1000 ft apart; 90° at the same level): two
    confirmed tracks, each following one aircraft from start to end, no deletion while plots arrive."""
    data = _scenario(_crossing(angle, dz))
    events = _run(data)
    confirmed = {e.track for e in events if e.kind == "confirmed"}
    m = _metrics(data, events)
    assert len(confirmed) == 2 and m["swaps"] == 0 and m["breaks"] == 0 and m["continuity_min"] > 0.99
    deleted = [e for e in events if e.kind == "deleted" and e.track in confirmed]
    assert not deleted or min(e.time for e in deleted) > data.plots.time.max() - 1.0


def test_track_kept_through_a_turn_while_plots_arrive():
    """A 3°/s turn of 90 s, primary-only: one confirmed track, never deleted before the plots end."""
    v = 200.0
    traj = KinematicTrajectory(0.0, -30e3, -20e3, 7000.0, math.radians(60), v,
                               [Leg(120.0), Leg.turn(90.0, 3.0, v), Leg(200.0)])
    data = _scenario([traj], duration=400.0)
    events = _run(data)
    confirmed = {e.track for e in events if e.kind == "confirmed"}
    assert len(confirmed) == 1
    assert all(e.time >= data.plots.time.max() for e in events if e.kind == "deleted" and e.track in confirmed)


def test_altitude_spread_is_the_conversion_derivative():
    """g = ∂z/∂h of the plane conversion at fixed (ρ, θ), against central finite differences of
    RadarFrame.to_plane (pyproj), near (20 km) and far (200 km) from the radar."""
    from radartracker.geometry.plane import RadarFrame
    from radartracker.tracking.association import altitude_spread

    plane = SystemPlane(48.85, 2.35)
    frame = RadarFrame(48.7, 2.3, 150.0, plane)
    rho = np.array([20e3, 80e3, 200e3])
    theta = np.radians([30.0, 200.0, 310.0])
    alt = np.full(3, 6000.0)
    z, _ = frame.to_plane(rho, theta, alt)
    C = frame.bias_jacobian(z, rho, alt)
    h = 1.0
    g = (frame.to_plane(rho, theta, alt + h)[0] - frame.to_plane(rho, theta, alt - h)[0]) / (2 * h)
    np.testing.assert_allclose(altitude_spread(C, rho, alt, 150.0, 1.0), g[:, :, None] * g[:, None, :], rtol=5e-3)  # sphere vs ellipsoid
    assert np.linalg.norm(g[0]) > 0.25 > 0.05 > np.linalg.norm(g[2])  # near the radar the altitude matters
