"""EUROCONTROL ASTERIX in and out: CAT048 (monoradar target reports) and CAT021 (ADS-B) read into
and written from :class:`~radartracker.formats.ScenarioData`, CAT062 (system tracks) written from a
replay. Encoding and decoding use ``libasterix`` (MIT, pure Python, generated from the
asterix-specs definitions); this module only maps our fields to the items:

* CAT048 ed. 1.32: I010 SAC/SIC, I140 time of day (1/128 s), I020 TYP, I040 ρ (1/256 NM) and
  θ (360°/2¹⁶), I070 Mode 3/A, I090 flight level (1/4 FL), I220 Mode S address.
* CAT021 ed. 2.6: I010, I040 (ATP 24-bit address), I071 time of applicability (1/128 s), I131 WGS-84
  position (180°/2³⁰), I080 address, I145 flight level (1/4 FL), I090 NACp.
* CAT062 ed. 1.21: I010, I015, I070 time (1/128 s), I105 WGS-84 position (180°/2²⁵), I100 plane
  x, y (0.5 m), I185 velocity (0.25 m/s), I040 track number, I080 track status, I136 flight level.

Altitudes: our ``altitude_m`` is the barometric (pressure) altitude; 1 FL = 100 ft. ASTERIX times
are seconds of the UTC day: reading adds ``day_start`` (seconds since 1970 of the first day's
midnight; from the packet time stamps for pcap) and a day each time the time of day wraps back.
CAT048 carries no radar site: the sites come from a sidecar ``<file>.radars.csv`` (the scenario
``radars.csv`` columns plus ``sac`` and ``sic``), which :func:`write_asterix` writes.

Containers: raw concatenated data blocks (``.ast``), the FINAL record format (8-byte header: byte
count, board, line, day, time in 10 ms; 4 bytes of 0xA5 padding) and classic pcap (Ethernet/SLL/raw
IPv4, UDP); pcapng is refused with a clear message.
"""

from __future__ import annotations

import csv
import logging
import math
import struct
from collections import Counter
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO

import numpy as np
from asterix.base import Bits, RawDatablock
import asterix.generated as gen

from radartracker.domain import Aircraft, Radar
from radartracker.errors import FormatError, InputError
from radartracker.io.atomic import atomic_open
from radartracker.io.limits import regular_file
from radartracker.io.tables import RADAR_COLUMNS, AdsbTable, PlotTable, ScenarioData

CAT048, CAT021, CAT062 = gen.Cat_048_1_32, gen.Cat_021_2_6, gen.Cat_062_1_21
NM, FT = 1852.0, 0.3048
FL_M = 100 * FT
DAY = 86400.0
log = logging.getLogger(__name__)
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
    with atomic_recording(path, data.radars, sac_sic) as fh:
        for cat, group in _runs(events):
            if cat == 0:
                recs = (cat048_record(p.time[i], *sac_sic[p.radar[i]], p.range_m[i], p.azimuth_rad[i],
                                      p.altitude_m[i], p.mode_s[i], p.mode_3a[i]) for i in group)
                fh.writelines(datablocks(CAT048, recs))
            else:
                recs = (cat021_record(a.time[i], *adsb_sac_sic, a.icao24[i], a.lat[i], a.lon[i],
                                      a.altitude_m[i], int(a.nacp[i])) for i in group)
                fh.writelines(datablocks(CAT021, recs))
    return len(events)


@contextmanager
def atomic_recording(path: Path, radars: list[Radar], sac_sic: dict[str, tuple[int, int]]) -> Iterator[IO[bytes]]:
    """The binary file of a new recording ``path`` and its ``.radars.csv`` sidecar, both atomic.

    The sidecar is renamed into place first and the recording last, so a recording that exists has
    its sidecar; when the block fails neither is left (a SIGKILL between the two renames can leave
    the sidecar alone, which no command reads without its recording).
    """
    sites = Path(str(path) + ".radars.csv")
    sites_written = False
    try:
        with atomic_open(path, "wb") as fh:
            yield fh
            _write_sites(sites, radars, sac_sic)
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


def _write_sites(path: Path, radars: list[Radar], sac_sic: dict[str, tuple[int, int]]) -> None:
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

    Track ids become track numbers 1, 2, … in order of first appearance; returns that mapping.
    """
    path = Path(path)
    if path.exists():
        raise FileExistsError(f"{path} already exists")
    numbers: dict = {}
    tracks = result.tracks
    for k in tracks.track.tolist():
        numbers.setdefault(k, len(numbers) + 1)
    s = np.asarray(tracks.state, float)
    if len(s):
        lat, lon = result.plane.to_geodetic(s[:, 0], s[:, 1])
    recs = (cat062_record(tracks.time[i], sac, sic, numbers[tracks.track[i]], lat[i], lon[i],
                          s[i, 0], s[i, 1], s[i, 2], s[i, 3]) for i in range(len(s)))
    with atomic_open(path, "wb") as fh:
        fh.writelines(datablocks(CAT062, recs))
    return numbers


# --- containers ------------------------------------------------------------------------------------

def _blocks_in(buf: bytes, where: str, bad: Counter | None = None) -> Iterator[bytes]:
    """Split concatenated data blocks, checking every length field.

    A length that does not fit is an :class:`InputError`; with ``bad`` (skip_bad) the rest of
    ``buf`` is counted under ``asterix_unreadable_tails`` instead (no block boundary to resume at).
    """
    off = 0
    while off < len(buf):
        why = None
        if len(buf) - off < 3:
            why = f"truncated data block header ({len(buf) - off} bytes left)"
        elif (n := int.from_bytes(buf[off + 1: off + 3], "big")) < 3:
            why = f"data block length {n} < 3 (not ASTERIX?)"
        elif off + n > len(buf):
            why = f"truncated data block (length {n}, {len(buf) - off} bytes left)"
        if why is not None:
            if bad is None:
                raise InputError(f"{where}: byte {off}: {why}")
            bad["asterix_unreadable_tails"] += 1
            log.warning("%s: byte %d: %s; skipped the %d bytes from there", where, off, why, len(buf) - off)
            return
        yield buf[off: off + n]
        off += n


def _is_final(buf: bytes) -> bool:
    n = int.from_bytes(buf[:2], "big")
    return 12 < n <= len(buf) and buf[n - 4: n] == b"\xa5" * 4


def read_final(buf: bytes, where: str, bad: Counter | None = None) -> Iterator[tuple[float | None, bytes]]:
    """(None, data block) of a FINAL-format file (its 10 ms time of day is not needed: I140 has it)."""
    off = 0
    while off < len(buf):
        n = int.from_bytes(buf[off: off + 2], "big")
        why = ("truncated FINAL record header" if len(buf) - off < 12 else
               f"truncated or bad FINAL record (byte count {n})" if n < 12 or off + n > len(buf) else
               "FINAL record without its A5A5A5A5 padding" if buf[off + n - 4: off + n] != b"\xa5" * 4 else None)
        if why is not None:
            if bad is None:
                raise InputError(f"{where}: byte {off}: {why}")
            bad["asterix_unreadable_tails"] += 1
            log.warning("%s: byte %d: %s; skipped the %d bytes from there", where, off, why, len(buf) - off)
            return
        for block in _blocks_in(buf[off + 8: off + n - 4], f"{where}: FINAL record at byte {off}", bad):
            yield None, block
        off += n


_PCAP_MAGIC = {b"\xd4\xc3\xb2\xa1": ("<", 1e-6), b"\xa1\xb2\xc3\xd4": (">", 1e-6),
               b"\x4d\x3c\xb2\xa1": ("<", 1e-9), b"\xa1\xb2\x3c\x4d": (">", 1e-9)}


def read_pcap(buf: bytes, where: str, bad: Counter | None = None) -> Iterator[tuple[float, bytes]]:
    """(packet time, data block) of the UDP payloads of a classic pcap file (with ``bad``: a packet
    whose payload is not whole data blocks is skipped and counted, a cut last packet counted)."""
    endian, unit = _PCAP_MAGIC[buf[:4]]
    if len(buf) < 24:
        raise InputError(f"{where}: truncated pcap header")
    link = struct.unpack(endian + "I", buf[20:24])[0]
    off = 24
    while off < len(buf):
        sec, frac, incl, _ = struct.unpack(endian + "IIII", buf[off: off + 16].ljust(16, b"\0"))
        pkt = buf[off + 16: off + 16 + incl]
        if len(buf) - off < 16 or len(pkt) < incl:
            if bad is None:
                raise InputError(f"{where}: byte {off}: truncated pcap packet ({len(buf) - off} bytes left)")
            bad["asterix_unreadable_tails"] += 1
            return
        payload = _udp_payload(pkt, link, where)
        if payload:
            blocks = list(_blocks_in(payload, f"{where}: packet at byte {off}", None if bad is None else Counter()))
            if bad is not None and len(b"".join(blocks)) < len(payload):
                bad["asterix_malformed_packets"] += 1
            for block in blocks:
                yield sec + frac * unit, block
        off += 16 + incl


def _udp_payload(pkt: bytes, link: int, where: str) -> bytes | None:
    if link == 1:  # Ethernet, optionally 802.1Q tagged
        ethertype, ip = int.from_bytes(pkt[12:14], "big"), 14
        while ethertype == 0x8100:
            ethertype, ip = int.from_bytes(pkt[ip + 2: ip + 4], "big"), ip + 4
    elif link == 113:  # Linux cooked capture
        ethertype, ip = int.from_bytes(pkt[14:16], "big"), 16
    elif link in (101, 228):  # raw IPv4
        ethertype, ip = 0x0800, 0
    else:
        raise InputError(f"{where}: pcap link type {link} not supported (Ethernet, Linux SLL or raw IPv4)")
    if ethertype != 0x0800 or len(pkt) < ip + 20 or pkt[ip + 9] != 17:
        return None  # not IPv4/UDP: not ASTERIX
    if int.from_bytes(pkt[ip + 6: ip + 8], "big") & 0x3FFF:
        return None  # IP fragment
    udp = ip + (pkt[ip] & 0x0F) * 4
    return pkt[udp + 8: udp + int.from_bytes(pkt[udp + 4: udp + 6], "big")]


def write_pcap(path: Path | str, packets: Iterable[tuple[float, bytes]], *, dst: str = "232.1.1.1",
               port: int = 8600) -> None:
    """Write (time, UDP payload) pairs as an Ethernet/IPv4/UDP pcap file (multicast, as ATC feeds are)."""
    d = bytes(int(x) for x in dst.split("."))
    with atomic_open(path, "wb") as fh:
        fh.write(struct.pack("<IHHiIII", 0xA1B2C3D4, 2, 4, 0, 0, 65535, 1))
        for t, payload in packets:
            udp = struct.pack(">HHHH", port, port, 8 + len(payload), 0) + payload
            hdr = struct.pack(">BBHHHBBH4s4s", 0x45, 0, 20 + len(udp), 0, 0, 64, 17, 0, bytes([10, 0, 0, 1]), d)
            csum = sum(struct.unpack(">10H", hdr))
            csum = ~((csum & 0xFFFF) + (csum >> 16)) & 0xFFFF
            ip = hdr[:10] + struct.pack(">H", csum) + hdr[12:]
            eth = bytes([1, 0, 0x5E, d[1] & 0x7F, d[2], d[3]]) + bytes(6) + b"\x08\x00"
            frame = eth + ip + udp
            sec = math.floor(t)
            fh.write(struct.pack("<IIII", sec, round((t - sec) * 1e6) % 1_000_000, len(frame), len(frame)))
            fh.write(frame)


def iter_datablocks(path: Path | str, bad: Counter | None = None) -> Iterator[tuple[float | None, bytes]]:
    """(packet time or None, data block) of a raw, FINAL or pcap ASTERIX file; with ``bad``
    (skip_bad), unreadable framing is counted there instead of raising :class:`InputError`."""
    path = Path(path)
    buf = regular_file(path).read_bytes()  # a device or pipe has no end: refused before reading
    if not buf:
        raise InputError(f"{path}: empty file")
    if buf[:4] == b"\x0a\x0d\x0d\x0a":
        raise InputError(f"{path}: pcapng is not supported; convert it with 'editcap -F pcap'")
    if buf[:4] in _PCAP_MAGIC:
        return read_pcap(buf, str(path), bad)
    if _is_final(buf):
        return read_final(buf, str(path), bad)
    return ((None, b) for b in _blocks_in(buf, str(path), bad))


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


class _Clock:
    """Absolute time from time of day: day_start plus a day at each backwards wrap."""

    def __init__(self, day_start: float) -> None:
        self.base, self.last = day_start, None

    def __call__(self, tod: float) -> float:
        if self.last is not None and tod < self.last - DAY / 2:
            self.base += DAY
        self.last = tod
        return self.base + tod


def read_sites(path: Path) -> tuple[list[Radar], dict[tuple[int, int], str]]:
    """Radar sites and the SAC/SIC → radar id map of a ``.radars.csv`` sidecar (each SAC/SIC once)."""
    from radartracker.io.scenario import _Rows, read_radars

    radars = read_radars(path)
    rows = _Rows(path, RADAR_COLUMNS + ("sac", "sic"))
    ids: dict[tuple[int, int], str] = {}
    first: dict[tuple[int, int], int] = {}
    for line, row in rows:
        key = tuple(int(rows.number(row, line, f, check=_byte)) for f in ("sac", "sic"))
        if key in ids:
            raise FormatError(rows.name, line, "sac/sic", f"SAC/SIC {key[0]}/{key[1]} already belongs to radar "
                              f"{ids[key]!r} on line {first[key]}")
        ids[key], first[key] = rows.text(row, "radar"), line
    return radars, ids


def _byte(v: float) -> str | None:
    return None if v == int(v) and 0 <= v <= 255 else "is not an integer 0..255"


def _records(cat: int, recs: list, decode, skipped: Counter) -> Iterator[dict]:
    """Decoded records; those without an item we need are skipped and counted by item."""
    for r in recs:
        try:
            yield decode(r)
        except MissingItem as exc:
            key = f"asterix_cat{cat:03d}_records_without_I{exc.item}"
            if not skipped[key]:
                log.warning("skipping CAT%03d records without I%s (counted under %s)", cat, exc.item, key)
            skipped[key] += 1


def _first(rec: dict, seen: set[tuple], skipped: Counter, reason: str) -> bool:
    """False for a record equal to one read before (a redundant feed recorded twice), counted."""
    key = (reason, *sorted((k, v) for k, v in rec.items() if not (isinstance(v, float) and math.isnan(v))))
    if key in seen:
        skipped[reason] += 1
        return False
    seen.add(key)
    return True


def read_asterix(path: Path | str, *, radars: Path | str | None = None, day_start: float = 0.0,
                 skip_bad: bool = False) -> ScenarioData:
    """Read a CAT048/CAT021 recording (raw, FINAL or pcap) as a scenario (see the module notes).

    Skipped and counted in ``skipped`` (never an error): blocks of other categories, blocks the
    library cannot decode (other editions, damaged bytes), records without an item we need (e.g. a
    CAT048 track-only report without I040), ADS-B reports with an impossible position or a NACp
    of 0 (accuracy unknown) or above 11, records equal to one read before (used once). With ``skip_bad`` also framing that cannot be read (the
    rest of the file, or one pcap packet) and plots whose SAC/SIC the sidecar lacks; without it
    those are :class:`InputError` naming the file and byte. A recording with nothing usable is an
    error.
    """
    path = Path(path)
    sites_path = Path(radars) if radars is not None else Path(str(path) + ".radars.csv")
    plots, adsb, skipped = [], [], Counter()
    seen_records: set[tuple] = set()
    clock = None
    for k, (stamp, block) in enumerate(iter_datablocks(path, skipped if skip_bad else None)):
        if clock is None:
            clock = _Clock(math.floor(stamp / DAY) * DAY if stamp is not None else day_start)
        try:
            cat, recs = decode_block(block, f"{path}: data block {k}")
        except InputError as exc:
            if not skipped["asterix_undecodable_blocks"]:
                log.warning("skipping blocks that do not decode (counted): %s", exc)
            skipped["asterix_undecodable_blocks"] += 1
            continue
        if cat == 48:
            for p in _records(48, recs, decode_cat048, skipped):
                p["time"] = clock(p["tod"])
                if _first(p, seen_records, skipped, "asterix_cat048_duplicate_records"):
                    plots.append(p)
        elif cat == 21:
            for a in _records(21, recs, decode_cat021, skipped):
                if not (-90.0 <= a["lat"] <= 90.0 and -180.0 <= a["lon"] <= 180.0):
                    skipped["asterix_cat021_impossible_positions"] += 1
                    continue
                if a["nacp"] is not None and not 1 <= a["nacp"] <= 11:  # 0: accuracy unknown; 12-15 undefined
                    skipped["asterix_cat021_unusable_nacp"] += 1
                    continue
                a["time"] = clock(a["tod"])
                if _first(a, seen_records, skipped, "asterix_cat021_duplicate_records"):
                    adsb.append(a)
        else:
            skipped[f"asterix_cat{cat:03d}_blocks"] += 1
    seen = sorted({(p["sac"], p["sic"]) for p in plots})
    if seen and not sites_path.exists():
        raise FileNotFoundError(
            f"{path}: CAT048 plots from SAC/SIC {', '.join(f'{a}/{b}' for a, b in seen)} but no radar sites: "
            f"write {sites_path} (columns {', '.join(RADAR_COLUMNS)}, sac, sic)")
    site_list, ids = read_sites(sites_path) if sites_path.exists() else ([], {})
    unknown = [f"{a}/{b}" for a, b in seen if (a, b) not in ids]
    if unknown and not skip_bad:
        raise FormatError(sites_path.name, None, "sac/sic", f"no radar with SAC/SIC {', '.join(unknown)} "
                          "(CAT048 plots carry them; --skip-bad skips and counts those plots)")
    if unknown:
        kept = [p for p in plots if (p["sac"], p["sic"]) in ids]
        skipped["asterix_cat048_unknown_sac_sic"] += len(plots) - len(kept)
        plots = kept
    if not plots and not adsb:
        raise InputError(f"{path}: no usable CAT048 plot or CAT021 report"
                         + (f" (skipped: {dict(sorted(skipped.items()))})" if skipped else ""))
    icaos = sorted({a["icao24"] for a in adsb} | {p["mode_s"] for p in plots if p["mode_s"]})
    equipped = {a["icao24"] for a in adsb}
    squawks: dict[str, Counter] = {}  # an aircraft's Mode 3/A code: the one its plots carry most often
    for p in plots:
        if p["mode_s"] and p["mode_3a"]:
            squawks.setdefault(p["mode_s"], Counter())[p["mode_3a"]] += 1
    return ScenarioData(
        reference=(float(np.mean([r.lat for r in site_list])), float(np.mean([r.lon for r in site_list])))
        if site_list else ((float(np.mean([a["lat"] for a in adsb])), float(np.mean([a["lon"] for a in adsb])))
                           if adsb else (0.0, 0.0)),
        radars=site_list,
        plots=PlotTable.from_columns(**{
            "time": [p["time"] for p in plots], "radar": [ids[(p["sac"], p["sic"])] for p in plots],
            "range_m": [p["range_m"] for p in plots], "azimuth_rad": [p["azimuth_rad"] for p in plots],
            "altitude_m": [p["altitude_m"] for p in plots], "mode_s": [p["mode_s"] for p in plots],
            "mode_3a": [p["mode_3a"] for p in plots], "target": [None] * len(plots)}),
        adsb=AdsbTable.from_columns(**{
            "time": [a["time"] for a in adsb], "icao24": [a["icao24"] for a in adsb],
            "lat": [a["lat"] for a in adsb], "lon": [a["lon"] for a in adsb],
            "altitude_m": [a["altitude_m"] for a in adsb],
            "nacp": [8 if a["nacp"] is None else a["nacp"] for a in adsb]}),
        aircraft=[Aircraft(i, adsb=i in equipped, mode_3a=squawks[i].most_common(1)[0][0] if i in squawks else None)
                  for i in icaos],
        name=path.stem, skipped=dict(skipped),
    )


def read_cat062(path: Path | str, *, day_start: float = 0.0) -> list[dict]:
    """The CAT062 system track updates of a recording (raw, FINAL or pcap), in file order, as
    :func:`decode_cat062` dicts with absolute ``time`` (see the module notes on time of day);
    records of other categories, and records without I010, I040, I070 or I080, are skipped."""
    out: list[dict] = []
    clock = None
    for k, (stamp, block) in enumerate(iter_datablocks(path)):
        if clock is None:
            clock = _Clock(math.floor(stamp / DAY) * DAY if stamp is not None else day_start)
        cat, recs = decode_block(block, f"{path}: data block {k}")
        if cat == 62:
            for d in _records(62, recs, decode_cat062, Counter()):
                d["time"] = clock(d["tod"])
                out.append(d)
    return out
