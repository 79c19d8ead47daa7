"""Byte mutations (flip, set, truncate, insert, delete) and the one rule every reader must follow:
it either returns something usable or raises a RadarTrackerError — any other exception is a bug."""

from __future__ import annotations

import math
import random

from hypothesis import strategies as st

from radartracker.domain import AdsbReport, Plot
from radartracker.errors import RadarTrackerError


def mutations(n: int) -> st.SearchStrategy:
    """Up to four edits of a buffer of ``n`` bytes, as (kind, position, value) tuples."""
    one = st.one_of(
        st.tuples(st.just("flip"), st.integers(0, n - 1), st.integers(0, 7)),
        st.tuples(st.just("set"), st.integers(0, n - 1), st.integers(0, 255)),
        st.tuples(st.just("truncate"), st.integers(0, n - 1), st.just(0)),
        st.tuples(st.just("insert"), st.integers(0, n), st.binary(min_size=1, max_size=8)),
        st.tuples(st.just("delete"), st.integers(0, n - 1), st.integers(1, 8)),
    )
    return st.lists(one, min_size=1, max_size=4)


def random_mutations(rng: random.Random, n: int) -> list[tuple]:
    """The same edits drawn by a seeded generator (for the long slow-marked runs)."""
    out = []
    for _ in range(rng.randint(1, 4)):
        kind = rng.choice(("flip", "set", "truncate", "insert", "delete"))
        value = {"flip": rng.randrange(8), "set": rng.randrange(256), "truncate": 0,
                 "insert": rng.randbytes(rng.randint(1, 8)), "delete": rng.randint(1, 8)}[kind]
        out.append((kind, rng.randrange(n + (kind == "insert")), value))
    return out


def apply(buf: bytes, edits: list[tuple]) -> bytes:
    b = bytearray(buf)
    for kind, pos, value in edits:
        pos = min(pos, max(len(b) - 1, 0))
        if kind == "flip" and b:
            b[pos] ^= 1 << value
        elif kind == "set" and b:
            b[pos] = value
        elif kind == "truncate":
            del b[pos:]
        elif kind == "insert":
            b[pos:pos] = value
        elif kind == "delete":
            del b[pos: pos + value]
    return bytes(b)


def scenario_items(data) -> list:
    """Every row of a read scenario as the domain objects the pipeline builds (their validators run)."""
    p, a = data.plots, data.adsb
    opt = (lambda v: None if math.isnan(v) else float(v))
    return ([Plot(float(p.time[i]), p.radar[i], float(p.range_m[i]), float(p.azimuth_rad[i]), opt(p.altitude_m[i]),
                  p.mode_s[i], p.mode_3a[i]) for i in range(len(p))]
            + [AdsbReport(float(a.time[i]), a.icao24[i], float(a.lat[i]), float(a.lon[i]), opt(a.altitude_m[i]),
                          int(a.nacp[i])) for i in range(len(a))])


def works_or_refuses(read, *args, **kw) -> str:
    """'read' (and every row usable) or 'refused' (a RadarTrackerError); anything else propagates."""
    try:
        data = read(*args, **kw)
    except RadarTrackerError:
        return "refused"
    if hasattr(data, "plots"):
        scenario_items(data)
    return "read"
