"""Real recorded flights (OpenSky Network ADS-B state vectors) used as ground-truth trajectories.

The package ships a small subset (``radartracker/data/flights_subset.csv.gz``, see the README beside
it); the full file lives in the project's ``shared/data/real_flights.csv.gz``. Feet and knots are
converted to SI here, at the edge.
"""

from __future__ import annotations

import csv
import gzip
from importlib.resources import files
from pathlib import Path

import attrs
import numpy as np

FT = 0.3048
SUBSET = files("radartracker") / "data" / "flights_subset.csv.gz"


@attrs.frozen
class Flight:
    """One recorded flight: times (s UTC), WGS84 positions (deg) and barometric altitude (m)."""

    flight_id: str
    icao24: str
    callsign: str
    time: np.ndarray
    lat: np.ndarray
    lon: np.ndarray
    altitude_m: np.ndarray

    @property
    def duration_s(self) -> float:
        return float(self.time[-1] - self.time[0])


def load_flights(path: Path | str | None = None, ids: list[str] | None = None) -> dict[str, Flight]:
    """Flights by id from a ``real_flights.csv.gz``-style file (default: the shipped subset).

    Rows with a repeated time stamp are dropped (the trajectory needs increasing times).
    """
    source = SUBSET if path is None else Path(path)
    rows: dict[str, list[tuple]] = {}
    meta: dict[str, tuple[str, str]] = {}
    with gzip.open(source, "rt", newline="") as f:  # type: ignore[arg-type]
        for r in csv.DictReader(f):
            fid = r["flight_id"]
            if ids is not None and fid not in ids:
                continue
            meta.setdefault(fid, (r["icao24"], r["callsign"]))
            rows.setdefault(fid, []).append(
                (float(r["timestamp"]), float(r["latitude"]), float(r["longitude"]), float(r["altitude"]) * FT))
    flights = {}
    for fid, rs in rows.items():
        a = np.array(sorted(rs))
        keep = np.concatenate([[True], np.diff(a[:, 0]) > 0])
        a = a[keep]
        flights[fid] = Flight(fid, meta[fid][0], meta[fid][1], a[:, 0], a[:, 1], a[:, 2], a[:, 3])
    if ids is not None and (missing := set(ids) - set(flights)):
        raise ValueError(f"flights not found in {source}: {sorted(missing)}")
    return flights
