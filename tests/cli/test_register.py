"""``radartracker register`` (issue 30): the bias components of a labelled scenario beside their bound."""

from __future__ import annotations

import json

import pytest

from radartracker.cli import main


@pytest.fixture(scope="module")
def scenario(tmp_path_factory):
    path = tmp_path_factory.mktemp("reg") / "scen"
    assert main(["--quiet", "simulate", str(path), "--scenario", "demo", "--duration", "300",
                 "--sensor-error", "R1:range_gain=3e-4,time_offset_s=0.1"]) == 0
    return path


def test_register_prints_and_writes_every_component_beside_its_bound(scenario, tmp_path, capsys):
    assert main(["register", str(scenario), "--json", str(tmp_path / "r.json")]) == 0
    out = capsys.readouterr().out
    assert out.count("\n") == 14 and "time_offset" in out and "position RMSE" in out
    rows = json.loads((tmp_path / "r.json").read_text())["components"]
    assert [(r["radar"], r["component"]) for r in rows[:4]] == [
        ("R1", "range_offset"), ("R1", "azimuth_offset"), ("R1", "range_gain"), ("R1", "time_offset")]
    truth = {"range_offset": 120.0, "range_gain": 3e-4, "time_offset": 0.1}
    for r in rows[:4]:
        assert r["status"] == "observable" and r["sd"] == pytest.approx(r["crlb_sd"], rel=0.02)
        if r["component"] in truth:
            assert r["truth"] == pytest.approx(truth[r["component"]]) and abs(r["z"]) < 3.0


def test_register_with_the_two_offsets_only(scenario, capsys):
    assert main(["register", str(scenario), "--components", "none", "--q", "1"]) == 0
    out = capsys.readouterr().out
    assert "range_gain" not in out and out.count("range_offset") == 3


@pytest.mark.parametrize("argv, words", [(["--components", "gain"], "--components: unknown 'gain'"),
                                         (["--range-gain-sd", "0"], "--range-gain-sd: 0.0 must be > 0.0"),
                                         (["--q", "-1"], "--q: -1.0 must be >= 0.0")])
def test_register_refuses_bad_options_in_one_line(scenario, capsys, argv, words):
    assert main(["register", str(scenario), *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and words in err[0]


def test_register_needs_labelled_plots(scenario, tmp_path, capsys):
    import shutil

    copy = tmp_path / "unlabelled"
    shutil.copytree(scenario, copy)
    lines = (copy / "plots.csv").read_text().splitlines()
    header = lines[0].split(",")
    k = header.index("target")
    (copy / "plots.csv").write_text("\n".join(",".join(f for i, f in enumerate(line.split(",")) if i != k)
                                              for line in lines) + "\n")
    assert main(["register", str(copy)]) == 2
    assert "register needs every plot labelled" in capsys.readouterr().err
