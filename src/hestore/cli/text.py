"""How the ``hestore`` command writes what it found: counts, numbers, revisions' changes, ``info``, paths, errors.

This module owns the text of the command line's results and of its
one-line errors. The handlers of `hestore.cli.commands` call the library,
then hand what it returned to a function here, which returns the lines to
print (or, for `error`, prints the line on stderr). Nothing here reads the
store: every value comes from the library through a handler.
"""

from __future__ import annotations

import sys

from hestore.history import KINDS as ELEMENT_KINDS
from hestore._values import KINDS as PROPERTY_KINDS

__all__ = [
    "INFO_LABELS", "TOP_COMPONENTS", "error", "count", "number", "changes", "revision_line", "diff_lines", "info",
    "info_lines",
    "property_rows", "json_default", "component_lines", "path_lines",
]

#: How many components ``graph NAME components`` lists, the largest first.
TOP_COMPONENTS = 10

#: How ``info`` labels each key of `info` in its text form (unlisted keys show as they are), in the order it
#: shows them.
INFO_LABELS = {
    "name": "name",
    "revision": "revision",
    "allow_loops": "self-loops allowed",
    "allow_multi_edges": "parallel edges allowed",
    "vertices": "vertices",
    "isolated_vertices": "isolated vertices",
    "edges": "edges",
    "loops": "self-loops",
    "parallel_edges": "parallel edges",
    "halfedges": "half-edges",
    "polygons": "polygons",
    "polygon_sizes": "polygon sizes",
    "boundary_edges": "boundary edges",
    "wire_edges": "wire edges",
    "boundary_loops": "boundary loops",
    "components": "components",
    "euler_characteristic": "Euler characteristic",
    "genus": "genus",
    "pinched_vertices": "pinched vertices",
    "is_closed": "closed",
    "is_manifold": "manifold",
}


def error(message: object) -> int:
    """Print ``hestore: error: …`` on stderr, one line whatever the message, and return exit status 2.

    Examples
    --------
    >>> import contextlib, io
    >>> with contextlib.redirect_stderr(io.StringIO()) as err:
    ...     status = error("no mesh named 'x'\\nmore detail")
    >>> status, err.getvalue()
    (2, "hestore: error: no mesh named 'x'\\n")
    """
    # One line, whatever the message: the rest goes to the logs, not the user.
    line = str(message).strip().splitlines()[0] if str(message).strip() else "unknown error"
    print(f"hestore: error: {line}", file=sys.stderr)
    return 2


def count(n: int, singular: str, plural: str | None = None) -> str:
    """``1 vertex``, ``2 vertices``.

    Examples
    --------
    >>> count(1, "vertex", "vertices"), count(2, "vertex", "vertices"), count(0, "edge")
    ('1 vertex', '2 vertices', '0 edges')
    """
    return f"{n} {singular if n == 1 else (plural or singular + 's')}"


def number(x: float | int) -> str:
    """An int as it is, a float to 12 significant digits.

    Examples
    --------
    >>> number(3), number(15.000000000000002), number(2 ** 0.5)
    ('3', '15', '1.41421356237')
    """
    return str(x) if isinstance(x, int) else f"{x:.12g}"


def changes(changes: dict) -> str:
    """``+3 −1 ~2 vertex, …``: how many of each kind were created (+), removed (−) and changed (~).

    Examples
    --------
    >>> none = {"created": 0, "removed": 0, "changed": 0}
    >>> changes({"vertex": {**none, "created": 2}, "halfedge": none, "edge": {**none, "changed": 1}, "polygon": none})
    '+2 vertex, ~1 edge'
    """
    parts = []
    for kind in ELEMENT_KINDS:
        c = changes[kind]
        marks = [f"{sign}{c[key]}" for sign, key in (("+", "created"), ("−", "removed"), ("~", "changed")) if c[key]]
        if marks:
            parts.append(f"{' '.join(marks)} {kind}")
    return ", ".join(parts) or "no change"


def revision_line(r) -> str:
    """One line of ``log``: a revision's number, time, changes (`changes`) and message.

    Examples
    --------
    >>> import datetime, hestore
    >>> none = {"created": 0, "removed": 0, "changed": 0}
    >>> when = datetime.datetime(2026, 11, 24, 3, 1, 6)
    >>> r = hestore.Revision(3, when, "flip", {kind: {**none, "changed": 1} for kind in ELEMENT_KINDS})
    >>> revision_line(r)
    '     3  2026-11-24 03:01:06 UTC  ~1 vertex, ~1 halfedge, ~1 edge, ~1 polygon  flip'
    """
    when = r.committed_at.strftime("%Y-%m-%d %H:%M:%S UTC")
    message = f"  {r.message}" if r.message else ""
    return f"{r.number:>6}  {when}  {changes(r.changes)}{message}"


def diff_lines(name: str, a: int, b: int, diff) -> list[str]:
    """``diff``: what changed from revision ``a`` to ``b`` (`changes`), then up to 20 ids a line.

    Examples
    --------
    >>> import hestore
    >>> store = hestore.open("sqlite://")
    >>> mesh = store.import_arrays("t", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [[0, 1, 2]]).mesh
    >>> _ = mesh.add_vertex()
    >>> diff_lines("t", 1, 2, mesh.diff(1, 2))
    ['t: revision 1 → 2: +1 vertex', '  created vertex 3']
    """
    lines = [f"{name}: revision {a} → {b}: {changes(diff.counts())}"]
    for what, ids in (("created", diff.created), ("removed", diff.removed), ("changed", diff.changed)):
        for kind in ELEMENT_KINDS:
            if ids[kind]:
                shown = ", ".join(map(str, ids[kind][:20])) + (", ..." if len(ids[kind]) > 20 else "")
                lines.append(f"  {what} {kind} {shown}")
    return lines


def info(mesh, stats) -> dict:
    """What ``info`` shows, as JSON-ready values; the text form is rendered from it (`info_lines`).

    The mesh's name, revision and policy, then every field of ``stats``
    (`hestore.Mesh.stats`, `hestore.summary.Stats.as_dict`), in the order of
    `INFO_LABELS`. Keys are the Python API's names, so a new field of
    ``Stats`` is one more key here without a change, and one more label in
    `INFO_LABELS`.

    Examples
    --------
    >>> import hestore
    >>> mesh = hestore.open("sqlite://").import_arrays("t", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [[0, 1, 2]]).mesh
    >>> shown = info(mesh, mesh.stats())
    >>> list(shown)[:3], shown["polygons"], shown["genus"]
    (['name', 'revision', 'allow_loops'], 1, 0)
    """
    shown = {
        "name": mesh.name,
        "revision": mesh.revision,
        "allow_loops": mesh.allow_loops,
        "allow_multi_edges": mesh.allow_multi_edges,
    }
    for key, value in stats.as_dict().items():
        shown.setdefault(key, value)
    # The labelled keys in their order, then any the labels do not know yet.
    order = {key: i for i, key in enumerate(INFO_LABELS)}
    return dict(sorted(shown.items(), key=lambda kv: order.get(kv[0], len(order))))


def _info_value(key: str, value: object, info: dict) -> str:
    if isinstance(value, bool):
        return "yes" if value else "no"
    if key == "genus" and value is None:
        # The genus is undefined where the surface is not one: say why.
        why = [what for what, field in (("wire edges", "wire_edges"), ("pinched vertices", "pinched_vertices"))
               if info.get(field)]
        return f"- ({' and '.join(why)})" if why else "-"
    if value is None:
        return "-"
    if isinstance(value, dict):
        return ", ".join(f"{k}: {v}" for k, v in value.items()) or "-"
    return str(value)


#: The verdicts of `info` that a mesh without vertices meets only vacuously: its text form says "empty" instead.
_VACUOUS = ("genus", "is_closed", "is_manifold")


def info_lines(info: dict, properties: list[dict]) -> list[str]:
    """The text form of ``info``: a labelled line per key of `info`, then the properties (`property_rows`).

    A mesh without vertices has every count 0, and `hestore.summary.Stats`
    calls it closed, manifold and of genus 0, as a statement about nothing
    is true; read as verdicts, that misleads. Its text form keeps the counts
    and ends with a line saying that the mesh is empty instead (the JSON
    form keeps the figures as they are).

    Examples
    --------
    >>> info_lines({"name": "t", "is_closed": False, "genus": None, "wire_edges": 1}, [])
    ['name:        t', 'closed:      no', 'genus:       - (wire edges)', 'wire edges:  1']
    >>> info_lines({"name": "e", "vertices": 0, "genus": 0, "is_closed": True, "is_manifold": True}, [])
    ['name:      e', 'vertices:  0', 'empty:     yes (no vertices: closed, manifold and genus do not apply)']
    """
    if info.get("vertices") == 0:
        info = {key: value for key, value in info.items() if key not in _VACUOUS}
        info["empty"] = "yes (no vertices: closed, manifold and genus do not apply)"
    labels = {key: INFO_LABELS.get(key, key) for key in info}
    width = max(len(label) for label in labels.values()) + 1
    lines = [f"{labels[key] + ':':<{width}}  {_info_value(key, value, info)}" for key, value in info.items()]
    if properties:
        lines.append(f"{'properties:':<{width}}  {len(properties)}")
        rows = [
            (
                p["kind"],
                p["name"],
                p["dtype"],
                str(tuple(p["shape"])),
                "no default" if p["default"] is None else f"default {p['default']!r}",
            )
            for p in properties
        ]
        widths = [max(len(row[c]) for row in rows) for c in range(4)]
        lines += ["  " + "  ".join([*(f"{cell:<{w}}" for cell, w in zip(row, widths)), row[4]]) for row in rows]
    return lines


def property_rows(mesh) -> list[dict]:
    """The mesh's properties (`hestore.Mesh.properties`), kind by kind, each in the order declared.

    Each as ``kind``, ``name``, ``dtype``, ``shape`` (a list: ``[]`` or
    ``[k]``) and ``default`` (None: no default; a list for shaped ones).

    Examples
    --------
    >>> import hestore
    >>> mesh = hestore.open("sqlite://").create_mesh("m")
    >>> _ = mesh.add_property("halfedge", "uv", "float64", shape=(2,))
    >>> property_rows(mesh)
    [{'kind': 'halfedge', 'name': 'uv', 'dtype': 'float64', 'shape': [2], 'default': None}]
    """
    return [
        {"kind": p.kind, "name": p.name, "dtype": p.dtype, "shape": list(p.shape), "default": p.default}
        for kind in PROPERTY_KINDS
        for p in mesh.properties(kind).values()
    ]


def json_default(value: object) -> object:
    """A property's default as JSON holds it: tuples as lists, NaN as null.

    Examples
    --------
    >>> json_default((1.0, float("nan"))), json_default("")
    ([1.0, None], '')
    """
    if isinstance(value, tuple):
        return [json_default(v) for v in value]
    if isinstance(value, float) and value != value:
        return None
    return value


def component_lines(components: list) -> list[str]:
    """``graph NAME components``: how many, of how many vertices, then the `TOP_COMPONENTS` largest.

    Each of those is its size and its lowest vertex id (a vertex to start
    from); equal sizes by lowest id.

    Examples
    --------
    >>> from types import SimpleNamespace as V
    >>> component_lines([[V(id=4)], [V(id=0), V(id=1)]])
    ['2 components of 3 vertices, the largest first:', '  2 vertices (lowest id 0)', '  1 vertex (lowest id 4)']
    """
    sizes = sorted(((len(c), min(v.id for v in c)) for c in components), key=lambda s: (-s[0], s[1]))
    vertices = sum(size for size, _ in sizes)
    head = f"{count(len(sizes), 'component')} of {count(vertices, 'vertex', 'vertices')}"
    lines = [head + (", the largest first:" if len(sizes) > 1 else ":" if sizes else "")]
    lines += [f"  {count(size, 'vertex', 'vertices')} (lowest id {lowest})" for size, lowest in sizes[:TOP_COMPONENTS]]
    rest = sizes[TOP_COMPONENTS:]
    if rest:
        lines.append(f"  ... and {len(rest)} more, of {count(rest[0][0], 'vertex', 'vertices')} or fewer each")
    return lines


def path_lines(ids: list[int], weight: str | None, total: float | int | None) -> list[str]:
    """``graph NAME path``: the vertex ids along the path, its number of edges and, weighted, its total.

    Examples
    --------
    >>> path_lines([0, 4, 3, 2], "cost", 3)
    ['path: 0 4 3 2', 'length: 3 edges', 'total cost: 3']
    """
    lines = ["path: " + " ".join(map(str, ids)), f"length: {count(len(ids) - 1, 'edge')}"]
    if weight is not None:
        lines.append(f"total {weight}: {number(total)}")
    return lines
