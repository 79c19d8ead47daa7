"""``triangulate`` outputs: a run that fails while writing (or is killed) keeps an earlier run's files
intact, ``--overwrite`` replaces them only once the new run is complete and never mixes two runs, and
bad inputs give one line naming file, line and field with exit 2."""

import errno
import json

import numpy as np
import pytest

import radartracker_plugins.triangulation.io as tio
from radartracker.cli import main

from tests.plugins.test_triangulation_cli import _rows, _write_bearings, _write_stations


def _tree(folder):
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}


@pytest.fixture()
def files(tmp_path):
    frame = _write_stations(tmp_path / "stations.csv")
    times = np.arange(0.0, 30.0, 2.0)
    pos = np.array([[1000.0 + 100.0 * t, 2000.0, 3000.0] for t in times])
    rows = _rows(frame, list(frame.stations) * 5, times, pos, "M", np.random.default_rng(3))
    rows += _rows(frame, list(frame.stations) * 5, times, pos + 5000.0, "N", np.random.default_rng(4))
    _write_bearings(tmp_path / "bearings.csv", rows)
    return ["triangulate", str(tmp_path / "bearings.csv"), "--stations", str(tmp_path / "stations.csv"),
            "--out", str(tmp_path / "out")]


def _fail_after_first_row(monkeypatch):
    """The fixes/tracks writer fails after one row (the disk filled up)."""
    real, calls = tio._geo_cols, []

    def geo_cols(*args):
        calls.append(1)
        if len(calls) > 1:
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(*args)

    monkeypatch.setattr(tio, "_geo_cols", geo_cols)
    return calls


def test_a_rerun_that_fails_while_writing_keeps_the_earlier_run(files, tmp_path, capsys, monkeypatch):
    assert main(files) == 0
    earlier = _tree(tmp_path / "out")
    assert sorted(earlier) == ["fixes.csv", "summary.json"]
    calls = _fail_after_first_row(monkeypatch)
    assert main([*files, "--overwrite", "--mode", "dynamic"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(calls) == 2 and len(err) == 1 and "No space left" in err[0]
    assert _tree(tmp_path / "out") == earlier  # no temporary file either


def test_a_failure_in_a_new_folder_leaves_no_folder(files, tmp_path, monkeypatch):
    _fail_after_first_row(monkeypatch)
    assert main(files) == 2
    assert not (tmp_path / "out").exists()  # made to check it can be written, removed again


def test_overwrite_replaces_the_earlier_run_whole(files, tmp_path):
    assert main(files) == 0
    assert main([*files, "--overwrite", "--mode", "dynamic"]) == 0
    assert sorted(_tree(tmp_path / "out")) == ["summary.json", "tracks.csv"]  # the static run's fixes.csv is gone
    assert json.loads((tmp_path / "out" / "summary.json").read_text())["mode"] == "dynamic"


def test_what_a_killed_run_left_does_not_block_the_next(files, tmp_path):
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / ".fixes.csv.999999999-abcdefgh.tmp").write_text("half written by a killed run")
    assert main(files) == 0
    assert sorted(_tree(tmp_path / "out")) == ["fixes.csv", "summary.json"]


@pytest.mark.parametrize("text,skip_bad,words", [
    ("time_s,station,azimuth_deg,elevation_deg\n", False, "bearings.csv: no bearings"),
    ("time_s,station,azimuth_deg,elevation_deg\n1.0,df0,x,1\n", True, "bearings.csv: no bearings (1 malformed"),
    ("time_s,station,azimuth_deg,elevation_deg\n1.0,df0,40.0\n", False,
     "bearings.csv line 2: 3 fields where the header has 4"),
    ("time_s,station,elevation_deg\n1.0,df0,1.0\n", False, "bearings.csv line 1: header lacks column(s) azimuth_deg"),
    ("", False, "bearings.csv: empty file"),
])
def test_bad_bearings_file_is_one_line_and_exit_2(tmp_path, capsys, text, skip_bad, words):
    _write_stations(tmp_path / "stations.csv")
    (tmp_path / "bearings.csv").write_text(text)
    argv = ["triangulate", str(tmp_path / "bearings.csv"), "--stations", str(tmp_path / "stations.csv"),
            "--out", str(tmp_path / "out")] + (["--skip-bad"] if skip_bad else [])
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and words in err[0], err
    with pytest.raises(tio.FormatError) as info:  # the reader's error carries the place, not only the text
        tio.read_bearings(tmp_path / "bearings.csv", skip_bad=skip_bad)
    assert info.value.file == "bearings.csv"
