"""Input tables as columns (SI units): plots, ADS-B reports, truth, and a whole scenario."""

from __future__ import annotations

import json
from collections.abc import Iterable
from typing import Any

import attrs
import numpy as np
import pyarrow as pa

from radartracker.domain import Aircraft, Radar


def concat_tables(tables: list) -> Any:
    """The rows of ``tables`` (attrs tables of one class: columns as arrays) one after the other, as one table."""
    cls = type(tables[0])
    return cls(**{f.name: np.concatenate([getattr(t, f.name) for t in tables]) for f in attrs.fields(cls)})


@attrs.frozen
class Column:
    """A column of a scenario table (docs/formats.md): its Arrow ``type`` as written to Parquet (a reader takes
    any integer or floating type for a number, any string type for a text) and the ``unit`` of its numbers
    ("" for a text), which a Parquet file carries in the field's metadata."""

    name: str
    type: pa.DataType
    unit: str = ""


def _numbers(unit: str, *names: str) -> tuple[Column, ...]:
    return tuple(Column(n, pa.float64(), unit) for n in names)


_TEXT = pa.string()
#: every scenario table's columns, in the order written; plots' ``target`` is optional
SCHEMAS: dict[str, tuple[Column, ...]] = {
    "radars": (Column("radar", _TEXT), *_numbers("deg", "lat", "lon"), *_numbers("m", "height_m", "sigma_range_m"),
               *_numbers("deg", "sigma_azimuth_deg"), *_numbers("s", "period_s"), *_numbers("m", "max_range_m")),
    "plots": (*_numbers("s", "time"), Column("radar", _TEXT), *_numbers("m", "range_m"),
              *_numbers("deg", "azimuth_deg"), *_numbers("m", "altitude_m"), Column("mode_s", _TEXT),
              Column("mode_3a", _TEXT), Column("target", _TEXT)),
    "adsb": (*_numbers("s", "time"), Column("icao24", _TEXT), *_numbers("deg", "lat", "lon"),
             *_numbers("m", "altitude_m"), Column("nacp", pa.int64())),
    "truth": (*_numbers("s", "time"), Column("target", _TEXT), *_numbers("deg", "lat", "lon"),
              *_numbers("m", "altitude_m")),
    "truth_biases": (Column("radar", _TEXT), *_numbers("m", "range_bias_m"), *_numbers("deg", "azimuth_bias_deg"),
                     *_numbers("1", "range_gain"), *_numbers("s", "time_offset_s")),
}
OPTIONAL_COLUMNS = {"plots": ("target",), "truth_biases": ("range_gain", "time_offset_s")}


def required_columns(table: str) -> tuple[str, ...]:
    """The names of the columns ``table`` (a key of :data:`SCHEMAS`) must have."""
    return tuple(c.name for c in SCHEMAS[table] if c.name not in OPTIONAL_COLUMNS.get(table, ()))


RADAR_COLUMNS, PLOT_COLUMNS, ADSB_COLUMNS = (required_columns(t) for t in ("radars", "plots", "adsb"))
TRUTH_COLUMNS, BIAS_COLUMNS = required_columns("truth"), required_columns("truth_biases")


FORMAT_VERSION = 1  # of the Parquet tables' metadata (docs/formats.md)


def table_metadata(table: str) -> dict[bytes, bytes]:
    """The schema metadata of a table radartracker writes as Parquet: key ``radartracker``, a JSON object
    naming the table and the version of its format (as pandas keeps its own under ``pandas``)."""
    return {b"radartracker": json.dumps({"table": table, "version": FORMAT_VERSION}).encode()}


def _obj(values: Iterable[Any]) -> np.ndarray:
    arr = np.empty(len(values := list(values)), dtype=object)
    arr[:] = values
    return arr


@attrs.define
class PlotTable:
    """Radar plots as columns (SI units; ``altitude_m`` NaN and codes ``None`` where absent).

    ``received``: when each plot was delivered (s, the clock of ``time``), NaN where the recording does not
    say; a pcap capture says (its packets' time stamps), the scenario formats do not. The assessment's
    time-stamp lateness is ``received − time``.
    """

    time: np.ndarray
    radar: np.ndarray
    range_m: np.ndarray
    azimuth_rad: np.ndarray
    altitude_m: np.ndarray
    mode_s: np.ndarray
    mode_3a: np.ndarray
    target: np.ndarray
    received: np.ndarray = attrs.field(
        default=attrs.Factory(lambda self: np.full(len(self.time), np.nan), takes_self=True))

    @classmethod
    def from_columns(cls, **cols: Iterable[Any]) -> PlotTable:
        """The table of the named columns; ``received`` is optional (the field's default: not known)."""
        return cls(
            time=np.asarray(cols["time"], float), radar=_obj(cols["radar"]),
            range_m=np.asarray(cols["range_m"], float), azimuth_rad=np.asarray(cols["azimuth_rad"], float),
            altitude_m=np.asarray(cols["altitude_m"], float), mode_s=_obj(cols["mode_s"]),
            mode_3a=_obj(cols["mode_3a"]), target=_obj(cols["target"]),
            **({"received": np.asarray(cols["received"], float)} if "received" in cols else {}),
        )

    def __len__(self) -> int:
        return len(self.time)

    def take(self, idx: np.ndarray) -> PlotTable:
        return PlotTable(**{f.name: getattr(self, f.name)[idx] for f in attrs.fields(PlotTable)})

    @property
    def has_truth_labels(self) -> bool:
        return len(self) > 0 and all(t is not None for t in self.target)


@attrs.define
class AdsbTable:
    """ADS-B reports as columns (degrees for lat/lon as in the file, metres for altitude)."""

    time: np.ndarray
    icao24: np.ndarray
    lat: np.ndarray
    lon: np.ndarray
    altitude_m: np.ndarray
    nacp: np.ndarray

    @classmethod
    def from_columns(cls, **cols: Iterable[Any]) -> AdsbTable:
        return cls(
            time=np.asarray(cols["time"], float), icao24=_obj(cols["icao24"]),
            lat=np.asarray(cols["lat"], float), lon=np.asarray(cols["lon"], float),
            altitude_m=np.asarray(cols["altitude_m"], float), nacp=np.asarray(cols["nacp"], int),
        )

    def __len__(self) -> int:
        return len(self.time)


@attrs.define
class TruthTable:
    """True aircraft positions as columns (degrees, metres)."""

    time: np.ndarray
    target: np.ndarray
    lat: np.ndarray
    lon: np.ndarray
    altitude_m: np.ndarray

    @classmethod
    def from_columns(cls, **cols: Iterable[Any]) -> TruthTable:
        return cls(
            time=np.asarray(cols["time"], float), target=_obj(cols["target"]),
            lat=np.asarray(cols["lat"], float), lon=np.asarray(cols["lon"], float),
            altitude_m=np.asarray(cols["altitude_m"], float),
        )

    def __len__(self) -> int:
        return len(self.time)


@attrs.define
class ScenarioData:
    """Everything a scenario folder holds, validated.

    ``reference`` is the system plane's centre (lat, lon in degrees); ``truth_biases`` maps a
    radar id to its true (Δr m, Δθ rad); ``truth_sensor`` (where a radar has them) to its true further
    components, ``{"range_gain": g, "time_offset": τ (s)}``; ``skipped`` counts rows skipped by reason.
    """

    reference: tuple[float, float]
    radars: list[Radar]
    plots: PlotTable
    adsb: AdsbTable
    truth: TruthTable | None = None
    truth_biases: dict[str, tuple[float, float]] | None = None
    truth_sensor: dict[str, dict[str, float]] | None = None
    aircraft: list[Aircraft] = attrs.field(factory=list)
    name: str = ""
    skipped: dict[str, int] = attrs.field(factory=dict)

    @property
    def radar_by_id(self) -> dict[str, Radar]:
        return {r.id: r for r in self.radars}


def label_spans(time: np.ndarray, target: np.ndarray, spans: dict | None = None) -> dict[str, tuple[float, float]]:
    """The first and last time of the plots of each truth label (``target`` not ``None``), sorted by label;
    ``spans`` from earlier blocks of the same file are extended."""
    spans = dict(spans or {})
    for tg, t in zip(target.tolist(), time.tolist()):
        if tg is not None:
            lo, hi = spans.get(str(tg), (t, t))
            spans[str(tg)] = (min(lo, t), max(hi, t))
    return dict(sorted(spans.items()))


def in_time_order(data: ScenarioData) -> ScenarioData:
    """``data`` with its plots and ADS-B reports in time order (a stable sort: equal times keep their order).
    A recording holds them in arrival order — radars' blocks interleaved as the network delivered them —
    while a scenario folder must be time-ordered per radar (and ADS-B in time order for streaming)."""
    p, a = data.plots, data.adsb
    op, oa = np.argsort(p.time, kind="stable"), np.argsort(a.time, kind="stable")
    adsb = AdsbTable(*(getattr(a, f.name)[oa] for f in attrs.fields(AdsbTable)))
    return attrs.evolve(data, plots=p.take(op), adsb=adsb)
