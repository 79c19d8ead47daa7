"""A run that fails leaves no empty output folder of its own making, and an earlier run's folder as it was."""

import pytest

from radartracker.cli import main


@pytest.fixture(scope="module")
def scenarios(tmp_path_factory):
    """A good scenario folder and the same with a plot whose range is not a number."""
    d = tmp_path_factory.mktemp("failed_run")
    assert main(["--quiet", "simulate", str(d / "good"), "--scenario", "seed", "--duration", "60"]) == 0
    assert main(["--quiet", "simulate", str(d / "bad"), "--scenario", "seed", "--duration", "60"]) == 0
    lines = (d / "bad" / "plots.csv").read_text().splitlines()
    fields = lines[3].split(",")
    fields[2] = "abc"
    lines[3] = ",".join(fields)
    (d / "bad" / "plots.csv").write_text("\n".join(lines) + "\n")
    return d


@pytest.mark.parametrize("command", [["replay", "{bad}", "--estimator", "decoupled", "--out", "{out}"],
                                     ["replay", "{bad}", "--estimator", "decoupled", "--out", "{out}", "--plots"],
                                     ["compare", "{bad}", "--estimators", "decoupled", "--out", "{out}"]],
                         ids=["replay", "replay --plots", "compare"])
def test_a_failed_run_removes_the_folders_it_made(scenarios, tmp_path, capsys, command):
    out = tmp_path / "new" / "deeper" / "out"
    argv = [a.format(bad=scenarios / "bad", out=out) for a in command]
    assert main(["--quiet", *argv]) == 2
    assert "plots.csv line 4" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []  # out and the two parents it made are gone


def test_a_failed_run_keeps_a_folder_that_was_there(scenarios, tmp_path, capsys):
    empty, earlier = tmp_path / "empty", tmp_path / "earlier"
    empty.mkdir()
    assert main(["--quiet", "replay", str(scenarios / "good"), "--estimator", "decoupled", "--out", str(earlier)]) == 0
    before = {p.name: p.read_bytes() for p in earlier.iterdir()}
    assert "config.json" in before
    assert main(["--quiet", "replay", str(scenarios / "bad"), "--estimator", "decoupled", "--out", str(empty)]) == 2
    assert empty.is_dir() and list(empty.iterdir()) == []
    assert main(["--quiet", "replay", str(scenarios / "bad"), "--estimator", "decoupled", "--out", str(earlier),
                 "--overwrite"]) == 2
    assert {p.name: p.read_bytes() for p in earlier.iterdir()} == before
