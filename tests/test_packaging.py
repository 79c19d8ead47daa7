"""A wheel built from the source tree holds every package of ``radartracker/`` and of ``plugins/`` (installed
as ``radartracker_plugins``), the package data, and the module of every entry point."""

from __future__ import annotations

import configparser
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SOURCES = ("radartracker", "plugins", "pyproject.toml", "setup.py", "README.md")
INSTALLED_AS = {"radartracker": "radartracker", "plugins": "radartracker_plugins"}


def _tree_packages(root: Path) -> set[str]:
    """Each folder holding an ``__init__.py``, as its path in an installed tree (``plugins/x`` →
    ``radartracker_plugins/x``)."""
    out = set()
    for top, name in INSTALLED_AS.items():
        for init in (root / top).rglob("__init__.py"):
            out.add("/".join([name, *init.parent.relative_to(root / top).parts]))
    return out


def _missing(tree: set[str], names: list[str]) -> set[str]:
    """The packages of ``tree`` whose ``__init__.py`` is not among the wheel's ``names``."""
    return {p for p in tree if f"{p}/__init__.py" not in names}


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> zipfile.ZipFile:
    """A wheel built from a copy of the sources (the build leaves ``build/`` and ``*.egg-info`` behind)."""
    tmp = tmp_path_factory.mktemp("wheel")
    src = tmp / "src"
    for name in SOURCES:
        path = ROOT / name
        if not path.exists():
            continue
        if path.is_dir():
            shutil.copytree(path, src / name, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
        else:
            src.mkdir(exist_ok=True)
            shutil.copy2(path, src / name)
    done = subprocess.run([sys.executable, "-m", "pip", "wheel", "--quiet", "--no-deps", "--no-build-isolation",
                           str(src), "-w", str(tmp / "dist")], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    (built,) = (tmp / "dist").glob("radartracker-*.whl")
    return zipfile.ZipFile(built)


def test_the_wheel_holds_every_package_of_the_tree(wheel):
    tree = _tree_packages(ROOT)
    assert {"radartracker", "radartracker/fusion", "radartracker_plugins", "radartracker_plugins/motion"} <= tree
    assert _missing(tree, wheel.namelist()) == set()


def test_the_wheel_holds_the_package_data(wheel):
    data = {f"radartracker/data/{p.name}" for p in (ROOT / "radartracker" / "data").iterdir() if p.is_file()}
    assert data and data <= set(wheel.namelist())


def test_every_entry_point_names_a_module_in_the_wheel(wheel):
    names = set(wheel.namelist())
    (path,) = [n for n in names if n.endswith(".dist-info/entry_points.txt")]
    points = configparser.ConfigParser(delimiters=("=",))
    points.read_string(wheel.read(path).decode())
    targets = [v.split(":")[0].strip() for s in points.sections() for v in points[s].values()]
    assert len(targets) > 20
    for module in targets:
        stem = module.replace(".", "/")
        assert f"{stem}.py" in names or f"{stem}/__init__.py" in names, module


def test_a_package_left_out_is_found_missing():
    """The check above can fail: a wheel's names without one folder's ``__init__.py`` leave it missing."""
    tree = _tree_packages(ROOT)
    names = [f"{p}/__init__.py" for p in tree if p != "radartracker/fusion"]
    assert _missing(tree, names) == {"radartracker/fusion"}
