"""The files of an assessment (docs/assessment.md, "What it writes"): ``report.html``, ``indicators.csv``
(every figure with its interval), ``verdicts.csv`` (each figure against its criterion), ``pd_bins.csv`` (Pd by
range, azimuth and altitude bin) and ``assessment.json``; the tables written by pyarrow's CSV writer, every file
atomically (a run that fails keeps an earlier run's files)."""

from __future__ import annotations

import json
from pathlib import Path

import pyarrow as pa
import pyarrow.csv as pacsv

from radartracker.assessment.assess import Assessment
from radartracker.assessment.report import render
from radartracker.io.atomic import replace_outputs

ASSESSMENT_FILES = ("report.html", "indicators.csv", "verdicts.csv", "pd_bins.csv", "assessment.json")
_CSV = pacsv.WriteOptions(quoting_style="needed")


def _csv(rows: list[dict], columns: list[str], path: Path) -> None:
    """``rows`` (dicts) as a CSV file of ``columns`` in that order; an empty table keeps its header."""
    table = pa.table({c: [r[c] for r in rows] for c in columns}) if rows else pa.table({c: pa.array([], pa.string())
                                                                                          for c in columns})
    pacsv.write_csv(table, path, _CSV)


def write_assessment(a: Assessment, out: Path, *, progress: bool = True) -> None:
    """Every file of :data:`ASSESSMENT_FILES` into the prepared folder ``out``; ``assessment.json`` last."""
    with replace_outputs(out, ASSESSMENT_FILES, last="assessment.json") as stage:
        _csv(a.indicator_rows(), ["radar", "indicator", "value", "ci_low", "ci_high", "n", "method", "reference",
                                  "note"], stage("indicators.csv"))
        _csv(a.verdicts(), ["radar", "indicator", "value", "ci_low", "ci_high", "rule", "verdict", "standard", "note"],
             stage("verdicts.csv"))
        _csv([{"radar": r.radar, **b} for r in a.radars for b in r.pd_bins],
             ["radar", "variable", "bin_low", "bin_high", "crossings", "detected", "pd", "ci_low", "ci_high"],
             stage("pd_bins.csv"))
        stage("report.html").write_text(render(a, progress=progress), encoding="utf-8")
        stage("assessment.json").write_text(json.dumps(a.summary(), indent=1, allow_nan=False) + "\n",
                                            encoding="utf-8")
