"""Navigation: reading the stored structure, one element at a time.

This module owns the queries behind every name of SPEC §3's navigation table
and behind the circulators. Its functions are free functions on a mesh's
identity (`hestore._session.MeshRef`) and integer ids, returning ids and id records; `hestore.handles` wraps them into
handles. Each answers with as few queries as it can: a half-edge's references
together with its target in one query, a vertex's whole star or a polygon's
whole ring in one query, ordered in Python afterwards. Every query is one of
`hestore._queries.elements` and `hestore._queries.stars`, run through
`hestore._session.Session.fetch`, so it sees the open transaction's own edits.

Rotation order is counter-clockwise, ``onext(h) = twin(prev(h))``, starting at
the element's own ``halfedge``.

An element that is not there raises `ElementNotFoundError`, or
`MeshNotFoundError` when the whole mesh is gone (`missing`).
"""

from __future__ import annotations

import math

from hestore import schema
from hestore.errors import ElementNotFoundError, InvariantViolationError, Violation
from hestore._queries import Query, elements, stars
from hestore._session import MeshRef

__all__ = [
    "missing",
    "exists",
    "halfedge_record",
    "vertex_row",
    "star",
    "ring",
    "edge_row",
    "polygon_halfedge",
    "is_boundary_vertex",
    "vector",
    "length",
    "find_halfedge",
    "ids",
]


def _rows(ref: MeshRef, query: Query, values: dict) -> list[tuple]:
    return ref.session.fetch(ref, query, values)


def missing(ref: MeshRef, kind: str, i: int) -> ElementNotFoundError:
    """The error for element ``i`` of ``kind`` not found: `MeshNotFoundError` if the mesh is gone."""
    if not _rows(ref, elements.mesh, {}):
        return ref.session.missing(ref)
    label = schema.KINDS[kind].label
    return ElementNotFoundError(f"{label} {i} does not exist in mesh {ref.name!r} (removed, or never created)")


# Looked up once per kind, so a point read pays no lookup of its query.
_EXISTS = {name: elements.exists(kind.table) for name, kind in schema.KINDS.items()}


def exists(ref: MeshRef, kind: str, i: int) -> None:
    """Raise unless element ``i`` of ``kind`` (a key of `hestore.schema.KINDS`) exists."""
    if not _rows(ref, _EXISTS[kind], {"i": i}):
        raise missing(ref, kind, i)


# -- half-edges ---------------------------------------------------------------


def halfedge_record(ref: MeshRef, h: int) -> tuple:
    """``(origin, next, prev, twin, edge, polygon, target)`` of half-edge ``h``, in one query."""
    rows = _rows(ref, elements.halfedge, {"i": h})
    if not rows:
        raise missing(ref, "halfedge", h)
    return rows[0]


def vector(ref: MeshRef, h: int) -> tuple[float, float, float] | None:
    """``position(target) - position(origin)`` of half-edge ``h``; ``None`` unless both ends have positions."""
    rec = halfedge_record(ref, h)
    a = vertex_row(ref, rec[0])
    b = vertex_row(ref, rec[6])
    if a[1] is None or b[1] is None:
        return None
    return (b[1] - a[1], b[2] - a[2], b[3] - a[3])


def length(ref: MeshRef, h: int) -> float | None:
    """Euclidean length of half-edge ``h``; ``None`` unless both ends have positions."""
    v = vector(ref, h)
    return None if v is None else math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])


# -- vertices -----------------------------------------------------------------


def vertex_row(ref: MeshRef, v: int) -> tuple:
    """``(halfedge, x, y, z)`` of vertex ``v`` (``halfedge`` None if isolated, coordinates None without a position)."""
    rows = _rows(ref, elements.vertex, {"i": v})
    if not rows:
        raise missing(ref, "vertex", v)
    return rows[0]


_STARS = {targets: stars.of_vertex(targets) for targets in (False, True)}

#: Fields of a `star` row: the half-edge, its prev and twin; then its edge and polygon, or (``targets``) its target.
STAR_ID, STAR_PREV, STAR_TWIN = 1, 2, 3
STAR_EDGE, STAR_POLYGON = 4, 5
STAR_TARGET = 4


def star(ref: MeshRef, v: int, *, targets: bool = False) -> list[tuple]:
    """Outgoing half-edges of vertex ``v``, counter-clockwise from ``v.halfedge``.

    Each row is ``(v.halfedge, id, prev, twin, edge, polygon)``, or with
    ``targets`` ``(v.halfedge, id, prev, twin, target)`` (the ``STAR_*``
    fields): only the neighbours need the twins' rows, so only they pay for
    reading them. One query for the whole star, ordered here: ``onext(h) =
    twin(prev(h))``, so the row after ``r`` is the one whose twin is ``r``'s
    prev.
    """
    rows = _rows(ref, _STARS[targets], {"i": v})
    if not rows:
        raise missing(ref, "vertex", v)
    start = rows[0][0]
    if start is None:
        return []
    after = {r[3]: r for r in rows}  # incoming half-edge -> the outgoing row it is the twin of
    for r in rows:
        if r[1] == start:
            ordered = [r]
            for _ in range(len(rows) - 1):
                r = after.get(r[2])
                if r is None or r[1] == start:
                    break
                ordered.append(r)
            else:
                # Every row visited once: the rotation must close back at the start.
                r = after.get(r[2])
                if r is not None and r[1] == start:
                    return ordered
            break
    raise InvariantViolationError(
        [Violation("V_ROTATION", "vertex", (v,), f"the rotation around vertex {v} does not close; run check()")]
    )


def is_boundary_vertex(ref: MeshRef, v: int) -> bool:
    """Whether vertex ``v`` has a free outgoing half-edge, or is isolated (as in OpenMesh).

    O(1): by the boundary convention ``v.halfedge`` is free if any is.
    """
    rows = _rows(ref, elements.vertex_free, {"i": v})
    if not rows:
        raise missing(ref, "vertex", v)
    return rows[0][0] is None or rows[0][1] is None


# -- polygons -----------------------------------------------------------------


def ring(ref: MeshRef, p: int) -> list[tuple]:
    """Half-edges of polygon ``p`` as ``(id, next, origin, edge, twin_polygon)``.

    In ``next`` order from ``p.halfedge``; one query for the whole ring.
    """
    rows = _rows(ref, elements.ring, {"i": p})
    if not rows:
        raise missing(ref, "polygon", p)
    start = rows[0][0]
    by_id = {r[1]: r[1:] for r in rows}
    ordered = []
    h = start
    for _ in range(len(rows)):
        rec = by_id.get(h)
        if rec is None:
            break
        ordered.append(rec)
        h = rec[1]
        if h == start:
            return ordered
    raise InvariantViolationError(
        [Violation("P_LOOP", "polygon", (p,), f"the half-edges of polygon {p} do not close; run check()")]
    )


def polygon_halfedge(ref: MeshRef, p: int) -> int:
    """The half-edge stored for polygon ``p``."""
    rows = _rows(ref, elements.polygon, {"i": p})
    if not rows:
        raise missing(ref, "polygon", p)
    return rows[0][0]


# -- edges --------------------------------------------------------------------


def edge_row(ref: MeshRef, e: int) -> tuple:
    """``(h, twin, origin(h), origin(twin), polygon(h), polygon(twin))`` of edge ``e``, ``h`` its half-edge."""
    rows = _rows(ref, elements.edge, {"i": e})
    if not rows:
        raise missing(ref, "edge", e)
    return rows[0]


# -- mesh level ---------------------------------------------------------------


def find_halfedge(ref: MeshRef, a: int, b: int) -> int | None:
    """A half-edge from vertex ``a`` to vertex ``b``, a free one if any (lowest id); ``None`` if none."""
    exists(ref, "vertex", a)
    exists(ref, "vertex", b)
    rows = _rows(ref, elements.find_halfedge, {"a": a, "b": b})
    return rows[0][0] if rows else None


def ids(ref: MeshRef, kind: str) -> list[int]:
    """Ids of every element of ``kind`` (a key of `hestore.schema.KINDS`), ascending."""
    found = [r[0] for r in _rows(ref, elements.ids(schema.KINDS[kind].table), {})]
    if not found and not _rows(ref, elements.mesh, {}):
        raise ref.session.missing(ref)
    return found
