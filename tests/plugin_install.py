"""Install a throw-away plugin from a test as pip would: a package and a dist-info with entry_points.txt on
sys.path (nothing in the core touched)."""

import sys
import textwrap


def install(tmp_path, monkeypatch, package: str, source: str, entry_points: str):
    """Package ``package`` with ``source`` as its ``__init__.py``, registered by ``entry_points`` (the text of
    entry_points.txt); returns the imported module. The caller's fixture removes it with :func:`uninstall`."""
    pkg = tmp_path / "site" / package
    pkg.mkdir(parents=True)
    (pkg / "__init__.py").write_text(textwrap.dedent(source))
    dist = tmp_path / "site" / f"{package}-0.1.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {package.replace('_', '-')}\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text(entry_points)
    monkeypatch.syspath_prepend(str(tmp_path / "site"))
    return sys.modules.get(package) or __import__(package)


def uninstall(package: str) -> None:
    for name in [m for m in sys.modules if m == package or m.startswith(package + ".")]:
        del sys.modules[name]
