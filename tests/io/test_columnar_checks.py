"""The columnar reader's syntax checks (compiled loops over a string column's bytes) accept exactly what
the regular expressions of the row checks' rules accept, and its numbers are what ``float()`` reads."""

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


@pytest.mark.parametrize("optional", [False, True])
def test_decimals_are_the_plain_syntax(optional):
    rng = random.Random(1)
    rule = re.compile(columnar.DECIMAL, re.ASCII)
    values = _strings(rng, 20000) + ["0", "-0.5", ".5", "5.", "1e3", "-1.5E-07", "", ".", "-", "e5", "1e", "1.2.3",
                                     "+1"]
    verdict = {v: rule.fullmatch(v) is not None or (optional and v == "") for v in values}
    assert 0.05 < sum(verdict.values()) / len(verdict) < 0.95
    for v in values:
        assert (_decimals([v], optional)[0] != 0) == verdict[v], v
    good = [v for v in values if verdict[v]]
    assert _decimals(good, optional)[0] != 0
    bad = next(v for v in values if not verdict[v])
    assert _decimals(good + [bad], optional)[0] == 0


def _decimals(values: list[str], optional: bool) -> tuple[int, np.ndarray]:
    out = np.full(len(values), -1.0)
    return columnar._decimals(*columnar._bytes(_column(values)), optional, out), out


def _decimal_texts(rng: random.Random, n: int) -> list[str]:
    """Plain decimals of 1 to 19 digits, some with an exponent (in and out of the range converted directly)."""
    texts = []
    for _ in range(n):
        digits = "".join(rng.choice("0123456789") for _ in range(rng.randint(1, 19)))
        point = rng.randint(0, len(digits))
        t = rng.choice(["", "", "-"]) + digits[:point] + rng.choice([".", ".", ""]) + digits[point:]
        if rng.random() < 0.3:
            t += rng.choice("eE") + rng.choice(["", "+", "-"]) + str(rng.randint(0, 40))
        texts.append(t)
    return texts


def test_decimals_converts_as_float_does():
    """Each value the kernel converts is float()'s double bit for bit; it says when some is left to pyarrow."""
    rng = random.Random(4)
    texts = _decimal_texts(rng, 20000) + ["0", "-0", "-0.0", ".5", "5.", "1e22", "1e23", "9e-22", "123456789012345",
                                          "1234567890123456", "0.000000000000000000001", "1" * 15 + "e7"]
    converted = 0
    for t in texts:
        found, out = _decimals([t], False)
        assert found in (1, 2), t
        if found == 1:
            converted += 1
            assert out.view(np.int64)[0] == np.float64(float(t)).view(np.int64), t
    assert 0.3 < converted / len(texts) < 0.9
    assert _decimals(["1.5", "", "-2e3"], True)[0] == 1 and np.isnan(_decimals(["1.5", "", "-2e3"], True)[1][1])
    assert _decimals(["1.5", "1" * 16], False)[0] == 2


@pytest.mark.parametrize("optional", [False, True])
def test_numbers_are_what_float_reads(optional):
    """Columns converted directly, through pyarrow (a value outside the direct conversion) or refused."""
    rng = random.Random(5)
    texts = [t for t in _decimal_texts(rng, 5000) if len(t.lstrip("-").replace(".", "")) <= 15 and "e" not in t.lower()]
    for column in (texts, texts + ["1" * 17], texts + ["1e300"], texts + [""]):
        got = columnar._numbers(_column(column), optional=optional)
        if "" in column and not optional:
            assert got is None
            continue
        want = np.array([float(t) if t else math.nan for t in column])
        assert np.array_equal(got, want, equal_nan=True) and (np.signbit(got) == np.signbit(want)).all()
    assert columnar._numbers(_column(texts + ["1e400"])) is None  # not finite


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
kernels = (columnar._decimals, columnar._digits)
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
