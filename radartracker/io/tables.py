"""Input tables as columns (SI units): plots, ADS-B reports, truth, and a whole scenario."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import attrs
import numpy as np

from radartracker.domain import Aircraft, Radar

RADAR_COLUMNS = ("radar", "lat", "lon", "height_m", "sigma_range_m", "sigma_azimuth_deg", "period_s", "max_range_m")
PLOT_COLUMNS = ("time", "radar", "range_m", "azimuth_deg", "altitude_m", "mode_s", "mode_3a")
ADSB_COLUMNS = ("time", "icao24", "lat", "lon", "altitude_m", "nacp")
TRUTH_COLUMNS = ("time", "target", "lat", "lon", "altitude_m")
BIAS_COLUMNS = ("radar", "range_bias_m", "azimuth_bias_deg")

def _obj(values: Iterable[Any]) -> np.ndarray:
    arr = np.empty(len(values := list(values)), dtype=object)
    arr[:] = values
    return arr


@attrs.define
class PlotTable:
    """Radar plots as columns (SI units; ``altitude_m`` NaN and codes ``None`` where absent)."""

    time: np.ndarray
    radar: np.ndarray
    range_m: np.ndarray
    azimuth_rad: np.ndarray
    altitude_m: np.ndarray
    mode_s: np.ndarray
    mode_3a: np.ndarray
    target: np.ndarray

    @classmethod
    def from_columns(cls, **cols: Iterable[Any]) -> PlotTable:
        return cls(
            time=np.asarray(cols["time"], float), radar=_obj(cols["radar"]),
            range_m=np.asarray(cols["range_m"], float), azimuth_rad=np.asarray(cols["azimuth_rad"], float),
            altitude_m=np.asarray(cols["altitude_m"], float), mode_s=_obj(cols["mode_s"]),
            mode_3a=_obj(cols["mode_3a"]), target=_obj(cols["target"]),
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
    radar id to its true (Δr m, Δθ rad); ``skipped`` counts rows skipped by reason.
    """

    reference: tuple[float, float]
    radars: list[Radar]
    plots: PlotTable
    adsb: AdsbTable
    truth: TruthTable | None = None
    truth_biases: dict[str, tuple[float, float]] | None = None
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
