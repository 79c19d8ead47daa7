"""The package layout holds: no import cycles in the core, plugins use nothing but ``radartracker.api``."""

from __future__ import annotations

import ast
from pathlib import Path

import networkx as nx

ROOT = Path(__file__).resolve().parents[1]


def _module_name(path: Path, top: Path, package: str) -> str:
    rel = path.relative_to(top).with_suffix("")
    parts = [package, *rel.parts]
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _runtime_nodes(tree: ast.AST):
    """Every node except those under ``if TYPE_CHECKING:`` (annotations only, never executed)."""
    for node in ast.iter_child_nodes(tree):
        if isinstance(node, ast.If) and getattr(node.test, "id", getattr(node.test, "attr", "")) == "TYPE_CHECKING":
            yield from (n for orelse in node.orelse for n in ast.walk(orelse))
            continue
        yield node
        yield from _runtime_nodes(node)


def _imports(path: Path, module: str) -> set[str]:
    """Modules imported at run time by ``path`` (absolute names; relative imports resolved)."""
    out = set()
    pkg = module if path.name == "__init__.py" else module.rpartition(".")[0]
    for node in _runtime_nodes(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = pkg.split(".")
                anchor = anchor[: len(anchor) - node.level + 1]
                base = ".".join(anchor + ([base] if base else []))
            out.add(base)
            out.update(f"{base}.{a.name}" for a in node.names)
    return out


def _graph(top: Path, package: str) -> nx.DiGraph:
    files = {_module_name(p, top, package): p for p in top.rglob("*.py")}
    g = nx.DiGraph()
    g.add_nodes_from(files)
    for mod, path in files.items():
        for imp in _imports(path, mod):
            if imp in files and imp != mod:
                g.add_edge(mod, imp)
    return g


def test_core_has_no_import_cycles():
    g = _graph(ROOT / "radartracker", "radartracker")
    # a package importing its own submodule is not a cycle the reader has to untangle
    g.remove_edges_from([(a, b) for a, b in list(g.edges) if b.startswith(a + ".")])
    cycles = list(nx.simple_cycles(g))
    assert cycles == [], f"import cycles: {cycles[:5]}"


def _folder(module: str) -> str:
    """The part of the core a module belongs to: its folder (``tracking``), or the top-level module itself."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else parts[0]


def folder_graph(g: nx.DiGraph) -> nx.DiGraph:
    """Imports between the core's folders and top-level modules (an edge when any module of one imports any
    module of the other), each edge with one import that makes it."""
    out = nx.DiGraph()
    for a, b in g.edges:
        fa, fb = _folder(a), _folder(b)
        if fa != fb and fb != "radartracker":
            out.add_edge(fa, fb, via=(a, b))
    return out


def test_core_folders_have_no_import_cycles():
    """No circle between folders either (pipeline → fusion → pipeline is a circle even when no two modules
    import each other): the core's parts can be read bottom-up."""
    f = folder_graph(_graph(ROOT / "radartracker", "radartracker"))
    cycles = [[(u, f.edges[u, v]["via"]) for u, v in zip(c, c[1:] + c[:1])] for c in nx.simple_cycles(f)]
    assert cycles == [], f"folder import cycles: {cycles[:3]}"


def test_plugins_import_only_the_public_api():
    offending = []
    for path in (ROOT / "plugins").rglob("*.py"):
        mod = _module_name(path, ROOT / "plugins", "radartracker_plugins")
        for imp in _imports(path, mod):
            if imp.startswith("radartracker.") and not (imp == "radartracker.api" or imp.startswith("radartracker.api.")):
                offending.append(f"{path.relative_to(ROOT)}: {imp}")
            if imp == "radartracker":
                offending.append(f"{path.relative_to(ROOT)}: radartracker")
    assert offending == []


def test_the_walker_sees_a_cycle_and_an_internal_import(tmp_path):
    """The two checks above can fail: a planted cycle and a planted internal import are found."""
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text("from pkg.b import x\n")
    (pkg / "b.py").write_text("from pkg import a\nx = 1\n")
    g = _graph(pkg, "pkg")
    g.remove_edges_from([(a, b) for a, b in list(g.edges) if b.startswith(a + ".")])
    assert list(nx.simple_cycles(g))
    plug = tmp_path / "plug.py"
    plug.write_text("from radartracker.tracking.manager import TrackManager\n")
    assert "radartracker.tracking.manager" in _imports(plug, "radartracker_plugins.plug")


def test_the_folder_walker_sees_a_circle_of_folders(tmp_path):
    """Folders x and y whose modules import each other's (no module cycle) make a folder cycle."""
    pkg = tmp_path / "pkg"
    for d in ("x", "y"):
        (pkg / d).mkdir(parents=True)
        (pkg / d / "__init__.py").write_text("")
    (pkg / "__init__.py").write_text("")
    (pkg / "x" / "a.py").write_text("from pkg.y.b import v\n")
    (pkg / "y" / "b.py").write_text("v = 1\n")
    (pkg / "y" / "c.py").write_text("from pkg.x.d import w\n")
    (pkg / "x" / "d.py").write_text("w = 2\n")
    g = _graph(pkg, "pkg")
    assert not list(nx.simple_cycles(g)) and list(nx.simple_cycles(folder_graph(g)))


def test_the_lazy_api_runs_what_type_checkers_read():
    """radartracker.api imports its names on first use (``_EXPORTS``); its ``TYPE_CHECKING`` block, what type
    checkers and editors read, names the same modules and names, and each resolves."""
    import radartracker.api as api

    tree = ast.parse((ROOT / "radartracker" / "api.py").read_text())
    block = next(n for n in tree.body if isinstance(n, ast.If) and getattr(n.test, "id", "") == "TYPE_CHECKING")
    read = {node.module: tuple(a.name for a in node.names) for node in block.body}
    assert read == api._EXPORTS
    assert all(getattr(api, name) is not None for name in api.__all__)
