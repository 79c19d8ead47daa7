"""The run's tables as Parquet files and DataFrames: the schema documented in docs/formats.md (types, units in
the metadata), read back with pyarrow and pandas, holding the values of the CSV files of the same run."""

from __future__ import annotations

import csv
import json
import math
import re
from pathlib import Path

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from radartracker.cli import main
from radartracker.errors import ConfigurationError, InputError
from radartracker.io.scenario import write_scenario
from radartracker.io.sources import read_source
from radartracker.pipeline.config import RunConfig
from radartracker.pipeline.outputs import read_output
from radartracker.pipeline.run import replay_folder, run
from radartracker.pipeline.writer import prepare, write_outputs
from radartracker.simulation.scenarios import build_scenario

ROOT = Path(__file__).resolve().parents[2]
TABLES = ("tracks", "events", "biases")


def documented(kind: int) -> dict[str, dict[str, tuple[str, str]]]:
    """docs/formats.md's schema table number ``kind`` (0: scenario tables, 1: replay outputs) as
    table → column → (Arrow type, unit)."""
    text = (ROOT / "docs" / "formats.md").read_text(encoding="utf-8")
    header = "| column | Arrow type | `unit` | tables |\n| --- | --- | --- | --- |\n"
    body = text.split(header)[kind + 1].split("\n\n")[0]
    out: dict[str, dict[str, tuple[str, str]]] = {}
    for line in body.splitlines():
        cols, typ, unit, tables = (c.strip() for c in line.strip("|").split("|"))
        for table in (t.strip() for t in tables.split(",")):
            for col in re.findall(r"`(\w+)`", cols):
                out.setdefault(table, {})[col] = (typ, unit)
    return out


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """One scenario replayed twice with the same settings: tables as CSV, and as Parquet."""
    d = tmp_path_factory.mktemp("outputs")
    write_scenario(d / "scen", build_scenario("tracking", seed=4, duration=240.0).run())
    for fmt in ("csv", "parquet"):
        assert main(["--quiet", "replay", str(d / "scen"), "--manager", "--estimator", "decoupled", "--out",
                     str(d / fmt), "--format", fmt]) == 0
    return d


@pytest.mark.parametrize("table", TABLES)
def test_parquet_outputs_have_the_documented_schema(runs, table):
    schema = pq.read_schema(runs / "parquet" / f"{table}.parquet")
    with open(runs / "csv" / f"{table}.csv", encoding="utf-8") as f:
        header = next(csv.reader(f))
    assert schema.names == header  # the CSV file's columns, in its order
    doc = documented(1)[table]
    assert {f.name: (str(f.type), f.metadata[b"unit"].decode()) for f in schema} == doc
    assert json.loads(schema.metadata[b"radartracker"]) == {"table": table, "version": 1}
    assert not list((runs / "parquet").glob("*.csv"))


@pytest.mark.parametrize("table", TABLES)
def test_parquet_outputs_hold_the_values_of_the_csv_files(runs, table):
    with open(runs / "csv" / f"{table}.csv", newline="", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    frame = pd.read_parquet(runs / "parquet" / f"{table}.parquet")
    assert len(frame) == len(rows) > 10
    for name in frame.columns:
        got = frame[name].tolist()
        if documented(1)[table][name][0] == "string":
            want = [r[name] or None for r in rows]
            assert [None if v is None or v is pd.NA or (isinstance(v, float) and math.isnan(v)) else v
                    for v in got] == want, name
        else:
            want = [float(r[name]) if r[name] else math.nan for r in rows]
            assert all(a == b or (math.isnan(a) and math.isnan(b)) for a, b in zip(got, want)), name
    assert str(frame["time"].dtype) == "float64" and (table == "biases" or str(frame["track"].dtype) == "int64")


def test_read_output_keeps_codes_as_texts_in_either_format(runs):
    a = read_output(runs / "csv" / "tracks.csv")
    b = read_output(runs / "parquet" / "tracks.parquet")
    assert a.equals(b)
    with open(runs / "csv" / "tracks.csv", newline="", encoding="utf-8") as f:
        codes = {r["mode_3a"] for r in csv.DictReader(f)} - {""}
    assert codes and set(a.column("mode_3a").drop_null().to_pylist()) == codes  # "7000", "2345" as written


def test_an_overwritten_run_keeps_only_the_new_format(runs, tmp_path):
    out = tmp_path / "out"
    for fmt in ("csv", "parquet"):
        assert main(["--quiet", "replay", str(runs / "scen"), "--manager", "--estimator", "decoupled", "--out",
                     str(out), "--format", fmt, "--overwrite"]) == 0
    assert sorted(p.name for p in out.glob("*s.*")) == ["biases.parquet", "events.parquet", "tracks.parquet"]


def test_run_result_frames_are_the_tables_it_writes(runs, tmp_path):
    data = read_source(runs / "scen")
    result = run(data, RunConfig(association="manager", estimator="decoupled"), progress=False)
    write_outputs(result, prepare(tmp_path / "out"))
    for table, frame in (("tracks", result.tracks_frame()), ("events", result.events_frame()),
                         ("biases", result.biases_frame())):
        with open(tmp_path / "out" / f"{table}.csv", newline="", encoding="utf-8") as f:
            rows = list(csv.DictReader(f))
        assert list(frame.columns) == list(rows[0]) and len(frame) == len(rows) > 10
        assert frame["time"].tolist() == [float(r["time"]) for r in rows]
    assert set(result.events_frame()["event"]) >= {"created", "confirmed", "updated", "deleted"}


def test_a_streamed_run_without_truth_points_to_its_files(runs, tmp_path):
    result = replay_folder(runs / "scen", RunConfig(association="manager", estimator="decoupled"),
                           prepare(tmp_path / "out"), progress=False, table_format="parquet")
    assert result.streamed and result.data.truth is not None  # truth: the events were kept for the evaluation
    assert len(result.tracks_frame()) == pq.read_metadata(tmp_path / "out" / "tracks.parquet").num_rows
    result.data.truth = None
    with pytest.raises(ConfigurationError, match="read_output"):
        result.tracks_frame()


def test_a_table_that_is_not_an_output_is_named(tmp_path):
    pq.write_table(pa.table({"time": [1.0]}), tmp_path / "tracks.parquet")
    with pytest.raises(InputError, match="tracks.parquet: not a tracks table"):
        read_output(tmp_path / "tracks.parquet")
