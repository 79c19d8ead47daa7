"""Objects, closed-form integration, track weight and the RTS baseline of the reconstruction plugin.

Oracles: scipy.integrate.solve_ivp on the model's ODE, scipy.stats.multivariate_normal, scipy.special.huber,
filterpy's rts_smoother.
"""

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.special import huber
from scipy.stats import multivariate_normal

from radartracker.geometry.kinematics import propagate
from radartracker_plugins.reconstruction.integrate import geo_track, sample
from radartracker_plugins.reconstruction.objects import ControlSegment, ControlTrack, GeoPoint, PlotTrack
from radartracker_plugins.reconstruction.smoother import rts_smooth
from radartracker_plugins.reconstruction.weight import TrackWeight


def _ode(controls):
    """Right-hand side of seed eq. 2.1 with controls(t) -> (u, w)."""
    def f(t, s):
        x, y, phi, v = s
        u, w = controls(t)
        return [v * np.sin(phi), v * np.cos(phi), u / v, w]
    return f


@pytest.mark.parametrize("u,w", [(0.0, 0.0), (3.0, 0.0), (-2.5, 0.0), (0.0, 0.8), (2.0, -0.5), (-4.0, 1.5)])
def test_propagate_matches_fine_numerical_solution(u, w):
    tau = np.linspace(0, 120, 13)
    x, y, phi, v = propagate(1000.0, -500.0, 0.7, 180.0, u, w, tau)
    sol = solve_ivp(_ode(lambda t: (u, w)), (0, 120), [1000.0, -500.0, 0.7, 180.0], t_eval=tau,
                    rtol=1e-12, atol=1e-9, method="DOP853")
    np.testing.assert_allclose(np.column_stack([x, y, phi, v]), sol.y.T, atol=1e-5)


def _track():
    segs = [ControlSegment(0.0, 0.0, 0, 60), ControlSegment(3.0, 0.2, 60, 150), ControlSegment(-2.0, -0.4, 150, 240)]
    return ControlTrack(GeoPoint(0, 0.0, 0.0, 1.0, 150.0), segs)


def test_piecewise_integration_matches_solve_ivp():
    ct = _track()
    t = np.linspace(0, 240, 97)
    controls = lambda tt: (ct[int(ct.segment_index(tt))].u, ct[int(ct.segment_index(tt))].w)  # noqa: E731
    y0 = [0.0, 0.0, 1.0, 150.0]
    # integrate segment by segment so the solver never steps across a discontinuity
    ref = []
    for s in ct:
        sel = (t >= s.t_start) & ((t < s.t_end) | (s is ct[-1]))
        sol = solve_ivp(_ode(controls), (s.t_start, s.t_end), y0, rtol=1e-12, atol=1e-9, method="DOP853",
                        dense_output=True)
        ref.append(sol.sol(t[sel]).T)
        y0 = sol.y[:, -1]
    np.testing.assert_allclose(sample(ct, t), np.vstack(ref), atol=1e-4)


def test_geo_track_links_segments_and_points():
    ct = _track()
    g = geo_track(ct, 2.0, height=lambda tt: 1000 + tt)
    assert len(g) == 121 and g.time[-1] == pytest.approx(240.0)
    assert g.control[0].geo_span is not None
    for k, seg in enumerate(g.control):
        pts = g.segment_points(k)
        assert all(seg.t_start <= p.t < seg.t_end or (k == len(ct) - 1 and p.t == seg.t_end) for p in pts)
        assert np.all(g.segment[seg.geo_span] == k)
    assert sum(len(g.segment_points(k)) for k in range(len(ct))) == len(g)
    assert g[10].h == pytest.approx(1020.0) and g[10].t == pytest.approx(20.0)
    prev, nxt = g.control.neighbours(1)
    assert prev.t_end == g.control[1].t_start and nxt.t_start == g.control[1].t_end
    assert g.control.neighbours(0)[0] is None


@pytest.mark.parametrize("bad", [
    lambda: ControlTrack(GeoPoint(0, 0, 0, 0, 100), []),
    lambda: ControlTrack(GeoPoint(0, 0, 0, 0, 100), [ControlSegment(0, 0, 0, 10), ControlSegment(0, 0, 11, 20)]),
    lambda: ControlTrack(GeoPoint(5, 0, 0, 0, 100), [ControlSegment(0, 0, 0, 10)]),
    lambda: ControlSegment(0, 0, 10, 10),
    lambda: ControlSegment(float("nan"), 0, 0, 10),
    lambda: GeoPoint(0, 0, 0, 0, -1.0),
])
def test_control_track_validates_itself(bad):
    with pytest.raises(ValueError):
        bad()


def _plots(n=40, seed=0):
    rng = np.random.default_rng(seed)
    t = np.sort(rng.uniform(0, 200, n))
    A = rng.normal(0, 60, (n, 2, 2))
    R = A @ np.swapaxes(A, 1, 2) + np.eye(2) * 100
    C = rng.normal(0, 1, (n, 2, 2))
    z = rng.normal(0, 300, (n, 2))
    radar = np.array(["a", "b"] * (n // 2), dtype=object)
    return PlotTrack("k", t, z, np.full(n, np.nan), radar, R, C)


def test_plot_track_validates_itself():
    pt = _plots()
    with pytest.raises(ValueError, match="R"):
        PlotTrack("k", pt.t, pt.z, pt.h, pt.radar, -pt.R, pt.C)
    with pytest.raises(ValueError, match="t"):
        PlotTrack("k", pt.t[::-1], pt.z, pt.h, pt.radar, pt.R, pt.C)
    assert pt[3]["radar"] == "b" and pt[3]["t"] == pt.t[3]


def test_gaussian_weight_is_the_negative_log_likelihood():
    pt = _plots()
    p = np.random.default_rng(1).normal(0, 200, (len(pt), 2))
    nll = -sum(multivariate_normal(p[i], pt.R[i]).logpdf(pt.z[i]) for i in range(len(pt)))
    assert TrackWeight(pt)(p) == pytest.approx(nll, rel=1e-10)
    assert TrackWeight(pt).subset(slice(0, 10))(p[:10]) == pytest.approx(
        -sum(multivariate_normal(p[i], pt.R[i]).logpdf(pt.z[i]) for i in range(10)), rel=1e-10)


def test_robust_losses_and_bias_correction():
    pt = _plots()
    p = np.random.default_rng(2).normal(0, 200, (len(pt), 2))
    w = TrackWeight(pt, "huber", c=1.5)
    d = np.sqrt(TrackWeight(pt).distances2(p))
    assert w(p) - w.const == pytest.approx(huber(1.5, d).sum(), rel=1e-12)
    wc = TrackWeight(pt, "cauchy", c=2.0)
    assert wc(p) - wc.const == pytest.approx(np.sum(2.0 * np.log(1 + d**2 / 4.0)), rel=1e-12)
    # plots shifted by a known bias: with the bias given, the weight equals the unbiased one
    bias = {"a": np.array([80.0, 0.002]), "b": np.array([-40.0, -0.001])}
    zb = pt.z + np.einsum("nij,nj->ni", pt.C, np.array([bias[r] for r in pt.radar]))
    biased = PlotTrack("k", pt.t, zb, pt.h, pt.radar, pt.R, pt.C)
    assert TrackWeight(biased, biases=bias)(p) == pytest.approx(TrackWeight(pt)(p), rel=1e-10)
    assert TrackWeight(biased)(p) != pytest.approx(TrackWeight(pt)(p), rel=1e-3)


def test_rts_matches_filterpy():
    from filterpy.kalman import KalmanFilter, rts_smoother

    from radartracker.estimation.motion import MotionModel

    pt = _plots(60, seed=3)
    q = 0.5
    xs, Ps, _ = rts_smooth(pt.t, pt.z, pt.R, q)
    kf = KalmanFilter(dim_x=4, dim_z=2)
    kf.x = np.array([pt.z[0, 0], pt.z[0, 1], 0, 0.0])
    kf.P = np.zeros((4, 4))
    kf.P[:2, :2] = pt.R[0] * 1e6
    kf.P[2:, 2:] = np.eye(2) * 300.0**2
    kf.H = np.hstack([np.eye(2), np.zeros((2, 2))])
    Fs, Qs = zip(*[MotionModel(q).transition(dt) for dt in np.diff(pt.t, prepend=pt.t[0])])
    mu, cov, _, _ = kf.batch_filter(pt.z, Fs=list(Fs), Qs=list(Qs), Rs=list(pt.R))
    # filterpy's smoother takes the transition from k to k + 1 at index k
    Fn, Qn = zip(*[MotionModel(q).transition(dt) for dt in np.append(np.diff(pt.t), 0.0)])
    ref, Pref, _, _ = rts_smoother(mu, cov, list(Fn), list(Qn))
    np.testing.assert_allclose(xs, ref, rtol=1e-7, atol=1e-6)
    np.testing.assert_allclose(Ps, Pref, rtol=1e-6, atol=1e-6)
