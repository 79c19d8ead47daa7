"""The scenario folder format (public contract, documented in docs/formats.md).

A scenario folder holds ``radars.csv``, ``plots.csv`` and optionally ``adsb.csv``, ``truth.csv``,
``truth_biases.csv`` and ``scenario.json`` (reference point, name). Degrees at the edge, SI inside.

Reading validates every row. A malformed row raises :class:`FormatError` naming file, line and
field; with ``skip_bad=True`` it is skipped instead and counted under its reason in
``ScenarioData.skipped`` (the replay reports those counts in ``summary.json``).
"""

from __future__ import annotations

import csv
import io
import json
import logging
import math
from collections import Counter
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import attrs
import numpy as np

from radartracker.domain import Aircraft, Radar
from radartracker.errors import FormatError
from radartracker.io.atomic import atomic_folder
from radartracker.tracking.admission import StreamClock
from radartracker.io.tables import (ADSB_COLUMNS, BIAS_COLUMNS, PLOT_COLUMNS, RADAR_COLUMNS, TRUTH_COLUMNS, AdsbTable,
                                    PlotTable, ScenarioData, TruthTable)

log = logging.getLogger(__name__)


# --- reading ----------------------------------------------------------------------------------


def read_text(path: Path) -> str:
    """A file's text: UTF-8 with or without a byte-order mark; a FormatError names the line of a bad byte."""
    data = path.read_bytes()
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data[:exc.start].count(b"\n") + 1
        raise FormatError(path.name, line, None, f"not UTF-8 text (byte {exc.start} is {data[exc.start]:#04x})",
                          "encoding") from None


class _Rows:
    """Iterate a CSV file's rows with line numbers; parse fields with errors naming the place.

    The header must name each column once. A row with the wrong number of fields goes to ``skip``
    (reason ``wrong_field_count``, or ``truncated_last_line`` for a last line without its newline).
    """

    def __init__(self, path: Path, required: tuple[str, ...], skip: _Skipper | None = None):
        self.path, self.name = path, path.name
        self.skip = skip if skip is not None else _Skipper(False)
        text = read_text(path)
        # a last line without its newline may have been cut short: its errors say so
        self.cut_line = None if not text or text.endswith(("\n", "\r")) else text.count("\n") + 1
        self._reader = csv.reader(io.StringIO(text, newline=""))
        try:
            header = next(self._reader, None)
        except csv.Error as exc:
            raise FormatError(self.name, 1, None, f"bad header: {exc}") from None
        if not header:
            raise FormatError(self.name, 1, None, "empty file: expected a header line")
        header = [h.strip() for h in header]
        twice = sorted({h for h in header if header.count(h) > 1})
        if twice:
            raise FormatError(self.name, 1, None, f"column(s) {', '.join(map(repr, twice))} appear more than once")
        missing = [c for c in required if c not in header]
        if missing:
            raise FormatError(self.name, 1, None, f"missing column(s) {', '.join(missing)}; header is {header}")
        self.header = header
        self.optional = set(header)

    def __iter__(self):
        n, reader = len(self.header), self._reader
        while True:
            try:
                fields = next(reader, None)
            except csv.Error as exc:  # e.g. a quote left open at the end of the file
                fields = exc
            if fields is None:
                return
            if not fields:
                continue  # a blank line
            line = reader.line_num
            if isinstance(fields, csv.Error) or len(fields) != n:
                got = f"unreadable ({fields})" if isinstance(fields, csv.Error) else f"{len(fields)} fields"
                self.reject(FormatError(self.name, line, None, f"{got}, header has {n}", "wrong_field_count"))
                continue
            yield line, dict(zip(self.header, fields))

    def reject(self, err: FormatError) -> None:
        """Raise ``err``, or skip and count it (skip_bad); on a cut last line, under ``truncated_last_line``."""
        if err.line is not None and err.line == self.cut_line:
            err = FormatError(err.file, err.line, err.field, f"{err.message} (the file ends in the middle of this "
                              "line: cut short?)", "truncated_last_line")
        self.skip(err)

    def number(self, row: dict, line: int, field: str, *, optional: bool = False,
               check: Callable[[float], str | None] | None = None) -> float:
        text = (row.get(field) or "").strip()
        if not text:
            if optional:
                return math.nan
            raise FormatError(self.name, line, field, "empty")
        try:
            value = float(text)
        except ValueError:
            raise FormatError(self.name, line, field, f"{text!r} is not a number") from None
        if not math.isfinite(value):
            raise FormatError(self.name, line, field, f"{text!r} is not finite")
        if check is not None and (why := check(value)) is not None:
            raise FormatError(self.name, line, field, f"{value!r} {why}")
        return value

    @staticmethod
    def text(row: dict, field: str) -> str | None:
        text = (row.get(field) or "").strip()
        return text or None


def _range(lo: float, hi: float, *, hi_open: bool = False) -> Callable[[float], str | None]:
    def check(v: float) -> str | None:
        ok = lo <= v < hi if hi_open else lo <= v <= hi
        return None if ok else f"outside [{lo}, {hi}{')' if hi_open else ']'}"
    return check


def _nonneg(v: float) -> str | None:
    return None if v >= 0 else "is negative"


def _positive(v: float) -> str | None:
    return None if v > 0 else "must be > 0"


def _code(rows: _Rows, row: dict, line: int, field: str, digits: str, n: int) -> str | None:
    value = rows.text(row, field)
    if value is None:
        return None
    value = value.lower()
    if len(value) != n or any(c not in digits for c in value):
        raise FormatError(rows.name, line, field, f"{value!r} is not {n} characters of {digits!r}")
    return value


_HEX, _OCT = "0123456789abcdef", "01234567"


def read_radars(path: Path) -> list[Radar]:
    rows = _Rows(path, RADAR_COLUMNS)
    radars: dict[str, tuple[Radar, int]] = {}
    for line, row in rows:
        rid = rows.text(row, "radar")
        if rid is None:
            raise FormatError(rows.name, line, "radar", "empty")
        if rid in radars:
            raise FormatError(rows.name, line, "radar", f"duplicate radar id {rid!r} (first on line {radars[rid][1]})")
        radars[rid] = (Radar(
            id=rid,
            lat=rows.number(row, line, "lat", check=_range(-90, 90)),
            lon=rows.number(row, line, "lon", check=_range(-180, 180)),
            height_m=rows.number(row, line, "height_m"),
            sigma_range_m=rows.number(row, line, "sigma_range_m", check=_nonneg),
            sigma_azimuth_rad=math.radians(rows.number(row, line, "sigma_azimuth_deg", check=_nonneg)),
            period_s=rows.number(row, line, "period_s", check=_positive),
            max_range_m=rows.number(row, line, "max_range_m", check=_positive),
        ), line)
    if not radars:
        raise FormatError(rows.name, 2, None, "no radars")
    return [r for r, _ in radars.values()]


class _Skipper:
    """Raise, or count and log, bad rows; count duplicate rows (always used once)."""

    def __init__(self, skip_bad: bool):
        self.skip_bad = skip_bad
        self.counts: Counter[str] = Counter()

    def __call__(self, err: FormatError) -> None:
        if not self.skip_bad:
            raise err
        self.count(err.file, err.reason, err)

    def count(self, file: str, reason: str, what: object) -> None:
        key = f"{file}:{reason}"
        if self.counts[key] < 5:
            log.warning("skipped (%s) %s", reason, what)
        self.counts[key] += 1


def _key(row: dict) -> tuple[str, ...]:
    """An exact duplicate has the same text in every field."""
    return tuple(row.values())


def read_plots(path: Path, radar_ids: set[str], skip: _Skipper) -> PlotTable:
    rows = _Rows(path, PLOT_COLUMNS, skip)
    has_target = "target" in rows.optional
    cols: dict[str, list] = {k: [] for k in ("time", "radar", "range_m", "azimuth_rad", "altitude_m", "mode_s", "mode_3a", "target")}
    last_time: dict[str, tuple[float, int]] = {}
    same_time: dict[str, set[tuple[str, ...]]] = {}  # rows of a radar at its latest time: duplicates are among them
    clock = StreamClock()
    for line, row in rows:
        try:
            t = rows.number(row, line, "time")
            rid = rows.text(row, "radar")
            if rid not in radar_ids:
                raise FormatError(rows.name, line, "radar", f"unknown radar {rid!r} (radars.csv has {sorted(radar_ids)})", "unknown_radar")
            if rid in last_time and t == last_time[rid][0] and _key(row) in same_time[rid]:
                skip.count(rows.name, "duplicate_row", f"{rows.name} line {line}")
                continue
            if rid in last_time and t < last_time[rid][0]:
                raise FormatError(rows.name, line, "time",
                                  f"{t} is earlier than {last_time[rid][0]} on line {last_time[rid][1]} of the same radar",
                                  "time_backwards")
            if not clock.admit(t):  # one far-off time stamp must not make the good rows after it "backwards"
                raise FormatError(rows.name, line, "time", f"{t} is more than {clock.config.max_ahead_s:g} s ahead of "
                                  f"the stream time {clock.now} (median of the last rows read)", "time_jump")
            rng = rows.number(row, line, "range_m", check=_nonneg)
            az = rows.number(row, line, "azimuth_deg", check=_range(0, 360, hi_open=True))
            alt = rows.number(row, line, "altitude_m", optional=True)
            ms = _code(rows, row, line, "mode_s", _HEX, 6)
            m3a = _code(rows, row, line, "mode_3a", _OCT, 4)
        except FormatError as err:
            rows.reject(err)
            continue
        if rid not in last_time or t > last_time[rid][0]:
            same_time[rid] = set()
        same_time[rid].add(_key(row))
        last_time[rid] = (t, line)
        for k, v in (("time", t), ("radar", rid), ("range_m", rng), ("azimuth_rad", math.radians(az)),
                     ("altitude_m", alt), ("mode_s", ms), ("mode_3a", m3a),
                     ("target", rows.text(row, "target") if has_target else None)):
            cols[k].append(v)
    if not cols["time"]:
        bad = sum(n for k, n in skip.counts.items() if k.startswith(f"{rows.name}:"))
        raise FormatError(rows.name, None, None, "no usable plot rows" + (f" ({bad} skipped)" if bad else
                          " after the header") + ": nothing to track", "empty")
    return PlotTable.from_columns(**cols)


def read_adsb(path: Path, skip: _Skipper) -> AdsbTable:
    rows = _Rows(path, ADSB_COLUMNS, skip)
    cols: dict[str, list] = {k: [] for k in ADSB_COLUMNS}
    seen: set[tuple[str, ...]] = set()
    for line, row in rows:
        try:
            rec = {
                "time": rows.number(row, line, "time"),
                "icao24": _code(rows, row, line, "icao24", _HEX, 6),
                "lat": rows.number(row, line, "lat", check=_range(-90, 90)),
                "lon": rows.number(row, line, "lon", check=_range(-180, 180)),
                "altitude_m": rows.number(row, line, "altitude_m", optional=True),
                "nacp": rows.number(row, line, "nacp", check=_range(1, 11)),
            }
            if rec["icao24"] is None:
                raise FormatError(rows.name, line, "icao24", "empty")
            if rec["nacp"] != int(rec["nacp"]):
                raise FormatError(rows.name, line, "nacp", f"{rec['nacp']!r} is not an integer")
        except FormatError as err:
            rows.reject(err)
            continue
        if (key := _key(row)) in seen:
            skip.count(rows.name, "duplicate_row", f"{rows.name} line {line}")
            continue
        seen.add(key)
        for k, v in rec.items():
            cols[k].append(v)
    return AdsbTable.from_columns(**cols)


def read_truth(path: Path, skip: _Skipper) -> TruthTable:
    rows = _Rows(path, TRUTH_COLUMNS)
    cols: dict[str, list] = {k: [] for k in TRUTH_COLUMNS}
    seen: set[tuple[str, ...]] = set()
    for line, row in rows:
        rec = (rows.number(row, line, "time"), rows.text(row, "target"),
               rows.number(row, line, "lat", check=_range(-90, 90)),
               rows.number(row, line, "lon", check=_range(-180, 180)), rows.number(row, line, "altitude_m"))
        if (key := _key(row)) in seen:
            skip.count(rows.name, "duplicate_row", f"{rows.name} line {line}")
            continue
        seen.add(key)
        for k, v in zip(TRUTH_COLUMNS, rec):
            cols[k].append(v)
    return TruthTable.from_columns(**cols)


def read_truth_biases(path: Path, radar_ids: set[str]) -> dict[str, tuple[float, float]]:
    rows = _Rows(path, BIAS_COLUMNS)
    out: dict[str, tuple[float, float]] = {}
    first: dict[str, int] = {}
    for line, row in rows:
        rid = rows.text(row, "radar")
        if rid not in radar_ids:
            raise FormatError(rows.name, line, "radar", f"unknown radar {rid!r}")
        if rid in first:
            raise FormatError(rows.name, line, "radar", f"radar {rid!r} appears twice (first on line {first[rid]})")
        first[rid] = line
        out[rid] = (rows.number(row, line, "range_bias_m"),
                    math.radians(rows.number(row, line, "azimuth_bias_deg")))
    return out


def _json_number(file: str, obj: dict, field: str, lo: float, hi: float) -> float:
    v = obj.get(field.rsplit(".", 1)[-1])
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise FormatError(file, None, field, f"expected a number, got {json.dumps(v)}")
    if not lo <= v <= hi:  # also refuses NaN and ±Infinity
        raise FormatError(file, None, field, f"{v!r} outside [{lo}, {hi}]")
    return float(v)


def read_meta(path: Path) -> dict[str, Any]:
    """``scenario.json``: ``name``, ``reference`` (lat, lon) and ``aircraft``, each checked; errors name the field."""
    name = path.name
    try:
        meta = json.loads(read_text(path))
    except json.JSONDecodeError as exc:
        raise FormatError(name, exc.lineno, None, f"not JSON: {exc.msg} (column {exc.colno})") from None
    if not isinstance(meta, dict):
        raise FormatError(name, None, None, f"expected a JSON object, got {type(meta).__name__}")
    out: dict[str, Any] = {}
    if "name" in meta:
        if not isinstance(meta["name"], str):
            raise FormatError(name, None, "name", f"expected a string, got {json.dumps(meta['name'])}")
        out["name"] = meta["name"]
    if "reference" in meta:
        ref = meta["reference"]
        if not isinstance(ref, dict):
            raise FormatError(name, None, "reference", f'expected {{"lat": …, "lon": …}}, got {json.dumps(ref)}')
        out["reference"] = (_json_number(name, ref, "reference.lat", -90, 90),
                            _json_number(name, ref, "reference.lon", -180, 180))
    aircraft = meta.get("aircraft", [])
    if not isinstance(aircraft, list):
        raise FormatError(name, None, "aircraft", f"expected a list, got {type(aircraft).__name__}")
    out["aircraft"] = []
    for i, a in enumerate(aircraft):
        try:
            if not isinstance(a, dict):
                raise TypeError(f"expected an object, got {json.dumps(a)}")
            out["aircraft"].append(Aircraft(**a))
        except (TypeError, ValueError) as exc:  # an unknown key, or a value the Aircraft validators refuse
            raise FormatError(name, None, f"aircraft[{i}]", str(exc)) from None
    return out


def read_scenario(folder: Path | str, *, skip_bad: bool = False) -> ScenarioData:
    """Read and validate a scenario folder (see docs/formats.md).

    Exact duplicate rows of plots, ADS-B and truth are used once and counted under
    ``<file>:duplicate_row``; a ``plots.csv`` without a usable row is an error (nothing to track).
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise FileNotFoundError(f"scenario folder {folder} does not exist")
    meta = read_meta(folder / "scenario.json") if (folder / "scenario.json").exists() else {}
    radars = read_radars(folder / "radars.csv")
    ids = {r.id for r in radars}
    skip = _Skipper(skip_bad)
    plots = read_plots(folder / "plots.csv", ids, skip)
    adsb = read_adsb(folder / "adsb.csv", skip) if (folder / "adsb.csv").exists() else AdsbTable.from_columns(
        **{k: [] for k in ADSB_COLUMNS})
    truth = read_truth(folder / "truth.csv", skip) if (folder / "truth.csv").exists() else None
    tb = read_truth_biases(folder / "truth_biases.csv", ids) if (folder / "truth_biases.csv").exists() else None
    # documented default reference: the centroid of the radar sites
    reference = meta.get("reference") or (float(np.mean([r.lat for r in radars])), float(np.mean([r.lon for r in radars])))
    return ScenarioData(reference=reference, radars=radars, plots=plots, adsb=adsb, truth=truth,
                        truth_biases=tb, aircraft=meta.get("aircraft", []), name=meta.get("name", folder.name),
                        skipped=dict(skip.counts))


# --- writing ----------------------------------------------------------------------------------


def _fmt(v: Any, spec: str) -> str:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return ""
    return format(v, spec) if spec else str(v)


def _azimuth_deg(rad: float) -> str:
    deg = round(math.degrees(rad) % 360.0, 7)
    return f"{0.0 if deg >= 360.0 else deg:.7f}"


def _write(path: Path, header: tuple[str, ...], rows: Iterable[Iterable[str]]) -> None:
    with path.open("w", newline="", encoding="utf-8") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(header)
        w.writerows(rows)


def write_scenario(folder: Path | str, data: ScenarioData) -> None:
    """Write ``data`` as a scenario folder (the folder must not exist); it appears complete or not at all."""
    with atomic_folder(folder) as tmp:
        _write_scenario_files(tmp, data)


def _write_scenario_files(folder: Path, data: ScenarioData) -> None:
    _write(folder / "radars.csv", RADAR_COLUMNS, (
        (r.id, f"{r.lat:.8f}", f"{r.lon:.8f}", f"{r.height_m:.2f}", f"{r.sigma_range_m:g}",
         f"{math.degrees(r.sigma_azimuth_rad):.6g}", f"{r.period_s:g}", f"{r.max_range_m:g}") for r in data.radars))
    p = data.plots
    labelled = any(t is not None for t in p.target)
    _write(folder / "plots.csv", PLOT_COLUMNS + (("target",) if labelled else ()), (
        (f"{p.time[i]:.4f}", p.radar[i], f"{p.range_m[i]:.3f}", _azimuth_deg(p.azimuth_rad[i]),
         _fmt(p.altitude_m[i], ".2f"), _fmt(p.mode_s[i], ""), _fmt(p.mode_3a[i], ""))
        + ((_fmt(p.target[i], ""),) if labelled else ()) for i in range(len(p))))
    a = data.adsb
    _write(folder / "adsb.csv", ADSB_COLUMNS, (
        (f"{a.time[i]:.3f}", a.icao24[i], f"{a.lat[i]:.8f}", f"{a.lon[i]:.8f}", _fmt(a.altitude_m[i], ".2f"),
         str(int(a.nacp[i]))) for i in range(len(a))))
    if data.truth is not None:
        tr = data.truth
        _write(folder / "truth.csv", TRUTH_COLUMNS, (
            (f"{tr.time[i]:.3f}", tr.target[i], f"{tr.lat[i]:.8f}", f"{tr.lon[i]:.8f}", f"{tr.altitude_m[i]:.2f}")
            for i in range(len(tr))))
    if data.truth_biases is not None:
        _write(folder / "truth_biases.csv", BIAS_COLUMNS, (
            (rid, f"{b[0]:.4f}", f"{math.degrees(b[1]):.8f}") for rid, b in data.truth_biases.items()))
    meta = {"name": data.name, "reference": {"lat": data.reference[0], "lon": data.reference[1]},
            "aircraft": [attrs.asdict(ac) for ac in data.aircraft]}
    (folder / "scenario.json").write_text(json.dumps(meta, indent=1))
