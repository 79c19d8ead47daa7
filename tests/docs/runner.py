"""Running a document as a reader would: its ```python, ```sh and ```console blocks in order, in one scratch
folder and one Python namespace per document (so a fragment runs in the context the blocks before it set up,
and a command finds the files an earlier one wrote).

A Python block is compiled as lines of the document itself, so a traceback points at the doc's line. The
``before:``/``after:`` directives run Python in the same namespace, where the helpers of
:mod:`tests.docs.contexts` are defined.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass, field
from pathlib import Path

from tests.docs import commands, contexts
from tests.docs.contexts import DocFailure
from tests.docs.mdparse import ROOT, RUN, REASON, Block, Document


@dataclass
class Tally:
    """What a run did, for the report: blocks run, passed over (slow, skipped), commands run."""

    run: list[str] = field(default_factory=list)
    slow: list[str] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)
    commands: int = 0
    assumed: int = 0


def _python(code: str, block: Block, namespace: dict, what: str) -> None:
    """Run ``code``; a block's own code gets the doc's line numbers (its traceback shows the doc)."""
    if what == "block":
        source, filename = "\n" * block.line + code, str(ROOT / block.doc)
    else:
        source, filename = code, f"<{block.where} {what}>"
    exec(compile(source, filename, "exec"), namespace)


def _assumed(block: Block) -> list[str]:
    """The command prefixes an ``assume`` directive names (``assume A, B (why)``)."""
    out = []
    for arg in block.args("assume"):
        out += [p.strip() for p in REASON.sub("", arg).split(",") if p.strip()]
    return out


def _shell(block: Block, cwd: Path, tally: Tally) -> None:
    """Every command of the block in order: status 0, and the JSON keys the doc shows printed."""
    where = dict(pair.split("=", 1) for arg in block.args("where") for pair in arg.split())
    prefixes = _assumed(block)
    used = set()
    for cmd in commands.commands(block):
        hit = next((p for p in prefixes if cmd.text == p or cmd.text.startswith(p + " ")), None)
        if hit:
            used.add(hit)
            tally.assumed += 1
            continue
        text = commands.runnable(cmd.text, where)
        status, out, err = commands.run(text, cwd)
        tally.commands += 1
        if status != 0:
            raise DocFailure(f"{cmd.where}: `{cmd.text}` (run as `{text}`) exited with {status}:\n{err[-3000:]}")
        if problems := commands.output_problems(cmd, out):
            raise DocFailure("\n".join(problems))
    if unused := [p for p in prefixes if p not in used]:
        raise DocFailure(f"{block.where}: `assume` names {unused}, which no command of the block starts with")


def run_document(doc: Document, cwd: Path, monkeypatch, *, slow: bool) -> Tally:
    """Run the document's blocks in order in ``cwd`` (slow ones only when ``slow``); a DocFailure names the
    first block or command that failed."""
    tally = Tally()
    namespace = contexts.namespace(cwd, monkeypatch)
    here = os.getcwd()
    os.chdir(cwd)
    try:
        for block in doc.blocks:
            if block.lang not in RUN:
                continue
            if block.skipped:
                tally.skipped.append(f"{block.where} {re.sub(r'^.*?[(]', '(', block.args('skip')[0])}")
                continue
            if block.slow and not slow:
                tally.slow.append(block.where)
                continue
            for code in block.args("before"):
                _python(code, block, namespace, "before")
            if block.lang == "python":
                _python(block.text, block, namespace, "block")
            else:
                _shell(block, cwd, tally)
            for code in block.args("after"):
                _python(code, block, namespace, "after")
            tally.run.append(block.where)
    finally:
        os.chdir(here)
    return tally
