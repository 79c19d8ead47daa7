"""The three tables a run writes — tracks, events, biases — as typed Arrow tables (docs/formats.md).

One definition serves every form they take: the CSV files (each number as its text,
:mod:`radartracker.pipeline.writer`), the Parquet files (``replay --format parquet``: the same values as
typed columns, each field's unit in its metadata) and the DataFrames of
:meth:`~radartracker.pipeline.result.RunResult.tracks_frame` and its siblings. Every number is rounded to its
column's decimals (:data:`DECIMALS`), so that the three forms hold the same values; a value not known is a
null (an empty CSV field, NaN in a DataFrame).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.csv as pacsv
import pyarrow.parquet as pq

from radartracker.errors import FormatError, TableName
from radartracker.io.limits import regular_file
from radartracker.io.tables import table_metadata
from radartracker.pipeline.recorder import BiasLog, Events

TRACK_COLUMNS = ("time", "track", "lat", "lon", "x_m", "y_m", "vx_mps", "vy_mps", "sd_x_m", "sd_y_m", "altitude_m",
                 "sd_altitude_m", "mode_s", "mode_3a")
EVENT_COLUMNS = ("time", "track", "event", "status", "lat", "lon", "x_m", "y_m", "vx_mps", "vy_mps", "sd_x_m",
                 "sd_y_m", "altitude_m", "sd_altitude_m", "mode_s", "mode_3a")
BIAS_COLUMNS = ("time", "radar", "range_bias_m", "azimuth_bias_deg", "sd_range_m", "sd_azimuth_deg")
COLUMNS = {"tracks": TRACK_COLUMNS, "events": EVENT_COLUMNS, "biases": BIAS_COLUMNS}
# the decimals each number column is rounded to (docs/formats.md)
DECIMALS = {"time": 3, "lat": 8, "lon": 8, "x_m": 2, "y_m": 2, "vx_mps": 3, "vy_mps": 3, "sd_x_m": 2, "sd_y_m": 2,
            "altitude_m": 1, "sd_altitude_m": 1, "range_bias_m": 3, "azimuth_bias_deg": 6, "sd_range_m": 3, "sd_azimuth_deg": 6}
#: the unit of each number column (a Parquet field's ``unit`` metadata); the others are texts, ``track`` an integer
UNITS = {"time": "s", "lat": "deg", "lon": "deg", "x_m": "m", "y_m": "m", "vx_mps": "m/s", "vy_mps": "m/s",
         "sd_x_m": "m", "sd_y_m": "m", "altitude_m": "m", "sd_altitude_m": "m", "range_bias_m": "m", "azimuth_bias_deg": "deg",
         "sd_range_m": "m", "sd_azimuth_deg": "deg"}
_NO_TEXT = pa.scalar(None, pa.string())


def _type(column: str) -> pa.DataType:
    return pa.float64() if column in UNITS else pa.int64() if column == "track" else pa.string()


def output_schema(table: str) -> pa.Schema:
    """The Arrow schema of ``table`` (``tracks``, ``events`` or ``biases``): types, each field's unit in its
    metadata (``""`` for a text or the track id), the table's name in the schema's."""
    return pa.schema([pa.field(c, _type(c), metadata={"unit": UNITS.get(c, "")}) for c in COLUMNS[table]],
                     metadata=table_metadata(table))


def _numbers(x, column: str, *, optional: bool = False) -> pa.Array:
    """The column's numbers rounded to its decimals d (:data:`DECIMALS`; ``numpy.round``: rint(x·10^d) / 10^d,
    half to even, within an ulp of the decimal; x itself where x·10^d overflows, as it then has no digit
    below 10^-d); ``optional``: null (an empty field) where not finite, else written ``nan``, ``inf``."""
    x = np.asarray(x, float)
    with np.errstate(over="ignore", invalid="ignore"):
        r = np.round(x, DECIMALS[column])
    v = np.where(np.isinf(r), x, r)
    return pa.array(v, pa.float64(), mask=~np.isfinite(v) if optional else None)


def _texts(values) -> pa.Array:
    """Texts (``str`` or ``None`` each), null (an empty field) where ``None`` or empty."""
    a = pa.array(values, pa.string())
    return pc.if_else(pc.equal(a, ""), _NO_TEXT, a)


def event_tables(ev: Events, plane, *, text: bool = False) -> tuple[pa.Table, pa.Table]:
    """The rows of the events table and of the tracks table (the track estimates among them, without event and
    status) for ``ev``: typed (:func:`output_schema`), or (``text``, the CSV files) every number as its text,
    made once for both tables."""
    lat, lon = plane.to_geodetic(ev.state[:, 0], ev.state[:, 1])
    s = ev.state
    with np.errstate(invalid="ignore"):  # a negative variance: no standard deviation, an empty field
        sd_x, sd_y = np.sqrt(ev.cov[:, 0, 0]), np.sqrt(ev.cov[:, 1, 1])
    columns = [_numbers(ev.time, "time"), pa.array(ev.track, pa.int64()), _texts(ev.kind), _texts(ev.status),
               _numbers(lat, "lat"), _numbers(lon, "lon"), _numbers(s[:, 0], "x_m"), _numbers(s[:, 1], "y_m"),
               _numbers(s[:, 2], "vx_mps"), _numbers(s[:, 3], "vy_mps"), _numbers(sd_x, "sd_x_m", optional=True),
               _numbers(sd_y, "sd_y_m", optional=True), _numbers(ev.altitude_m, "altitude_m", optional=True),
               _numbers(ev.altitude_sd_m, "sd_altitude_m", optional=True),
               _texts(ev.mode_s), _texts(ev.mode_3a)]
    if text:
        columns = [c if pa.types.is_string(c.type) else pc.cast(c, pa.string()) for c in columns]
        events = pa.Table.from_arrays(columns, names=list(EVENT_COLUMNS))
    else:
        events = pa.Table.from_arrays(columns, schema=output_schema("events"))
    tracks = events.filter(pa.array(ev.estimate_mask(), pa.bool_())).select(list(TRACK_COLUMNS))
    return events, tracks if text else tracks.cast(output_schema("tracks"))


def bias_table(b: BiasLog) -> pa.Table:
    """The rows of the biases table for ``b``: Δr (m) and Δθ (degrees) with their standard deviations."""
    with np.errstate(invalid="ignore"):
        sd = np.sqrt(b.cov[:, [0, 1], [0, 1]])
    columns = [_numbers(b.time, "time"), _texts([str(r) for r in b.radar.tolist()]),
               _numbers(b.value[:, 0], "range_bias_m"), _numbers(np.degrees(b.value[:, 1]), "azimuth_bias_deg"),
               _numbers(sd[:, 0], "sd_range_m"), _numbers(np.degrees(sd[:, 1]), "sd_azimuth_deg")]
    return pa.Table.from_arrays(columns, schema=output_schema("biases"))


class ParquetSink:
    """One table written as a Parquet file piece by piece (a row group per piece), the schema's metadata
    included; :meth:`close` completes it."""

    def __init__(self, path: Path, table: str) -> None:
        self._writer = pq.ParquetWriter(path, output_schema(table))

    def write(self, table: pa.Table) -> None:
        if table.num_rows:
            self._writer.write_table(table)

    def close(self) -> None:
        self._writer.close()


def read_output(path: Path | str) -> pa.Table:
    """An output table a run wrote (``tracks``, ``events`` or ``biases``; ``.csv`` or ``.parquet``, chosen by the
    name) as a typed Arrow table of :func:`output_schema` (``.to_pandas()`` for a DataFrame): a code such as a
    Mode 3/A ``0741`` stays a text. An InputError names a file that is not such a table."""
    path = Path(path)
    table = path.stem
    if table not in COLUMNS or path.suffix not in (".csv", ".parquet"):
        raise FormatError(path.name, None, None, "not an output table (tracks, events or biases; .csv or .parquet)")
    schema = output_schema(table)
    try:
        if path.suffix == ".parquet":
            return pq.read_table(regular_file(path), columns=list(COLUMNS[table])).cast(schema)
        opts = pacsv.ConvertOptions(column_types=schema, include_columns=list(COLUMNS[table]), null_values=[""],
                                    strings_can_be_null=True)  # "NA" is a radar's id, "nan" a number
        return pacsv.read_csv(regular_file(path), convert_options=opts).cast(schema)
    except (pa.ArrowException, ValueError, KeyError) as exc:  # a column missing or of another type
        raise FormatError(TableName(path.name), None, None, f"not a {table} table as a run writes it ({exc})") from None
