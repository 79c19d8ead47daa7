"""One pipeline, two associations: the same schema, every option honoured or refused, config.json
reproduces a run byte for byte, estimator instances get their radars and the run's q."""

from __future__ import annotations

import csv
import json

import attrs
import numpy as np
import pytest

from radartracker.cli import main
from radartracker.errors import ConfigurationError
from radartracker.estimation.base import EstimatorConfig
from radartracker.estimation.motion import MotionModel
from radartracker.io.scenario import write_scenario
from radartracker.pipeline.config import RunConfig
from radartracker.pipeline.run import run
from radartracker.pipeline.stream import scenario_stream
from radartracker.pipeline.writer import BIAS_COLUMNS, EVENT_COLUMNS, TRACK_COLUMNS
from radartracker.registry import load_estimator
from radartracker.simulation.scenarios import build_scenario


@pytest.fixture(scope="module")
def labelled():
    return build_scenario("demo", seed=2, duration=150.0).run()


@pytest.fixture(scope="module")
def unlabelled():
    return build_scenario("tracking", seed=5, duration=150.0).run()


@pytest.fixture(scope="module")
def folders(tmp_path_factory, labelled, unlabelled):
    root = tmp_path_factory.mktemp("scen")
    write_scenario(root / "labels", labelled)
    write_scenario(root / "manager", unlabelled)
    return {"labels": root / "labels", "manager": root / "manager"}


def _header(path):
    with path.open() as f:
        return next(csv.reader(f))


def _no_nan(text: str) -> dict:
    def refuse(name):
        raise AssertionError(f"non-JSON constant {name} in summary.json")
    return json.loads(text, parse_constant=refuse)


@pytest.mark.parametrize("association", ["labels", "manager"])
def test_q_changes_estimates_and_config_reproduces_the_run(tmp_path, folders, association):
    scen = str(folders[association])
    out = {q: tmp_path / f"q{q}" for q in ("5", "50")}
    for q, o in out.items():
        assert main(["--quiet", "replay", scen, "--out", str(o), "--q", q, "--estimator", "coupled"]) == 0
    for name in ("tracks.csv", "biases.csv"):
        assert (out["5"] / name).read_bytes() != (out["50"] / name).read_bytes()
    cfg = json.loads((out["50"] / "config.json").read_text())["settings"]
    assert cfg["q"] == 50.0 and cfg["association"] == association and cfg["estimator"] == "coupled"
    again = tmp_path / "again"
    assert main(["--quiet", "replay", scen, "--config", str(out["50"] / "config.json"), "--out", str(again)]) == 0
    for name in ("tracks.csv", "biases.csv", "events.csv", "config.json"):
        assert (again / name).read_bytes() == (out["50"] / name).read_bytes(), name
    # the schema, identical on both paths
    assert _header(again / "tracks.csv") == list(TRACK_COLUMNS)
    assert _header(again / "events.csv") == list(EVENT_COLUMNS)
    assert _header(again / "biases.csv") == list(BIAS_COLUMNS)
    summary = _no_nan((again / "summary.json").read_text())
    assert summary["reference"] and summary["association"] == association
    assert all(b["z_range"] is not None and b["error_range_m"] is not None for b in summary["biases"].values())
    with (again / "tracks.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert all(r["sd_x_m"] and r["sd_y_m"] for r in rows)  # covariances on both paths
    assert any(r["mode_s"] and r["altitude_m"] for r in rows)
    assert all(r["track"].isdigit() for r in rows)  # track ids: integers on both paths


def test_both_paths_give_the_same_summary_keys(tmp_path, folders):
    keys = []
    for assoc, scen in folders.items():
        o = tmp_path / assoc
        assert main(["--quiet", "replay", str(scen), "--out", str(o)]) == 0
        s = _no_nan((o / "summary.json").read_text())
        keys.append((set(s), set(s["truth"]), set(s["tracking"]), set(next(iter(s["biases"].values())))))
        assert s["estimator"] == "coupled-sparse"  # the default: the best installed exact estimator
    assert keys[0] == keys[1]


@pytest.mark.parametrize("association", ["--manager", "--association=labels"])
def test_motion_model_reaches_the_filters_on_both_associations(tmp_path, folders, association):
    """One tracker: the labelled association is the TrackManager with the labels associator, so a motion
    model and its options apply to it as to the manager's own association."""
    assert main(["--quiet", "replay", str(folders["labels"]), "--out", str(tmp_path / "m"), association,
                 "--motion-model", "imm", "--motion-option", "q_turn=20"]) == 0
    cfg = json.loads((tmp_path / "m" / "config.json").read_text())
    assert cfg["settings"]["motion_options"] == {"q_turn": "20"} and cfg["plugins"]["motion_model"]["q_turn"] == 20.0
    assert cfg["settings"]["associator"] == ("labels" if "labels" in association else "gnn")


@pytest.mark.parametrize("argv, option", [
    (["--q", "nan"], "--q"), (["--q", "-1"], "--q"), (["--q", "inf"], "--q"), (["--q", "x"], "--q"),
    (["--motion-option", "q=nan"], "q"), (["--motion-option", "nosuch=1"], "nosuch"),
    (["--estimator-option", "nosuch=1"], "nosuch"), (["--estimator", "nosuch"], "nosuch"),
])
def test_bad_options_name_themselves_before_any_work(tmp_path, folders, capsys, monkeypatch, argv, option):
    monkeypatch.setattr("radartracker.pipeline.run._by_manager", None)  # must fail before any computation
    assert main(["replay", str(folders["manager"]), "--out", str(tmp_path / "o"), *argv]) == 2
    err = capsys.readouterr().err
    assert option in err and "Traceback" not in err


def test_estimator_instance_gets_radars_and_the_runs_q(labelled):
    by_name = run(labelled, RunConfig(estimator="coupled"), progress=False)
    inst = load_estimator("coupled")(EstimatorConfig(motion=MotionModel(5.0)))
    by_inst = run(labelled, RunConfig(), estimator=inst, progress=False)
    np.testing.assert_array_equal(by_inst.tracks.state, by_name.tracks.state)
    assert by_inst.estimator_name == "coupled"
    with pytest.raises(ConfigurationError, match="q = 0.0 but the run uses q = 5.0"):
        run(labelled, RunConfig(), estimator=load_estimator("coupled")(), progress=False)


def test_consistency_warning_when_nis_is_far_off(labelled):
    result = run(labelled, RunConfig(estimator="decoupled"), progress=False)
    assert 0.5 * 2 < result.mean_nis < 2 * 2 and not any("NIS" in w for w in result.consistency()["warnings"])
    bad = attrs.evolve(result, mean_nis=result.mean_nis * 10)
    assert any("mean NIS" in w for w in bad.consistency()["warnings"])


def test_scenario_stream_is_time_ordered_and_complete(unlabelled):
    items = scenario_stream(unlabelled)
    assert len(items) == len(unlabelled.plots) + len(unlabelled.adsb)
    assert all(a.time <= b.time for a, b in zip(items, items[1:]))


def test_compare_help_states_the_real_default_q(capsys):
    with pytest.raises(SystemExit):
        main(["compare", "--help"])
    assert "default 5" in capsys.readouterr().out.replace("\n", " ")


@pytest.mark.parametrize("settings, match", [
    (dict(association="manager", screening={"gate_plots": -1}), "gate_plots"),
    (dict(association="labels", clock={"window": 0}), "window"),
    (dict(association="manager", manager={"screening": {}}), "unknown setting 'screening'"),
    (dict(association="manager", manager={"nosuch": 1}), "nosuch"),
    (dict(association="manager", manager={"confirm_m": 2.5}), "confirm_m"),
    (dict(association="labels", associator="gnn"), "--associator"),
    (dict(q=float("nan")), "--q"),
    (dict(association="sideways"), "association"),
])
def test_settings_of_the_wrong_kind_or_path_are_refused(unlabelled, settings, match):
    with pytest.raises(ConfigurationError, match=match):
        run(unlabelled, RunConfig(**settings), progress=False)


def test_a_failing_estimator_is_named_with_aircraft_and_time(labelled, monkeypatch):
    from radartracker.errors import PluginError

    est = load_estimator("decoupled")(EstimatorConfig(motion=MotionModel(5.0)))
    calls = []

    def update(m):
        calls.append(m)
        if len(calls) == 50:
            raise ValueError("boom")
        return type(est).update(est, m)

    monkeypatch.setattr(est, "update", update)
    with pytest.raises(PluginError, match=r"estimator 'decoupled' failed on track \d+ (\(Mode S \w+\) )?at t=[\d.]+ s: "
                                          r"ValueError: boom"):
        run(labelled, RunConfig(), estimator=est, progress=False)


@pytest.mark.parametrize("association", ["labels", "manager"])
def test_screening_settings_reach_both_paths(labelled, association):
    tight = run(labelled, RunConfig(association=association, screening={"gate_plots": 1.0}), progress=False)
    off = run(labelled, RunConfig(association=association, screening={"enabled": False, "gate_plots": 1.0}),
              progress=False)
    assert tight.counts.get("plots_outlier", 0) > 0 and off.counts.get("plots_outlier", 0) == 0
    assert tight.config.screening["gate_plots"] == 1.0 and off.config.screening["enabled"] is False


def test_the_collector_settings_of_a_run_are_given_back() -> None:
    """young_garbage raises the youngest generation's threshold and freezes the objects that existed before the
    block, only while it runs; objects a caller froze stay frozen."""
    import gc

    from radartracker.pipeline.run import GC_YOUNG_THRESHOLD, young_garbage

    before = gc.get_threshold()
    assert gc.get_freeze_count() == 0
    kept = [[] for _ in range(10)]  # containers that exist before the block
    with young_garbage():
        assert gc.get_threshold()[0] == max(GC_YOUNG_THRESHOLD, before[0])
        assert gc.get_freeze_count() >= len(kept)
    assert gc.get_threshold() == before and gc.get_freeze_count() == 0
    # a caller's frozen object stays frozen, judged on the object itself: the freeze count is shared with
    # other threads, and a frozen object another thread frees lowers it (2 of 840 000 did in a CI run)
    marker: list = []
    gc.freeze()
    try:
        with young_garbage():
            assert _frozen(marker)
        assert _frozen(marker)
    finally:
        gc.unfreeze()
    assert not _frozen(marker)


def _frozen(obj: object) -> bool:
    """Whether the tracked container ``obj`` is in the collector's permanent generation (``gc.freeze``):
    tracked, yet in none of the generations ``gc.get_objects`` lists."""
    import gc

    return gc.is_tracked(obj) and all(o is not obj for o in gc.get_objects())
