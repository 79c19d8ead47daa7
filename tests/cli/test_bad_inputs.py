"""Every command that reads a file, given a damaged one: a missing column, a field that is not a number,
an empty file, a file of the wrong type, no file. Each must print one line naming the file (and for a
field, its line and name) and exit 2 — never a traceback — and write nothing."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from radartracker.cli import main
from radartracker.io.asterix import write_asterix
from radartracker.io.recording import TrackPoints, write_new4, write_scenario_recording
from radartracker.io.scenario import write_scenario
from radartracker.simulation.scenarios import build_scenario

from tests.plugins.test_triangulation_cli import _rows, _write_bearings, _write_stations


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    d = tmp_path_factory.mktemp("bad_inputs")
    data = build_scenario("demo", seed=3, duration=20.0).run()
    write_scenario(d / "scen", data)
    write_asterix(d / "rec.ast", data)
    write_scenario_recording(d / "rec", data)
    write_new4(d / "t.new4", TrackPoints(1.7e9 + np.arange(20.0), 56.0 + 0.01 * np.arange(20),
                                         37.0 + 0.01 * np.arange(20), np.full(20, 1000.0)))
    frame = _write_stations(d / "stations.csv")
    times = np.arange(0.0, 20.0, 2.0)
    pos = np.array([[1000.0 + 100.0 * t, 2000.0, 3000.0] for t in times])
    _write_bearings(d / "bearings.csv", _rows(frame, list(frame.stations), times, pos, "M", np.random.default_rng(2)))
    return d


# command (with {d} for the inputs, {o} for the output), the file damaged, its separator, a numeric column
COMMANDS = {
    "replay": ("replay {d}/scen --out {o} --estimator decoupled", "scen/plots.csv", ",", "range_m"),
    "asterix-export": ("asterix-export {d}/scen --out {o}.ast", "scen/radars.csv", ",", "lat"),
    "write-recording": ("write-recording --scenario {d}/scen --out {o}", "scen/plots.csv", ",", "azimuth_deg"),
    "asterix-import": ("asterix-import {d}/rec.ast --out {o}", "rec.ast.radars.csv", ",", "sic"),
    "convert": ("convert {d}/rec --out {o}", "rec/plots.txt", "\t", None),  # bad rows are counted, by design
    "triangulate": ("triangulate {d}/bearings.csv --stations {d}/stations.csv --out {o}", "stations.csv", ",",
                    "height_m"),
    "reconstruct": ("reconstruct {d}/t.new4 --out {o} --engine serial --no-figures", "t.new4", "\t", None),
}


def _damage(path, kind, sep, column):
    if kind in ("missing_column", "not_a_number"):
        lines = path.read_text().splitlines(keepends=True)
        first = next(i for i, line in enumerate(lines) if not line.startswith("#"))
        header = lines[first].rstrip("\n").split(sep)
    if kind == "missing_column":
        j = header.index(column) if column in header else 0
        lines[first:] = [sep.join(f for k, f in enumerate(line.rstrip("\n").split(sep)) if k != j) + "\n"
                         for line in lines[first:]]
        path.write_text("".join(lines))
    elif kind == "not_a_number":
        fields = lines[first + 1].rstrip("\n").split(sep)
        fields[header.index(column)] = "abc"
        lines[first + 1] = sep.join(fields) + "\n"
        path.write_text("".join(lines))
        return first + 2  # the damaged line's number
    elif kind == "empty":
        path.write_bytes(b"")
    elif kind == "wrong_type":
        path.write_bytes(bytes(range(256)) * 8)
    elif kind == "missing":
        path.unlink()
    return None


CASES = [(cmd, kind) for cmd, (_, _, _, column) in COMMANDS.items()
         for kind in ("missing_column", "not_a_number", "empty", "wrong_type", "missing")
         if column is not None or kind not in ("not_a_number", "missing_column")]
CASES += [("send", kind) for kind in ("empty", "text_recording", "missing")]  # send relays any framing as is
CASES += [("asterix-import", "text_recording")]


@pytest.mark.parametrize("command,kind", CASES)
def test_damaged_input_is_one_line_and_exit_2(inputs, tmp_path, capsys, command, kind):
    d = tmp_path / "in"
    shutil.copytree(inputs, d)
    if command == "send":
        argv, rel, sep, column = "send {d}/rec.ast --to udp://127.0.0.1:9 --speed 0", "rec.ast", None, None
    else:
        argv, rel, sep, column = COMMANDS[command]
    if kind == "text_recording":  # a text file where the binary recording belongs
        rel, kind = "rec.ast", "replace_with_text"
        (d / rel).write_text("time,radar\n1.0,R1\n")
        line = None
    else:
        line = _damage(d / rel, kind, sep, column)
    out = tmp_path / "out"
    rc = main(["--quiet", *argv.format(d=d, o=out).split()])
    err = [e for e in capsys.readouterr().err.splitlines() if e.strip()]
    assert rc == 2 and len(err) == 1, err
    name = rel.rsplit("/", 1)[-1]
    assert name in err[0], err
    if line is not None:
        assert f"line {line}" in err[0] and column in err[0], err
    assert not out.exists() or list(out.iterdir()) == []  # triangulate/replay check the folder first
    assert sorted(p.name for p in tmp_path.iterdir()) in (["in"], ["in", "out"])  # no hidden leftovers


def test_replay_with_a_header_only_truth_file(inputs, tmp_path, capsys):
    # a truth file without rows is a run without truth: the replay's own outputs, no evaluation
    shutil.copytree(inputs / "scen", tmp_path / "scen")
    header = (tmp_path / "scen" / "truth.csv").read_text().splitlines()[0]
    (tmp_path / "scen" / "truth.csv").write_text(header + "\n")
    assert main(["--quiet", "replay", str(tmp_path / "scen"), "--out", str(tmp_path / "out"),
                 "--estimator", "decoupled"]) == 0
    (tmp_path / "scen" / "truth.csv").unlink()
    assert main(["--quiet", "replay", str(tmp_path / "scen"), "--out", str(tmp_path / "none"),
                 "--estimator", "decoupled"]) == 0
    assert (tmp_path / "out" / "tracks.csv").read_bytes() == (tmp_path / "none" / "tracks.csv").read_bytes()


def test_replay_with_a_binary_config_file(inputs, tmp_path, capsys):
    (tmp_path / "config.json").write_bytes(bytes(range(256)))
    assert main(["--quiet", "replay", str(inputs / "scen"), "--out", str(tmp_path / "out"),
                 "--config", str(tmp_path / "config.json")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "config.json" in err[0] and "UTF-8" in err[0]


def test_replay_of_a_csv_file_says_it_is_not_a_scenario_folder(inputs, tmp_path, capsys):
    plots = inputs / "scen" / "plots.csv"
    assert main(["--quiet", "replay", str(plots), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(plots) in err[0] and "is a file, not a scenario folder" in err[0], err
