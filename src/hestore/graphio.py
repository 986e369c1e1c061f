"""Graph files: writing the networkx views of a mesh to GraphML and edge lists.

This module owns `write_graph`, which turns one of the graphs of
`hestore.graphs.to_networkx` into a file other tools read: GraphML
(``.graphml``: nodes, edges with their keys, every attribute; None values
left out, tuples and lists as JSON text) or an edge list (``.edgelist``: a
line ``u v {attributes}`` per edge, a multigraph's key as the attribute
``key``). The views are frozen and cached, so the writers work on a plain
copy whose attribute values the format can hold; the view is never changed.

Examples
--------
>>> import hestore, tempfile, pathlib
>>> from hestore.graphio import write_graph
>>> mesh = hestore.open("sqlite://").import_arrays("t", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [[0, 1, 2]]).mesh
>>> path = pathlib.Path(tempfile.mkdtemp()) / "t.edgelist"
>>> write_graph(mesh.to_networkx(), path)
(3, 3)
>>> print(path.read_text().splitlines()[0])
0 1 {'key': 0, 'halfedges': (0, 1), 'polygons': (0, None)}
"""

from __future__ import annotations

import json
import os
from typing import Callable

import networkx as nx

from hestore.errors import InvalidInputError
from hestore.io import file_errors
from hestore.urls import check_path

__all__ = ["FORMATS", "format_of", "write_graph"]

#: The graph file formats `write_graph` writes, by extension.
FORMATS = {".graphml": "GraphML", ".edgelist": "edge list"}

#: Returned by a converter for an attribute that is left out.
_DROP = object()


def format_of(path: str | os.PathLike) -> str:
    """The extension of ``path`` if `write_graph` writes it, else `InvalidInputError`.

    Examples
    --------
    >>> format_of("g.GraphML")
    '.graphml'
    """
    path = check_path(path)
    suffix = os.path.splitext(path)[1].lower()
    if suffix not in FORMATS:
        what = repr(suffix) if suffix else "(no extension)"
        raise InvalidInputError(
            f"{path}: unsupported graph file format {what}; write .graphml (GraphML) or .edgelist (an edge list)"
        )
    return suffix


def _plain(value: object) -> object:
    """``value`` with numpy scalars (and containers of them) as Python ones."""
    if isinstance(value, dict):
        return {_plain(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return type(value)(_plain(v) for v in value)
    item = getattr(value, "item", None)
    if item is not None and not isinstance(value, (bool, int, float, str)):
        try:
            return item()
        except (TypeError, ValueError):
            return value
    return value


def _graphml_value(value: object) -> object:
    """A GraphML-writable attribute value: scalars as they are, None dropped, the rest as JSON text."""
    value = _plain(value)
    if value is None:
        return _DROP
    if isinstance(value, (bool, int, float, str)):
        return value
    return json.dumps(value)


def _writable_copy(graph: nx.Graph, convert: Callable[[object], object], *, key: str | None = None) -> nx.Graph:
    """A new, unfrozen graph of ``graph``'s type with every attribute value passed through ``convert``.

    With ``key``, a multigraph's edge keys are also written as that edge
    attribute (an edge list has no place for keys).
    """

    def attrs(data: dict) -> dict:
        out = {}
        for name, value in data.items():
            value = convert(value)
            if value is not _DROP:
                out[str(name)] = value
        return out

    copy = type(graph)()
    copy.graph.update(attrs(graph.graph))
    copy.add_nodes_from((n, attrs(d)) for n, d in graph.nodes(data=True))
    if graph.is_multigraph():
        copy.add_edges_from(
            (u, v, k, ({key: _plain(k)} if key else {}) | attrs(d)) for u, v, k, d in graph.edges(keys=True, data=True)
        )
    else:
        copy.add_edges_from((u, v, attrs(d)) for u, v, d in graph.edges(data=True))
    return copy


def write_graph(graph: nx.Graph, path: str | os.PathLike) -> tuple[int, int]:
    """Write ``graph`` to ``path``, GraphML or an edge list by its extension, replacing the file.

    Parameters
    ----------
    graph : networkx.Graph
        Any networkx graph; the views of `hestore.Mesh.to_networkx` (frozen)
        included. It is not changed.
    path : str or os.PathLike
        ``*.graphml`` or ``*.edgelist``.

    Returns
    -------
    (int, int)
        The nodes and edges written (an edge list has no isolated nodes).

    Raises
    ------
    InvalidInputError
        Another extension, a path that cannot be one, or a file that cannot
        be written (``"cannot write {path}: {reason}"``).
    """
    path = check_path(path)
    suffix = format_of(path)
    if suffix == ".graphml":
        copy = _writable_copy(graph, _graphml_value)
        with file_errors(path, "write"):
            nx.write_graphml(copy, path)
    else:
        copy = _writable_copy(graph, _plain, key="key")
        with file_errors(path, "write"):
            nx.write_edgelist(copy, path, data=True)
    return copy.number_of_nodes(), copy.number_of_edges()
