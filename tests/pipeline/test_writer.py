"""The output tables read back (Python's ``csv`` module) hold the run's values within their stated precision
(docs/formats.md: half a unit of the last decimal), empty fields where a value is missing, the texts as
given, and ``tracks.csv`` the estimate rows of ``events.csv``. The oracle for latitude and longitude is the
forward projection of what was read, which must land on the plane position written."""

from __future__ import annotations

import csv
import math

import numpy as np
import pytest

from radartracker.geometry.plane import SystemPlane
from radartracker.pipeline.recorder import BiasLog, Events
from radartracker.pipeline.writer import BIAS_COLUMNS, EVENT_COLUMNS, TRACK_COLUMNS, OutputStream

KINDS = ["created", "confirmed", "updated", "coasting", "deleted"]
PLANE = SystemPlane(47.0, 8.0)


def _events(rng: np.random.Generator, n: int) -> Events:
    """Events with awkward values in every field: rounding halves, -0, NaN covariances, huge and negative
    numbers, missing identities."""
    xy = rng.normal(0, 2e5, (n, 2))
    xy[:8] = [[0.125, -0.125], [2.675, -2.675], [1.005, -0.005], [-0.0, 0.0], [1e-9, -1e-9], [99.995, -99.995],
              [4e5, -4e5], [0.5, 1.5]]
    state = np.c_[xy, rng.normal(0, 250, (n, 2))]
    state[::9, 2:] = [-0.0, 0.0005]
    cov = np.einsum("ni,ij->nij", rng.uniform(1, 1e6, (n, 4)), np.eye(4))
    cov[::5] = np.nan  # no covariance: empty sd fields
    cov[7, 0, 0] = -1.0  # a negative variance: no standard deviation either
    alt = rng.normal(9000, 3000, n)
    alt[::4] = np.nan
    mode_s = np.array([None if i % 3 else "3c4a5b" for i in range(n)], object)
    mode_3a = np.array(["" if i % 6 == 1 else ("0741" if i % 2 else None) for i in range(n)], object)
    kind = np.array([KINDS[i % 5] for i in range(n)], object)
    status = np.array(["tentative" if i % 2 else "confirmed" for i in range(n)], object)
    time = np.arange(n) * 0.0005 + 1e5
    time[3] = 2.0**53  # beyond what a rounding to 10^-3 can change
    return Events(time=time, track=rng.integers(1, 2**62, n), kind=kind, status=status, state=state, cov=cov,
                  altitude_m=alt, altitude_sd_m=np.where(np.isnan(alt), np.nan, rng.uniform(2, 900, n)), mode_s=mode_s,
                  mode_3a=mode_3a, target=np.full(n, None, object))


def _biases(rng: np.random.Generator, n: int) -> BiasLog:
    value = np.c_[rng.normal(0, 100, n), rng.normal(0, 1e-3, n)]
    cov = np.einsum("ni,ij->nij", np.c_[rng.uniform(1, 100, n), rng.uniform(1e-9, 1e-6, n)], np.eye(2))
    radar = np.array([f"R{i % 4:02d}" for i in range(n - 2)] + ['R,"7"', "Zürich"], object)
    return BiasLog(time=np.arange(n) * 0.5 + 0.0005, radar=radar, value=value, cov=cov)


def _read(path) -> tuple[list[str], list[list[str]]]:
    with open(path, newline="", encoding="utf-8") as f:
        header, *rows = csv.reader(f)
    return header, rows


def _close(text: str, want: float, decimals: int) -> bool:
    """``text`` is ``want`` to ``decimals`` decimals: within half a unit of the last (and a few ulps)."""
    if not math.isfinite(want):
        return text == str(want)
    got = float(text)
    return abs(got - want) <= 0.5 * 10.0**-decimals * (1 + 1e-9) + 4 * math.ulp(want)


def _optional(text: str, want: float, decimals: int) -> bool:
    return text == "" if not math.isfinite(want) else _close(text, want, decimals)


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    """Events and biases written in two flushes each by an OutputStream."""
    rng = np.random.default_rng(3)
    ev, b = _events(rng, 600), _biases(rng, 50)
    out = tmp_path_factory.mktemp("out")
    sink = OutputStream(out, PLANE)
    for part in (slice(0, 250), slice(250, None)):
        sink.events(ev.take(np.arange(len(ev))[part]))
        sink.biases(BiasLog(b.time[part], b.radar[part], b.value[part], b.cov[part]))
    sink.events(ev.take(np.zeros(len(ev), bool)))  # an empty flush writes nothing
    for name, path in sink.finish().items():
        path.replace(out / name)
    return ev, b, out


def test_events_hold_the_values_to_their_decimals(written):
    ev, _, out = written
    header, rows = _read(out / "events.csv")
    assert header == list(EVENT_COLUMNS) and len(rows) == len(ev)
    for i, r in enumerate(rows):
        x, y, vx, vy = ev.state[i]
        sd = [math.sqrt(v) if v >= 0 else math.nan for v in (ev.cov[i, 0, 0], ev.cov[i, 1, 1])]
        assert _close(r[0], ev.time[i], 3) and int(r[1]) == ev.track[i], i
        assert r[2:4] == [ev.kind[i], ev.status[i]], i
        assert all(_close(t, v, d) for t, v, d in zip(r[6:10], (x, y, vx, vy), (2, 2, 3, 3))), (i, r)
        assert _optional(r[10], sd[0], 2) and _optional(r[11], sd[1], 2) and _optional(r[12], ev.altitude_m[i], 1), i
        assert _optional(r[13], ev.altitude_sd_m[i], 1), i
        assert r[14:] == [ev.mode_s[i] or "", ev.mode_3a[i] or ""], i
    lat, lon = (np.array([float(r[k]) for r in rows]) for k in (4, 5))
    px, py = PLANE.to_plane(lat, lon)
    # 10^-8 degree is at most 1.2 mm on the ground; the plane position read is within 5 mm of the state
    assert np.abs(px - ev.state[:, 0]).max() < 1e-2 and np.abs(py - ev.state[:, 1]).max() < 1e-2
    assert float(rows[3][0]) == 2.0**53  # kept, not rounded through an overflow


def test_tracks_are_the_estimate_rows_of_events(written):
    ev, _, out = written
    header, tracks = _read(out / "tracks.csv")
    _, events = _read(out / "events.csv")
    assert header == list(TRACK_COLUMNS)
    keep = [EVENT_COLUMNS.index(c) for c in TRACK_COLUMNS]
    assert tracks == [[r[k] for k in keep] for r in events if r[2] in ("confirmed", "updated")]
    assert len(tracks) == int(np.isin(ev.kind.astype(str), ["confirmed", "updated"]).sum()) > 0


def test_biases_hold_the_values_in_metres_and_degrees(written):
    _, b, out = written
    header, rows = _read(out / "biases.csv")
    assert header == list(BIAS_COLUMNS) and len(rows) == len(b.time)
    for i, r in enumerate(rows):
        want = (b.value[i, 0], math.degrees(b.value[i, 1]), math.sqrt(b.cov[i, 0, 0]),
                math.degrees(math.sqrt(b.cov[i, 1, 1])))
        assert _close(r[0], b.time[i], 3) and r[1] == b.radar[i], i
        assert all(_close(t, v, d) for t, v, d in zip(r[2:], want, (3, 6, 3, 6))), (i, r)


def test_values_not_finite_or_huge_in_a_column_that_needs_a_value_read_back_as_they_were(tmp_path):
    ev = _events(np.random.default_rng(4), 10)
    ev.state[:5, 2] = math.nan, math.inf, -math.inf, 1e305, -1e300  # x·10^3 overflows at 1e305
    sink = OutputStream(tmp_path, PLANE)
    sink.events(ev)
    sink.finish()["events.csv"].replace(tmp_path / "events.csv")
    _, rows = _read(tmp_path / "events.csv")
    assert [r[8] for r in rows[:3]] == ["nan", "inf", "-inf"]
    assert [float(r[8]) for r in rows[3:5]] == [1e305, -1e300]
