"""Hypotheses, constrained fitting and end-to-end recovery of known controls.

Oracles: brute-force enumeration of segmentations; the weight of the true trajectory (the optimiser
must do at least as well); the true controls and switch times of simulated flights; the tuned RTS
smoother on the same plots.
"""

import itertools

import numpy as np
import pytest

from radartracker.geometry.plane import SystemPlane
from radartracker.simulation.simulator import KinematicTrajectory, Leg
from radartracker_plugins.reconstruction import MultiHypothesisReconstructor, ReconstructionConfig
from radartracker_plugins.reconstruction.fit import ControlObjective, fit_hypothesis
from radartracker_plugins.reconstruction.hypotheses import segmentations
from radartracker_plugins.reconstruction.integrate import sample
from radartracker_plugins.reconstruction.objects import ControlSegment, ControlTrack, GeoPoint
from radartracker_plugins.reconstruction.sim import REFERENCE, radars_around, simulate_flight
from radartracker_plugins.reconstruction.smoother import tuned_rts
from radartracker_plugins.reconstruction.weight import TrackWeight


def _brute(sig, K, m):
    N = len(sig)
    best = (np.inf, None)
    for cuts in itertools.combinations(range(1, N), K - 1):
        b = (0, *cuts, N)
        if any(b[i + 1] - b[i] < m for i in range(K)):
            continue
        sse = sum(((sig[b[i]:b[i + 1]] - sig[b[i]:b[i + 1]].mean(0)) ** 2).sum() for i in range(K))
        if sse < best[0]:
            best = (sse, cuts)
    return best


def test_segmentation_dp_equals_brute_force():
    rng = np.random.default_rng(4)
    sig = np.repeat(rng.normal(0, 2, (4, 2)), [5, 3, 6, 4], axis=0) + rng.normal(0, 0.5, (18, 2))
    sse, starts = segmentations(sig, 2, 5)
    for K in range(1, 6):
        ref_sse, ref_cuts = _brute(sig, K, 2)
        assert sse[K - 1] == pytest.approx(ref_sse, rel=1e-9)
        assert tuple(starts[K - 1]) == (ref_cuts or ())


LEGS = [Leg(150.0), Leg(60.0, u=3.0), Leg(120.0, w=0.6), Leg(90.0, u=-2.0, w=-0.3), Leg(180.0)]
SWITCHES = np.cumsum([leg.duration for leg in LEGS])[:-1]


@pytest.fixture(scope="module")
def flight():
    plane = SystemPlane(*REFERENCE)
    traj = KinematicTrajectory(0.0, -20e3, 10e3, 6000.0, 1.2, 170.0, LEGS)
    radars = radars_around(plane, [(-60, -40), (50, 60)], [4.0, 6.0])
    return simulate_flight(traj, radars, seed=7)


@pytest.fixture(scope="module")
def rec(flight):
    return MultiHypothesisReconstructor().reconstruct(flight[0])


def test_recovers_known_controls_and_switch_times(rec):
    ct = rec.control
    assert len(ct) == len(LEGS)
    np.testing.assert_allclose(ct.switch_times, SWITCHES, atol=6.0)
    np.testing.assert_allclose(ct.u, [leg.u for leg in LEGS], atol=0.2)
    np.testing.assert_allclose(ct.w, [leg.w for leg in LEGS], atol=0.05)
    # ranked alternatives are kept with their weights and scores
    assert len(rec.hypotheses) >= 3 and all(a.score <= b.score for a, b in zip(rec.hypotheses, rec.hypotheses[1:]))


def test_beats_truth_weight_and_the_smoother(flight, rec):
    pt, truth = flight
    w = TrackWeight(pt)
    est = sample(rec.control, pt.t)[:, :2]
    assert rec.best.weight <= w(truth) + 1e-6  # the optimum explains the plots at least as well as the truth
    rmse = np.sqrt(np.mean(np.sum((est - truth) ** 2, axis=1)))
    xs, _ = tuned_rts(pt.t, pt.z, pt.R)
    rts = np.sqrt(np.mean(np.sum((xs[:, :2] - truth) ** 2, axis=1)))
    raw = np.sqrt(np.mean(np.sum((pt.z - truth) ** 2, axis=1)))
    assert rmse < 0.6 * rts < raw


def test_infeasible_start_slides_back_into_the_constraints(flight):
    pt, _ = flight
    cfg = ReconstructionConfig()
    t = pt.t - pt.t[0]
    start = GeoPoint(0.0, *pt.z[0], 1.2, 170.0)
    bad = ControlTrack(start, [ControlSegment(7.0, 3.0, 0, 300), ControlSegment(-9.0, -3.5, 300, t[-1])])
    obj = ControlObjective(TrackWeight(pt), t, 0.0, t[-1], 2, cfg)
    theta = obj.pack((start.x, start.y, start.phi, start.v), bad.u, bad.w, np.array([0, 300, t[-1]]))
    assert obj(theta) > obj(np.clip(theta, *obj.bounds())) + cfg.penalty
    fitted, _, _ = fit_hypothesis(bad, t, TrackWeight(pt), cfg)
    assert np.all(np.abs(fitted.u) <= cfg.max_u) and np.all(np.abs(fitted.w) <= cfg.max_w)
    assert np.all(np.diff([s.t_start for s in fitted] + [fitted.t_end]) >= cfg.dt_min - 1e-9)


def test_robust_loss_resists_outliers(flight):
    pt, truth = flight
    rng = np.random.default_rng(1)
    z = pt.z.copy()
    bad = rng.choice(len(z), len(z) // 20, replace=False)
    z[bad] += rng.choice([-1, 1], (len(bad), 2)) * 3000.0
    import attrs

    dirty = attrs.evolve(pt, z=z)
    err = {}
    for loss in ("gauss", "huber"):
        r = MultiHypothesisReconstructor(ReconstructionConfig(loss=loss, hypotheses=1)).reconstruct(dirty)
        err[loss] = np.sqrt(np.mean(np.sum((sample(r.control, pt.t)[:, :2] - truth) ** 2, axis=1)))
    assert err["huber"] < 0.5 * err["gauss"]


def test_chain_rule_jacobian_matches_finite_differences(flight):
    from scipy.optimize._numdiff import approx_derivative

    pt, _ = flight
    t = pt.t - pt.t[0]
    cfg = ReconstructionConfig()
    ct = ControlTrack(GeoPoint(0.0, *pt.z[0], 1.1, 165.0),
                      [ControlSegment(0.3, 0.1, 0, 140), ControlSegment(2.5, -0.2, 140, 230),
                       ControlSegment(-1.0, 0.5, 230, 400), ControlSegment(0.0, -0.1, 400, t[-1])])
    obj = ControlObjective(TrackWeight(pt), t, 0.0, t[-1], len(ct), cfg)
    theta = obj.pack((ct.initial.x, ct.initial.y, ct.initial.phi, ct.initial.v), ct.u, ct.w,
                     np.array([s.t_start for s in ct] + [t[-1]]))
    num = approx_derivative(obj.residuals, theta, method="3-point")
    np.testing.assert_allclose(obj.jacobian(theta), num, rtol=1e-5, atol=1e-6 * np.abs(num).max())


def test_split_keeps_the_track_and_halves_the_worst_segment(flight):
    from radartracker_plugins.reconstruction.hypotheses import split

    pt, _ = flight
    t = pt.t - pt.t[0]
    ct = ControlTrack(GeoPoint(0.0, *pt.z[0], 1.2, 170.0), [ControlSegment(0.0, 0.0, 0, 300), ControlSegment(0.0, 0.0, 300, t[-1])])
    child = split(ct, 3, TrackWeight(pt), t, 10.0)
    assert len(child) == 3
    np.testing.assert_allclose(sample(child, t), sample(ct, t), atol=1e-6)
    # the segment with the larger Mahalanobis excess Σd² − 2n (computed here from scratch) is halved
    w = TrackWeight(pt)
    d2 = w.distances2(sample(ct, t)[:, :2])
    excess = [d2[t < 300].sum() - 2 * (t < 300).sum(), d2[t >= 300].sum() - 2 * (t >= 300).sum()]
    expected = [150.0, 300.0] if excess[0] > excess[1] else [300.0, 300.0 + (t[-1] - 300.0) / 2]
    np.testing.assert_allclose(child.switch_times, expected)


def test_multiple_shooting_jacobian_and_round_trip(flight):
    from scipy.optimize._numdiff import approx_derivative

    from radartracker_plugins.reconstruction.shooting import MultipleShooting

    pt, _ = flight
    t = pt.t - pt.t[0]
    obj = ControlObjective(TrackWeight(pt), t, 0.0, t[-1], 3, ReconstructionConfig())
    theta = obj.pack((pt.z[0, 0], pt.z[0, 1], 1.1, 165.0), np.array([0.3, 2.5, -1.0]), np.array([0.1, -0.2, 0.3]),
                     np.array([0.0, 150.0, 300.0, t[-1]]))
    ms = MultipleShooting(obj)
    phi = ms.from_single(theta)
    np.testing.assert_allclose(ms.to_single(phi), theta)
    r = ms.residuals(phi)
    # a chained start has no continuity gaps, and the plot residuals are the single-shooting ones
    np.testing.assert_allclose(r[2 * len(t):], 0.0, atol=1e-6)
    np.testing.assert_allclose(r[:2 * len(t)], obj.residuals(theta)[:2 * len(t)], atol=1e-8)  # (the jump prior's rows follow)
    phi[4:8] += [30.0, -20.0, 0.01, 2.0]  # open a gap at the second segment's start
    num = approx_derivative(ms.residuals, phi, method="3-point")
    np.testing.assert_allclose(ms.jacobian(phi), num, rtol=1e-5, atol=1e-6 * np.abs(num).max())


def _random_flight(rng):
    legs = [Leg(float(rng.uniform(80, 200)))]
    for i in range(int(rng.integers(2, 4))):
        legs.append(Leg(float(rng.uniform(40, 120)), u=float(rng.uniform(1.5, 3.5) * rng.choice([-1, 1]))))
        legs.append(Leg(float(rng.uniform(80, 200)), w=float(rng.choice([0.0, rng.uniform(-0.6, 0.6)]))))
    return KinematicTrajectory(0.0, rng.uniform(-20e3, 20e3), rng.uniform(-20e3, 20e3), 5000.0,
                               rng.uniform(0, 2 * np.pi), float(rng.uniform(130, 220)), legs)


def _monte_carlo(n, seed):
    rng = np.random.default_rng(seed)
    plane = SystemPlane(*REFERENCE)
    for i in range(n):
        traj = _random_flight(rng)
        pt, truth = simulate_flight(traj, radars_around(plane, [(-60, -40), (50, 60)], rng.uniform(4, 12, 2)), seed=i)
        rec = MultiHypothesisReconstructor().reconstruct(pt)
        rmse = np.sqrt(np.mean(np.sum((sample(rec.control, pt.t)[:, :2] - truth) ** 2, axis=1)))
        xs, _ = tuned_rts(pt.t, pt.z, pt.R)
        rts = np.sqrt(np.mean(np.sum((xs[:, :2] - truth) ** 2, axis=1)))
        assert rmse < rts, (i, rmse, rts)
        assert rec.best.weight <= TrackWeight(pt)(truth) + 1e-6
        if len(rec.control) == len(traj.legs):
            true_sw = np.cumsum([leg.duration for leg in traj.legs])[:-1]
            np.testing.assert_allclose(rec.control.switch_times, true_sw, atol=8.0)


def test_monte_carlo_recovery_short():
    _monte_carlo(1, seed=11)


@pytest.mark.slow
def test_monte_carlo_recovery():
    _monte_carlo(10, seed=12)


def test_jump_prior_jacobian_and_weight(flight):
    from scipy.optimize._numdiff import approx_derivative

    from radartracker_plugins.reconstruction.fit import jump_prior

    pt, _ = flight
    t = pt.t - pt.t[0]
    cfg = ReconstructionConfig(jump_sd=0.5)
    ct = ControlTrack(GeoPoint(0.0, *pt.z[0], 1.1, 165.0),
                      [ControlSegment(0.3, 0.1, 0, 140), ControlSegment(2.5, -0.2, 140, 230), ControlSegment(-1.0, 0.5, 230, t[-1])])
    obj = ControlObjective(TrackWeight(pt), t, 0.0, t[-1], len(ct), cfg)
    theta = obj.pack((ct.initial.x, ct.initial.y, ct.initial.phi, ct.initial.v), ct.u, ct.w,
                     np.array([s.t_start for s in ct] + [t[-1]]))
    num = approx_derivative(obj.residuals, theta, method="3-point")
    np.testing.assert_allclose(obj.jacobian(theta), num, rtol=1e-5, atol=1e-6 * np.abs(num).max())
    # the objective is the plots' NLL plus ½ Σ (jump / sd)², computed here from the controls
    jumps = np.concatenate([np.diff(ct.u), np.diff(ct.w)])
    plain = ControlObjective(TrackWeight(pt), t, 0.0, t[-1], len(ct), ReconstructionConfig())
    assert obj(theta) == pytest.approx(plain(theta) + 0.5 * np.sum((jumps / 0.5) ** 2), rel=1e-12)
    assert jump_prior(ct, cfg) == pytest.approx(0.5 * np.sum((jumps / 0.5) ** 2))
