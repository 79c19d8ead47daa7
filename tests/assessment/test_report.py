"""``radartracker assess`` end to end on the ``paris`` scenario: the report renders (every figure an embedded
PNG, every table filled), the tables and the JSON summary are written, and bad input is one line, exit 2."""

from __future__ import annotations

import base64
import json
from html.parser import HTMLParser
from pathlib import Path

import pyarrow.csv as pacsv
import pytest

from radartracker.cli import main


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
    assert len(page.images) == 2 + 2 * 4  # the two bias figures, and two rows of figures per radar
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
    assert main(["--quiet", "assess", str(scenario), "--out", str(tmp_path / "o"), "--profile", str(profile)]) == 0
    summary = json.loads((tmp_path / "o" / "assessment.json").read_text())
    assert summary["profile"]["name"] == "strict"
    assert {r["verdicts"]["range_sigma_m"] for r in summary["radars"].values()} == {"fail"}
    assert summary["system"]["verdicts"] == {}


def test_an_asterix_recording_is_judged_against_its_adsb(tmp_path, paris_assessment):
    """A CAT048/CAT021 recording has no truth: the reference is the validated ADS-B, and false plots and false
    tracks are said to be not assessable."""
    recording = tmp_path / "paris.ast"
    assert main(["asterix-export", str(paris_assessment.parent / "paris"), "--out", str(recording), "--quiet"]) == 0
    assert main(["--quiet", "assess", str(recording), "--out", str(tmp_path / "o")]) == 0
    summary = json.loads((tmp_path / "o" / "assessment.json").read_text())
    assert summary["reference"] == "adsb"
    for r in summary["radars"].values():
        assert "false_plots_per_scan" in r["not_assessable"]
        assert 0.8 < r["figures"]["pd"]["value"] < 1.0
    assert "false_tracks" not in summary["system"]["figures"]


def test_a_bad_plot_row_is_one_line_naming_file_line_and_field(tmp_path, capsys, paris_assessment):
    import shutil

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
