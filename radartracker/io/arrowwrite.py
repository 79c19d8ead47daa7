"""A scenario's tables as one set of Arrow tables, written as CSV files or as Parquet: one file per table, or
plots and ADS-B reports as datasets partitioned by hour (and radar) (:mod:`radartracker.io.datasets`).

The columns and units are those of the CSV files (degrees at the edge, :data:`~radartracker.io.tables.SCHEMAS`),
each number the double itself (no decimals to round to), a value not known a null; every field carries its
unit in its metadata (``unit``) and the schema names its table (:func:`~radartracker.io.tables.table_metadata`), as
:func:`table_schema` makes them (docs/formats.md, "Parquet").
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv
import pyarrow.parquet as pq

from radartracker.io.datasets import PARTITIONS, ROWS_PER_GROUP, write_partitioned
from radartracker.io.tables import SCHEMAS, ScenarioData, table_metadata

_PLAIN = pacsv.WriteOptions(include_header=False, quoting_style="none")
_QUOTED = pacsv.WriteOptions(include_header=False, quoting_style="needed")


def _write_csv(table: pa.Table, path: Path) -> None:
    """``table`` as a CSV file: its header, then its rows with bare fields, or quoted texts when one holds a
    comma or a quote (pyarrow refuses those bare)."""
    with open(path, "wb") as f:
        f.write((",".join(table.column_names) + "\n").encode())
        try:
            pacsv.write_csv(table, f, _PLAIN)
        except pa.ArrowInvalid:
            f.seek(0)
            f.truncate()
            f.write((",".join(table.column_names) + "\n").encode())
            pacsv.write_csv(table, f, _QUOTED)


def table_schema(name: str, columns: list[str] | None = None) -> pa.Schema:
    """The Arrow schema of the scenario table ``name`` (the given ``columns`` of it, in its order): types, each
    field's unit in its metadata, the table's name in the schema's."""
    fields = [pa.field(c.name, c.type, metadata={"unit": c.unit}) for c in SCHEMAS[name]
              if columns is None or c.name in columns]
    return pa.schema(fields, metadata=table_metadata(name))


def _numbers(x: np.ndarray) -> pa.Array:
    """Floats, null where not a number (a value not known)."""
    x = np.asarray(x, float)
    return pa.array(x, pa.float64(), mask=np.isnan(x))


def _azimuth_deg(rad: np.ndarray) -> np.ndarray:
    """Radians as degrees in [0, 360) (a tiny negative angle would give 360 itself: 0)."""
    deg = np.mod(np.degrees(rad), 360.0)
    return np.where(deg >= 360.0, 0.0, deg)


def _table(name: str, columns: dict[str, object]) -> pa.Table:
    schema = table_schema(name, list(columns))
    arrays = [v if isinstance(v := columns[f.name], pa.Array) else pa.array(v, f.type) for f in schema]
    return pa.Table.from_arrays(arrays, schema=schema)


def scenario_tables(data: ScenarioData) -> dict[str, pa.Table]:
    """``data``'s tables in their file units (``truth`` and ``truth_biases`` only when ``data`` has them; a
    plots ``target`` column only when a plot carries a label, as the CSV files)."""
    r = data.radars
    out = {"radars": _table("radars", {
        "radar": [x.id for x in r], "lat": [x.lat for x in r], "lon": [x.lon for x in r],
        "height_m": [x.height_m for x in r], "sigma_range_m": [x.sigma_range_m for x in r],
        "sigma_azimuth_deg": np.degrees([x.sigma_azimuth_rad for x in r]), "period_s": [x.period_s for x in r],
        "max_range_m": [x.max_range_m for x in r]})}
    p = data.plots
    plots = {"time": p.time, "radar": p.radar, "range_m": p.range_m, "azimuth_deg": _azimuth_deg(p.azimuth_rad),
             "altitude_m": _numbers(p.altitude_m), "mode_s": p.mode_s, "mode_3a": p.mode_3a}
    if any(t is not None for t in p.target):
        plots["target"] = p.target
    out["plots"] = _table("plots", plots)
    a = data.adsb
    out["adsb"] = _table("adsb", {"time": a.time, "icao24": a.icao24, "lat": a.lat, "lon": a.lon,
                                  "altitude_m": _numbers(a.altitude_m), "nacp": a.nacp})
    if data.truth is not None:
        t = data.truth
        out["truth"] = _table("truth", {"time": t.time, "target": t.target, "lat": t.lat, "lon": t.lon,
                                        "altitude_m": t.altitude_m})
    if data.truth_biases is not None:
        b = data.truth_biases
        cols = {"radar": list(b), "range_bias_m": [v[0] for v in b.values()],
                "azimuth_bias_deg": np.degrees([v[1] for v in b.values()])}
        if data.truth_sensor:  # the further components only where a scenario has them
            cols["range_gain"] = [data.truth_sensor.get(r, {}).get("range_gain", 0.0) for r in b]
            cols["time_offset_s"] = [data.truth_sensor.get(r, {}).get("time_offset", 0.0) for r in b]
        out["truth_biases"] = _table("truth_biases", cols)
    return out


def write_tables(folder: Path, data: ScenarioData, table_format: str = "parquet") -> None:
    """Write ``data``'s tables into ``folder`` as ``NAME.csv`` (``table_format`` csv: pyarrow's CSV writer, each
    number the shortest text that reads back as its double, a null an empty field, a text quoted where it
    holds a comma or a quote), as ``NAME.parquet`` (parquet), or (dataset) as Parquet with plots and ADS-B
    reports as the datasets ``plots/`` (by hour and radar) and ``adsb/`` (by hour)."""
    for name, table in scenario_tables(data).items():
        if table_format == "csv":
            _write_csv(table, folder / f"{name}.csv")
        elif table_format == "dataset" and name in PARTITIONS:
            write_partitioned(table, folder / name, PARTITIONS[name])
        else:
            pq.write_table(table, folder / f"{name}.parquet", row_group_size=ROWS_PER_GROUP)
