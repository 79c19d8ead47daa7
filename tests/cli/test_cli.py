"""The command line end to end: simulate, replay (with figures), estimators, demo, bad input."""

import csv
import json

import pytest

from radartracker.cli import _parser, main
from radartracker.pipeline.writer import TRACK_COLUMNS


def test_simulate_then_replay(tmp_path, capsys):
    scen, out = tmp_path / "scen", tmp_path / "out"
    assert main(["simulate", str(scen), "--scenario", "demo", "--duration", "300"]) == 0
    assert {p.name for p in scen.iterdir()} >= {"radars.csv", "plots.csv", "adsb.csv", "truth.csv", "truth_biases.csv"}
    assert main(["replay", str(scen), "--estimator", "decoupled", "--out", str(out), "--plots"]) == 0
    with (out / "biases.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert list(rows[0]) == ["time", "radar", "range_bias_m", "azimuth_bias_deg", "sd_range_m", "sd_azimuth_deg"]
    with (out / "tracks.csv").open() as f:
        header = next(csv.reader(f))
    assert header == list(TRACK_COLUMNS)
    summary = json.loads((out / "summary.json").read_text())
    assert set(summary["biases"]) == {"R1", "R2", "R3"} and summary["truth"]["estimates_compared"] > 0
    assert (out / "biases.png").stat().st_size > 10_000
    assert main(["simulate", str(scen)]) == 2  # existing folder: an error, no traceback
    assert "already exists" in capsys.readouterr().err


def test_replay_bad_input_message_and_skip(tmp_path, capsys):
    scen = tmp_path / "scen"
    main(["simulate", str(scen), "--scenario", "seed", "--duration", "200"])
    lines = (scen / "plots.csv").read_text().splitlines()
    fields = lines[3].split(",")
    fields[2] = "NaN"
    lines[3] = ",".join(fields)
    (scen / "plots.csv").write_text("\n".join(lines) + "\n")
    assert main(["replay", str(scen), "--out", str(tmp_path / "o")]) == 2
    assert "plots.csv line 4, field 'range_m': 'NaN' is not finite" in capsys.readouterr().err
    assert not (tmp_path / "o").exists() or not any((tmp_path / "o").iterdir())  # nothing half-written
    assert main(["replay", str(scen), "--out", str(tmp_path / "o"), "--skip-bad"]) == 0
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert summary["skipped_input_rows"] == {"plots.csv:malformed": 1}


def test_estimators_and_demo(capsys):
    assert main(["estimators"]) == 0
    assert "decoupled" in capsys.readouterr().out
    assert main(["demo", "--estimator", "decoupled"]) == 0
    out = capsys.readouterr().out
    assert "R1" in out and "position RMSE" in out


def test_estimators_shows_the_q_a_run_uses(capsys):
    """Issue 32: the listing showed the motion models' q = 1 while runs use the estimator's q (5): it shows
    the run's q (read from a run's effective settings, not from the listing's code)."""
    from radartracker.pipeline.config import RunConfig, motion_factory, resolve

    cfg = resolve(RunConfig(association="manager", estimator="coupled-sparse"), None, "coupled-sparse")
    q = motion_factory(cfg).config.q
    assert main(["estimators"]) == 0
    imm = next(line for line in capsys.readouterr().out.splitlines() if "turn_rate_sd" in line)
    assert f"q={q:g} (the run's q unless set)" in imm and q == 5.0


def test_replay_without_truth_labels_uses_the_track_manager(tmp_path):
    scen, out = tmp_path / "scen", tmp_path / "out"
    assert main(["simulate", str(scen), "--scenario", "tracking", "--duration", "240"]) == 0
    assert main(["replay", str(scen), "--estimator", "coupled", "--out", str(out), "--plots"]) == 0
    with (out / "events.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert {r["event"] for r in rows} >= {"created", "confirmed", "updated"}
    summary = json.loads((out / "summary.json").read_text())
    assert summary["association"] == "manager" and summary["tracking"]["false_tracks"] == 0
    assert (out / "tracks.png").stat().st_size > 10_000 and (out / "coupling.graphml").exists()


@pytest.mark.parametrize("argv, option", [
    (["--duration", "inf"], "--duration"), (["--duration", "nan"], "--duration"), (["--duration", "-5"], "--duration"),
    (["--scenario", "traffic", "--adsb-share", "2"], "--adsb-share"), (["--scenario", "traffic", "--radars", "0"], "--radars"),
    (["--seed", "-1"], "--seed"),
])
def test_simulate_numeric_options_are_validated(tmp_path, capsys, argv, option):
    assert main(["simulate", str(tmp_path / "s"), *argv]) == 2
    assert option in capsys.readouterr().err and not (tmp_path / "s").exists()


def test_estimator_option_reaches_the_plugin_on_both_paths(tmp_path):
    scen = tmp_path / "scen"
    assert main(["simulate", str(scen), "--scenario", "demo", "--duration", "120"]) == 0
    for assoc in ("labels", "manager"):
        out = tmp_path / assoc
        assert main(["--quiet", "replay", str(scen), "--out", str(out), "--association", assoc,
                     "--estimator", "coupled-sparse", "--estimator-option", "refresh_every=7"]) == 0
        cfg = json.loads((out / "config.json").read_text())
        assert cfg["settings"]["estimator_options"] == {"refresh_every": "7"}
        assert cfg["plugins"]["estimator"]["refresh_every"] == 7
    assert main(["replay", str(scen), "--out", str(tmp_path / "bad"), "--estimator", "coupled-sparse",
                 "--estimator-option", "refresh_every=-1"]) == 2


@pytest.fixture()
def fresh_parser():
    """main() keeps its parser per state of the path, each command's function bound when it was built: a
    test that replaces a command's function has it built anew, and leaves no parser holding the replacement."""
    _parser.cache_clear()
    yield
    _parser.cache_clear()


def test_quiet_silences_progress_and_library_logs_then_restores(monkeypatch, fresh_parser):
    import logging
    import os

    seen = {}

    def fake(args):
        seen["env"] = os.environ.get("TQDM_DISABLE"), os.environ.get("DASK_LOGGING__DISTRIBUTED")
        seen["dask"] = logging.getLogger("distributed").getEffectiveLevel()
        return 0

    monkeypatch.delenv("TQDM_DISABLE", raising=False)
    monkeypatch.setattr("radartracker.cli._cmd_estimators", fake)
    assert main(["--quiet", "estimators"]) == 0
    assert seen == {"env": ("1", "error"), "dask": logging.ERROR}
    assert "TQDM_DISABLE" not in os.environ


def test_quiet_before_the_command_reaches_commands_with_their_own_quiet(monkeypatch, fresh_parser):
    seen = []
    monkeypatch.setattr("radartracker.cli._cmd_estimators", lambda args: seen.append(args.quiet) or 0)
    assert main(["--quiet", "estimators"]) == 0 and main(["estimators"]) == 0
    assert seen == [True, False]


def test_demo_refuses_a_negative_seed(capsys):
    assert main(["demo", "--seed", "-3"]) == 2 and "--seed" in capsys.readouterr().err
