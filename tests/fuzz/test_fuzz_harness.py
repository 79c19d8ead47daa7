"""Every reader fuzzed in child processes (tests/fuzz/harness.py): a quick pass here, ≥ 10⁵ inputs per reader
behind the slow marker; a traceback, a signal or a hang fails. The corpus of inputs that once failed is
read again each run."""

from __future__ import annotations

import faulthandler
import os
import re
import random
import signal
from pathlib import Path

import pytest

from radartracker.errors import RadarTrackerError
from radartracker.io.limits import read_json
from radartracker.io.recording import read_new4, read_plt
from radartracker.io.scenario import read_radars
from radartracker.pipeline.config import read_config
from radartracker_plugins.triangulation.io import read_stations

from tests.fuzz.harness import fuzz, readers

READERS = readers()
CORPUS = Path(__file__).parent / "corpus"
BY_SUFFIX = {".scenario.json": read_json, ".config.json": read_config, ".radars.csv": read_radars,
             ".stations.csv": read_stations, ".new4": read_new4, ".plt": read_plt}


@pytest.mark.parametrize("name", READERS)
def test_quick_pass(name):
    tally, seen = fuzz(name, 40)
    assert sum(tally.values()) == 40 and not (tally["traceback"] or tally["signal"] or tally["hang"]), seen


@pytest.mark.slow
@pytest.mark.parametrize("name", READERS)
def test_100k_inputs(name):
    tally, seen = fuzz(name, 100_000)
    assert sum(tally.values()) == 100_000 and not (tally["traceback"] or tally["signal"] or tally["hang"]), seen


def _crashing(work: Path) -> dict:
    def read(path: Path, rng: random.Random):
        if rng.random() < 0.2:
            faulthandler.disable()  # pytest's handler would print the child's stack
            os.kill(os.getpid(), signal.SIGSEGV)  # what compiled code reading out of bounds does
        if rng.random() < 0.2:
            raise ZeroDivisionError("a bug")
    return {"crash": (b"abc", read, "x")}


def test_a_signal_and_a_traceback_are_counted_as_failures():
    tally, seen = fuzz("crash", 30, inputs=_crashing)
    assert tally["signal"] > 0 and tally["traceback"] > 0 and sum(tally.values()) == 30, tally
    assert any("exit code -11" in s for s in seen) and any("ZeroDivisionError" in s for s in seen)


@pytest.mark.parametrize("path", sorted(p for p in CORPUS.iterdir() if p.name != "README.md"), ids=lambda p: p.name)
def test_corpus_of_inputs_that_once_failed(path):
    read = next(f for suffix, f in BY_SUFFIX.items() if path.name.endswith(suffix))
    with pytest.raises(RadarTrackerError, match=re.escape(path.name)):
        read(path)
