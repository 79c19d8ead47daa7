"""The fast ASTERIX paths against libasterix: the same bytes written, the same values read."""

from __future__ import annotations

import math

import numpy as np
import pytest

from radartracker.io.asterix import (CAT048, CAT062, cat021_record, cat048_record, cat062_record, datablocks,
                                     decode_block, decode_cat021, decode_cat048)
from radartracker.service.codec import blocks, cat021_bytes, cat048_bytes, cat062_bytes, decode_block_fast

rng = np.random.default_rng(7)
N = 60


def _lib(rec) -> bytes:
    return rec.unparse().to_bytes()


def _code() -> str:
    return f"{int(rng.integers(0, 4096)):04o}"


def _addr() -> str:
    return f"{int(rng.integers(0, 2**24)):06x}"


def _same(a: dict, b: dict) -> bool:
    return a.keys() <= b.keys() and all((isinstance(v, float) and math.isnan(v) and math.isnan(b[k])) or v == b[k]
                                        for k, v in a.items() if k in b)


@pytest.mark.parametrize("k", range(N))
def test_cat048_bytes_and_values_as_libasterix(k):
    args = (float(rng.uniform(0, 86400)), int(rng.integers(0, 256)), int(rng.integers(0, 256)),
            float(rng.uniform(0, 400_000)), float(rng.uniform(0, 2 * math.pi)),
            [None, float(rng.uniform(-300, 15_000))][k % 2], [None, _addr()][k % 3 > 0], [None, _code()][k % 4 > 0])
    ours = cat048_bytes(*args)
    assert ours == _lib(cat048_record(*args))
    block = blocks(48, [ours, ours], 1000)[0]
    cat, fast = decode_block_fast(block)
    assert cat == 48 and len(fast) == 2
    assert _same(fast[0], decode_cat048(decode_block(block, "t")[1][0]))


@pytest.mark.parametrize("k", range(N))
def test_cat021_bytes_and_values_as_libasterix(k):
    args = (float(rng.uniform(0, 86400)), int(rng.integers(0, 256)), int(rng.integers(0, 256)), _addr(),
            float(rng.uniform(-90, 90)), float(rng.uniform(-180, 180)),
            [None, float(rng.uniform(-300, 15_000))][k % 2], [None, int(rng.integers(0, 12))][k % 3 > 0])
    ours = cat021_bytes(*args)
    assert ours == _lib(cat021_record(*args))
    block = blocks(21, [ours], 1000)[0]
    assert _same(decode_block_fast(block)[1][0], decode_cat021(decode_block(block, "t")[1][0]))


@pytest.mark.parametrize("k", range(N))
def test_cat062_bytes_as_libasterix(k):
    args = (float(rng.uniform(0, 86400)), 0, 100, int(rng.integers(1, 65536)), float(rng.uniform(-90, 90)),
            float(rng.uniform(-180, 180)), float(rng.uniform(-4e6, 4e6)), float(rng.uniform(-4e6, 4e6)),
            float(rng.uniform(-400, 400)), float(rng.uniform(-400, 400)), [None, float(rng.uniform(0, 15_000))][k % 2])
    kw = {"mode_3a": [None, _code()][k % 3 > 0], "mode_s": [None, _addr()][k % 4 > 0],
          "coasting": k % 5 == 1, "ended": k % 7 == 2}
    assert cat062_bytes(*args, **kw) == _lib(cat062_record(*args, **kw))


def test_blocks_as_libasterix_datablocks():
    recs = [cat048_record(1.0 + i, 0, 1, 1e5, 1.0, 9000.0, "abcdef", "1234") for i in range(50)]
    assert blocks(48, [_lib(r) for r in recs], 300) == list(datablocks(CAT048, recs, 297))


def test_unsupported_layouts_go_to_libasterix():
    rec = CAT048.cv_record.create({"010": (("SAC", 0), ("SIC", 1)), "140": (1.0, "s"), "020": ((5, 0, 0, 0, 0, None),),
                                   "040": (("RHO", (10.0, "NM")), ("THETA", (1.0, "°"))),
                                   "120": {"CAL": (0, 0, ("CAL", 3))}})  # I120 compound: not on the fast path
    block = next(datablocks(CAT048, [rec]))
    assert decode_block_fast(block) is None and decode_block(block, "t")[0] == 48
    good = blocks(48, [cat048_bytes(1.0, 0, 1, 1e5, 1.0)], 100)[0]
    assert decode_block_fast(good[:-1]) is None  # a record running past the block's end
    assert decode_block_fast(next(datablocks(CAT062, [cat062_record(1.0, 0, 1, 1, 0, 0, 0, 0, 0, 0)]))) is None


def test_send_repacks_the_same_datagrams_with_and_without_the_fast_path(tmp_path, monkeypatch):
    from radartracker.io.asterix import write_asterix
    from radartracker.service import sender
    from radartracker.simulation.scenarios import build_scenario

    write_asterix(tmp_path / "r.ast", build_scenario("tracking", seed=2, duration=60).run())
    fast = list(sender.datagrams(tmp_path / "r.ast"))
    monkeypatch.setattr(sender, "split_block_fast", lambda block: None)
    assert fast == list(sender.datagrams(tmp_path / "r.ast")) and len(fast) > 10
