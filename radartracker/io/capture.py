"""ASTERIX capture framing: the data blocks of a recording, whatever holds them.

Containers: raw concatenated data blocks (``.ast``), the FINAL record format (8-byte header: byte
count, board, line, day, time in 10 ms; 4 bytes of 0xA5 padding) and classic pcap (Ethernet/SLL/raw
IPv4, UDP); pcapng is refused with a clear message. A data block is one category byte and a
big-endian 16-bit length that counts the whole block; every length is checked against the bytes
there are. This module decodes no record (:mod:`radartracker.io.asterix` does).
"""

from __future__ import annotations

import logging
import math
import struct
from collections import Counter
from collections.abc import Iterable, Iterator
from pathlib import Path

from radartracker.errors import InputError
from radartracker.io.atomic import atomic_open
from radartracker.io.limits import regular_file

log = logging.getLogger(__name__)


def _unreadable_tail(where: str, off: int, why: str, left: int, bad: Counter | None) -> None:
    """Framing that cannot be read at byte ``off``: an :class:`InputError`, or with ``bad`` (skip_bad)
    counted under ``asterix_unreadable_tails`` and warned of (the ``left`` bytes from there are skipped:
    there is no boundary to resume at)."""
    if bad is None:
        raise InputError(f"{where}: byte {off}: {why}")
    bad["asterix_unreadable_tails"] += 1
    log.warning("%s: byte %d: %s; skipped the %d bytes from there", where, off, why, left)


def blocks_in(buf: bytes, where: str, bad: Counter | None = None) -> Iterator[bytes]:
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
            _unreadable_tail(where, off, why, len(buf) - off, bad)
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
            _unreadable_tail(where, off, why, len(buf) - off, bad)
            return
        for block in blocks_in(buf[off + 8: off + n - 4], f"{where}: FINAL record at byte {off}", bad):
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
            blocks = list(blocks_in(payload, f"{where}: packet at byte {off}", None if bad is None else Counter()))
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
    return ((None, b) for b in blocks_in(buf, str(path), bad))
