"""The seed's conversion program ``tracks_plots_00`` (seed 000 §2.6, DESIGN §8), streaming.

Input: a recording folder with ``plots_ads.txt``, ``tracks.txt``, ``plots.txt`` (columns in
:mod:`radartracker.io.recording`). Output ``new/<global>/``: ``ads``, ``240_mr`` (multi-radar track),
``<radar>_mr`` (monoradar tracks) and ``<radar>_r`` (radar plots), each as ``.new4`` and ``.plt``,
plus ``new/report.json`` accounting for every input line.

Algorithm, in memory bounded by the number of distinct global track numbers plus one bucket:

1. read ``plots_ads.txt``: count valid ADS-B reports per global track number; select at most
   AZN_TRACKS_MAX globals with at least AZN_TRACKS_MIN_MEASUR reports, most reports first (ties:
   smaller global first);
2. read all three files again; every valid record of a selected aircraft (radar and monoradar records
   only if ``sensor`` == RADAR_SENSOR_ONLY) is appended as a fixed-size binary record to one of K
   bucket files on disk (K grows with the input size so a bucket stays near ``bucket_bytes``);
3. per bucket: load it, sort by (global, kind, radar, time, line), drop tracks with fewer than
   TRACKS_MIN_MEASUR points, write the files.

Everything is written into a hidden sibling of the output folder that is renamed at the end
(:func:`radartracker.io.atomic.atomic_folder`), so an error or a crash never leaves a half-written
output folder.
"""

from __future__ import annotations

import json
import math
import shutil
import time as _time
from collections import Counter
from collections.abc import Callable, Iterator
from pathlib import Path

import attrs
import numpy as np

from radartracker.errors import FormatError
from radartracker.io.atomic import atomic_folder
from radartracker.io.convert_options import ConvertOptions
from radartracker.io.limits import BOUNDS, MAX_LINE_BYTES, check_lines, regular_file
from radartracker.io.recording import ADS_FILE, COLUMNS, MULTI_RADAR, PLOTS_FILE, TRACKS_FILE, format_new4, format_plt

KIND_ADS, KIND_MULTI, KIND_MONO, KIND_PLOT = 0, 1, 2, 3
_KIND_FILE = {KIND_ADS: ADS_FILE, KIND_MULTI: TRACKS_FILE, KIND_MONO: TRACKS_FILE, KIND_PLOT: PLOTS_FILE}
SPOOL_DTYPE = np.dtype([("global", "<i8"), ("kind", "u1"), ("radar", "<u4"), ("line", "<i8"),
                        ("time", "<f8"), ("lat", "<f8"), ("lon", "<f8"), ("alt", "<f8")])
MAX_LISTED_LINES = 10_000  # line numbers of bad lines kept per reason (the count is always exact)
_FLUSH_RECORDS = 100_000
_READ_BYTES = 1 << 20
UNIX_TIME_S = BOUNDS["unix_time_s"][:2]


class _Tally:
    """Per input file: a count per reason; for blank and malformed lines also their line numbers."""

    def __init__(self) -> None:
        self.counts: Counter[str] = Counter()
        self.lines: dict[str, list[int]] = {}
        self.errors: list[dict] = []
        self.total = 0  # lines in the file, set when it has been read

    def add(self, reason: str, line: int | None = None, n: int = 1, error: str | None = None) -> None:
        self.counts[reason] += n
        if line is not None:
            listed = self.lines.setdefault(reason, [])
            if len(listed) < MAX_LISTED_LINES:
                listed.append(line)
        if error is not None and len(self.errors) < 100:
            self.errors.append({"line": line, "error": error})

    def as_dict(self, total: int) -> dict:
        out = {"lines": total, **{k: self.counts[k] for k in sorted(self.counts)}}
        out["line_numbers"] = {k: v for k, v in sorted(self.lines.items())}
        out["line_numbers_truncated"] = any(self.counts[k] > len(v) for k, v in self.lines.items())
        if self.errors:
            out["first_errors"] = self.errors
        return out


def _lines(path: Path) -> Iterator[tuple[int, bytes, bool]]:
    """(line number, line without its LF/CRLF, whether it ended with a newline) of a regular file; a line
    longer than :data:`radartracker.io.limits.MAX_LINE_BYTES` is a FormatError naming it."""
    with open(regular_file(path), "rb", buffering=_READ_BYTES) as fh:
        for n, raw in enumerate(iter(lambda: fh.readline(MAX_LINE_BYTES + 1), b""), 1):
            ended = raw.endswith(b"\n")
            if len(raw) > MAX_LINE_BYTES and not ended:
                check_lines(path.name, raw, n)
            yield n, raw.rstrip(b"\r\n") if ended else raw.rstrip(b"\r"), ended


def _header(path: Path) -> dict[str, int]:
    """Column indices of the required columns; a FormatError for a missing, repeated or bad header."""
    required = COLUMNS[path.name]
    with open(regular_file(path), "rb") as fh:
        first = fh.readline(MAX_LINE_BYTES + 1)
    check_lines(path.name, first)
    if not first.strip():
        raise FormatError(path.name, 1, None, "empty file or blank header; expected the columns "
                          f"{', '.join(required)} separated by tabs")
    try:
        names = [n.strip() for n in first.rstrip(b"\r\n").decode("utf-8-sig").split("\t")]
    except UnicodeDecodeError:
        raise FormatError(path.name, 1, None, "not UTF-8 text: not a recording file") from None
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise FormatError(path.name, 1, None, f"column(s) {', '.join(twice)} appear more than once")
    index = {name: i for i, name in enumerate(names)}
    missing = [c for c in required if c not in index]
    if missing:
        raise FormatError(path.name, 1, None, f"header lacks column(s) {', '.join(missing)} "
                          f"(found: {', '.join(names)})")
    return index


class _Bad(Exception):
    def __init__(self, field: str, text: str) -> None:
        super().__init__(f"field {field}: {text}")


def _number(parts: list[bytes], i: int, field: str, lo: float, hi: float, optional: bool = False) -> float:
    text = parts[i].strip()
    if not text and optional:
        return math.nan
    try:
        v = float(text)
    except ValueError:
        raise _Bad(field, f"not a number: {text.decode('utf-8', 'replace')!r}") from None
    if not lo <= v <= hi:  # also rejects NaN
        raise _Bad(field, f"{v!r} outside [{lo}, {hi}]")
    return v


def _make_parser(path: Path) -> Callable[[bytes], tuple]:
    """A function line -> (global or None, kind, radar token, sensor token, time, lat, lon, alt)."""
    ix = _header(path)
    ncols = max(ix.values()) + 1
    is_ads = path.name == ADS_FILE
    it, ig, ila, ilo, ial = ix["time"], ix["global"], ix["lat"], ix["lon"], ix["altitude_m"]
    ir = -1 if is_ads else ix["radar"]
    isn = -1 if is_ads else ix["sensor"]
    plot = path.name == PLOTS_FILE

    def parse(line: bytes) -> tuple:
        parts = line.split(b"\t")
        if len(parts) < ncols:
            raise _Bad("line", f"expected {ncols} tab-separated fields, got {len(parts)}")
        g = parts[ig].strip()
        if g:
            if not g.isdigit():
                raise _Bad("global", f"not a non-negative integer: {g.decode('utf-8', 'replace')!r}")
            gnum: int | None = int(g)
        else:
            gnum = None
        t = _number(parts, it, "time", *UNIX_TIME_S)  # a date (the .plt files write it as one)
        lat = _number(parts, ila, "lat", -90.0, 90.0)
        lon = _number(parts, ilo, "lon", -180.0, 180.0)
        alt = _number(parts, ial, "altitude_m", -2000.0, 100_000.0, optional=True)
        if is_ads:
            return gnum, KIND_ADS, "", "", t, lat, lon, alt
        radar = parts[ir].strip().decode("ascii", "replace")
        if not radar or not radar.replace("_", "").replace("-", "").replace(".", "").isalnum():
            raise _Bad("radar", f"must be a token of [A-Za-z0-9_.-], got {radar!r}")
        sensor = parts[isn].strip().decode("utf-8", "replace")
        kind = KIND_PLOT if plot else (KIND_MULTI if radar == MULTI_RADAR else KIND_MONO)
        return gnum, kind, radar, sensor, t, lat, lon, alt

    return parse


def _scan(path: Path, tally: _Tally | None) -> Iterator[tuple[int, tuple]]:
    """Valid parsed records of a file with their line numbers; header, blank and malformed lines are
    counted in ``tally`` (when given)."""
    parse = _make_parser(path)
    n = 0
    for n, line, ended in _lines(path):
        if n == 1:
            if tally:
                tally.add("header")
            continue
        if not line.strip():
            if tally:
                tally.add("blank", n)
            continue
        try:
            rec = parse(line)
        except _Bad as exc:
            if tally:
                reason = "malformed" if ended else "truncated_last_line"
                tally.add(reason, n, error=f"{path.name}: line {n}: {exc}")
            continue
        yield n, rec
    if tally:
        tally.total = n


def select_aircraft(ads_path: Path, opts: ConvertOptions) -> tuple[list[int], Counter[int]]:
    """Pass 1: the selected global track numbers (most ADS-B reports first) and all counts."""
    counts: Counter[int] = Counter()
    for _, rec in _scan(ads_path, None):
        if rec[0] is not None:
            counts[rec[0]] += 1
    eligible = sorted((g for g, c in counts.items() if c >= opts.AZN_TRACKS_MIN_MEASUR),
                      key=lambda g: (-counts[g], g))
    return eligible[: opts.AZN_TRACKS_MAX], counts


class _Spool:
    """K bucket files of fixed-size binary records; buffered, flushed at a bounded record count."""

    def __init__(self, folder: Path, k: int) -> None:
        folder.mkdir()
        self.paths = [folder / f"bucket{i:04d}.bin" for i in range(k)]
        self.files = [open(p, "wb") for p in self.paths]
        self.buf: list[list[tuple]] = [[] for _ in range(k)]
        self.pending = 0

    def add(self, bucket: int, rec: tuple) -> None:
        self.buf[bucket].append(rec)
        self.pending += 1
        if self.pending >= _FLUSH_RECORDS:
            self.flush()

    def flush(self) -> None:
        for fh, buf in zip(self.files, self.buf):
            if buf:
                np.array(buf, dtype=SPOOL_DTYPE).tofile(fh)
                buf.clear()
        self.pending = 0

    def close(self) -> None:
        self.flush()
        for fh in self.files:
            fh.close()


def _spool(folder: Path, opts: ConvertOptions, selected: list[int], counts: Counter[int],
           tallies: dict[str, _Tally], radars: dict[str, int], spool: _Spool) -> None:
    """Pass 2: route every valid line to a bucket or count it under its reason."""
    rank = {g: i for i, g in enumerate(selected)}
    k = len(spool.paths)
    want_sensor = opts.RADAR_SENSOR_ONLY
    for name in (ADS_FILE, TRACKS_FILE, PLOTS_FILE):
        tally = tallies[name]
        for n, (g, kind, radar, sensor, t, lat, lon, alt) in _scan(folder / name, tally):
            if g is None:
                tally.add("unassociated")
                continue
            r = rank.get(g)
            if r is None:
                reason = ("aircraft_over_AZN_TRACKS_MAX" if counts.get(g, 0) >= opts.AZN_TRACKS_MIN_MEASUR
                          else "aircraft_ads_track_too_short")
                tally.add(reason)
                continue
            if kind in (KIND_MONO, KIND_PLOT) and want_sensor is not None and sensor != want_sensor:
                tally.add("sensor_filtered")
                continue
            rid = radars.setdefault(radar, len(radars)) if kind in (KIND_MONO, KIND_PLOT) else 0
            spool.add(r % k, (g, kind, rid, n, t, lat, lon, alt))


def _write_bucket(path: Path, out: Path, opts: ConvertOptions, radar_names: list[str],
                  tallies: dict[str, _Tally], files: Counter[str]) -> None:
    """Sort one bucket and write its tracks (or count them as too short)."""
    a = np.fromfile(path, dtype=SPOOL_DTYPE)
    if not len(a):
        return
    a = a[np.lexsort((a["line"], a["time"], a["radar"], a["kind"], a["global"]))]
    key = np.stack([a["global"], a["kind"].astype(np.int64), a["radar"].astype(np.int64)], axis=1)
    starts = np.flatnonzero(np.r_[True, np.any(key[1:] != key[:-1], axis=1)])
    ends = np.r_[starts[1:], len(a)]
    for s, e in zip(starts.tolist(), ends.tolist()):
        g, kind, rid = int(a["global"][s]), int(a["kind"][s]), int(a["radar"][s])
        tally = tallies[_KIND_FILE[kind]]
        if e - s < opts.TRACKS_MIN_MEASUR:
            tally.add("track_too_short", n=e - s)
            continue
        if kind == KIND_ADS:
            stem = "ads"
        elif kind == KIND_MULTI:
            stem = f"{MULTI_RADAR}_mr"
        else:
            stem = f"{radar_names[rid]}_{'mr' if kind == KIND_MONO else 'r'}"
        seg = a[s:e]
        d = out / str(g)
        d.mkdir(exist_ok=True)
        cols = (seg["time"], seg["lat"], seg["lon"], seg["alt"])
        (d / f"{stem}.new4").write_text(format_new4(*cols), encoding="utf-8", newline="\n")
        (d / f"{stem}.plt").write_text(format_plt(*cols, name=f"{g} {stem}"), encoding="utf-8", newline="\n")
        tally.add("written", n=e - s)
        files[_KIND_FILE[kind]] += 1


def convert(recording: Path | str, out: Path | str, opts: ConvertOptions | None = None) -> dict:
    """Convert a recording folder into ``out`` (which must not exist); returns the report."""
    opts = opts or ConvertOptions()
    recording, out = Path(recording), Path(out)
    if out.exists():
        raise FileExistsError(f"{out} already exists; the output folder must not exist beforehand")
    for name in (ADS_FILE, TRACKS_FILE, PLOTS_FILE):
        if not (recording / name).is_file():
            problem = "not a file" if (recording / name).exists() else "missing"
            raise FileNotFoundError(f"{recording / name}: {problem}; a recording folder holds "
                                    f"{ADS_FILE}, {TRACKS_FILE} and {PLOTS_FILE}")
        _header(recording / name)  # fail early, before writing anything
    with atomic_folder(out) as tmp:
        report = _convert_into(recording, tmp, opts)
        shutil.rmtree(tmp / ".spool")
        (tmp / "report.json").write_text(json.dumps(report, indent=1) + "\n", encoding="utf-8")
    return report


def _convert_into(recording: Path, tmp: Path, opts: ConvertOptions) -> dict:
    t0 = _time.perf_counter()
    selected, counts = select_aircraft(recording / ADS_FILE, opts)
    sizes = {n: (recording / n).stat().st_size for n in (ADS_FILE, TRACKS_FILE, PLOTS_FILE)}
    # A binary spool record (57 B) is about half a text line: K buckets of ~bucket_bytes each.
    k = max(1, min(len(selected), math.ceil(sum(sizes.values()) / (2 * opts.bucket_bytes))))
    tallies = {n: _Tally() for n in (ADS_FILE, TRACKS_FILE, PLOTS_FILE)}
    radars: dict[str, int] = {}
    spool = _Spool(tmp / ".spool", k)
    try:
        _spool(recording, opts, selected, counts, tallies, radars, spool)
    finally:
        spool.close()
    names = list(radars)
    files: Counter[str] = Counter()
    for p in spool.paths:
        _write_bucket(p, tmp, opts, names, tallies, files)
        p.unlink()
    report_files = {}
    for name, tally in tallies.items():
        total = tally.total
        d = tally.as_dict(total)
        d["output_files"] = 2 * files[name]
        d["accounted"] = sum(v for key, v in tally.counts.items())
        if d["accounted"] != total:
            raise RuntimeError(f"internal accounting error for {name}: {d['accounted']} != {total}")
        report_files[name] = d
    return {
        "program": "tracks_plots_00 (radartracker convert)",
        "parameters": attrs.asdict(opts),
        "selected_aircraft": selected,
        "ads_reports_per_selected_aircraft": [counts[g] for g in selected],
        "aircraft_with_ads": len(counts),
        "buckets": k,
        "input_bytes": sizes,
        "seconds": round(_time.perf_counter() - t0, 3),
        "files": report_files,
    }

