"""The shell commands of the docs: read from ```sh and ```console blocks, checked against the CLI's parser,
and run — ``radartracker ...`` in this process through :func:`radartracker.cli.main`, anything else by bash
with this environment's ``bin`` first on the PATH (``python`` is this environment's; a script path such as
``benchmarks/x.py`` that the scratch folder does not have is the repository's).

Usage notation is allowed in a command: ``[...]`` groups are optional (left out when the command runs,
their options still checked) and ``…`` stands for more of the same (left out).
"""

from __future__ import annotations

import contextlib
import functools
import io
import json
import os
import re
import shlex
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

from tests.docs.mdparse import ROOT, Block

OPTIONAL = re.compile(r"(?:(?<=\s)|^)\[(?:[^\[\]]|\[[^\[\]]*\])*\]")  # [--opt X], also [--ref LAT,LON[,H]]


@dataclass(frozen=True)
class Command:
    """One command as the doc writes it (continuation lines joined), with the output the doc shows after it."""

    where: str
    text: str
    output: tuple[str, ...] = ()


def _logical_lines(lines: list[str]) -> list[tuple[int, str]]:
    """``(index of the first line, line)`` with backslash continuations joined."""
    out: list[tuple[int, str]] = []
    buf, first = "", 0
    for i, line in enumerate(lines):
        if not buf:
            first = i
        if line.rstrip().endswith("\\"):
            buf += line.rstrip()[:-1] + " "
            continue
        out.append((first, buf + line))
        buf = ""
    if buf:
        out.append((first, buf))
    return out


def split_line(text: str) -> list[str]:
    """A logical line's commands as written: a ``#`` comment dropped, ``&&`` chains split (each must succeed)."""
    parts, cur, quote, i = [], "", None, 0
    while i < len(text):
        ch = text[i]
        if quote:
            quote = None if ch == quote else quote
        elif ch in "'\"":
            quote = ch
        elif ch == "#" and (not cur or cur[-1].isspace()):
            break
        elif text.startswith("&&", i):
            parts.append(cur)
            cur, i = "", i + 2
            continue
        cur += ch
        i += 1
    parts.append(cur)
    return [p.strip() for p in parts if p.strip()]


def commands(block: Block) -> list[Command]:
    """The commands of a ```sh block (every line) or a ```console block (its ``$ `` lines)."""
    lines = block.text.rstrip("\n").split("\n")
    out: list[Command] = []
    if block.lang == "sh":
        for i, line in _logical_lines(lines):
            out += [Command(f"{block.doc}:{block.line + 1 + i}", c) for c in split_line(line)]
        return out
    assert block.lang == "console", block.lang
    prompts = [i for i, line in enumerate(lines) if line.startswith("$ ")]
    for n, i in enumerate(prompts):
        end = prompts[n + 1] if n + 1 < len(prompts) else len(lines)
        (_, line), *rest = _logical_lines([lines[i][2:], *lines[i + 1:end]])
        output = tuple(text for _, text in rest)
        cmds = split_line(line)
        out += [Command(f"{block.doc}:{block.line + 1 + i}", c, output if k == len(cmds) - 1 else ())
                for k, c in enumerate(cmds)]
    return out


def runnable(text: str, where: dict[str, str]) -> str:
    """A command as it runs: optional groups and ``…`` left out, ``where`` placeholders replaced."""
    text = OPTIONAL.sub(" ", text).replace(" … ", " ")
    for name, value in where.items():
        text = re.sub(rf"(?<![\w/.-]){re.escape(name)}(?![\w-])", value, text)
    return text.strip()


# --- the CLI's parser ------------------------------------------------------------------------------


@functools.lru_cache(maxsize=1)
def parsers() -> tuple:
    """``(main parser, {sub-command: its parser})`` as ``radartracker`` builds them."""
    from radartracker.cli import build_parser

    main = build_parser()
    sub = next(a for a in main._actions if a.__class__.__name__ == "_SubParsersAction")
    return main, dict(sub.choices)


def cli_problems(text: str) -> list[str]:
    """What in a ``radartracker ...`` command the CLI does not have: its sub-command, or an option of it.
    Values are not checked (a usage line has placeholders); every ``--option``, optional or not, is."""
    tokens = [t.strip("[]|") for t in shlex.split(text.replace("…", " "), comments=True)]
    if not tokens or tokens[0] != "radartracker":
        return []
    main, subs = parsers()
    rest = tokens[1:]
    while rest and rest[0].startswith("-"):
        if rest[0] not in main._option_string_actions:
            return [f"radartracker has no option {rest[0]}"]
        rest = rest[1:]
    if not rest or re.fullmatch(r"[A-Z][A-Z_]*", rest[0]):  # `radartracker --quiet COMMAND`
        return []
    if rest[0] not in subs:
        return [f"radartracker has no command {rest[0]!r}"]
    known = set(subs[rest[0]]._option_string_actions) | set(main._option_string_actions)
    return [f"radartracker {rest[0]} has no option {t.split('=')[0]}" for t in rest[1:]
            if t.startswith("--") and t.split("=")[0] not in known]


def cli_default(command: str, option: str):
    """The default of ``radartracker COMMAND OPTION`` in its parser (KeyError for an unknown one)."""
    _, subs = parsers()
    return subs[command]._option_string_actions[option].default


# --- running ---------------------------------------------------------------------------------------


def run(text: str, cwd: Path, timeout: float = 600.0) -> tuple[int, str, str]:
    """Exit status, stdout and stderr of a command line run in ``cwd``: ``radartracker ...`` in this process,
    anything else by bash."""
    argv = shlex.split(text)
    if argv[0] == "radartracker" and not set("|<>;$`") & set(text):
        return _in_process(argv[1:], cwd)
    if argv[0] in ("python", "python3"):  # this environment's; a script of the repository is found there
        script = next((a for a in argv[1:] if not a.startswith("-")), None)
        if script and not (cwd / script).exists() and (ROOT / script).is_file():
            argv = [a if a != script else str(ROOT / script) for a in argv]
        text = shlex.join([sys.executable, *argv[1:]])
    env = dict(os.environ, PATH=f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}")
    proc = subprocess.run(["bash", "-c", text], cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    return proc.returncode, proc.stdout, proc.stderr


def _in_process(args: list[str], cwd: Path) -> tuple[int, str, str]:
    from radartracker.cli import main

    out, err = io.StringIO(), io.StringIO()
    here = os.getcwd()
    os.chdir(cwd)
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                status = main(args)
            except SystemExit as exc:  # argparse's own refusals
                status = exc.code if isinstance(exc.code, int) else 2
    finally:
        os.chdir(here)
    return status, out.getvalue(), err.getvalue()


def json_keys(line: str) -> set[str] | None:
    """The top-level keys of a JSON object the doc shows (``...`` for members left out), or None."""
    text = re.sub(r",\s*\.\.\.\s*(?=[}\]])", "", line.strip())
    try:
        value = json.loads(text)
    except ValueError:
        return None
    return set(value) if isinstance(value, dict) else None


def output_problems(cmd: Command, stdout: str) -> list[str]:
    """The one comparison of printed output the test makes (cheap and stable): a JSON object the doc shows
    after a command has keys that the command's JSON output has too (values differ from run to run)."""
    printed = set().union(*(k for k in map(json_keys, stdout.strip().splitlines()) if k is not None))
    return [f"{cmd.where}: the output shown has keys {missing} that `{cmd.text}` does not print"
            for shown in map(json_keys, cmd.output) if shown is not None and (missing := sorted(shown - printed))]
