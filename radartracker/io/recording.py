"""Text recordings in (``tracks.txt``, ``plots.txt``, ``plots_ads.txt``) and per-track files out
(``.new4``, OziExplorer ``.plt``) — seed 000 §2.6, program ``tracks_plots_00``.

The seed names the three input files (written by ``vidparser.exe``) but not their columns; we define
them here and in ``docs/formats.md``. Every file is UTF-8, tab-separated, with one header line naming
the columns (any order, extra columns ignored); LF or CRLF line ends. Units are in the column names.

* ``plots_ads.txt`` — ADS-B reports: ``time global mode_s lat lon altitude_m nacp``.
* ``tracks.txt`` — monoradar tracks (``radar`` = the radar's number) and multi-radar tracks
  (``radar`` = ``240``): ``time sensor radar global local lat lon altitude_m mode_s mode_3a``.
* ``plots.txt`` — radar plots: ``time sensor radar global local lat lon altitude_m range_m
  azimuth_deg mode_s mode_3a``; lat/lon are the plot's position computed from range and azimuth.

``time`` is seconds since 1970-01-01 UTC, ``global`` the multi-radar (global) track number (empty:
the record was not associated with any aircraft), ``local`` the radar's own track number,
``sensor`` the detection type (CAT048 I020/TYP: 1 PSR, 2 SSR, 3 SSR+PSR, 4 Mode S all-call,
5 Mode S roll-call, 6 all-call+PSR, 7 roll-call+PSR), empty fields are missing values.

Writers stream: :class:`RecordingWriter` takes records one at a time (or any iterable), so a
recording of any size is written in constant memory.
"""

from __future__ import annotations

import datetime as _dt
import math
import re
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import IO, NamedTuple

import numpy as np
from radartracker.errors import FormatError, InputError
from radartracker.io.atomic import atomic_folder, write_text
from radartracker.io.limits import BOUNDS, bound, read_bytes

ADS_FILE, TRACKS_FILE, PLOTS_FILE = "plots_ads.txt", "tracks.txt", "plots.txt"
MULTI_RADAR = "240"  # the seed's radar number of the multi-radar (system) track

ADS_COLUMNS = ("time", "global", "mode_s", "lat", "lon", "altitude_m", "nacp")
TRACK_COLUMNS = ("time", "sensor", "radar", "global", "local", "lat", "lon", "altitude_m",
                 "mode_s", "mode_3a")
PLOT_COLUMNS = ("time", "sensor", "radar", "global", "local", "lat", "lon", "altitude_m",
                "range_m", "azimuth_deg", "mode_s", "mode_3a")
COLUMNS = {ADS_FILE: ADS_COLUMNS, TRACKS_FILE: TRACK_COLUMNS, PLOTS_FILE: PLOT_COLUMNS}

FEET = 0.3048
_OZI_EPOCH = _dt.datetime(1899, 12, 30, tzinfo=_dt.timezone.utc)
_UNIX_EPOCH_DAYS = (_dt.datetime(1970, 1, 1, tzinfo=_dt.timezone.utc) - _OZI_EPOCH).days  # 25569
_TOKEN = re.compile(r"[A-Za-z0-9_.-]+")


class AdsRecord(NamedTuple):
    """One line of ``plots_ads.txt``."""

    time: float
    global_: int | None
    mode_s: str | None
    lat: float
    lon: float
    altitude_m: float | None
    nacp: int | None = None


class TrackRecord(NamedTuple):
    """One line of ``tracks.txt`` (``radar == "240"``: multi-radar track)."""

    time: float
    sensor: str | None
    radar: str
    global_: int | None
    local: int | None
    lat: float
    lon: float
    altitude_m: float | None
    mode_s: str | None = None
    mode_3a: str | None = None


class PlotRecord(NamedTuple):
    """One line of ``plots.txt``."""

    time: float
    sensor: str | None
    radar: str
    global_: int | None
    local: int | None
    lat: float
    lon: float
    altitude_m: float | None
    range_m: float
    azimuth_deg: float
    mode_s: str | None = None
    mode_3a: str | None = None


# --- formatting ----------------------------------------------------------------------------------

def _f(v: float | None, spec: str) -> str:
    return "" if v is None or (isinstance(v, float) and math.isnan(v)) else format(v, spec)


def _s(v: object) -> str:
    return "" if v is None else str(v)


def format_ads(r: AdsRecord) -> str:
    return (f"{r.time:.3f}\t{_s(r.global_)}\t{_s(r.mode_s)}\t{r.lat:.7f}\t{r.lon:.7f}\t"
            f"{_f(r.altitude_m, '.1f')}\t{_s(r.nacp)}\n")


def format_track(r: TrackRecord) -> str:
    return (f"{r.time:.3f}\t{_s(r.sensor)}\t{r.radar}\t{_s(r.global_)}\t{_s(r.local)}\t"
            f"{r.lat:.7f}\t{r.lon:.7f}\t{_f(r.altitude_m, '.1f')}\t{_s(r.mode_s)}\t{_s(r.mode_3a)}\n")


def format_plot(r: PlotRecord) -> str:
    return (f"{r.time:.3f}\t{_s(r.sensor)}\t{r.radar}\t{_s(r.global_)}\t{_s(r.local)}\t"
            f"{r.lat:.7f}\t{r.lon:.7f}\t{_f(r.altitude_m, '.1f')}\t{r.range_m:.1f}\t"
            f"{r.azimuth_deg:.4f}\t{_s(r.mode_s)}\t{_s(r.mode_3a)}\n")


class RecordingWriter:
    """Streams records into a recording folder (created; must not exist), all three files at once.

    Use as a context manager; ``write_*`` accept one record, ``extend`` any iterable of records. The
    files grow in ``partial`` (a hidden sibling, :func:`radartracker.io.atomic.atomic_folder`), which
    becomes ``folder`` when the block ends without an exception and is removed when it raises.
    """

    def __init__(self, folder: Path | str, *, buffer_lines: int = 20_000) -> None:
        self.folder = Path(folder)
        if self.folder.exists():
            raise FileExistsError(f"{self.folder} already exists; choose a new recording folder")
        self._commit = atomic_folder(self.folder)
        self.partial = self._commit.__enter__()
        self._fh: dict[str, IO[str]] = {}
        self._buf: dict[str, list[str]] = {}
        self._limit = buffer_lines
        try:
            for name, cols in COLUMNS.items():
                fh = open(self.partial / name, "w", encoding="utf-8", newline="\n")
                self._fh[name], self._buf[name] = fh, []
                fh.write("\t".join(cols) + "\n")
        except BaseException as exc:
            self.close(exc)
            raise

    def _put(self, name: str, line: str) -> None:
        buf = self._buf[name]
        buf.append(line)
        if len(buf) >= self._limit:
            self._fh[name].write("".join(buf))
            buf.clear()

    def write_ads(self, r: AdsRecord) -> None:
        self._put(ADS_FILE, format_ads(r))

    def write_track(self, r: TrackRecord) -> None:
        if not _TOKEN.fullmatch(r.radar):
            raise InputError(f"tracks.txt: radar must be a token of [A-Za-z0-9_.-], got {r.radar!r}")
        self._put(TRACKS_FILE, format_track(r))

    def write_plot(self, r: PlotRecord) -> None:
        if not _TOKEN.fullmatch(r.radar):
            raise InputError(f"plots.txt: radar must be a token of [A-Za-z0-9_.-], got {r.radar!r}")
        self._put(PLOTS_FILE, format_plot(r))

    def extend(self, records: Iterable[AdsRecord | TrackRecord | PlotRecord]) -> None:
        for r in records:
            if isinstance(r, PlotRecord):
                self.write_plot(r)
            elif isinstance(r, TrackRecord):
                self.write_track(r)
            elif isinstance(r, AdsRecord):
                self.write_ads(r)
            else:
                raise TypeError(f"not a recording record: {r!r}")

    def flush(self) -> None:
        for name, fh in self._fh.items():
            fh.write("".join(self._buf[name]))
            self._buf[name].clear()
            fh.flush()

    def close(self, exc: BaseException | None = None) -> None:
        """Finish the files and rename the folder into place; with ``exc``, discard it instead."""
        try:
            if exc is None:
                self.flush()
        finally:
            for fh in self._fh.values():
                fh.close()
            self._fh.clear()
        if exc is None:
            self._commit.__exit__(None, None, None)
        else:
            self._commit.__exit__(type(exc), exc, exc.__traceback__)

    def __enter__(self) -> RecordingWriter:
        return self

    def __exit__(self, exc_type: object, exc: BaseException | None, tb: object) -> None:
        self.close(exc)


def write_recording(folder: Path | str, records: Iterable[AdsRecord | TrackRecord | PlotRecord]) -> Path:
    """Write any iterable of records (streamed, any size) as a recording folder; returns it."""
    with RecordingWriter(folder) as w:
        w.extend(records)
    return Path(folder)


# --- .new4 and OziExplorer .plt ------------------------------------------------------------------

class TrackPoints(NamedTuple):
    """Points of one converted track: time (s UTC), lat, lon (deg), altitude (m, NaN = missing)."""

    time: np.ndarray
    lat: np.ndarray
    lon: np.ndarray
    altitude_m: np.ndarray


def format_new4(time, lat, lon, alt) -> str:
    """``.new4`` text: per line time, latitude, longitude, altitude (m) separated by tabs (seed §2.6)."""
    return "".join(
        f"{t:.3f}\t{la:.7f}\t{lo:.7f}\t{'nan' if a != a else format(a, '.1f')}\n"
        for t, la, lo, a in zip(np.asarray(time, float).tolist(), np.asarray(lat, float).tolist(),
                                np.asarray(lon, float).tolist(), np.asarray(alt, float).tolist())
    )


def ozi_days(time_s: float) -> float:
    """OziExplorer (Delphi) date: days since 1899-12-30 00:00 UTC of a Unix time in seconds."""
    return _UNIX_EPOCH_DAYS + time_s / 86400.0


def format_plt(time, lat, lon, alt, name: str) -> str:
    """OziExplorer track file: six header lines, then ``lat,lon,break,alt_ft,days,date,time``.

    Altitude in feet (-777 = not valid); the date field is days since 1899-12-30 (fractional).
    """
    t = np.asarray(time, float)
    head = (f"OziExplorer Track Point File Version 2.1\nWGS 84\nAltitude is in Feet\nReserved 3\n"
            f"0,2,255,{name.replace(',', ' ')},0,0,2,8421376\n{len(t)}\n")
    day = np.floor(t / 86400.0)
    sec = np.floor(t - day * 86400.0).astype(np.int64).tolist()
    dates = {d: f"{_dt.date(1970, 1, 1) + _dt.timedelta(days=d):%d-%b-%y}" for d in set(day.astype(int).tolist())}
    a_ft = np.asarray(alt, float) / FEET
    rows = [
        f"{la:.7f},{lo:.7f},{1 if i == 0 else 0},{'-777' if a != a else format(a, '.1f')},"
        f"{_UNIX_EPOCH_DAYS + ti / 86400.0:.10f},{dates[d]},{s // 3600:02d}:{s // 60 % 60:02d}:{s % 60:02d}\n"
        for i, (ti, la, lo, a, d, s) in enumerate(zip(t.tolist(), np.asarray(lat, float).tolist(),
                                                      np.asarray(lon, float).tolist(), a_ft.tolist(),
                                                      day.astype(int).tolist(), sec))
    ]
    return head + "".join(rows)


def write_new4(path: Path | str, pts: TrackPoints) -> None:
    """Write a ``.new4`` file atomically."""
    write_text(path, format_new4(*pts))


def write_plt(path: Path | str, pts: TrackPoints, name: str = "track") -> None:
    """Write an OziExplorer ``.plt`` file atomically."""
    write_text(path, format_plt(*pts, name=name))


def _bad(path: Path, line: int, field: str, text: str) -> FormatError:
    return FormatError(str(path), line, field, text)


_NEW4_RANGE = {"time": BOUNDS["unix_time_s"][:2], "lat": (-90.0, 90.0), "lon": (-180.0, 180.0)}


def _text_lines(path: Path, errors: str = "strict") -> list[str]:
    """Lines of a UTF-8 file (a byte-order mark is skipped); a FormatError names the line of a bad byte."""
    data = read_bytes(path)  # a regular file, no line longer than the limit (radartracker.io.limits)
    try:
        return data.decode("utf-8-sig", errors).splitlines()
    except UnicodeDecodeError as exc:
        raise _bad(path, data[:exc.start].count(b"\n") + 1, "line",
                   f"not UTF-8 text (byte {exc.start} is {data[exc.start]:#04x})") from None


def read_new4(path: Path | str) -> TrackPoints:
    """Read a ``.new4`` file; a FormatError (file, line, field) on a bad line (lat/lon out of range too)."""
    path = Path(path)
    cols: list[list[float]] = [[], [], [], []]
    for n, line in enumerate(_text_lines(path), 1):
        if not line.strip():
            continue
        parts = line.split("\t")
        if len(parts) != 4:
            raise _bad(path, n, "line", f"expected 4 tab-separated fields, got {len(parts)}")
        for c, (field, text) in enumerate(zip(("time", "lat", "lon", "altitude_m"), parts)):
            try:
                v = float(text)
            except ValueError:
                raise _bad(path, n, field, f"not a number: {text!r}") from None
            if c < 3 and not math.isfinite(v):
                raise _bad(path, n, field, f"must be finite, got {text!r}")
            lo, hi = _NEW4_RANGE.get(field, (-math.inf, math.inf))
            if not lo <= v <= hi and c < 3:
                raise _bad(path, n, field, f"{v!r} outside [{lo:g}, {hi:g}]")
            cols[c].append(v)
    return TrackPoints(*(np.asarray(c, float) for c in cols))


def read_plt(path: Path | str) -> TrackPoints:
    """Read an OziExplorer ``.plt`` track (time from the days field; altitude feet → metres)."""
    path = Path(path)
    cols: list[list[float]] = [[], [], [], []]
    lines = iter(enumerate(_text_lines(path, "replace"), 1))  # names may be in a Windows code page
    first = next(lines, (1, ""))[1]
    if not first.startswith("OziExplorer Track Point File"):
        raise _bad(path, 1, "header", "not an OziExplorer track file")
    for _ in range(5):
        if next(lines, None) is None:
            raise _bad(path, 1, "header", "truncated: fewer than six header lines")
    for n, line in lines:
        if not line.strip():
            continue
        parts = [p.strip() for p in line.split(",")]
        if len(parts) < 5:
            raise _bad(path, n, "line", f"expected at least 5 comma-separated fields, got {len(parts)}")
        try:
            lat, lon, alt_ft, days = float(parts[0]), float(parts[1]), float(parts[3]), float(parts[4])
        except ValueError:
            raise _bad(path, n, "line", f"bad number in {line.strip()!r}") from None
        if not (-90 <= lat <= 90 and -180 <= lon <= 180):
            raise _bad(path, n, "lat/lon", f"out of range: {lat}, {lon}")
        if (why := bound("unix_time_s", (days - _UNIX_EPOCH_DAYS) * 86400.0)) is not None:
            raise _bad(path, n, "days", f"{parts[4]!r}: {why}")
        cols[0].append((days - _UNIX_EPOCH_DAYS) * 86400.0)
        cols[1].append(lat)
        cols[2].append(lon)
        cols[3].append(math.nan if alt_ft == -777 else alt_ft * FEET)
    return TrackPoints(*(np.asarray(c, float) for c in cols))


def read_converted(folder: Path | str) -> dict[str, TrackPoints]:
    """All ``.new4`` tracks of one aircraft folder ``new/<global>/``, keyed by file stem."""
    return {p.stem: read_new4(p) for p in sorted(Path(folder).glob("*.new4"))}


# --- synthetic recordings of any size --------------------------------------------------------------

def synthetic_records(*, seed: int = 0, batches: int | None = None, aircraft_per_batch: int = 100,
                      flight_s: float = 1200.0, t0: float = 1.7e9,
                      center: tuple[float, float] = (56.8, 60.6)) -> Iterator[list]:
    """Batches of records of a synthetic recording (endless when ``batches`` is None).

    Each batch: ``aircraft_per_batch`` straight flights sharing one time window of ``flight_s``;
    ADS-B every second (70 % of aircraft; 10 % only for their first 10 s), a multi-radar track every
    4 s, and for four radars (periods 4, 5, 6, 10 s) a plot and a monoradar track update per scan.
    Plot range/azimuth come from the exact pyproj geometry, lat/lon from the noisy measurement;
    2 % extra false plots carry no global number. Records within a batch are in time order.
    """
    from radartracker.geometry.plane import RadarFrame, SystemPlane

    rng = np.random.default_rng(seed)
    plane = SystemPlane(*center)
    sites = [("1", 60e3, 0.0, 4.0), ("2", -60e3, 20e3, 5.0), ("3", 0.0, 70e3, 6.0), ("4", 10e3, -80e3, 10.0)]
    frames = []
    for name, x, y, period in sites:
        la, lo = plane.to_geodetic(x, y)
        frames.append((name, RadarFrame(float(la), float(lo), 300.0, plane), period))
    b = 0
    while batches is None or b < batches:
        w0 = t0 + b * flight_s
        n = aircraft_per_batch
        g0 = 1 + b * n
        xy0 = rng.uniform(-120e3, 120e3, (n, 2))
        hdg = rng.uniform(0, 2 * np.pi, n)
        v = rng.uniform(180.0, 250.0, n)
        alt = rng.uniform(6000.0, 11000.0, n)
        equip = rng.choice(3, n, p=[0.7, 0.1, 0.2])  # full ADS-B, first 10 s only, none
        icao = [f"{0x400000 + g0 + i:06x}" for i in range(n)]
        recs: list[tuple[float, object]] = []

        def pos(i: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            dt = t - w0
            return plane.to_geodetic(xy0[i, 0] + v[i] * np.sin(hdg[i]) * dt,
                                     xy0[i, 1] + v[i] * np.cos(hdg[i]) * dt)

        ta = np.arange(0.0, flight_s, 1.0) + w0
        ai, at = np.meshgrid(np.arange(n), ta, indexing="ij")
        keep = (equip[ai] == 0) | ((equip[ai] == 1) & (at - w0 < 10.0))
        ai, at = ai[keep], at[keep]
        la, lo = pos(ai, at)
        for i, t, a, o in zip(ai.tolist(), at.tolist(), la.tolist(), lo.tolist()):
            recs.append((t, AdsRecord(t, g0 + i, icao[i], a, o, float(alt[i]), 8)))
        tm = np.arange(0.0, flight_s, 4.0) + w0
        mi, mt = (m.ravel() for m in np.meshgrid(np.arange(n), tm, indexing="ij"))
        la, lo = pos(mi, mt)
        la, lo = la + rng.normal(0, 2e-4, la.shape), lo + rng.normal(0, 3e-4, lo.shape)
        for i, t, a, o in zip(mi.tolist(), mt.tolist(), la.tolist(), lo.tolist()):
            recs.append((t, TrackRecord(t, None, MULTI_RADAR, g0 + i, None, a, o, float(alt[i]), icao[i])))
        for r, (name, frame, period) in enumerate(frames):
            ts = np.arange(rng.uniform(0, period), flight_s, period) + w0
            pi, pt = (m.ravel() for m in np.meshgrid(np.arange(n), ts, indexing="ij"))
            la, lo = pos(pi, pt)
            rho, theta, _ = frame.polar(la, lo, alt[pi])
            inside = rho < 250e3
            pi, pt, la, lo, rho, theta = (q[inside] for q in (pi, pt, la, lo, rho, theta))
            rho = rho + rng.normal(0, 50.0, rho.shape)
            theta = np.mod(theta + rng.normal(0, np.radians(0.05), theta.shape), 2 * np.pi)
            pla, plo, _ = frame.locate(rho, theta, alt[pi])
            sensor = rng.choice(np.array(["3", "2", "1"]), len(pi), p=[0.7, 0.2, 0.1]).tolist()
            az = np.degrees(theta)
            mla, mlo = la + rng.normal(0, 1e-4, la.shape), lo + rng.normal(0, 2e-4, lo.shape)
            for k, (i, t) in enumerate(zip(pi.tolist(), pt.tolist())):
                g = g0 + i
                if rng.random() < 0.02:  # a false plot, not associated
                    recs.append((t, PlotRecord(t, "1", name, None, None, float(la[k]) + 0.01,
                                               float(lo[k]), None, float(rho[k]), float(az[k]))))
                recs.append((t, PlotRecord(t, sensor[k], name, g, 100 * r + i, float(pla[k]), float(plo[k]),
                                           float(alt[i]), float(rho[k]), float(az[k]), icao[i], None)))
                recs.append((t + 0.5, TrackRecord(t + 0.5, sensor[k], name, g, 100 * r + i, float(mla[k]),
                                                  float(mlo[k]), float(alt[i]), icao[i], None)))
        recs.sort(key=lambda tr: tr[0])
        yield [r for _, r in recs]
        b += 1


def write_synthetic_recording(folder: Path | str, *, target_bytes: int | None = None,
                              batches: int | None = None, seed: int = 0, **kw) -> int:
    """Write a synthetic recording until it holds ``target_bytes`` or ``batches`` batches; returns bytes."""
    if target_bytes is None and batches is None:
        raise ValueError("give target_bytes or batches")
    folder = Path(folder)
    with RecordingWriter(folder) as w:
        for batch in synthetic_records(seed=seed, batches=batches, **kw):
            w.extend(batch)
            if target_bytes is not None:
                w.flush()
                if sum((w.partial / n).stat().st_size for n in COLUMNS) >= target_bytes:
                    break
    return sum((folder / n).stat().st_size for n in COLUMNS)


def scenario_records(data) -> Iterator[AdsRecord | PlotRecord]:
    """Records of a simulated (or read) :class:`~radartracker.formats.ScenarioData`, in time order.

    ``global`` is the aircraft's position in ``data.aircraft`` + 1 (plots without a known target:
    empty); plot lat/lon come from the measured range/azimuth at the plot's altitude with the exact
    geometry (altitude missing: located at 0 m); ``sensor`` is 5 (Mode S) when the plot carries a
    Mode S address, else 2 (SSR) with a Mode 3/A code, else 1 (PSR). The simulator has no tracker, so
    no ``tracks.txt`` records come from it.
    """
    from radartracker.geometry.plane import RadarFrame, SystemPlane

    number = {a.icao24: i + 1 for i, a in enumerate(data.aircraft)}
    plane = SystemPlane(*data.reference)
    p = data.plots
    lat, lon = np.full(len(p), np.nan), np.full(len(p), np.nan)
    for radar in data.radars:
        idx = np.flatnonzero(p.radar == radar.id)
        frame = RadarFrame(radar.lat, radar.lon, radar.height_m, plane)
        lat[idx], lon[idx], _ = frame.locate(p.range_m[idx], p.azimuth_rad[idx],
                                             np.nan_to_num(p.altitude_m[idx], nan=0.0))
    out: list[tuple[float, int, AdsRecord | PlotRecord]] = []
    for k in range(len(p)):
        ms, m3 = p.mode_s[k], p.mode_3a[k]
        alt = float(p.altitude_m[k])
        out.append((float(p.time[k]), 1, PlotRecord(
            float(p.time[k]), "5" if ms else "2" if m3 else "1", str(p.radar[k]), number.get(p.target[k]),
            None, float(lat[k]), float(lon[k]), None if alt != alt else alt, float(p.range_m[k]),
            float(np.degrees(p.azimuth_rad[k])), ms, m3)))
    a = data.adsb
    for k in range(len(a)):
        alt = float(a.altitude_m[k])
        out.append((float(a.time[k]), 0, AdsRecord(float(a.time[k]), number.get(a.icao24[k]), a.icao24[k],
                                                   float(a.lat[k]), float(a.lon[k]),
                                                   None if alt != alt else alt, int(a.nacp[k]))))
    out.sort(key=lambda r: (r[0], r[1]))
    return (r for _, _, r in out)


def write_scenario_recording(folder: Path | str, data) -> Path:
    """Write a :class:`~radartracker.formats.ScenarioData` (e.g. ``simulate`` output) as a recording."""
    return write_recording(folder, scenario_records(data))
