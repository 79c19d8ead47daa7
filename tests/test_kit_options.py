"""Typed plugin options from KEY=VALUE strings (registry), and the TrackManager built from plugin objects."""

import math

import attrs
import numpy as np
import pytest

from radartracker.registry import make_manager
from radartracker.cli import main
from radartracker.errors import ConfigurationError, PluginError
from radartracker.pipeline.stream import scenario_stream
from radartracker.registry import (CallableFilterFactory, FilterFactory, describe_options, make_estimator,
                                   make_filter_factory, parse_key_values, parse_options, plugin_listing)
from radartracker.simulation.scenarios import build_scenario
from radartracker.tracking.config import ManagerConfig
from radartracker_plugins.decoupled import DecoupledEstimator
from radartracker_plugins.motion import AdaptiveConfig, CVConfig, CVFilter, IMMConfig, IMMFilter


@attrs.frozen
class Opts:
    rate: float = 1.0
    count: int = 3
    flag: bool = False
    label: str = "x"
    limit: float | None = None
    taus: tuple[float, ...] = (1.0, 2.0)
    matrix: tuple[tuple[float, ...], ...] | None = None


def test_parse_options_reads_every_supported_type():
    o = parse_options("plugin 'p'", Opts, {"rate": "2.5", "count": "7", "flag": "yes", "label": "a=b",
                                            "limit": "none", "taus": "3, 4,5", "matrix": "0.9,0.1; 0.2,0.8"})
    assert o == Opts(2.5, 7, True, "a=b", None, (3.0, 4.0, 5.0), ((0.9, 0.1), (0.2, 0.8)))
    assert parse_options("p", Opts, {"limit": "4"}).limit == 4.0
    assert parse_options("p", Opts, None) == Opts()
    assert parse_options("p", Opts, {"count": "1"}, base=Opts(rate=9.0)) == Opts(rate=9.0, count=1)


@pytest.mark.parametrize("options, message", [
    ({"rat": "1"}, "plugin 'p': unknown option 'rat'; valid options: count, flag, label, limit, matrix, rate, taus"),
    ({"count": "1.5"}, "plugin 'p': option count='1.5'"),
    ({"flag": "maybe"}, "plugin 'p': option flag='maybe': expected true or false"),
    ({"rate": "fast"}, "plugin 'p': option rate='fast'"),
    ({"rate": "inf"}, "plugin 'p': option rate='inf': 'inf' is not finite"),
    ({"taus": "1,nan"}, "plugin 'p': option taus='1,nan': 'nan' is not finite"),
])
def test_parse_options_errors_name_plugin_key_and_valid_keys(options, message):
    with pytest.raises(ConfigurationError, match=message.replace("(", r"\(").replace(")", r"\)")) as err:
        parse_options("plugin 'p'", Opts, options)
    assert "valid options" in str(err.value)


def test_parse_key_values():
    assert parse_key_values(["a=1", "b = x=y", "a=2"]) == {"a": "2", "b": "x=y"}
    with pytest.raises(ConfigurationError, match="'novalue': expected KEY=VALUE"):
        parse_key_values(["novalue"])


def test_motion_options_become_the_models_typed_config():
    f = make_filter_factory("imm", {"q": "2", "sojourn_s": "100,20", "turn_rate_sd": str(math.radians(1.0))})
    assert isinstance(f, FilterFactory) and f.name == "imm" and f.cls is IMMFilter
    assert f.config == IMMConfig(q=2.0, sojourn_s=(100.0, 20.0), turn_rate_sd=math.radians(1.0))
    filt = f()
    assert isinstance(filt, IMMFilter) and filt.config is f.config
    assert make_filter_factory("adaptive", {"allow_negative_beta": "true"}).config == AdaptiveConfig(allow_negative_beta=True)
    # options apply on top of a given config; a config of another model is refused
    assert make_filter_factory("cv", {"max_gap_s": "60"}, CVConfig(q=3.0)).config == CVConfig(q=3.0, max_gap_s=60.0)
    with pytest.raises(ConfigurationError, match="takes a CVConfig, not a IMMConfig"):
        make_filter_factory("cv", None, IMMConfig())
    with pytest.raises(ConfigurationError, match="motion model 'cv': unknown option 'q_turn'; valid options: max_gap_s, "
                                                 "prior_sd_velocity_mps, q"):
        make_filter_factory("cv", {"q_turn": "1"})
    with pytest.raises(ConfigurationError, match="motion model 'imm'.*'transition'"):
        make_filter_factory("imm", {"transition": "0.5,0.6;0.5,0.5"})
    with pytest.raises(ConfigurationError, match="unknown motion model 'ca'; installed: adaptive, cv, fading, imm"):
        make_filter_factory("ca")


def test_filter_factory_from_a_class_or_a_callable():
    assert make_filter_factory(CVFilter, {"q": "4"}).config == CVConfig(q=4.0)
    made = make_filter_factory(lambda: CVFilter(CVConfig(q=7.0)))
    assert isinstance(made, CallableFilterFactory) and made().config.q == 7.0
    assert make_filter_factory(made) is made
    with pytest.raises(ConfigurationError, match="options and config apply to a plugin name or class"):
        make_filter_factory(lambda: CVFilter(), {"q": "1"})
    with pytest.raises(ConfigurationError, match="returned int, not a TrackFilter"):
        make_filter_factory(lambda: 3)()


def test_make_estimator_with_an_instance_adds_only_missing_radars():
    est = DecoupledEstimator()
    est.add_radar("R1")
    assert make_estimator(est, None, ["R1", "R2", "R2"]) is est and est.radars == ["R1", "R2"]


def test_listing_and_description(capsys):
    assert main(["estimators"]) == 0
    text = capsys.readouterr().out
    assert text.strip() == plugin_listing()
    for line in ("estimators:", "motion models:", "reconstructors:", "  imm ", "options: prior_sd_velocity_mps=300",
                 "q_turn=1", "fixed_lambda=none"):
        assert line in text
    assert "refresh_every=256" in text
    assert ("q", "float", 1.0) in describe_options(CVConfig)


@pytest.fixture(scope="module")
def tiny():
    data = build_scenario("demo", seed=4, duration=90.0).run()
    return data, scenario_stream(data)


def test_manager_takes_an_estimator_instance_and_a_filter_factory(tiny):
    data, items = tiny
    made = []

    def factory():
        made.append(CVFilter(CVConfig(q=3.0, prior_sd_velocity_mps=250.0)))
        return made[-1]

    config = ManagerConfig(estimator="coupled")
    est = make_estimator("decoupled", config.estimator_config, [])
    mgr = make_manager(data.radars, data.reference, config, estimator=est, filter_factory=factory)
    mgr.process_many(items)
    assert mgr.estimator is est and sorted(est.radars) == sorted(r.id for r in data.radars)
    assert mgr.confirmed_tracks() and all(any(t.filter is f for f in made) for t in mgr.tracks.values())
    # the same run by names and options gives the same biases
    by_name = make_manager(data.radars, data.reference,
                           attrs.evolve(config, estimator="decoupled", motion_model="cv",
                                        motion_options={"q": "3", "prior_sd_velocity_mps": "250"}))
    by_name.process_many(items)
    for rid, b in mgr.biases().items():
        np.testing.assert_array_equal(b.bias, by_name.biases()[rid].bias)
        np.testing.assert_array_equal(b.cov, by_name.biases()[rid].cov)


def test_a_plugin_raising_during_a_run_is_named(tiny):
    data, items = tiny

    class Broken(DecoupledEstimator):
        name = "broken"

        def update(self, m):
            if m.time > 40.0:
                raise TypeError("kaboom")
            return super().update(m)

    mgr = make_manager(data.radars, data.reference, ManagerConfig(), estimator=Broken())
    with pytest.raises(PluginError, match=r"estimator 'broken' failed on track \d+ .*at t=4\d\.\d+ s: TypeError: kaboom"):
        mgr.process_many(items)

    class BrokenFilter(CVFilter):
        def update(self, time, z, R):
            raise KeyError("inside the filter")

    mgr = make_manager(data.radars, data.reference, ManagerConfig(), filter_factory=BrokenFilter)
    with pytest.raises(PluginError, match="motion model 'cv' failed on track .* KeyError"):
        mgr.process_many(items)


def test_manager_filters_share_the_estimators_process_noise_by_default(tiny):
    """ManagerConfig.motion None: the model's defaults, with q from estimator_config unless set."""
    data, items = tiny
    for model, options, q in (("cv", {}, 5.0), ("imm", {}, 5.0), ("cv", {"q": "2"}, 2.0)):
        config = ManagerConfig(motion_model=model, motion_options=options)
        mgr = make_manager(data.radars, data.reference, config)
        mgr.process_many(items[:200])
        assert mgr.tracks and all(t.filter.config.q == q for t in mgr.tracks.values())
    assert ManagerConfig().estimator_config.motion.q == 5.0
    mgr = make_manager(data.radars, data.reference, ManagerConfig(motion_model="adaptive"))  # no q setting
    mgr.process_many(items[:200])
    assert mgr.tracks and all(t.filter.config == AdaptiveConfig() for t in mgr.tracks.values())
