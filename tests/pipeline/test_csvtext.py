"""The compiled CSV formatter writes the bytes Python's own formatting gives, on the values where a
shortcut would differ: exact and near rounding ties, -0, tiny and huge magnitudes, NaN and infinities,
empty optional fields, non-ASCII and newline-holding texts, row and column selections; and the
writer's tables are those of a straightforward per-row formatter (the previous writer)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from radartracker.domain import BiasState
from radartracker.geometry.plane import SystemPlane
from radartracker.pipeline.csvtext import Table
from radartracker.pipeline.recorder import Recorder
from radartracker.pipeline.writer import _bias_rows, _rows

TIES = [0.125, 0.375, 2.5, 3.5, -2.5, 0.5, 1.5, -0.5, 1.005, 2.675, 1e-3 / 2, 0.0045, 1234.5625]


def _edge_values(rng: np.random.Generator) -> np.ndarray:
    near = [np.nextafter(v, s) for v in TIES for s in (-np.inf, np.inf)]
    mags = 10.0 ** rng.uniform(-12, 17, 400) * rng.choice([-1.0, 1.0], 400)
    return np.array([*TIES, *near, 0.0, -0.0, 1e-300, -1e-300, 5e-324, 2.0**50, 2.0**52 + 1, 1e300, -1e300,
                     9.999999995, 99.995, -99.995, 0.9999999999, math.nan, -math.nan, math.inf, -math.inf,
                     *mags, *rng.normal(0, 3e5, 200)])


@pytest.mark.parametrize("decimals", [0, 1, 2, 3, 6, 8])
def test_numbers_are_pythons_percent_format(decimals):
    x = _edge_values(np.random.default_rng(decimals))
    got = Table(len(x)).number(x, decimals).rows().splitlines()
    assert got == [f"{v:.{decimals}f}" for v in x.tolist()]


@pytest.mark.parametrize("decimals", [0, 1, 2, 3, 6, 8])
def test_values_next_to_rounding_ties_are_pythons_percent_format(decimals):
    """Decimal halves k + 1/2 (scaled by 10^-d) of every magnitude, and their neighbours a few ulps away."""
    rng = np.random.default_rng(100 + decimals)
    k = np.floor(10.0 ** rng.uniform(0, 15 - decimals, 3000)) * rng.choice([-1.0, 1.0], 3000)
    half = (k + 0.5) / 10.0**decimals
    x = np.concatenate([half, *(np.nextafter(half, half + s * np.inf) for s in (-1, 1)),
                        *(half + s * np.spacing(half) * m for s in (-1, 1) for m in (2, 3, 8))])
    got = Table(len(x)).number(x, decimals).rows().splitlines()
    assert got == [f"{v:.{decimals}f}" for v in x.tolist()]


def test_optional_numbers_are_empty_where_not_finite_and_integers_exact():
    x = _edge_values(np.random.default_rng(1))
    k = np.random.default_rng(2).integers(-(2**62), 2**62, len(x))
    k[:3] = [0, -1, 2**63 - 1]
    got = Table(len(x)).number(x, 2, optional=True).integer(k).rows().splitlines()
    assert got == [f"{v:.2f},{i}" if math.isfinite(v) else f",{i}" for v, i in zip(x.tolist(), k.tolist())]


def test_texts_selected_rows_and_columns():
    texts = ["", "é→ü", "abc", "a\nb", "R07"] * 3
    x = np.linspace(-2.0, 2.0, len(texts))
    t = Table(len(texts)).text(texts).number(x, 3).text([s[::-1] for s in texts])
    rows = [1, 4, 0, 4, 12]
    assert t.rows(rows, [2, 1]) == "".join(f"{texts[r][::-1]},{x[r]:.3f}\n" for r in rows)
    assert t.rows() == "".join(f"{a},{v:.3f},{a[::-1]}\n" for a, v in zip(texts, x.tolist()))
    assert t.rows([]) == "" and Table(0).number(np.empty(0), 2).rows() == ""


def test_labels_and_a_part_of_the_rows_written_in_the_same_pass():
    """A labels column writes each value's text (made once per distinct value); rows_and_part gives every
    row and, copied from them, the chosen rows' chosen fields, as rows() gives them."""
    codes = [None, "7421", "é→ü", None, "a\nb", "7421", "", 0] * 4
    x = np.array([1.005, -2.5, math.nan, 0.125, 1e300, -0.0, 3.0, math.inf] * 4)
    kinds = ["updated", "coasting", "updated", "confirmed"] * 8
    t = Table(len(x)).labels(codes, lambda v: str(v) if v else "").number(x, 2, optional=True).labels(kinds)
    mask = np.array([k != "coasting" for k in kinds])
    full, part = t.rows_and_part(mask, [2, 0, 1])
    field = [f"{v:.2f}" if math.isfinite(v) else "" for v in x.tolist()]
    assert bytes(full).decode() == t.rows() == "".join(f"{c or ''},{v},{k}\n" for c, v, k in zip(codes, field, kinds))
    assert bytes(part).decode() == t.rows(np.flatnonzero(mask), [2, 0, 1]) == "".join(
        f"{k},{c or ''},{v}\n" for c, v, k, m in zip(codes, field, kinds, mask) if m)
    _, twice = t.rows_and_part(np.ones(len(x), bool), [1, 1, 1, 0])  # a part longer than the rows
    assert bytes(twice).decode() == t.rows(None, [1, 1, 1, 0]) == "".join(f"{v},{v},{v},{c or ''}\n" for c, v in zip(codes, field))
    assert Table(0).labels([]).rows_and_part(np.zeros(0, bool), [0]) == (b"", b"")


def _reference_rows(ev, plane, with_kind: bool) -> str:
    """The previous writer: one f-string per row, indexing the arrays."""
    def num(v, spec):
        return format(v, spec) if math.isfinite(v) else ""
    lat, lon = plane.to_geodetic(ev.state[:, 0], ev.state[:, 1])
    sd = np.sqrt(np.stack([ev.cov[:, 0, 0], ev.cov[:, 1, 1]], axis=-1))
    out = []
    for i in range(len(ev)):
        x = ev.state[i]
        kind = f"{ev.kind[i]},{ev.status[i]}," if with_kind else ""
        out.append(f"{ev.time[i]:.3f},{ev.track[i]},{kind}{lat[i]:.8f},{lon[i]:.8f},{x[0]:.2f},{x[1]:.2f},{x[2]:.3f},"
                   f"{x[3]:.3f},{num(sd[i, 0], '.2f')},{num(sd[i, 1], '.2f')},{num(ev.altitude_m[i], '.1f')},"
                   f"{ev.mode_s[i] or ''},{ev.mode_3a[i] or ''}\n")
    return "".join(out)


def test_event_and_bias_tables_are_those_of_the_per_row_formatter():
    rng = np.random.default_rng(3)
    rec = Recorder(0.0)
    kinds = ["created", "confirmed", "updated", "coasting", "deleted"]
    for i in range(600):
        xy = rng.normal(0, 2e5, 2) if i % 7 else np.array(TIES[i % len(TIES)] * np.array([1.0, -1.0]))
        state = (*xy.tolist(), *rng.normal(0, 250, 2).tolist()) if i % 2 else np.r_[xy, -0.0, 0.125]
        cov = None if i % 5 == 3 else np.diag([TIES[i % 4] ** 2 * 1e4, rng.uniform(1, 1e6), 1.0, 1.0])
        rec.event(i * 0.0005 + 0.0005 * (i % 3 == 0), i % 37 + 1, kinds[i % 5], "confirmed", state, cov,
                  None if i % 4 == 0 else float(rng.normal(9000, 3000)), None if i % 3 else "3c4a5b",
                  "" if i % 6 == 1 else "7421")
        rec.bias(i * 0.5, _bias(f"R{i % 4:02d}", rng))
    ev, plane = rec.events(), SystemPlane(47.0, 8.0)
    events, tracks = _rows(ev, plane)
    assert bytes(events).decode() == _reference_rows(ev, plane, True)
    assert bytes(tracks).decode() == _reference_rows(ev.take(np.isin(ev.kind.astype(str), ["confirmed", "updated"])), plane,
                                              False)
    b = rec.biases()
    assert _bias_rows(b).decode() == "".join(
        f"{t:.3f},{r},{v[0]:.3f},{math.degrees(v[1]):.6f},{math.sqrt(P[0, 0]):.3f},{math.degrees(math.sqrt(P[1, 1])):.6f}\n"
        for t, r, v, P in zip(b.time, b.radar, b.value, b.cov))


def _bias(radar: str, rng: np.random.Generator) -> BiasState:
    return BiasState(radar, 0.0, np.array([rng.normal(0, 100), rng.normal(0, 1e-3)]),
                     np.diag([rng.uniform(1, 100), rng.uniform(1e-9, 1e-6)]))


CHILD = r"""
import json, numpy as np
from radartracker.pipeline import csvtext
from radartracker.pipeline.config import RunConfig
from radartracker.pipeline.warmup import warm_up
warm_up(RunConfig(association="manager"), notice=False)
kernels = (csvtext._write, csvtext._digits)
before = [len(f.signatures) for f in kernels]
t = csvtext.Table(3).number(np.array([1.5, -2.0, np.nan]), 2, optional=True).integer(np.arange(3)).text(["a", "é", ""])
t.rows(); t.rows([2, 0], [2, 0]); t.rows_and_part(np.array([True, False, True]), [2, 0])
print(json.dumps([before, [len(f.signatures) for f in kernels]]))
"""


def test_the_warm_up_readies_the_row_writer():
    """A replay's first table rows are not compiled inside the run (the warm-up wrote the tiny run's)."""
    import json
    import subprocess
    import sys

    out = subprocess.run([sys.executable, "-c", CHILD], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    before, after = json.loads(out.stdout.strip().splitlines()[-1])
    assert before == after == [1, 1]
