"""The SQL of the unit of work: batched loads of a mesh's rows, set-based writes of its changes.

This module moves a `hestore._unitofwork.UnitOfWork`'s rows between the
database and memory (SQLAlchemy's ``persistence`` to the unit of work):
`Persistence.load` fetches stars, rings and rows by id in one ``UNION ALL``
(`hestore._queries.stars.load`), with the positions, property catalogue and
values the unit of work asks for (`hestore._queries`); `Persistence.write`
turns one `hestore._unitofwork.ChangeSet` into one statement per table and
kind of change — an ``executemany`` on SQLite, a single statement over
``unnest``-ed arrays on PostgreSQL, and the binary ``COPY`` / multi-row
``INSERT`` paths of `hestore._columns` for the whole tables of a bulk
import. It owns the write statements (registered queries ``uow.*``, and the
PostgreSQL ``unnest`` SQL). It also reads and locks a mesh's catalogue row
(`Persistence.mesh_row`). It is used by `hestore._session` only; it knows
nothing of transactions.
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np
import sqlalchemy as sa
from sqlalchemy.dialects.sqlite import insert as sqlite_insert
from sqlalchemy.schema import CreateTable

from hestore import schema
from hestore._columns import write_columns
from hestore._journal import created_changes, to_history
from hestore._queries import Executor, query
from hestore._queries import catalogue, elements, history, stars, values as value_rows
from hestore._statements import MAX_IN, in_chunks, in_keys, in_list_bucket, padded, padded_values
from hestore._unitofwork import HE_COLUMNS, UNSET, BulkValues, ChangeSet, PropertyChanges
from hestore._values import Property, dump_default, property_of, table_of

__all__ = ["Persistence"]


def _catalogue_row(p: Property) -> tuple:
    return (p.id, p.kind, p.name, p.dtype, p.size, dump_default(p.default))


def _value_columns(table: sa.Table) -> tuple:
    return ("property", "id", "part") + tuple(c.name for c in table.c if c.name.startswith("v"))


#: Rows from which a PostgreSQL write lets the planner see its arrays' length (see `_pg_arrays`).
_SIZED_ROWS = 100_000


def _pg_arrays(types, sized: bool) -> str:
    """The arguments of ``unnest`` for one array parameter of each of ``types``.

    ``%b``: psycopg sends the arrays in binary, without formatting every
    element as text. Each goes through a scalar subquery so that no plan
    knows its length: a planner that can count the elements finds every
    call's own plan cheaper than the generic one and plans each write again
    (about half the server's time for a small flush); this way, once psycopg
    has prepared the statement, PostgreSQL keeps one generic plan, an index
    probe per row. From `_SIZED_ROWS` rows (``sized``) a plan made for the
    size is worth its planning (a hash join beat the probes from about
    80,000 of a million rows, measured), so the planner sees the arrays.
    """
    return ", ".join(f"%b::{t}[]" if sized else f"(SELECT %b::{t}[])" for t in types)


def _pg_statement(table: sa.Table, what: str, cols: tuple, sized: bool) -> str:
    """PostgreSQL SQL writing many rows of ``table`` from one array per column (``sized``: see `_pg_arrays`)."""
    q = '"{}"'.format

    def sql_type(c: str) -> str:
        t = table.c[c].type
        return "double precision" if isinstance(t, sa.Float) else "text" if isinstance(t, sa.String) else "bigint"

    arrays = _pg_arrays((sql_type(c) for c in cols), sized)
    name = q(table.name)
    if what == "delete":
        match = " AND ".join(f"t.{q(c)} = u.{q(c)}" for c in cols)
        return (
            f"DELETE FROM {name} AS t USING unnest({arrays}) AS u({', '.join(q(c) for c in cols)}) "
            f"WHERE t.{q('mesh_id')} = %s AND {match}"
        )
    if what in ("insert", "upsert"):
        columns = ", ".join(q(c) for c in ("mesh_id",) + tuple(cols))
        sql = f"INSERT INTO {name} ({columns}) SELECT %s, * FROM unnest({arrays})"
        if what == "upsert":
            key = [c.name for c in table.primary_key]
            sets = ", ".join(f"{q(c)} = excluded.{q(c)}" for c in cols if c not in key)
            sql += f" ON CONFLICT ({', '.join(q(c) for c in key)}) DO UPDATE SET {sets}"
        return sql
    sets = ", ".join(f"{q(c)} = u.{q(c)}" for c in cols[1:])
    return (
        f"UPDATE {name} AS t SET {sets} FROM unnest({arrays}) AS u({', '.join(q(c) for c in cols)}) "
        f"WHERE t.{q('mesh_id')} = %s AND t.{q('id')} = u.{q('id')}"
    )


def _pg_to_history(table: sa.Table, what: str, key: tuple, sized: bool) -> str:
    """`hestore._journal.to_history` on PostgreSQL for the keys of ``unnest``-ed arrays, as a CTE of their write.

    Parameters: ``old`` takes the revision, the key arrays, the mesh and the
    revision again; ``new`` the revision, the mesh and the key arrays.
    ``sized``: see `_pg_arrays`.
    """
    q = '"{}"'.format
    history = schema.HISTORY[table.name]
    if what == "old":
        names, picked, cond = [c.name for c in table.columns], [f"t.{q(c.name)}" for c in table.columns], "<"
    else:
        names = [c.name for c in table.primary_key]
        picked, cond = [f"t.{q(c)}" for c in names], "="
    arrays = _pg_arrays(("bigint" for _ in key), sized)
    match = " AND ".join(f"t.{q(c)} = u.{q(c)}" for c in key)
    into = f"INSERT INTO {q(history.name)} ({', '.join(q(c) for c in names)}, {q('rev_to')}) "
    unnest = f"unnest({arrays}) AS u({', '.join(q(c) for c in key)})"
    if what == "new":
        # Keys with no row before the statement: it runs as a CTE of the insert, on the old snapshot.
        picked = ["p.m", *(f"u.{q(c)}" for c in names if c != "mesh_id")]
        return (
            f"{into}SELECT {', '.join(picked)}, p.r FROM (SELECT %s::bigint AS r, %s::bigint AS m) AS p, {unnest} "
            f"WHERE NOT EXISTS (SELECT 1 FROM {q(table.name)} AS t WHERE t.{q('mesh_id')} = p.m AND {match}) "
            "ON CONFLICT DO NOTHING"
        )
    sql = (
        f"{into}SELECT {', '.join(picked)}, %s FROM {q(table.name)} AS t "
        f"JOIN {unnest} ON {match} "
        f"WHERE t.{q('mesh_id')} = %s AND t.{q('rev')} {cond} %s"
    )
    return sql + " ON CONFLICT DO NOTHING"


_VALUE_TABLE_NAMES = frozenset(t.name for t in schema.VALUE_TABLES)


@functools.cache
def _in_names(size: int) -> tuple:
    """The revision, the mesh and an `in_keys` list of ``size``: the parameters of a journal statement, in order."""
    return ("r", "m", *(k.key for k in in_keys(size)))


#: Rows from which a PostgreSQL bulk update goes through a scratch table.
_STAGE_ROWS = 20_000

_VERTEX_INSERT = ("id", "halfedge", "x", "y", "z")
_POSITION = ("id", "x", "y", "z")
_CATALOGUE = ("id", "kind", "name", "dtype", "size", "default_value")
_VALUE_KEY = ("property", "id")
_PAIR = ("id", "halfedge")
_HE_UPDATE = ("id", "origin", "next", "prev", "polygon")
#: The parameters of `hestore._queries.history.add_revision`, in the order `Persistence.write` has them.
_REVISION = ("m", "n", "at", "msg", "ch", "sv", "se", "sp", "sq", "act", "tgt")


@functools.cache
def _recording(name: str, what: str, cols: tuple) -> tuple[bool, tuple, tuple, tuple]:
    """How a write of ``cols`` to table ``name`` is recorded in history.

    ``(versioned, key, positions of the key in cols, records)``: records
    ``"old"`` copies the rows as they were before the write, ``"new"`` marks
    keys that did not exist. A value row may come back after it was deleted;
    an element or property never does (its id is new), and what a revision
    created is found from its id counters instead.
    """
    table = schema.metadata.tables[name]
    key = ("id",) if what == "update" else tuple(c for c in cols if table.c[c].primary_key)
    records: tuple = ("old",) if what in ("update", "delete") else ()
    if what in ("insert", "upsert") and name in _VALUE_TABLE_NAMES:
        records = ("new",) if what == "insert" else ("old", "new")
    return name in schema.HISTORY, key, tuple(cols.index(k) for k in key), records


def _mesh_update() -> sa.Update:
    """The mesh's id counters after a flush, and its revision bumped by ``:bump``."""
    ms = schema.meshes
    return (
        ms.update()
        .where(ms.c.id == sa.bindparam("m"))
        .values(
            next_vertex=sa.bindparam("nv"),
            next_edge=sa.bindparam("ne"),
            next_polygon=sa.bindparam("np"),
            next_property=sa.bindparam("nq"),
            revision=ms.c.revision + sa.bindparam("bump"),
        )
    )


# The statements of a flush, each registered once (`hestore._queries.Query`); the reads of a load are
# `hestore._queries.stars`', `hestore._queries.catalogue`'s and `hestore._queries.values`'.

_UPDATE_MESH = query("uow.update_mesh")(_mesh_update)

#: The counters' update with the revision's row riding on it (PostgreSQL: one round trip).
_UPDATE_MESH_ADDED = query("uow.update_mesh_added")(
    lambda: _mesh_update().add_cte(history.revision_insert().cte("added"))
)


@query("uow.drop")
def _drop_rows(table: sa.Table):
    key = table.c.id if table is schema.meshes else table.c.mesh_id
    return table.delete().where(key == sa.bindparam("m"))


@query("uow.clear")
def _clear_values(table: sa.Table):
    return table.delete().where(table.c.mesh_id == sa.bindparam("m"), table.c.property == sa.bindparam("q"))


@query("uow.update_staged")
def _update_staged():
    s, v = schema.position_updates, schema.vertices
    where = (v.c.mesh_id == s.c.mesh_id, v.c.id == s.c.id)
    return v.update().where(*where).values(x=s.c.x, y=s.c.y, z=s.c.z, rev=sa.bindparam("r"))


@query("uow.journal_ids")
def _journal_ids(table: sa.Table, what: str, size: int):
    return to_history(table, what, "sqlite", table.c.id.in_(in_keys(size)))


@query("uow.journal_keys")
def _journal_keys(table: sa.Table, what: str, key: tuple):
    return to_history(table, what, "sqlite", *(table.c[c] == sa.bindparam(c) for c in key))


#: The rows `_journal_picked` records, by name: those of one property, those in the positions' scratch table.
_WHERE = {
    "property": lambda t: t.c.property == sa.bindparam("q"),
    "staged": lambda t: sa.exists().where(
        schema.position_updates.c.mesh_id == t.c.mesh_id, schema.position_updates.c.id == t.c.id
    ),
}


@query("uow.journal_picked")
def _journal_picked(table: sa.Table, what: str, where: str, dialect: str):
    return to_history(table, what, dialect, _WHERE[where](table))


@query("uow.write")
def _write_rows(table: sa.Table, what: str, cols: tuple):
    """SQLite's ``executemany`` statements: delete (matching every column), update (by id), insert, upsert."""
    m = table.c.mesh_id == sa.bindparam("m")
    if what == "delete":
        return table.delete().where(m, *(table.c[c] == sa.bindparam(c) for c in cols))
    if what == "update":
        key = table.c.id == sa.bindparam("id")
        return table.update().where(m, key).values({c: sa.bindparam(c) for c in cols[1:]})
    insert = sqlite_insert(table).values({"mesh_id": sa.bindparam("m"), **{c: sa.bindparam(c) for c in cols}})
    if what == "upsert":
        key = [c.name for c in table.primary_key]
        insert = insert.on_conflict_do_update(
            index_elements=key, set_={c: insert.excluded[c] for c in cols if c not in key}
        )
    return insert


class Persistence:
    """The SQL a `hestore._unitofwork.UnitOfWork` needs: batched loads and set-based writes.

    Parameters
    ----------
    db : hestore._queries.Executor
        The session's statements, run on its cursor.
    """

    def __init__(self, db: Executor) -> None:
        self.db = db
        self.cursor = db.cursor
        self._pg = db.dialect.name == "postgresql"
        self._pg_sql: dict[tuple, str] = {}

    # -- the catalogue row ------------------------------------------------

    def mesh_row(self, mesh_id: int, *, lock: bool) -> tuple | None:
        """The mesh's counters, policy, whether it has properties, its revision and history flag, or None.

        ``(next_vertex, next_edge, next_polygon, next_property, allow_loops,
        allow_multi_edges, has_properties, revision, history)``. With ``lock`` the row is locked
        for the rest of the transaction (``SELECT ... FOR UPDATE``; the caller
        sets the lock timeout).
        """
        return self.db.first(catalogue.mesh_row(lock), {"m": mesh_id})

    def catalogue(self, mesh_id: int) -> list[Property]:
        """The mesh's declared properties."""
        return [property_of(*row) for row in self.db.rows(catalogue.properties_of, {"m": mesh_id})]

    # -- loads -----------------------------------------------------------

    def load(self, mesh_id: int, want: dict[str, list[int]]) -> list[tuple]:
        """Rows for every kind of request in ``want``, in one statement.

        ``want`` maps a part to its ids: ``"vertices"``, ``"halfedges"``,
        ``"stars"`` (vertex rows, their outgoing half-edges and those
        half-edges' twins), ``"edges"`` (edge rows and both half-edges) and
        ``"polygons"`` (polygon rows and their half-edges). Each row is
        ``(kind, id, ...)`` with kind `K_VERTEX` ``(id, halfedge)``, `K_HALFEDGE`
        ``(id, origin, next, prev, twin, edge, polygon)``, `K_EDGE` or
        `K_POLYGON` ``(id, halfedge)``, padded with NULLs. Each id list is
        bucketed (`hestore._statements.in_list_bucket`), so a handful of
        compiled statements serve every operation.
        """
        parts = [(name, ids) for name, ids in want.items() if ids]
        if not parts:
            return []
        if any(len(ids) > MAX_IN for _, ids in parts):
            rows: list[tuple] = []
            for name, ids in parts:
                for chunk, _ in in_chunks(ids):
                    rows.extend(self.load(mesh_id, {name: chunk}))
            return rows
        sizes = tuple((name, in_list_bucket(len(ids))) for name, ids in parts)
        values: dict[str, Any] = {"m": mesh_id}
        for (name, ids), (_, size) in zip(parts, sizes):
            values.update(padded(ids, size, name))
        return self.db.rows(stars.load(sizes), values)

    def positions(self, mesh_id: int, ids: list[int]) -> dict[int, tuple | None]:
        """Stored positions of these vertices: ``{id: (x, y, z) or None}``."""
        out: dict[int, tuple | None] = {}
        for chunk, size in in_chunks(ids):
            values = {"m": mesh_id, **padded(chunk, size)}
            for i, x, y, z in self.db.rows(elements.vertices(size), values):
                out[i] = None if x is None else (x, y, z)
        return out

    def values(self, mesh_id: int, props: list[Property], ids: list[int]) -> dict[tuple[int, int], list]:
        """Stored values of these properties for these elements: ``{(property id, id): rows}``.

        Rows are ``(part, v0, …)`` as `hestore._values.value_of` reads them;
        an element without a stored value has no entry. One statement per
        value table (and per 512 ids).
        """
        out: dict[tuple[int, int], list] = {}
        by_table: dict = {}
        for prop in props:
            by_table.setdefault(table_of(prop.dtype), []).append(prop.id)
        for table, pids in by_table.items():
            psize = in_list_bucket(len(pids))
            for chunk, size in in_chunks(ids):
                values = {"m": mesh_id}
                values.update(padded(chunk, size))
                values.update(padded(pids, psize, "q"))
                for row in self.db.rows(value_rows.of_elements(table, size, psize), values):
                    out.setdefault((row[0], row[1]), []).append(row[2:])
        return out

    # -- writes ----------------------------------------------------------

    def write(self, changes: ChangeSet, message: str | None = None) -> None:
        """Write one flush worth of changes, then the mesh's counters and revision.

        Every row written carries the transaction's revision (``rev``); a row
        version an earlier revision wrote is first copied to its table's
        history twin (`hestore._journal.to_history`), so history is recorded
        where the rows change: on PostgreSQL by the write statement itself
        (data-modifying CTEs, no extra round trip), on SQLite by one more
        statement per table, before the writes (for an element table, one
        over every row the flush deletes, updates or moves, however many
        writes change it). The first flush of a transaction
        (``changes.bump``) also adds the revision's row, with ``message``.

        One statement per table and kind of change: an ``executemany`` on
        SQLite (in-process, so a row costs about a microsecond), and on
        PostgreSQL a single statement over ``unnest``-ed arrays, so the server
        does one set-based write instead of one round of work per row. Whole
        tables of a bulk import go through `hestore._columns.write_columns`.
        A dropped mesh loses every row and its catalogue row.
        """
        if changes.drop:
            for table in (*schema.MESH_TABLES, schema.meshes):
                self.db.run(_drop_rows(table), {"m": changes.mesh_id})
            return
        h, v, e, p = schema.halfedges, schema.vertices, schema.edges, schema.polygons
        elements = ((v, changes.vertices), (h, changes.halfedges), (e, changes.edges), (p, changes.polygons))
        positions = changes.properties.positions if changes.properties is not None else []
        # On SQLite each element table's rows this flush deletes, updates or moves are recorded by one
        # statement first, not one per write (PostgreSQL records them inside the writes themselves).
        journaled = changes.history and not self._pg
        if journaled:
            for table, rows in elements:
                ids = [*rows.deleted, *(row[0] for row in rows.updated)]
                if table is v:
                    ids += [row[0] for row in positions]
                if ids:
                    self._journal(changes, table, "old", ("id",), [ids])
        write = functools.partial(self._write, journaled=journaled)
        for table, rows in elements:
            write(changes, table, "delete", ("id",), [(i,) for i in rows.deleted])
        write(changes, v, "insert", _VERTEX_INSERT, changes.vertices.inserted)
        write(changes, h, "insert", HE_COLUMNS, changes.halfedges.inserted)
        write(changes, e, "insert", _PAIR, changes.edges.inserted)
        write(changes, p, "insert", _PAIR, changes.polygons.inserted)
        write(changes, h, "update", _HE_UPDATE, changes.halfedges.updated)
        write(changes, v, "update", _PAIR, changes.vertices.updated)
        write(changes, e, "update", _PAIR, changes.edges.updated)
        write(changes, p, "update", _PAIR, changes.polygons.updated)
        if changes.bulk is not None:
            self._write_bulk(changes, changes.bulk)
        if changes.properties is not None:
            self._write_properties(changes, changes.properties)
            write(changes, v, "update", _POSITION, positions)
        nv, ne, np_, nq = changes.counters
        values = {"m": changes.mesh_id, "nv": nv, "ne": ne, "np": np_, "nq": nq, "bump": changes.bump}
        if changes.bump and changes.history:
            counts = None
            if changes.bulk is not None:
                # Whole tables wrote no history: what they created is counted here, once.
                n = {name: len(columns["id"]) for name, columns in changes.bulk.tables.items()}
                counts = created_changes(n["vertices"], n["halfedges"], n["edges"], n["polygons"])
            at = history.now(sqlite=not self._pg)
            if self._pg:
                sv, se, sp, sq = changes.start
                values.update(
                    n=changes.revision, at=at, msg=message, ch=counts, sv=sv, se=se, sp=sp, sq=sq, act=None, tgt=None
                )
                # The revision's row rides on the counters' update: one round trip.
                self.db.run(_UPDATE_MESH_ADDED, values)
                return
            row = (changes.mesh_id, changes.revision, at, message, counts, *changes.start, None, None)
            self.db.run_ordered(history.add_revision, _REVISION, row)
        self.db.run(_UPDATE_MESH, values)

    def _write_properties(self, changes: ChangeSet, pc: PropertyChanges) -> None:
        """Catalogue, values and bulk positions of one flush, in `PropertyChanges`' order.

        `write` writes the positions set one by one, after these.
        """
        write = self._write
        catalogue = schema.properties
        for prop in pc.removed:
            self._clear(changes, prop)
        write(changes, catalogue, "delete", ("id",), [(p.id,) for p in pc.removed])
        write(changes, catalogue, "insert", _CATALOGUE, [_catalogue_row(p) for p in pc.added])
        for bulk in pc.bulk:
            self._write_bulk_values(changes, bulk)
        unset: dict = {}
        upserts: dict = {}
        for (pid, i), (prop, rows) in pc.values.items():
            table = table_of(prop.dtype)
            if rows is UNSET:
                unset.setdefault(table, []).append((pid, i))
            else:
                # An element's value always has the same number of rows: an upsert replaces it.
                width = sum(1 for c in table.c if c.name.startswith("v"))
                upserts.setdefault(table, []).extend((pid, i, *(row + (None,) * width)[: width + 1]) for row in rows)
        for table, keys in unset.items():
            write(changes, table, "delete", _VALUE_KEY, keys)
        for table, rows in upserts.items():
            write(changes, table, "upsert", _value_columns(table), rows)
        # Purged after the writes: values set in this flush on elements it deletes go too.
        purge: dict = {}
        for prop, ids in pc.purge:
            purge.setdefault(table_of(prop.dtype), []).extend((prop.id, i) for i in ids)
        for table, keys in purge.items():
            write(changes, table, "delete", _VALUE_KEY, keys)

    def _clear(self, changes: ChangeSet, prop: Property) -> None:
        """Delete every value of one property."""
        table = table_of(prop.dtype)
        if changes.history:
            self._journal_where(changes, table, "old", "property", {"q": prop.id})

        self.db.run(_clear_values(table), {"m": changes.mesh_id, "q": prop.id})

    def _write_bulk_values(self, changes: ChangeSet, bulk: BulkValues) -> None:
        """One set-based write of many elements' values (or positions)."""
        columns = bulk.columns
        if bulk.prop is None:
            if self._pg and len(bulk.ids) >= _STAGE_ROWS:
                self._update_positions_staged(changes, columns)
            else:
                cols = [columns[c].tolist() for c in _POSITION]
                self._write_columns(changes, schema.vertices, "update", _POSITION, cols)
            return
        prop = bulk.prop
        table = table_of(prop.dtype)
        if bulk.replace_all:
            self._clear(changes, prop)
        else:
            gone = np.concatenate([bulk.ids, bulk.unset]) if bulk.unset is not None else bulk.ids
            self._write_columns(changes, table, "delete", _VALUE_KEY, [[prop.id] * len(gone), gone.tolist()])
        n = len(columns["id"])
        if not n:
            return
        columns = {"property": np.full(n, prop.id, dtype=np.int64), **columns}
        if prop.dtype == "str" and self._pg:
            # Binary COPY has no text layout here: one INSERT over unnest-ed arrays instead.
            names = tuple(columns)
            self._write_columns(changes, table, "insert", names, [list(columns[c]) for c in names])
            return
        columns["rev"] = np.full(n, changes.revision)
        write_columns(self.cursor(), self.db.dialect, table, changes.mesh_id, columns, nulls=False)
        if changes.history:
            self._journal_where(changes, table, "new", "property", {"q": prop.id})

    def _update_positions_staged(self, changes: ChangeSet, columns: dict) -> None:
        """Many positions on PostgreSQL: binary COPY into a scratch table, then one ``UPDATE ... FROM``.

        An ``UPDATE`` over ``unnest``-ed arrays of a million elements is
        planned as a million index probes; a join with a table the planner
        can size is a hash join.
        """
        staging = schema.position_updates
        cursor = self.cursor()
        dialect = self.db.dialect
        cursor.execute(str(CreateTable(staging, if_not_exists=True).compile(dialect=dialect)))
        write_columns(cursor, dialect, staging, changes.mesh_id, {c: columns[c] for c in _POSITION})
        if changes.history:
            self._journal_where(changes, schema.vertices, "old", "staged", {})
        self.db.run(_update_staged, {"r": changes.revision})
        cursor.execute(f"TRUNCATE {staging.name}")

    def _journal(self, changes: ChangeSet, table: sa.Table, what: str, key: tuple, columns: list[list]) -> None:
        """`hestore._journal.to_history` on SQLite for the rows matched by ``key`` columns.

        Rows picked by id: one statement per `MAX_IN` ids; by a longer key
        (a value's property and element): one ``executemany``. A row written
        twice in one transaction is recorded once, so history keeps the state
        before the transaction (it is net).
        """
        if key == ("id",):
            head = (changes.revision, changes.mesh_id)
            for chunk, size in in_chunks(columns[0]):
                # Every edit pays for this call: the values go in order, without a dict.
                values = (*head, *padded_values(chunk, size))
                self.db.run_ordered(_journal_ids(table, what, size), _in_names(size), values)
            return
        fixed = {"m": changes.mesh_id, "r": changes.revision}
        self.db.run_columns(_journal_keys(table, what, key), fixed, dict(zip(key, columns)))

    def _journal_where(self, changes: ChangeSet, table: sa.Table, what: str, where: str, values: dict) -> None:
        """`hestore._journal.to_history` for every row a condition (`_WHERE`) picks: one ``INSERT ... SELECT``."""
        picked = _journal_picked(table, what, where, self.db.dialect.name)
        self.db.run(picked, {"m": changes.mesh_id, "r": changes.revision, **values})

    def _write_bulk(self, changes: ChangeSet, bulk) -> None:
        total = sum(len(columns["id"]) for columns in bulk.tables.values())
        done = 0
        for name, columns in bulk.tables.items():
            report = None
            if bulk.progress is not None:
                report = lambda rows, base=done: bulk.progress(base + rows, total)  # noqa: E731
            table = schema.metadata.tables[name]
            columns = {**columns, "rev": np.full(len(columns["id"]), changes.revision)}
            write_columns(self.cursor(), self.db.dialect, table, changes.mesh_id, columns, progress=report)
            done += len(columns["id"])

    def _write(self, changes: ChangeSet, table: sa.Table, what: str, cols: tuple, rows: list[tuple],
               journaled: bool = False) -> None:
        """Insert, update (by id, the first column) or delete (matching every column) rows of ``table``.

        ``journaled``: the rows' old versions are in history already (`write` recorded them).
        """
        if rows:
            self._write_columns(changes, table, what, cols, [list(c) for c in zip(*rows)], journaled)

    def _write_columns(self, changes: ChangeSet, table: sa.Table, what: str, cols: tuple, columns: list[list],
                       journaled: bool = False) -> None:
        """`_write` for rows given as one list per column: one statement (up to three on SQLite with history)."""
        if not columns or not len(columns[0]):
            return
        versioned, key, at, records = _recording(table.name, what, cols)
        if versioned and what != "delete":
            cols, columns = (*cols, "rev"), [*columns, [changes.revision] * len(columns[0])]
        if journaled:
            records = tuple(r for r in records if r != "old")
        if not (versioned and changes.history and records):
            self._write_statement(changes, table, what, cols, columns)
            return
        keys = [columns[i] for i in at]
        if self._pg:
            self._write_pg(changes, table, what, cols, columns, records, key, keys)
            return
        if "old" in records:
            self._journal(changes, table, "old", key, keys)
        self._write_statement(changes, table, what, cols, columns)
        if "new" in records:
            self._journal(changes, table, "new", key, keys)

    def _write_pg(self, changes: ChangeSet, table: sa.Table, what: str, cols: tuple, columns: list[list],
                  records: tuple = (), key: tuple = (), keys: list[list] = ()) -> None:
        """`_write_statement` on PostgreSQL, with its history ``records``: one statement, one round trip.

        The records are data-modifying CTEs of the write. Every part of a
        statement reads the snapshot from before it, so ``old`` copies the
        rows as they were and ``new`` finds the keys that did not exist yet.
        """
        sized = len(columns[0]) >= _SIZED_ROWS
        cached = (what, table.name, cols, records, sized)
        sql = self._pg_sql.get(cached)
        if sql is None:
            parts = ", ".join(f"h_{r} AS ({_pg_to_history(table, r, key, sized)})" for r in records)
            sql = self._pg_sql[cached] = (f"WITH {parts} " if parts else "") + _pg_statement(table, what, cols, sized)
        params: list = []
        for r in records:
            rev, m = changes.revision, changes.mesh_id
            params += [rev, *keys, m, rev] if r == "old" else [rev, m, *keys]
        params += [changes.mesh_id, *columns] if what in ("insert", "upsert") else [*columns, changes.mesh_id]
        self.cursor().execute(sql, params)

    def _write_statement(
        self, changes: ChangeSet, table: sa.Table, what: str, cols: tuple, columns: list[list]
    ) -> None:
        if self._pg:
            self._write_pg(changes, table, what, cols, columns)
            return

        self.db.run_columns(_write_rows(table, what, cols), {"m": changes.mesh_id}, dict(zip(cols, columns)))
