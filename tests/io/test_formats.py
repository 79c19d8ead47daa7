"""Scenario folder round trip and bad input: errors name file, line and field, or skip and count."""

import math
import shutil

import numpy as np
import pytest

from radartracker.errors import FormatError
from radartracker.io.scenario import read_scenario, write_scenario


@pytest.fixture()
def folder(tmp_path, demo_data):
    write_scenario(tmp_path / "s", demo_data)
    return tmp_path / "s"


def test_round_trip_keeps_plots_to_file_precision(folder, demo_data):
    back = read_scenario(folder)
    p, q = demo_data.plots, back.plots
    assert len(p) == len(q) and back.name == "demo"
    np.testing.assert_allclose(q.time, p.time, atol=5e-5)
    np.testing.assert_allclose(q.range_m, p.range_m, atol=5e-4)
    dth = np.mod(q.azimuth_rad - p.azimuth_rad + math.pi, 2 * math.pi) - math.pi
    assert np.max(np.abs(dth)) < math.radians(5e-8)
    assert list(q.mode_s) == list(p.mode_s) and list(q.target) == list(p.target)
    assert back.reference == demo_data.reference
    assert back.truth_biases.keys() == demo_data.truth_biases.keys()
    assert len(back.adsb) == len(demo_data.adsb) and len(back.truth) == len(demo_data.truth)
    assert [a.icao24 for a in back.aircraft] == [a.icao24 for a in demo_data.aircraft]


def _edit_line(path, lineno, transform):
    lines = path.read_text().splitlines(keepends=True)
    lines[lineno - 1] = transform(lines[lineno - 1])
    path.write_text("".join(lines))


def _set_field(path, lineno, column, value):
    header = path.read_text().splitlines()[0].split(",")
    col = header.index(column)

    def tr(line):
        fields = line.rstrip("\n").split(",")
        fields[col] = value
        return ",".join(fields) + "\n"
    _edit_line(path, lineno, tr)


@pytest.mark.parametrize("column,value,words", [
    ("range_m", "abc", "plots.csv line 7, field 'range_m': 'abc' is not a number"),
    ("range_m", "nan", "plots.csv line 7, field 'range_m': 'nan' is not finite"),
    ("azimuth_deg", "360", "plots.csv line 7, field 'azimuth_deg': 360.0 outside \\[0, 360\\)"),
    ("radar", "R9", "plots.csv line 7, field 'radar': unknown radar 'R9'"),
    ("mode_s", "12345g", "plots.csv line 7, field 'mode_s'"),
    ("time", "-100", "plots.csv line 7, field 'time': -100.0 is earlier than"),
])
def test_bad_plot_row_names_file_line_field(folder, column, value, words):
    _set_field(folder / "plots.csv", 7, column, value)
    with pytest.raises(FormatError, match=words):
        read_scenario(folder)


def test_bad_rows_skipped_and_counted_on_request(folder, demo_data):
    _set_field(folder / "plots.csv", 7, "range_m", "abc")
    _set_field(folder / "plots.csv", 9, "radar", "R9")
    _set_field(folder / "plots.csv", 12, "range_m", "inf")
    back = read_scenario(folder, skip_bad=True)
    assert back.skipped == {"plots.csv:malformed": 2, "plots.csv:unknown_radar": 1}
    assert len(back.plots) == len(demo_data.plots) - 3


def test_short_row_and_missing_column_and_empty_file(folder):
    _edit_line(folder / "plots.csv", 5, lambda line: ",".join(line.split(",")[:3]) + "\n")
    with pytest.raises(FormatError, match="plots.csv line 5: 3 fields, header has 8"):
        read_scenario(folder)
    (folder / "plots.csv").write_text("time,radar,range_m\n1,R1,5\n")
    with pytest.raises(FormatError, match="plots.csv line 1: missing column\\(s\\) azimuth_deg"):
        read_scenario(folder)
    (folder / "plots.csv").write_text("")
    with pytest.raises(FormatError, match="plots.csv line 1: empty file"):
        read_scenario(folder)


def test_bad_radar_file(folder):
    _set_field(folder / "radars.csv", 2, "sigma_range_m", "-3")
    with pytest.raises(FormatError, match=r"radars.csv line 2, field 'sigma_range_m': -3.0 outside the physical "
                                          r"bounds \[0, 10000\] m"):
        read_scenario(folder)


@pytest.mark.parametrize("field,value", [("sigma_range_m", "1e308"), ("height_m", "1e308"), ("period_s", "0"),
                                         ("sigma_azimuth_deg", "90"), ("max_range_m", "1e300")])
def test_radar_values_beyond_physical_bounds(folder, field, value):
    _set_field(folder / "radars.csv", 3, field, value)
    with pytest.raises(FormatError, match=rf"radars.csv line 3, field '{field}': .* outside the physical bounds"):
        read_scenario(folder)


def test_reference_defaults_to_radar_centroid(folder):
    (folder / "scenario.json").unlink()
    back = read_scenario(folder)
    assert back.reference[0] == pytest.approx(np.mean([r.lat for r in back.radars]))


def test_write_refuses_existing_folder(folder, demo_data):
    with pytest.raises(FileExistsError):
        write_scenario(folder, demo_data)


def test_missing_folder(tmp_path):
    with pytest.raises(FileNotFoundError, match="does not exist"):
        read_scenario(tmp_path / "nope")
    shutil.rmtree(tmp_path)
