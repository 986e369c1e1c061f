"""The SQL of the mesh catalogue: which meshes a database holds, by name, and their creation, renaming and copying.

This module owns every statement about the ``meshes`` table as a list of
named meshes — finding one by name, listing them, creating, renaming, and
the rows a copy takes from its source (`copy_rows`, which reads the source
as of a revision with `hestore.journal.as_of`) together with the copy's
first revision record. `hestore.store` calls it with the connection of a
`hestore.session.Session` scope, so each step is atomic; the session's own
rows of a mesh (its counters and lock, its revision) are
`hestore.persistence`'s.

A name taken between a check and an insert (another connection) is
`MeshExistsError`, never the driver's integrity error.
"""

from __future__ import annotations

from datetime import datetime, timezone
from typing import NamedTuple

import sqlalchemy as sa

from hestore import schema
from hestore.errors import MeshExistsError
from hestore.journal import as_of

__all__ = ["Entry", "names", "find", "row", "create", "rename", "copy_counters", "copy_rows", "add_revision"]

_M = schema.meshes


class Entry(NamedTuple):
    """A mesh of the catalogue: its id and policy."""

    id: int
    allow_loops: bool
    allow_multi_edges: bool


def names(conn: sa.Connection) -> list[str]:
    """The names of all meshes, sorted."""
    return list(conn.execute(sa.select(_M.c.name).order_by(_M.c.name)).scalars())


def find(conn: sa.Connection, name: str) -> Entry | None:
    """The mesh called ``name``, or None."""
    found = conn.execute(
        sa.select(_M.c.id, _M.c.allow_loops, _M.c.allow_multi_edges).where(_M.c.name == name)
    ).first()
    return None if found is None else Entry(found.id, bool(found.allow_loops), bool(found.allow_multi_edges))


def row(conn: sa.Connection, mesh_id: int) -> sa.Row:
    """The whole ``meshes`` row of mesh ``mesh_id`` (policy, history flag, revision, id counters)."""
    return conn.execute(sa.select(_M).where(_M.c.id == mesh_id)).one()


def create(conn: sa.Connection, name: str, allow_loops: bool, allow_multi_edges: bool, history: bool) -> int:
    """Insert an empty mesh at revision 0; return its id.

    Raises
    ------
    MeshExistsError
        A mesh has that name (also one another connection took a moment ago).
    """
    if find(conn, name) is not None:
        raise MeshExistsError(f"a mesh named {name!r} already exists")
    try:
        return conn.execute(
            _M.insert()
            .values(
                name=name, allow_loops=allow_loops, allow_multi_edges=allow_multi_edges, revision=0,
                next_vertex=0, next_edge=0, next_polygon=0, next_property=0, history=history,
            )
            .returning(_M.c.id)
        ).scalar_one()
    except sa.exc.IntegrityError:
        # Another connection took the name between the check and the insert.
        raise MeshExistsError(f"a mesh named {name!r} already exists") from None


def rename(conn: sa.Connection, mesh_id: int, new_name: str) -> None:
    """Give mesh ``mesh_id`` the name ``new_name`` (`MeshExistsError` if another mesh has it)."""
    if find(conn, new_name) is not None:
        raise MeshExistsError(f"a mesh named {new_name!r} already exists")
    try:
        conn.execute(_M.update().where(_M.c.id == mesh_id).values(name=new_name))
    except sa.exc.IntegrityError:
        raise MeshExistsError(f"a mesh named {new_name!r} already exists") from None


def copy_counters(conn: sa.Connection, target_id: int, source: sa.Row) -> None:
    """Make mesh ``target_id`` a copy's revision 1 with the id counters of ``source`` (a `row`).

    So no id the source ever handed out is handed out by the copy.
    """
    conn.execute(
        _M.update()
        .where(_M.c.id == target_id)
        .values(
            revision=1, next_vertex=source.next_vertex, next_edge=source.next_edge,
            next_polygon=source.next_polygon, next_property=source.next_property,
        )
    )


def copy_rows(conn: sa.Connection, source_id: int, revision: int | None, target_id: int, table: sa.Table) -> None:
    """Copy the rows of ``table`` from one mesh (as of ``revision``, or current) to another, as its revision 1.

    One ``INSERT ... SELECT``; the copy starts without history.
    """
    cols = [c for c in table.c if c.name not in ("mesh_id", "rev")]
    rows = sa.select(sa.literal(target_id, sa.Integer), *cols, sa.literal(1, sa.BigInteger)).where(
        table.c.mesh_id == source_id
    )
    if revision is not None:
        rows = as_of(rows, sa.literal(revision))
    conn.execute(table.insert().from_select([table.c.mesh_id, *cols, table.c.rev], rows))


def add_revision(conn: sa.Connection, mesh_id: int, number: int, message: str | None, changes: str | None) -> None:
    """Record revision ``number`` of a mesh written outside its unit of work (a copy), with its changes."""
    conn.execute(
        schema.revisions.insert().values(
            mesh_id=mesh_id, number=number, committed_at=datetime.now(timezone.utc), message=message, changes=changes,
        )
    )
