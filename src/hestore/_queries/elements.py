"""The statements of one element: its row and its neighbours' in one query, ids, counts (`hestore.navigation`'s).

Each is a point read of mesh ``:m`` compiled once and run through
`hestore._session.Session.fetch`, so it sees the open transaction's edits
and, rewritten by `hestore._journal.as_of`, a view's revision. A twin is
outer-joined on its whole key (`twin_of`): a view rewrites such a join into
two indexed joins, where an inner join would make it read the whole table.
The stars of vertices are `hestore._queries.stars`'.
"""

from __future__ import annotations

import sqlalchemy as sa

from hestore import schema
from hestore._queries import query
from hestore._statements import in_keys, indexed_by

__all__ = [
    "twin_of", "mesh", "exists", "halfedge", "vertex", "vertex_free", "ring", "polygon", "edge", "find_halfedge",
    "ids", "revision", "counts", "vertices",
]

_H = schema.halfedges


def twin_of(left: sa.FromClause = _H) -> tuple[sa.FromClause, sa.Join]:
    """The twins ``t`` of the half-edges, and ``left`` (the half-edges, or a join of them) outer-joined to them.

    On the twin's whole key: a view rewrites such a join into two indexed
    joins (`hestore._journal.as_of`), where an inner join would make it read
    the whole table.
    """
    t = _H.alias("t")
    return t, left.outerjoin(t, sa.and_(t.c.mesh_id == _H.c.mesh_id, t.c.id == _H.c.twin))


def _is(table: sa.Table, name: str = "i"):
    """``table``'s row of mesh ``:m`` with id ``:i``."""
    return sa.and_(table.c.mesh_id == sa.bindparam("m"), table.c.id == sa.bindparam(name))


@query("elements.mesh")
def mesh():
    """The mesh ``:m``'s id, if it is there."""
    m = schema.meshes
    return sa.select(m.c.id).where(m.c.id == sa.bindparam("m"))


@query("elements.exists")
def exists(table: sa.Table):
    """A row if element ``:i`` of ``table`` exists."""
    return sa.select(sa.literal_column("1")).where(_is(table))


@query("elements.halfedge")
def halfedge():
    """``(origin, next, prev, twin, edge, polygon, target)`` of half-edge ``:i``."""
    t, j = twin_of()
    return sa.select(_H.c.origin, _H.c.next, _H.c.prev, _H.c.twin, _H.c.edge, _H.c.polygon, t.c.origin).select_from(
        j
    ).where(_is(_H))


@query("elements.vertex")
def vertex():
    """``(halfedge, x, y, z)`` of vertex ``:i``."""
    v = schema.vertices
    return sa.select(v.c.halfedge, v.c.x, v.c.y, v.c.z).where(_is(v))


@query("elements.vertex_free")
def vertex_free():
    """``(halfedge, its polygon)`` of vertex ``:i``: whether it is a boundary vertex."""
    v = schema.vertices
    return (
        sa.select(v.c.halfedge, _H.c.polygon)
        .select_from(v.outerjoin(_H, sa.and_(_H.c.mesh_id == v.c.mesh_id, _H.c.id == v.c.halfedge)))
        .where(_is(v))
    )


@query("elements.ring")
def ring():
    """``(p.halfedge, id, next, origin, edge, twin's polygon)`` of each half-edge of polygon ``:i``."""
    p = schema.polygons
    # Joined on the parameters, not on p's columns: a view (`hestore._journal.as_of`) can then narrow the
    # half-edges before the join.
    own = p.outerjoin(_H, sa.and_(_H.c.mesh_id == sa.bindparam("m"), _H.c.polygon == sa.bindparam("i")))
    t, j = twin_of(own)
    stmt = sa.select(p.c.halfedge, _H.c.id, _H.c.next, _H.c.origin, _H.c.edge, t.c.polygon).select_from(j).where(_is(p))
    return indexed_by(stmt, _H, "ix_halfedges_polygon")


@query("elements.polygon")
def polygon():
    """The half-edge stored for polygon ``:i``."""
    p = schema.polygons
    return sa.select(p.c.halfedge).where(_is(p))


@query("elements.edge")
def edge():
    """``(h, twin, origin(h), origin(twin), polygon(h), polygon(twin))`` of edge ``:i``, ``h`` its half-edge."""
    e = schema.edges
    t, j = twin_of(e.outerjoin(_H, sa.and_(_H.c.mesh_id == e.c.mesh_id, _H.c.id == e.c.halfedge)))
    return (
        sa.select(e.c.halfedge, _H.c.twin, _H.c.origin, t.c.origin, _H.c.polygon, t.c.polygon)
        .select_from(j)
        .where(_is(e))
    )


@query("elements.find_halfedge")
def find_halfedge():
    """The half-edge from vertex ``:a`` to vertex ``:b``, a free one first, then the lowest id."""
    t = _H.alias("t")
    stmt = (
        sa.select(_H.c.id)
        .select_from(_H.join(t, sa.and_(t.c.mesh_id == _H.c.mesh_id, t.c.id == _H.c.twin)))
        .where(_H.c.mesh_id == sa.bindparam("m"), _H.c.origin == sa.bindparam("a"), t.c.origin == sa.bindparam("b"))
        .order_by(sa.case((_H.c.polygon.is_(None), 0), else_=1), _H.c.id)
        .limit(1)
    )
    return indexed_by(stmt, _H, "ix_halfedges_origin")


@query("elements.ids")
def ids(table: sa.Table):
    """The ids of every row of ``table`` of mesh ``:m``, ascending."""
    return sa.select(table.c.id).where(table.c.mesh_id == sa.bindparam("m")).order_by(table.c.id)


@query("elements.revision")
def revision():
    """Mesh ``:m``'s revision."""
    m = schema.meshes
    return sa.select(m.c.revision).where(m.c.id == sa.bindparam("m"))


@query("elements.counts")
def counts():
    """``(mesh id or None, vertices, half-edges, edges, polygons)`` of mesh ``:m``, in one statement."""

    def count(t: sa.Table):
        return sa.select(sa.func.count()).select_from(t).where(t.c.mesh_id == sa.bindparam("m")).scalar_subquery()

    m = schema.meshes
    return sa.select(
        sa.select(m.c.id).where(m.c.id == sa.bindparam("m")).scalar_subquery(),
        count(schema.vertices),
        count(schema.halfedges),
        count(schema.edges),
        count(schema.polygons),
    )


@query("elements.vertices")
def vertices(size: int):
    """``(id, x, y, z)`` of the vertices ``:i0 … :i{size-1}`` that exist."""
    v = schema.vertices
    return sa.select(v.c.id, v.c.x, v.c.y, v.c.z).where(v.c.mesh_id == sa.bindparam("m"), v.c.id.in_(in_keys(size)))
