"""The unit of work: a mesh's rows as one write transaction sees them.

This module owns the in-memory side of editing. Topological operations
(`hestore._kernel`) never talk to SQL; they read and write through a
`UnitOfWork`, which

* loads rows in batches (a vertex's whole star in one query) through the
  loader it was given (`hestore._persistence.Persistence.load`) and keeps
  them for the rest of the transaction — valid because the transaction holds
  the mesh's write lock, so nobody else can change them;
* records every change of an operation in an undo log, so an operation that
  raises half-way (a ``makeAdjacent`` that finds no free gap on the third
  corner) leaves no trace (`UnitOfWork.operation`);
* hands over what changed since the last flush as a `ChangeSet` — a small
  typed record of inserted, updated and deleted rows per table, the id
  counters, whole tables of a bulk import, or the mesh's drop — which
  `hestore._persistence` writes when the session flushes (before a read, a
  savepoint, or the commit). Every edit reaches the database through that one
  record, so whatever must see every change plugs in there.

Half-edge records are tuples ``(origin, next, prev, twin, edge, polygon)``;
`GONE` marks a deleted element. Ids come from the mesh's counters and are
never reused: edge ``e`` owns half-edges ``2e`` and ``2e + 1``.

Two caches, two classes: `UnitOfWork` keeps the topology (the four element
tables, the stars, the id counters); the `ValueWork` it owns (``uow.values``)
keeps the property catalogue, pending values, staged set-based writes and
positions, and derives the values of elements an operator makes (`derive`).
Both write to one undo log of small typed entries, each of which knows how
to undo itself.
"""

from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, Callable, Iterable, Iterator, NamedTuple

from hestore import schema
from hestore.errors import ElementNotFoundError, InvariantViolationError, InvalidInputError, Violation
from hestore._values import Property, mean, value_of
from hestore._values import rows as value_rows

__all__ = [
    "UnitOfWork",
    "ValueWork",
    "ChangeSet",
    "RowChanges",
    "BulkRows",
    "PropertyChanges",
    "BulkValues",
    "UNSET",
    "GONE",
    "HE_COLUMNS",
    "ORIGIN",
    "NEXT",
    "PREV",
    "TWIN",
    "EDGE",
    "POLYGON",
]

ORIGIN, NEXT, PREV, TWIN, EDGE, POLYGON = range(6)

#: The ``halfedges`` columns of a loaded or inserted row, in record order after the id.
HE_COLUMNS = ("id", "origin", "next", "prev", "twin", "edge", "polygon")

#: Row kinds of `hestore._persistence.Persistence.load`'s result.
K_VERTEX, K_HALFEDGE, K_EDGE, K_POLYGON = range(4)


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
#: A property value written back to "no value" (the default).
UNSET = _Marker("UNSET")
_ABSENT = _Marker("ABSENT")


# --------------------------------------------------------------------------
# The undo log: one small entry per change, each undoing itself


class _Restore:
    """A dict entry as it was before a change (absent, or its old value)."""

    __slots__ = ("d", "key", "old")

    def __init__(self, d: dict, key: Any, old: Any) -> None:
        self.d, self.key, self.old = d, key, old

    def undo(self, uow: "UnitOfWork") -> None:
        if self.old is _ABSENT:
            self.d.pop(self.key, None)
        else:
            self.d[self.key] = self.old


class _Dirtied:
    """An element marked as changed since the last flush."""

    __slots__ = ("dirty", "key")

    def __init__(self, dirty: set, key: int) -> None:
        self.dirty, self.key = dirty, key

    def undo(self, uow: "UnitOfWork") -> None:
        self.dirty.discard(self.key)


class _Left:
    """A half-edge added to (``added``) or removed from a vertex's cached star."""

    __slots__ = ("v", "h", "added")

    def __init__(self, v: int, h: int, added: bool) -> None:
        self.v, self.h, self.added = v, h, added

    def undo(self, uow: "UnitOfWork") -> None:
        if self.added:
            uow._out[self.v].discard(self.h)
        else:
            uow._out[self.v].add(self.h)


class _Counters:
    """The id counters before a change."""

    __slots__ = ("counters",)

    def __init__(self, counters: tuple) -> None:
        self.counters = counters

    def undo(self, uow: "UnitOfWork") -> None:
        uow.next_vertex, uow.next_edge, uow.next_polygon, uow.next_property = self.counters


class _Staged:
    """What was staged for the next flush before a change: whole tables, the drop, set-based value writes."""

    __slots__ = ("bulk", "drop", "bulk_values")

    def __init__(self, uow: "UnitOfWork") -> None:
        self.bulk, self.drop, self.bulk_values = uow._bulk, uow._drop, uow.values._bulk_vals

    def undo(self, uow: "UnitOfWork") -> None:
        uow._bulk, uow._drop, uow.values._bulk_vals = self.bulk, self.drop, self.bulk_values


class RowChanges(NamedTuple):
    """The rows of one table a flush inserts, updates and deletes, each list by id.

    ``inserted`` rows are full rows (id first, in the column order
    `hestore._persistence` writes); ``updated`` rows are the id and the
    changed reference columns; ``deleted`` holds ids.
    """

    inserted: list
    updated: list
    deleted: list


class BulkRows(NamedTuple):
    """Whole tables written at once by an import: ``{table name: {column: ndarray}}``.

    ``progress(done, total)`` is called with rows written, if given.
    """

    tables: dict
    progress: Callable[[int, int], object] | None = None


class BulkValues(NamedTuple):
    """Values of one property for many elements, staged by one set-based call.

    ``columns`` are `hestore._values.columns_of`'s (rows of the elements to
    set); ``unset`` the ids whose values are removed; ``replace_all``: the
    ids are every live element of the kind, so every old row goes first.
    A position write has ``prop`` None and columns ``id, x, y, z``.
    """

    prop: Property | None
    ids: Any
    columns: dict
    unset: Any
    replace_all: bool = False


class PropertyChanges(NamedTuple):
    """What a flush writes about properties and positions.

    Applied in this order: ``removed`` properties lose their catalogue row
    and every value; ``added`` ones are inserted; ``bulk`` writes (in call
    order); then single ``values`` (``{(property id, element id): (Property,
    rows or UNSET)}``) and ``positions`` (``[(id, x, y, z)]`` of stored
    vertices); last ``purge``: the values of elements deleted in this flush,
    ``[(Property, ids)]``.
    """

    removed: list
    added: list
    bulk: list
    values: dict
    positions: list
    purge: list

    def __bool__(self) -> bool:
        return any(self)


@dataclass(frozen=True)
class ChangeSet:
    """What one flush writes for one mesh.

    Attributes
    ----------
    mesh_id : int
    vertices : RowChanges
        Inserted ``(id, halfedge, x, y, z)``; updated ``(id, halfedge)``.
    halfedges : RowChanges
        Inserted ``(id, origin, next, prev, twin, edge, polygon)``; updated
        ``(id, origin, next, prev, polygon)`` (twin and edge never change).
    edges, polygons : RowChanges
        Inserted and updated ``(id, halfedge)``.
    counters : tuple of int
        ``(next_vertex, next_edge, next_polygon, next_property)`` after the flush.
    bump : int
        What the mesh's revision grows by: 1 in the first flush of a
        transaction that changes the mesh, else 0.
    revision : int
        The revision this transaction makes: every row written carries it,
        and the row versions it supersedes go to history with it.
    history : bool
        Whether the mesh keeps history (superseded row versions are kept).
    start : tuple of int
        The counters before this flush's changes: in a revision's first
        flush, where its new elements' ids begin.
    bulk : BulkRows or None
        Whole tables of an import.
    drop : bool
        The mesh is deleted with all its rows (nothing else is written).
    properties : PropertyChanges or None
        Properties declared and removed, values and positions written.
    """

    mesh_id: int
    vertices: RowChanges
    halfedges: RowChanges
    edges: RowChanges
    polygons: RowChanges
    counters: tuple[int, int, int, int]
    bump: int
    revision: int = 1
    history: bool = True
    start: tuple[int, int, int, int] = (0, 0, 0, 0)
    bulk: BulkRows | None = None
    drop: bool = False
    properties: PropertyChanges | None = None


class UnitOfWork:
    """A write transaction's view of one mesh: cached rows, undo log, change set.

    Parameters
    ----------
    mesh_id : int
        The mesh.
    load : callable
        ``load(mesh_id, want) -> rows``: `hestore._persistence.Persistence.load`.
    counters : tuple of int
        ``(next_vertex, next_edge, next_polygon, next_property)`` as stored.
    allow_loops, allow_multi_edges : bool
        The mesh's policy.
    catalogue, has_properties, read_values, read_positions
        Handed to the value cache, `ValueWork` (``uow.values``), which says what they are.
    revision : int
        The revision the open transaction makes (the stored one plus one).
    history : bool
        Whether the mesh keeps history.
    """

    def __init__(
        self,
        mesh_id: int,
        load: Callable[[int, dict], list],
        counters: tuple,
        allow_loops: bool,
        allow_multi_edges: bool,
        catalogue: Callable[[int], list] | None = None,
        has_properties: bool = False,
        read_values: Callable[[int, list, list], dict] | None = None,
        read_positions: Callable[[int, list], dict] | None = None,
        *,
        revision: int = 1,
        history: bool = True,
    ) -> None:
        self.mesh_id = mesh_id
        self.revision = revision
        self.history = history
        self._load = load
        self.allow_loops = allow_loops
        self.allow_multi_edges = allow_multi_edges
        self.next_vertex, self.next_edge, self.next_polygon, self.next_property = counters
        self._counters0 = tuple(counters)
        # each kind's current rows and rows as in the database (NEW: not there yet)
        self._rows: dict[str, tuple[dict[int, Any], dict[int, Any]]] = {kind: ({}, {}) for kind in schema.KINDS}
        self._v, self._v0 = self._rows["vertex"]
        self._he, self._he0 = self._rows["halfedge"]
        self._e, self._e0 = self._rows["edge"]
        self._p, self._p0 = self._rows["polygon"]
        # the positions of vertices made since the last flush (written with their rows)
        self._pos: dict[int, tuple] = {}
        # vertices whose every outgoing half-edge (and its twin) is cached
        self._out: dict[int, set[int]] = {}
        self._dirty_he: set[int] = set()
        self._dirty_v: set[int] = set()
        self._dirty_e: set[int] = set()
        self._dirty_p: set[int] = set()
        self._bulk: BulkRows | None = None
        self._drop = False
        self._undo: list | None = None
        # a dry run (a ``can_*`` predicate): derived values and positions are not computed
        self._dry = False
        #: Properties, values and positions: the value cache.
        self.values = ValueWork(self, catalogue, has_properties, read_values, read_positions)

    # -- operations ------------------------------------------------------

    @contextmanager
    def operation(self, *, keep: bool = True) -> Iterator["UnitOfWork"]:
        """One atomic operation: its changes are kept, or all undone if it raises.

        With ``keep=False`` they are undone either way (a dry run: the
        ``can_*`` predicates run the operation itself and throw it away).
        """
        self._undo = []
        self._dry = not keep
        try:
            yield self
        except BaseException:
            self.rollback_to(0)
            raise
        else:
            if not keep:
                self.rollback_to(0)
        finally:
            self._undo = None
            self._dry = False

    def mark(self) -> int:
        """A point inside the current operation that `rollback_to` can return to."""
        return len(self._undo) if self._undo is not None else 0

    def rollback_to(self, mark: int) -> None:
        """Undo the current operation's changes made since ``mark``, newest first."""
        undo = self._undo or []
        while len(undo) > mark:
            undo.pop().undo(self)

    def _set(self, d: dict, key: Any, value: Any) -> None:
        if self._undo is not None:
            self._undo.append(_Restore(d, key, d.get(key, _ABSENT)))
        d[key] = value

    def _del(self, d: dict, key: Any) -> None:
        if self._undo is not None:
            self._undo.append(_Restore(d, key, d.get(key, _ABSENT)))
        d.pop(key, None)

    def _save_staged(self) -> None:
        if self._undo is not None:
            self._undo.append(_Staged(self))

    def _touch(self, dirty: set, key: int) -> None:
        # Undone with the operation too: an aborted operation must leave
        # nothing to flush, not even a no-op update that would bump the revision.
        if key not in dirty:
            dirty.add(key)
            if self._undo is not None:
                self._undo.append(_Dirtied(dirty, key))

    def _save_counters(self) -> None:
        if self._undo is not None:
            self._undo.append(_Counters(self.counters))

    @property
    def counters(self) -> tuple[int, int, int, int]:
        """``(next_vertex, next_edge, next_polygon, next_property)`` now."""
        return (self.next_vertex, self.next_edge, self.next_polygon, self.next_property)

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
        rows = self._load(self.mesh_id, want)
        he, he0 = self._he, self._he0
        by_kind = ((self._v, self._v0), None, (self._e, self._e0), (self._p, self._p0))
        outs: dict[int, set[int]] = {v: set() for v in star_ids}
        for row in rows:
            kind, i = row[0], row[1]
            if kind == K_HALFEDGE:
                if i not in he:
                    he[i] = he0[i] = row[2:]
                # The cached origin, which an operator may have changed (the
                # old and new origins' stars are cached before it does).
                rec = he[i]
                if rec is not GONE and rec[ORIGIN] in outs:
                    outs[rec[ORIGIN]].add(i)
            else:
                cur, loaded = by_kind[kind]
                if i not in cur:
                    cur[i] = loaded[i] = row[2]
        # Remember what does not exist, so it is not asked for again.
        for name, cur in (
            ("stars", self._v),
            ("vertices", self._v),
            ("halfedges", he),
            ("edges", self._e),
            ("polygons", self._p),
        ):
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

    def corrupt(self, code: str, kind: str, element: int, message: str) -> InvariantViolationError:
        """The error to raise when stored data is found broken mid-operation."""
        return InvariantViolationError([Violation(code, kind, (element,), f"{message}; run check()")])

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

    def set_origin(self, h: int, v: int) -> None:
        """Make half-edge ``h`` leave vertex ``v`` (an operator moving an edge's end)."""
        r = self.he(h)
        old = r[ORIGIN]
        if old == v:
            return
        # Both stars are cached first, so they stay complete: a star loaded
        # later would be read from the database, where h still leaves ``old``.
        self.outgoing(old)
        self.outgoing(v)
        self._set(self._he, h, (v,) + r[ORIGIN + 1 :])
        self._touch(self._dirty_he, h)
        self._out_remove(old, h)
        self._out_add(v, h)

    def set_polygon_he(self, p: int, h: int) -> None:
        """Point polygon ``p`` at half-edge ``h`` of its loop."""
        if self.polygon_he(p) != h:
            self._set(self._p, p, h)
            self._touch(self._dirty_p, p)

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
            self._undo.append(_Left(v, h, True))

    def _out_remove(self, v: int, h: int) -> None:
        self._out[v].discard(h)
        if self._undo is not None:
            self._undo.append(_Left(v, h, False))

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

    def insert_bulk(self, bulk: BulkRows, counters: tuple[int, int, int]) -> None:
        """Stage whole tables of an import for the next flush, with the counters after them.

        Only for a mesh without elements: the rows are written as given,
        not merged with the cache.
        """
        self._save_counters()
        self._save_staged()
        self._bulk = bulk
        self.next_vertex, self.next_edge, self.next_polygon = counters

    def drop(self) -> None:
        """Delete the mesh with all its rows at the next flush."""
        self._save_staged()
        self._drop = True

    # -- what the value cache asks of the topology ----------------------------

    def exists(self, kind: str, i: int) -> None:
        """Raise `ElementNotFoundError` unless element ``i`` of ``kind`` exists now."""
        found = schema.KINDS[kind]
        self._row(self._rows[kind][0], found.table.name, i, found.label)

    def made(self, kind: str, i: int) -> bool:
        """Whether element ``i`` of ``kind`` was made since the last flush (so nothing of it is stored)."""
        return self._rows[kind][1].get(i) is NEW

    def removed(self, kind: str, i: int) -> bool:
        """Whether element ``i`` of ``kind`` was deleted since the last flush."""
        return self._rows[kind][0].get(i) is GONE

    def new_position(self, v: int) -> tuple | None:
        """The position vertex ``v`` was made with (a vertex made since the last flush)."""
        return self._pos.get(v)

    # -- flushing --------------------------------------------------------

    @property
    def cached_halfedges(self) -> int:
        """How many half-edge rows are cached (a bound on any walk among them)."""
        return len(self._he)

    @property
    def dirty(self) -> bool:
        """Whether anything changed since the last flush."""
        return bool(
            self._dirty_he or self._dirty_v or self._dirty_e or self._dirty_p or self._bulk is not None or self._drop
            or self.values.dirty or self.counters != self._counters0
        )

    def changes(self, bump: int) -> ChangeSet:
        """What a flush must write now: the difference between the cache and the database.

        Parameters
        ----------
        bump : int
            What the mesh's revision grows by (see `ChangeSet.bump`).
        """
        counters = self.counters
        empty = RowChanges([], [], [])
        if self._drop:
            return ChangeSet(self.mesh_id, empty, empty, empty, empty, counters, bump, drop=True)
        he = RowChanges([], [], [])
        for h in sorted(self._dirty_he):
            cur, old = self._he[h], self._he0.get(h, NEW)
            if old is NEW:
                if cur is not GONE:
                    he.inserted.append((h,) + cur)
            elif cur is GONE:
                he.deleted.append(h)
            elif cur != old:
                he.updated.append((h, cur[ORIGIN], cur[NEXT], cur[PREV], cur[POLYGON]))
        v = RowChanges([], [], [])
        for i in sorted(self._dirty_v):
            cur, old = self._v[i], self._v0.get(i, NEW)
            if old is NEW:
                if cur is not GONE:
                    v.inserted.append((i, cur) + tuple(self._pos.get(i) or (None, None, None)))
            elif cur is GONE:
                v.deleted.append(i)
            elif cur != old:
                v.updated.append((i, cur))
        pairs = []
        for dirty, cur_d, old_d in ((self._dirty_e, self._e, self._e0), (self._dirty_p, self._p, self._p0)):
            rows = RowChanges([], [], [])
            for i in sorted(dirty):
                cur, old = cur_d[i], old_d.get(i, NEW)
                if old is NEW:
                    if cur is not GONE:
                        rows.inserted.append((i, cur))
                elif cur is GONE:
                    rows.deleted.append(i)
                elif cur != old:
                    rows.updated.append((i, cur))
            pairs.append(rows)
        deleted = {"vertex": v.deleted, "halfedge": he.deleted, "edge": pairs[0].deleted, "polygon": pairs[1].deleted}
        properties = self.values.changes(deleted)
        return ChangeSet(
            self.mesh_id, v, he, pairs[0], pairs[1], counters, bump, self.revision, self.history, self._counters0,
            self._bulk, properties=properties,
        )

    def flushed(self) -> None:
        """Record that the last `changes` are in the database: start the next diff from here."""
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
        self._bulk = None
        self.values.flushed()
        self._counters0 = self.counters


class ValueWork:
    """A write transaction's properties, values and positions of one mesh: the value cache of a `UnitOfWork`.

    It holds the property catalogue (loaded on first need), the values and
    positions set since the last flush, the set-based writes staged for it,
    and the stored positions read meanwhile; it derives the values of the
    elements an operator makes or changes (`derive`). It asks the topology
    (its ``uow``) whether elements exist or were made or removed since the
    last flush, and records its changes in the same undo log.

    Parameters
    ----------
    uow : UnitOfWork
        The topology it belongs to.
    catalogue : callable, optional
        ``catalogue(mesh_id) -> list[Property]``: the declared properties
        (`hestore._persistence.Persistence.catalogue`), loaded on first need.
    has_properties : bool
        Whether the mesh has any property as stored (if not, the catalogue
        is never loaded for the deletions of a flush).
    read_values : callable, optional
        ``read_values(mesh_id, props, ids) -> {(property id, id): rows}``:
        stored values (`hestore._persistence.Persistence.values`), read when
        an operator derives new elements' values from old ones (`derive`).
    read_positions : callable, optional
        ``read_positions(mesh_id, ids) -> {id: (x, y, z) or None}``: stored
        positions (`hestore._persistence.Persistence.positions`).
    """

    def __init__(
        self,
        uow: UnitOfWork,
        catalogue: Callable[[int], list] | None,
        has_properties: bool,
        read_values: Callable[[int, list, list], dict] | None,
        read_positions: Callable[[int, list], dict] | None,
    ) -> None:
        self._uow = uow
        self._load_catalogue = catalogue
        self._read_values = read_values
        self._read_positions = read_positions
        # the catalogue by (kind, name) once loaded; what changed since the last flush
        self._props: dict[tuple[str, str], Property] | None = None if has_properties else {}
        self._added: dict[int, Property] = {}
        self._removed: dict[int, Property] = {}
        self._vals: dict[tuple[int, int], tuple] = {}
        self._bulk_vals: list[BulkValues] = []
        self._pos_set: dict[int, tuple | None] = {}
        # stored positions read since the last flush (the writer lock keeps them valid until it)
        self._xyz: dict[int, tuple | None] = {}

    def catalogue(self) -> dict[tuple[str, str], Property]:
        """The mesh's properties by ``(kind, name)``, as this transaction sees them."""
        if self._props is None:
            self._props = {(p.kind, p.name): p for p in self._load_catalogue(self._uow.mesh_id)}
        return self._props

    def add_property(self, prop: Property) -> Property:
        """Declare ``prop`` (its id is allocated here); return it with its id."""
        uow = self._uow
        catalogue = self.catalogue()
        if (prop.kind, prop.name) in catalogue:
            raise InvalidInputError(f"mesh already has a {prop.kind} property named {prop.name!r}")
        uow._save_counters()
        prop = Property(prop.kind, prop.name, prop.dtype, prop.shape, prop.default, uow.next_property)
        uow.next_property += 1
        uow._set(catalogue, (prop.kind, prop.name), prop)
        uow._set(self._added, prop.id, prop)
        return prop

    def remove_property(self, prop: Property) -> None:
        """Remove a declared property with all its values."""
        uow = self._uow
        uow._del(self.catalogue(), (prop.kind, prop.name))
        if prop.id in self._added:
            uow._del(self._added, prop.id)
        else:
            uow._set(self._removed, prop.id, prop)
        for key in [key for key in self._vals if key[0] == prop.id]:
            uow._del(self._vals, key)
        uow._save_staged()
        self._bulk_vals = [b for b in self._bulk_vals if b.prop is None or b.prop.id != prop.id]

    def set_value(self, prop: Property, i: int, value_rows: list | _Marker) -> None:
        """Set element ``i``'s value of ``prop`` to these rows (`hestore._values.rows`), or `UNSET`."""
        self._uow.exists(prop.kind, i)
        self._uow._set(self._vals, (prop.id, i), (prop, value_rows))

    def set_position(self, v: int, xyz: tuple | None) -> None:
        """Move vertex ``v`` (None: no position)."""
        self._uow.vhe(v)
        # An update written after the flush's inserts and bulk writes, so the
        # last call wins; a vertex new in this flush is inserted, then moved.
        self._uow._set(self._pos_set, v, xyz)

    def stage(self, bulk: BulkValues) -> None:
        """Stage a set-based write of values (or positions) for the next flush.

        The caller has checked that every id exists. Single writes staged
        earlier to the same elements are dropped: the bulk write replaces them.
        """
        uow = self._uow
        if bulk.prop is None:
            pending, key_of = self._pos_set, lambda key: key
        else:
            pid = bulk.prop.id
            pending, key_of = self._vals, lambda key: key[1] if key[0] == pid else None
        if pending:
            ids = set(bulk.ids.tolist())
            for key in [key for key in pending if key_of(key) in ids]:
                uow._del(pending, key)
        uow._save_staged()
        self._bulk_vals = self._bulk_vals + [bulk]

    @property
    def staged(self) -> bool:
        """Whether set-based writes are staged for the next flush."""
        return bool(self._bulk_vals)

    def positions(self, ids: Iterable[int]) -> dict[int, tuple | None]:
        """The positions of these vertices as this transaction sees them."""
        uow = self._uow
        out: dict[int, tuple | None] = {}
        stored = []
        for v in dict.fromkeys(ids):
            if v in self._pos_set:
                out[v] = self._pos_set[v]
            elif uow.made("vertex", v):
                out[v] = uow.new_position(v)
            elif v in self._xyz:
                out[v] = self._xyz[v]
            else:
                stored.append(v)
        if stored:
            found = self._read_positions(uow.mesh_id, stored)
            self._xyz.update(found)
            out.update(found)
        return out

    def mean_position(self, ids: Iterable[int]) -> tuple | None:
        """The mean position of these vertices (one per entry), or None if one has none.

        Not computed in a dry run, which only asks whether an operator would succeed.
        """
        ids = list(ids)
        if self._uow._dry or not ids:
            return None
        found = self.positions(ids)
        xyz = [found.get(v) for v in ids]
        if any(p is None or None in p for p in xyz):
            return None
        return tuple(mean([p[k] for p in xyz]) for k in range(3))

    def _values(self, props: list[Property], ids: set[int]) -> dict:
        """``{(property id, id): value or None}`` as this transaction sees them."""
        uow = self._uow
        kind = props[0].kind
        out: dict = {}
        stored = [i for i in ids if not uow.made(kind, i)]  # one made since the last flush has nothing stored
        found: dict = {}
        if stored:
            fresh = [p for p in props if p.id not in self._added]
            if fresh:
                found = self._read_values(uow.mesh_id, fresh, stored)
        for prop in props:
            for i in ids:
                pending = self._vals.get((prop.id, i))
                if pending is not None:
                    rows = pending[1]
                    out[prop.id, i] = prop.default if rows is UNSET else value_of(prop, rows)
                else:
                    out[prop.id, i] = value_of(prop, found.get((prop.id, i), []))
        return out

    def derive(self, kind: str, plan: Iterable[tuple]) -> None:
        """Give elements an operator made or changed their values, from elements they came from.

        ``plan`` holds ``(target, how, sources)``; every source is read as it
        was before this call. ``how`` is ``"copy"`` (the first source's
        value), ``"mean"`` (the mean of the sources for ``float64``, the first
        source's otherwise: a new vertex) or ``"corner"`` (the mean for
        ``float64``, the default otherwise: a new corner). A mean is taken
        only where every source has a value. This is the one place where
        operators meet properties (SPEC §3.1): they say where an element
        came from, the unit of work carries its values.
        """
        uow = self._uow
        if uow._dry:
            return
        catalogue = self.catalogue()
        props = [p for p in catalogue.values() if p.kind == kind] if catalogue else []
        if not props:
            return
        plan = list(plan)
        values = self._values(props, {s for _, _, sources in plan for s in sources})
        for target, how, sources in plan:
            for prop in props:
                found = [values[prop.id, s] for s in sources]
                if how == "copy" or (prop.dtype != "float64" and how == "mean"):
                    value = found[0]
                elif prop.dtype != "float64":
                    value = None
                elif any(x is None for x in found):
                    value = None
                elif prop.shape:
                    value = tuple(mean([x[k] for x in found]) for k in range(prop.shape[0]))
                else:
                    value = mean(found)
                if value is None:
                    if uow.made(kind, target) and (prop.id, target) not in self._vals:
                        continue  # nothing stored, nothing to remove
                    uow._set(self._vals, (prop.id, target), (prop, UNSET))
                else:
                    uow._set(self._vals, (prop.id, target), (prop, value_rows(prop, value)))

    @property
    def dirty(self) -> bool:
        """Whether a property, value or position changed since the last flush."""
        return bool(self._added or self._removed or self._vals or self._bulk_vals or self._pos_set)

    def changes(self, deleted: dict[str, list]) -> PropertyChanges | None:
        """What a flush writes of properties and positions; ``deleted`` ids by kind lose their values."""
        uow = self._uow
        purge = []
        if any(deleted.values()) and (self._props is None or self._props):
            for prop in self.catalogue().values():
                if deleted[prop.kind]:
                    purge.append((prop, deleted[prop.kind]))
        positions = [
            (v, *(xyz or (None, None, None)))
            for v, xyz in sorted(self._pos_set.items()) if not uow.removed("vertex", v)
        ]
        # Values of elements made and removed since the last flush are never written.
        values = {key: val for key, val in self._vals.items() if not uow.removed(val[0].kind, key[1])}
        changes = PropertyChanges(
            list(self._removed.values()), list(self._added.values()), list(self._bulk_vals),
            values, positions, purge,
        )
        return changes if changes else None

    def flushed(self) -> None:
        """Record that the last `changes` are in the database."""
        self._xyz.clear()
        self._added, self._removed, self._vals, self._pos_set = {}, {}, {}, {}
        self._bulk_vals = []
