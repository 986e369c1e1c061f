"""The statements of vertex stars: the outgoing half-edges of one vertex or of a batch, and the unit of work's loads.

A vertex's star is written once (`out_of`, read by the half-edges'
``ix_halfedges_origin`` index, `indexed`) and read four ways:

- `of_vertex`: one vertex's star with the vertex's own row (so an isolated
  vertex and a missing one are told apart), for `hestore.navigation`;
- `batch`, `placed` and `among`: the stars of up to `MAX_IN` vertices in
  one statement (an ``IN`` list compiled per power-of-two size), with each
  half-edge's target, its target's position, or its edge's row, for the
  searches and induced views of `hestore.traversal`;
- `load`: the rows a `hestore._unitofwork.UnitOfWork` loads in one
  ``UNION ALL`` — vertices with their stars and their half-edges' twins,
  half-edges, edges with both half-edges, polygons with their rings — for
  `hestore._persistence`.

The twin is outer-joined on its whole key (`hestore._queries.elements.twin_of`).
"""

from __future__ import annotations

from typing import Any

import sqlalchemy as sa

from hestore import schema
from hestore._queries import query
from hestore._queries.elements import twin_of
from hestore._statements import in_keys, indexed_by
from hestore._unitofwork import HE_COLUMNS, K_EDGE, K_HALFEDGE, K_POLYGON, K_VERTEX

__all__ = ["out_of", "indexed", "of_vertex", "batch", "placed", "among", "load"]

_H = schema.halfedges


def out_of(vertices: Any, h: sa.FromClause = _H) -> Any:
    """The condition "a half-edge ``h`` of mesh ``:m`` out of ``vertices``": one bind parameter or a list of them."""
    at = h.c.origin.in_(vertices) if isinstance(vertices, list) else h.c.origin == vertices
    return sa.and_(h.c.mesh_id == sa.bindparam("m"), at)


def indexed(stmt: Any, h: sa.FromClause = _H) -> Any:
    """``stmt`` reading the half-edges ``h`` by their origin's index (see `hestore._statements.indexed_by`)."""
    return indexed_by(stmt, h, "ix_halfedges_origin")


@query("stars.of_vertex")
def of_vertex(targets: bool):
    """``(v.halfedge, id, prev, twin, edge, polygon)`` of each half-edge out of vertex ``:i``; ``targets``: ``(…, twin,
    target)``.

    One row with NULLs for an isolated vertex, none for a missing one.
    """
    v = schema.vertices
    # Joined on the parameters, not on v's columns: a view (`hestore._journal.as_of`) can then narrow
    # the half-edges before the join.
    j = v.outerjoin(_H, out_of(sa.bindparam("i")))
    extra = [_H.c.edge, _H.c.polygon]
    if targets:
        t, j = twin_of(j)
        extra = [t.c.origin]
    stmt = (
        sa.select(v.c.halfedge, _H.c.id, _H.c.prev, _H.c.twin, *extra)
        .select_from(j)
        .where(v.c.mesh_id == sa.bindparam("m"), v.c.id == sa.bindparam("i"))
    )
    return indexed(stmt)


@query("stars.batch")
def batch(size: int):
    """``(origin, target, edge)`` of each half-edge out of the vertices ``:i0 … :i{size-1}``."""
    t, j = twin_of()
    return indexed(sa.select(_H.c.origin, t.c.origin, _H.c.edge).select_from(j).where(out_of(in_keys(size))))


@query("stars.placed")
def placed(size: int):
    """`batch`'s rows with their target's position: ``(origin, target, edge, x, y, z)``."""
    t, j = twin_of()
    w = schema.vertices.alias("w")
    j = j.outerjoin(w, sa.and_(w.c.mesh_id == _H.c.mesh_id, w.c.id == t.c.origin))
    stmt = sa.select(_H.c.origin, t.c.origin, _H.c.edge, w.c.x, w.c.y, w.c.z).select_from(j)
    return indexed(stmt.where(out_of(in_keys(size))))


@query("stars.among")
def among(size: int):
    """``(id, origin, twin, edge, polygon, target, edge's halfedge)`` of each half-edge out of ``:i0 …``."""
    t, j = twin_of()
    e = schema.edges
    j = j.outerjoin(e, sa.and_(e.c.mesh_id == _H.c.mesh_id, e.c.id == _H.c.edge))
    stmt = sa.select(_H.c.id, _H.c.origin, _H.c.twin, _H.c.edge, _H.c.polygon, t.c.origin, e.c.halfedge).select_from(j)
    return indexed(stmt.where(out_of(in_keys(size))))


@query("stars.load")
def load(sizes: tuple):
    """The ``UNION ALL`` behind `hestore._persistence.Persistence.load` for its parts' sizes.

    ``sizes`` is ``((part, size), …)``; each part's ids are ``:{part}0 …``.
    Each row is ``(kind, id, …)``: `K_VERTEX`, `K_EDGE` and `K_POLYGON`
    rows ``(id, halfedge)``, `K_HALFEDGE` rows ``(id, origin, next, prev,
    twin, edge, polygon)``, padded with NULLs.
    """
    h, v, e, p = schema.halfedges, schema.vertices, schema.edges, schema.polygons
    null = sa.cast(sa.null(), sa.BigInteger)
    m = sa.bindparam("m")

    def kind(k: int):
        return sa.literal_column(str(k), sa.Integer)

    def he_cols(t):
        return [kind(K_HALFEDGE)] + [t.c[name] for name in HE_COLUMNS]

    def pair_cols(k, t):
        return [kind(k), t.c.id, t.c.halfedge] + [null] * 5

    selects = []
    for name, size in sizes:
        ids = in_keys(size, name)
        if name == "vertices":
            selects.append(sa.select(*pair_cols(K_VERTEX, v)).where(v.c.mesh_id == m, v.c.id.in_(ids)))
        elif name == "halfedges":
            selects.append(sa.select(*he_cols(h)).where(h.c.mesh_id == m, h.c.id.in_(ids)))
        elif name == "stars":
            s, t = h.alias("s"), h.alias("t")
            selects.append(sa.select(*pair_cols(K_VERTEX, v)).where(v.c.mesh_id == m, v.c.id.in_(ids)))
            selects.append(indexed(sa.select(*he_cols(h)).where(out_of(ids))))
            twin = sa.and_(t.c.mesh_id == s.c.mesh_id, t.c.id == s.c.twin)
            twins = sa.select(*he_cols(t)).select_from(s.join(t, twin))
            selects.append(indexed(twins.where(out_of(ids, s)), s))
        elif name == "edges":
            a, b = h.alias("a"), h.alias("b")
            selects.append(sa.select(*pair_cols(K_EDGE, e)).where(e.c.mesh_id == m, e.c.id.in_(ids)))
            on_a = sa.and_(a.c.mesh_id == e.c.mesh_id, a.c.id == e.c.halfedge)
            selects.append(sa.select(*he_cols(a)).select_from(e.join(a, on_a)).where(e.c.mesh_id == m, e.c.id.in_(ids)))
            selects.append(
                sa.select(*he_cols(b))
                .select_from(e.join(a, on_a).join(b, sa.and_(b.c.mesh_id == a.c.mesh_id, b.c.id == a.c.twin)))
                .where(e.c.mesh_id == m, e.c.id.in_(ids))
            )
        elif name == "polygons":
            selects.append(sa.select(*pair_cols(K_POLYGON, p)).where(p.c.mesh_id == m, p.c.id.in_(ids)))
            ring = sa.select(*he_cols(h)).where(h.c.mesh_id == m, h.c.polygon.in_(ids))
            selects.append(indexed_by(ring, h, "ix_halfedges_polygon"))
        else:  # pragma: no cover - programming error
            raise ValueError(f"unknown load part {name!r}")
    return sa.union_all(*selects)
