"""GraphML of a networkx graph with the bytes of ``networkx.write_graphml``, written as one string.

networkx builds an ElementTree element per node, edge and datum, indents it and serialises it in
Python (~33 ms for the 200-aircraft replay's coupling graph, ~1.8 µs per input). :func:`write_graphml`
writes the same document directly for what a run's coupling graph holds: an undirected simple graph
without graph-level attributes or defaults whose data values are ``str``, ``int``, ``float`` or
``bool``. Any other graph, or lxml installed (networkx then writes with lxml), goes to networkx itself.

The document networkx writes (its ``GraphMLWriter`` with ElementTree, pretty-printed): one ``key`` per
(name, GraphML type, scope) in the order first met over the nodes then the edges, ids ``d0``, ``d1``…,
listed last-made first; each datum's text ``str(value)``; two spaces of indent per level; an element
without content as ``<tag … />``; text escaped as ElementTree escapes it.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import networkx as nx

_XML_TYPE = {int: "long", str: "string", float: "double", bool: "boolean"}  # networkx's, for these types
_HEAD = ("<?xml version='1.0' encoding='utf-8'?>\n"
         '<graphml xmlns="http://graphml.graphdrawing.org/xmlns" xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance"'
         ' xsi:schemaLocation="http://graphml.graphdrawing.org/xmlns '
         'http://graphml.graphdrawing.org/xmlns/1.0/graphml.xsd">')


def _text(s: str) -> str:
    """Character data as ElementTree escapes it."""
    if "&" in s:
        s = s.replace("&", "&amp;")
    if "<" in s:
        s = s.replace("<", "&lt;")
    if ">" in s:
        s = s.replace(">", "&gt;")
    return s


def _attr(s: str) -> str:
    """An attribute value as ElementTree escapes it."""
    s = _text(s)
    for c, ref in (('"', "&quot;"), ("\r", "&#13;"), ("\n", "&#10;"), ("\t", "&#09;")):
        if c in s:
            s = s.replace(c, ref)
    return s


def graphml_text(g: nx.Graph) -> str | None:
    """The document ``nx.write_graphml(g)`` writes (without lxml), or ``None`` for a graph outside the cases
    of the module docstring."""
    if g.is_directed() or g.is_multigraph() or g.graph:
        return None
    keys: dict[tuple[str, str, str], str] = {}
    out: list[str] = []

    def element(tag: str, head: str, data: dict, scope: str) -> bool:
        """``<tag head>`` and its data; False for a value networkx would type otherwise than _XML_TYPE."""
        if not data:
            out.append(f"\n    <{tag} {head} />")
            return True
        out.append(f"\n    <{tag} {head}>")
        for k, v in data.items():
            xml_type = _XML_TYPE.get(type(v))
            if xml_type is None:
                return False
            name = str(k)
            key = keys.setdefault((name, xml_type, scope), f"d{len(keys)}")
            value = str(v)
            out.append(f'\n      <data key="{key}">{_text(value)}</data>' if value else f'\n      <data key="{key}" />')
        out.append(f"\n    </{tag}>")
        return True

    for node, data in g.nodes(data=True):
        if not element("node", f'id="{_attr(str(node))}"', data, "node"):
            return None
    for u, v, data in g.edges(data=True):
        if not element("edge", f'source="{_attr(str(u))}" target="{_attr(str(v))}"', data, "edge"):
            return None
    key_lines = [f'\n  <key id="{key}" for="{scope}" attr.name="{_attr(name)}" attr.type="{xml_type}" />'
                 for (name, xml_type, scope), key in reversed(keys.items())]
    graph = ('\n  <graph edgedefault="undirected">' + "".join(out) + "\n  </graph>" if out
             else '\n  <graph edgedefault="undirected" />')
    return _HEAD + "".join(key_lines) + graph + "\n</graphml>\n"


def write_graphml(g: nx.Graph, path: Path | str) -> None:
    """Write ``g`` to ``path`` as ``nx.write_graphml(g, path)`` does, byte for byte (see the module docstring)."""
    text = graphml_text(g) if importlib.util.find_spec("lxml") is None else None
    if text is None:
        nx.write_graphml(g, str(path))
        return
    with open(path, "wb") as f:
        f.write(text.encode("utf-8", "xmlcharrefreplace"))
