"""Fast paths of the ASTERIX items the service reads and writes, held byte for byte to libasterix.

``libasterix`` (:mod:`radartracker.io.asterix`) decodes every record in Python through its generic
description of the category, item by item; the service must decode national traffic (≈1 200 records/s)
on the same core that tracks it. This module walks the FSPEC with :mod:`struct` for the layouts radars
and ground stations commonly send:

* CAT048: every item of ed. 1.32 except I120 (compound); CAT021: every item of ed. 2.6 except the
  compounds I220, I110 and I295. A record with an item outside that set, or a block whose records
  do not end exactly at its end, is not guessed at: :func:`decode_block_fast` returns ``None`` and
  the caller decodes the block with libasterix.
* The encoders write exactly the bytes of :func:`~radartracker.io.asterix.cat048_record`,
  :func:`~radartracker.io.asterix.cat021_record` and :func:`~radartracker.io.asterix.cat062_record`
  (tests/service/test_codec.py compares them on random values).

Item lengths: ``n`` fixed octets, ``"x"`` extended (FX in bit 1 of each octet), ``"r8"`` repetitive
(one count octet, 8 octets each), ``"e"`` explicit (first octet: length), ``"c130"`` the CAT048 I130
compound (primary octets with FX, then one octet per subfield present).
"""

from __future__ import annotations

import math
import struct

from radartracker.io.asterix import FL_M, NM

_UAP048 = ("010", 2), ("140", 3), ("020", "x"), ("040", 4), ("070", 2), ("090", 2), ("130", "c130"), \
    ("220", 3), ("240", 6), ("250", "r8"), ("161", 2), ("042", 4), ("200", 4), ("170", "x"), \
    ("210", 4), ("030", "x"), ("080", 2), ("100", 4), ("110", 2), ("120", None), ("230", 2), \
    ("260", 7), ("055", 1), ("050", 2), ("065", 1), ("060", 2), ("SP", "e"), ("RE", "e")
_UAP021 = ("010", 2), ("040", "x"), ("161", 2), ("015", 1), ("071", 3), ("130", 6), ("131", 8), \
    ("072", 3), ("150", 2), ("151", 2), ("080", 3), ("073", 3), ("074", 4), ("075", 3), \
    ("076", 4), ("140", 2), ("090", "x"), ("210", 1), ("070", 2), ("230", 2), ("145", 2), \
    ("152", 2), ("200", 1), ("155", 2), ("157", 2), ("160", 4), ("165", 2), ("077", 3), \
    ("170", 6), ("020", 1), ("220", None), ("146", 2), ("148", 2), ("110", None), ("016", 1), \
    ("008", 1), ("271", "x"), ("132", 1), ("250", "r8"), ("260", 7), ("400", 1), ("295", None), \
    (None, None), (None, None), (None, None), (None, None), (None, None), ("RE", "e"), ("SP", "e")


class _Unsupported(Exception):
    """A record this fast path does not read: the block goes to libasterix."""


def _item_length(buf: bytes, off: int, rule) -> int:
    if isinstance(rule, int):
        return rule
    if rule == "x":
        n = 1
        while buf[off + n - 1] & 1:
            n += 1
        return n
    if rule == "r8":
        return 1 + 8 * buf[off]
    if rule == "e":
        if buf[off] < 1:
            raise _Unsupported
        return buf[off]
    if rule == "c130":
        n, present = 1, bin(buf[off] & 0xFE).count("1")
        while buf[off + n - 1] & 1:
            present += bin(buf[off + n] & 0xFE).count("1")
            n += 1
        return n + present
    raise _Unsupported


def _items(buf: bytes, off: int, uap) -> tuple[dict[str, int], int]:
    """{item: offset} of one record starting at ``off``, and the offset after it."""
    frns = []
    k = 0
    while True:
        b = buf[off]
        off += 1
        frns += [7 * k + i for i in range(7) if b & (0x80 >> i)]
        k += 1
        if not b & 1:
            break
    where = {}
    for frn in frns:
        if frn >= len(uap):
            raise _Unsupported
        name, rule = uap[frn]
        if name is None or rule is None:
            raise _Unsupported
        where[name] = off
        off += _item_length(buf, off, rule)
    return where, off


def _u(buf: bytes, off: int, n: int) -> int:
    return int.from_bytes(buf[off: off + n], "big")


def _s(buf: bytes, off: int, n: int) -> int:
    return int.from_bytes(buf[off: off + n], "big", signed=True)


def _fl(raw16: int) -> float:
    """Flight level (1/4 FL, 14-bit two's complement) of I048/090, in metres."""
    v = raw16 & 0x3FFF
    return (v - 0x4000 if v & 0x2000 else v) / 4 * FL_M


def _code(raw16: int) -> str:
    return f"{raw16 & 0x0FFF:04o}"


def _cat048(buf: bytes, w: dict[str, int]) -> dict:
    if "010" not in w or "140" not in w or "040" not in w:
        raise _Unsupported  # libasterix's reading names what is missing
    o = w["040"]
    return {"sac": buf[w["010"]], "sic": buf[w["010"] + 1], "tod": _u(buf, w["140"], 3) / 128,
            "range_m": _u(buf, o, 2) / 256 * NM, "azimuth_rad": math.radians(_u(buf, o + 2, 2) * 360 / 65536),
            "altitude_m": _fl(_u(buf, w["090"], 2)) if "090" in w else math.nan,
            "mode_3a": _code(_u(buf, w["070"], 2)) if "070" in w else None,
            "mode_s": f"{_u(buf, w['220'], 3):06x}" if "220" in w else None}


def _cat021(buf: bytes, w: dict[str, int]) -> dict:
    if "080" not in w or ("071" not in w and "073" not in w) or ("131" not in w and "130" not in w):
        raise _Unsupported
    if "131" in w:
        lat, lon = (_s(buf, w["131"] + k, 4) * 180 / 2**30 for k in (0, 4))
    else:
        lat, lon = (_s(buf, w["130"] + k, 3) * 180 / 2**23 for k in (0, 3))
    nacp = None
    if "090" in w and buf[w["090"]] & 1:
        nacp = (buf[w["090"] + 1] >> 1) & 0x0F
    return {"tod": _u(buf, w["071"] if "071" in w else w["073"], 3) / 128, "icao24": f"{_u(buf, w['080'], 3):06x}",
            "lat": lat, "lon": lon, "altitude_m": _s(buf, w["145"], 2) / 4 * FL_M if "145" in w else math.nan,
            "nacp": nacp}


def _walk(block: bytes, uap) -> list[tuple[dict, int, int]] | None:
    """(item offsets, start, end) of each record of a data block; ``None`` when a record runs past the
    block or uses an item the fast path does not read."""
    out, off, end = [], 3, len(block)
    try:
        while off < end:
            where, nxt = _items(block, off, uap)
            if nxt > end:
                return None
            out.append((where, off, nxt))
            off = nxt
    except (_Unsupported, IndexError):
        return None
    return out


def decode_block_fast(block: bytes) -> tuple[int, list[dict]] | None:
    """(category, record dicts as :func:`~radartracker.io.asterix.decode_cat048` / ``decode_cat021``
    give them) of a CAT048 or CAT021 data block; ``None`` when libasterix must decode it."""
    cat = block[0]
    if cat not in (48, 21):
        return None
    uap, read = (_UAP048, _cat048) if cat == 48 else (_UAP021, _cat021)
    if (records := _walk(block, uap)) is None:
        return None
    try:
        return cat, [read(block, where) for where, _, _ in records]
    except (_Unsupported, IndexError):
        return None


def split_block_fast(block: bytes) -> tuple[int, list[tuple[bytes, float | None]]] | None:
    """(category, [(record bytes, time of day)]) of a CAT048/CAT021 block, for repacking records into
    datagrams without decoding them; ``None`` when libasterix must read the block."""
    cat = block[0]
    if cat not in (48, 21):
        return None
    uap, tod_item = (_UAP048, "140") if cat == 48 else (_UAP021, "071")
    if (records := _walk(block, uap)) is None:
        return None
    try:
        return cat, [(block[a:b], _u(block, where[tod_item], 3) / 128 if tod_item in where else None)
                     for where, a, b in records]
    except IndexError:
        return None


# --- encoding (the load generator and the publisher) ---------------------------------------------

def _q(x: float, lsb: float) -> int:
    return round(x / lsb)


def _tod3(t: float) -> bytes:
    return (_q(float(t) % 86400.0, 1 / 128) & 0xFFFFFF).to_bytes(3, "big")


def cat048_bytes(time: float, sac: int, sic: int, range_m: float, azimuth_rad: float,
                 altitude_m: float | None = None, mode_s: str | None = None, mode_3a: str | None = None) -> bytes:
    """The bytes of :func:`radartracker.io.asterix.cat048_record` (one record, no block header)."""
    typ = 5 if mode_s else 2 if mode_3a else 1
    f1, body = 0xF0, [bytes([sac, sic]), _tod3(time), bytes([typ << 5]),
                      struct.pack(">HH", _q(range_m / NM, 1 / 256) & 0xFFFF,
                                  _q(math.degrees(azimuth_rad) % 360.0, 360 / 65536) & 0xFFFF)]
    if mode_3a:
        f1 |= 0x08
        body.append(struct.pack(">H", int(mode_3a, 8)))
    if altitude_m is not None and math.isfinite(altitude_m):
        f1 |= 0x04
        body.append(struct.pack(">H", _q(altitude_m / FL_M, 0.25) & 0x3FFF))
    if mode_s:
        return bytes([f1 | 1, 0x80]) + b"".join(body) + int(mode_s, 16).to_bytes(3, "big")
    return bytes([f1]) + b"".join(body)


def cat021_bytes(time: float, sac: int, sic: int, icao24: str, lat: float, lon: float,
                 altitude_m: float | None = None, nacp: int | None = None) -> bytes:
    """The bytes of :func:`radartracker.io.asterix.cat021_record`."""
    f = [0xCA | 1, 0x10 | 1, 0x00]  # 010 040 071 131 | 080 | (090, 145)
    body = [bytes([sac, sic]), b"\x20", _tod3(time),
            struct.pack(">ii", _q(lat, 180 / 2**30), _q(lon, 180 / 2**30)), int(icao24, 16).to_bytes(3, "big")]
    if nacp is not None:
        f[2] |= 0x20
        body.append(bytes([0x01, (int(nacp) & 0x0F) << 1]))
    if altitude_m is not None and math.isfinite(altitude_m):
        f[2] |= 0x02
        body.append(struct.pack(">h", _q(altitude_m / FL_M, 0.25)))
    if not f[2]:
        f = [f[0], f[1] & 0xFE]
    return bytes(f) + b"".join(body)


def cat062_bytes(time: float, sac: int, sic: int, track_number: int, lat: float, lon: float, x_m: float,
                 y_m: float, vx_mps: float, vy_mps: float, altitude_m: float | None = None, *,
                 mode_3a: str | None = None, mode_s: str | None = None, coasting: bool = False,
                 ended: bool = False) -> bytes:
    """The bytes of :func:`radartracker.io.asterix.cat062_record`."""
    f = [0xBE | 1, 0x0C, 0x00]  # 010 015 070 105 100 185 | 040 080 | 136
    body = [bytes([sac, sic, 0]), _tod3(time), struct.pack(">ii", _q(lat, 180 / 2**25), _q(lon, 180 / 2**25)),
            _q(x_m, 0.5).to_bytes(3, "big", signed=True) + _q(y_m, 0.5).to_bytes(3, "big", signed=True),
            struct.pack(">hh", _q(vx_mps, 0.25), _q(vy_mps, 0.25))]
    if mode_3a:
        f[1] |= 0x40
        body.append(struct.pack(">H", int(mode_3a, 8)))
    if mode_s:
        f[1] |= 0x10
        body.append(b"\x80" + int(mode_s, 16).to_bytes(3, "big"))
    body.append(struct.pack(">H", track_number))
    body.append(bytes([0x01, 0x40 * ended | 1, 0x01, 0x80 * coasting]) if coasting or ended else b"\x00")
    if altitude_m is not None and math.isfinite(altitude_m):
        f[2] |= 0x20
        body.append(struct.pack(">h", _q(altitude_m / FL_M, 0.25)))
    fspec = bytes([f[0], f[1] | 1, f[2]]) if f[2] else bytes(f[:2])
    return fspec + b"".join(body)


def blocks(cat: int, records: list[bytes], max_bytes: int) -> list[bytes]:
    """Data blocks (category, length, records) of at most ``max_bytes`` bytes each."""
    out, batch, size = [], [], 3
    for r in records:
        if batch and size + len(r) > max_bytes:
            out.append(bytes([cat]) + size.to_bytes(2, "big") + b"".join(batch))
            batch, size = [], 3
        batch.append(r)
        size += len(r)
    if batch:
        out.append(bytes([cat]) + size.to_bytes(2, "big") + b"".join(batch))
    return out
