"""ASTERIX import under damaged bytes, records lacking items, unknown categories and editions:
every input is read (and usable) or refused with a RadarTrackerError, never a traceback."""

from __future__ import annotations

import json
import logging
import random
import time
from collections import Counter

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from radartracker.io.asterix import CAT021, CAT048, datablocks
from radartracker.io.asterix_reader import read_asterix, read_cat062

from tests.fuzz.mutations import apply, mutations, random_mutations, works_or_refuses

FUZZ = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
CONTAINERS = ("ast", "ff", "pcap")

# every item we write, per category; a generated record carries any subset of them
CAT048_ITEMS = {"010": (("SAC", 0), ("SIC", 1)), "140": (3600.0, "s"), "020": ((5, 0, 0, 0, 0, None),),
                "040": (("RHO", (20.0, "NM")), ("THETA", (45.0, "°"))), "070": (0, 0, 0, 0, ("MODE3A", "1234")),
                "090": (0, 0, ("FL", (300.0, "FL"))), "220": 0x3C0001}
CAT021_ITEMS = {"010": (("SAC", 0), ("SIC", 200)), "040": ((1, 0, 0, 0, None),), "071": (3600.5, "s"),
                "131": (("LAT", (48.9, "°")), ("LON", (2.3, "°"))), "080": 0x3C0001,
                "145": (300.0, "FL"), "090": ((0, 0, None), (0, 0, 8, None))}
NEEDED = {48: {"010", "140", "040"}, 21: {"080", "071", "131"}}


def _write(tmp, name: str, data: bytes):
    path = tmp / name
    path.write_bytes(data)
    return path


@given(container=st.sampled_from(CONTAINERS), edits=st.data(), skip_bad=st.booleans())
@FUZZ
def test_damaged_recordings_are_read_or_refused(recordings, container, edits, skip_bad):
    bufs, sites = recordings
    buf = apply(bufs[container], edits.draw(mutations(len(bufs[container]))))
    path = _write(sites.parent, f"m.{container}", buf)
    works_or_refuses(read_asterix, path, radars=sites, skip_bad=skip_bad)
    works_or_refuses(read_cat062, path)


@given(records=st.lists(st.tuples(st.sampled_from((48, 21)), st.data()), min_size=1, max_size=8))
@FUZZ
def test_records_lacking_items_are_counted_not_fatal(recordings, records):
    """Any subset of the optional items: records with what we need are used, the others counted."""
    _, sites = recordings
    blocks, expect = [], Counter()
    for i, (cat, data) in enumerate(records):
        items = dict(CAT048_ITEMS if cat == 48 else CAT021_ITEMS)
        items["140" if cat == 48 else "071"] = (3600.0 + i, "s")  # distinct records (equal ones are used once)
        keep = data.draw(st.sets(st.sampled_from(sorted(items)), min_size=1))
        spec = CAT048 if cat == 48 else CAT021
        blocks += list(datablocks(spec, [spec.cv_record.create({k: items[k] for k in sorted(keep)})]))
        expect[cat, NEEDED[cat] <= keep] += 1
    path = _write(sites.parent, "items.ast", b"".join(blocks))
    if not expect[48, True] and not expect[21, True]:
        assert works_or_refuses(read_asterix, path, radars=sites) == "refused"
        return
    data = read_asterix(path, radars=sites)
    assert len(data.plots) == expect[48, True] and len(data.adsb) == expect[21, True]
    for cat in (48, 21):
        counted = sum(n for k, n in data.skipped.items() if k.startswith(f"asterix_cat{cat:03d}_records_without"))
        assert counted == expect[cat, False]


@given(cat=st.integers(0, 255), body=st.binary(max_size=64), where=st.integers(0, 10))
@settings(FUZZ, max_examples=100)
def test_unknown_categories_and_editions_are_skipped(recordings, cat, body, where):
    """A block of any category with any content (another edition, another standard) in a good recording."""
    bufs, sites = recordings
    raw = bufs["ast"]
    block = bytes([cat]) + (3 + len(body)).to_bytes(2, "big") + body
    cut, off = [], 0  # insert at a block boundary
    while off < len(raw):
        cut.append(off)
        off += int.from_bytes(raw[off + 1: off + 3], "big")
    at = cut[min(where, len(cut) - 1)]
    path = _write(sites.parent, "cat.ast", raw[:at] + block + raw[at:])
    if works_or_refuses(read_asterix, path, radars=sites) == "read":  # refused: it decoded as plots of unknown sites
        good = read_asterix(_write(sites.parent, "good.ast", raw), radars=sites)
        data = read_asterix(path, radars=sites)
        assert len(data.plots) >= len(good.plots) and len(data.adsb) >= len(good.adsb)


@pytest.mark.slow
def test_100k_mutations(recordings, tmp_path):
    """≥ 100 000 seeded mutations over the three containers; prints the tally (docs/reliability.md)."""
    bufs, sites = recordings
    rng = random.Random(20261201)
    tally: Counter = Counter()
    t0 = time.perf_counter()
    n = 100_000
    logging.disable(logging.WARNING)  # each damaged file logs what it skipped: 10⁵ of them say nothing new
    try:
        for i in range(n):
            container = CONTAINERS[i % 3]
            buf = apply(bufs[container], random_mutations(rng, len(bufs[container])))
            path = _write(tmp_path, f"m.{container}", buf)
            skip_bad = bool(i & 4)
            tally[f"{container}:{works_or_refuses(read_asterix, path, radars=sites, skip_bad=skip_bad)}"] += 1
    finally:
        logging.disable(logging.NOTSET)
    print(json.dumps({"mutations": n, "seconds": round(time.perf_counter() - t0, 1), "tracebacks": 0,
                      **dict(sorted(tally.items()))}))
    assert sum(tally.values()) == n
