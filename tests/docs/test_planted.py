"""The docs checks can fail: errors planted into a copy of a doc's text (or into the code it quotes) are
each reported, naming the doc line, while the doc as it is passes."""

from __future__ import annotations

import importlib

import attrs
import pytest

from radartracker.tracking.config import ManagerConfig
from tests.docs import checks, commands
from tests.docs.mdparse import load, parse
from tests.docs.runner import run_document

DOC = "docs/tracking.md"


def _plant(name: str, old: str, new: str) -> str:
    """The doc's text with its one ``old`` replaced by ``new``."""
    text = load(name).text
    assert text.count(old) == 1, f"{name}: {old!r} is no longer there once; choose another plant"
    return text.replace(old, new)


def test_the_docs_as_they_are_pass():
    text = load(DOC).text
    for check in (checks.module_path_problems, checks.default_problems, checks.cli_problems):
        problems, checked = check(DOC, text)
        assert problems == [] and checked > 0, (check.__name__, problems)


@pytest.mark.parametrize("old,new,named", [
    ("`radartracker.registry.make_manager`", "`radartracker.registry.make_managers`", "make_managers"),
    ("`radartracker.tracking.manager.TrackManager`", "`radartracker.tracking.managers.TrackManager`", "managers"),
    ("`tests/tracking/test_manager.py`", "`tests/tracking/test_managers.py`", "test_managers.py"),
    ("`radartracker/registry.py: motion_q` and", "`radartracker/registry.py: motion_qq` and", "motion_qq"),
])
def test_a_planted_module_path_is_reported(old, new, named):
    problems, _ = checks.module_path_problems(DOC, _plant(DOC, old, new))
    assert len(problems) == 1 and named in problems[0], problems
    assert problems[0].startswith(f"{DOC}:")


@pytest.mark.parametrize("old,new,named", [
    ("`delete_after_s` = 40 s", "`delete_after_s` = 30 s", "ManagerConfig.delete_after_s` = 30"),
    ("`ClockConfig.max_ahead_s` = 300 s", "`ClockConfig.max_ahead_s` = 3000 s", "ClockConfig.max_ahead_s` = 3000"),
    ("`IMMConfig.turn_rate_entry_sd` = 2°", "`IMMConfig.turn_rate_entry_sd` = 2", "turn_rate_entry_sd` = 2,"),
    ("`new_track_exclusion` = 27.63", "`new_track_exclusion` = 27.36", "new_track_exclusion` = 27.36,"),
    ("`ManagerConfig.frame_s` = 0.5 s", "`ManagerConfig.frame_ms` = 0.5 s", "no 'frame_ms'"),
])
def test_a_planted_default_is_reported(old, new, named):
    problems, checked = checks.default_problems(DOC, _plant(DOC, old, new))
    assert len(problems) == 1 and named in problems[0], problems
    assert checked == checks.default_problems(DOC, load(DOC).text)[1]


def test_a_default_changed_in_the_code_is_reported(monkeypatch):
    """The other direction: the code's default moves, the doc stays — ManagerConfig's and a CLI option's."""

    @attrs.frozen
    class Changed(ManagerConfig):
        delete_after_s: float = 30.0

    for name in checks.OWNER_MODULES:  # every module the checker looks a short name up in
        module = importlib.import_module(name)
        if getattr(module, "ManagerConfig", None) is ManagerConfig:
            monkeypatch.setattr(module, "ManagerConfig", Changed)
    checks.owner.cache_clear()
    try:
        problems, _ = checks.default_problems(DOC, load(DOC).text)
    finally:
        checks.owner.cache_clear()
    assert len(problems) == 1 and "ManagerConfig.delete_after_s` = 40, but the code's default is 30.0" in problems[0]

    period = commands.parsers()[1]["serve"]._option_string_actions["--period"]
    monkeypatch.setattr(period, "default", 5.0)
    problems, _ = checks.default_problems("docs/service.md", load("docs/service.md").text)
    assert problems == ["docs/service.md:43: `serve --period` = 4, but the code's default is 5.0"]


def test_a_planted_command_option_is_reported():
    name = "docs/service.md"
    planted = _plant(name, "--speed 10\n", "--sped 10\n")
    problems, _ = checks.cli_problems(name, planted)
    assert len(problems) == 1 and "radartracker send has no option --sped" in problems[0], problems


def test_a_planted_failing_block_stops_the_run(tmp_path, monkeypatch):
    planted = parse(DOC, _plant(DOC, "chi_bar, P_bar = f.predict(t1)", "chi_bar, P_bar = f.predicts(t1)"))
    with pytest.raises(AttributeError, match="predicts"):
        run_document(planted, tmp_path, monkeypatch, slow=False)


@pytest.mark.parametrize("old,new,problem", [
    ("```python\nfrom radartracker.registry import make_filter_factory", "```\nfrom radartracker.registry import make_filter_factory",
     "fence labelled ''"),
    ("```text\nν = z", "    ν = z", "an indented code block"),
    ("<!-- docs-test: before: import numpy", "<!-- docs-test: beforehand: import numpy", "unknown directive"),
])
def test_a_planted_convention_break_is_reported(old, new, problem):
    text = load(DOC).text
    if new.startswith("    "):  # an indented block: the whole fenced formula unfenced
        start = text.index(old)
        end = text.index("```", start + len(old))
        text = text[:start] + "    " + text[start + len("```text\n"):end].rstrip("\n") + "\n" + text[end + 4:]
    else:
        text = _plant(DOC, old, new)
    problems = parse(DOC, text).problems
    assert any(problem in p for p in problems), problems
