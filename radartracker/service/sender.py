"""``radartracker send``: a recording replayed onto the network with its original timing.

The recording's records are repacked into datagrams of at most one Ethernet payload (1472 bytes,
a data block of one category each, records in file order; split by the codec fast path, else by
libasterix); a datagram leaves when the recording's
clock — the time of day of its first record, scaled by ``speed`` — reaches it (``speed`` = 0: as
fast as possible). Records of categories other than 048, 021 and 062 are sent as their original
blocks.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path

from radartracker.io.asterix import CAT021, CAT048, CAT062, DAY, decode_block
from radartracker.io.capture import iter_datablocks
from radartracker.service.codec import split_block_fast
from radartracker.service.endpoints import Endpoint, open_sender
from radartracker.service.publisher import UDP_PAYLOAD

_SPECS = {48: CAT048, 21: CAT021, 62: CAT062}
_TOD_ITEM = {48: "140", 21: "071", 62: "070"}


def datagrams(path: Path | str, max_bytes: int = UDP_PAYLOAD) -> Iterator[tuple[float | None, int, bytes]]:
    """(time of day of the first record or None, records, payload) of each datagram to send."""
    for k, (_, block) in enumerate(iter_datablocks(path)):
        fast = split_block_fast(block)
        if fast is not None:
            cat, pieces = fast
            for cat_block, n, tod in _repack(cat, pieces, max_bytes):
                yield tod, n, cat_block
            continue
        cat, recs = decode_block(block, f"{path}: data block {k}")
        if cat not in _SPECS:
            yield None, 0, block
            continue
        batch, size = [], 3
        for rec in recs:
            n = len(rec.unparse().to_bytes())
            if batch and size + n > max_bytes:
                yield _tod(cat, batch[0]), len(batch), _SPECS[cat].create(batch).unparse().to_bytes()
                batch, size = [], 3
            batch.append(rec)
            size += n
        if batch:
            yield _tod(cat, batch[0]), len(batch), _SPECS[cat].create(batch).unparse().to_bytes()


def _repack(cat: int, pieces: list[tuple[bytes, float | None]], max_bytes: int) -> Iterator[tuple[bytes, int, float | None]]:
    """Records already split (codec fast path) into blocks of at most ``max_bytes``."""
    batch: list[tuple[bytes, float | None]] = []
    size = 3
    for rec, tod in pieces + [(b"", None)]:
        if batch and (not rec or size + len(rec) > max_bytes):
            body = b"".join(r for r, _ in batch)
            yield bytes([cat]) + (3 + len(body)).to_bytes(2, "big") + body, len(batch), batch[0][1]
            batch, size = [], 3
        if rec:
            batch.append((rec, tod))
            size += len(rec)


def _tod(cat: int, rec) -> float | None:
    item = rec.get_item(_TOD_ITEM[cat])
    return None if item is None else item.variation.content.as_quantity("s")


def send(path: Path | str, to: Endpoint, speed: float = 1.0, interface: str = "0.0.0.0") -> dict:
    """Send the recording to ``to`` (a multicast group out of ``interface``); returns the datagrams,
    records and bytes sent, the datagrams refused, and the seconds it took. A datagram is refused when
    the destination answered an earlier one with "port unreachable" (nobody listening, e.g. a service
    being restarted): the kernel reports it on the next send, which then sends nothing; sending goes on."""
    sock = open_sender(to, interface=interface)
    sent = {"datagrams": 0, "records": 0, "bytes": 0, "datagrams_refused": 0}
    start, t0, last, days = time.monotonic(), None, None, 0.0
    try:
        for tod, n, payload in datagrams(path):
            if tod is not None and speed > 0:
                if last is not None and tod < last - DAY / 2:  # past midnight
                    days += DAY
                last = tod
                t0 = tod if t0 is None else t0
                delay = start + (tod + days - t0) / speed - time.monotonic()
                if delay > 0:
                    time.sleep(delay)
            try:
                sock.send(payload)
            except ConnectionRefusedError:
                sent["datagrams_refused"] += 1
                continue
            sent["datagrams"] += 1
            sent["records"] += n
            sent["bytes"] += len(payload)
    finally:
        sock.close()
    sent["seconds"] = round(time.monotonic() - start, 3)
    return sent
