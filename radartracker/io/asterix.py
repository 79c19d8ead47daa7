"""EUROCONTROL ASTERIX records encoded and decoded: CAT048 (monoradar target reports) and CAT021
(ADS-B) written from a :class:`~radartracker.io.tables.ScenarioData`, CAT062 (system tracks) written
from a replay, and each record decoded into our fields. Encoding and decoding use ``libasterix``
(MIT, pure Python, generated from the asterix-specs definitions); this module only maps our fields
to the items:

* CAT048 ed. 1.32: I010 SAC/SIC, I140 time of day (1/128 s), I020 TYP, I040 ρ (1/256 NM) and
  θ (360°/2¹⁶), I070 Mode 3/A, I090 flight level (1/4 FL), I220 Mode S address.
* CAT021 ed. 2.6: I010, I040 (ATP 24-bit address), I071 time of applicability (1/128 s), I131 WGS-84
  position (180°/2³⁰), I080 address, I145 flight level (1/4 FL), I090 NACp.
* CAT062 ed. 1.21: I010, I015, I070 time (1/128 s), I105 WGS-84 position (180°/2²⁵), I100 plane
  x, y (0.5 m), I185 velocity (0.25 m/s), I040 track number, I080 track status, I136 flight level.

Altitudes: our ``altitude_m`` is the barometric (pressure) altitude; 1 FL = 100 ft. Times are
written as seconds of the UTC day (t mod 86400). CAT048 carries no radar site: :func:`write_asterix`
writes the sites beside the recording as ``<file>.radars.csv`` (the scenario ``radars.csv`` columns
plus ``sac`` and ``sic``). Writing emits raw concatenated data blocks; the capture containers are
:mod:`radartracker.io.capture`, reading a recording back is :mod:`radartracker.io.asterix_reader`.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any

import numpy as np
from asterix.base import Bits, RawDatablock
import asterix.generated as gen

from radartracker.domain import Radar
from radartracker.errors import InputError
from radartracker.io.atomic import atomic_open
from radartracker.io.tables import RADAR_COLUMNS, ScenarioData
from radartracker.progress import progress_bar

CAT048, CAT021, CAT062 = gen.Cat_048_1_32, gen.Cat_021_2_6, gen.Cat_062_1_21
NM, FT = 1852.0, 0.3048
FL_M = 100 * FT
DAY = 86400.0
MAX_BLOCK = 60_000  # bytes of records per data block (the length field allows 65535)


# --- encoding --------------------------------------------------------------------------------------

def _tod(t: float) -> float:
    return float(t) % DAY


def cat048_record(time: float, sac: int, sic: int, range_m: float, azimuth_rad: float,
                  altitude_m: float | None = None, mode_s: str | None = None, mode_3a: str | None = None,
                  extra: dict | None = None):
    """One CAT048 target report (TYP: 5 Mode S roll-call, 2 SSR, 1 PSR as the codes present);
    ``extra`` adds items (a local track's I161/I200/I170)."""
    typ = 5 if mode_s else 2 if mode_3a else 1
    items: dict = {
        "010": (("SAC", sac), ("SIC", sic)),
        "140": (_tod(time), "s"),
        "020": ((typ, 0, 0, 0, 0, None),),
        "040": (("RHO", (range_m / NM, "NM")), ("THETA", (math.degrees(azimuth_rad) % 360.0, "°"))),
        **(extra or {}),
    }
    if mode_3a:
        items["070"] = (0, 0, 0, 0, ("MODE3A", mode_3a))
    if altitude_m is not None and math.isfinite(altitude_m):
        items["090"] = (0, 0, ("FL", (altitude_m / FL_M, "FL")))
    if mode_s:
        items["220"] = int(mode_s, 16)
    return CAT048.cv_record.create(items)


def cat021_record(time: float, sac: int, sic: int, icao24: str, lat: float, lon: float,
                  altitude_m: float | None = None, nacp: int | None = None):
    """One CAT021 ADS-B report (24-bit ICAO address, high-resolution position)."""
    items: dict = {
        "010": (("SAC", sac), ("SIC", sic)),
        "040": ((1, 0, 0, 0, None),),  # ATP = 1: 24-bit ICAO address
        "071": (_tod(time), "s"),
        "131": (("LAT", (lat, "°")), ("LON", (lon, "°"))),
        "080": int(icao24, 16),
    }
    if altitude_m is not None and math.isfinite(altitude_m):
        items["145"] = (altitude_m / FL_M, "FL")
    if nacp is not None:
        items["090"] = ((0, 0, None), (0, 0, int(nacp), None))
    return CAT021.cv_record.create(items)


def cat062_record(time: float, sac: int, sic: int, track_number: int, lat: float, lon: float,
                  x_m: float, y_m: float, vx_mps: float, vy_mps: float, altitude_m: float | None = None, *,
                  mode_3a: str | None = None, mode_s: str | None = None, coasting: bool = False,
                  ended: bool = False):
    """One CAT062 system track update (position in WGS-84 and in the system plane, velocity).

    I080: CNF = 0 (confirmed); with ``coasting`` or ``ended`` the extents up to the fourth are sent,
    TSE (last update of the track) and CST (coasted: no plot in the last scan) set as given.
    """
    items: dict = {
        "010": (("SAC", sac), ("SIC", sic)),
        "015": 0,
        "070": (_tod(time), "s"),
        "105": (("LAT", (lat, "°")), ("LON", (lon, "°"))),
        "100": (("X", (x_m, "m")), ("Y", (y_m, "m"))),
        "185": (("VX", (vx_mps, "m/s")), ("VY", (vy_mps, "m/s"))),
        "040": int(track_number),
        "080": (0, 32 * ended, 0, 64 * coasting) if coasting or ended else (0,),
    }
    if altitude_m is not None and math.isfinite(altitude_m):
        items["136"] = (altitude_m / FL_M, "FL")
    if mode_3a:
        items["060"] = (0, 0, 0, 0, ("MODE3A", mode_3a))
    if mode_s:
        items["380"] = {"ADR": int(mode_s, 16)}
    return CAT062.cv_record.create(items)


def datablocks(cat, records: Iterable, max_bytes: int = MAX_BLOCK) -> Iterator[bytes]:
    """Pack records into data blocks of at most ``max_bytes`` bytes of records."""
    batch: list = []
    size = 0
    for rec in records:
        n = len(rec.unparse().to_bytes())
        if batch and size + n > max_bytes:
            yield cat.create(batch).unparse().to_bytes()
            batch, size = [], 0
        batch.append(rec)
        size += n
    if batch:
        yield cat.create(batch).unparse().to_bytes()


def sac_sic_of(data: ScenarioData, sac: int = 0) -> dict[str, tuple[int, int]]:
    """Our default SAC/SIC for the radars of a scenario: one SAC, SIC = position + 1."""
    return {r.id: (sac, i + 1) for i, r in enumerate(data.radars)}


def write_asterix(path: Path | str, data: ScenarioData, *, sac_sic: dict[str, tuple[int, int]] | None = None,
                  adsb_sac_sic: tuple[int, int] = (0, 200)) -> int:
    """Write the plots as CAT048 and the ADS-B reports as CAT021 (raw blocks, in time order) and the
    radar sites as ``<path>.radars.csv``; returns the number of records."""
    path = Path(path)
    if path.exists():
        raise FileExistsError(f"{path} already exists")
    sac_sic = sac_sic or sac_sic_of(data)
    missing = sorted(set(data.plots.radar.tolist()) - set(sac_sic))
    if missing:
        raise ValueError(f"no SAC/SIC for radar(s) {', '.join(missing)}")
    p, a = data.plots, data.adsb
    events = sorted([(float(p.time[i]), 0, i) for i in range(len(p))] + [(float(a.time[i]), 1, i) for i in range(len(a))])
    # a progress bar on stderr once writing takes 2 s (off with --quiet): encoding is pure Python
    bar = progress_bar(total=len(events), desc=f"write {path.name}", unit="record")
    with atomic_recording(path, data.radars, sac_sic) as fh, bar:
        for cat, group in _runs(events):
            if cat == 0:
                recs = (cat048_record(p.time[i], *sac_sic[p.radar[i]], p.range_m[i], p.azimuth_rad[i],
                                      p.altitude_m[i], p.mode_s[i], p.mode_3a[i]) for i in _ticking(group, bar))
                fh.writelines(datablocks(CAT048, recs))
            else:
                recs = (cat021_record(a.time[i], *adsb_sac_sic, a.icao24[i], a.lat[i], a.lon[i],
                                      a.altitude_m[i], int(a.nacp[i])) for i in _ticking(group, bar))
                fh.writelines(datablocks(CAT021, recs))
    return len(events)


def _ticking(items: Iterable[int], bar: Any) -> Iterator[int]:
    """``items``, ``bar`` moved on by each one once it is used."""
    for item in items:
        yield item
        bar.update()


@contextmanager
def atomic_recording(path: Path, radars: list[Radar], sac_sic: dict[str, tuple[int, int]]) -> Iterator[IO[bytes]]:
    """The binary file of a new recording ``path`` and its ``.radars.csv`` sidecar, both atomic.

    The sidecar is renamed into place first and the recording last, so a recording that exists has
    its sidecar; when the block fails neither is left (a SIGKILL between the two renames can leave
    the sidecar alone, which no command reads without its recording).
    """
    sites = sidecar_of(path)
    sites_written = False
    try:
        with atomic_open(path, "wb") as fh:
            yield fh
            write_sites(sites, radars, sac_sic)
            sites_written = True
    except BaseException:
        if sites_written:
            sites.unlink(missing_ok=True)
        raise


def _runs(events: list[tuple[float, int, int]]) -> Iterator[tuple[int, list[int]]]:
    """Consecutive runs of the same category (0: CAT048, 1: CAT021) in time order."""
    cat, run = None, []
    for _, c, i in events:
        if c != cat and run:
            yield cat, run
            run = []
        cat = c
        run.append(i)
    if run:
        yield cat, run


def sidecar_of(path: Path | str) -> Path:
    """The radar sites file beside a recording: ``<path>.radars.csv``."""
    return Path(str(path) + ".radars.csv")


def write_sites(path: Path, radars: list[Radar], sac_sic: dict[str, tuple[int, int]]) -> None:
    """The ``.radars.csv`` sidecar (radars.csv columns plus SAC/SIC), written atomically."""
    with atomic_open(path, "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(RADAR_COLUMNS + ("sac", "sic"))
        for r in radars:
            if r.id in sac_sic:
                w.writerow([r.id, f"{r.lat:.8f}", f"{r.lon:.8f}", f"{r.height_m:.2f}", f"{r.sigma_range_m:g}",
                            f"{math.degrees(r.sigma_azimuth_rad):.6g}", f"{r.period_s:g}", f"{r.max_range_m:g}",
                            *sac_sic[r.id]])


def write_cat062(path: Path | str, result, *, sac: int = 0, sic: int = 100) -> dict:
    """Write a :class:`~radartracker.pipeline.result.RunResult`'s track estimates as CAT062 (raw blocks).

    Track ids become track numbers 1, 2, … in order of first appearance; returns that mapping. A track that
    ended (deleted or merged) gets one more record at its end, I080 TSE set (the last update of the track),
    its position the last estimate's carried on at its velocity to that time: what the system showed until
    the track was dropped. The records are written in time order (estimates before an end at the same time).
    """
    path = Path(path)
    if path.exists():
        raise FileExistsError(f"{path} already exists")
    numbers: dict = {}
    tracks = result.tracks
    for k in tracks.track.tolist():
        numbers.setdefault(k, len(numbers) + 1)
    s = np.asarray(tracks.state, float)
    last = {k: i for i, k in enumerate(tracks.track.tolist())}  # each track's last estimate (time order)
    ends = result.track_ends()
    rows = [(float(tracks.time[i]), 0, i) for i in range(len(s))]
    rows += [(t, 1, last[k]) for k, t in ends.items() if k in last and t >= float(tracks.time[last[k]])]
    rows.sort(key=lambda r: (r[0], r[1]))
    t = np.array([r[0] for r in rows], float)
    src = np.array([r[2] for r in rows], int)
    xy = s[src, :2] + s[src, 2:] * (t - np.asarray(tracks.time, float)[src])[:, None]  # (N, 2)
    if rows:
        lat, lon = result.plane.to_geodetic(xy[:, 0], xy[:, 1])
    recs = (cat062_record(t[j], sac, sic, numbers[tracks.track[i]], lat[j], lon[j], xy[j, 0], xy[j, 1], s[i, 2],
                          s[i, 3], ended=bool(end))
            for j, (_, end, i) in enumerate(rows))
    with atomic_open(path, "wb") as fh:
        fh.writelines(datablocks(CAT062, recs))
    return numbers


# --- decoding --------------------------------------------------------------------------------------

class MissingItem(InputError):
    """A record without an item we need (e.g. a CAT048 track-only report without I040)."""

    def __init__(self, item: str) -> None:
        super().__init__(f"no I{item}")
        self.item = item


def _need(rec, item: str):
    i = rec.get_item(item)
    if i is None:
        raise MissingItem(item)
    return i.variation


def _q(rec, item: str, sub: str | None, unit: str) -> float | None:
    i = rec.get_item(item)
    if i is None:
        return None
    v = i.variation if sub is None else i.variation.get_item(sub).variation
    return v.content.as_quantity(unit)


def decode_block(block: bytes, where: str) -> tuple[int, list]:
    """(category, decoded records) of one data block; categories other than 021/048/062: no records.

    A block the library cannot decode (another edition, damaged bytes) is an :class:`InputError`.
    """
    try:
        raw = RawDatablock.parse(Bits.from_bytes(block))
        if isinstance(raw, ValueError):
            raise InputError(f"{where}: {raw}")
        cat = raw[0].get_category()
        spec = {48: CAT048, 21: CAT021, 62: CAT062}.get(cat)
        if spec is None:
            return cat, []
        recs = spec.cv_uap.parse(raw[0].get_raw_records())
    except InputError:
        raise
    except Exception as exc:  # the decoder of untrusted bytes may fail in any way: the block is unusable
        raise InputError(f"{where}: block does not decode: {type(exc).__name__}: {exc}") from None
    if isinstance(recs, ValueError):
        raise InputError(f"{where}: CAT{cat:03d} block does not decode: {recs}")
    return cat, recs


def decode_cat048(rec) -> dict:
    """Our fields of one CAT048 record; :class:`MissingItem` without I010, I140 or I040."""
    i010 = _need(rec, "010")
    _need(rec, "140"), _need(rec, "040")
    fl = _q(rec, "090", "FL", "FL")
    i070, i220 = rec.get_item("070"), rec.get_item("220")
    return {
        "sac": i010.get_item("SAC").as_uint(), "sic": i010.get_item("SIC").as_uint(),
        "tod": _q(rec, "140", None, "s"),
        "range_m": _q(rec, "040", "RHO", "NM") * NM,
        "azimuth_rad": math.radians(_q(rec, "040", "THETA", "°")),
        "altitude_m": math.nan if fl is None else fl * FL_M,
        "mode_3a": None if i070 is None else i070.variation.get_item("MODE3A").variation.content.as_string(),
        "mode_s": None if i220 is None else f"{i220.variation.as_uint():06x}",
    }


def decode_cat021(rec) -> dict:
    """Our fields of one CAT021 record; :class:`MissingItem` without I080, a time or a position."""
    _need(rec, "080")
    if rec.get_item("131") is None:
        _need(rec, "130")
    if rec.get_item("071") is None:
        _need(rec, "073")
    fl = _q(rec, "145", None, "FL")
    tod = _q(rec, "071", None, "s")
    i090 = rec.get_item("090")
    nacp = i090.variation.get_item("NACP") if i090 is not None else None
    if _q(rec, "131", "LAT", "°") is not None:
        lat, lon = _q(rec, "131", "LAT", "°"), _q(rec, "131", "LON", "°")
    else:
        lat, lon = _q(rec, "130", "LAT", "°"), _q(rec, "130", "LON", "°")
    return {
        "tod": tod if tod is not None else _q(rec, "073", None, "s"),
        "icao24": f"{rec.get_item('080').variation.as_uint():06x}",
        "lat": lat, "lon": lon,
        "altitude_m": math.nan if fl is None else fl * FL_M,
        "nacp": None if nacp is None else nacp.as_uint(),
    }


def decode_cat062(rec) -> dict:
    """Our fields of one CAT062 record; :class:`MissingItem` without I010, I040, I070 or I080."""
    for item in ("010", "040", "070", "080"):
        _need(rec, item)
    fl = _q(rec, "136", None, "FL")
    i060, i380, i080 = rec.get_item("060"), rec.get_item("380"), rec.get_item("080").variation
    adr = None if i380 is None else i380.variation.get_item("ADR")
    return {
        "sac": rec.get_item("010").variation.get_item("SAC").as_uint(),
        "sic": rec.get_item("010").variation.get_item("SIC").as_uint(),
        "mode_3a": None if i060 is None else i060.variation.get_item("MODE3A").variation.content.as_string(),
        "mode_s": None if adr is None else f"{adr.variation.as_uint():06x}",
        "coasting": bool(i080.get_item("CST") and i080.get_item("CST").as_uint()),
        "ended": bool(i080.get_item("TSE") and i080.get_item("TSE").as_uint()),
        "tod": _q(rec, "070", None, "s"), "track_number": rec.get_item("040").variation.as_uint(),
        "lat": _q(rec, "105", "LAT", "°"), "lon": _q(rec, "105", "LON", "°"),
        "x_m": _q(rec, "100", "X", "m"), "y_m": _q(rec, "100", "Y", "m"),
        "vx_mps": _q(rec, "185", "VX", "m/s"), "vy_mps": _q(rec, "185", "VY", "m/s"),
        "altitude_m": math.nan if fl is None else fl * FL_M,
    }
