"""The files of an assessment (docs/assessment.md, "What it writes"): ``report.html``, ``indicators.csv``
(every figure with its interval), ``verdicts.csv`` (each figure against its criterion), ``pd_bins.csv`` (Pd by
range, azimuth and altitude bin), each table also as Parquet (``indicators.parquet``, ...), and
``assessment.json``; every file atomically, all replacing an earlier run's together (a run that fails keeps
the earlier run's files).

Each table is made once as a typed Arrow table (:data:`TABLES`: a figure or bound float64, a count int64, a
text string; a value not known, NaN, a null) and written by pyarrow twice: as CSV (a null an empty field) and
as Parquet (the schema's metadata names the table, as the replay's Parquet outputs do). Both are written every
run: the tables are small (tens to hundreds of rows), so a second form costs nothing, and a script finds the
same files after every run.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import pyarrow as pa
import pyarrow.csv as pacsv
import pyarrow.parquet as pq

from radartracker.assessment.assess import Assessment
from radartracker.assessment.report import render
from radartracker.io.atomic import replace_outputs
from radartracker.io.tables import table_metadata

_F, _I, _S = pa.float64(), pa.int64(), pa.string()
#: each table's columns in order, with their Arrow types
TABLES: dict[str, tuple[tuple[str, pa.DataType], ...]] = {
    "indicators": (("radar", _S), ("indicator", _S), ("value", _F), ("ci_low", _F), ("ci_high", _F), ("n", _I),
                   ("method", _S), ("reference", _S), ("note", _S)),
    "verdicts": (("radar", _S), ("indicator", _S), ("value", _F), ("ci_low", _F), ("ci_high", _F), ("rule", _S),
                 ("verdict", _S), ("standard", _S), ("note", _S)),
    "pd_bins": (("radar", _S), ("variable", _S), ("bin_low", _F), ("bin_high", _F), ("crossings", _I),
                ("detected", _I), ("pd", _F), ("ci_low", _F), ("ci_high", _F)),
}
ASSESSMENT_FILES = ("report.html", *(f"{t}.{ext}" for t in TABLES for ext in ("csv", "parquet")),
                    "assessment.json")
_CSV = pacsv.WriteOptions(quoting_style="needed")


def schema(name: str) -> pa.Schema:
    """The Arrow schema of table ``name`` of :data:`TABLES`, its name and format version in the metadata."""
    return pa.schema([pa.field(c, t) for c, t in TABLES[name]], metadata=table_metadata(name))


def typed_table(name: str, rows: list[dict]) -> pa.Table:
    """``rows`` (dicts holding at least the table's columns) as table ``name`` of :data:`schema`; a NaN float
    (a figure without a value) becomes a null, ±∞ (an unbounded interval) stays."""
    def cell(v: object) -> object:
        return None if isinstance(v, float) and math.isnan(v) else v

    s = schema(name)
    return pa.Table.from_pylist([{c: cell(r[c]) for c in s.names} for r in rows], schema=s)


def write_assessment(a: Assessment, out: Path, *, progress: bool = True) -> None:
    """Every file of :data:`ASSESSMENT_FILES` into the prepared folder ``out``; ``assessment.json`` last."""
    tables = {"indicators": a.indicator_rows(), "verdicts": a.verdicts(),
              "pd_bins": [{"radar": r.radar, **b} for r in a.radars for b in r.pd_bins]}
    with replace_outputs(out, ASSESSMENT_FILES, last="assessment.json") as stage:
        for name, rows in tables.items():
            table = typed_table(name, rows)
            pacsv.write_csv(table, stage(f"{name}.csv"), _CSV)
            pq.write_table(table, stage(f"{name}.parquet"))
        stage("report.html").write_text(render(a, progress=progress), encoding="utf-8")
        stage("assessment.json").write_text(json.dumps(a.summary(), indent=1, allow_nan=False) + "\n",
                                            encoding="utf-8")
