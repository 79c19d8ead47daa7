"""Scenario tables as Parquet files and partitioned datasets: the replay of a Parquet copy gives the tracks of
the CSV folder, a dataset is read in time order a piece at a time, and a damaged Parquet table is one line
naming the file and the field (exit 2), never a traceback."""

from __future__ import annotations

import csv
import json
import math
import shutil
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv
import pyarrow.parquet as pq
import pytest

from radartracker.cli import main
from radartracker.errors import FormatError, InputError
from radartracker.io.datasets import merge_blocks
from radartracker.io.scenario import open_scenario, read_scenario, write_scenario
from radartracker.io.tables import PlotTable
from radartracker.simulation.scenarios import build_scenario

TEXT_COLUMNS = ("radar", "mode_s", "mode_3a", "target", "icao24")


@pytest.fixture(scope="module")
def csv_folder(tmp_path_factory):
    """The ``tracking`` scenario (false plots, a primary-only aircraft, equal Mode 3/A codes) as CSV files."""
    folder = tmp_path_factory.mktemp("parquet") / "csv"
    write_scenario(folder, build_scenario("tracking", seed=2, duration=300.0).run())
    return folder


def parquet_copy(src: Path, dst: Path) -> Path:
    """Each CSV table of ``src`` as a Parquet file in ``dst``, converted by pyarrow alone: the numbers its CSV
    reader reads (correctly rounded, as Python's float()), the texts as texts."""
    dst.mkdir()
    for path in src.glob("*.csv"):
        header = path.read_text().splitlines()[0].split(",")
        types = {c: pa.string() for c in header if c in TEXT_COLUMNS}
        table = pacsv.read_csv(path, convert_options=pacsv.ConvertOptions(column_types=types))
        pq.write_table(table, dst / f"{path.stem}.parquet")
    shutil.copy(src / "scenario.json", dst)
    return dst


def _rows(path: Path) -> list[dict[str, str]]:
    with open(path, newline="", encoding="utf-8") as f:
        return list(csv.DictReader(f))


def _replay(folder: Path, out: Path, *args: str) -> None:
    assert main(["--quiet", "replay", str(folder), "--out", str(out), "--estimator", "decoupled", *args]) == 0


@pytest.mark.parametrize("association", ["manager", "labels"])
def test_replay_of_a_parquet_copy_gives_the_tracks_of_the_csv_folder(csv_folder, tmp_path, association):
    copy = parquet_copy(csv_folder, tmp_path / "pq")
    assert not list(copy.glob("*.csv")) and (copy / "plots.parquet").exists()
    _replay(csv_folder, tmp_path / "a", "--association", association)
    _replay(copy, tmp_path / "b", "--association", association)
    a, b = _rows(tmp_path / "a" / "tracks.csv"), _rows(tmp_path / "b" / "tracks.csv")
    assert len(a) == len(b) > 100
    for ra, rb in zip(a, b):
        assert ra["track"] == rb["track"] and ra["mode_s"] == rb["mode_s"] and ra["mode_3a"] == rb["mode_3a"]
        for col in ("time", "x_m", "y_m", "vx_mps", "vy_mps", "lat", "lon"):
            assert float(ra[col]) == pytest.approx(float(rb[col]), abs=1e-6)


def test_a_dataset_written_by_hour_and_radar_replays_as_the_csv_folder(csv_folder, tmp_path):
    """The simulated scenario written as CSV (rounded to the file's decimals) and as a partitioned dataset (the
    doubles themselves): the same tracks, within what the CSV rounding (0.1 ms, 1 mm, 1e-7 degree) moves them."""
    data = build_scenario("tracking", seed=2, duration=300.0).run()
    write_scenario(tmp_path / "ds", data, format="dataset")
    plot_files = sorted(p.relative_to(tmp_path / "ds").as_posix() for p in (tmp_path / "ds" / "plots").rglob("*.parquet"))
    assert plot_files == [f"plots/hour=0/radar={r.id}/part-0.parquet" for r in sorted(data.radars, key=lambda r: r.id)]
    _replay(csv_folder, tmp_path / "a", "--manager")
    _replay(tmp_path / "ds", tmp_path / "b", "--manager")
    a, b = _rows(tmp_path / "a" / "tracks.csv"), _rows(tmp_path / "b" / "tracks.csv")
    assert len(a) == len(b) > 100 and [r["track"] for r in a] == [r["track"] for r in b]
    for ra, rb in zip(a, b):
        assert float(ra["time"]) == pytest.approx(float(rb["time"]), abs=1.1e-3)
        assert math.hypot(float(ra["x_m"]) - float(rb["x_m"]), float(ra["y_m"]) - float(rb["y_m"])) < 1.0


def test_a_dataset_streams_its_plots_in_time_order_a_block_at_a_time(tmp_path):
    """Plots of three radars across an hour boundary as six files: the streamed blocks are the plots of the CSV
    reading, in time order, and each holds at most what one block's memory (shared by the hour's three files:
    512 rows each here) allows, however long the recording."""
    data = build_scenario("demo", seed=3, duration=1200.0).run()
    data.plots.time[:] += 7200.0 - 600.0  # hours 1 and 2
    write_scenario(tmp_path / "ds", data, format="dataset")
    write_scenario(tmp_path / "csv", data)
    hours = {p.name for p in (tmp_path / "ds" / "plots").iterdir()}
    assert hours == {"hour=1", "hour=2"}
    files = open_scenario(tmp_path / "ds", block_bytes=3 * 512 * 64)
    blocks = list(files.plot_blocks())
    got = np.concatenate([b.time for b in blocks])
    want = np.sort(read_scenario(tmp_path / "csv").plots.time)
    assert files.rows == len(data.plots) + len(data.adsb)
    assert np.all(np.diff(got) >= 0) and np.allclose(got, want, atol=5e-5, rtol=0)
    assert len(blocks) > 3 and max(len(b) for b in blocks) <= 3 * 512


@pytest.mark.parametrize("seed", range(5))
def test_merging_streams_keeps_time_order_and_stream_order_at_equal_times(seed):
    rng = np.random.default_rng(seed)
    streams, rows = [], []
    for k in range(4):
        t = np.sort(rng.integers(0, 50, 40)).astype(float)  # many equal times, within and across streams
        rows += [(x, k, i) for i, x in enumerate(t)]
        cuts = np.sort(rng.choice(np.arange(1, 40), 3, replace=False))
        streams.append(iter([_plots(t[a:b], k, np.arange(a, b)) for a, b in zip([0, *cuts], [*cuts, 40])]))
    merged = list(merge_blocks(streams))
    got = [(t, int(r[1:]), rng_m) for b in merged for t, r, rng_m in zip(b.time, b.radar, b.range_m)]
    assert got == sorted(rows)  # by time, then stream, then position in the stream


def _plots(t: np.ndarray, stream: int, index: np.ndarray) -> PlotTable:
    n = len(t)
    return PlotTable.from_columns(time=t, radar=[f"R{stream}"] * n, range_m=index.astype(float), azimuth_rad=np.zeros(n),
                                  altitude_m=np.zeros(n), mode_s=[None] * n, mode_3a=[None] * n, target=[None] * n)


def test_a_time_column_of_timestamps_is_read_as_seconds(csv_folder, tmp_path):
    copy = parquet_copy(csv_folder, tmp_path / "pq")
    t = pq.read_table(copy / "plots.parquet")
    us = np.round(t["time"].to_numpy() * 1e6).astype(np.int64)  # microseconds
    t = t.set_column(0, "time", pa.array(us, pa.int64()).cast(pa.timestamp("us", tz="UTC")))
    pq.write_table(t, copy / "plots.parquet")
    np.testing.assert_array_equal(read_scenario(copy).plots.time, us / 1e6)


def _damaged(csv_folder: Path, tmp_path: Path, change) -> Path:
    copy = parquet_copy(csv_folder, tmp_path / "pq")
    table = pq.read_table(copy / "plots.parquet")
    change(copy, table)
    return copy


def _set(copy: Path, table: pa.Table, column: str, values) -> None:
    pq.write_table(table.set_column(table.schema.get_field_index(column), column, values), copy / "plots.parquet")


BAD = {
    "not parquet": (lambda c, t: (c / "plots.parquet").write_bytes(b"time,radar\n1,R1\n"),
                    "plots.parquet: not a readable Parquet file"),
    "cut short": (lambda c, t: (c / "plots.parquet").write_bytes((c / "plots.parquet").read_bytes()[:-100]),
                  "plots.parquet: not a readable Parquet file"),
    "missing column": (lambda c, t: pq.write_table(t.drop(["azimuth_deg"]), c / "plots.parquet"),
                       "plots.parquet: missing column(s) azimuth_deg"),
    "wrong type": (lambda c, t: _set(c, t, "range_m", t["range_m"].cast(pa.string())),
                   "plots.parquet, field 'range_m': type string, expected a number"),
    "code as a number": (lambda c, t: _set(c, t, "mode_3a", pa.array(np.arange(len(t)))),
                         "plots.parquet, field 'mode_3a': type int64, expected text"),
    "bad value": (lambda c, t: _set(c, t, "azimuth_deg", pa.array([1.0] * 6 + [400.0] + [1.0] * (len(t) - 7))),
                  "plots.parquet row 7, field 'azimuth_deg': 400.0 outside [0, 360)"),
    "not finite": (lambda c, t: _set(c, t, "range_m", pa.array([1e5] * 4 + [math.inf] + [1e5] * (len(t) - 5))),
                   "plots.parquet row 5, field 'range_m': 'inf' is not finite"),
    "quoted text": (lambda c, t: _set(c, t, "radar", pa.array(t["radar"].to_pylist()[:2] + ['A,"1'] +
                                                              t["radar"].to_pylist()[3:])),
                    "plots.parquet row 3, field 'radar': unknown radar 'A,\"1'"),
    # a column name in the footer that is not UTF-8 (pyarrow decodes it in Python): found by the fuzzer
    "name not utf-8": (lambda c, t: (c / "plots.parquet").write_bytes(
                           (c / "plots.parquet").read_bytes().replace(b"range_m", b"range\xff\xfe")),
                       "plots.parquet: not a readable Parquet file"),
    "two tables": (lambda c, t: shutil.copy(c / "plots.parquet", c / "plots.csv"),
                   "plots.csv and plots.parquet are the same table 'plots': keep one"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_a_damaged_parquet_table_is_one_line_naming_file_and_field(csv_folder, tmp_path, capsys, case):
    change, words = BAD[case]
    copy = _damaged(csv_folder, tmp_path, change)
    with pytest.raises((FormatError, InputError)) as err:
        read_scenario(copy)
    assert words in str(err.value)
    assert main(["replay", str(copy), "--out", str(tmp_path / "out")]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and words in lines[0] and "Traceback" not in lines[0]


def test_a_bad_row_of_a_dataset_names_its_file_and_row(tmp_path):
    data = build_scenario("demo", seed=3, duration=120.0).run()
    write_scenario(tmp_path / "ds", data, format="dataset")
    path = tmp_path / "ds" / "plots" / "hour=0" / "radar=R2" / "part-0.parquet"
    t = pq.read_table(path)
    pq.write_table(t.set_column(1, "range_m", pa.array([1e5, 1e5, -3.0] + [1e5] * (len(t) - 3))), path)
    with pytest.raises(FormatError, match=r"^plots/hour=0/radar=R2/part-0.parquet row 3, field 'range_m': -3.0 is "
                                          r"negative$"):
        read_scenario(tmp_path / "ds")
    back = read_scenario(tmp_path / "ds", skip_bad=True)
    assert back.skipped == {"plots/hour=0/radar=R2/part-0.parquet:malformed": 1}
    assert len(back.plots) == len(data.plots) - 1


def test_written_scenario_tables_have_the_documented_schema(tmp_path):
    from tests.pipeline.test_outputs import documented

    write_scenario(tmp_path / "pq", build_scenario("demo", seed=3, duration=60.0).run(), format="parquet")
    doc = documented(0)
    for path in sorted((tmp_path / "pq").glob("*.parquet")):
        schema = pq.read_schema(path)
        assert {f.name: (str(f.type), f.metadata[b"unit"].decode()) for f in schema} == doc[path.stem], path.name
        assert json.loads(schema.metadata[b"radartracker"]) == {"table": path.stem, "version": 1}
    assert {p.stem for p in (tmp_path / "pq").glob("*.parquet")} == set(doc)
