"""``triangulate`` inputs: BOM, non-UTF-8 and repeated columns in the CSVs; numeric options out of range."""

import math
import re

import numpy as np
import pytest

from radartracker.cli import main
from radartracker.errors import InputError
from radartracker_plugins.triangulation import io

from tests.plugins.test_triangulation_cli import _rows, _write_bearings, _write_stations


@pytest.fixture()
def files(tmp_path):
    frame = _write_stations(tmp_path / "stations.csv")
    times = np.arange(0.0, 60.0, 2.0)
    pos = np.array([[1000.0 + 100.0 * t, 2000.0, 3000.0] for t in times])
    _write_bearings(tmp_path / "bearings.csv", _rows(frame, list(frame.stations), times, pos, "M",
                                                     np.random.default_rng(1)))
    return tmp_path / "bearings.csv", tmp_path / "stations.csv"


def test_bom_is_accepted(files):
    bearings, stations = files
    before = io.read_bearings(bearings)[0], io.read_stations(stations)
    for p in files:
        p.write_bytes(b"\xef\xbb\xbf" + p.read_bytes())
    assert (io.read_bearings(bearings)[0], io.read_stations(stations)) == before


def test_non_utf8_and_repeated_columns_are_named(files):
    bearings, stations = files
    lines = bearings.read_bytes().split(b"\n")
    bearings.write_bytes(b"\n".join(lines[:3] + [lines[3] + b"\xff"] + lines[4:]))
    with pytest.raises(InputError, match="bearings.csv line 4: not UTF-8"):
        io.read_bearings(bearings)
    text = stations.read_text().splitlines()
    stations.write_text("\n".join(text[:1] + [text[1] + ",id"] + [t + ",x" for t in text[2:]]) + "\n")
    with pytest.raises(InputError, match="stations.csv line 2: column.* id appear more than once"):
        io.read_stations(stations)


@pytest.mark.parametrize("options,words", [
    (["--reference", "91,2"], "--reference: LAT = 91.0 outside"),
    (["--reference", "50,nan"], "--reference: LON = nan outside"),
    (["--reference", "50,7,inf"], "--reference: H = inf outside"),
    (["--mode", "dynamic", "--step", "1e-9"], "--step 1e-09: target M would get .* output times"),
    (["--mode", "dynamic", "--step", "nan"], "--step: must be a finite number > 0"),
    (["--mode", "dynamic", "--order", "1000"], "--order: must be 0..10"),
    (["--max-gdop", "-1"], "--max-gdop: must be > 0"),
    (["--warn-gdop", "nan"], "--warn-gdop: must be > 0"),
])
def test_numeric_options_out_of_range_are_refused(files, tmp_path, capsys, options, words):
    bearings, stations = files
    rc = main(["triangulate", str(bearings), "--stations", str(stations), "--out", str(tmp_path / "out"), *options])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1 and re.search(words, err), err


def test_a_fine_but_bounded_step_works(files, tmp_path):
    bearings, stations = files
    assert main(["triangulate", str(bearings), "--stations", str(stations), "--out", str(tmp_path / "out"),
                 "--mode", "dynamic", "--step", "0.01"]) == 0
    n = len((tmp_path / "out" / "tracks.csv").read_text().splitlines()) - 1
    t = [b.time for b in io.read_bearings(bearings)[0]]
    assert n == math.floor((max(t) - min(t)) / 0.01 + 1e-6) + 1


def test_duplicate_bearing_rows_are_used_once(files, tmp_path):
    bearings, stations = files
    clean, counts = io.read_bearings(bearings)
    assert counts == {"malformed": 0, "duplicate": 0}
    lines = bearings.read_text().splitlines(keepends=True)
    bearings.write_text("".join(lines[:3] + [lines[2]] * 2 + lines[3:]))
    again, counts = io.read_bearings(bearings)
    assert again == clean and counts == {"malformed": 0, "duplicate": 2}
