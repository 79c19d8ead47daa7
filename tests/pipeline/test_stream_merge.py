"""The block-by-block merge of plots.csv and adsb.csv (pipeline.stream._merged) against heapq.merge of the items,
with equal times inside blocks, across block boundaries and between the two files."""

from __future__ import annotations

import heapq
import itertools
import operator

import attrs
import numpy as np
import pytest

from radartracker.io.tables import AdsbTable, PlotTable
from radartracker.pipeline.stream import _merged, _ordered, _plots, _reports


def _split(table, cuts, cls):
    return [cls(**{f.name: getattr(table, f.name)[a:b] for f in attrs.fields(cls)}) for a, b in itertools.pairwise([0, *cuts, len(table)])]


@pytest.mark.parametrize("seed", range(10))
def test_merge_by_blocks_is_the_stable_merge_of_the_items(seed):
    rng = np.random.default_rng(seed)
    n_p, n_a = int(rng.integers(0, 300)), int(rng.integers(0, 300))
    span = int(rng.choice([3, 30, 3000]))  # few distinct times: many ties
    p = PlotTable.from_columns(time=np.sort(rng.integers(0, span, n_p)).astype(float), radar=[f"R{i % 3}" for i in range(n_p)],
                               range_m=rng.uniform(0, 1e5, n_p), azimuth_rad=rng.uniform(0, 6, n_p),
                               altitude_m=np.full(n_p, np.nan), mode_s=[None] * n_p, mode_3a=[None] * n_p,
                               target=list(range(n_p)))
    a = AdsbTable.from_columns(time=np.sort(rng.integers(0, span, n_a)).astype(float), icao24=["abcdef"] * n_a,
                               lat=rng.uniform(-90, 90, n_a), lon=rng.uniform(-180, 180, n_a),
                               altitude_m=np.arange(n_a, dtype=float), nacp=np.full(n_a, 8))
    cuts_p = np.sort(rng.integers(0, n_p + 1, int(rng.integers(0, 8)))).tolist()  # empty blocks too
    cuts_a = np.sort(rng.integers(0, n_a + 1, int(rng.integers(0, 8)))).tolist()
    got = [x for chunk in _merged(_ordered(_split(p, cuts_p, PlotTable), "p"), _ordered(_split(a, cuts_a, AdsbTable), "a"))
           for x in chunk]
    want = list(heapq.merge(_plots(p)(0, n_p), _reports(a)(0, n_a), key=operator.attrgetter("time")))
    assert len(want) == n_p + n_a
    assert got == want
