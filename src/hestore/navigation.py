"""Navigation: reading the stored structure through handles.

Free functions for every name of SPEC §3's navigation table and for the
circulators. Each answers with as few queries as it can: a half-edge's
references together with its target in one query, a vertex's whole star or a
polygon's whole ring in one query, ordered in Python afterwards.

Rotation order is counter-clockwise, ``onext(h) = twin(prev(h))``, starting at
the element's own ``halfedge``. Everything reads what the current connection
sees: committed data, plus the open transaction's own edits.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import sqlalchemy as sa

from hestore import handles, schema
from hestore.errors import ElementNotFoundError, InvariantViolationError
from hestore.statements import indexed_by
from hestore.validation import Violation

if TYPE_CHECKING:  # pragma: no cover
    from hestore.handles import Edge, HalfEdge, Polygon, Vertex
    from hestore.mesh import Mesh

# `hestore.handles` imports this module; its classes are looked up at call time.

__all__ = [
    "halfedge_record",
    "next_halfedge",
    "prev_halfedge",
    "twin",
    "origin",
    "target",
    "polygon",
    "edge",
    "is_boundary_halfedge",
    "onext",
    "oprev",
    "dnext",
    "dprev",
    "rnext",
    "rprev",
    "vector",
    "length",
    "vertex_halfedge",
    "position",
    "outgoing",
    "incoming",
    "neighbors",
    "vertex_edges",
    "vertex_polygons",
    "degree",
    "is_isolated",
    "is_boundary_vertex",
    "polygon_halfedges",
    "polygon_vertices",
    "polygon_edges",
    "polygon_neighbors",
    "polygon_degree",
    "edge_halfedges",
    "edge_vertices",
    "edge_polygons",
    "is_boundary_edge",
    "is_loop",
    "find_halfedge",
]

_H = schema.halfedges


def _rows(mesh: "Mesh", key: str, build, **values) -> list[tuple]:
    store = mesh._store
    stmt = store.statements.get(key, build)
    values["m"] = mesh._id
    return stmt.rows(store._cursor(), values)


def _missing(kind: str, mesh: "Mesh", i: int) -> ElementNotFoundError:
    return ElementNotFoundError(f"{kind} {i} does not exist in mesh {mesh.name!r} (removed, or never created)")


# -- half-edges ---------------------------------------------------------------


def _build_he():
    t = _H.alias("t")
    return (
        sa.select(_H.c.origin, _H.c.next, _H.c.prev, _H.c.twin, _H.c.edge, _H.c.polygon, t.c.origin)
        .select_from(_H.outerjoin(t, sa.and_(t.c.mesh_id == _H.c.mesh_id, t.c.id == _H.c.twin)))
        .where(_H.c.mesh_id == sa.bindparam("m"), _H.c.id == sa.bindparam("i"))
    )


def halfedge_record(h: "HalfEdge") -> tuple:
    """``(origin, next, prev, twin, edge, polygon, target)`` ids of ``h`` in one query."""
    rows = _rows(h.mesh, "nav_he", _build_he, i=h.id)
    if not rows:
        raise _missing("half-edge", h.mesh, h.id)
    return rows[0]


def _he(mesh: "Mesh", i: int) -> "HalfEdge":
    return handles.HalfEdge(mesh, i)


def next_halfedge(h: "HalfEdge") -> "HalfEdge":
    """The next half-edge around the left polygon (or boundary loop)."""
    return _he(h.mesh, halfedge_record(h)[1])


def prev_halfedge(h: "HalfEdge") -> "HalfEdge":
    """The previous half-edge around the left polygon (or boundary loop)."""
    return _he(h.mesh, halfedge_record(h)[2])


def twin(h: "HalfEdge") -> "HalfEdge":
    """The opposite half-edge of the same edge."""
    return _he(h.mesh, halfedge_record(h)[3])


def origin(h: "HalfEdge") -> "Vertex":
    """The vertex ``h`` starts at."""
    return handles.Vertex(h.mesh, halfedge_record(h)[0])


def target(h: "HalfEdge") -> "Vertex":
    """The vertex ``h`` ends at (the origin of its twin)."""
    return handles.Vertex(h.mesh, halfedge_record(h)[6])


def polygon(h: "HalfEdge") -> "Polygon | None":
    """The polygon to the left of ``h``; ``None`` if ``h`` is free."""
    p = halfedge_record(h)[5]
    return None if p is None else handles.Polygon(h.mesh, p)


def edge(h: "HalfEdge") -> "Edge":
    """The edge ``h`` is half of."""
    return handles.Edge(h.mesh, halfedge_record(h)[4])


def is_boundary_halfedge(h: "HalfEdge") -> bool:
    """Whether ``h`` is free (has no polygon)."""
    return halfedge_record(h)[5] is None


def onext(h: "HalfEdge") -> "HalfEdge":
    """``twin(prev(h))``: the next outgoing half-edge counter-clockwise around the origin."""
    return twin(prev_halfedge(h))


def oprev(h: "HalfEdge") -> "HalfEdge":
    """``next(twin(h))``: the next outgoing half-edge clockwise around the origin."""
    return next_halfedge(twin(h))


def dnext(h: "HalfEdge") -> "HalfEdge":
    """``prev(twin(h))``: around the destination."""
    return prev_halfedge(twin(h))


def dprev(h: "HalfEdge") -> "HalfEdge":
    """``twin(next(h))``: around the destination."""
    return twin(next_halfedge(h))


def rnext(h: "HalfEdge") -> "HalfEdge":
    """``twin(next(twin(h)))``: around the right polygon."""
    return twin(next_halfedge(twin(h)))


def rprev(h: "HalfEdge") -> "HalfEdge":
    """``twin(prev(twin(h)))``: around the right polygon."""
    return twin(prev_halfedge(twin(h)))


def vector(h: "HalfEdge") -> tuple[float, float, float] | None:
    """``position(target) - position(origin)``; ``None`` unless both ends have positions."""
    rec = halfedge_record(h)
    a = _vertex_row(h.mesh, rec[0])
    b = _vertex_row(h.mesh, rec[6])
    if a[1] is None or b[1] is None:
        return None
    return (b[1] - a[1], b[2] - a[2], b[3] - a[3])


def length(h: "HalfEdge") -> float | None:
    """Euclidean length of ``h``; ``None`` unless both ends have positions."""
    v = vector(h)
    return None if v is None else math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])


# -- vertices -----------------------------------------------------------------


def _build_v():
    v = schema.vertices
    return sa.select(v.c.halfedge, v.c.x, v.c.y, v.c.z).where(
        v.c.mesh_id == sa.bindparam("m"), v.c.id == sa.bindparam("i")
    )


def _vertex_row(mesh: "Mesh", i: int) -> tuple:
    rows = _rows(mesh, "nav_v", _build_v, i=i)
    if not rows:
        raise _missing("vertex", mesh, i)
    return rows[0]


def vertex_halfedge(v: "Vertex") -> "HalfEdge | None":
    """An outgoing half-edge of ``v`` (a free one if any); ``None`` if isolated."""
    h = _vertex_row(v.mesh, v.id)[0]
    return None if h is None else _he(v.mesh, h)


def position(v: "Vertex") -> tuple[float, float, float] | None:
    """``(x, y, z)`` of ``v``, or ``None`` if it has no position."""
    row = _vertex_row(v.mesh, v.id)
    return None if row[1] is None else (row[1], row[2], row[3])


def _build_star():
    v, t = schema.vertices, _H.alias("t")
    j = v.outerjoin(_H, sa.and_(_H.c.mesh_id == v.c.mesh_id, _H.c.origin == v.c.id)).outerjoin(
        t, sa.and_(t.c.mesh_id == _H.c.mesh_id, t.c.id == _H.c.twin)
    )
    stmt = (
        sa.select(v.c.halfedge, _H.c.id, _H.c.prev, _H.c.twin, _H.c.edge, _H.c.polygon, t.c.origin)
        .select_from(j)
        .where(v.c.mesh_id == sa.bindparam("m"), v.c.id == sa.bindparam("i"))
    )
    return indexed_by(stmt, _H, "ix_halfedges_origin")


def _star(v: "Vertex") -> list[tuple]:
    """Outgoing half-edges of ``v`` as ``(id, prev, twin, edge, polygon, target)``, CCW from ``v.halfedge``."""
    rows = _rows(v.mesh, "nav_star", _build_star, i=v.id)
    if not rows:
        raise _missing("vertex", v.mesh, v.id)
    start = rows[0][0]
    if start is None:
        return []
    by_id = {r[1]: r[1:] for r in rows}
    out_of_twin = {r[3]: r[1] for r in rows}
    ordered = []
    h = start
    for _ in range(len(rows)):
        rec = by_id.get(h)
        if rec is None:
            break
        ordered.append(rec)
        h = out_of_twin.get(rec[1])  # onext(h) = twin(prev(h))
        if h == start:
            return ordered
    raise InvariantViolationError(
        [Violation("V_ROTATION", "vertex", (v.id,), f"the rotation around vertex {v.id} does not close; run check()")]
    )


def outgoing(v: "Vertex") -> list["HalfEdge"]:
    """Half-edges leaving ``v``, counter-clockwise from ``v.halfedge``."""
    return [_he(v.mesh, r[0]) for r in _star(v)]


def incoming(v: "Vertex") -> list["HalfEdge"]:
    """Half-edges arriving at ``v``: the twins of `outgoing`, in the same order."""
    return [_he(v.mesh, r[2]) for r in _star(v)]


def neighbors(v: "Vertex") -> list["Vertex"]:
    """The target of each outgoing half-edge (repeats for parallel edges, ``v`` for a loop)."""
    return [handles.Vertex(v.mesh, r[5]) for r in _star(v)]


def vertex_edges(v: "Vertex") -> list["Edge"]:
    """The edge of each outgoing half-edge (a self-loop appears twice)."""
    return [handles.Edge(v.mesh, r[3]) for r in _star(v)]


def vertex_polygons(v: "Vertex") -> list["Polygon"]:
    """The polygon of each outgoing half-edge, skipping free gaps."""
    return [handles.Polygon(v.mesh, r[4]) for r in _star(v) if r[4] is not None]


def degree(v: "Vertex") -> int:
    """Number of outgoing half-edges (a self-loop counts twice, as in networkx)."""
    return len(_star(v))


def is_isolated(v: "Vertex") -> bool:
    """Whether no edge touches ``v``."""
    return _vertex_row(v.mesh, v.id)[0] is None


def _build_vfree():
    v = schema.vertices
    return (
        sa.select(v.c.halfedge, _H.c.polygon)
        .select_from(v.outerjoin(_H, sa.and_(_H.c.mesh_id == v.c.mesh_id, _H.c.id == v.c.halfedge)))
        .where(v.c.mesh_id == sa.bindparam("m"), v.c.id == sa.bindparam("i"))
    )


def is_boundary_vertex(v: "Vertex") -> bool:
    """Whether ``v`` has a free outgoing half-edge, or is isolated (as in OpenMesh).

    O(1): by the boundary convention ``v.halfedge`` is free if any is.
    """
    rows = _rows(v.mesh, "nav_vfree", _build_vfree, i=v.id)
    if not rows:
        raise _missing("vertex", v.mesh, v.id)
    return rows[0][0] is None or rows[0][1] is None


# -- polygons -----------------------------------------------------------------


def _build_ring():
    p, t = schema.polygons, _H.alias("t")
    j = p.outerjoin(_H, sa.and_(_H.c.mesh_id == p.c.mesh_id, _H.c.polygon == p.c.id)).outerjoin(
        t, sa.and_(t.c.mesh_id == _H.c.mesh_id, t.c.id == _H.c.twin)
    )
    stmt = (
        sa.select(p.c.halfedge, _H.c.id, _H.c.next, _H.c.origin, _H.c.edge, t.c.polygon)
        .select_from(j)
        .where(p.c.mesh_id == sa.bindparam("m"), p.c.id == sa.bindparam("i"))
    )
    return indexed_by(stmt, _H, "ix_halfedges_polygon")


def _ring(p: "Polygon") -> list[tuple]:
    """Half-edges of ``p`` as ``(id, next, origin, edge, twin_polygon)``, in ``next`` order."""
    rows = _rows(p.mesh, "nav_ring", _build_ring, i=p.id)
    if not rows:
        raise _missing("polygon", p.mesh, p.id)
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
        [Violation("P_LOOP", "polygon", (p.id,), f"the half-edges of polygon {p.id} do not close; run check()")]
    )


def polygon_halfedges(p: "Polygon") -> list["HalfEdge"]:
    """The half-edges of ``p`` in ``next`` order, from ``p.halfedge``."""
    return [_he(p.mesh, r[0]) for r in _ring(p)]


def polygon_vertices(p: "Polygon") -> list["Vertex"]:
    """The corners of ``p`` (origins of its half-edges), counter-clockwise."""
    return [handles.Vertex(p.mesh, r[2]) for r in _ring(p)]


def polygon_edges(p: "Polygon") -> list["Edge"]:
    """The edges of ``p``, in ``next`` order."""
    return [handles.Edge(p.mesh, r[3]) for r in _ring(p)]


def polygon_neighbors(p: "Polygon") -> list["Polygon"]:
    """The polygon across each edge of ``p``, free sides skipped (``p`` itself where it meets itself)."""
    return [handles.Polygon(p.mesh, r[4]) for r in _ring(p) if r[4] is not None]


def polygon_degree(p: "Polygon") -> int:
    """Number of half-edges of ``p``."""
    return len(_ring(p))


# -- edges --------------------------------------------------------------------


def _build_e():
    e, t = schema.edges, _H.alias("t")
    j = e.outerjoin(_H, sa.and_(_H.c.mesh_id == e.c.mesh_id, _H.c.id == e.c.halfedge)).outerjoin(
        t, sa.and_(t.c.mesh_id == _H.c.mesh_id, t.c.id == _H.c.twin)
    )
    return (
        sa.select(e.c.halfedge, _H.c.twin, _H.c.origin, t.c.origin, _H.c.polygon, t.c.polygon)
        .select_from(j)
        .where(e.c.mesh_id == sa.bindparam("m"), e.c.id == sa.bindparam("i"))
    )


def _edge_row(e: "Edge") -> tuple:
    """``(h, twin, origin(h), origin(twin), polygon(h), polygon(twin))``."""
    rows = _rows(e.mesh, "nav_e", _build_e, i=e.id)
    if not rows:
        raise _missing("edge", e.mesh, e.id)
    return rows[0]


def edge_halfedges(e: "Edge") -> tuple["HalfEdge", "HalfEdge"]:
    """``(e.halfedge, its twin)``."""
    row = _edge_row(e)
    return _he(e.mesh, row[0]), _he(e.mesh, row[1])


def edge_vertices(e: "Edge") -> tuple["Vertex", "Vertex"]:
    """``(origin, target)`` of ``e.halfedge``."""
    row = _edge_row(e)
    return handles.Vertex(e.mesh, row[2]), handles.Vertex(e.mesh, row[3])


def edge_polygons(e: "Edge") -> list["Polygon"]:
    """The polygons on the two sides of ``e``, free sides skipped."""
    row = _edge_row(e)
    return [handles.Polygon(e.mesh, p) for p in (row[4], row[5]) if p is not None]


def is_boundary_edge(e: "Edge") -> bool:
    """Whether at least one side of ``e`` is free (as OpenMesh's ``is_boundary``)."""
    row = _edge_row(e)
    return row[4] is None or row[5] is None


def is_loop(e: "Edge") -> bool:
    """Whether both ends of ``e`` are the same vertex."""
    row = _edge_row(e)
    return row[2] == row[3]


def edge_halfedge(e: "Edge") -> "HalfEdge":
    """The half-edge stored for ``e``."""
    return _he(e.mesh, _edge_row(e)[0])


def polygon_halfedge(p: "Polygon") -> "HalfEdge":
    """The half-edge stored for ``p``."""
    pol = schema.polygons
    rows = _rows(
        p.mesh,
        "nav_p",
        lambda: sa.select(pol.c.halfedge).where(pol.c.mesh_id == sa.bindparam("m"), pol.c.id == sa.bindparam("i")),
        i=p.id,
    )
    if not rows:
        raise _missing("polygon", p.mesh, p.id)
    return _he(p.mesh, rows[0][0])


# -- mesh level ---------------------------------------------------------------


def _build_find():
    t = _H.alias("t")
    stmt = (
        sa.select(_H.c.id)
        .select_from(_H.join(t, sa.and_(t.c.mesh_id == _H.c.mesh_id, t.c.id == _H.c.twin)))
        .where(_H.c.mesh_id == sa.bindparam("m"), _H.c.origin == sa.bindparam("a"), t.c.origin == sa.bindparam("b"))
        .order_by(sa.case((_H.c.polygon.is_(None), 0), else_=1), _H.c.id)
        .limit(1)
    )
    return indexed_by(stmt, _H, "ix_halfedges_origin")


def find_halfedge(a: "Vertex", b: "Vertex") -> "HalfEdge | None":
    """A half-edge from ``a`` to ``b``, a free one if any (lowest id); ``None`` if none."""
    _vertex_row(a.mesh, a.id)
    _vertex_row(b.mesh, b.id)
    rows = _rows(a.mesh, "nav_find", _build_find, a=a.id, b=b.id)
    return _he(a.mesh, rows[0][0]) if rows else None
