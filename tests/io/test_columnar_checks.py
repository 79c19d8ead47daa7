"""The columnar reader's syntax checks (a regular expression match in pyarrow for numbers, compiled loops over
a string column's bytes for codes and labels) accept exactly what Python's regular expressions of the same
rules accept, and its numbers are what ``float()`` reads."""

import math
import random
import re

import numpy as np
import pyarrow as pa
import pytest

from radartracker.io import columnar

ALPHABET = "0123456789" * 4 + ".-+eE x\u0663\u00e9aAfFgG"  # mostly digits: many values pass


def _column(values: list[str]) -> pa.ChunkedArray:
    """Two chunks, the first a slice of a longer array (its offsets start past 0)."""
    k = len(values) // 2
    return pa.chunked_array([pa.array(["12.5x", *values[:k]], pa.string()).slice(1), pa.array(values[k:], pa.string())],
                            pa.string())


def _strings(rng: random.Random, n: int) -> list[str]:
    return ["".join(rng.choice(ALPHABET) for _ in range(rng.randint(0, 8))) for _ in range(n)]


def _plain(v: str, optional: bool) -> bool:
    """The oracle: Python's ``re`` on :data:`DECIMAL` (ASCII digits only), and a finite double (or empty, if
    ``optional``)."""
    if v == "":
        return optional
    return re.fullmatch(columnar.DECIMAL, v, re.ASCII) is not None and math.isfinite(float(v))


@pytest.mark.parametrize("optional", [False, True])
def test_numbers_accept_exactly_the_plain_syntax(optional):
    rng = random.Random(1)
    values = _strings(rng, 4000) + ["0", "-0.5", ".5", "5.", "1e3", "-1.5E-07", "", ".", "-", "e5", "1e", "1.2.3",
                                    "+1", " 1", "1 ", "inf", "nan", "1e400", "-1e400", "\u0663", "1_0"]
    verdict = {v: _plain(v, optional) for v in values}
    assert 0.05 < sum(verdict.values()) / len(verdict) < 0.95
    for v in values:
        assert (columnar._numbers(_column([v]), optional=optional) is not None) == verdict[v], v
    good = [v for v in values if verdict[v]]
    assert columnar._numbers(_column(good), optional=optional) is not None
    bad = next(v for v in values if not verdict[v])
    assert columnar._numbers(_column(good + [bad]), optional=optional) is None


def _decimal_texts(rng: random.Random, n: int) -> list[str]:
    """Plain decimals of 1 to 19 digits, some with an exponent."""
    texts = []
    for _ in range(n):
        digits = "".join(rng.choice("0123456789") for _ in range(rng.randint(1, 19)))
        point = rng.randint(0, len(digits))
        t = rng.choice(["", "", "-"]) + digits[:point] + rng.choice([".", ".", ""]) + digits[point:]
        if rng.random() < 0.3:
            t += rng.choice("eE") + rng.choice(["", "+", "-"]) + str(rng.randint(0, 40))
        texts.append(t)
    return texts


@pytest.mark.parametrize("optional", [False, True])
def test_numbers_are_what_float_reads(optional):
    """Every value is ``float()``'s double bit for bit (sign of zero included); empty: NaN if optional, else
    the column is refused; a value beyond the largest double refuses the column."""
    rng = random.Random(5)
    texts = _decimal_texts(rng, 5000) + ["0", "-0", "-0.0", ".5", "5.", "1e22", "1e23", "9e-22", "123456789012345",
                                         "1234567890123456", "0.000000000000000000001", "1" * 15 + "e7", "1e-400"]
    for column in (texts, texts + [""]):
        got = columnar._numbers(_column(column), optional=optional)
        if "" in column and not optional:
            assert got is None
            continue
        want = np.array([float(t) if t else math.nan for t in column])
        assert np.array_equal(got.view(np.int64), want.view(np.int64)), column
        assert not got.flags.writeable
    assert columnar._numbers(_column(texts + ["1e400"]), optional=optional) is None


@pytest.mark.parametrize("digits, length, pattern", [(16, 6, "[0-9a-fA-F]{6}"), (8, 4, "[0-7]{4}")])
def test_codes_are_digits_of_their_base_and_length(digits, length, pattern):
    rng = random.Random(digits)
    alphabet = "0123456789abcdefABCDEFgG \u0663"
    values = ["".join(rng.choice(alphabet) for _ in range(rng.choice([0, length - 1, length, length, length + 1])))
              for _ in range(20000)]
    for optional in (False, True):
        for v in values[:4000]:
            expected = re.fullmatch(pattern, v) is not None or (optional and v == "")
            got = columnar._codes(_column([v]), digits, length, optional=optional)
            assert (got is not None) == expected, v
            if got is not None:
                assert got.tolist() == [v.lower() or None]


def test_labels_are_printable_ascii_without_space():
    rng = random.Random(3)
    rule = re.compile(r"[!-~]*")
    values = ["".join(rng.choice("aZ09_-~! \t\u00e9\u0663") for _ in range(rng.randint(0, 6))) for _ in range(5000)]
    for v in values:
        got = columnar._digits(*columnar._bytes(_column([v])), columnar._LABEL, -1, True)
        assert got == (rule.fullmatch(v) is not None), v


CHILD = r"""
import json, sys
from radartracker.io import columnar
from radartracker.io.scenario import open_scenario, write_scenario
from radartracker.pipeline.config import RunConfig
from radartracker.pipeline.stream import iter_files
from radartracker.pipeline.warmup import warm_up
from radartracker.simulation.scenarios import build_scenario

warm_up(RunConfig(association="manager"), notice=False)
kernels = (columnar._digits, columnar._repeats)
before = [len(f.signatures) for f in kernels]
write_scenario(sys.argv[1], build_scenario("tracking", seed=2, duration=60.0).run())
n = sum(1 for _ in iter_files(open_scenario(sys.argv[1])))
print(json.dumps([before, [len(f.signatures) for f in kernels], n]))
"""


def test_the_warm_up_readies_the_reader_checks(tmp_path):
    """A streamed replay's first blocks are not held up compiling the checks (the warm-up ran them)."""
    import json
    import subprocess
    import sys

    out = subprocess.run([sys.executable, "-c", CHILD, str(tmp_path / "scen")], capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stderr
    before, after, n = json.loads(out.stdout.strip().splitlines()[-1])
    assert n > 100 and before == after == [1, 1]
