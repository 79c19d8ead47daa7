"""The first run after installing says that it compiles the numba kernels, once; a warm cache says nothing."""

import subprocess
import sys
import textwrap

import pytest

from radartracker.compiled import COMPILING

KERNELS = """
from numba import njit
from radartracker.compiled import kernel

@kernel
def twice(x):
    return 2.0 * x

@njit
def plain(x):  # not cached: compiled by every process, never said
    return x + 1.0
"""

CHILD = """
import sys
sys.path.insert(0, sys.argv[1])
from radartracker.compiled import compile_notice, in_disk_cache
import tiny_kernels as m
before = in_disk_cache(m.twice)
with compile_notice():
    m.plain(1.0)
    m.twice(2.0)
print(before, in_disk_cache(m.twice))
"""


def _child(folder, cache):
    out = subprocess.run([sys.executable, "-c", CHILD, str(folder)], capture_output=True, text=True, timeout=300,
                         env={"NUMBA_CACHE_DIR": str(cache), "PATH": ""})
    assert out.returncode == 0, out.stderr
    return out.stdout.split(), out.stderr.splitlines()


def test_a_cold_cache_is_said_once_and_a_warm_one_not_at_all(tmp_path):
    (tmp_path / "tiny_kernels.py").write_text(textwrap.dedent(KERNELS))
    cache = tmp_path / "numba_cache"  # empty: as after installing
    found, said = _child(tmp_path, cache)
    assert found == ["False", "True"]  # not in the cache before, in it after
    assert said[0] == f"radartracker: {COMPILING}" and len(said) == 2
    assert said[1].startswith("radartracker: kernels compiled in ") and said[1].endswith(" s")
    found, said = _child(tmp_path, cache)
    assert found == ["True", "True"] and said == []


REPLAY = """
import sys
from radartracker.cli import main
sys.exit(main(["replay", sys.argv[1], "--out", sys.argv[2], "--estimator", "decoupled", "--manager"]))
"""


@pytest.mark.slow
def test_the_first_replay_says_it_compiles_before_its_progress_bar(tmp_path):
    """A replay whose stderr is not a terminal (a notebook, a log) with numba's cache empty: the warm-up
    compiles first, said once, and the progress bar starts after it (its rate is the run's)."""
    from radartracker.cli import main

    assert main(["--quiet", "simulate", str(tmp_path / "scen"), "--scenario", "demo", "--duration", "900"]) == 0
    env = {"NUMBA_CACHE_DIR": str(tmp_path / "numba_cache"), "PATH": ""}
    out = subprocess.run([sys.executable, "-c", REPLAY, str(tmp_path / "scen"), str(tmp_path / "out")],
                         capture_output=True, text=True, timeout=600, env=env)
    assert out.returncode == 0, out.stderr
    err = out.stderr
    assert err.count(COMPILING) == 1 and err.count("kernels compiled in") == 1
    bar = err.find("track decoupled/")
    assert bar == -1 or bar > err.find("kernels compiled in")


def test_a_cache_is_cold_until_one_kernel_of_the_modules_is_in_it(tmp_path):
    """cache_is_cold, what replay asks before its progress bar: cold with an empty cache, warm once one kernel
    of the modules (not all: a run need not use every one) has been compiled."""
    (tmp_path / "tiny_kernels.py").write_text(textwrap.dedent(KERNELS))
    probe = ("import sys; sys.path.insert(0, sys.argv[1]); from radartracker.compiled import cache_is_cold; "
             "import tiny_kernels as m; print(cache_is_cold(m)); m.twice(1.0); print(cache_is_cold(m))")
    env = {"NUMBA_CACHE_DIR": str(tmp_path / "numba_cache"), "PATH": ""}
    runs = [subprocess.run([sys.executable, "-c", probe, str(tmp_path)], capture_output=True, text=True, timeout=300,
                           env=env) for _ in range(2)]
    assert [r.stdout.split() for r in runs] == [["True", "False"], ["False", "False"]], runs[0].stderr
