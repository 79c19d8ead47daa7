"""Checks of a document's text against the code: module paths import, file paths exist, ``radartracker``
commands name commands and options the CLI has, and the defaults it quotes are the code's.

A quoted default is a code span holding NAME, followed by ``=`` and VALUE — in the Markdown source, the
name ManagerConfig.gate between backquotes, then " = 13.82" (docs/architecture.md, "Docs that are
executed"). There:

* NAME is ``Owner.field`` (``Owner`` a config class, function or constant of :data:`OWNER_MODULES`, or a
  full dotted path; ``.field`` may go on into nested configs, dict keys and a function's keyword
  parameters), or ``radartracker COMMAND --option`` (the default of that option in the CLI's parser), or
  a bare ``field`` after an ``Owner.field`` in the same paragraph (it is that owner's);
* VALUE is a number (``100 000``-style thousands allowed; a trailing ``°`` means the code holds radians),
  a tuple ``(120, 30)``, ``true``/``false``/``none``, or a string as Python writes it, in a code span.
  A number is compared at the precision the doc writes it: ``0.0087`` states 4 decimals.

Each function takes a document's name and text (a copy can be checked) and returns a list of problems.
"""

from __future__ import annotations

import functools
import importlib
import inspect
import math
import re
from importlib import metadata
from typing import Any

import attrs

from tests.docs import commands
from tests.docs.mdparse import ROOT, parse

DOTTED = re.compile(r"(?<![\w./-])(radartracker(?:_plugins)?(?:\.[A-Za-z_]\w*)+)")
SUBPACKAGES = sorted(p.parent.name for p in ROOT.glob("radartracker/*/__init__.py"))  # `io/scenario.py` is theirs
FILE_PATH = re.compile(r"(?<![\w./-])((?:radartracker|plugins|tests|scripts|benchmarks|docs|"
                       + "|".join(SUBPACKAGES) + r")/[\w./*-]*[\w/])")
FILE_ATTR = re.compile(r"`((?:[\w-]+/)+[\w-]+\.py): ?([A-Za-z_][\w.]*)`")  # `pipeline/run.py: run`
NAME = r"[\w-]+\.[\w.]+|(?:radartracker )?[a-z][\w-]* --[\w-]+|[a-z_]\w*"  # Owner.field, a CLI option, a field
NUMBER = r"[-−]?\d{1,3}(?:[ \u2009\u202f]\d{3})+(?:\.\d+)?°?|[-−]?\d+(?:\.\d+)?°?"  # 100 000, 0.5°
VALUE = rf"`\"[^`\"\n]*\"`|\([^()\n]*\)|true\b|false\b|none\b|{NUMBER}"
DEFAULT = re.compile(rf"`(?P<name>{NAME})`(?:[ \t]*\n)?[ \t]*=[ \t]*(?:\n[ \t]*)?(?P<value>{VALUE})")
OWNER_MODULES = (
    "radartracker.tracking.config", "radartracker.pipeline.config", "radartracker.estimation.screening",
    "radartracker.clock", "radartracker.estimation.base", "radartracker.estimation.motion", "radartracker.api",
    "radartracker.registry", "radartracker.fusion.center", "radartracker.fusion.cat048",
    "radartracker.service.service", "radartracker.simulation.traffic", "radartracker_plugins.motion",
    "radartracker_plugins.reconstruction", "radartracker_plugins.triangulation",
)


# --- module and file paths -----------------------------------------------------------------------


@functools.lru_cache(maxsize=1)
def entry_point_groups() -> frozenset[str]:
    """The entry-point groups the distribution registers plugins in (``radartracker.estimators``, ...)."""
    return frozenset(ep.group for ep in metadata.distribution("radartracker").entry_points)


def resolve(dotted: str) -> Any:
    """The object a dotted name names: the longest importable module prefix, then attributes (and dict keys).
    A LookupError says which part is missing."""
    parts = dotted.split(".")
    for n in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:n]))
        except ModuleNotFoundError as exc:
            if exc.name is None or not ".".join(parts[:n]).startswith(exc.name):
                raise  # the module exists but one of its own imports is missing: a real failure
            continue
        break
    else:
        raise LookupError(f"no module {parts[0]!r}")
    for i, part in enumerate(parts[n:], n):
        if isinstance(obj, dict) and part in obj:
            obj = obj[part]
        elif hasattr(obj, part):
            obj = getattr(obj, part)
        else:
            raise LookupError(f"{'.'.join(parts[:i])} has no {part!r}")
    return obj


def module_path_problems(name: str, text: str) -> tuple[list[str], int]:
    """Dotted ``radartracker.``/``radartracker_plugins.`` names in the prose and the Python blocks that do not
    resolve (entry-point groups are names too), and file paths of the repository that do not exist.
    Output blocks (```text, ```console, files) are left out: they show what a program printed or wrote.
    Returns the problems and how many names were checked."""
    doc = parse(name, text)
    texts = [(doc.prose, 1)] + [(b.text, b.line + 1) for b in doc.blocks if b.lang == "python"]
    problems, checked = [], 0
    for body, first in texts:
        for m in DOTTED.finditer(body):
            dotted, line = m.group(1), first + body.count("\n", 0, m.start())
            checked += 1
            if dotted in entry_point_groups():
                continue
            try:
                resolve(dotted)
            except (LookupError, ImportError) as exc:
                problems.append(f"{name}:{line}: {dotted}: {exc}")
        if body is doc.prose:
            p, n = _file_problems(doc)
            problems, checked = problems + p, checked + n
    return problems, checked


def _repo_path(path: str) -> str:
    """A path as the repository has it: ``io/scenario.py`` is ``radartracker/io/scenario.py``."""
    return f"radartracker/{path}" if path.split("/")[0] in SUBPACKAGES else path


def _file_problems(doc) -> tuple[list[str], int]:
    """File paths of the repository named in the prose that do not exist (globs allowed), and code spans
    ``path.py: name`` whose module has no such name."""
    problems, checked = [], 0
    for m in FILE_PATH.finditer(doc.prose):
        checked += 1
        if not any(ROOT.glob(_repo_path(m.group(1)))):
            problems.append(f"{doc.name}:{doc.line_of(m.start())}: {m.group(1)}: no such file in the repository")
    for m in FILE_ATTR.finditer(doc.prose):
        checked += 1
        parts = _repo_path(m.group(1)).removesuffix(".py").split("/")
        if parts[0] not in ("radartracker", "plugins"):
            continue
        module = ".".join(["radartracker_plugins" if parts[0] == "plugins" else parts[0], *parts[1:]])
        try:
            resolve(f"{module}.{m.group(2)}")
        except (LookupError, ImportError) as exc:
            problems.append(f"{doc.name}:{doc.line_of(m.start())}: {m.group(1)}: {m.group(2)}: {exc}")
    return problems, checked


def cli_problems(name: str, text: str) -> tuple[list[str], int]:
    """``radartracker`` commands — every one of the ```sh/```console blocks (run or not) and every code span of
    the prose that starts with ``radartracker `` — name a command and options the CLI has."""
    doc = parse(name, text)
    found = [(c.where, c.text) for b in doc.blocks if b.lang in ("sh", "console") for c in commands.commands(b)]
    found += [(f"{name}:{doc.line_of(m.start())}", m.group(1))
              for m in re.finditer(r"`(radartracker [^`\n]+)`", doc.prose)]
    problems = [f"{where}: `{cmd}`: {p}" for where, cmd in found for p in commands.cli_problems(cmd)]
    return problems, len(found)


# --- defaults ----------------------------------------------------------------------------------


@functools.lru_cache(maxsize=None)
def owner(short: str) -> Any:
    """The config class or constant named ``short`` in :data:`OWNER_MODULES` (the same object in all that
    have it), or a LookupError."""
    found = {id(o): o for o in (getattr(importlib.import_module(m), short, None) for m in OWNER_MODULES)
             if o is not None}
    if len(found) != 1:
        raise LookupError(f"{short!r} is {'ambiguous' if found else 'not a class or constant of'} "
                          f"{', '.join(OWNER_MODULES)}; write its full dotted path")
    return next(iter(found.values()))


def _instance(obj: Any) -> Any:
    """An attrs class as its default instance (defaults and factories applied); anything else as it is."""
    return obj() if isinstance(obj, type) and attrs.has(obj) else obj


def code_default(name: str) -> Any:
    """The value the code gives NAME (see the module docstring); LookupError when NAME names nothing."""
    cli = re.fullmatch(r"(?:radartracker )?([a-z][\w-]*) (--[\w-]+)", name)
    if cli:
        try:
            return commands.cli_default(*cli.groups())
        except KeyError:
            raise LookupError(f"radartracker has no command or option {name!r}") from None
    head, *rest = name.split(".")
    if head in ("radartracker", "radartracker_plugins"):  # a full path: its module, then the rest
        parts = name.split(".")
        n = next(i for i in range(len(parts), 0, -1) if _is_module(".".join(parts[:i])))
        obj, rest = resolve(".".join(parts[:n + 1])), parts[n + 1:]
    else:
        obj = owner(head)
    obj = _instance(obj)
    for part in rest:
        obj = _instance(_step(obj, part, name))
    return obj


def _is_module(dotted: str) -> bool:
    try:
        importlib.import_module(dotted)
    except ImportError:
        return False
    return True


def _step(obj: Any, part: str, name: str) -> Any:
    """``obj``'s ``part``: a dict key, an attribute, or the default of a function's keyword parameter."""
    if isinstance(obj, dict) and part in obj:
        return obj[part]
    if hasattr(obj, part):
        return getattr(obj, part)
    if callable(obj):
        param = inspect.signature(obj).parameters.get(part)
        if param is not None and param.default is not inspect.Parameter.empty:
            return param.default
    raise LookupError(f"{name}: no {part!r}")


def _number(text: str) -> float:
    return float(re.sub(r"[ \u2009\u202f]", "", text).replace("−", "-"))


def _same_number(doc: str, code: Any) -> bool:
    """Whether ``code`` written at the doc's precision is the doc's number (``°``: the code's radians)."""
    if isinstance(code, bool) or not isinstance(code, (int, float)):
        return False
    degrees = doc.endswith("°")
    doc = doc.rstrip("°")
    decimals = len(doc.split(".")[1]) if "." in doc else 0
    value = math.degrees(code) if degrees else float(code)
    return math.isclose(round(value, decimals), _number(doc), rel_tol=1e-12, abs_tol=1e-12)


def same(doc: str, code: Any) -> bool:
    """Whether the VALUE the doc writes is the code's value."""
    if doc.startswith("`"):
        return isinstance(code, str) and doc.strip("`")[1:-1] == code
    if doc in ("true", "false", "none"):
        return code is {"true": True, "false": False, "none": None}[doc]
    if doc.startswith("("):
        items = [s.strip() for s in doc[1:-1].split(",") if s.strip()]
        return (isinstance(code, (tuple, list)) and len(code) == len(items)
                and all(_same_number(d, c) for d, c in zip(items, code)))
    return _same_number(doc, code)


def _qualified(doc, m: re.Match) -> str | None:
    """The NAME of a quoted default as the code knows it: ``Owner.field`` and CLI options as written; a bare
    ``field`` takes the owner of the last qualified default before it in its paragraph (None without one:
    then it is no quoted default, as the bare ``dof`` of docs/formats.md's "`dof` = 2·bearings − 3")."""
    quoted = m["name"]
    if "." in quoted or " " in quoted:
        return quoted
    start = doc.prose.rfind("\n\n", 0, m.start()) + 1
    owners = [_owner_of(q["name"]) for q in DEFAULT.finditer(doc.prose, start, m.start()) if "." in q["name"]]
    return f"{owners[-1]}.{quoted}" if owners else None


def _owner_of(qualified: str) -> str:
    """The owner part of a qualified NAME: ``ManagerConfig`` of ``ManagerConfig.estimator_config.motion.q``,
    ``radartracker.clock.ClockConfig`` of ``radartracker.clock.ClockConfig.window``."""
    parts = qualified.split(".")
    n = 1
    if parts[0] in ("radartracker", "radartracker_plugins"):
        while n < len(parts) and _is_module(".".join(parts[:n + 1])):
            n += 1
        n += 1
    return ".".join(parts[:n])


def default_problems(name: str, text: str) -> tuple[list[str], int]:
    """Every quoted default of the prose checked against the code; returns the problems and how many."""
    doc = parse(name, text)
    problems, checked = [], 0
    for m in DEFAULT.finditer(doc.prose):
        quoted, value = _qualified(doc, m), m["value"]
        if quoted is None:
            continue
        where = f"{name}:{doc.line_of(m.start())}"
        checked += 1
        try:
            code = code_default(quoted)
        except (LookupError, ImportError) as exc:
            problems.append(f"{where}: `{quoted}` = {value}: {exc}")
            continue
        if not same(value, code):
            problems.append(f"{where}: `{quoted}` = {value}, but the code's default is {code!r}")
    return problems, checked
