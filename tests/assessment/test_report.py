"""``radartracker assess`` end to end on the ``paris`` scenario: the report renders (every figure an embedded
PNG, every table filled), the tables (CSV and Parquet, the same) and the JSON summary are written, an
``--overwrite`` replaces them all, and bad input is one line, exit 2."""

from __future__ import annotations

import base64
import json
import math
import shutil
from html.parser import HTMLParser
from pathlib import Path

import pyarrow as pa
import pyarrow.csv as pacsv
import pyarrow.parquet as pq
import pytest

from radartracker.assessment.writer import ASSESSMENT_FILES
from radartracker.cli import main

#: the columns of each table and their Arrow types, as docs/assessment.md states them
STATED = {"indicators": [("radar", "string"), ("indicator", "string"), ("value", "double"), ("ci_low", "double"),
                         ("ci_high", "double"), ("n", "int64"), ("method", "string"), ("reference", "string"),
                         ("note", "string")],
          "verdicts": [("radar", "string"), ("indicator", "string"), ("value", "double"), ("ci_low", "double"),
                       ("ci_high", "double"), ("rule", "string"), ("verdict", "string"), ("standard", "string"),
                       ("note", "string")],
          "pd_bins": [("radar", "string"), ("variable", "string"), ("bin_low", "double"), ("bin_high", "double"),
                      ("crossings", "int64"), ("detected", "int64"), ("pd", "double"), ("ci_low", "double"),
                      ("ci_high", "double")]}


class _Page(HTMLParser):
    """The images' sources and each table's rows of cells."""

    def __init__(self) -> None:
        super().__init__()
        self.images: list[str] = []
        self.tables: list[list[list[str]]] = []
        self._cell: list[str] | None = None

    def handle_starttag(self, tag, attrs):
        if tag == "img":
            self.images.append(dict(attrs)["src"])
        elif tag == "table":
            self.tables.append([])
        elif tag == "tr":
            self.tables[-1].append([])
        elif tag in ("td", "th"):
            self._cell = []

    def handle_endtag(self, tag):
        if tag in ("td", "th"):
            self.tables[-1][-1].append("".join(self._cell).strip())
            self._cell = None

    def handle_data(self, data):
        if self._cell is not None:
            self._cell.append(data)


@pytest.fixture(scope="module")
def paris_assessment(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("assess")
    assert main(["--quiet", "simulate", str(root / "paris"), "--scenario", "paris", "--duration", "300"]) == 0
    assert main(["--quiet", "assess", str(root / "paris"), "--out", str(root / "out")]) == 0
    return root / "out"


def test_report_renders_every_figure_and_table(paris_assessment):
    page = _Page()
    page.feed((paris_assessment / "report.html").read_text(encoding="utf-8"))
    assert len(page.images) == 2 + 3 * 4  # the two bias figures, and three figures per radar: two rows, the scatter
    for src in page.images:
        assert src.startswith("data:image/png;base64,")
        png = base64.b64decode(src.split(",", 1)[1])
        assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 5000
    assert len(page.tables) == 1 + 4 + 1  # verdicts, one per radar, the system tracks
    for table in page.tables:
        assert len(table) > 1 and all(len(row) == len(table[0]) for row in table)
        assert all(cell for row in table for cell in row)
    verdicts = {row[5] for row in page.tables[0][1:]}
    assert verdicts <= {"pass", "fail", "inconclusive", "not assessed"} and "pass" in verdicts


def test_tables_and_summary(paris_assessment):
    summary = json.loads((paris_assessment / "assessment.json").read_text())
    assert summary["reference"] == "truth" and set(summary["radars"]) == {"ORLY", "CDG", "EVREUX", "REIMS"}
    truth = {"ORLY": 90.0, "CDG": -60.0, "EVREUX": 150.0, "REIMS": -110.0}
    for rid, r in summary["radars"].items():
        e = r["figures"]["range_bias_m"]
        assert e["ci_low"] - 5 < truth[rid] < e["ci_high"] + 5
        assert r["observability"] == "anchored"
    assert summary["radars"]["EVREUX"]["verdicts"]["range_bias_m"] == "fail"  # 150 m against < 100 m
    indicators = pacsv.read_csv(paris_assessment / "indicators.csv").to_pylist()
    assert {"radar", "indicator", "value", "ci_low", "ci_high", "method", "reference"} <= set(indicators[0])
    pd_bins = pacsv.read_csv(paris_assessment / "pd_bins.csv").to_pylist()
    assert {b["variable"] for b in pd_bins} == {"range_km", "azimuth_deg", "altitude_m", "elevation_deg"}
    for r in summary["radars"].values():  # four radars 250 km out, traffic to their edges: all judged
        assert len(r["coverage"]) == 12 and 0.0 < r["figures"]["detection_range_km"]["value"] <= 250.0
        assert "cone_of_silence_deg" in r["figures"] or "cone_of_silence_deg" in r["not_assessable"]
    assert all(0 <= b["ci_low"] <= b["pd"] <= b["ci_high"] <= 1 for b in pd_bins)


def test_the_parquet_tables_are_the_csv_tables_typed(paris_assessment):
    """Each table's Parquet file holds the stated types and, cell for cell, what its CSV file reads back as (a
    figure without a value a null in both; numbers within a float's round trip)."""
    assert sorted(p.name for p in paris_assessment.iterdir()) == sorted(ASSESSMENT_FILES)
    for name, columns in STATED.items():
        parquet = pq.read_table(paris_assessment / f"{name}.parquet")
        assert [(f.name, str(f.type)) for f in parquet.schema] == columns
        types = {c: pa.type_for_alias(t) for c, t in columns}
        csv = pacsv.read_csv(paris_assessment / f"{name}.csv", convert_options=pacsv.ConvertOptions(column_types=types))
        assert csv.column_names == parquet.column_names and csv.num_rows == parquet.num_rows > 0
        for column, kind in columns:
            ours, theirs = parquet.column(column).to_pylist(), csv.column(column).to_pylist()
            if kind == "double":
                assert all(a is None and b is None or a == pytest.approx(b, rel=1e-15) or a == b
                           for a, b in zip(ours, theirs)), column
            else:
                assert ours == theirs, column
    indicators = pq.read_table(paris_assessment / "indicators.parquet").to_pylist()
    missing = [r for r in indicators if r["note"].startswith("not assessable")]
    assert missing and all(r["value"] is None and r["n"] == 0 for r in missing)
    assert any(r["ci_high"] == math.inf for r in indicators)  # an unbounded interval stays ∞, not a null


def test_a_bad_profile_is_one_line_naming_file_line_and_field(tmp_path, capsys, paris_assessment):
    profile = tmp_path / "p.toml"
    profile.write_text('name = "mine"\n\n[[criteria]]\nindicator = "pd"\nrule = "above"\nthreshold = "high"\n'
                       'radar_kind = "any"\nstandard = "ours"\n')
    assert main(["assess", str(tmp_path / "none"), "--out", str(tmp_path / "o"), "--profile", str(profile)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and f"{profile}: line 6: criteria[0].threshold" in err
    assert not (tmp_path / "o").exists()


def test_a_replaced_profile_judges_by_its_own_figures(tmp_path, paris_assessment):
    profile = tmp_path / "strict.json"
    profile.write_text(json.dumps({"name": "strict", "criteria": [
        {"indicator": "range_sigma_m", "rule": "below", "threshold": 10.0, "radar_kind": "any",
         "standard": "a test's"}]}))
    scenario = paris_assessment.parent / "paris"
    shutil.copytree(paris_assessment, tmp_path / "o")  # an earlier run's files, replaced by --overwrite
    assert main(["--quiet", "assess", str(scenario), "--out", str(tmp_path / "o"), "--profile", str(profile),
                 "--overwrite"]) == 0
    summary = json.loads((tmp_path / "o" / "assessment.json").read_text())
    assert summary["profile"]["name"] == "strict"
    for ext in ("csv", "parquet"):  # both forms of the table are this run's
        rows = (pq.read_table if ext == "parquet" else pacsv.read_csv)(tmp_path / "o" / f"verdicts.{ext}").to_pylist()
        assert {r["indicator"] for r in rows} == {"range_sigma_m"} and len(rows) == 4
    assert {r["verdicts"]["range_sigma_m"] for r in summary["radars"].values()} == {"fail"}
    assert summary["system"]["verdicts"] == {}


def test_an_asterix_recording_is_judged_against_its_adsb(tmp_path, paris_assessment):
    """A CAT048/CAT021 recording has no truth: the reference is the validated ADS-B and the other aircraft
    reconstructed (the default), and false plots and false tracks are said to be not assessable."""
    recording = tmp_path / "paris.ast"
    assert main(["asterix-export", str(paris_assessment.parent / "paris"), "--out", str(recording), "--quiet"]) == 0
    assert main(["--quiet", "assess", str(recording), "--out", str(tmp_path / "o")]) == 0
    summary = json.loads((tmp_path / "o" / "assessment.json").read_text())
    assert summary["reference"] == "adsb+reconstruction" and summary["reference_left_out"] == {}
    for r in summary["radars"].values():
        assert "false_plots_per_scan" in r["not_assessable"]
        assert 0.8 < r["figures"]["pd"]["value"] < 1.0
    assert "false_tracks" not in summary["system"]["figures"]


def test_a_bad_plot_row_is_one_line_naming_file_line_and_field(tmp_path, capsys, paris_assessment):
    scenario = tmp_path / "bad"
    shutil.copytree(paris_assessment.parent / "paris", scenario)
    lines = (scenario / "plots.csv").read_text().splitlines()
    fields = lines[5].split(",")
    fields[2] = "far"  # range_m
    lines[5] = ",".join(fields)
    (scenario / "plots.csv").write_text("\n".join(lines) + "\n")
    assert main(["assess", str(scenario), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "plots.csv" in err and "line 6" in err and "range_m" in err, err
    assert not (tmp_path / "o").exists()
