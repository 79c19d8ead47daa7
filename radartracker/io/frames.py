"""A scenario built from pandas DataFrames (or Arrow tables) holding the scenario files' columns and units.

Each DataFrame becomes an Arrow table (``pyarrow.Table.from_pandas``) read by the readers of the files
(:func:`radartracker.io.scenario.read_tables`, through :mod:`radartracker.io.arrowsource`): the same columns
(docs/formats.md: degrees, metres, seconds; any column order, other columns ignored), the same checks,
and errors naming the table and its row counted from 1 (``plots (DataFrame) row 7, field 'range_m': …``).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import pyarrow as pa

from radartracker.domain import Aircraft
from radartracker.errors import FormatError, InputError, TableName
from radartracker.io.arrowsource import ArrowSource, table_source
from radartracker.io.scenario import read_tables
from radartracker.io.tables import ScenarioData

if TYPE_CHECKING:
    import pandas as pd


def _source(frame: pd.DataFrame | pa.Table, table: str) -> ArrowSource:
    name = f"{table} (DataFrame)" if not isinstance(frame, pa.Table) else f"{table} (Arrow table)"
    if isinstance(frame, pa.Table):
        return table_source(frame, name)
    try:
        return table_source(pa.Table.from_pandas(frame, preserve_index=False), name)
    except (pa.ArrowException, TypeError, ValueError) as exc:  # e.g. a column of numbers and texts mixed
        raise FormatError(TableName(name), None, None, f"cannot be made an Arrow table ({exc})") from None


def scenario_from_frames(radars: pd.DataFrame | pa.Table, plots: pd.DataFrame | pa.Table, *,
                         adsb: pd.DataFrame | pa.Table | None = None, truth: pd.DataFrame | pa.Table | None = None,
                         truth_biases: pd.DataFrame | pa.Table | None = None,
                         reference: tuple[float, float] | None = None, aircraft: list[Aircraft] | None = None,
                         name: str = "frames", skip_bad: bool = False) -> ScenarioData:
    """A checked :class:`ScenarioData` from DataFrames holding the columns of ``radars.csv``, ``plots.csv`` and,
    optionally, ``adsb.csv``, ``truth.csv`` and ``truth_biases.csv`` (docs/formats.md); ``reference`` (lat, lon
    in degrees) as ``scenario.json``'s (default: the centroid of the radar sites), ``aircraft`` its identities.
    A bad row is a :class:`FormatError` naming the table, row and field, or with ``skip_bad`` is counted."""
    if reference is not None:
        lat, lon = (float(v) for v in reference)
        if not (math.isfinite(lat) and math.isfinite(lon) and -90 <= lat <= 90 and -180 <= lon <= 180):
            raise InputError(f"reference {reference!r}: a latitude in [-90, 90] and a longitude in [-180, 180]")
    frames = {"radars": radars, "plots": plots, "adsb": adsb, "truth": truth, "truth_biases": truth_biases}
    tables = {k: _source(f, k) if f is not None else None for k, f in frames.items()}
    meta = {"name": name, "aircraft": list(aircraft or [])} | ({"reference": (lat, lon)} if reference else {})
    return read_tables(tables, meta, name, skip_bad=skip_bad)
