"""Topological operations: the algorithms of the general half-edge structure.

These are seed 000's algorithms (``findFreeIncident``, ``makeAdjacent``,
``addEdge``, ``addPolygon``, ``removePolygon``, ``removeEdge``,
``removeVertex``), extended with OpenMesh's boundary convention
(``V_BOUNDARY``: a vertex with a free outgoing half-edge points at one).

Every operation is a free function on a `hestore._unitofwork.UnitOfWork` and
works on integer ids. Each first checks every precondition it can see
without changing anything and raises a typed `hestore.errors.TopologyError`;
only then does it mutate. ``makeAdjacent`` is the one check that can only be
answered by trying: the caller runs operations inside the unit of work's undo
log, so a refusal half-way through leaves nothing behind.

Vocabulary: a half-edge is *free* when it has no polygon; a vertex is *free*
when it is isolated or has a free outgoing half-edge. ``rotate_cw(h) =
next(twin(h))`` steps to the next outgoing half-edge around ``origin(h)``
(the seed's ``vertexNext``); ``rotate_ccw(h) = twin(prev(h))`` steps back.

Errors carry ``refs``, ``(kind, id)`` pairs; `hestore.mesh` turns them into
handles (``elements``).
"""

from __future__ import annotations

from typing import Sequence

from hestore.errors import (
    HalfEdgeNotFreeError,
    InvalidInputError,
    NonManifoldError,
    NotAChainError,
    PolicyError,
    VertexNotFreeError,
)
from hestore._unitofwork import EDGE, NEXT, ORIGIN, POLYGON, PREV, TWIN, UnitOfWork

__all__ = [
    "add_vertex",
    "add_edge",
    "add_polygon",
    "add_polygon_from_vertices",
    "remove_polygon",
    "remove_edge",
    "remove_vertex",
    "make_adjacent",
    "find_free_incident",
    "is_free_vertex",
    "target",
    "describe",
    "edges_between",
    "check_policy",
    "polygon_loop",
    "adjust_outgoing",
    "unlink",
    "fans",
]


def target(uow: UnitOfWork, h: int) -> int:
    """The vertex half-edge ``h`` arrives at."""
    return uow.he(uow.he(h)[TWIN])[ORIGIN]


def describe(uow: UnitOfWork, h: int) -> str:
    """``half-edge 7 (3→4)``: a half-edge for a message."""
    return f"half-edge {h} ({uow.he(h)[ORIGIN]}→{target(uow, h)})"


def is_free_vertex(uow: UnitOfWork, v: int) -> bool:
    """Whether an edge can be attached at ``v``.

    By the boundary convention ``v.halfedge`` is free whenever any outgoing
    half-edge is, so this is O(1).
    """
    h = uow.vhe(v)
    return h is None or uow.he(h)[POLYGON] is None


def find_free_incident(uow: UnitOfWork, start: int, stop: int, exclude: frozenset = frozenset()) -> int | None:
    """The first free half-edge arriving at a vertex, from ``start`` up to ``stop``.

    Walks the incoming half-edges ``h → twin(next(h))`` beginning with
    ``start`` (included) and ending before ``stop`` (excluded); ``None`` when
    every one of them has a polygon or is in ``exclude``. This is the seed's
    ``findFreeIncident(v, startingFrom, andBefore)``.
    """
    h = start
    limit = 2 * len(uow.outgoing(uow.he(uow.he(start)[NEXT])[ORIGIN])) + 2
    for _ in range(limit):
        if h == stop:
            return None
        if uow.he(h)[POLYGON] is None and h not in exclude:
            return h
        h = uow.he(uow.he(h)[NEXT])[TWIN]
    raise uow.corrupt("V_ROTATION", "halfedge", start, f"the incoming half-edges around half-edge {start} do not close")


def make_adjacent(uow: UnitOfWork, h_in: int, h_out: int, loop: frozenset = frozenset()) -> bool:
    """Reorder the links around a vertex so that ``next(h_in) == h_out``.

    ``h_in`` arrives at the vertex and ``h_out`` leaves it; both are free.
    The fan between them (``next(h_in)`` … ``prev(h_out)``) is moved into
    another free gap found by `find_free_incident`; ``False`` when there is
    none (OpenMesh's "complex vertex"), and then nothing was changed.

    ``loop`` holds the half-edges of the polygon being made: none of them may
    be the gap, or a loop that passes a vertex twice would have its earlier
    corner unlinked by a later one.
    """
    if uow.he(h_in)[NEXT] == h_out:
        return True
    b = uow.he(h_in)[NEXT]
    d = uow.he(h_out)[PREV]
    g = find_free_incident(uow, uow.he(h_out)[TWIN], h_in, loop)
    if g is None:
        return False
    h = uow.he(g)[NEXT]
    uow.link(h_in, h_out)
    uow.link(g, b)
    uow.link(d, h)
    return True


def _first_free_outgoing(uow: UnitOfWork, v: int) -> int | None:
    start = uow.vhe(v)
    if start is None:
        return None
    h = start
    for _ in range(len(uow.outgoing(v)) + 1):
        if uow.he(h)[POLYGON] is None:
            return h
        h = uow.he(uow.he(h)[TWIN])[NEXT]
        if h == start:
            return None
    raise uow.corrupt("V_ROTATION", "vertex", v, f"the rotation around vertex {v} does not close")


def adjust_outgoing(uow: UnitOfWork, v: int) -> None:
    """Restore V_BOUNDARY at ``v``: if it has a free outgoing half-edge, ``v.halfedge`` is one."""
    h = uow.vhe(v)
    if h is not None and uow.he(h)[POLYGON] is not None:
        free = _first_free_outgoing(uow, v)
        if free is not None:
            uow.set_vhe(v, free)


def add_vertex(uow: UnitOfWork, position: tuple | None = None) -> int:
    """Allocate an isolated vertex and return its id."""
    return uow.new_vertex(position)


def edges_between(uow: UnitOfWork, a: int, b: int) -> list[int]:
    """Half-edges a→b, lowest id first."""
    return sorted(h for h in uow.outgoing(a) if target(uow, h) == b)


def check_policy(uow: UnitOfWork, a: int, b: int, ignore: frozenset = frozenset()) -> None:
    """Raise `PolicyError` if a new edge ``a``–``b`` would be a loop or a parallel edge the mesh forbids.

    Edges in ``ignore`` do not count (those an operator is about to remove).
    """
    if a == b and not uow.allow_loops:
        raise PolicyError(f"vertex {a}: this mesh does not allow self-loop edges", (("vertex", a),))
    if uow.allow_multi_edges:
        return
    existing = [e for e in (uow.he(h)[EDGE] for h in edges_between(uow, a, b)) if e not in ignore]
    if existing:
        raise PolicyError(
            f"vertices {a} and {b} are already joined by edge {existing[0]}; this mesh does not allow parallel edges",
            (("vertex", a), ("vertex", b), ("edge", existing[0])),
        )


def _check_edge(uow: UnitOfWork, a: int, b: int) -> None:
    uow.load(stars=(a, b))
    uow.vhe(a)
    uow.vhe(b)
    check_policy(uow, a, b)
    for v in dict.fromkeys((a, b)):
        if not is_free_vertex(uow, v):
            raise VertexNotFreeError(
                f"vertex {v} is not free: every half-edge leaving it has a polygon, so no edge can be attached there",
                (("vertex", v),),
            )


def _link_new_edge(uow: UnitOfWork, h: int, t: int) -> None:
    # addEdge's two "link one side" steps. The free gap used at a vertex is the
    # one just before v.halfedge, which the boundary convention keeps free.
    for out, back in ((h, t), (t, h)):
        v = uow.he(out)[ORIGIN]
        first = uow.vhe(v)
        if first is None:
            uow.set_vhe(v, out)
        else:
            arriving = uow.he(first)[PREV]
            uow.link(arriving, out)
            uow.link(back, first)


def add_edge(uow: UnitOfWork, a: int, b: int) -> int:
    """Add an edge between vertices ``a`` and ``b`` and return its id.

    Both vertices must be free; the new half-edges are linked into each
    vertex's rotation at a free gap. ``a == b`` makes a self-loop.
    """
    _check_edge(uow, a, b)
    e, h, t = uow.new_edge(a, b)
    _link_new_edge(uow, h, t)
    return e


def _check_loop(uow: UnitOfWork, loop: Sequence[int]) -> None:
    if not loop:
        raise InvalidInputError("a polygon needs at least one half-edge")
    uow.load(halfedges=loop)
    seen: set[int] = set()
    for h in loop:
        uow.he(h)
        if h in seen:
            raise InvalidInputError(f"half-edge {h} appears twice in the loop")
        seen.add(h)
    uow.load(stars=[uow.he(h)[ORIGIN] for h in loop])
    n = len(loop)
    for i, h in enumerate(loop):
        nxt = loop[(i + 1) % n]
        if target(uow, h) != uow.he(nxt)[ORIGIN]:
            raise NotAChainError(
                f"{describe(uow, h)} is followed by {describe(uow, nxt)}: they do not meet",
                (("halfedge", h), ("halfedge", nxt)),
            )
    for h in loop:
        p = uow.he(h)[POLYGON]
        if p is not None:
            raise HalfEdgeNotFreeError(
                f"{describe(uow, h)} already has polygon {p}; edge {uow.he(h)[EDGE]} cannot take "
                f"another polygon on that side (a complex edge)",
                (("halfedge", h), ("polygon", p)),
            )


def add_polygon(uow: UnitOfWork, loop: Sequence[int]) -> int:
    """Turn a loop of free half-edges into a polygon and return its id.

    The loop must chain (``target(loop[i]) == origin(loop[i+1])``, cyclically)
    and every half-edge must be free. The links around each corner are
    reordered with `make_adjacent` where needed.
    """
    loop = list(loop)
    _check_loop(uow, loop)
    n = len(loop)
    members = frozenset(loop)
    corners = [(h, loop[(i + 1) % n]) for i, h in enumerate(loop)]
    mark = uow.mark()
    if not (
        all(make_adjacent(uow, h, nxt, members) for h, nxt in corners)
        and all(uow.he(h)[NEXT] == nxt for h, nxt in corners)
    ):
        # The seed's corner-by-corner reordering depends on where the loop
        # starts when it meets a vertex twice; its rule ("if and only if the
        # links can be reordered") does not. Decide that rule exactly.
        uow.rollback_to(mark)
        _arrange_fans(uow, corners)
    p = uow.new_polygon(loop[0])
    for h in loop:
        uow.set_polygon(h, p)
    for v in dict.fromkeys(uow.he(h)[ORIGIN] for h in loop):
        adjust_outgoing(uow, v)
    return p


def fans(uow: UnitOfWork, v: int) -> list[list[int]]:
    """The fans around ``v``: runs of outgoing half-edges joined by polygons.

    Consecutive outgoing half-edges ``o`` and ``next(twin(o))`` are in one fan
    when the wedge between them has a polygon; a free wedge ends a fan. Fans
    can be put around the vertex in any order without touching a polygon.
    """
    start = uow.vhe(v)
    rotation = [start]
    h = uow.he(uow.he(start)[TWIN])[NEXT]
    while h != start:
        rotation.append(h)
        if len(rotation) > len(uow.outgoing(v)):
            raise uow.corrupt("V_ROTATION", "vertex", v, f"the rotation around vertex {v} does not close")
        h = uow.he(uow.he(h)[TWIN])[NEXT]
    free = [uow.he(uow.he(o)[TWIN])[POLYGON] is None for o in rotation]  # the wedge after o
    if not any(free):
        return [rotation]
    first = len(free) - free[::-1].index(True)  # a fan starts right after a free wedge
    fans, current = [], []
    for k in range(first, first + len(rotation)):
        current.append(rotation[k % len(rotation)])
        if free[k % len(rotation)]:
            fans.append(current)
            current = []
    return fans


def _arrange_fans(uow: UnitOfWork, corners: list[tuple[int, int]]) -> None:
    """Relink every corner vertex so that ``next(h) == nxt`` for each corner.

    Each corner asks that the fan ending with ``twin(h)`` be followed by the
    fan starting with ``nxt``. These successor constraints are satisfiable
    exactly when they form chains, or one cycle through every fan of the
    vertex; the fans are then put around the vertex in that order (chains in
    their present order). Raises `NonManifoldError` otherwise, before
    changing anything.
    """
    at: dict[int, list[tuple[int, int]]] = {}
    for h, nxt in corners:
        at.setdefault(uow.he(nxt)[ORIGIN], []).append((h, nxt))
    links: list[tuple[int, int]] = []
    for v, vcorners in at.items():
        around = fans(uow, v)
        ending = {fan[-1]: i for i, fan in enumerate(around)}
        starting = {fan[0]: i for i, fan in enumerate(around)}
        succ: dict[int, int] = {}
        pred: dict[int, int] = {}
        for h, nxt in vcorners:
            a, b = ending.get(uow.he(h)[TWIN]), starting.get(nxt)
            if a is None or b is None or a in succ or b in pred:
                raise _complex_vertex(uow, h, nxt)
            succ[a], pred[b] = b, a
        order: list[int] = []
        for i in range(len(around)):
            if i not in pred:
                while i is not None:
                    order.append(i)
                    i = succ.get(i)
        if not order:  # every fan has a predecessor: the constraints close into cycles
            i = 0
            while not (order and i == 0):
                order.append(i)
                i = succ[i]
        if len(order) < len(around):
            # Some around lie on a cycle of constraints that is not the whole vertex.
            raise _complex_vertex(uow, *vcorners[0])
        for k, i in enumerate(order):
            after = around[order[(k + 1) % len(order)]]
            links.append((uow.he(around[i][-1])[TWIN], after[0]))
    for a, b in links:
        uow.link(a, b)


def _complex_vertex(uow: UnitOfWork, h: int, nxt: int) -> NonManifoldError:
    v = uow.he(nxt)[ORIGIN]
    return NonManifoldError(
        f"vertex {v} has no free gap left to reorder its neighbourhood into, so "
        f"{describe(uow, h)} cannot be followed by {describe(uow, nxt)} in one polygon "
        f"(a complex vertex: the polygon would join fans that cannot be separated)",
        (("vertex", v), ("halfedge", h), ("halfedge", nxt)),
    )


def _choose_halfedge(uow: UnitOfWork, a: int, b: int, used: set[int]) -> int | None:
    """A free a→b half-edge not yet in the loop; ``None`` if no edge joins a, b.

    Prefers one whose twin is not in the loop either (so two parallel edges
    give a 2-gon, not a polygon on both sides of one edge), then the lowest id.
    """
    candidates = edges_between(uow, a, b)
    if not candidates:
        return None
    free = [h for h in candidates if uow.he(h)[POLYGON] is None and h not in used]
    if not free:
        taken = ", ".join(
            f"{h} (polygon {uow.he(h)[POLYGON]})" if uow.he(h)[POLYGON] is not None else f"{h} (earlier in this loop)"
            for h in candidates
        )
        raise HalfEdgeNotFreeError(
            f"vertices {a} and {b} are joined, but every half-edge {a}→{b} is taken: {taken}; "
            f"no polygon can run {a}→{b} (a complex edge; hestore never adds a parallel edge silently)",
            (("vertex", a), ("vertex", b)) + tuple(("halfedge", h) for h in candidates),
        )
    free.sort(key=lambda h: (uow.he(h)[TWIN] in used, h))
    return free[0]


def add_polygon_from_vertices(uow: UnitOfWork, vertices: Sequence[int]) -> int:
    """Add the polygon with corners ``vertices`` (counter-clockwise) and return its id.

    Between consecutive corners a free half-edge is used if one exists; a new
    edge is created only where no edge joins the two vertices at all.
    """
    vertices = list(vertices)
    if not vertices:
        raise InvalidInputError("a polygon needs at least one vertex")
    uow.load(stars=vertices)
    for v in vertices:
        uow.vhe(v)
    n = len(vertices)
    loop: list[int] = []
    used: set[int] = set()
    for i, a in enumerate(vertices):
        b = vertices[(i + 1) % n]
        h = _choose_halfedge(uow, a, b, used)
        if h is None:
            _check_edge(uow, a, b)
            _e, h, t = uow.new_edge(a, b)
            _link_new_edge(uow, h, t)
        loop.append(h)
        used.add(h)
    return add_polygon(uow, loop)


def polygon_loop(uow: UnitOfWork, p: int) -> list[int]:
    """The half-edges of polygon ``p`` in ``next`` order, from ``p.halfedge``."""
    start = uow.polygon_he(p)
    loop = [start]
    h = uow.he(start)[NEXT]
    while h != start:
        loop.append(h)
        if len(loop) > uow.cached_halfedges:  # more steps than rows: the loop is broken
            raise uow.corrupt("P_LOOP", "polygon", p, f"the half-edges of polygon {p} do not close into a loop")
        h = uow.he(h)[NEXT]
    return loop


def remove_polygon(uow: UnitOfWork, p: int) -> None:
    """Remove polygon ``p``; its half-edges become free, its edges stay."""
    uow.load(polygons=(p,))
    loop = polygon_loop(uow, p)
    uow.load(stars=[uow.he(h)[ORIGIN] for h in loop])
    for h in loop:
        uow.set_polygon(h, None)
    uow.delete_polygon(p)
    for h in loop:
        v = uow.he(h)[ORIGIN]
        if uow.he(uow.vhe(v))[POLYGON] is not None:
            uow.set_vhe(v, h)


def _load_footprint(uow: UnitOfWork, vertices: list[int], polygons: list[int]) -> None:
    """Cache, in two queries, everything removing these polygons and edges touches."""
    uow.load(polygons=polygons)
    corners = [uow.he(h)[ORIGIN] for p in polygons for h in polygon_loop(uow, p)]
    uow.load(stars=vertices + corners)


def unlink(uow: UnitOfWork, h: int) -> None:
    """Take ``h`` out of its origin's rotation (removeEdge's "link one side off the model").

    Read fresh each time: for a self-loop the second side sees the first side's relinking.
    """
    v = uow.he(h)[ORIGIN]
    arriving = uow.he(h)[PREV]
    leaving = uow.he(uow.he(h)[TWIN])[NEXT]
    if uow.vhe(v) == h:
        uow.set_vhe(v, None if leaving == h else leaving)
    uow.link(arriving, leaving)


def remove_edge(uow: UnitOfWork, e: int) -> None:
    """Remove edge ``e`` and the polygons on both of its sides."""
    uow.load(edges=(e,))
    h = uow.edge_he(e)
    t = uow.he(h)[TWIN]
    polygons = [p for p in dict.fromkeys((uow.he(h)[POLYGON], uow.he(t)[POLYGON])) if p is not None]
    _load_footprint(uow, [uow.he(h)[ORIGIN], uow.he(t)[ORIGIN]], polygons)
    for p in polygons:
        remove_polygon(uow, p)
    unlink(uow, h)
    unlink(uow, t)
    uow.delete_edge(e)


def remove_vertex(uow: UnitOfWork, v: int) -> None:
    """Remove vertex ``v`` with every edge incident to it (a loop once)."""
    uow.load(stars=(v,))
    uow.vhe(v)
    out = uow.outgoing(v)
    ends = [v] + [target(uow, h) for h in out]
    polygons = {uow.he(x)[POLYGON] for h in out for x in (h, uow.he(h)[TWIN])} - {None}
    _load_footprint(uow, ends, sorted(polygons))
    for e in sorted({uow.he(h)[EDGE] for h in out}):
        remove_edge(uow, e)
    uow.delete_vertex(v)
