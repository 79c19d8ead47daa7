"""The benchmark and study scripts still import: a name removed from the package fails here, not in a
session months later. Imports only; nothing is run."""

from __future__ import annotations

import ast
import importlib
import importlib.util
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FOLDERS = ("benchmarks", "scripts")
MODULES = sorted(p for folder in FOLDERS for p in (ROOT / folder).glob("*.py"))
OURS = ("radartracker", "radartracker_plugins")


def test_there_are_modules() -> None:
    assert {p.parent.name for p in MODULES} == set(FOLDERS)
    assert (ROOT / "benchmarks" / "bench_guard.py") in MODULES


@pytest.mark.parametrize("path", MODULES, ids=lambda p: f"{p.parent.name}/{p.name}")
def test_module_imports(path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The module loads (its ``__main__`` block not run), with its own folder on the path as when run."""
    monkeypatch.syspath_prepend(str(path.parent))
    spec = importlib.util.spec_from_file_location(f"_bench_{path.parent.name}_{path.stem}", path)
    module = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, spec.name, module)
    spec.loader.exec_module(module)


def _imports(path: Path) -> list[tuple[int, str, str | None]]:
    """(line, module, name or None) of every import of the package in the file, inside functions too."""
    out = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module.split(".")[0] in OURS:
            out += [(node.lineno, node.module, a.name) for a in node.names]
        elif isinstance(node, ast.Import):
            out += [(node.lineno, a.name, None) for a in node.names if a.name.split(".")[0] in OURS]
    return out


@pytest.mark.parametrize("path", MODULES, ids=lambda p: f"{p.parent.name}/{p.name}")
def test_deferred_imports_resolve(path: Path) -> None:
    """Imports made inside functions (run only when a benchmark runs) name modules and names that exist."""
    missing = []
    for line, module, name in _imports(path):
        mod = importlib.import_module(module)
        if name is not None and not hasattr(mod, name) and importlib.util.find_spec(f"{module}.{name}") is None:
            missing.append(f"line {line}: from {module} import {name}")
    assert not missing, f"{path.name}: " + "; ".join(missing)
