"""The statements of the catalogues: meshes by name (find, list, create, rename, copy) and each mesh's properties.

This module owns every statement about the ``meshes`` table as a list of
named meshes — finding one by name, listing them, creating, renaming, and
the rows a copy takes from its source (`copy_rows`, which reads the source
as of a revision with `hestore._journal.as_of`) together with the copy's
first revision record — and the reads of a mesh's catalogue of properties
(`properties_of`, `properties_of_kind`, `property_named`), which the unit of
work and `hestore.properties` share. `hestore.store` calls the functions
with the executor of a `hestore._session.Session` scope, so each step is
atomic; the session's own rows of a mesh (its counters and lock, its
revision) are `mesh_row` and `hestore._persistence`'s.

A name taken between a check and an insert (another connection) is
`MeshExistsError`, never the driver's integrity error.
"""

from __future__ import annotations

from typing import NamedTuple

import sqlalchemy as sa

from hestore import schema
from hestore._drivers import is_integrity_error
from hestore.errors import MeshExistsError
from hestore._journal import as_of
from hestore._queries import Executor, query
from hestore._queries import history
from hestore._values import catalogue_columns

__all__ = [
    "Entry", "MeshRow", "names", "find", "row", "create", "rename", "copy_counters", "copy_rows", "add_revision",
    "mesh_row", "properties_of", "properties_of_kind", "property_named",
]

_M = schema.meshes


class Entry(NamedTuple):
    """A mesh of the catalogue: its id and policy."""

    id: int
    allow_loops: bool
    allow_multi_edges: bool


class MeshRow(NamedTuple):
    """A mesh's ``meshes`` row: policy, history flag, revision and id counters."""

    id: int
    name: str
    allow_loops: bool
    allow_multi_edges: bool
    history: bool
    revision: int
    next_vertex: int
    next_edge: int
    next_polygon: int
    next_property: int


@query("catalogue.names")
def _names():
    return sa.select(_M.c.name).order_by(_M.c.name)


@query("catalogue.find")
def _find():
    return sa.select(_M.c.id, _M.c.allow_loops, _M.c.allow_multi_edges).where(_M.c.name == sa.bindparam("name"))


@query("catalogue.row")
def _row():
    return sa.select(*(_M.c[name] for name in MeshRow._fields)).where(_M.c.id == sa.bindparam("m"))


@query("catalogue.create")
def _create():
    return _M.insert().values(
        name=sa.bindparam("name"), allow_loops=sa.bindparam("loops"), allow_multi_edges=sa.bindparam("multi"),
        revision=0, next_vertex=0, next_edge=0, next_polygon=0, next_property=0, history=sa.bindparam("history"),
    ).returning(_M.c.id)


@query("catalogue.rename")
def _rename():
    return _M.update().where(_M.c.id == sa.bindparam("m")).values(name=sa.bindparam("name"))


@query("catalogue.copy_counters")
def _copy_counters():
    counters = ("next_vertex", "next_edge", "next_polygon", "next_property")
    return _M.update().where(_M.c.id == sa.bindparam("m")).values(revision=1, **{c: sa.bindparam(c) for c in counters})


@query("catalogue.copy_rows", prepare=False)
def _copy_rows(table: sa.Table, past: bool):
    cols = [c for c in table.c if c.name not in ("mesh_id", "rev")]
    rows = sa.select(sa.bindparam("target", type_=sa.Integer), *cols, sa.literal(1, sa.BigInteger)).where(
        table.c.mesh_id == sa.bindparam("source")
    )
    if past:
        rows = as_of(rows, sa.bindparam("asof", type_=sa.BigInteger))
    return table.insert().from_select([table.c.mesh_id, *cols, table.c.rev], rows)


def names(db: Executor) -> list[str]:
    """The names of all meshes, sorted."""
    return [name for (name,) in db.rows(_names)]


def find(db: Executor, name: str) -> Entry | None:
    """The mesh called ``name``, or None."""
    found = db.first(_find, {"name": name})
    return None if found is None else Entry(found[0], bool(found[1]), bool(found[2]))


def row(db: Executor, mesh_id: int) -> MeshRow:
    """The ``meshes`` row of mesh ``mesh_id`` (policy, history flag, revision, id counters)."""
    i, name, loops, multi, keep, *numbers = db.first(_row, {"m": mesh_id})
    return MeshRow(i, name, bool(loops), bool(multi), bool(keep), *numbers)


def create(db: Executor, name: str, allow_loops: bool, allow_multi_edges: bool, history: bool) -> int:
    """Insert an empty mesh at revision 0; return its id.

    Raises
    ------
    MeshExistsError
        A mesh has that name (also one another connection took a moment ago).
    """
    if find(db, name) is not None:
        raise MeshExistsError(f"a mesh named {name!r} already exists")
    try:
        values = {"name": name, "loops": allow_loops, "multi": allow_multi_edges, "history": history}
        return db.first(_create, values)[0]
    except Exception as exc:
        if is_integrity_error(exc):
            # Another connection took the name between the check and the insert.
            raise MeshExistsError(f"a mesh named {name!r} already exists") from None
        raise


def rename(db: Executor, mesh_id: int, new_name: str) -> None:
    """Give mesh ``mesh_id`` the name ``new_name`` (`MeshExistsError` if another mesh has it)."""
    if find(db, new_name) is not None:
        raise MeshExistsError(f"a mesh named {new_name!r} already exists")
    try:
        db.run(_rename, {"m": mesh_id, "name": new_name})
    except Exception as exc:
        if is_integrity_error(exc):
            raise MeshExistsError(f"a mesh named {new_name!r} already exists") from None
        raise


def copy_counters(db: Executor, target_id: int, source: MeshRow) -> None:
    """Make mesh ``target_id`` a copy's revision 1 with the id counters of ``source`` (a `row`).

    So no id the source ever handed out is handed out by the copy.
    """
    counters = {c: getattr(source, c) for c in ("next_vertex", "next_edge", "next_polygon", "next_property")}
    db.run(_copy_counters, {"m": target_id, **counters})


def copy_rows(db: Executor, source_id: int, revision: int | None, target_id: int, table: sa.Table) -> None:
    """Copy the rows of ``table`` from one mesh (as of ``revision``, or current) to another, as its revision 1.

    One ``INSERT ... SELECT``; the copy starts without history.
    """
    db.run(_copy_rows(table, revision is not None), {"source": source_id, "target": target_id, "asof": revision})


def add_revision(db: Executor, mesh_id: int, number: int, message: str | None, changes: str | None) -> None:
    """Record revision ``number`` of a mesh written outside its unit of work (a copy), with its changes."""
    db.run(history.add_revision, {
        "m": mesh_id, "n": number, "at": history.now(db.dialect.name == "sqlite"), "msg": message, "ch": changes,
        "sv": 0, "se": 0, "sp": 0, "sq": 0, "act": None, "tgt": None,
    })


@query("catalogue.mesh_row")
def mesh_row(lock: bool):
    """Mesh ``:m``'s counters, policy, whether it has properties, its revision and history flag.

    ``(next_vertex, next_edge, next_polygon, next_property, allow_loops,
    allow_multi_edges, has_properties, revision, history)``; with ``lock``
    the row is locked for the rest of the transaction (``SELECT ... FOR
    UPDATE``).
    """
    props = schema.properties
    has = sa.exists().where(props.c.mesh_id == _M.c.id)
    stmt = sa.select(
        _M.c.next_vertex, _M.c.next_edge, _M.c.next_polygon, _M.c.next_property,
        _M.c.allow_loops, _M.c.allow_multi_edges, has, _M.c.revision, _M.c.history,
    ).where(_M.c.id == sa.bindparam("m"))
    return stmt.with_for_update(of=_M) if lock else stmt


@query("catalogue.properties")
def properties_of():
    """Every property declared on mesh ``:m`` (`hestore._values.catalogue_columns`), in the order declared."""
    p = schema.properties
    return sa.select(*catalogue_columns()).where(p.c.mesh_id == sa.bindparam("m")).order_by(p.c.id)


@query("catalogue.properties_of_kind")
def properties_of_kind(kind: str):
    """The properties declared on ``kind`` in mesh ``:m``, in the order declared."""
    p = schema.properties
    return sa.select(*catalogue_columns()).where(p.c.mesh_id == sa.bindparam("m"), p.c.kind == kind).order_by(p.c.id)


@query("catalogue.property_named")
def property_named(kind: str, table: sa.Table):
    """The property ``:n`` of ``kind`` in mesh ``:m``, and whether element ``:i`` of ``table`` (that kind's) exists."""
    p = schema.properties
    exists = sa.exists().where(table.c.mesh_id == sa.bindparam("m"), table.c.id == sa.bindparam("i"))
    return sa.select(*catalogue_columns(), exists).where(
        p.c.mesh_id == sa.bindparam("m"), p.c.kind == kind, p.c.name == sa.bindparam("n")
    )
