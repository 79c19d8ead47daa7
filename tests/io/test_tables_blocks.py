"""plots.csv and adsb.csv read block by block and column by column give what reading every row one by one
gives: the same tables, the same skip counts, the same errors (file, line, field), whatever the block
size and whatever the damage."""

from __future__ import annotations

import csv
import io
import math
import random
import shutil

import attrs
import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from radartracker.errors import RadarTrackerError
from radartracker.io.csvblocks import Rows
from radartracker.io import columnar
from radartracker.io.scenario import open_scenario, read_scenario, write_scenario
from radartracker.simulation.scenarios import build_scenario

BLOCKS = ((700, False), (700, True), (1 << 20, True))  # 700 bytes: about 12 rows a block


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    data = build_scenario("demo", seed=3, duration=60.0).run()
    out = tmp_path_factory.mktemp("blocks") / "scen"
    write_scenario(out, data)
    return out


def _outcome(folder, skip_bad, **kw):
    """What reading gives: the tables' columns and skip counts, or the error's text."""
    try:
        d = read_scenario(folder, skip_bad=skip_bad, **kw)
    except RadarTrackerError as exc:
        return ("refused", type(exc).__name__, str(exc))
    cols = {}
    for table in (d.plots, d.adsb):
        for f in attrs.fields(type(table)):
            v = getattr(table, f.name)
            cols[f"{type(table).__name__}.{f.name}"] = (str(v.dtype), [None if x != x else x for x in v.tolist()])
    return ("read", cols, d.skipped)


def _assert_same_every_way(folder, skip_bad):
    want = _outcome(folder, skip_bad, block_bytes=1 << 30, fast=False)  # every row, one by one, one block
    for block_bytes, fast in BLOCKS:
        assert _outcome(folder, skip_bad, block_bytes=block_bytes, fast=fast) == want, (block_bytes, fast)
    return want


def test_clean_files_whole_or_in_blocks(folder):
    got = _assert_same_every_way(folder, False)
    assert got[0] == "read" and len(got[1]["PlotTable.time"][1]) > 200


DAMAGES = {
    "bad number": lambda f: f.replace(",", ",x", 1),
    "quoted field": lambda f: f.replace(",", ',"', 1).replace(",", '",', 2),
    "quoted line break": lambda f: f.replace(",", ',"a\nb",', 1),
    "crlf": lambda f: f + "\r",
    "blank line": lambda f: f + "\n",
    "upper-case code": lambda f: f.upper(),
    "space in a field": lambda f: f.replace(",", ", ", 1),
    "one field too many": lambda f: f + ",",
    "duplicate": lambda f: f + "\n" + f,
    "far ahead": lambda f: "99999" + f[f.index(","):],
    "backwards": lambda f: "0.001" + f[f.index(","):],
    "exponent": lambda f: "1e1" + f[f.index(","):],
    "underscore": lambda f: "1_0" + f[f.index(","):],
}


@pytest.mark.parametrize("damage", sorted(DAMAGES))
@pytest.mark.parametrize("name", ["plots.csv", "adsb.csv"])
def test_damaged_rows_give_the_same_rows_counts_and_errors(folder, tmp_path, name, damage):
    work = tmp_path / "s"
    shutil.copytree(folder, work)
    lines = (work / name).read_text().split("\n")
    for k in (3, len(lines) // 2, len(lines) - 3):  # early, middle (a later block), late
        lines[k] = DAMAGES[damage](lines[k])
    (work / name).write_text("\n".join(lines))
    for skip_bad in (False, True):
        _assert_same_every_way(work, skip_bad)


@pytest.mark.parametrize("tail", [b"", b"\xef\xbb\xbf", b"cut"])
def test_bom_and_cut_last_line(folder, tmp_path, tail):
    work = tmp_path / "s"
    shutil.copytree(folder, work)
    raw = (work / "plots.csv").read_bytes()
    raw = (b"\xef\xbb\xbf" + raw) if tail == b"\xef\xbb\xbf" else raw[:-20] if tail == b"cut" else raw
    (work / "plots.csv").write_bytes(raw)
    for skip_bad in (False, True):
        _assert_same_every_way(work, skip_bad)


def test_a_bad_byte_is_named_by_its_line_before_any_row(folder, tmp_path):
    work = tmp_path / "s"
    shutil.copytree(folder, work)
    lines = (work / "adsb.csv").read_bytes().split(b"\n")
    lines[2] = lines[2].replace(b",", b",x", 1)  # a bad row before the bad byte
    lines[40] = lines[40] + b"\xff"
    (work / "adsb.csv").write_bytes(b"\n".join(lines))
    got = _assert_same_every_way(work, False)
    assert got[0] == "refused" and "adsb.csv line 41" in got[2] and "not UTF-8" in got[2]


@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_random_line_edits(folder, tmp_path_factory, data):
    work = tmp_path_factory.mktemp("fuzz") / "s"
    shutil.copytree(folder, work)
    name = data.draw(st.sampled_from(["plots.csv", "adsb.csv"]))
    lines = (work / name).read_text().splitlines(keepends=True)
    for _ in range(data.draw(st.integers(1, 4))):
        k = data.draw(st.integers(1, len(lines) - 1))
        fields = lines[k].rstrip("\n").split(",")
        j = data.draw(st.integers(0, len(fields) - 1))
        fields[j] = data.draw(st.one_of(st.sampled_from(["", " 1", "1e400", "-0", "NaN", '"', "ABCDEF", "7777", "8"]),
                                        st.text(alphabet="0123456789.-e,\"\r\n ", max_size=8)))
        lines[k] = ",".join(fields) + "\n"
    (work / name).write_text("".join(lines))
    for block_bytes in (700, 1 << 20):
        for skip_bad in (False, True):
            want = _outcome(work, skip_bad, block_bytes=1 << 30, fast=False)
            assert _outcome(work, skip_bad, block_bytes=block_bytes, fast=True) == want


@pytest.mark.parametrize("text", ["a,b\n1,2\n\n3,4\n", 'a,b\n1,"x\ny"\n3,4', "a,b\r\n1,2\r\n3,4\n",
                                  "a,b\n1,2\n3\n4,5,6\n"])
def test_rows_and_line_numbers_are_csv_modules(tmp_path, text):
    """Rows and line numbers as csv.reader over the whole text gives them (blank lines left out)."""
    path = tmp_path / "t.csv"
    path.write_text(text, newline="")
    reader = csv.reader(io.StringIO(text, newline=""))
    next(reader)
    want = [(reader.line_num, r) for r in reader if r]
    for block_bytes in (1, 4, 1 << 20):
        rows = Rows(path, ("a", "b"), block_bytes=block_bytes)
        rows.skip = lambda err: got.append((err.line, None))
        got = []
        for line, row in rows:
            got.append((line, list(row.values())))
        assert got == [(n, r if len(r) == 2 else None) for n, r in want]


def test_pyarrow_reads_plain_decimals_as_float_does():
    rng = random.Random(1)
    texts = []
    for _ in range(20000):
        digits = "".join(rng.choice("0123456789") for _ in range(rng.randint(1, 19)))
        point = rng.randint(0, len(digits))
        t = ("-" if rng.random() < 0.3 else "") + digits[:point] + "." + digits[point:]
        if rng.random() < 0.3:
            t += f"e{rng.randint(-320, 310)}"
        texts.append(t)
    got = pc.cast(pa.array(texts), pa.float64()).to_numpy()
    want = np.array([float(t) for t in texts])
    assert (got.view(np.int64) == want.view(np.int64)).all()  # the same doubles, bit for bit


def test_numpy_radians_is_math_radians():
    v = np.random.default_rng(2).uniform(0, 360, 100000)
    assert (np.radians(v) == np.array([math.radians(x) for x in v.tolist()])).all()


def _streamed(folder, skip_bad, **kw):
    """What the streaming replay reads (:func:`open_scenario`: ADS-B duplicates looked for at the latest
    time only): each file's kept rows and the skip counts, or the error's text."""
    try:
        files = open_scenario(folder, skip_bad=skip_bad, **kw)
        tables = list(files.plot_blocks()) + list(files.adsb_blocks())
    except RadarTrackerError as exc:
        return ("refused", type(exc).__name__, str(exc))
    cols: dict = {}
    for table in tables:
        for f in attrs.fields(type(table)):
            cols.setdefault(f"{type(table).__name__}.{f.name}", []).extend(
                None if x != x else x for x in getattr(table, f.name).tolist())
    return ("read", cols, files.data.skipped)


def _tie_run(lines, k, size, field):
    """``size`` rows at the time of line ``k`` after it, told apart by ``field`` (a number), then an exact copy of
    the first of them: a duplicate within a run of equal times, not next to it."""
    fields = lines[k].split(",")
    run = [",".join(fields[:field] + [f"{100 + i}.5"] + fields[field + 1:]) for i in range(size)]
    lines[k + 1:k + 1] = run + [run[0]]


@pytest.mark.parametrize("size", [2, 70])  # compared pair by pair / a run too long for that: by a set of strings
@pytest.mark.parametrize("name,field", [("plots.csv", 2), ("adsb.csv", 4)])
def test_duplicates_among_equal_times_streamed(folder, tmp_path, monkeypatch, name, field, size):
    """Exact duplicates in runs of equal times, within a block and across blocks, give the rows, counts and
    errors of the row checks when the files are streamed; the compiled comparison of a run's lines is used
    (it finds the repeat, or none, or leaves a long run to the set of strings)."""
    work = tmp_path / "s"
    shutil.copytree(folder, work)
    lines = (work / name).read_text().split("\n")
    for k in (len(lines) - 20, len(lines) // 2, 5):  # from the end: the indices before stay put
        _tie_run(lines, k, size, field)
    (work / name).write_text("\n".join(lines))
    found, kernel = [], columnar._repeats

    def spy(*args):
        found.append(kernel(*args))
        return found[-1]

    monkeypatch.setattr(columnar, "_repeats", spy)
    want = _streamed(work, False, block_bytes=1 << 30, fast=False)  # duplicates are counted, never refused
    assert want[0] == "read" and want[2][f"{name}:duplicate_row"] == 3
    for block_bytes in (700, 1500, 1 << 20):
        assert _streamed(work, False, block_bytes=block_bytes, fast=True) == want, block_bytes
    assert set(found) >= ({0, 1} if size == 2 else {0, -1})
