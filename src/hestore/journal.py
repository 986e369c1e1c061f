"""The SQL of history: reading a mesh as it was, and the row versions between revisions.

This module owns the statements over the history tables of
`hestore.schema` (SPEC §4.1) that are not part of writing a flush (those are
`hestore.persistence`'s): turning any read statement into the same read of
an earlier revision (`as_of`), listing kept revisions, fetching the row
versions that changed between two revisions, and the set-based statements
that make the current rows equal to an earlier revision's (`restore`). It
is used by `hestore.session` only.

A row version belongs to revision ``r`` when ``rev <= r < rev_to``: current
rows have no ``rev_to``, history rows have one, and a history row with
``rev`` NULL records that its key did not exist before ``rev_to``.
"""

from __future__ import annotations

import json
from typing import Any

import sqlalchemy as sa
from sqlalchemy.dialects.postgresql import insert as postgresql_insert
from sqlalchemy.dialects.sqlite import insert as sqlite_insert
from sqlalchemy.sql.util import find_tables
from sqlalchemy.sql.visitors import replacement_traverse

from hestore import schema

__all__ = [
    "to_history", "as_of", "request_as_of", "touched", "created", "rows_at", "restore_statements", "created_changes",
    "COUNTED", "restored",
]

#: The element kinds of SPEC §4.1's ``changes``.
KINDS = ("vertex", "halfedge", "edge", "polygon")


def created_changes(vertices: int, halfedges: int, edges: int, polygons: int) -> str:
    """The ``changes`` JSON of a revision that only created elements (an import, a copy).

    Examples
    --------
    >>> created_changes(3, 6, 3, 1)[:46]
    '{"vertex": {"created": 3, "removed": 0, "chang'
    """
    counts = dict(zip(KINDS, (vertices, halfedges, edges, polygons)))
    return json.dumps({k: {"created": int(n), "removed": 0, "changed": 0} for k, n in counts.items()})


def to_history(table: sa.Table, what: str, dialect: str, *where) -> sa.Insert:
    """Record in ``table``'s history the rows ``where`` picks (with ``mesh_id = :m``), for revision ``:r``.

    ``what="old"``: each row an earlier revision wrote (``rev < :r``) is
    copied as it is, before the statement that changes or deletes it.
    ``what="new"``: each row this revision wrote (``rev = :r``) that has no
    history row for it yet did not exist before: a row of its key alone
    (``rev`` NULL) records that, after the statement that inserted it.
    A key recorded for this revision already is left as it is (a batch may
    name a key twice).
    """
    history = schema.HISTORY[table.name]
    r = sa.bindparam("r", type_=sa.BigInteger())
    if what == "old":
        names = [c.name for c in table.columns]
        rows = sa.select(*table.columns, r).where(table.c.mesh_id == sa.bindparam("m"), table.c.rev < r, *where)
    else:
        key = [c for c in table.primary_key]
        names = [c.name for c in key]
        rows = sa.select(*key, r).where(table.c.mesh_id == sa.bindparam("m"), table.c.rev == r, *where)
    insert = postgresql_insert if dialect == "postgresql" else sqlite_insert
    return insert(history).from_select([*names, "rev_to"], rows).on_conflict_do_nothing()


def _versions_at(source: sa.FromClause, revision: Any, mesh: Any = None) -> sa.Subquery:
    """The rows of a versioned table (or an alias of one) as they were at ``revision``, same columns.

    With ``mesh``, both halves are narrowed to that mesh inside the union: a database cannot always
    push the outer condition in (SQLite never does for the right side of an outer join).
    """
    table = source if isinstance(source, sa.Table) else source.element
    history = schema.HISTORY[table.name].alias(f"{source.name}_h")
    mine = () if mesh is None else (source.c.mesh_id == mesh,)
    theirs = () if mesh is None else (history.c.mesh_id == mesh,)
    current = sa.select(*source.c).where(source.c.rev <= revision, *mine)
    old = sa.select(*(history.c[c.name] for c in source.c)).where(
        history.c.rev <= revision, history.c.rev_to > revision, *theirs
    )
    return sa.union_all(current, old).subquery(f"{source.name}_at")


def as_of(statement, revision: Any, mesh: Any = None):
    """``statement`` reading every versioned table as it was at ``revision`` (a bind parameter or a literal).

    ``mesh`` (the mesh's id, or its bind parameter) narrows every table read to that mesh.

    Each versioned table or alias of one the statement reads from is
    replaced by the union of its current rows written by ``revision`` at
    the latest and its history rows that were current then; a condition on
    the mesh or the key reaches both halves, so a point read stays two index
    probes and the cost of a view grows with what changed since, not with
    the mesh.

    Examples
    --------
    >>> e = schema.edges
    >>> sql = str(as_of(sa.select(e.c.id).where(e.c.mesh_id == 1), 4))
    >>> "edges_history" in sql and "rev_to" in sql
    True
    """
    subs: dict[int, sa.Subquery] = {}
    for source in find_tables(statement, include_aliases=True):
        table = source if isinstance(source, sa.Table) else getattr(source, "element", None)
        versioned = isinstance(table, sa.Table) and table.name in schema.HISTORY
        if versioned and schema.metadata.tables.get(table.name) is table:
            subs[id(source)] = _versions_at(source, revision, mesh)
    if not subs:
        return statement

    def replace(element):
        sub = subs.get(id(element))
        if sub is not None:
            return sub
        owner = getattr(element, "table", None)
        if isinstance(element, sa.ColumnClause) and owner is not None and id(owner) in subs:
            return subs[id(owner)].c[element.name]
        return None

    return replacement_traverse(statement, {}, replace)


def request_as_of(request: tuple, revision: int) -> tuple:
    """A `hestore.columns.read_columns` request reading its table as it was at ``revision``.

    Examples
    --------
    >>> v = schema.vertices
    >>> source, cols = request_as_of((v, [v.c.id, v.c.x]), 3)
    >>> source.name, [c.name for c in cols]
    ('vertices_at', ['id', 'x'])
    """
    table, cols, *where = request
    source = _versions_at(table, sa.literal(revision))

    def replace(element):
        if isinstance(element, sa.ColumnClause) and getattr(element, "table", None) is table:
            return source.c[element.name]
        return None

    def moved(expr):
        return replacement_traverse(expr, {}, replace)

    return (source, [moved(c) for c in cols], *([[moved(w) for w in where[0]]] if where else []))


def touched(table: sa.Table, after: Any, until: Any) -> sa.Select:
    """The keys of ``table`` whose row changed in a revision in ``(after, until]``: ``SELECT DISTINCT key``.

    Read from the history twin's ``(mesh_id, rev_to)`` index: its size is
    the number of changes, whatever the size of the mesh.
    """
    history = schema.HISTORY[table.name]
    key = [history.c[c.name] for c in table.primary_key if c.name != "mesh_id"]
    return (
        sa.select(*key)
        .where(history.c.mesh_id == sa.bindparam("m"), history.c.rev_to > after, history.c.rev_to <= until)
        .distinct()
    )


#: The tables whose new rows take ids from a counter of ``meshes`` (and ``revisions``): that counter, and
#: how many ids each of its steps gives (an edge's two half-edges).
COUNTED = {"vertices": ("next_vertex", 1), "halfedges": ("next_edge", 2), "edges": ("next_edge", 1),
           "polygons": ("next_polygon", 1), "properties": ("next_property", 1)}


def created(table: sa.Table, start: dict, end: dict):
    """The condition "``table``'s row was created between two points", from the id counters at both.

    Ids are handed out in order and never reused, so what a run of
    revisions created is a range of ids: no history row is needed for it.
    None for a table whose rows have no counter (property values).
    """
    if table.name not in COUNTED:
        return None
    name, step = COUNTED[table.name]
    return (table.c.id >= step * start[name]) & (table.c.id < step * end[name])


def rows_at(table: sa.Table, revision: Any, keys: sa.Select | None = None, new=None) -> sa.Select:
    """The rows of ``table`` at ``revision`` (without ``mesh_id`` and ``rev``): all, or those with ``keys``.

    ``new``: a condition that picks more rows (`created`'s).
    """
    cols = [c for c in table.c if c.name not in ("mesh_id", "rev")]
    stmt = sa.select(*cols).where(table.c.mesh_id == sa.bindparam("m"))
    if keys is not None:
        key = [c for c in table.primary_key if c.name != "mesh_id"]
        picked = sa.tuple_(*key).in_(keys)
        stmt = stmt.where(picked if new is None else sa.or_(picked, new))
    return as_of(stmt, revision)


def restore_statements(table: sa.Table, target: int, revision: int, since: dict) -> list:
    """The statements that make ``table``'s current rows of a mesh (``:m``) equal to its rows at ``target``.

    Run as ``revision`` (a new revision): the keys changed after
    ``target`` are moved to history as they are, deleted, and their
    versions valid at ``target`` are written back with ``rev = revision``;
    keys that did not exist then stay deleted, and keys that come back get
    their "did not exist" record for this revision. Set-based: one statement
    each, over the history twin's index; nothing is read into Python.
    ``since`` holds the id counters when revision ``target + 1`` began:
    rows with ids from there on were created after ``target``.
    """
    history = schema.HISTORY[table.name]
    key = [c for c in table.primary_key if c.name != "mesh_id"]
    m = sa.bindparam("m")
    if target == 0:
        changed = sa.true()  # revision 0 is empty: everything goes
    else:
        keys = sa.select(*(history.c[c.name] for c in key)).where(history.c.mesh_id == m, history.c.rev_to > target)
        changed = sa.tuple_(*key).in_(keys)
        if table.name in COUNTED:
            name, step = COUNTED[table.name]
            changed = sa.or_(changed, table.c.id >= step * since[name])
    names = [c.name for c in table.columns]
    copy_old = history.insert().from_select(
        [*names, "rev_to"],
        sa.select(*table.columns, sa.literal(revision, sa.BigInteger)).where(
            table.c.mesh_id == m, table.c.rev < revision, changed
        ),
    )
    delete = table.delete().where(table.c.mesh_id == m, changed)
    statements = [copy_old, delete]
    if target > 0:
        values = [history.c[n] for n in names if n != "rev"]
        back = sa.select(*values, sa.literal(revision, sa.BigInteger)).where(
            history.c.mesh_id == m, history.c.rev <= target, history.c.rev_to > target, history.c.rev_to < revision
        )
        statements.append(table.insert().from_select([n for n in names if n != "rev"] + ["rev"], back))
    return statements


def restored(table: sa.Table, target: int, revision: int):
    """The condition "this row of ``table`` came back from history in `restore_statements`" (by key, indexed)."""
    history = schema.HISTORY[table.name]
    key = [c for c in table.primary_key if c.name != "mesh_id"]
    back = sa.select(*(history.c[c.name] for c in key)).where(
        history.c.mesh_id == sa.bindparam("m"), history.c.rev <= target, history.c.rev_to > target,
        history.c.rev_to < revision,
    )
    return sa.tuple_(*key).in_(back)
