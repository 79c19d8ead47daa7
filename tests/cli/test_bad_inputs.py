"""Every command that reads a file, given a damaged one: a missing column, a field that is not a number,
an empty file, a file of the wrong type, no file. Each must print one line naming the file (and for a
field, its line and name) and exit 2 — never a traceback — and write nothing."""

from __future__ import annotations

import json
import os
import resource
import shutil
import subprocess
import sys
import time
from pathlib import Path

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
    assert not out.exists()  # nor an empty folder: one made to check it is writable is removed again
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


# --- issue 28: every traceback, unbounded run and memory bomb found, in a subprocess under 2 GiB -------------

LIMIT_BYTES = 2 << 30


def _limited() -> None:  # preexec_fn: the child may use 2 GiB of address space, as the issue's bound
    resource.setrlimit(resource.RLIMIT_AS, (LIMIT_BYTES, LIMIT_BYTES))


def _command(argv: list[str]) -> tuple[int, list[str], float]:
    """Exit code, non-blank stderr lines and seconds of ``radartracker ARGV`` in a child process."""
    t0 = time.monotonic()
    p = subprocess.run([sys.executable, "-c", "import sys; from radartracker.cli import main; sys.exit(main())",
                        "--quiet", *argv], capture_output=True, text=True, timeout=60, preexec_fn=_limited,
                       env={**os.environ, "TQDM_DISABLE": "1"})
    return p.returncode, [e for e in p.stderr.splitlines() if e.strip()], time.monotonic() - t0


def _copy(src: Path, dst: Path) -> Path:
    shutil.copytree(src, dst)
    return dst


def _set(path: Path, line: int, column: str, value: str) -> None:
    lines = path.read_text().splitlines()
    header = lines[0].split(",")
    fields = lines[line - 1].split(",")
    fields[header.index(column)] = value
    lines[line - 1] = ",".join(fields)
    path.write_text("\n".join(lines) + "\n")


def _case(name: str, d: Path, o: Path) -> tuple[list[str], str]:
    """The command line of a case of issue 28 and the words its one error line must hold."""
    scen = d / "scen"
    if name == "nested_scenario_json":
        s = _copy(scen, d / name)
        (s / "scenario.json").write_text("[" * 100_000 + "]" * 100_000)
        return ["replay", str(s), "--out", str(o)], "scenario.json line 1: nested more than 64 levels deep"
    if name == "nested_config":
        (d / "cfg.json").write_text('{"a":' * 100_000 + "1" + "}" * 100_000)
        return ["replay", str(scen), "--out", str(o), "--config", str(d / "cfg.json")], "cfg.json line 1: nested"
    if name == "long_integer_scenario_json":
        s = _copy(scen, d / name)
        (s / "scenario.json").write_text('{"name": "x",\n "reference": {"lat": ' + "9" * 5000 + ', "lon": 1}}')
        return ["replay", str(s), "--out", str(o)], "scenario.json line 2: a number of 5,000 characters"
    if name in ("sigma_1e308", "sigma_1e308_manager", "sigma_1e308_export"):
        s = _copy(scen, d / name)
        _set(s / "radars.csv", 2, "sigma_range_m", "1e308")
        argv = (["asterix-export", str(s), "--out", str(o) + ".ast"] if name.endswith("export")
                else ["replay", str(s), "--out", str(o)] + (["--manager"] if name.endswith("manager") else []))
        return argv, "radars.csv line 2, field 'sigma_range_m': 1e+308 outside the physical bounds"
    if name in ("single_bearing", "bidi_emoji_target"):
        target = "S" if name == "single_bearing" else "\u202e\U0001F600"
        _write_bearings(d / "b.csv", [(5.0, "df0", 0.3, 0.1, target)])
        return (["triangulate", str(d / "b.csv"), "--stations", str(d / "stations.csv"), "--out", str(o)],
                f"no target located: 1 of 1 refused (target {target}: degenerate geometry: 1 bearing(s) give 2 "
                "equations for 3 unknowns")
    if name in ("one_site", "height_1e308", "sigma_1e-300"):
        lines = (d / "stations.csv").read_text().splitlines()
        rows = [r.split(",") for r in lines[2:]]
        for r in rows:
            if name == "one_site":
                r[1:3] = rows[0][1:3]
            elif name == "height_1e308":
                r[3] = "1e308"
            else:
                r[4] = "1e-300"
        (d / "st.csv").write_text("\n".join(lines[:2] + [",".join(r) for r in rows]) + "\n")
        words = {"one_site": "every bearing comes from one site", "height_1e308": "line 3, field 'height_m'",
                 "sigma_1e-300": "line 3, field 'sigma_azimuth_deg'"}[name]
        return ["triangulate", str(d / "bearings.csv"), "--stations", str(d / "st.csv"), "--out", str(o)], words
    if name == "reconstruct_grid_1e-6":
        return (["reconstruct", str(d / "t.new4"), "--out", str(o), "--engine", "serial", "--grid", "1e-6"],
                "--grid: 1e-06 outside [0.001, 3600]")
    if name == "simulate_traffic_1e6":
        return (["simulate", str(o), "--scenario", "traffic", "--aircraft", "1000000"],
                "--scenario traffic with 1,000,000 aircraft over 180 s needs about")
    if name == "line_of_256_MB":
        s = _copy(scen, d / name)
        with open(s / "plots.csv", "ab") as f:
            f.write(b"9" * (256 << 20) + b"\n")
        return ["replay", str(s), "--out", str(o)], "plots.csv line"
    if name == "plots_csv_is_dev_zero":
        s = _copy(scen, d / name)
        (s / "plots.csv").unlink()
        (s / "plots.csv").symlink_to("/dev/zero")
        return ["replay", str(s), "--out", str(o)], "plots.csv: is a character device, not a regular file"
    if name == "first_row_far_ahead":
        s = _copy(scen, d / name)
        _set(s / "plots.csv", 2, "time", "1e12")
        return ["replay", str(s), "--out", str(o)], "plots.csv line 2, field 'time': 1000000000000.0 is more than"
    raise KeyError(name)


WHY = ["nested_scenario_json", "nested_config", "long_integer_scenario_json", "sigma_1e308", "sigma_1e308_manager",
       "sigma_1e308_export", "single_bearing", "bidi_emoji_target", "one_site", "height_1e308", "sigma_1e-300",
       "reconstruct_grid_1e-6", "simulate_traffic_1e6", "line_of_256_MB", "plots_csv_is_dev_zero",
       "first_row_far_ahead"]


@pytest.mark.parametrize("name", WHY)
def test_issue_28_case_is_one_line_and_exit_2(inputs, tmp_path, name):
    d = tmp_path / "in"
    shutil.copytree(inputs, d)
    argv, words = _case(name, d, tmp_path / "out")
    rc, err, seconds = _command(argv)
    assert rc == 2 and len(err) == 1 and words in err[0] and seconds < 60, (rc, err[-3:], seconds)


def test_huge_lsq_weights_give_the_identity_weights_fix(inputs, tmp_path):
    """W = 1e300·I overflowed the residuals; only ratios of W matter (the estimate is invariant to a common
    factor), so the fix must be the W = I one."""
    (tmp_path / "w.csv").write_text("station,w_azimuth,w_elevation\n" + "".join(f"df{i},1e300,1e300\n" for i in range(3)))
    base = ["triangulate", str(inputs / "bearings.csv"), "--stations", str(inputs / "stations.csv"), "--estimator", "lsq"]
    assert _command([*base, "--out", str(tmp_path / "huge"), "--weights", str(tmp_path / "w.csv")])[0] == 0
    assert _command([*base, "--out", str(tmp_path / "unit"), "--weights", "identity"])[0] == 0
    assert (tmp_path / "huge" / "fixes.csv").read_text() == (tmp_path / "unit" / "fixes.csv").read_text()


def test_convert_counts_a_time_of_1e308(inputs, tmp_path):
    """convert counts bad lines by design (report.json): a time of 1e308 is one malformed line, no traceback."""
    rec = _copy(inputs / "rec", tmp_path / "rec")
    lines = (rec / "plots_ads.txt").read_text().splitlines()
    lines[1] = "\t".join(["1e308"] + lines[1].split("\t")[1:])
    (rec / "plots_ads.txt").write_text("\n".join(lines) + "\n")
    rc, err, _ = _command(["convert", str(rec), "--out", str(tmp_path / "new"), "--AZN_TRACKS_MIN_MEASUR", "1"])
    report = json.loads((tmp_path / "new" / "report.json").read_text())["files"]["plots_ads.txt"]
    assert rc == 0 and not err and report["malformed"] == 1 and report["line_numbers"]["malformed"] == [2]
    assert "field time: 1e+308 outside" in report["first_errors"][0]["error"]


def test_a_truth_time_of_1e9_is_evaluated_within_2_gib(inputs, tmp_path):
    s = _copy(inputs / "scen", tmp_path / "scen")
    with open(s / "truth.csv", "a") as f:
        f.write("1000000000.000,4b0000,55.6,37.5,9833.00\n")
    rc, err, seconds = _command(["replay", str(s), "--out", str(tmp_path / "out")])
    assert rc == 0 and not err and seconds < 60
