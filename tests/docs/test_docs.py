"""README.md and docs/*.md are executed: every block follows the fence convention, files parse, every
Python block and shell command runs (the slow ones under ``-m slow``), every module path resolves, every
``radartracker`` command names options the CLI has, and every quoted default is the code's.
docs/architecture.md, "Docs that are executed", states the convention."""

from __future__ import annotations

import configparser
import json
import re
import tomllib

import pytest

from tests.docs import checks
from tests.docs.report import REPORT
from tests.docs.mdparse import RUN, documents, load
from tests.docs.runner import run_document

DOCS = documents()
RUNNABLE = [d for d in DOCS if any(b.lang in RUN and not b.skipped for b in load(d).blocks)]
WITH_SLOW = [d for d in DOCS if any(b.slow and not b.skipped for b in load(d).blocks)]


def _none(problems) -> None:
    if problems:
        pytest.fail("\n".join(problems), pytrace=False)


@pytest.mark.parametrize("name", DOCS)
def test_every_block_is_fenced_and_labelled(name):
    doc = load(name)
    REPORT.add("blocks", len(doc.blocks))
    _none(doc.problems)


def _parse_file_block(lang: str, text: str) -> None:
    """A ```json block is one JSON value or JSON lines (``...`` stands for members left out); ```toml and
    ```ini parse as such."""
    if lang == "json":
        text = re.sub(r",\s*\.\.\.\s*(?=[}\]])", "", text).replace("{...}", "{}")
        try:
            json.loads(text)
        except ValueError:
            for line in filter(str.strip, text.splitlines()):
                json.loads(line)
    elif lang == "toml":
        tomllib.loads(text)
    else:
        configparser.ConfigParser(strict=True, interpolation=None).read_string(text)


@pytest.mark.parametrize("name", DOCS)
def test_file_blocks_parse(name):
    for block in load(name).blocks:
        if block.lang in ("json", "toml", "ini"):
            REPORT.add("files", 1)
            try:
                _parse_file_block(block.lang, block.text)
            except ValueError as exc:
                pytest.fail(f"{block.where}: the ```{block.lang} block does not parse: {exc}")


STATIC = {  # what the report counts → the check: module and file paths resolve, commands name what the CLI
    # has, quoted defaults are the code's
    "paths": checks.module_path_problems,
    "commands parsed": checks.cli_problems,
    "defaults": checks.default_problems,
}


@pytest.mark.parametrize("what", STATIC)
@pytest.mark.parametrize("name", DOCS)
def test_static_checks(name, what):
    problems, checked = STATIC[what](name, load(name).text)
    REPORT.add(what, checked)
    _none(problems)


@pytest.mark.parametrize("name", RUNNABLE)
def test_document_runs(name, tmp_path, monkeypatch):
    """The document's blocks in order in a scratch folder; slow ones are left to the test below."""
    tally = run_document(load(name), tmp_path, monkeypatch, slow=False)
    REPORT.tally(tally)
    assert tally.run or tally.slow, f"{name}: nothing ran"


@pytest.mark.slow
@pytest.mark.parametrize("name", WITH_SLOW)
def test_document_runs_with_its_slow_blocks(name, tmp_path, monkeypatch):
    tally = run_document(load(name), tmp_path, monkeypatch, slow=True)
    REPORT.tally(tally)
    assert not tally.slow
