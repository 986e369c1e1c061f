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
from hestore.statements import StatementCache, indexed_by

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

    # -- loads -----------------------------------------------------------

    def _he_select(self):
        h = schema.halfedges
        return sa.select(*(h.c[name] for name in _HE_COLS))

    def halfedges(self, mesh_id: int, ids: Iterable[int]) -> list[tuple]:
        h = schema.halfedges
        return self.st.rows_in(
            self.cursor(),
            "he_by_id",
            lambda ph: self._he_select().where(h.c.mesh_id == sa.bindparam("m"), h.c.id.in_(ph)),
            {"m": mesh_id},
            ids,
        )

    def polygon_halfedges(self, mesh_id: int, polygon_ids: Iterable[int]) -> list[tuple]:
        h = schema.halfedges
        return self.st.rows_in(
            self.cursor(),
            "he_by_polygon",
            lambda ph: indexed_by(
                self._he_select().where(h.c.mesh_id == sa.bindparam("m"), h.c.polygon.in_(ph)),
                h,
                "ix_halfedges_polygon",
            ),
            {"m": mesh_id},
            polygon_ids,
        )

    def stars(self, mesh_id: int, vertex_ids: Iterable[int]) -> list[tuple]:
        """Every half-edge leaving one of the vertices, and its twin."""
        h = schema.halfedges

        def build(ph):
            out = self._he_select().where(h.c.mesh_id == sa.bindparam("m"), h.c.origin.in_(ph))
            t = h.alias("t")
            s = h.alias("s")
            twins = (
                sa.select(*(t.c[name] for name in _HE_COLS))
                .select_from(s.join(t, sa.and_(t.c.mesh_id == s.c.mesh_id, t.c.id == s.c.twin)))
                .where(s.c.mesh_id == sa.bindparam("m"), s.c.origin.in_(ph))
            )
            out = indexed_by(out, h, "ix_halfedges_origin")
            twins = indexed_by(twins, s, "ix_halfedges_origin")
            return sa.union_all(out, twins)

        return self.st.rows_in(self.cursor(), "stars", build, {"m": mesh_id}, vertex_ids)

    def _pairs(self, table: sa.Table, key: str, mesh_id: int, ids: Iterable[int]) -> list[tuple]:
        return self.st.rows_in(
            self.cursor(),
            key,
            lambda ph: sa.select(table.c.id, table.c.halfedge).where(
                table.c.mesh_id == sa.bindparam("m"), table.c.id.in_(ph)
            ),
            {"m": mesh_id},
            ids,
        )

    def vertices(self, mesh_id: int, ids: Iterable[int]) -> list[tuple]:
        return self._pairs(schema.vertices, "v_by_id", mesh_id, ids)

    def edges(self, mesh_id: int, ids: Iterable[int]) -> list[tuple]:
        return self._pairs(schema.edges, "e_by_id", mesh_id, ids)

    def polygons(self, mesh_id: int, ids: Iterable[int]) -> list[tuple]:
        return self._pairs(schema.polygons, "p_by_id", mesh_id, ids)

    # -- writes ----------------------------------------------------------

    def _insert(self, table: sa.Table):
        return self.st.get(("ins", table.name), lambda: table.insert())

    def _delete(self, table: sa.Table):
        return self.st.get(
            ("del", table.name),
            lambda: table.delete().where(
                table.c.mesh_id == sa.bindparam("m"), table.c.id == sa.bindparam("i")
            ),
        )

    def write(self, mesh_id: int, changes: dict[str, Any], counters: tuple, bump: int) -> None:
        """Write one flush worth of changes and the mesh's counters."""
        cur = self.cursor()
        h, v, e, p = schema.halfedges, schema.vertices, schema.edges, schema.polygons
        m = mesh_id
        for table, key in ((v, "v"), (h, "he"), (e, "e"), (p, "p")):
            self._delete(table).run_many(cur, ({"m": m, "i": i} for i in changes[key + "_del"]))
        self._insert(v).run_many(
            cur,
            (
                {"mesh_id": m, "id": i, "halfedge": he, "x": xyz[0], "y": xyz[1], "z": xyz[2]}
                for i, he, xyz in changes["v_ins"]
            ),
        )
        self._insert(h).run_many(
            cur,
            (
                {"mesh_id": m, "id": i, "origin": r[0], "next": r[1], "prev": r[2], "twin": r[3], "edge": r[4], "polygon": r[5]}
                for i, r in changes["he_ins"]
            ),
        )
        for table, key in ((e, "e"), (p, "p")):
            self._insert(table).run_many(
                cur, ({"mesh_id": m, "id": i, "halfedge": he} for i, he in changes[key + "_ins"])
            )
        upd_he = self.st.get(
            "upd_he",
            lambda: h.update()
            .where(h.c.mesh_id == sa.bindparam("m"), h.c.id == sa.bindparam("i"))
            .values(next=sa.bindparam("n"), prev=sa.bindparam("pv"), polygon=sa.bindparam("f")),
        )
        upd_he.run_many(
            cur, ({"m": m, "i": i, "n": r[1], "pv": r[2], "f": r[5]} for i, r in changes["he_upd"])
        )
        upd_v = self.st.get(
            "upd_v",
            lambda: v.update()
            .where(v.c.mesh_id == sa.bindparam("m"), v.c.id == sa.bindparam("i"))
            .values(halfedge=sa.bindparam("he")),
        )
        upd_v.run_many(cur, ({"m": m, "i": i, "he": he} for i, he in changes["v_upd"]))
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
        upd_m.run(cur, {"m": m, "nv": counters[0], "ne": counters[1], "np": counters[2], "bump": bump})


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
        undo, self._undo = self._undo or [], None
        for entry in reversed(undo):
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

    def _ingest_he(self, rows: Iterable[tuple]) -> None:
        he, he0 = self._he, self._he0
        for row in rows:
            hid = row[0]
            if hid not in he:
                rec = tuple(row[1:])
                he[hid] = rec
                he0[hid] = rec

    @staticmethod
    def _ingest_pairs(current: dict, loaded: dict, rows: Iterable[tuple]) -> None:
        for eid, he in rows:
            if eid not in current:
                current[eid] = he
                loaded[eid] = he

    def load_stars(self, vertex_ids: Iterable[int]) -> None:
        """Cache the vertices and every half-edge leaving them (with twins)."""
        want = [v for v in dict.fromkeys(vertex_ids) if v not in self._out]
        if not want:
            return
        self._ingest_pairs(self._v, self._v0, self.sql.vertices(self.mesh_id, [v for v in want if v not in self._v]))
        rows = self.sql.stars(self.mesh_id, want)
        self._ingest_he(rows)
        wanted = set(want)
        outs: dict[int, set[int]] = {v: set() for v in want}
        he = self._he
        for row in rows:
            hid = row[0]
            if row[1] in wanted and he[hid] is not GONE:
                outs[row[1]].add(hid)
        self._out.update(outs)

    def load_polygons(self, polygon_ids: Iterable[int]) -> None:
        """Cache the polygons and their half-edges (as stored)."""
        want = [p for p in dict.fromkeys(polygon_ids) if p not in self._p]
        if want:
            self._ingest_pairs(self._p, self._p0, self.sql.polygons(self.mesh_id, want))
            self._ingest_he(self.sql.polygon_halfedges(self.mesh_id, want))

    def load_edges(self, edge_ids: Iterable[int]) -> None:
        """Cache the edges and their half-edges."""
        want = [e for e in dict.fromkeys(edge_ids) if e not in self._e]
        if want:
            self._ingest_pairs(self._e, self._e0, self.sql.edges(self.mesh_id, want))
            self.load_halfedges([h for e in want for h in (2 * e, 2 * e + 1)])
            for e in want:
                if e in self._e and self._e[e] is not GONE:
                    h = self._e[e]
                    self.load_halfedges([h, self.he(h)[TWIN]])

    def load_halfedges(self, ids: Iterable[int]) -> None:
        want = [h for h in dict.fromkeys(ids) if h not in self._he]
        if want:
            self._ingest_he(self.sql.halfedges(self.mesh_id, want))
            for h in want:
                self._he.setdefault(h, _ABSENT)

    def load_vertices(self, ids: Iterable[int]) -> None:
        want = [v for v in dict.fromkeys(ids) if v not in self._v]
        if want:
            self._ingest_pairs(self._v, self._v0, self.sql.vertices(self.mesh_id, want))
            for v in want:
                self._v.setdefault(v, _ABSENT)

    # -- reads -----------------------------------------------------------

    def he(self, h: int) -> tuple:
        """The record ``(origin, next, prev, twin, edge, polygon)`` of half-edge ``h``."""
        rec = self._he.get(h, None)
        if rec is None:
            self.load_halfedges([h])
            rec = self._he[h]
        if rec is GONE or rec is _ABSENT:
            raise ElementNotFoundError(f"half-edge {h} does not exist in this mesh")
        return rec

    def has_vertex(self, v: int) -> bool:
        if v not in self._v:
            self.load_vertices([v])
        rec = self._v[v]
        return rec is not GONE and rec is not _ABSENT

    def vhe(self, v: int) -> int | None:
        """The half-edge of vertex ``v`` (``None`` if isolated)."""
        if v not in self._v:
            self.load_vertices([v])
        rec = self._v[v]
        if rec is GONE or rec is _ABSENT:
            raise ElementNotFoundError(f"vertex {v} does not exist in this mesh")
        return rec

    def edge_he(self, e: int) -> int:
        if e not in self._e:
            self.load_edges([e])
        rec = self._e.get(e, _ABSENT)
        if rec is GONE or rec is _ABSENT:
            raise ElementNotFoundError(f"edge {e} does not exist in this mesh")
        return rec

    def polygon_he(self, p: int) -> int:
        if p not in self._p:
            self.load_polygons([p])
        rec = self._p.get(p, _ABSENT)
        if rec is GONE or rec is _ABSENT:
            raise ElementNotFoundError(f"polygon {p} does not exist in this mesh")
        return rec

    def outgoing(self, v: int) -> set[int]:
        """Ids of the half-edges leaving ``v`` (a set; no rotation order)."""
        if v not in self._out:
            self.vhe(v)
            self.load_stars([v])
        return self._out[v]

    def corrupt(self, code: str, message: str) -> InvariantViolationError:
        """The error to raise when stored data is found broken mid-operation."""
        from hestore.validation import Violation

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
