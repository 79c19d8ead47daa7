"""A scenario built from DataFrames is the scenario of the same tables read from files, checked as they are:
a bad value names the DataFrame, its row and the field."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.csv as pacsv
import pytest

from radartracker.errors import FormatError, InputError
from radartracker.io.frames import scenario_from_frames
from radartracker.io.scenario import read_scenario, write_scenario

CODES = ("radar", "mode_s", "mode_3a", "target", "icao24")


@pytest.fixture(scope="module")
def folder(tmp_path_factory, demo_data):
    d = tmp_path_factory.mktemp("frames") / "s"
    write_scenario(d, demo_data)
    return d


def _frame(folder, name) -> pd.DataFrame:
    """A table as a DataFrame, read by pyarrow's CSV reader (decimal text to the nearest double, as Python's
    float(); the codes as texts)."""
    header = (folder / f"{name}.csv").read_text().splitlines()[0].split(",")
    types = {c: pa.string() for c in header if c in CODES}
    return pacsv.read_csv(folder / f"{name}.csv", convert_options=pacsv.ConvertOptions(column_types=types)).to_pandas()


def test_frames_give_the_scenario_of_the_files(folder):
    frames = {name: _frame(folder, name) for name in ("radars", "plots", "adsb", "truth", "truth_biases")}
    got = scenario_from_frames(frames["radars"], frames["plots"], adsb=frames["adsb"], truth=frames["truth"],
                               truth_biases=frames["truth_biases"], reference=(55.75, 37.62), name="demo")
    want = read_scenario(folder)
    for table in ("plots", "adsb", "truth"):
        a, b = getattr(got, table), getattr(want, table)
        for col in a.__attrs_attrs__:
            x, y = getattr(a, col.name), getattr(b, col.name)
            if x.dtype == object:
                assert list(x) == list(y), (table, col.name)
            else:
                np.testing.assert_array_equal(x, y, err_msg=f"{table}.{col.name}")
    assert got.radars == want.radars and got.truth_biases == want.truth_biases
    assert got.reference == (55.75, 37.62) and got.name == "demo"


def test_an_arrow_table_is_taken_as_it_is(folder):
    radars = pa.Table.from_pandas(_frame(folder, "radars"), preserve_index=False)
    plots = pa.Table.from_pandas(_frame(folder, "plots"), preserve_index=False)
    assert len(scenario_from_frames(radars, plots).plots) == len(read_scenario(folder).plots)


def test_a_bad_value_names_the_frame_row_and_field(folder):
    radars, plots = _frame(folder, "radars"), _frame(folder, "plots")
    plots.loc[6, "range_m"] = -1.0
    with pytest.raises(FormatError, match=r"^plots \(DataFrame\) row 7, field 'range_m': -1.0 is negative$"):
        scenario_from_frames(radars, plots)
    assert scenario_from_frames(radars, plots, skip_bad=True).skipped == {"plots (DataFrame):malformed": 1}
    plots["mode_3a"] = 741
    with pytest.raises(FormatError, match=r"field 'mode_3a': type int64, expected text"):
        scenario_from_frames(radars, plots)
    plots["mode_3a"] = [1.5] + ["0741"] * (len(plots) - 1)  # numbers and texts in one column
    with pytest.raises(FormatError, match=r"^plots \(DataFrame\): cannot be made an Arrow table"):
        scenario_from_frames(radars, plots)
    with pytest.raises(InputError, match="reference"):
        scenario_from_frames(radars, _frame(folder, "plots"), reference=(95.0, 0.0))
