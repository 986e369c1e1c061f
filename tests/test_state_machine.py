"""A hypothesis state machine: random edit sequences on a real stored mesh.

`MeshMachine` applies random operations — add_vertex, add_edge (self-loops
and parallel edges included), add_polygon by vertices (1–5 corners,
duplicates allowed, so many are refused) and by half-edges (a free loop
followed with ``next``, a random chain of free half-edges, sometimes
truncated, shuffled or with a taken half-edge mixed in), remove_polygon,
remove_edge, remove_vertex, operations on stale handles, and opening,
committing and rolling back (nested) transaction blocks — to a mesh in a real
database, and the same operations' known effects to a plain in-memory model:

* ``vertices``: ids; ``edges``: id -> (a, b, a→b half-edge, b→a half-edge);
  ``halfedges``: id -> (origin, target, edge); ``face``: half-edge -> polygon
  or None; ``polygons``: id -> half-edges in ``next`` order.
* properties, declared when the mesh is made (``PROPS``): ``values``: property
  name -> {id: value} of the elements that have one set (the others read the
  default, or are masked where there is none); ``positions``: vertex id ->
  (x, y, z) or None. Values are written one at a time (``handle[name] = x``,
  ``del handle[name]``) and set-based (`set_property_array` on random subsets
  of the live ids, some entries masked to unset them); positions with
  `set_position` and `set_positions`.
* add_edge adds an edge; add_polygon by vertices uses a free a→b half-edge
  between consecutive corners where an edge joins them and creates an edge
  exactly where none does (at that point of the loop: after a new edge a→b,
  the pair b→a finds its free twin); remove_edge removes the polygons on both
  sides; remove_vertex removes every incident edge with its polygons; a
  refused operation changes nothing; rolling a block back restores the model
  (values and positions included) as it was when the block began. Removed
  elements take their values with them, except that half-edges (and their
  corner values) outlive `remove_polygon`.

After every step: ``mesh.check() == []``; the stored rows of the mesh equal the
model (vertices, edges, every half-edge's origin, twin, edge and polygon);
counts match; every polygon's half-edge and vertex cycles equal the model's
(up to rotation); every edge's end points are the model's; `property_array` of
every property and every vertex's stored position equal the model's; the revision is the
number of committed transactions that changed the mesh (plus one while an open
block has changed it). When an operation raises, a dump of every row of every
table is identical to the one before it. For every add_polygon,
`can_add_polygon` is asked first and must agree with the outcome, and with an
independent oracle (`Model.can_close`, seed 000's "if and only if" rule on the
fans around each vertex) wherever the model knows which half-edges the loop
uses. New ids are never ids handed out before in the committed history (a
rolled-back block's ids may come again: those elements never existed).

`test_rotation_oracle_examples` compares the oracle with the kernel
exhaustively (every closed chain of up to four free half-edges) on a few
small meshes with self-loops, fans and digons.

A failure is reported without shrinking (replaying against a database is
slow); set ``HESTORE_SHRINK=1`` for a minimal failing sequence.
"""

from __future__ import annotations

import copy
import itertools
import math
import os

import numpy as np
import pytest
import sqlalchemy as sa
from hypothesis import HealthCheck, Phase, event, settings
from hypothesis import strategies as st
from hypothesis.stateful import (
    RuleBasedStateMachine,
    initialize,
    invariant,
    precondition,
    rule,
    run_state_machine_as_test,
)

import hestore
from hestore import Edge, HalfEdge, Polygon, Vertex
from hestore.errors import (
    ElementNotFoundError,
    HalfEdgeNotFreeError,
    InvalidInputError,
    NonManifoldError,
    NotAChainError,
    PolicyError,
    VertexNotFreeError,
)
from hestore.schema import VALUE_TABLES

from helpers import dump

MAX_VERTICES = 12
MAX_DEPTH = 3

# Positions of the columns in `helpers.dump` rows (table column order).
HE_ID, HE_ORIGIN, HE_NEXT, HE_PREV, HE_TWIN, HE_EDGE, HE_POLYGON = range(1, 8)


#: The properties every machine's mesh declares: (kind, name, dtype, shape, default).
PROPS = [
    ("vertex", "t", "float64", (), 0.0),
    ("halfedge", "uv", "float64", (2,), None),
    ("edge", "w", "int64", (), 0),
    ("polygon", "label", "str", (), ""),
]
PROP_KIND = {name: kind for kind, name, _d, _s, _x in PROPS}
PROP_DEFAULT = {name: default for _k, name, _d, _s, default in PROPS}
_FLOATS = st.floats(allow_nan=True, allow_infinity=True, width=64)
PROP_VALUES = {
    "t": _FLOATS,
    "uv": st.tuples(_FLOATS, _FLOATS),
    "w": st.integers(-(2**63), 2**63 - 1) | st.integers(-3, 3),
    "label": st.text(st.characters(exclude_categories=("Cs",), exclude_characters="\x00"), max_size=8),
}
POSITIONS = st.tuples(*[st.floats(allow_nan=False, allow_infinity=False, width=64)] * 3)


def same(a, b) -> bool:
    """Equal values, NaN equal to NaN (tuples compared item by item)."""
    if isinstance(a, tuple) and isinstance(b, tuple):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return a == b and type(a) is type(b)


def python_values(array) -> list:
    """An array from `property_array` as Python values: tuples for shaped ones, None where masked."""
    out = []
    for x in array.tolist():
        if isinstance(x, list):
            x = None if all(c is None for c in x) else tuple(x)
        out.append(x)
    return out


class Rollback(Exception):
    """Raised into a block to roll it back."""


def rotations_equal(a, b) -> bool:
    a, b = list(a), list(b)
    return len(a) == len(b) and (not a or any(a[i:] + a[:i] == b for i in range(len(a))))


class Model:
    """What the mesh must contain, by id."""

    def __init__(self) -> None:
        self.vertices: set[int] = set()
        self.edges: dict[int, tuple[int, int, int, int]] = {}
        self.halfedges: dict[int, tuple[int, int, int]] = {}
        self.face: dict[int, int | None] = {}
        self.polygons: dict[int, list[int]] = {}
        # ids handed out in the history that leads here (committed, or in the open blocks)
        self.used = {"vertex": set(), "edge": set(), "halfedge": set(), "polygon": set()}
        # ids of elements removed in that history: their handles are stale
        self.removed = {"vertex": set(), "edge": set(), "halfedge": set(), "polygon": set()}
        # property values set (id -> value; unset: absent) and vertex positions
        self.values: dict[str, dict[int, object]] = {name: {} for _k, name, _d, _s, _x in PROPS}
        self.positions: dict[int, tuple | None] = {}

    # -- queries ------------------------------------------------------------

    def outgoing(self, v: int) -> list[int]:
        return sorted(h for h, (o, _t, _e) in self.halfedges.items() if o == v)

    def is_free(self, v: int) -> bool:
        out = self.outgoing(v)
        return not out or any(self.face[h] is None for h in out)

    def free_halfedges(self) -> list[int]:
        return sorted(h for h, p in self.face.items() if p is None)

    def joined(self, a: int, b: int) -> bool:
        return any(frozenset((x, y)) == frozenset((a, b)) for x, y, _h, _t in self.edges.values())

    def between(self, a: int, b: int) -> list[int]:
        """Half-edges a→b."""
        return sorted(h for h, (o, t, _e) in self.halfedges.items() if o == a and t == b)

    def live(self, kind: str) -> list[int]:
        """The ids of the live elements of a kind, in id order."""
        found = {"vertex": self.vertices, "halfedge": self.halfedges, "edge": self.edges, "polygon": self.polygons}
        return sorted(found[kind])

    def expected_values(self, name: str) -> list:
        """What `property_array(kind, name)` must hold, as Python values (None: masked)."""
        have = self.values[name]
        return [have.get(i, PROP_DEFAULT[name]) for i in self.live(PROP_KIND[name])]

    def cycle_vertices(self, p: int) -> list[int]:
        return [self.halfedges[h][0] for h in self.polygons[p]]

    def can_close(self, loop, new_edges=()) -> bool:
        """Whether free, chaining, distinct half-edges ``loop`` can bound a polygon.

        An independent oracle for seed 000's rule: "a half-edge loop can be
        turned into a polygon if and only if every half-edge in the loop is
        free and the loop can be made properly oriented by reordering the
        connectivity around the vertices of the loop". Around a vertex, each
        polygon corner (``next(i) == o``) fixes one step of the rotation,
        ``twin(i) → o``; free gaps can be reordered at will. With the new
        polygon's corners added, the fixed steps around every vertex of the
        loop must still fit into one rotation cycle: either they form no
        cycle (fans separated by free gaps), or one cycle through every
        outgoing half-edge (a closed vertex). ``new_edges`` are edges the call
        would create first, as ``(a, b, h, t)`` with placeholder half-edge ids.
        """
        twin, origin = {}, {}
        for a, b, h, t in list(self.edges.values()) + list(new_edges):
            twin[h], twin[t], origin[h], origin[t] = t, h, a, b
        succ = {}
        for cycle in list(self.polygons.values()) + [list(loop)]:
            for i, h in enumerate(cycle):
                succ[twin[h]] = cycle[(i + 1) % len(cycle)]
        for v in {origin[h] for h in loop}:
            nodes = [h for h, o in origin.items() if o == v]
            on_cycle = []
            for x in nodes:
                y, steps = succ.get(x), 0
                while y is not None and y != x and steps <= len(nodes):
                    y, steps = succ.get(y), steps + 1
                if y == x:
                    on_cycle.append(x)
            if on_cycle:
                x, length = succ[on_cycle[0]], 1
                while x != on_cycle[0]:
                    x, length = succ[x], length + 1
                if length != len(nodes):
                    return False
        return True

    # -- effects -------------------------------------------------------------

    def fresh(self, kind: str, i: int) -> None:
        assert i not in self.used[kind], f"{kind} id {i} handed out again (ids are never reused)"
        self.used[kind].add(i)

    def add_vertex(self, v: int, position=None) -> None:
        self.fresh("vertex", v)
        self.vertices.add(v)
        self.positions[v] = None if position is None else tuple(float(c) for c in position)

    def add_edge(self, e: int, a: int, b: int, h: int, t: int) -> None:
        self.fresh("edge", e)
        self.fresh("halfedge", h)
        self.fresh("halfedge", t)
        self.edges[e] = (a, b, h, t)
        self.halfedges[h] = (a, b, e)
        self.halfedges[t] = (b, a, e)
        self.face[h] = self.face[t] = None

    def add_polygon(self, p: int, loop: list[int]) -> None:
        self.fresh("polygon", p)
        for h in loop:
            assert self.face[h] is None
            self.face[h] = p
        self.polygons[p] = list(loop)

    def remove_polygon(self, p: int) -> None:
        for h in self.polygons.pop(p):
            self.face[h] = None  # half-edges stay, with their (corner) values
        self.values["label"].pop(p, None)
        self.removed["polygon"].add(p)

    def remove_edge(self, e: int) -> None:
        _a, _b, h, t = self.edges[e]
        for p in {self.face[h], self.face[t]} - {None}:
            self.remove_polygon(p)
        del self.edges[e]
        for x in (h, t):
            del self.halfedges[x]
            del self.face[x]
            self.values["uv"].pop(x, None)
            self.removed["halfedge"].add(x)
        self.values["w"].pop(e, None)
        self.removed["edge"].add(e)

    def remove_vertex(self, v: int) -> None:
        for e in sorted({self.halfedges[h][2] for h in self.outgoing(v)}):
            self.remove_edge(e)
        self.vertices.remove(v)
        self.values["t"].pop(v, None)
        del self.positions[v]
        self.removed["vertex"].add(v)


class Frame:
    """An open block: the model as it began, and whether it changed the mesh."""

    def __init__(self, cm, snapshot: Model) -> None:
        self.cm = cm
        self.snapshot = snapshot
        self.changed = False


class MeshMachine(RuleBasedStateMachine):
    """Set ``url`` on a subclass; each example gets its own store and mesh."""

    url: str = ""
    counter = itertools.count()

    def __init__(self) -> None:
        super().__init__()
        self.store = None
        self.mesh = None
        self.model = Model()
        self.stack: list[Frame] = []
        self.committed_revision = 0
        self.committed_dump = None
        self.last_dump = None
        self.prop_ids: dict[str, int] = {}
        self.verified: dict[str, tuple] = {}  # property name -> what it was last checked against

    # -- set-up and tear-down -------------------------------------------------

    @initialize(loops=st.booleans(), multi=st.booleans(), strict=st.integers(0, 3), start=st.integers(0, 6))
    def make_mesh(self, loops, multi, strict, start):
        # mostly permissive meshes, sometimes ones that forbid loops / parallel edges
        self.allow_loops = loops or strict > 0
        self.allow_multi = multi or strict > 0
        self.store = hestore.open(self.url)
        self.name = f"sm{next(self.counter)}"
        self.mesh = self.store.create_mesh(self.name, allow_loops=self.allow_loops,
                                           allow_multi_edges=self.allow_multi)
        with self.store.transaction():  # one transaction: revision 1
            for kind, name, dtype, shape, default in PROPS:
                self.prop_ids[name] = self.mesh.add_property(kind, name, dtype, shape=shape, default=default).id
            for _ in range(start):
                self.model.add_vertex(self.mesh.add_vertex().id)
        self.committed_revision = 1
        self.last_dump = self.committed_dump = dump(self.store)

    def teardown(self):
        if self.store is None:
            return
        try:
            while self.stack:
                frame = self.stack.pop()
                try:
                    frame.cm.__exit__(Rollback, Rollback(), None)
                except Exception:
                    pass
            try:
                self.store.delete_mesh(self.name)
            except Exception:
                pass
        finally:
            self.store.close()

    # -- helpers ----------------------------------------------------------------

    def V(self, i):
        return Vertex(self.mesh, i)

    def E(self, i):
        return Edge(self.mesh, i)

    def H(self, i):
        return HalfEdge(self.mesh, i)

    def P(self, i):
        return Polygon(self.mesh, i)

    @property
    def expected_revision(self) -> int:
        return self.committed_revision + (1 if any(f.changed for f in self.stack) else 0)

    def changed(self) -> None:
        """A mutating call succeeded."""
        if self.stack:
            self.stack[-1].changed = True
        else:
            self.committed_revision += 1

    def refused(self, call, errors):
        """``call()`` must raise one of ``errors`` and change nothing at all."""
        before = self.last_dump
        with pytest.raises(errors) as info:
            call()
        event(f"refused: {type(info.value).__name__}")
        assert dump(self.store) == before, f"refused call ({info.value!r}) changed the database"
        assert self.mesh.revision == self.expected_revision
        return info.value

    def new_ids(self, table: str, known) -> list[int]:
        rows = dump(self.store)[table]
        return sorted(r[1] for r in rows if r[0] == self.mesh.id and r[1] not in known)

    # -- blocks -----------------------------------------------------------------

    @precondition(lambda self: len(self.stack) < MAX_DEPTH)
    @rule()
    def begin_block(self):
        self._begin_block()

    @precondition(lambda self: len(self.stack) < MAX_DEPTH)
    @rule()
    def begin_block_again(self):
        self._begin_block()

    def _begin_block(self):
        cm = self.store.transaction()
        cm.__enter__()
        self.stack.append(Frame(cm, copy.deepcopy(self.model)))
        assert self.store.in_transaction

    @precondition(lambda self: self.stack)
    @rule()
    def commit_block(self):
        frame = self.stack.pop()
        frame.cm.__exit__(None, None, None)
        if self.stack:
            self.stack[-1].changed |= frame.changed
        else:
            if frame.changed:
                self.committed_revision += 1
            assert not self.store.in_transaction

    @precondition(lambda self: self.stack)
    @rule()
    def rollback_block(self):
        frame = self.stack.pop()
        event(f"rollback at depth {len(self.stack) + 1}")
        suppressed = frame.cm.__exit__(Rollback, Rollback(), None)
        assert not suppressed
        self.model = frame.snapshot

    # -- adding -----------------------------------------------------------------

    @precondition(lambda self: len(self.model.vertices) < MAX_VERTICES)
    @rule(position=st.none() | st.tuples(*[st.floats(-1e3, 1e3, allow_nan=False)] * 3))
    def add_vertex(self, position):
        v = self.mesh.add_vertex(position)
        self.model.add_vertex(v.id, position)
        self.changed()
        assert v.is_isolated
        if position is not None:
            assert v.position == tuple(float(c) for c in position)

    @precondition(lambda self: self.model.vertices)
    @rule(data=st.data())
    def add_edge(self, data):
        self._add_edge(data)

    @precondition(lambda self: self.model.vertices)
    @rule(data=st.data())
    def add_edge_again(self, data):  # (a second rule doubles how often edges are added)
        self._add_edge(data)

    def _add_edge(self, data):
        m = self.model
        vs = sorted(m.vertices)
        a = data.draw(st.sampled_from(vs), label="a")
        b = data.draw(st.sampled_from(vs) | st.just(a), label="b")
        errors = []
        if a == b and not self.allow_loops:
            errors.append(PolicyError)
        if not self.allow_multi and m.joined(a, b):
            errors.append(PolicyError)
        if not m.is_free(a) or not m.is_free(b):
            errors.append(VertexNotFreeError)
        if errors:
            self.refused(lambda: self.mesh.add_edge(self.V(a), self.V(b)), tuple(errors))
            return
        e = self.mesh.add_edge(self.V(a), self.V(b))
        h, t = e.halfedges()
        assert e.vertices() == (self.V(a), self.V(b))
        assert (h.origin.id, h.target.id, t.origin.id) == (a, b, b)
        m.add_edge(e.id, a, b, h.id, t.id)
        self.changed()

    def _predict_from_vertices(self, corners):
        """What add_polygon(corners) must do, from the model alone.

        Returns ``(error, new_pairs, loop, new_edges)``: the error the first
        impossible pair of corners must raise (or None); the unordered vertex
        pairs of the edges the call creates; the half-edges the polygon must
        use (placeholders for new edges' ones) or None where there is a choice
        between parallel free half-edges, which SPEC leaves open; the new
        edges as ``(a, b, h, t)``.
        """
        m = self.model
        n = len(corners)
        available = {}  # ordered pair -> free half-edges a→b not yet used by this loop
        joined_now = {frozenset((x, y)) for x, y, _h, _t in m.edges.values()}
        new_pairs, new_edges, loop = [], [], []
        ambiguous = False
        for i, a in enumerate(corners):
            b = corners[(i + 1) % n]
            for key in ((a, b), (b, a)):
                if key not in available:
                    available[key] = [h for h in m.between(*key) if m.face[h] is None]
            if frozenset((a, b)) in joined_now:
                free = [h for h in available[(a, b)] if h not in loop]
                if not free:
                    return HalfEdgeNotFreeError, new_pairs, None, new_edges
                ambiguous |= len(free) > 1
                loop.append(free[0])
                continue
            if a == b and not self.allow_loops:
                return PolicyError, new_pairs, None, new_edges
            if not m.is_free(a) or not m.is_free(b):
                return VertexNotFreeError, new_pairs, None, new_edges
            # a new edge a→b: its a→b half-edge is used now, its b→a twin is free for later
            k = len(new_edges)
            h, t = ("new", k, 0), ("new", k, 1)
            new_edges.append((a, b, h, t))
            joined_now.add(frozenset((a, b)))
            new_pairs.append(tuple(sorted((a, b))))
            available[(b, a)].append(t)
            if a == b:
                available[(a, b)] = available[(b, a)]
            loop.append(h)
        return None, new_pairs, (None if ambiguous else loop), new_edges

    @precondition(lambda self: self.model.vertices)
    @rule(data=st.data())
    def add_polygon_by_vertices(self, data):
        # 1-5 corners, duplicates allowed: many are refused
        vs = sorted(self.model.vertices)
        self._add_polygon_by_vertices(data, st.lists(st.sampled_from(vs), min_size=1, max_size=5))

    @precondition(lambda self: self.model.vertices)
    @rule(data=st.data())
    def add_polygon_by_distinct_vertices(self, data):
        # 2-4 different corners: more of these succeed
        vs = sorted(self.model.vertices)
        self._add_polygon_by_vertices(data, st.lists(st.sampled_from(vs), min_size=min(2, len(vs)),
                                                     max_size=4, unique=True))

    @precondition(lambda self: self.model.vertices)
    @rule(data=st.data())
    def add_polygon_by_distinct_vertices_again(self, data):
        vs = sorted(self.model.vertices)
        self._add_polygon_by_vertices(data, st.lists(st.sampled_from(vs), min_size=min(3, len(vs)),
                                                     max_size=3, unique=True))

    def _add_polygon_by_vertices(self, data, corner_lists):
        m = self.model
        corners = data.draw(corner_lists, label="corners")
        handles = [self.V(v) for v in corners]
        error, new_pairs, predicted, new_edges = self._predict_from_vertices(corners)
        can = self.mesh.can_add_polygon(handles)
        assert dump(self.store) == self.last_dump, "can_add_polygon changed the database"
        if error is not None:
            assert can is False, f"can_add_polygon said yes, expected {error.__name__}"
            self.refused(lambda: self.mesh.add_polygon(handles), error)
            return
        if predicted is not None:
            expected = m.can_close(predicted, new_edges)
            assert can == expected, (
                f"can_add_polygon({corners}) is {can}, but the loop {predicted} "
                f"{'can' if expected else 'cannot'} be made a polygon by reordering around its vertices"
            )
        if not can:
            self.refused(lambda: self.mesh.add_polygon(handles), NonManifoldError)
            return
        known_edges = set(m.edges)
        p = self.mesh.add_polygon(handles)
        self.changed()
        event(f"add_polygon by {len(corners)} vertices")
        # the new edges: exactly the predicted ones
        new_ids = self.new_ids("edges", known_edges)
        assert sorted(new_pairs) == sorted(tuple(sorted(v.id for v in self.E(e).vertices())) for e in new_ids)
        for e in new_ids:
            h, t = self.E(e).halfedges()
            m.add_edge(e, h.origin.id, h.target.id, h.id, t.id)
        loop = [h.id for h in p.halfedges()]
        assert len(loop) == len(corners)
        assert rotations_equal([m.halfedges[h][0] for h in loop], corners)
        for h in loop:
            assert m.face[h] is None, f"half-edge {h} used by the new polygon was not free"
        if predicted is not None:
            new_halfedges = {x for e in new_ids for x in m.edges[e][2:]}
            def matches(rotated):
                pairs = zip(predicted, rotated)
                return all(q == g if not isinstance(q, tuple) else g in new_halfedges for q, g in pairs)

            assert any(matches(loop[r:] + loop[:r]) for r in range(len(loop))), (
                f"polygon uses half-edges {loop}, expected {predicted}"
            )
        m.add_polygon(p.id, loop)

    def _free_next_loop(self, start: int) -> list[int]:
        loop = [start]
        h = self.H(start).next.id
        while h != start:
            loop.append(h)
            assert len(loop) <= len(self.model.halfedges), "the next loop of a free half-edge does not close"
            h = self.H(h).next.id
        return loop

    @precondition(lambda self: self.model.free_halfedges())
    @rule(data=st.data(), how=st.sampled_from(["loop", "rotated", "truncated", "shuffled", "chain",
                                               "with_taken", "duplicate"]))
    def add_polygon_by_halfedges(self, data, how):
        self._add_polygon_by_halfedges(data, how)

    @precondition(lambda self: self.model.free_halfedges())
    @rule(data=st.data(), how=st.sampled_from(["loop", "chain"]))
    def add_polygon_by_halfedges_again(self, data, how):
        self._add_polygon_by_halfedges(data, how)

    def _add_polygon_by_halfedges(self, data, how):
        m = self.model
        free = m.free_halfedges()
        start = data.draw(st.sampled_from(free), label="start")
        must_succeed = False
        if how in ("loop", "rotated", "truncated", "shuffled", "duplicate"):
            loop = self._free_next_loop(start)
            assert all(m.face[h] is None for h in loop), "next of a free half-edge is not free"
            if how in ("loop", "rotated"):
                k = data.draw(st.integers(0, len(loop) - 1), label="rotation") if how == "rotated" else 0
                loop = loop[k:] + loop[:k]
                must_succeed = True
            elif how == "truncated" and len(loop) > 1:
                loop = loop[: data.draw(st.integers(1, len(loop) - 1), label="keep")]
            elif how == "shuffled":
                loop = data.draw(st.permutations(loop), label="order")
            elif how == "duplicate":
                loop = loop + [loop[data.draw(st.integers(0, len(loop) - 1), label="dup")]]
        else:
            # a random walk along free half-edges, hoping to come back to the start
            # (sometimes going on through it, so that the loop passes a vertex twice)
            loop = [start]
            for _ in range(5):
                here = m.halfedges[loop[-1]][1]
                if here == m.halfedges[start][0] and data.draw(st.integers(0, 3), label="stop") > 0:
                    break
                options = [h for h in m.outgoing(here) if m.face[h] is None and h not in loop]
                if not options:
                    break
                loop.append(data.draw(st.sampled_from(options), label="step"))
            if how == "with_taken":
                taken = sorted(h for h, p in m.face.items() if p is not None)
                if taken:
                    loop[data.draw(st.integers(0, len(loop) - 1), label="at")] = data.draw(
                        st.sampled_from(taken), label="taken")
        handles = [self.H(h) for h in loop]
        if len(set(loop)) != len(loop):
            # malformed input: raises from both, changes nothing
            self.refused(lambda: self.mesh.can_add_polygon(handles), InvalidInputError)
            self.refused(lambda: self.mesh.add_polygon(handles), InvalidInputError)
            return
        chains = all(m.halfedges[h][1] == m.halfedges[loop[(i + 1) % len(loop)]][0] for i, h in enumerate(loop))
        all_free = all(m.face[h] is None for h in loop)
        errors = ([] if chains else [NotAChainError]) + ([] if all_free else [HalfEdgeNotFreeError])
        can = self.mesh.can_add_polygon(handles)
        assert dump(self.store) == self.last_dump, "can_add_polygon changed the database"
        if errors:
            assert can is False
            self.refused(lambda: self.mesh.add_polygon(handles), tuple(errors))
            return
        if must_succeed:
            assert can is True, f"a whole free loop {loop} (following next) must be accepted"
        expected = m.can_close(loop)
        assert can == expected, (
            f"can_add_polygon({loop}) is {can}, but the loop {'can' if expected else 'cannot'} "
            f"be made a polygon by reordering around its vertices"
        )
        if not can:
            self.refused(lambda: self.mesh.add_polygon(handles), NonManifoldError)
            return
        p = self.mesh.add_polygon(handles)
        self.changed()
        event(f"add_polygon by half-edges ({how})")
        got = [h.id for h in p.halfedges()]
        assert rotations_equal(got, loop)
        m.add_polygon(p.id, got)

    # -- removing ---------------------------------------------------------------

    @precondition(lambda self: self.model.polygons)
    @rule(data=st.data())
    def remove_polygon(self, data):
        p = data.draw(st.sampled_from(sorted(self.model.polygons)), label="polygon")
        self.mesh.remove_polygon(self.P(p))
        self.model.remove_polygon(p)
        self.changed()

    @precondition(lambda self: self.model.edges)
    @rule(data=st.data())
    def remove_edge(self, data):
        e = data.draw(st.sampled_from(sorted(self.model.edges)), label="edge")
        self.mesh.remove_edge(self.E(e))
        self.model.remove_edge(e)
        self.changed()

    @precondition(lambda self: self.model.vertices)
    @rule(data=st.data())
    def remove_vertex(self, data):
        v = data.draw(st.sampled_from(sorted(self.model.vertices)), label="vertex")
        self.mesh.remove_vertex(self.V(v))
        self.model.remove_vertex(v)
        self.changed()

    # -- properties and positions -------------------------------------------------

    def _handle(self, kind: str, i: int):
        return {"vertex": self.V, "halfedge": self.H, "edge": self.E, "polygon": self.P}[kind](i)

    @rule(data=st.data(), name=st.sampled_from([name for _k, name, _d, _s, _x in PROPS]))
    def set_value(self, data, name):
        self._set_value(data, name)

    @rule(data=st.data(), name=st.sampled_from([name for _k, name, _d, _s, _x in PROPS]))
    def set_value_again(self, data, name):  # (a second rule doubles how often values are written)
        self._set_value(data, name)

    def _set_value(self, data, name):
        kind = PROP_KIND[name]
        live = self.model.live(kind)
        if not live:
            return
        i = data.draw(st.sampled_from(live), label="id")
        how = ["set", "set", "set", "None", "del"][data.draw(st.integers(0, 4), label="how")]
        h = self._handle(kind, i)
        if how == "set":
            value = data.draw(PROP_VALUES[name], label="value")
            h[name] = value
            self.model.values[name][i] = value
        else:
            if how == "del":
                del h[name]
            else:
                h[name] = None
            self.model.values[name].pop(i, None)
        self.changed()
        event(f"property value: {how}")

    @rule(data=st.data(), name=st.sampled_from([name for _k, name, _d, _s, _x in PROPS]),
          handles=st.booleans())
    def set_values_bulk(self, data, name, handles):
        kind = PROP_KIND[name]
        live = self.model.live(kind)
        if not live:
            return
        ids = data.draw(st.lists(st.sampled_from(live), min_size=1, max_size=len(live), unique=True), label="ids")
        vals = [data.draw(PROP_VALUES[name], label="value") for _ in ids]
        unset = data.draw(st.lists(st.booleans(), min_size=len(ids), max_size=len(ids)), label="unset")
        unset[data.draw(st.integers(0, len(ids) - 1), label="kept")] = False  # (at least one value is written)
        if name == "label":
            array = np.empty(len(ids), dtype=object)
            array[:] = vals
            if data.draw(st.booleans(), label="None for unset"):
                array[np.array(unset)] = None
            else:
                array = np.ma.MaskedArray(array, mask=unset)
        else:
            array = np.array(vals, dtype=np.float64 if name != "w" else np.int64)
            mask = np.array(unset).reshape((-1,) + (1,) * (array.ndim - 1))
            array = np.ma.MaskedArray(array, mask=np.broadcast_to(mask, array.shape).copy())
        targets = [self._handle(kind, i) for i in ids] if handles else np.array(ids, dtype=np.int64)
        self.mesh.set_property_array(kind, name, targets, array)
        for i, value, u in zip(ids, vals, unset):
            if u:
                self.model.values[name].pop(i, None)
            else:
                self.model.values[name][i] = value
        self.changed()
        event(f"set_property_array of {name}")

    @precondition(lambda self: self.model.vertices)
    @rule(data=st.data(), position=st.none() | POSITIONS)
    def set_position(self, data, position):
        v = data.draw(st.sampled_from(sorted(self.model.vertices)), label="vertex")
        self.mesh.set_position(self.V(v), position)
        self.model.positions[v] = None if position is None else tuple(float(c) for c in position)
        self.changed()

    @precondition(lambda self: self.model.vertices)
    @rule(data=st.data(), handles=st.booleans())
    def set_positions(self, data, handles):
        vs = sorted(self.model.vertices)
        ids = data.draw(st.lists(st.sampled_from(vs), min_size=1, max_size=len(vs), unique=True), label="ids")
        xyz = [data.draw(POSITIONS, label="position") for _ in ids]
        self.mesh.set_positions([self.V(v) for v in ids] if handles else ids, np.array(xyz, dtype=np.float64))
        for v, p in zip(ids, xyz):
            self.model.positions[v] = p
        self.changed()

    # -- operations that must fail ----------------------------------------------

    @rule(data=st.data(), what=st.sampled_from(["stale", "stale", "malformed"]))
    def operation_that_must_fail(self, data, what):
        if what == "stale":
            self._use_stale_handle(data)
        elif self.model.vertices:
            self._malformed_input(data)

    def _use_stale_handle(self, data):
        """Handles of removed elements (or of ids never handed out) raise ElementNotFoundError."""
        m = self.model
        kind = data.draw(st.sampled_from(["vertex", "edge", "halfedge", "polygon"]), label="kind")
        never = 10**9 + 7
        i = data.draw(st.sampled_from(sorted(m.removed[kind]) + [never]), label="id")
        live = sorted(m.vertices)
        other = self.V(live[0]) if live else None
        if kind == "vertex":
            v = self.V(i)
            calls = [lambda: self.mesh.remove_vertex(v), lambda: v.degree, lambda: v.neighbors(),
                     lambda: self.mesh.add_polygon([v]), lambda: self.mesh.can_add_polygon([v]),
                     lambda: self.mesh.vertex(i), lambda: v["t"], lambda: v.__setitem__("t", 1.0),
                     lambda: self.mesh.set_position(v, (0, 0, 0)),
                     lambda: self.mesh.set_positions([v], [[0, 0, 0]]),
                     lambda: self.mesh.set_property_array("vertex", "t", [i], [1.0])]
            if other is not None:
                calls += [lambda: self.mesh.add_edge(other, v), lambda: self.mesh.add_edge(v, other),
                          lambda: self.mesh.add_polygon([other, v])]
        elif kind == "edge":
            e = self.E(i)
            calls = [lambda: self.mesh.remove_edge(e), lambda: e.vertices(), lambda: e.halfedges(),
                     lambda: self.mesh.edge(i), lambda: e.__setitem__("w", 1), lambda: e.__delitem__("w"),
                     lambda: self.mesh.set_property_array("edge", "w", [e], [1])]
        elif kind == "halfedge":
            h = self.H(i)
            calls = [lambda: h.next, lambda: h.origin, lambda: self.mesh.add_polygon([h]),
                     lambda: self.mesh.can_add_polygon([h]), lambda: self.mesh.halfedge(i),
                     lambda: h["uv"], lambda: h.__setitem__("uv", (1.0, 2.0))]
        else:
            p = self.P(i)
            calls = [lambda: self.mesh.remove_polygon(p), lambda: p.vertices(), lambda: p.degree,
                     lambda: self.mesh.polygon(i), lambda: p.__setitem__("label", "x"),
                     lambda: self.mesh.set_property_array("polygon", "label", [i], ["x"])]
        call = data.draw(st.sampled_from(calls), label="call")
        self.refused(call, ElementNotFoundError)

    def _malformed_input(self, data):
        v = self.V(data.draw(st.sampled_from(sorted(self.model.vertices)), label="v"))
        call = data.draw(st.sampled_from([
            lambda: self.mesh.add_vertex((math.nan, 0.0, 0.0)),
            lambda: self.mesh.add_vertex((1.0, 2.0)),
            lambda: self.mesh.add_polygon([]),
            lambda: self.mesh.add_polygon(v),
            lambda: self.mesh.add_edge(v, v.id),
            lambda: v.__setitem__("t", "1.0"),
            lambda: v.__setitem__("t", (1.0,)),
            lambda: self.mesh.set_position(v, (math.nan, 0.0, 0.0)),
            lambda: self.mesh.set_positions([v, v], np.zeros((2, 3))),
            lambda: self.mesh.set_positions([v], np.zeros((1, 2))),
            lambda: self.mesh.set_property_array("vertex", "t", [v.id, v.id], [1.0, 2.0]),
            lambda: self.mesh.set_property_array("vertex", "t", [v.id], ["x"]),
        ]), label="call")
        self.refused(call, InvalidInputError)

    # -- other connections --------------------------------------------------------

    @rule()
    def other_connection_sees_committed_state(self):
        assert dump(self.url) == self.committed_dump
        with hestore.open(self.url) as other:
            mesh = other.mesh(self.name)
            assert mesh.revision == self.committed_revision
            assert mesh.check() == []

    @precondition(lambda self: not self.stack)
    @rule()
    def reopen_store(self):
        self.store.close()
        self.store = hestore.open(self.url)
        self.mesh = self.store.mesh(self.name)
        assert (self.mesh.allow_loops, self.mesh.allow_multi_edges) == (self.allow_loops, self.allow_multi)

    # -- invariants ---------------------------------------------------------------

    def _check_properties(self):
        """`property_array` of every property equals the model.

        `property_array` is a function of the property's stored value rows and
        of the live ids of its kind; where both and the model's expectation are
        what they were when it was last read and found right, it is not read
        again (most steps leave most properties alone).
        """
        m, mesh = self.model, self.mesh
        with self.store.session.reading() as conn:
            raw = {}
            for t in VALUE_TABLES:
                for r in conn.execute(sa.select(*t.c).where(t.c.mesh_id == mesh.id).order_by(*t.c)):
                    raw.setdefault(r[1], []).append(tuple(r))
        for kind, name, _dtype, _shape, _default in PROPS:
            want = m.expected_values(name)
            key = (repr(raw.get(self.prop_ids[name], [])), tuple(m.live(kind)), repr(want))
            if self.verified.get(name) == key:
                continue
            ids, array = mesh.property_array(kind, name)
            assert ids.tolist() == m.live(kind)
            got = python_values(array)
            assert len(got) == len(want) and all(same(g, w) for g, w in zip(got, want)), (
                f"property {name!r}: {got} != {want}")
            self.verified[name] = key

    @invariant()
    def matches_model(self):
        if self.mesh is None:
            return
        m = self.model
        mesh = self.mesh
        d = dump(self.store)
        self.last_dump = d
        if not self.stack:
            self.committed_dump = d
        mid = mesh.id
        assert mesh.check() == []
        assert {r[1] for r in d["vertices"] if r[0] == mid} == m.vertices
        assert {r[1] for r in d["edges"] if r[0] == mid} == set(m.edges)
        assert {r[1] for r in d["polygons"] if r[0] == mid} == set(m.polygons)
        rows = {r[HE_ID]: r for r in d["halfedges"] if r[0] == mid}
        assert set(rows) == set(m.halfedges)
        for h, (origin, _target, e) in m.halfedges.items():
            r = rows[h]
            a, b, x, y = m.edges[e]
            assert (r[HE_ORIGIN], r[HE_EDGE], r[HE_TWIN], r[HE_POLYGON]) == (origin, e, y if h == x else x, m.face[h])
        assert mesh.counts() == hestore.Counts(
            vertices=len(m.vertices), halfedges=2 * len(m.edges), edges=len(m.edges), polygons=len(m.polygons)
        )
        for p, loop in m.polygons.items():
            P = self.P(p)
            assert rotations_equal([h.id for h in P.halfedges()], loop)
            assert rotations_equal([v.id for v in P.vertices()], m.cycle_vertices(p))
        for e, (a, b, h, _t) in m.edges.items():
            E = self.E(e)
            assert tuple(v.id for v in E.vertices()) == (a, b)
            assert E.halfedge.id == h
        self._check_properties()
        stored = {r[1]: (None if r[3] is None else tuple(r[3:6])) for r in d["vertices"] if r[0] == mid}
        assert stored == m.positions
        assert mesh.revision == self.expected_revision
        assert self.store.in_transaction == bool(self.stack)


#: Shrinking replays the machine against the database hundreds of times (up to
#: hypothesis's five-minute limit), so by default a failure is reported as
#: found; set HESTORE_SHRINK=1 to get a minimal failing sequence.
SHRINK = os.environ.get("HESTORE_SHRINK", "") not in ("", "0")


def _run(url: str, max_examples: int, steps: int) -> None:
    machine = type("Machine", (MeshMachine,), {"url": url})
    phases = [Phase.explicit, Phase.reuse, Phase.generate] + ([Phase.shrink] if SHRINK else [])
    run_state_machine_as_test(
        machine,
        settings=settings(
            max_examples=max_examples,
            stateful_step_count=steps,
            deadline=None,
            suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much],
            phases=phases,
            database=None,
        ),
    )


def test_state_machine(db_url, backend):
    if backend == "sqlite":
        _run(db_url, max_examples=60, steps=40)
    else:
        _run(db_url, max_examples=15, steps=30)


# --------------------------------------------------------------------------
# The oracle against the kernel, exhaustively on small fixed meshes


def model_of(mesh) -> Model:
    """A `Model` read back from the stored mesh."""
    d = dump(mesh.store)
    mid = mesh.id
    model = Model()
    model.vertices = {r[1] for r in d["vertices"] if r[0] == mid}
    rows = {r[HE_ID]: r for r in d["halfedges"] if r[0] == mid}
    for e_row in (r for r in d["edges"] if r[0] == mid):
        e, h = e_row[1], e_row[2]
        t = rows[h][HE_TWIN]
        a, b = rows[h][HE_ORIGIN], rows[t][HE_ORIGIN]
        model.edges[e] = (a, b, h, t)
        model.halfedges[h], model.halfedges[t] = (a, b, e), (b, a, e)
    for h, r in rows.items():
        model.face[h] = r[HE_POLYGON]
    for p in mesh.polygons():
        model.polygons[p.id] = [h.id for h in p.halfedges()]
    return model


def _three_loops_two_monogons(mesh):
    v = mesh.add_vertex()
    for _ in range(3):
        mesh.add_edge(v, v)
    mesh.add_polygon([mesh.halfedge(1)])
    mesh.add_polygon([mesh.halfedge(3)])


def _loop_on_a_path(mesh):
    # a - b - c with a self-loop at b (the shapes of BUG-K3)
    a, b, c = (mesh.add_vertex() for _ in range(3))
    mesh.add_edge(a, b)
    mesh.add_edge(b, b)
    mesh.add_edge(b, c)


def _two_fans_and_a_wire(mesh):
    v = mesh.add_vertex()
    ring = [mesh.add_vertex() for _ in range(5)]
    mesh.add_polygon([v, ring[0], ring[1]])
    mesh.add_polygon([v, ring[2], ring[3]])
    mesh.add_edge(v, ring[4])


def _bowtie_with_loop(mesh):
    v = mesh.add_vertex()
    a, b, c, d = (mesh.add_vertex() for _ in range(4))
    mesh.add_polygon([v, a, b])
    mesh.add_polygon([v, c, d])
    mesh.add_edge(v, v)


def _digon_and_loops(mesh):
    a, b = mesh.add_vertex(), mesh.add_vertex()
    e1, e2 = mesh.add_edge(a, b), mesh.add_edge(a, b)
    mesh.add_polygon([e1.halfedges()[0], e2.halfedges()[1]])
    mesh.add_edge(a, a)
    mesh.add_edge(b, b)


FIXTURES = {
    "three_loops_two_monogons": _three_loops_two_monogons,
    "loop_on_a_path": _loop_on_a_path,
    "two_fans_and_a_wire": _two_fans_and_a_wire,
    "bowtie_with_loop": _bowtie_with_loop,
    "digon_and_loops": _digon_and_loops,
}


def _free_chains(model: Model, max_len: int):
    """Every sequence of distinct free half-edges of length ≤ max_len that closes into a chain."""
    free = model.free_halfedges()
    out = []

    def extend(chain):
        last_target = model.halfedges[chain[-1]][1]
        if last_target == model.halfedges[chain[0]][0]:
            out.append(list(chain))
        if len(chain) == max_len:
            return
        for h in free:
            if h not in chain and model.halfedges[h][0] == last_target:
                extend(chain + [h])

    for h in free:
        extend([h])
    return out


@pytest.mark.parametrize("fixture", sorted(FIXTURES))
def test_rotation_oracle_examples(store, fixture):
    """`can_add_polygon` agrees with the oracle on every closed chain of free half-edges (up to 4).

    And where it says yes, `add_polygon` inside a rolled-back block stores a
    valid mesh whose polygon is that loop.
    """
    mesh = store.create_mesh(fixture)
    FIXTURES[fixture](mesh)
    assert mesh.check() == []
    model = model_of(mesh)
    before = dump(store)
    wrong = []
    for loop in _free_chains(model, 4):
        expected = model.can_close(loop)
        got = mesh.can_add_polygon([mesh.halfedge(h) for h in loop])
        if got != expected:
            wrong.append((loop, got, expected))
            continue
        if got:
            with pytest.raises(Rollback):
                with store.transaction():
                    p = mesh.add_polygon([mesh.halfedge(h) for h in loop])
                    assert rotations_equal([h.id for h in p.halfedges()], loop)
                    assert mesh.check() == []
                    raise Rollback
        else:
            with pytest.raises(NonManifoldError):
                mesh.add_polygon([mesh.halfedge(h) for h in loop])
    assert dump(store) == before
    assert not wrong, "can_add_polygon (got) disagrees with the rotation oracle (expected): " + "; ".join(
        f"{loop}: got {got}, expected {expected}" for loop, got, expected in wrong
    )
