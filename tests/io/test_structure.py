"""Structural mistakes in input files: clear errors naming file, line and field, or skipped and counted."""

import json

import numpy as np
import pytest

from radartracker.errors import FormatError
from radartracker.io.recording import TrackPoints, read_new4, write_new4
from radartracker.io.scenario import read_scenario, write_scenario

FILES = ("radars.csv", "plots.csv", "adsb.csv", "truth.csv", "truth_biases.csv", "scenario.json")


@pytest.fixture()
def folder(tmp_path, demo_data):
    write_scenario(tmp_path / "s", demo_data)
    return tmp_path / "s"


def _lines(path):
    return path.read_text(encoding="utf-8").splitlines(keepends=True)


def _write(path, lines):
    path.write_text("".join(lines), encoding="utf-8")


def test_repeated_column_name_is_refused(folder):
    lines = _lines(folder / "plots.csv")
    _write(folder / "plots.csv", [lines[0].rstrip("\n") + ",time\n"] + [x.rstrip("\n") + ",0\n" for x in lines[1:]])
    with pytest.raises(FormatError, match=r"plots.csv line 1: column\(s\) 'time' appear more than once"):
        read_scenario(folder)


def test_duplicate_radar_and_duplicate_truth_bias_are_refused(folder, tmp_path):
    other = tmp_path / "o"
    other.mkdir()
    for name in FILES:
        (other / name).write_bytes((folder / name).read_bytes())
    lines = _lines(folder / "radars.csv")
    _write(folder / "radars.csv", lines + [lines[1]])
    with pytest.raises(FormatError, match=rf"radars.csv line {len(lines) + 1}, field 'radar': duplicate radar id"):
        read_scenario(folder)
    lines = _lines(other / "truth_biases.csv")
    _write(other / "truth_biases.csv", lines + [lines[2]])
    with pytest.raises(FormatError, match=rf"truth_biases.csv line {len(lines) + 1}, field 'radar': .* appears twice"):
        read_scenario(other)


def test_skip_bad_skips_wrong_field_count_and_a_cut_last_line(folder, demo_data):
    lines = _lines(folder / "plots.csv")
    n = len(lines) - 1
    lines[4] = ",".join(lines[4].split(",")[:3]) + "\n"  # too few fields
    lines[6] = lines[6].rstrip("\n") + ",extra,fields\n"  # too many
    lines[-1] = lines[-1][: len(lines[-1]) // 2]  # cut mid-line, no newline
    _write(folder / "plots.csv", lines)
    with pytest.raises(FormatError, match="plots.csv line 5: 3 fields, header has"):
        read_scenario(folder)
    data = read_scenario(folder, skip_bad=True)
    assert data.skipped["plots.csv:wrong_field_count"] == 2
    assert data.skipped["plots.csv:truncated_last_line"] == 1
    assert len(data.plots) == n - 3
    _write(folder / "plots.csv", lines[:4] + lines[7:])  # only the cut line is bad now
    with pytest.raises(FormatError, match=f"plots.csv line {len(lines) - 3}: .*cut short"):
        read_scenario(folder)


def test_duplicate_rows_are_used_once_and_counted(folder):
    clean = read_scenario(folder)
    for name, k in (("plots.csv", 9), ("adsb.csv", 4), ("truth.csv", 3)):
        lines = _lines(folder / name)
        _write(folder / name, lines[: k + 1] + [lines[k]] * 2 + lines[k + 1:])
    data = read_scenario(folder)
    assert data.skipped == {"plots.csv:duplicate_row": 2, "adsb.csv:duplicate_row": 2, "truth.csv:duplicate_row": 2}
    for table in ("plots", "adsb", "truth"):
        a, b = getattr(data, table), getattr(clean, table)
        assert len(a) == len(b)
        np.testing.assert_array_equal(a.time, b.time)


def test_a_target_in_two_places_at_once_is_an_error_naming_both_lines(folder):
    """Two truth rows of one target at one time with different positions (not an exact duplicate) would make its
    velocity there 0/0 in every evaluation: one error naming the file, the line, the field and the first line."""
    lines = _lines(folder / "truth.csv")
    header = lines[0].split(",")
    fields = lines[3].split(",")
    fields[header.index("lat")] = str(float(fields[header.index("lat")]) + 0.01)
    _write(folder / "truth.csv", lines[:4] + [",".join(fields)] + lines[4:])
    with pytest.raises(FormatError, match=r"truth.csv line 5, field .time.: target .\w+. already has another "
                                          r"position at [0-9.]+ s \(line 4\)"):
        read_scenario(folder)


def test_byte_order_mark_is_accepted_everywhere(folder):
    clean = read_scenario(folder)
    for name in FILES:
        (folder / name).write_bytes(b"\xef\xbb\xbf" + (folder / name).read_bytes())
    data = read_scenario(folder)
    assert data.reference == clean.reference and data.radars == clean.radars and data.name == clean.name
    np.testing.assert_array_equal(data.plots.range_m, clean.plots.range_m)
    np.testing.assert_array_equal(data.adsb.lat, clean.adsb.lat)


@pytest.mark.parametrize("name", ["plots.csv", "radars.csv", "scenario.json"])
def test_non_utf8_file_is_named_with_its_line(folder, name):
    lines = (folder / name).read_bytes().split(b"\n")
    lines[2] = lines[2] + b"\xe9"  # Latin-1 é
    (folder / name).write_bytes(b"\n".join(lines))
    with pytest.raises(FormatError, match=rf"{name} line 3: not UTF-8 text"):
        read_scenario(folder)


@pytest.mark.parametrize("edit,words", [
    (lambda m: m["reference"].update(lat=91), "scenario.json, field 'reference.lat': 91 outside"),
    (lambda m: m["reference"].pop("lon"), "scenario.json, field 'reference.lon': expected a number, got null"),
    (lambda m: m.update(reference=None), "scenario.json, field 'reference': expected"),
    (lambda m: m["reference"].update(lat="56.1"), "scenario.json, field 'reference.lat': expected a number"),
    (lambda m: m["reference"].update(lon=float("nan")), "scenario.json, field 'reference.lon': nan outside"),
    (lambda m: m.update(name=3), "scenario.json, field 'name': expected a string"),
    (lambda m: m.update(aircraft={}), "scenario.json, field 'aircraft': expected a list"),
    (lambda m: m["aircraft"][1].update(icao24="xyz"), r"scenario.json, field 'aircraft\[1\]'"),
    (lambda m: m["aircraft"][0].update(wings=2), r"scenario.json, field 'aircraft\[0\]'.*wings"),
    (lambda m: m["aircraft"].append(None), r"scenario.json, field 'aircraft\[\d+\]': expected an object"),
])
def test_scenario_json_problems_name_file_and_field(folder, edit, words):
    meta = json.loads((folder / "scenario.json").read_text())
    edit(meta)
    (folder / "scenario.json").write_text(json.dumps(meta))
    with pytest.raises(FormatError, match=words):
        read_scenario(folder)


def test_scenario_json_syntax_error_names_the_line(folder):
    (folder / "scenario.json").write_text('{"name": "x",\n "reference": {"lat": 1,}\n}')
    with pytest.raises(FormatError, match="scenario.json line 2: not JSON"):
        read_scenario(folder)


def test_plots_with_only_a_header_is_a_clear_error(folder):
    (folder / "plots.csv").write_text(_lines(folder / "plots.csv")[0])
    with pytest.raises(FormatError, match="plots.csv: no usable plot rows after the header: nothing to track"):
        read_scenario(folder)
    lines = _lines(folder / "plots.csv")
    (folder / "plots.csv").write_text(lines[0] + "1,R1,x,0,,,\n")
    with pytest.raises(FormatError, match=r"no usable plot rows \(1 skipped\)"):
        read_scenario(folder, skip_bad=True)


@pytest.mark.parametrize("row,field", [("0\t91\t37\t100", "lat"), ("0\t56\t-180.5\t100", "lon")])
def test_new4_out_of_range_is_a_format_error(tmp_path, row, field):
    path = tmp_path / "a.new4"
    path.write_text("0\t56\t37\t100\n" + row + "\n")
    with pytest.raises(FormatError, match=rf"a.new4 line 2, field '{field}': .* outside"):
        read_new4(path)


def test_new4_with_bom_and_non_utf8(tmp_path):
    path = tmp_path / "a.new4"
    pts = TrackPoints(np.array([0.0, 1.0]), np.array([56.0, 56.1]), np.array([37.0, 37.1]), np.array([100.0, np.nan]))
    write_new4(path, pts)
    path.write_bytes(b"\xef\xbb\xbf" + path.read_bytes())
    np.testing.assert_array_equal(read_new4(path).lat, pts.lat)
    path.write_bytes(path.read_bytes() + b"2\t56\t37\t1\xff\n")
    with pytest.raises(FormatError, match="a.new4 line 3.*not UTF-8"):
        read_new4(path)
