"""Triangulation files: stations and bearings in (degrees at the edge), fixes and tracks out.

Formats are specified in ``docs/formats.md`` ("Triangulation files"). Readers raise
``FormatError`` naming the file, the line and the field, or — with ``skip_bad`` — skip and count
malformed rows.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path

import numpy as np

from .dynamic import TrackFix
from .frame import TriangulationFrame
from .sensors import Bearing, DirectionFinder
from .static import Fix
from radartracker.api import FormatError, atomic_open, read_text

STATION_COLUMNS = ("id", "lat_deg", "lon_deg", "height_m", "sigma_azimuth_deg", "sigma_elevation_deg")
BEARING_COLUMNS = ("time_s", "station", "azimuth_deg", "elevation_deg")
COV_COLUMNS = ("cov_ee_m2", "cov_en_m2", "cov_eu_m2", "cov_nn_m2", "cov_nu_m2", "cov_uu_m2")
FIX_COLUMNS = ("target", "time_s", "n_bearings", "stations", "lat_deg", "lon_deg", "height_m",
               "east_m", "north_m", "up_m", *COV_COLUMNS, "gdop", "chi2", "dof", "status")
TRACK_COLUMNS = ("target", "time_s", "lat_deg", "lon_deg", "height_m", "east_m", "north_m", "up_m",
                 *COV_COLUMNS, "gdop", "status")
_UPPER = np.triu_indices(3)


def _rows(path: Path, required: tuple[str, ...]) -> Iterator[tuple[int, dict[str, str] | str]]:
    """(line number, row) of each data line; instead of the row, what is wrong with its field count."""
    text = read_text(path)
    lines = ((i, line) for i, line in enumerate(text.splitlines(), 1) if line.strip() and not line.startswith("#"))
    try:
        lineno, header = next(lines)
    except StopIteration:
        raise FormatError(path.name, None, None, f"empty file, expected a header {','.join(required)}") from None
    names = [h.strip() for h in next(csv.reader([header]))]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise FormatError(path.name, lineno, None, f"column(s) {', '.join(twice)} appear more than once")
    missing = [c for c in required if c not in names]
    if missing:
        raise FormatError(path.name, lineno, None, f"header lacks column(s) {', '.join(missing)}")
    for lineno, line in lines:
        values = next(csv.reader([line]))
        yield lineno, (f"{len(values)} fields where the header has {len(names)}" if len(values) != len(names)
                       else {k: v.strip() for k, v in zip(names, values)})


class _FieldError(ValueError):
    def __init__(self, field: str, problem: str) -> None:
        super().__init__(problem)
        self.field, self.problem = field, problem


# domain attribute -> file column, to name the column the user wrote
_COLUMN_OF = {"time": "time_s", "azimuth_rad": "azimuth_deg", "elevation_rad": "elevation_deg",
              "lat": "lat_deg", "lon": "lon_deg", "sigma_azimuth_rad": "sigma_azimuth_deg",
              "sigma_elevation_rad": "sigma_elevation_deg"}


def _number(row: dict[str, str], field: str) -> float:
    try:
        value = float(row[field])
    except ValueError:
        raise _FieldError(field, f"{row[field]!r} is not a number") from None
    if not math.isfinite(value):
        raise _FieldError(field, f"{row[field]!r} is not finite")
    return value


def _read(path: Path, required: tuple[str, ...], make: Callable[[dict[str, str]], object],
          skip_bad: bool) -> tuple[list, int]:
    out, skipped = [], 0
    for lineno, row in _rows(path, required):
        if isinstance(row, str):
            if skip_bad:
                skipped += 1
                continue
            raise FormatError(path.name, lineno, None, row)
        try:
            out.append(make(row))
        except ValueError as exc:
            if skip_bad:
                skipped += 1
                continue
            if isinstance(exc, _FieldError):
                field, problem = exc.field, exc.problem
            else:  # a domain validator: "attribute: problem"
                attr, _, problem = str(exc).partition(": ")
                field = _COLUMN_OF.get(attr, attr)
            raise FormatError(path.name, lineno, field, problem) from None
    return out, skipped


def read_stations(path: str | Path) -> list[DirectionFinder]:
    """Direction finders from a stations CSV (σ in degrees); every row must be valid."""
    def make(row):
        return DirectionFinder(
            row["id"], _number(row, "lat_deg"), _number(row, "lon_deg"), _number(row, "height_m"),
            math.radians(_number(row, "sigma_azimuth_deg")), math.radians(_number(row, "sigma_elevation_deg")))
    path = Path(path)
    stations, _ = _read(path, STATION_COLUMNS, make, skip_bad=False)
    if not stations:
        raise FormatError(path.name, None, None, "no stations")
    ids = [s.id for s in stations]
    twice = sorted({i for i in ids if ids.count(i) > 1})
    if twice:
        raise FormatError(path.name, None, "id", f"station id(s) {twice} appear more than once")
    return stations


def read_bearings(path: str | Path, skip_bad: bool = False) -> tuple[list[Bearing], dict[str, int]]:
    """Bearings from a bearings CSV (degrees) and the rows skipped by reason: ``malformed`` (with
    ``skip_bad``) and ``duplicate`` (an exact repeat of an earlier row, used once)."""
    def make(row):
        return Bearing(_number(row, "time_s"), row["station"],
                       math.radians(_number(row, "azimuth_deg")), math.radians(_number(row, "elevation_deg")),
                       row.get("target") or "1")
    path = Path(path)
    rows, malformed = _read(path, BEARING_COLUMNS, make, skip_bad)
    if not rows:  # nothing to triangulate is an input problem, not a result
        raise FormatError(path.name, None, None, "no bearings" + (f" ({malformed} malformed rows skipped)"
                                                                   if malformed else ""))
    unique = list(dict.fromkeys(rows))
    return unique, {"malformed": malformed, "duplicate": len(rows) - len(unique)}


def _geo_cols(frame: TriangulationFrame, r: np.ndarray, cov: np.ndarray) -> list:
    lat, lon, h = frame.geodetic(r)
    return [f"{float(lat):.8f}", f"{float(lon):.8f}", f"{float(h):.3f}", *(f"{v:.3f}" for v in r),
            *(f"{v:.6g}" for v in cov[_UPPER])]


def _status(poor: bool, gdop: float) -> str:
    return f"poor geometry (GDOP {gdop:.3g})" if poor else "ok"


def write_fixes(path: str | Path, frame: TriangulationFrame, fixes: Iterable[tuple[str, Fix]]) -> None:
    """One row per static fix (written atomically)."""
    with atomic_open(path, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(FIX_COLUMNS)
        for target, f in fixes:
            w.writerow([target, f"{f.time:.6f}", f.n_bearings, " ".join(f.stations),
                        *_geo_cols(frame, f.position, f.cov), f"{f.gdop:.4g}", f"{f.chi2:.4g}", f.dof,
                        _status(f.poor_geometry, f.gdop)])


def write_tracks(path: str | Path, frame: TriangulationFrame,
                 tracks: Iterable[tuple[str, TrackFix, np.ndarray]]) -> None:
    """One row per (target, output time) of each dynamic track (written atomically)."""
    with atomic_open(path, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(TRACK_COLUMNS)
        for target, tr, times in tracks:
            for t, r, c in zip(times, tr.position(times), tr.covariance(times)):
                w.writerow([target, f"{t:.6f}", *_geo_cols(frame, r, c), f"{tr.gdop:.4g}",
                            _status(tr.poor_geometry, tr.gdop)])
