"""Innovation screening (issue 12 §1): gross errors are rejected, counted, and pull no bias."""

import math

import attrs
import numpy as np
import pytest
from scipy import stats
from scipy.spatial.distance import mahalanobis

from radartracker.registry import make_manager, restore_manager
from radartracker.domain import AdsbReport, Plot
from radartracker.estimation import screening
from radartracker.estimation.screening import (ACCEPT, REINIT, REJECT, AdsbPlausibility, ScreeningConfig,
                                               bias_corrected, extend_run, judge, normalised_innovation,
                                               position_d2, speed_consistent)
from radartracker.pipeline.config import RunConfig
from radartracker.pipeline.run import run
from radartracker.simulation.scenarios import _icao, build_scenario
from radartracker.tracking.config import ManagerConfig

ESTIMATOR = "coupled-sparse"  # consistent covariances: the decoupled filter's σ is too small for a 3σ test


def test_normalised_innovation_is_the_mahalanobis_distance_and_chi2_distributed():
    rng = np.random.default_rng(1)
    C = np.array([[0.6, -40e3], [0.8, 30e3]])
    R = np.array([[900.0, 120.0], [120.0, 2500.0]])
    Pb = np.diag([25.0, 1e-8])
    Pp = np.array([[400.0, -50.0], [-50.0, 300.0]])
    bias, pos = np.array([50.0, 1e-3]), np.array([1e4, -2e4])
    S = Pp + C @ Pb @ C.T + R
    z = pos + C @ bias + rng.multivariate_normal(np.zeros(2), S, 4000)
    d2 = np.array([normalised_innovation(zi, C, R, bias, Pb, pos, Pp) for zi in z])
    ref = np.array([mahalanobis(zi, pos + C @ bias, np.linalg.inv(S)) ** 2 for zi in z[:50]])
    np.testing.assert_allclose(d2[:50], ref, rtol=1e-9)
    assert stats.kstest(d2, stats.chi2(2).cdf).pvalue > 1e-3
    assert normalised_innovation(np.array([np.nan, 0.0]), C, R, bias, Pb, pos, Pp) == math.inf
    assert normalised_innovation(z[0], C, -R, bias, Pb, pos, -Pp) == math.inf


def test_bias_correction_equals_the_numpy_products():
    rng = np.random.default_rng(2)
    for _ in range(20):
        C, Pb = rng.normal(size=(2, 2)) * [1.0, 3e4], rng.normal(size=(2, 2))
        Pb, R = Pb @ Pb.T * [[25.0, 1e-3], [1e-3, 1e-7]], np.diag(rng.uniform(100, 3000, 2))
        z, bias = rng.normal(size=2) * 1e5, rng.normal(size=2) * [50.0, 1e-3]
        zc, Rc = bias_corrected(z, C, R, bias, Pb)
        np.testing.assert_allclose(zc, z - C @ bias, rtol=1e-14, atol=1e-9)
        np.testing.assert_allclose(Rc, R + C @ Pb @ C.T, rtol=1e-13)


def test_position_d2_is_the_unbiased_case_bit_for_bit():
    """position_d2 (a corrected position) equals normalised_innovation with C = 0 exactly, non-PD included."""
    rng = np.random.default_rng(3)
    zero2, zero22 = np.zeros(2), np.zeros((2, 2))
    for k in range(200):
        A, B = rng.normal(size=(2, 2)), rng.normal(size=(2, 2))
        R, P = A @ A.T * 900.0, B @ B.T * 400.0
        if k % 10 == 0:  # not positive definite, zero or with signed zeros
            R, P = (-R, P) if k % 20 else (np.array([[0.0, -0.0], [-0.0, 0.0]]), np.zeros((2, 2)))
        z, pos = rng.normal(size=2) * 1e4, rng.normal(size=2) * 1e4
        want = normalised_innovation(z, zero22, R, zero2, zero22, pos, P)
        assert position_d2(z, R, pos, P) == want
        assert want == math.inf or want == pytest.approx(float((z - pos) @ np.linalg.solve(P + R, z - pos)), rel=1e-9)


def test_gate_by_kind_and_tentative():
    cfg = ScreeningConfig(gate_plots=1.0, gate_adsb=2.0, gate_positions=3.0, gate_tentative=4.0)
    assert [cfg.gate(k) for k in ("plots", "adsb", "positions")] == [1.0, 2.0, 3.0]
    assert {cfg.gate(k, True) for k in ("plots", "adsb", "positions")} == {4.0}
    with pytest.raises(KeyError):
        cfg.gate("bearings")


def test_judge_reinitialises_after_a_run_of_consistent_rejections():
    cfg = ScreeningConfig(gate_plots=10.0, gate_tentative=5.0, reinit_after=3)
    R = np.eye(2) * 100.0

    def at(t, x=None):  # an aircraft flying east at 250 m/s, or a position x
        return t, np.array([250.0 * t if x is None else x, 0.0]), R

    assert judge(cfg, "plots", 9.9, [], True, False, *at(0.0)) == (ACCEPT, [])
    assert judge(cfg, "plots", 9.9, [], True, True, *at(0.0))[0] == REJECT  # a tentative track's tighter gate
    run, verdicts = [], []
    for t in (0.0, 4.0, 8.0):  # consistent rejections: the track is wrong
        verdict, run = judge(cfg, "plots", 50.0, run, True, False, *at(t))
        verdicts.append(verdict)
    assert verdicts == [REJECT, REJECT, REINIT] and run == []
    # an unidentified track is never re-initialised
    run = []
    for t in (0.0, 4.0, 8.0):
        verdict, run = judge(cfg, "plots", 50.0, run, False, False, *at(t))
    assert verdict == REJECT and len(run) == 3  # kept at reinit_after entries
    # scattered gross errors between good measurements: a 20 km jump restarts the run
    run = extend_run(cfg, extend_run(cfg, [], *at(0.0)), *at(4.0))
    assert len(extend_run(cfg, run, *at(8.0, 2000.0 + 20e3))) == 1
    verdict, after = judge(cfg, "plots", 50.0, run, True, False, *at(8.0, 2000.0 + 20e3))
    assert verdict == REJECT and len(after) == 1
    assert len(extend_run(ScreeningConfig(reinit_after=1), run, *at(8.0))) == 1
    # the σ of the consistency test is the largest axis of R (closed form vs numpy)
    Ra = np.array([[900.0, 300.0], [300.0, 100.0]])
    assert extend_run(cfg, [], 0.0, np.zeros(2), Ra)[0][2] == pytest.approx(math.sqrt(np.linalg.eigvalsh(Ra)[-1]))


def test_adsb_plausibility():
    cfg = ScreeningConfig(adsb_min_nacp=5, adsb_max_speed_mps=600.0, reinit_after=3)
    chk = AdsbPlausibility(cfg)
    assert chk.check("abc123", 0.0, np.zeros(2), 40.0, 4) == "adsb_low_nacp"
    assert chk.check("abc123", 0.0, np.zeros(2), 40.0, 8) is None
    assert chk.check("abc123", 1.0, np.array([250.0, 0.0]), 40.0, 8) is None
    # a single 1° jump costs only itself: the next report is judged against the last accepted one
    assert chk.check("abc123", 2.0, np.array([500.0, 111e3]), 40.0, 8) == "adsb_implausible_speed"
    assert chk.check("abc123", 3.0, np.array([750.0, 0.0]), 40.0, 8) is None
    # a wild first report: the reference moves to the truth after reinit_after reports in a row
    assert chk.check("def456", 0.0, np.array([0.0, 111e3]), 40.0, 8) is None
    got = [chk.check("def456", t, np.array([250.0 * t, 0.0]), 40.0, 8) for t in (1.0, 2.0, 3.0, 4.0)]
    assert got == ["adsb_implausible_speed", "adsb_implausible_speed", None, None]
    assert speed_consistent(cfg, 10.0, np.zeros(2), 30.0, np.array([6000.0, 0.0]), 30.0)
    assert not speed_consistent(cfg, 10.0, np.zeros(2), 30.0, np.array([6500.0, 0.0]), 30.0)


def test_speed_consistent_decides_as_numpy_hypot_at_the_limit():
    """The scalar test decides as ‖b − a‖ by numpy.hypot ≤ allowance, also a ulp either side of the limit
    (math.hypot and the C library's hypot differ in the last bit for ~0.1 % of inputs)."""
    rng = np.random.default_rng(8)
    cfg = ScreeningConfig(adsb_max_speed_mps=600.0, speed_sigmas=5.0)
    sd = 30.0
    for _ in range(3000):
        a, b = rng.normal(size=2) * 1e5, rng.normal(size=2) * 1e5
        d = float(np.hypot(*(b - a)))
        for limit in (d, np.nextafter(d, 0.0), np.nextafter(d, np.inf), d * (1 + 1e-12), d * 0.9):
            dt = (limit - cfg.speed_sigmas * math.hypot(sd, sd)) / cfg.adsb_max_speed_mps
            allowance = cfg.adsb_max_speed_mps * abs(dt) + cfg.speed_sigmas * math.hypot(sd, sd)
            want = bool(np.hypot(*(b - a)) <= allowance)
            assert speed_consistent(cfg, dt, a, sd, b, sd) == want
            assert speed_consistent(cfg, dt, tuple(a), sd, tuple(b), sd) == want


def _items(data):
    p, a = data.plots, data.adsb
    items = [Plot(float(p.time[i]), p.radar[i], float(p.range_m[i]), float(p.azimuth_rad[i]),
                  None if math.isnan(p.altitude_m[i]) else float(p.altitude_m[i]), p.mode_s[i], p.mode_3a[i])
             for i in range(len(p))]
    items += [AdsbReport(float(a.time[i]), a.icao24[i], float(a.lat[i]), float(a.lon[i]),
                         None if math.isnan(a.altitude_m[i]) else float(a.altitude_m[i]), int(a.nacp[i]))
              for i in range(len(a))]
    return sorted(items, key=lambda x: (x.time, isinstance(x, AdsbReport)))


@pytest.fixture(scope="module")
def demo():
    data = build_scenario("demo", seed=3, duration=360.0).run()
    items = _items(data)

    def nearest(cls, code, t, radar=None):
        cand = [i for i, x in enumerate(items) if isinstance(x, cls) and (x.mode_s if cls is Plot else x.icao24) == code
                and (radar is None or x.radar == radar)]
        return min(cand, key=lambda i: abs(items[i].time - t))

    bad = {
        nearest(Plot, _icao(0), 180.0, "R1"): lambda x: attrs.evolve(x, range_m=x.range_m + 20_000.0),
        nearest(AdsbReport, _icao(1), 120.0): lambda x: attrs.evolve(x, lat=-x.lat, lon=x.lon - 180.0),
        nearest(AdsbReport, _icao(0), 240.0): lambda x: attrs.evolve(x, lat=x.lat + 1.0),
    }
    faulty = [bad[i](x) if i in bad else x for i, x in enumerate(items)]
    without = [x for i, x in enumerate(items) if i not in bad]
    return data, faulty, without


def _run(data, items, **config):
    mgr = make_manager(data.radars, data.reference, ManagerConfig(estimator=ESTIMATOR, **config))
    mgr.process_many(items)
    return mgr


def _swapped_address(items: list, code: str) -> list:
    """``items`` with a wrong first plot under Mode S ``code``: another aircraft's plot of the same radar,
    just before that aircraft's own first plot (its track starts in the wrong place)."""
    first = next(i for i, x in enumerate(items) if isinstance(x, Plot) and x.mode_s == code)
    donor = next(x for x in items[first:] if isinstance(x, Plot) and x.mode_s not in (code, None)
                 and x.radar == items[first].radar)
    return items[:first] + [attrs.evolve(donor, time=items[first].time - 0.01, mode_s=code)] + items[first:]


def test_gross_errors_rejected_biases_within_3_sigma(demo):
    """One antipodal ADS-B report, one 1° ADS-B shift, one +20 km Mode S plot: each counted, and the
    estimator ends exactly where the run without those three measurements ends (the oracle)."""
    data, faulty, without = demo
    mgr, ref = _run(data, faulty), _run(data, without)
    counts = mgr.accounting()
    assert counts["plots_outlier"] == 1
    assert counts["adsb_implausible_speed"] == 2
    assert counts["plots_used"] == ref.accounting()["plots_used"]
    assert counts["adsb_used"] == ref.accounting()["adsb_used"]
    for rid, (true_r, true_a) in data.truth_biases.items():
        b, b_ref = mgr.estimator.bias(rid), ref.estimator.bias(rid)
        np.testing.assert_array_equal(b.bias, b_ref.bias)
        np.testing.assert_array_equal(b.cov, b_ref.cov)
        assert abs(b.bias[0] - true_r) < 3 * math.sqrt(b.cov[0, 0])
        assert abs(b.bias[1] - true_a) < 3 * math.sqrt(b.cov[1, 1])


def test_without_screening_the_same_errors_ruin_the_biases(demo):
    """The test above can fail: unscreened, the same three measurements move a bias far out of 3σ."""
    data, faulty, _ = demo
    mgr = _run(data, faulty, screening=ScreeningConfig(enabled=False))
    z = [abs(mgr.estimator.bias(rid).bias[k] - data.truth_biases[rid][k]) / math.sqrt(mgr.estimator.bias(rid).cov[k, k])
         for rid in data.truth_biases for k in (0, 1)]
    assert max(z) > 10.0


def test_swapped_address_at_start_does_not_lock_out_the_truth(demo):
    """A wrong first plot under an aircraft's Mode S address (another aircraft's position) starts its
    track in the wrong place; the aircraft's own plots are rejected a few times, then the track is
    re-initialised on them and the aircraft is tracked and used for the biases."""
    data, _, without = demo
    code = _icao(2)
    mgr = _run(data, _swapped_address(without, code))
    assert mgr.track_counts()["tracks_reinitialised"] >= 1
    live = [t for t in mgr.tracks.values() if t.mode_s == code]
    assert len(live) == 1 and live[0].status in ("confirmed", "coasting") and live[0].n_plots > 20


def _tables(data, plot_fix=None, adsb_fix=None, drop=()):
    """A copy of ``data`` with plot/ADS-B columns changed in place of rows, or rows dropped."""
    plots, adsb = data.plots, data.adsb
    if plot_fix:
        rng = plots.range_m.copy()
        for i, dr in plot_fix.items():
            rng[i] += dr
        plots = attrs.evolve(plots, range_m=rng)
    if adsb_fix:
        lat, lon = adsb.lat.copy(), adsb.lon.copy()
        for i, (la, lo) in adsb_fix.items():
            lat[i], lon[i] = la, lo
        adsb = attrs.evolve(adsb, lat=lat, lon=lon)
    for kind, idx in drop:
        keep = np.setdiff1d(np.arange(len(plots if kind == "plot" else adsb)), idx)
        if kind == "plot":
            plots = plots.take(keep)
        else:
            adsb = attrs.evolve(adsb, **{f.name: getattr(adsb, f.name)[keep] for f in attrs.fields(type(adsb))})
    return attrs.evolve(data, plots=plots, adsb=adsb)


def _nearest(times, mask, t):
    idx = np.flatnonzero(mask)
    return int(idx[np.argmin(np.abs(times[idx] - t))])


def test_labelled_path_screens_the_same_gross_errors(demo):
    """The labelled replay (truth labels) with the same three gross errors ends exactly where it ends
    without them, within 3σ of the true biases."""
    data = demo[0]
    p, a = data.plots, data.adsb
    ip = _nearest(p.time, (p.mode_s == _icao(0)) & (p.radar == "R1"), 180.0)
    ia1, ia0 = _nearest(a.time, a.icao24 == _icao(1), 120.0), _nearest(a.time, a.icao24 == _icao(0), 240.0)
    faulty = _tables(data, {ip: 20_000.0},
                     {ia1: (-a.lat[ia1], a.lon[ia1] - 180.0), ia0: (a.lat[ia0] + 1.0, a.lon[ia0])})
    without = _tables(data, drop=[("plot", [ip]), ("adsb", [ia1, ia0])])
    cfg = RunConfig(association="labels", estimator=ESTIMATOR)
    res, ref = run(faulty, cfg, progress=False), run(without, cfg, progress=False)
    assert res.counts["plots_outlier"] == 1 and res.counts["adsb_implausible_speed"] == 2
    for rid, (true_r, true_a) in data.truth_biases.items():
        b = res.final_biases[rid]
        np.testing.assert_array_equal(b.bias, ref.final_biases[rid].bias)
        assert abs(b.bias[0] - true_r) < 3 * math.sqrt(b.cov[0, 0])
        assert abs(b.bias[1] - true_a) < 3 * math.sqrt(b.cov[1, 1])


def test_labelled_path_wild_first_measurement(demo):
    """A +20 km first plot of an aircraft: absorbed by the diffuse prior, the aircraft is started again
    after its good plots disagree, and the biases stay within 3σ."""
    data = demo[0]
    p = data.plots
    first = int(np.flatnonzero(p.target == _icao(3))[0])
    res = run(_tables(data, {first: 20_000.0}), RunConfig(association="labels", estimator=ESTIMATOR), progress=False)
    assert res.track_counts["tracks_reinitialised"] == 1
    for rid, (true_r, true_a) in data.truth_biases.items():
        b = res.final_biases[rid]
        assert abs(b.bias[0] - true_r) < 3 * math.sqrt(b.cov[0, 0])
        assert abs(b.bias[1] - true_a) < 3 * math.sqrt(b.cov[1, 1])


def test_unbiased_position_screened(demo):
    """A triangulated fix (PlaneMeasurement without radar) 20 km off its Mode S-identified aircraft is
    counted as ``positions_outlier`` and changes no bias; a good one is used."""
    from radartracker.estimation.base import PlaneMeasurement
    from radartracker.geometry.plane import SystemPlane

    data, _, without = demo
    without = [x for x in without if x.time < 240.0]
    plane = SystemPlane(*data.reference)
    rep = next(x for x in without if isinstance(x, AdsbReport) and x.icao24 == _icao(0) and x.time > 200.0)
    xy = np.array([float(v) for v in plane.to_plane(rep.lat, rep.lon)])
    k = without.index(rep)

    def fix(dx):
        return PlaneMeasurement(rep.time + 0.5, _icao(0), None, xy + [dx, 0.0], np.zeros((2, 2)),
                                np.eye(2) * 100.0**2)

    bad = _run(data, without[:k] + [fix(20_000.0)] + without[k:])
    good = _run(data, without[:k] + [fix(0.0)] + without[k:])
    ref = _run(data, without)
    assert bad.accounting()["positions_outlier"] == 1 and "positions_outlier" not in good.accounting()
    assert good.accounting()["positions_used"] == 1
    for rid in data.truth_biases:
        np.testing.assert_array_equal(bad.estimator.bias(rid).bias, ref.estimator.bias(rid).bias)


def test_adsb_plausibility_state_round_trip():
    cfg = ScreeningConfig()
    a, b = AdsbPlausibility(cfg), AdsbPlausibility(cfg)
    for t in range(5):
        a.check("abc123", float(t), np.array([250.0 * t, 0.0]), 40.0, 8)
    a.check("abc123", 5.0, np.array([0.0, 111e3]), 40.0, 8)  # a failure in progress is state too
    b.load_state_dict(a.state_dict())
    probe = [(6.0, np.array([0.0, 111e3 + 250.0])), (7.0, np.array([0.0, 111e3 + 500.0])),
             (8.0, np.array([2000.0, 0.0]))]
    got_a = [a.check("abc123", t, xy, 40.0, 8) for t, xy in probe]
    assert got_a == [b.check("abc123", t, xy, 40.0, 8) for t, xy in probe]
    assert got_a == ["adsb_implausible_speed", None, "adsb_implausible_speed"]  # 3 agreeing failures move it


def _adsb_batches(rng, cfg, reference, n_batches, codes, step_s):
    """Batches of ADS-B reports (code, time, xy, sd, nacp) of ``codes``, with addresses repeated within a
    batch, low NACp, wild jumps, NaN, and first reports of an address placed within 10⁻¹⁵ or a few ulp
    either side of its speed limit from ``reference``'s state at the batch start."""
    t = 0.0
    for _ in range(n_batches):
        last, batch = reference.state_dict()["last"], []
        for _ in range(int(rng.integers(0, 40))):
            t += float(rng.uniform(0.0, step_s))
            code = codes[int(rng.integers(len(codes)))]
            sd = float(rng.uniform(5.0, 60.0))
            xy = np.array([250.0 * t, 1000.0 * codes.index(code)]) + rng.normal(0.0, 20.0, 2)
            u = rng.uniform()
            if code in last and all(c != code for c, *_ in batch) and u < 0.4:  # at the limit
                t0, (x0, y0), sd0 = last[code]
                allowance = cfg.adsb_max_speed_mps * abs(t - t0) + cfg.speed_sigmas * math.hypot(sd0, sd)
                d = allowance * (1.0 + float(rng.choice([-1e-13, -1e-15, 0.0, 1e-15, 1e-13])))
                d = float(np.nextafter(d, rng.choice([0.0, np.inf]))) if rng.uniform() < 0.3 else d
                a = rng.uniform(0.0, 2.0 * math.pi)
                xy = np.array([x0 + d * math.cos(a), y0 + d * math.sin(a)])
            elif u < 0.5:
                xy = xy + [0.0, 111e3]  # a wild report, or a wild run
            elif u < 0.52:
                xy[int(rng.integers(2))] = np.nan
            batch.append((code, t, xy, sd, int(rng.choice([8, 8, 8, 4]))))
        yield batch


def test_snapshot_mid_rejection_run_continues_exactly(demo, tmp_path):
    """A snapshot taken while a track holds a run of rejected measurements (and the ADS-B check its
    references) restores them: the continued run equals the uninterrupted one."""
    data, faulty, _ = demo
    items = [x for x in _swapped_address(faulty, _icao(2)) if x.time < 240.0]
    whole = _run(data, items)
    mgr = make_manager(data.radars, data.reference, ManagerConfig(estimator=ESTIMATOR))
    k = 0
    while not any(t.rejected for t in mgr.tracks.values()):
        mgr.process(items[k])
        k += 1
    mgr.snapshot(tmp_path / "snap")
    restored = restore_manager(tmp_path / "snap")
    assert [t.rejected[0][0] for t in restored.tracks.values() if t.rejected] == \
        [t.rejected[0][0] for t in mgr.tracks.values() if t.rejected]
    restored.process_many(items[k:])
    assert restored.accounting() == whole.accounting()
    assert restored.track_counts()["tracks_reinitialised"] >= 1
    assert restored.track_counts() == whole.track_counts()
    for rid in data.truth_biases:
        np.testing.assert_array_equal(restored.estimator.bias(rid).bias, whole.estimator.bias(rid).bias)


def test_a_reinitialised_track_keeps_the_inputs_accounted(demo):
    """Every input is counted once under one reason, re-initialisations included: they are events of a
    track, reported apart (``TrackManager.track_counts``), not a reason an input was used or refused."""
    data, _, without = demo
    items = _swapped_address(without, _icao(2))
    mgr = _run(data, items)
    assert mgr.track_counts()["tracks_reinitialised"] >= 1
    assert sum(mgr.accounting().values()) == len(items) and "tracks_reinitialised" not in mgr.accounting()
