"""The assessment against known truth: a simulated scenario with known biases, noise, Pd and false plots,
and planted wrong codes, split plots and disordered time stamps; every figure's 95 % interval must hold
the true value (the Monte Carlo version, over many seeds: test_montecarlo.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import binom

from radartracker.assessment import stats
from radartracker.assessment.assess import AssessmentConfig, assess
from radartracker.simulation.faults import Faults, known_figures, plant
from radartracker.assessment.profile import Criterion, load_profile
from radartracker.assessment.reference import ReferenceConfig
from radartracker.simulation.scenarios import build_scenario

FAULTS = Faults(wrong_mode_3a=0.03, wrong_mode_c=0.02, wrong_mode_s=0.03, split=0.02, out_of_order=0.01,
                reflection=0.02)


@pytest.fixture(scope="module")
def planted():
    sim = build_scenario("tracking", seed=4, duration=600.0)
    data = plant(sim.run(), FAULTS, seed=4)
    return sim, data, assess(data, load_profile(), progress=False)


def test_every_figure_holds_the_truth_in_its_interval(planted):
    """Each radar's figures with a known true value: every 95 % interval holds it, but for the few that one run
    misses by chance. Of m independent 95 % intervals, Binomial(m, 0.05) miss; more misses than its 99.5 %
    quantile (5 of 32) fail the test. One figure off every time is the Monte Carlo test's to catch
    (test_montecarlo.py: each figure's coverage over 40 runs)."""
    sim, data, a = planted
    truth = known_figures(sim.radars, data.truth_biases, FAULTS)
    assert a.reference == "truth"
    misses = {}
    for r in a.radars:
        assert set(truth[r.radar]) <= set(r.figures)
        misses |= {(r.radar, k): (v, r.figures[k]) for k, v in truth[r.radar].items() if not r.figures[k].contains(v)}
    m = sum(len(t) for t in truth.values())
    assert len(misses) <= binom.ppf(0.995, m, 1 - stats.LEVEL), f"true values outside the 95 % interval: {misses}"


def test_faults_are_seen(planted):
    """The planted faults move the figures away from a clean radar's (the intervals are not merely wide)."""
    _, _, a = planted
    for r in a.radars:
        assert r.figures["mode_3a_correctness"].high < 1.0 or r.figures["mode_c_correctness"].high < 1.0
        assert r.figures["split_plot_share"].low > 0.0
        assert r.figures["out_of_order_share"].low > 0.0
        assert r.figures["reflection_share"].low > 0.0
        assert 0.8 < r.figures["pd"].value < 0.97
        assert r.figures["range_sigma_m"].high - r.figures["range_sigma_m"].low < 15.0


def test_system_tracks_use_the_pipeline_indicators(planted):
    _, _, a = planted
    s = a.system
    assert 0.0 < s["position_rmse_m"].value < 500.0
    assert 0.5 < s["probability_of_update"].value <= 1.0
    assert s["false_tracks"].value >= 0


def test_adsb_reference_without_truth(demo_data):
    """Without truth.csv and without the reconstruction (``--no-reconstruct``) the ADS-B aircraft are the reference: biases and Pd still recovered, false plots not
    assessable (the aircraft without ADS-B are not in the reference)."""
    import attrs

    data = attrs.evolve(demo_data, truth=None)
    a = assess(data, load_profile(), AssessmentConfig(reference=ReferenceConfig(reconstruct=False)), progress=False)
    assert a.reference == "adsb"
    for r in a.radars:
        tr, ta = demo_data.truth_biases[r.radar]
        for name, true in (("range_bias_vs_reference_m", tr), ("azimuth_bias_vs_reference_deg", math.degrees(ta))):
            e = r.figures[name]  # within 3σ (the interval is ±1.96σ): few plots against two ADS-B aircraft
            assert abs(e.value - true) <= 3.0 * (e.high - e.low) / (2 * 1.96), (r.radar, name, e, true)
        assert r.figures["pd"].n > 0 and r.figures["pd"].value > 0.97
        assert "false_plots_per_scan" in r.not_assessable and "false_plots_per_scan" not in r.figures
    assert "false_tracks" not in a.system


@pytest.mark.parametrize("k, n", [(0, 40), (3, 200), (57, 60), (450, 500), (30, 100)])
def test_proportion_intervals_by_their_definitions(k, n):
    """Wilson's bounds from its formula; Clopper–Pearson's as the p whose binomial tails at k are α/2."""
    e = stats.proportion(k, n)
    if e.method == "wilson":
        z, p = 1.959963984540054, k / n
        centre = (p + z * z / (2 * n)) / (1 + z * z / n)
        half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
        assert (e.low, e.high) == pytest.approx((centre - half, centre + half), abs=1e-12)
    else:
        assert e.method == "clopper-pearson"
        assert e.low == 0.0 if k == 0 else binom.sf(k - 1, n, e.low) == pytest.approx(0.025, abs=1e-9)
        assert e.high == 1.0 if k == n else binom.cdf(k, n, e.high) == pytest.approx(0.025, abs=1e-9)


def test_sigma_rate_and_mean_intervals():
    rng = np.random.default_rng(2)
    x = rng.normal(3.0, 2.0, 400)
    s = stats.sigma(x)
    assert s.low < np.std(x, ddof=1) < s.high and s.contains(2.0)
    assert stats.mean(x).contains(3.0)
    r = stats.rate(0, 10)
    assert r.low == 0.0 and r.high == pytest.approx(-math.log(0.025) / 10, rel=1e-9)  # exact Poisson at 0 events


@pytest.mark.parametrize("rule, low, high, verdict", [
    ("below", 1.0, 2.0, "pass"), ("below", 4.0, 5.0, "fail"), ("below", 2.0, 4.0, "inconclusive"),
    ("abs_below", -2.0, 1.0, "pass"), ("abs_below", -5.0, -4.0, "fail"), ("above", 4.0, 5.0, "pass"),
    ("above", 1.0, 2.0, "fail"), ("above", 2.5, 3.5, "inconclusive")])
def test_verdict_is_decided_by_the_interval(rule, low, high, verdict):
    c = Criterion("range_bias_m", rule, 3.0, "any", "a standard")
    assert c.judge(stats.Estimate((low + high) / 2, low, high, 10, "t")) == verdict


def test_codes_by_majority_without_an_aircraft_list(planted):
    """Without the scenario's aircraft list each aircraft's Mode 3/A code is the one most of its plots carry:
    the planted 3 % of wrong codes are still found wrong."""
    import attrs

    _, data, a = planted
    b = assess(attrs.evolve(data, aircraft=[]), load_profile(), progress=False)
    for ra, rb in zip(a.radars, b.radars):
        assert rb.figures["mode_3a_correctness"] == ra.figures["mode_3a_correctness"]
