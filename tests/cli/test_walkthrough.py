"""docs/user-guide.md's first walkthrough, run as written, ends clean; a run that warns says each warning
once, worded as the guide shows it, with what it means and what to change."""

import re
import subprocess
import sys
from pathlib import Path

import pytest

from radartracker.pipeline.result import consistency_warning

GUIDE = Path(__file__).resolve().parents[2] / "docs" / "user-guide.md"
MAIN = "import sys; from radartracker.cli import main; sys.exit(main(sys.argv[1:]))"
WARNING = re.compile(r"mean (NEES|NIS.*?) [\d.]+ against \d expected")


def _walkthrough() -> list[list[str]]:
    """The guide's first shell block: its simulate and first replay commands, comments dropped."""
    block = re.search(r"## Simulate, replay, look\n.*?```sh\n(.*?)```", GUIDE.read_text(encoding="utf-8"), re.S).group(1)
    lines = [line.split("#")[0].split() for line in block.splitlines()]
    simulate = next(c for c in lines if c[:2] == ["radartracker", "simulate"])
    replay = next(c for c in lines if c[:2] == ["radartracker", "replay"])
    return [simulate[1:], replay[1:]]


def _run(argv: list[str], cwd: Path) -> tuple[list[str], list[str]]:
    """The lines ``radartracker ARGV`` printed on stdout and on stderr (progress bars' redraws as lines)."""
    out = subprocess.run([sys.executable, "-c", MAIN, *argv], capture_output=True, text=True, cwd=cwd, timeout=600)
    assert out.returncode == 0, out.stderr
    return out.stdout.splitlines(), out.stderr.replace("\r", "\n").splitlines()


@pytest.mark.slow  # the paris replay with figures, as tests/docs runs the block (-m slow)
def test_the_first_walkthrough_ends_clean(tmp_path):
    for argv in _walkthrough():
        stdout, stderr = _run(argv, tmp_path)
    assert [line for line in stdout + stderr if WARNING.search(line)] == []
    assert "mean NEES" in "\n".join(stdout) and stdout[-1] == "outputs in out"


def test_a_run_that_warns_says_each_warning_once(tmp_path):
    """q = 0 on manoeuvring aircraft: the NEES and both NIS far too large, each said once (the log), not again
    in the table, each saying what to change."""
    _run(["simulate", "scen", "--scenario", "manoeuvres", "--duration", "300"], tmp_path)
    stdout, stderr = _run(["replay", "scen", "--out", "out", "--q", "0", "--estimator", "decoupled"], tmp_path)
    warned = [line for line in stdout + stderr if WARNING.search(line)]
    assert sorted(WARNING.search(w).group(1) for w in warned) == ["NEES", "NIS of the estimator",
                                                                  "NIS of the track filters"]
    assert all("overconfident" in w and "raise --q" in w for w in warned)


def test_the_guides_warning_is_the_one_printed():
    """The guide's example line, numbers aside, is what the code writes for it."""
    shown = next(line for line in GUIDE.read_text(encoding="utf-8").splitlines() if line.startswith("WARNING "))
    made = "WARNING radartracker.pipeline.writer: paris: " + consistency_warning("nis", 7.10, 2.0, 0.2)
    assert shown == made
