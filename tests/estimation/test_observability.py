"""Bias components the data do not inform are reported and used at their prior (issue 30,
radartracker.estimation.observability): the rule, the coupling graph's isolation, and a lone radar replayed."""

from __future__ import annotations

import math

import numpy as np

from radartracker.domain import BiasState
from radartracker.estimation.coupling import CouplingGraph
from radartracker.estimation.observability import UNOBSERVABLE_RATIO, held_at_prior
from radartracker.pipeline.config import RunConfig, resolve
from radartracker.pipeline.run import run
from radartracker.registry import load_estimator
from radartracker.simulation.scenarios import build_scenario
from radartracker.simulation.traffic import traffic_scenario

PRIOR = np.diag([500.0**2, math.radians(0.5) ** 2])


def _state(var_range: float, var_azimuth: float) -> BiasState:
    cov = np.array([[var_range, 0.3 * math.sqrt(var_range * var_azimuth)],
                    [0.3 * math.sqrt(var_range * var_azimuth), var_azimuth]])
    return BiasState("R1", 10.0, np.array([120.0, 0.002]), cov)


def test_an_isolated_radar_is_held_at_its_prior_whatever_its_variance():
    held = held_at_prior(_state(4.0, 1e-8), PRIOR, isolated=True)
    assert held.unobservable == ("range_offset", "azimuth_offset")
    np.testing.assert_array_equal(held.bias, [0.0, 0.0])
    np.testing.assert_array_equal(held.cov, PRIOR)
    assert (held.radar, held.time) == ("R1", 10.0)


def test_a_component_near_its_prior_variance_is_held_and_decorrelated_the_other_kept():
    near = UNOBSERVABLE_RATIO * PRIOR[0, 0] * 1.01
    state = _state(near, 1e-8)
    held = held_at_prior(state, PRIOR, isolated=False)
    assert held.unobservable == ("range_offset",)
    np.testing.assert_array_equal(held.bias, [0.0, 0.002])
    np.testing.assert_array_equal(held.cov, [[PRIOR[0, 0], 0.0], [0.0, 1e-8]])
    kept = _state(UNOBSERVABLE_RATIO * PRIOR[0, 0] * 0.99, 1e-8)
    assert held_at_prior(kept, PRIOR, isolated=False) is kept


def test_isolated_until_an_aircraft_is_shared_and_tied_after_it_is_removed():
    g = CouplingGraph(["R1", "R2", "R3"])
    assert g.isolated("R1")  # nothing seen yet
    g.observe("A", "R1", 0.0), g.observe("B", "R1", 0.0), g.observe("C", "R3", 0.0)
    assert g.isolated("R1") and g.isolated("R3")
    g.observe("A", "R2", 1.0)  # R1 and R2 share A
    g.observe("C", None, 1.0)  # R3's aircraft reports ADS-B
    assert not g.isolated("R1") and not g.isolated("R2") and not g.isolated("R3")
    g.remove_aircraft("A"), g.remove_aircraft("C")  # the links stay, as marginalised edges
    restored = CouplingGraph()
    restored.load_state_dict(g.state_dict())
    for graph in (g, restored):
        assert [graph.isolated(r) for r in ("R1", "R2", "R3")] == [False, False, False]
        assert {r: v["status"] for r, v in graph.report()["radars"].items()} == {
            "R1": "relative", "R2": "relative", "R3": "anchored"}


def _prior_only(data, config):
    """The run's coupled-sparse estimator, but never given a measurement: the tracks corrected with the prior alone."""
    cls = load_estimator("coupled-sparse")

    class PriorOnly(cls):
        def update_many(self, *args, **kwargs):
            return None

    return PriorOnly(resolve(config, data, "coupled-sparse").estimator_settings())


def test_a_lone_radar_without_adsb_stays_at_its_prior_and_says_so():
    """One radar, no ADS-B: its range offset is seen only through path curvature (before: 4,256 ± 475 m for a
    true −52 m, track RMSE 1,105 m). Reported unobservable, at 0 ± the prior σ, and the tracks are as good as
    with the prior alone (an estimator never given a measurement)."""
    data = traffic_scenario(seed=2, radars=1, adsb_share=0.0, duration=600.0, aircraft=30).run()
    config = RunConfig(estimator="coupled-sparse", association="manager")
    result = run(data, config, progress=False)
    prior_only = run(data, config, progress=False, estimator=_prior_only(data, config))
    b = result.final_biases["R00"]
    true_range, _ = data.truth_biases["R00"]
    assert b.unobservable == ("range_offset", "azimuth_offset")
    assert abs(b.range_m - true_range) <= math.sqrt(PRIOR[0, 0])
    np.testing.assert_allclose([b.sd_range_m, b.sd_azimuth_rad], np.sqrt(np.diag(PRIOR)))
    summary = result.summary()
    assert summary["biases"]["R00"]["unobservable"] == ["range_offset", "azimuth_offset"]
    assert summary["observability"]["radars"]["R00"]["status"] == "isolated"
    assert "unobservable, at the prior: range_offset, azimuth_offset" in result.summary_table()
    rmse = summary["tracking"]["position_rmse_m"]
    assert rmse <= prior_only.summary()["tracking"]["position_rmse_m"] * (1 + 1e-9)
    assert summary["tracking"]["breaks"] <= prior_only.summary()["tracking"]["breaks"]
    logged = result.biases  # biases.csv: as the tracks were corrected, at the prior throughout
    np.testing.assert_array_equal(logged.value[logged.radar == "R00"], 0.0)


def test_radars_that_share_aircraft_are_estimated_not_held():
    data = build_scenario("paris", seed=1, duration=200.0).run()
    result = run(data, RunConfig(estimator="coupled-sparse", association="manager"), progress=False)
    assert {r: b.unobservable for r, b in result.final_biases.items()} == {r.id: () for r in data.radars}
    assert all(v["unobservable"] == [] for v in result.summary()["biases"].values())
