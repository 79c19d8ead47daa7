"""Numeric command-line options — non-finite, out of range, absurdly small or large — give exit 0
or one error line and exit 2 (argparse's own refusal is exit 2 too), never a traceback."""

from __future__ import annotations

import shutil

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from radartracker.cli import main

from tests.fuzz.test_fuzz_files import files  # noqa: F401  (fixture)

FUZZ = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
NUMBERS = st.one_of(st.sampled_from([0.0, -0.0, -1.0, 1e-9, 1e-300, 5e-324, 1e300, float("inf"), float("-inf"),
                                     float("nan"), 91.0, -181.0]),
                    st.floats(), st.floats(min_value=1e-3, max_value=1e3))


def _run(argv: list[str]) -> int:
    try:
        return main(argv)
    except SystemExit as exc:  # argparse refusing a value that is not a number
        return exc.code


@pytest.fixture(scope="module")
def out(tmp_path_factory):
    return tmp_path_factory.mktemp("fuzz_cli")


@given(option=st.sampled_from(["--step", "--warn-gdop", "--max-gdop", "--order", "--reference"]), data=st.data(),
       mode=st.sampled_from(["static", "dynamic"]))
@FUZZ
def test_triangulate_numeric_options(files, out, option, data, mode):  # noqa: F811
    _, d = files
    if option == "--order":
        value = str(data.draw(st.integers(-5, 2**40)))
    elif option == "--reference":
        value = ",".join(repr(data.draw(NUMBERS)) for _ in range(data.draw(st.integers(2, 3))))
    else:
        value = repr(data.draw(NUMBERS))
    shutil.rmtree(out / "tri", ignore_errors=True)
    rc = _run(["triangulate", str(d / "bearings.csv"), "--stations", str(d / "stations.csv"), "--out",
               str(out / "tri"), "--mode", mode, f"{option}={value}"])
    assert rc in (0, 2)  # 2: refused (a value, or every target: e.g. --max-gdop 1e-9)


@given(duration=NUMBERS)
@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
def test_simulate_duration(out, duration):
    if 0 < duration and duration == duration and duration > 30.0 and duration <= 7 * 86400:
        duration = 30.0  # a valid long run is not what this test is about (and would take minutes)
    shutil.rmtree(out / "sim", ignore_errors=True)
    assert _run(["simulate", str(out / "sim"), "--scenario", "demo", f"--duration={duration!r}"]) in (0, 2)
