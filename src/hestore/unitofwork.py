"""The unit of work: a mesh's rows as one write transaction sees them.

Topological operations (`hestore.kernel`) never talk to SQL. They read and
write through a `UnitOfWork`, which

* loads rows in batches (a vertex's whole star in one query) and keeps them
  for the rest of the transaction — valid because the transaction holds the
  mesh's write lock, so nobody else can change them;
* records every change of an operation in an undo log, so an operation that
  raises half-way (a ``makeAdjacent`` that finds no free gap on the third
  corner) leaves no trace;
* writes the difference between what it loaded and what it holds now in a
  few set-based statements when the store flushes it (before a read, a
  savepoint, or the commit).

Half-edge records are tuples ``(origin, next, prev, twin, edge, polygon)``;
`GONE` marks a deleted element. Ids come from the mesh's counters and are
never reused: edge ``e`` owns half-edges ``2e`` and ``2e + 1``.
"""

from __future__ import annotations

from typing import Any, Iterable

import sqlalchemy as sa

from hestore import schema
from hestore.errors import ElementNotFoundError, InvariantViolationError
from hestore.statements import MAX_IN, StatementCache, in_list_bucket, indexed_by
from hestore.validation import Violation

__all__ = ["UnitOfWork", "MeshSQL", "GONE", "ORIGIN", "NEXT", "PREV", "TWIN", "EDGE", "POLYGON"]

ORIGIN, NEXT, PREV, TWIN, EDGE, POLYGON = range(6)


class _Marker:
    __slots__ = ("name",)

    def __init__(self, name: str) -> None:
        self.name = name

    def __repr__(self) -> str:
        return self.name


#: Current value of a deleted element.
GONE = _Marker("GONE")
#: Loaded value of an element that is not in the database yet.
NEW = _Marker("NEW")
_ABSENT = _Marker("ABSENT")

_HE_COLS = ("id", "origin", "next", "prev", "twin", "edge", "polygon")


K_VERTEX, K_HALFEDGE, K_EDGE, K_POLYGON = range(4)


def _load_statement(sizes: tuple) -> sa.CompoundSelect:
    """The ``UNION ALL`` behind `MeshSQL.load` for the given part sizes."""
    h, v, e, p = schema.halfedges, schema.vertices, schema.edges, schema.polygons
    null = sa.cast(sa.null(), sa.BigInteger)
    m = sa.bindparam("m")

    def kind(k: int):
        return sa.literal_column(str(k), sa.Integer)

    def he_cols(t):
        return [kind(K_HALFEDGE)] + [t.c[name] for name in _HE_COLS]

    def pair_cols(k, t):
        return [kind(k), t.c.id, t.c.halfedge] + [null] * 5

    selects = []
    for name, size in sizes:
        ids = [sa.bindparam(f"{name}{i}") for i in range(size)]
        if name == "vertices":
            selects.append(sa.select(*pair_cols(K_VERTEX, v)).where(v.c.mesh_id == m, v.c.id.in_(ids)))
        elif name == "halfedges":
            selects.append(sa.select(*he_cols(h)).where(h.c.mesh_id == m, h.c.id.in_(ids)))
        elif name == "stars":
            s, t = h.alias("s"), h.alias("t")
            selects.append(sa.select(*pair_cols(K_VERTEX, v)).where(v.c.mesh_id == m, v.c.id.in_(ids)))
            out = sa.select(*he_cols(h)).where(h.c.mesh_id == m, h.c.origin.in_(ids))
            selects.append(indexed_by(out, h, "ix_halfedges_origin"))
            twins = (
                sa.select(*he_cols(t))
                .select_from(s.join(t, sa.and_(t.c.mesh_id == s.c.mesh_id, t.c.id == s.c.twin)))
                .where(s.c.mesh_id == m, s.c.origin.in_(ids))
            )
            selects.append(indexed_by(twins, s, "ix_halfedges_origin"))
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


class MeshSQL:
    """The SQL a `UnitOfWork` needs: batched loads and set-based writes.

    Parameters
    ----------
    statements : StatementCache
        Compiled statements of the store's dialect.
    cursor_factory : callable
        Returns a DBAPI cursor on the store's connection.
    """

    def __init__(self, statements: StatementCache, cursor_factory) -> None:
        self.st = statements
        self.cursor = cursor_factory
        self._pg_sql: dict[tuple, str] = {}

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
        bucketed (`hestore.statements.in_list_bucket`), so a handful of
        compiled statements serve every operation.
        """
        parts = [(name, ids) for name, ids in want.items() if ids]
        if not parts:
            return []
        sizes = tuple((name, in_list_bucket(len(ids))) for name, ids in parts)
        if any(len(ids) > MAX_IN for _, ids in parts):
            rows: list[tuple] = []
            for name, ids in parts:
                for start in range(0, len(ids), MAX_IN):
                    rows.extend(self.load(mesh_id, {name: ids[start : start + MAX_IN]}))
            return rows
        stmt = self.st.get(("load",) + sizes, lambda: _load_statement(sizes))
        values: dict[str, Any] = {"m": mesh_id}
        for (name, ids), (_, size) in zip(parts, sizes):
            last = ids[-1]
            for k in range(size):
                values[f"{name}{k}"] = ids[k] if k < len(ids) else last
        return stmt.rows(self.cursor(), values)

    # -- writes ----------------------------------------------------------

    def write(self, mesh_id: int, changes: dict[str, Any], counters: tuple, bump: int) -> None:
        """Write one flush worth of changes and the mesh's counters.

        One statement per table and kind of change: an ``executemany`` on
        SQLite (in-process, so a row costs about a microsecond), and on
        PostgreSQL a single statement over ``unnest``-ed arrays, so the server
        does one set-based write instead of one round of work per row.
        """
        h, v, e, p = schema.halfedges, schema.vertices, schema.edges, schema.polygons
        write = self._write_pg if self.st.dialect.name == "postgresql" else self._write_many
        for table, key in ((v, "v"), (h, "he"), (e, "e"), (p, "p")):
            write(mesh_id, table, "delete", ("id",), [(i,) for i in changes[key + "_del"]])
        write(mesh_id, v, "insert", ("id", "halfedge", "x", "y", "z"), [(i, he) + tuple(xyz) for i, he, xyz in changes["v_ins"]])
        write(mesh_id, h, "insert", _HE_COLS, [(i,) + r for i, r in changes["he_ins"]])
        for table, key in ((e, "e"), (p, "p")):
            write(mesh_id, table, "insert", ("id", "halfedge"), changes[key + "_ins"])
        write(mesh_id, h, "update", ("id", "next", "prev", "polygon"), [(i, r[1], r[2], r[5]) for i, r in changes["he_upd"]])
        write(mesh_id, v, "update", ("id", "halfedge"), changes["v_upd"])
        ms = schema.meshes
        upd_m = self.st.get(
            "upd_mesh",
            lambda: ms.update()
            .where(ms.c.id == sa.bindparam("m"))
            .values(
                next_vertex=sa.bindparam("nv"),
                next_edge=sa.bindparam("ne"),
                next_polygon=sa.bindparam("np"),
                revision=ms.c.revision + sa.bindparam("bump"),
            ),
        )
        upd_m.run(self.cursor(), {"m": mesh_id, "nv": counters[0], "ne": counters[1], "np": counters[2], "bump": bump})

    def _write_many(self, mesh_id: int, table: sa.Table, what: str, cols: tuple, rows: list[tuple]) -> None:
        if not rows:
            return

        def build():
            key = table.c.mesh_id == sa.bindparam("m"), table.c.id == sa.bindparam("id")
            if what == "delete":
                return table.delete().where(*key)
            if what == "update":
                return table.update().where(*key).values({c: sa.bindparam(c) for c in cols[1:]})
            return table.insert().values({"mesh_id": sa.bindparam("m"), **{c: sa.bindparam(c) for c in cols}})

        stmt = self.st.get((what, table.name, cols), build)
        stmt.run_many(self.cursor(), ({"m": mesh_id, **dict(zip(cols, row))} for row in rows))

    def _write_pg(self, mesh_id: int, table: sa.Table, what: str, cols: tuple, rows: list[tuple]) -> None:
        if not rows:
            return
        sql = self._pg_sql.get((what, table.name, cols))
        if sql is None:
            sql = self._pg_sql[(what, table.name, cols)] = _pg_statement(table, what, cols)
        arrays = [list(column) for column in zip(*rows)]
        self.cursor().execute(sql, [mesh_id, *arrays] if what == "insert" else [*arrays, mesh_id])


def _pg_statement(table: sa.Table, what: str, cols: tuple) -> str:
    """PostgreSQL SQL writing many rows of ``table`` from one array per column."""
    q = '"{}"'.format
    types = ["double precision" if isinstance(table.c[c].type, sa.Float) else "bigint" for c in cols]
    arrays = ", ".join(f"%s::{t}[]" for t in types)
    name = q(table.name)
    if what == "delete":
        return f"DELETE FROM {name} WHERE {q('id')} = ANY(%s::bigint[]) AND {q('mesh_id')} = %s"
    if what == "insert":
        columns = ", ".join(q(c) for c in ("mesh_id",) + tuple(cols))
        return f"INSERT INTO {name} ({columns}) SELECT %s, * FROM unnest({arrays})"
    sets = ", ".join(f"{q(c)} = u.{q(c)}" for c in cols[1:])
    return (
        f"UPDATE {name} AS t SET {sets} FROM unnest({arrays}) AS u({', '.join(q(c) for c in cols)}) "
        f"WHERE t.{q('mesh_id')} = %s AND t.{q('id')} = u.{q('id')}"
    )


class UnitOfWork:
    """A write transaction's view of one mesh: cached rows, undo log, diff.

    Parameters
    ----------
    mesh_id : int
        The mesh.
    sql : MeshSQL
        Loads and writes rows.
    counters : tuple of int
        ``(next_vertex, next_edge, next_polygon)`` as stored.
    allow_loops, allow_multi_edges : bool
        The mesh's policy.
    """

    def __init__(self, mesh_id: int, sql: MeshSQL, counters: tuple, allow_loops: bool, allow_multi_edges: bool) -> None:
        self.mesh_id = mesh_id
        self.sql = sql
        self.allow_loops = allow_loops
        self.allow_multi_edges = allow_multi_edges
        self.next_vertex, self.next_edge, self.next_polygon = counters
        self._counters0 = tuple(counters)
        # current values / values as in the database (NEW: not there yet)
        self._he: dict[int, Any] = {}
        self._he0: dict[int, Any] = {}
        self._v: dict[int, Any] = {}
        self._v0: dict[int, Any] = {}
        self._e: dict[int, Any] = {}
        self._e0: dict[int, Any] = {}
        self._p: dict[int, Any] = {}
        self._p0: dict[int, Any] = {}
        self._pos: dict[int, tuple] = {}
        # vertices whose every outgoing half-edge (and its twin) is cached
        self._out: dict[int, set[int]] = {}
        self._dirty_he: set[int] = set()
        self._dirty_v: set[int] = set()
        self._dirty_e: set[int] = set()
        self._dirty_p: set[int] = set()
        self._undo: list | None = None

    # -- operations ------------------------------------------------------

    def begin_operation(self) -> None:
        """Start recording changes so that `abort_operation` can undo them."""
        self._undo = []

    def end_operation(self) -> None:
        """Keep the operation's changes."""
        self._undo = None

    def abort_operation(self) -> None:
        """Undo every change since `begin_operation`, newest first."""
        self.rollback_to(0)
        self._undo = None

    def mark(self) -> int:
        """A point inside the current operation that `rollback_to` can return to."""
        return len(self._undo) if self._undo is not None else 0

    def rollback_to(self, mark: int) -> None:
        """Undo the current operation's changes made since ``mark``, newest first."""
        undo = self._undo or []
        while len(undo) > mark:
            entry = undo.pop()
            kind = entry[0]
            if kind == "set":
                _, d, key, old = entry
                if old is _ABSENT:
                    d.pop(key, None)
                else:
                    d[key] = old
            elif kind == "out+":
                self._out[entry[1]].discard(entry[2])
            elif kind == "out-":
                self._out[entry[1]].add(entry[2])
            elif kind == "dirty":
                entry[1].discard(entry[2])
            elif kind == "counters":
                self.next_vertex, self.next_edge, self.next_polygon = entry[1]

    def _set(self, d: dict, key: int, value: Any) -> None:
        if self._undo is not None:
            self._undo.append(("set", d, key, d.get(key, _ABSENT)))
        d[key] = value

    def _touch(self, dirty: set, key: int) -> None:
        # Undone with the operation too: an aborted operation must leave
        # nothing to flush, not even a no-op update that would bump the revision.
        if key not in dirty:
            dirty.add(key)
            if self._undo is not None:
                self._undo.append(("dirty", dirty, key))

    def _save_counters(self) -> None:
        if self._undo is not None:
            self._undo.append(("counters", (self.next_vertex, self.next_edge, self.next_polygon)))

    # -- loading ---------------------------------------------------------

    def load(
        self,
        *,
        vertices: Iterable[int] = (),
        halfedges: Iterable[int] = (),
        stars: Iterable[int] = (),
        edges: Iterable[int] = (),
        polygons: Iterable[int] = (),
    ) -> None:
        """Cache whatever of these is not cached yet, in one query.

        ``stars`` are vertices whose every outgoing half-edge (and its twin)
        is wanted; the others are elements by id (an edge or polygon with its
        half-edges). Rows already cached are kept as they are: the cache holds
        this transaction's edits, the database does not yet.
        """
        # Most calls find everything cached already: keep that path cheap.
        out = self._out
        star_ids = [v for v in stars if v not in out]
        want = {}
        if star_ids:
            star_ids = want["stars"] = list(dict.fromkeys(star_ids))
        for name, ids, cur in (
            ("vertices", vertices, self._v),
            ("halfedges", halfedges, self._he),
            ("edges", edges, self._e),
            ("polygons", polygons, self._p),
        ):
            if ids:
                missing = [i for i in ids if i not in cur]
                if name == "vertices" and star_ids:
                    missing = [i for i in missing if i not in star_ids]
                if missing:
                    want[name] = list(dict.fromkeys(missing))
        if not want:
            return
        rows = self.sql.load(self.mesh_id, want)
        he, he0 = self._he, self._he0
        by_kind = ((self._v, self._v0), None, (self._e, self._e0), (self._p, self._p0))
        outs: dict[int, set[int]] = {v: set() for v in star_ids}
        for row in rows:
            kind, i = row[0], row[1]
            if kind == K_HALFEDGE:
                if i not in he:
                    he[i] = he0[i] = row[2:]
                if row[2] in outs and he[i] is not GONE:
                    outs[row[2]].add(i)
            else:
                cur, loaded = by_kind[kind]
                if i not in cur:
                    cur[i] = loaded[i] = row[2]
        # Remember what does not exist, so it is not asked for again.
        for name, cur in (("stars", self._v), ("vertices", self._v), ("halfedges", he), ("edges", self._e), ("polygons", self._p)):
            for i in want.get(name, ()):
                cur.setdefault(i, _ABSENT)
        self._out.update(outs)

    # -- reads -----------------------------------------------------------

    def he(self, h: int) -> tuple:
        """The record ``(origin, next, prev, twin, edge, polygon)`` of half-edge ``h``."""
        rec = self._he.get(h)
        if rec is None:
            self.load(halfedges=(h,))
            rec = self._he[h]
        if rec is GONE or rec is _ABSENT:
            raise ElementNotFoundError(f"half-edge {h} does not exist in this mesh")
        return rec

    def _row(self, current: dict, part: str, i: int, what: str) -> Any:
        if i not in current:
            self.load(**{part: (i,)})
        rec = current[i]
        if rec is GONE or rec is _ABSENT:
            raise ElementNotFoundError(f"{what} {i} does not exist in this mesh")
        return rec

    def vhe(self, v: int) -> int | None:
        """The half-edge of vertex ``v`` (``None`` if isolated)."""
        return self._row(self._v, "vertices", v, "vertex")

    def edge_he(self, e: int) -> int:
        """The half-edge of edge ``e``."""
        return self._row(self._e, "edges", e, "edge")

    def polygon_he(self, p: int) -> int:
        """The half-edge of polygon ``p``."""
        return self._row(self._p, "polygons", p, "polygon")

    def outgoing(self, v: int) -> set[int]:
        """Ids of the half-edges leaving ``v`` (a set; no rotation order)."""
        if v not in self._out:
            self.load(stars=(v,))
            self.vhe(v)
        return self._out[v]

    def corrupt(self, code: str, message: str) -> InvariantViolationError:
        """The error to raise when stored data is found broken mid-operation."""
        return InvariantViolationError([Violation(code, "halfedge", (), message)])

    # -- writes ----------------------------------------------------------

    def link(self, a: int, b: int) -> None:
        """Make ``b`` follow ``a``: ``next(a) = b`` and ``prev(b) = a``."""
        ra = self.he(a)
        if ra[NEXT] != b:
            self._set(self._he, a, ra[:NEXT] + (b,) + ra[NEXT + 1 :])
            self._touch(self._dirty_he, a)
        rb = self.he(b)
        if rb[PREV] != a:
            self._set(self._he, b, rb[:PREV] + (a,) + rb[PREV + 1 :])
            self._touch(self._dirty_he, b)

    def set_polygon(self, h: int, p: int | None) -> None:
        r = self.he(h)
        self._set(self._he, h, r[:POLYGON] + (p,))
        self._touch(self._dirty_he, h)

    def set_vhe(self, v: int, h: int | None) -> None:
        self.vhe(v)
        self._set(self._v, v, h)
        self._touch(self._dirty_v, v)

    def new_vertex(self, position: tuple | None) -> int:
        self._save_counters()
        v = self.next_vertex
        self.next_vertex += 1
        self._set(self._v, v, None)
        self._set(self._v0, v, NEW)
        self._set(self._pos, v, position)
        self._set(self._out, v, set())
        self._touch(self._dirty_v, v)
        return v

    def _out_add(self, v: int, h: int) -> None:
        self._out[v].add(h)
        if self._undo is not None:
            self._undo.append(("out+", v, h))

    def _out_remove(self, v: int, h: int) -> None:
        self._out[v].discard(h)
        if self._undo is not None:
            self._undo.append(("out-", v, h))

    def new_edge(self, a: int, b: int) -> tuple[int, int, int]:
        """Allocate edge ``a``–``b`` as an isolated pair: ``(edge, a→b, b→a)``.

        The caller links the two half-edges into the vertices' rotations.
        """
        self.outgoing(a)
        self.outgoing(b)
        self._save_counters()
        e = self.next_edge
        self.next_edge += 1
        h, t = 2 * e, 2 * e + 1
        self._set(self._he, h, (a, t, t, t, e, None))
        self._set(self._he0, h, NEW)
        self._set(self._he, t, (b, h, h, h, e, None))
        self._set(self._he0, t, NEW)
        self._set(self._e, e, h)
        self._set(self._e0, e, NEW)
        self._touch(self._dirty_he, h)
        self._touch(self._dirty_he, t)
        self._touch(self._dirty_e, e)
        self._out_add(a, h)
        self._out_add(b, t)
        return e, h, t

    def new_polygon(self, h: int) -> int:
        self._save_counters()
        p = self.next_polygon
        self.next_polygon += 1
        self._set(self._p, p, h)
        self._set(self._p0, p, NEW)
        self._touch(self._dirty_p, p)
        return p

    def delete_polygon(self, p: int) -> None:
        self.polygon_he(p)
        self._set(self._p, p, GONE)
        self._touch(self._dirty_p, p)

    def delete_edge(self, e: int) -> None:
        h = self.edge_he(e)
        t = self.he(h)[TWIN]
        for x in (h, t):
            origin = self.he(x)[ORIGIN]
            if origin in self._out:
                self._out_remove(origin, x)
            self._set(self._he, x, GONE)
            self._touch(self._dirty_he, x)
        self._set(self._e, e, GONE)
        self._touch(self._dirty_e, e)

    def delete_vertex(self, v: int) -> None:
        self.vhe(v)
        self._set(self._v, v, GONE)
        self._touch(self._dirty_v, v)

    # -- flushing --------------------------------------------------------

    @property
    def dirty(self) -> bool:
        """Whether anything changed since the last flush."""
        return bool(
            self._dirty_he or self._dirty_v or self._dirty_e or self._dirty_p
            or (self.next_vertex, self.next_edge, self.next_polygon) != self._counters0
        )

    def changes(self) -> dict[str, list]:
        """What a flush must write: inserts, updates and deletes per table."""
        out: dict[str, list] = {
            k: [] for k in ("he_ins", "he_upd", "he_del", "v_ins", "v_upd", "v_del", "e_ins", "e_del", "p_ins", "p_del")
        }
        for h in sorted(self._dirty_he):
            cur, old = self._he[h], self._he0.get(h, NEW)
            if old is NEW:
                if cur is not GONE:
                    out["he_ins"].append((h, cur))
            elif cur is GONE:
                out["he_del"].append(h)
            elif cur != old:
                out["he_upd"].append((h, cur))
        for v in sorted(self._dirty_v):
            cur, old = self._v[v], self._v0.get(v, NEW)
            if old is NEW:
                if cur is not GONE:
                    out["v_ins"].append((v, cur, self._pos.get(v) or (None, None, None)))
            elif cur is GONE:
                out["v_del"].append(v)
            elif cur != old:
                out["v_upd"].append((v, cur))
        for dirty, cur_d, old_d, key in ((self._dirty_e, self._e, self._e0, "e"), (self._dirty_p, self._p, self._p0, "p")):
            for i in sorted(dirty):
                cur, old = cur_d[i], old_d.get(i, NEW)
                if old is NEW:
                    if cur is not GONE:
                        out[key + "_ins"].append((i, cur))
                elif cur is GONE:
                    out[key + "_del"].append(i)
        return out

    def flush(self, bump: int) -> None:
        """Write everything changed since the last flush, then start afresh.

        Parameters
        ----------
        bump : int
            How much to add to the mesh's revision (1 for the first flush of a
            transaction that changes the mesh, else 0).
        """
        counters = (self.next_vertex, self.next_edge, self.next_polygon)
        self.sql.write(self.mesh_id, self.changes(), counters, bump)
        for dirty, cur_d, old_d in (
            (self._dirty_he, self._he, self._he0),
            (self._dirty_v, self._v, self._v0),
            (self._dirty_e, self._e, self._e0),
            (self._dirty_p, self._p, self._p0),
        ):
            for i in dirty:
                cur = cur_d[i]
                old_d[i] = NEW if cur is GONE else cur
            dirty.clear()
        self._pos.clear()
        self._counters0 = counters
