"""The Python examples of the README and of the user-facing docs run as written (in a scratch folder)."""

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
# (file, block number): the examples that are whole programs; the others are fragments of a class or a
# call shown in its context (plugin skeletons), named in docs/plugins.md as such
RUNNABLE = [("README.md", 0), ("docs/tracking.md", 0), ("docs/user-guide.md", 0), ("docs/user-guide.md", 1),
            ("docs/api.md", 0)]


def _blocks(path: Path) -> list[str]:
    return re.findall(r"```python\n(.*?)```", path.read_text(encoding="utf-8"), re.S)


@pytest.mark.parametrize("name,k", RUNNABLE, ids=[f"{n}#{k}" for n, k in RUNNABLE])
def test_example_runs(name, k, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    code = _blocks(ROOT / name)[k]
    exec(compile(code, f"{name} example {k}", "exec"), {"__name__": "__example__"})
    assert capsys.readouterr().out or list(tmp_path.iterdir())  # it showed or wrote something


def test_the_plugin_guides_associator_passes_its_checks():
    """docs/plugins.md's nearest-neighbour associator, as written there, passes check_associator."""
    from radartracker.testing import ASSOCIATOR_CHECKS, check_associator

    block = next(b for b in _blocks(ROOT / "docs/plugins.md") if "class Nearest(Associator)" in b)
    space: dict = {"__name__": "__example__"}
    exec(compile(block, "docs/plugins.md associator", "exec"), space)
    assert check_associator(space["Nearest"]) == ASSOCIATOR_CHECKS


def test_the_traffic_example_runs(tmp_path, monkeypatch, capsys):
    """docs/api.md's example with the traffic library (an optional extra: skipped without it)."""
    pytest.importorskip("traffic.core", reason="the optional extra radartracker[traffic] is not installed")
    monkeypatch.chdir(tmp_path)
    block = next(b for b in _blocks(ROOT / "docs/api.md") if "traffic_from_tracks" in b)
    exec(compile(block, "docs/api.md traffic example", "exec"), {"__name__": "__example__"})
    assert "flight_id" in capsys.readouterr().out
