"""Local graph queries: answers about a few vertices, read from the store without a whole graph (SPEC §6).

This module owns `k_ring`, `shortest_path` and the reads behind the induced
views of ``to_networkx(kind, vertices=...)`` (`vertex_rows`,
`halfedges_among`). They touch only the rows near the vertices asked about,
so they cost the same on a mesh of a hundred elements and on one of
millions, where a whole networkx graph takes seconds and gigabytes.

How they read: a search expands a whole batch of vertices with one
statement — the outgoing half-edges of every vertex of the batch, each with
its target (its twin's origin), and for the weighted search the target's
position — an ``IN`` list compiled per power-of-two size
(`hestore.statements.in_list_bucket`), run through
`hestore.session.Session.fetch`. So a breadth-first search costs one query
per level, and the reads see an open block's own edits and, on a view of the
past (`hestore.Mesh.at`), that revision. The twin (and its origin's vertex
row) is outer-joined on its whole key, as `hestore.navigation` does: a view
rewrites such a join into two indexed joins (`hestore.journal.as_of`), where
an inner join would make it read the whole table. A search's queries run
inside one read snapshot, so it never mixes two committed states.

The graph they search is the multigraph of `hestore.graphs` (``"multigraph"``):
one node per vertex, one edge per mesh edge. Self-loops never shorten a path
and parallel edges join the same two vertices, so a search only needs each
vertex's distinct neighbours; the ``"length"`` of an edge is the Euclidean
distance between its ends' positions, equal for parallel edges.
"""

from __future__ import annotations

import heapq
import math
from contextlib import contextmanager
from typing import Callable, Iterator, Sequence

import sqlalchemy as sa

from hestore import schema
from hestore.columns import read_snapshot
from hestore.errors import (
    InvalidInputError,
    InvariantViolationError,
    NoPathError,
    Violation,
    shown,
)
from hestore.navigation import exists, missing
from hestore.statements import in_chunks, in_keys, indexed_by, padded
from hestore.values import check_choice, check_integer
from hestore.session import MeshRef

__all__ = ["WEIGHTS", "k_ring", "shortest_path", "vertex_rows", "halfedges_among"]

#: The weights `shortest_path` takes: None (every edge weighs 1) and ``"length"`` (`hestore.graphs.LENGTH`).
WEIGHTS = (None, "length")

#: The shortest ``IN`` list compiled. Compiling a statement costs about 0.7 ms, so a cold query would
#: pay more for compiling the sizes 1, 2, 4 and 8 than for padding a short list to 16 (a few µs); a
#: k-ring of k ≤ 3 on a triangle mesh then compiles one statement.
_LEAST_IN = 16

#: How many vertices of least estimate the weighted search expands with one query. Expanding a few more
#: than the one of least estimate costs the same query, and a vertex expanded too early is expanded again
#: when a shorter way to it turns up, so the answer stays exact.
_BATCH = 16

_H = schema.halfedges
_V = schema.vertices


# --------------------------------------------------------------------------
# Batched reads


@contextmanager
def _consistent(ref: MeshRef) -> Iterator[None]:
    """Run the block's reads in one read snapshot of the session's connection (an open block's own state).

    A search's queries then see one committed state even while other
    processes commit. Cheaper than `hestore.session.Session.snapshot`, which
    also reads the revision: a cold query on PostgreSQL pays about a
    millisecond per round trip it makes.
    """
    with ref.session.reading() as connection, read_snapshot(connection):
        yield


def _in_rows(ref: MeshRef, name: str, build: Callable[[int], object], ids: Sequence[int]) -> list[tuple]:
    """The rows of ``build(size)`` (a statement with ``IN (:i0 … :i{size-1})``) for ``ids``, in chunks.

    One statement per chunk of `MAX_IN` ids, compiled once per bucket size (`_LEAST_IN` at least).
    """
    rows: list[tuple] = []
    for chunk, size in in_chunks(ids, _LEAST_IN):
        rows.extend(ref.session.fetch(ref, (name, size), lambda size=size: build(size), padded(chunk, size)))
    return rows


def _twin():
    """The half-edges outer-joined to their twins ``t``, on the twin's whole key (see the module's docstring)."""
    t = _H.alias("t")
    return t, _H.outerjoin(t, sa.and_(t.c.mesh_id == _H.c.mesh_id, t.c.id == _H.c.twin))


def _build_star(size: int):
    t, j = _twin()
    stmt = (
        sa.select(_H.c.origin, t.c.origin)
        .select_from(j)
        .where(_H.c.mesh_id == sa.bindparam("m"), _H.c.origin.in_(in_keys(size)))
    )
    return indexed_by(stmt, _H, "ix_halfedges_origin")


def _build_placed_star(size: int):
    t, j = _twin()
    w = _V.alias("w")
    j = j.outerjoin(w, sa.and_(w.c.mesh_id == _H.c.mesh_id, w.c.id == t.c.origin))
    stmt = (
        sa.select(_H.c.origin, t.c.origin, _H.c.edge, w.c.x, w.c.y, w.c.z)
        .select_from(j)
        .where(_H.c.mesh_id == sa.bindparam("m"), _H.c.origin.in_(in_keys(size)))
    )
    return indexed_by(stmt, _H, "ix_halfedges_origin")


def _broken(ref: MeshRef, origin: int) -> InvariantViolationError:
    return InvariantViolationError(
        [Violation("REF", "vertex", (origin,), f"an outgoing half-edge of vertex {origin} in mesh "
                   f"{ref.name!r} has no twin; run check()")]
    )


def _stars(ref: MeshRef, ids: Sequence[int]) -> list[tuple[int, int]]:
    """``(origin, target)`` of every outgoing half-edge of the vertices ``ids``: one query per `MAX_IN` of them."""
    rows = _in_rows(ref, "traversal_star", _build_star, ids)
    for origin, target in rows:
        if target is None:
            raise _broken(ref, origin)
    return rows


def _build_vertices(size: int):
    return sa.select(_V.c.id, _V.c.x, _V.c.y, _V.c.z).where(
        _V.c.mesh_id == sa.bindparam("m"), _V.c.id.in_(in_keys(size))
    )


def vertex_rows(ref: MeshRef, ids: Sequence[int]) -> list[tuple]:
    """``(id, x, y, z)`` of each of the vertices ``ids`` (distinct), ascending; coordinates None without a position.

    Raises
    ------
    ElementNotFoundError
        One of them does not exist (`MeshNotFoundError`: the mesh is gone).
    """
    rows = sorted(_in_rows(ref, "traversal_vertices", _build_vertices, ids))
    if len(rows) != len(ids):
        found = {r[0] for r in rows}
        raise missing(ref, "vertex", min(i for i in ids if i not in found))
    return rows


def _build_among(size: int):
    t, j = _twin()
    e = schema.edges
    j = j.outerjoin(e, sa.and_(e.c.mesh_id == _H.c.mesh_id, e.c.id == _H.c.edge))
    stmt = (
        sa.select(_H.c.id, _H.c.origin, _H.c.twin, _H.c.edge, _H.c.polygon, t.c.origin, e.c.halfedge)
        .select_from(j)
        .where(_H.c.mesh_id == sa.bindparam("m"), _H.c.origin.in_(in_keys(size)))
    )
    return indexed_by(stmt, _H, "ix_halfedges_origin")


def halfedges_among(ref: MeshRef, ids: Sequence[int]) -> list[tuple]:
    """The half-edges between the vertices ``ids`` (origin and target both among them), ascending by id.

    Each row is ``(id, origin, twin, edge, polygon, target, edge's halfedge)``;
    ``polygon`` None where free. Read by origin, one query per `MAX_IN`
    vertices, and kept where the target is among ``ids`` too; the twin of a
    kept half-edge is kept, so every edge comes with both its half-edges.
    """
    among = set(ids)
    rows = _in_rows(ref, "traversal_among", _build_among, ids)
    for row in rows:
        if row[5] is None or row[6] is None:
            raise _broken(ref, row[1])
    return sorted(r for r in rows if r[5] in among)


# --------------------------------------------------------------------------
# Arguments


def _order(k: object) -> int:
    """``k`` of `k_ring`: an integer ≥ 0 (a numpy one too), never a bool or a float."""
    k = check_integer(k, "k, a number of edges,")
    if k < 0:
        raise InvalidInputError(f"k is a number of edges, an integer >= 0, not {shown(k)}")
    return k


def _weight(weight: object) -> str | None:
    return None if weight is None else check_choice(weight, WEIGHTS, "weight (None to count the edges)")


# --------------------------------------------------------------------------
# k-ring


def k_ring(ref: MeshRef, v: int, k: int) -> set[int]:
    """The vertices within ``k`` edges of vertex ``v``, ``v`` included.

    A breadth-first search, one query per level for its whole frontier
    (`MAX_IN` vertices a query): ``k`` queries at most, however many
    vertices the levels hold. Self-loops and parallel edges change nothing.

    Parameters
    ----------
    ref : hestore.session.MeshRef
        The mesh (its identity: the facade passes `Mesh.ref`).
    v : int
        The id of the vertex at the centre.
    k : int
        How many edges away at most: 0 gives ``{v}``, 1 ``v`` and its
        neighbours, and so on.

    Returns
    -------
    set of int
        The keys of networkx's ``single_source_shortest_path_length(G, v,
        cutoff=k)`` on the mesh's multigraph: vertex ids.

    Raises
    ------
    ElementNotFoundError
        ``v`` does not exist (removed, or never created).
    InvalidInputError
        ``k`` is not an integer ≥ 0.

    Examples
    --------
    A strip of four triangles, 0-2-4 along the bottom and 1-3-5 along the top:

    >>> import hestore
    >>> xyz = [(i // 2, i % 2, 0) for i in range(6)]
    >>> mesh = hestore.open("sqlite://").import_arrays("strip", xyz, [[0, 2, 1], [1, 2, 3], [2, 4, 3], [3, 4, 5]]).mesh
    >>> sorted(k_ring(mesh.ref, 0, 1)), sorted(k_ring(mesh.ref, 0, 2))
    ([0, 1, 2], [0, 1, 2, 3, 4])
    >>> k_ring(mesh.ref, 5, 0)
    {5}
    """
    k = _order(k)
    with _consistent(ref):
        seen = {v}
        frontier = [v]
        if k == 0:
            exists(ref, "vertex", v)
        for level in range(k):
            if not frontier:
                break
            stars = _stars(ref, frontier)
            if level == 0 and not stars:
                exists(ref, "vertex", v)  # isolated, or not there at all: only then one query more
            found = []
            for _origin, target in stars:
                if target not in seen:
                    seen.add(target)
                    found.append(target)
            frontier = found
    return seen


# --------------------------------------------------------------------------
# Shortest paths


def shortest_path(ref: MeshRef, a: int, b: int, weight: str | None = None) -> list[int]:
    """A shortest path from vertex ``a`` to vertex ``b``, as its vertices.

    ``weight=None`` counts edges: a bidirectional breadth-first search that
    expands the smaller side's whole frontier with one query.
    ``weight="length"`` sums Euclidean edge lengths: an A* search whose
    estimate is the straight-line distance to ``b`` (never more than the
    length of any way there, since an edge's length is the straight-line
    distance between its ends), expanding the `_BATCH` vertices of least
    estimate with one query that brings their neighbours' positions too.

    Parameters
    ----------
    ref : hestore.session.MeshRef
        The mesh (its identity: the facade passes `Mesh.ref`).
    a, b : int
        The ids of the first and the last vertex.
    weight : {None, "length"}
        What a path's length is: its number of edges, or the sum of their
        Euclidean lengths (from the positions of their ends).

    Returns
    -------
    list of int
        Vertex ids from ``a`` to ``b``, consecutive ones joined by an edge; ``[a]`` when
        ``a == b``. As short as networkx's ``shortest_path`` on the mesh's
        multigraph (with ``"length"``: weighing each pair of vertices by its
        lightest edge); among paths of equal length, any one.

    Raises
    ------
    NoPathError
        No path joins them (they are in different components).
    ElementNotFoundError
        ``a`` or ``b`` does not exist.
    InvalidInputError
        ``weight`` is neither None nor ``"length"``; or it is ``"length"``
        and the search meets an edge with an end that has no position (so no
        length), as ``hestore graph NAME path --weight length`` does.

    Examples
    --------
    From ``a`` to ``c`` along the legs of a right triangle (9 + 12) or along
    its hypotenuse (15), cut into three edges of 5:

    >>> import hestore
    >>> mesh = hestore.open("sqlite://").create_mesh("m")
    >>> xyz = [(0, 0, 0), (9, 0, 0), (9, 12, 0), (6, 8, 0), (3, 4, 0)]
    >>> a, b, c, q, p = (mesh.add_vertex(position) for position in xyz)
    >>> pentagon = mesh.add_polygon([a, b, c, q, p])
    >>> shortest_path(mesh.ref, a.id, c.id)  # the fewest edges
    [0, 1, 2]
    >>> shortest_path(mesh.ref, a.id, c.id, "length")  # the shortest
    [0, 4, 3, 2]
    >>> lone = mesh.add_vertex()
    >>> shortest_path(mesh.ref, a.id, lone.id)
    Traceback (most recent call last):
    ...
    hestore.errors.NoPathError: no path from vertex 0 to vertex 5 in mesh 'm': they are in different components
    """
    weight = _weight(weight)
    with _consistent(ref):
        if weight is None:
            vertex_rows(ref, sorted({a, b}))  # both there, in one query
            path = [a] if a == b else _bfs_path(ref, a, b)
        else:
            path = _astar_path(ref, a, b)
    if path is None:
        raise NoPathError(
            f"no path from vertex {a} to vertex {b} in {_described(ref)}: they are in different components"
        )
    return path


def _described(ref: MeshRef) -> str:
    at = "" if ref.revision is None else f" at revision {ref.revision}"
    return f"mesh {ref.name!r}{at}"


def _walk(parents: dict[int, int | None], v: int) -> list[int]:
    """``v``, its parent, its parent's parent, … up to the search's root."""
    out = [v]
    while (v := parents[v]) is not None:
        out.append(v)
    return out


def _bfs_path(ref: MeshRef, a: int, b: int) -> list[int] | None:
    """Fewest edges: a bidirectional breadth-first search, one query per level of the smaller side.

    Whole levels are expanded until the two sides meet; then every node
    newly reached by one side that the other has reached gives a shortest
    path (after levels ``La`` and ``Lb`` met nowhere, the two ends are more
    than ``La + Lb`` edges apart, and such a node is at most ``La + 1 + Lb``),
    so the first one ends the search.
    """
    sides = [({a: None}, [a]), ({b: None}, [b])]
    while sides[0][1] and sides[1][1]:
        k = 0 if len(sides[0][1]) <= len(sides[1][1]) else 1
        parents, frontier = sides[k]
        others = sides[1 - k][0]
        found = []
        for origin, target in _stars(ref, frontier):
            if target in parents:
                continue
            parents[target] = origin
            if target in others:
                half, rest = _walk(parents, target), _walk(others, target)[1:]
                path = half[::-1] + rest
                return path if k == 0 else path[::-1]
            found.append(target)
        sides[k] = (parents, found)
    return None


def _distance(p: tuple, q: tuple) -> float:
    return math.sqrt((p[0] - q[0]) ** 2 + (p[1] - q[1]) ** 2 + (p[2] - q[2]) ** 2)


def _unweighable(ref: MeshRef, edge: int, vertex: int) -> InvalidInputError:
    return InvalidInputError(
        f"cannot weigh the paths of {_described(ref)} by length: edge {edge} has no length: "
        f"vertex {vertex} has no position"
    )


def _astar_path(ref: MeshRef, a: int, b: int) -> list[int] | None:
    """Least total length: A* with the straight-line distance to ``b``, `_BATCH` vertices a query.

    A vertex may be expanded before its shortest distance is known (it was
    in a batch with a better one); it is queued again when a shorter way to
    it turns up, and the search stops only when no queued estimate is below
    the best length found to ``b`` — so the answer is exact.
    """
    rows = {i: None if x is None else (x, y, z) for i, x, y, z in vertex_rows(ref, sorted({a, b}))}
    if a == b:
        return [a]
    goal = rows[b]
    place: dict[int, tuple | None] = {a: rows[a]}

    def estimate(v: int) -> float:
        return 0.0 if goal is None else _distance(place[v], goal)

    dist = {a: 0.0}
    parents: dict[int, int | None] = {a: None}
    expanded: dict[int, float] = {}
    best = math.inf
    queue = [(0.0, 0.0, a)]
    while queue and queue[0][0] < best:
        batch = []
        while queue and len(batch) < _BATCH and queue[0][0] < best:
            _, d, v = heapq.heappop(queue)
            if d > dist[v] or expanded.get(v) == d:
                continue  # a stale entry, or expanded at this distance already
            expanded[v] = d
            batch.append(v)
        if not batch:
            continue
        for origin, target, edge, x, y, z in _in_rows(ref, "traversal_placed_star", _build_placed_star, batch):
            if target is None:
                raise _broken(ref, origin)
            if place[origin] is None:
                raise _unweighable(ref, edge, origin)
            if x is None or y is None or z is None:
                raise _unweighable(ref, edge, target)
            if target == origin:
                continue
            if target not in place:
                place[target] = (x, y, z)
            d = dist[origin] + _distance(place[origin], place[target])
            if d < dist.get(target, math.inf):
                dist[target] = d
                parents[target] = origin
                if target == b:
                    best = d
                else:
                    heapq.heappush(queue, (d + estimate(target), d, target))
    if best == math.inf:
        return None
    return _walk(parents, b)[::-1]

