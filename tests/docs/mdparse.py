"""A Markdown document as the docs test reads it: its fenced blocks, each with the ``docs-test`` directives
written just before it, and its prose (the text with every block blanked out, line numbers kept).

The convention (docs/architecture.md, "Docs that are executed"): every code block is fenced and labelled —
``python`` and ``sh`` run, ``console`` runs its ``$ `` lines (the other lines are their output), ``text`` is
printed output, a diagram or a formula, ``json``/``toml``/``ini`` are files (parsed). A directive is an HTML
comment on the lines just before a fence, invisible on the rendered page::

    <!-- docs-test: slow -->                       run only under ``-m slow``
    <!-- docs-test: skip (why) -->                 never run (a reason is required)
    <!-- docs-test: assume CMD, CMD (why) -->      commands starting so are not run (e.g. the install)
    <!-- docs-test: where NAME=VALUE ... -->       placeholders of the block's commands, replaced
    <!-- docs-test: before: PYTHON -->            run first, in the document's namespace
    <!-- docs-test: after: PYTHON -->             run after the block, likewise
"""

from __future__ import annotations

import functools
import re
from dataclasses import dataclass
from pathlib import Path

from markdown_it import MarkdownIt

ROOT = Path(__file__).resolve().parents[2]
RUN = ("python", "sh", "console")  # blocks that run
FILES = ("json", "toml", "ini")  # blocks that are files: parsed
LABELS = (*RUN, "text", *FILES)
KINDS = ("slow", "skip", "assume", "where", "before", "after")
DIRECTIVE = re.compile(r"<!--\s*docs-test:\s*(.*?)\s*-->", re.S)
REASON = re.compile(r"\((?P<reason>[^()]*\S[^()]*)\)\s*$")


def documents() -> list[str]:
    """README.md and every docs/*.md, as paths relative to the repository."""
    return ["README.md", *sorted(str(p.relative_to(ROOT)) for p in (ROOT / "docs").glob("*.md"))]


@dataclass(frozen=True)
class Block:
    """A fenced block: ``line`` is the 1-based line of its opening fence, ``text`` its content."""

    doc: str
    line: int
    lang: str
    text: str
    directives: tuple[tuple[str, str], ...] = ()

    def args(self, kind: str) -> list[str]:
        return [arg for k, arg in self.directives if k == kind]

    @property
    def slow(self) -> bool:
        return bool(self.args("slow"))

    @property
    def skipped(self) -> bool:
        return bool(self.args("skip"))

    @property
    def where(self) -> str:
        return f"{self.doc}:{self.line}"


@dataclass(frozen=True)
class Document:
    """``prose``: the text with every block (fenced, indented, HTML) blanked, so line numbers still hold."""

    name: str
    text: str
    blocks: tuple[Block, ...]
    prose: str
    problems: tuple[str, ...]  # fences, indented code and directives that break the convention

    def line_of(self, offset: int) -> int:
        """The line of an offset into ``prose``."""
        return self.prose.count("\n", 0, offset) + 1


@functools.lru_cache(maxsize=1)
def _parser() -> MarkdownIt:
    return MarkdownIt("commonmark").enable("table")


def parse_directive(body: str) -> tuple[str, str]:
    """``(kind, argument)`` of a directive's text, or a ValueError saying what is wrong with it."""
    m = re.match(r"(?P<kind>\w+)(?P<colon>:?)\s*(?P<arg>.*)$", body, re.S)
    if not m or m["kind"] not in KINDS:
        raise ValueError(f"unknown directive {body!r} (known: {', '.join(KINDS)})")
    kind, arg = m["kind"], m["arg"].strip()
    if kind in ("skip", "assume") and not REASON.search(arg):
        raise ValueError(f"{kind} needs a reason in parentheses: {body!r}")
    if kind in ("before", "after", "where", "assume") and not arg:
        raise ValueError(f"{kind} needs an argument: {body!r}")
    if kind == "where" and not all("=" in pair for pair in arg.split()):
        raise ValueError(f"where takes NAME=VALUE pairs: {body!r}")
    if kind == "slow" and arg:
        raise ValueError(f"slow takes no argument: {body!r}")
    return kind, arg


def parse(name: str, text: str) -> Document:
    """The blocks, prose and convention problems of document ``name`` whose content is ``text``."""
    lines = text.split("\n")
    blanked = list(lines)
    blocks, problems, pending = [], [], []
    for tok in _parser().parse(text):
        if tok.map is None:
            continue
        if tok.type not in ("fence", "code_block", "html_block"):
            if pending:  # a paragraph, list, table... between a directive and its fence
                problems.append(f"{name}:{pending[0][0]}: a docs-test directive not just before a fence")
                pending = []
            continue
        start, end = tok.map
        blanked[start:end] = [""] * (end - start)
        if tok.type == "html_block":
            for m in DIRECTIVE.finditer(tok.content):
                try:
                    pending.append((start + 1, parse_directive(m.group(1))))
                except ValueError as exc:
                    problems.append(f"{name}:{start + 1}: {exc}")
            continue
        if tok.type == "code_block":
            problems.append(f"{name}:{start + 1}: an indented code block: fence it and label it (```text for a formula)")
            continue
        lang = tok.info.strip().split(" ")[0]
        if lang not in LABELS:
            problems.append(f"{name}:{start + 1}: fence labelled {lang!r}; use one of {', '.join(LABELS)}")
        directives = tuple(d for _, d in pending)
        if directives and lang not in RUN:
            problems.append(f"{name}:{start + 1}: docs-test directives before a ```{lang} block, which does not run")
        blocks.append(Block(name, start + 1, lang, tok.content, directives))
        pending = []
    if pending:
        problems.append(f"{name}:{pending[0][0]}: a docs-test directive not just before a fence")
    return Document(name, text, tuple(blocks), "\n".join(blanked), tuple(problems))


@functools.lru_cache(maxsize=None)
def load(name: str) -> Document:
    """Document ``name`` (relative to the repository) as it is on disk."""
    return parse(name, (ROOT / name).read_text(encoding="utf-8"))
