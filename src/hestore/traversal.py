"""Local graph queries: answers about a few vertices, read from the store without a whole graph (SPEC §6).

This module owns `k_ring`, `shortest_path`, `path_weight` and the reads
behind the induced views of ``to_networkx(kind, vertices=...)``
(`vertex_rows`, `halfedges_among`). They touch only the rows near the
vertices asked about, so they cost the same on a mesh of a hundred elements
and on one of millions, where a whole networkx graph takes seconds and
gigabytes. It also owns the names the graph views and the paths share —
the view kinds (`KINDS`) and the derived edge weight (`LENGTH`) — here,
below `hestore.graphs`, so that the command line offers them without
importing networkx.

How they read: a search expands a whole batch of vertices with one
statement — the outgoing half-edges of every vertex of the batch, each with
its target (its twin's origin), and for a weighted search the target's
position or the edge's value of the property — an ``IN`` list compiled per
power-of-two size (`hestore._statements.in_list_bucket`), one of the stars of
`hestore._queries.stars`, run through `hestore._session.Session.fetch`. So a
breadth-first search costs one query per level, and the reads see an open
block's own edits and, on a view of the past (`hestore.Mesh.at`), that
revision. The twin (and its origin's vertex row, and the edge's row) is
outer-joined on its whole key: a view rewrites such a join into two indexed
joins (`hestore._journal.as_of`), where an inner join would make it read the
whole table. A search's queries run inside one read snapshot
(`hestore._session.Session.consistent`), so it never mixes two committed
states.

The graph they search is the multigraph of `hestore.graphs` (``"multigraph"``):
one node per vertex, one edge per mesh edge. Self-loops never shorten a path
and parallel edges join the same two vertices, so a search only needs each
vertex's distinct neighbours and, weighted, the lightest edge to each; the
``"length"`` of an edge is the Euclidean distance between its ends'
positions, equal for parallel edges.
"""

from __future__ import annotations

import heapq
import math
from typing import Sequence

from hestore import properties
from hestore import _values as values
from hestore.errors import (
    InvalidInputError,
    InvariantViolationError,
    NoPathError,
    PropertyNotFoundError,
    Violation,
    shown,
)
from hestore.navigation import exists, missing
from hestore._queries import Query, elements, stars
from hestore._queries import values as value_rows
from hestore._statements import in_chunks, padded
from hestore._values import Property, check_integer
from hestore._session import MeshRef

__all__ = [
    "KINDS", "LENGTH", "NUMERIC", "k_ring", "shortest_path", "path_weight", "vertex_rows", "halfedges_among",
]

#: The graph kinds `hestore.graphs.to_networkx` makes, the default first.
KINDS = ("multigraph", "graph", "halfedge", "dual")

#: The derived edge weight (and graph attribute): the Euclidean length of an edge, from its ends' positions.
LENGTH = "length"

#: The dtypes of the edge properties a path can be weighed by, one value per edge (no shape).
NUMERIC = ("int64", "float64")

#: The shortest ``IN`` list compiled. Compiling a statement costs about 0.7 ms, so a cold query would
#: pay more for compiling the sizes 1, 2, 4 and 8 than for padding a short list to 16 (a few µs); a
#: k-ring of k ≤ 3 on a triangle mesh then compiles one statement.
_LEAST_IN = 16

#: How many vertices of least estimate the weighted search expands with one query. Expanding a few more
#: than the one of least estimate costs the same query, and a vertex expanded too early is expanded again
#: when a shorter way to it turns up, so the answer stays exact.
_BATCH = 16


# --------------------------------------------------------------------------
# Batched reads


def _consistent(ref: MeshRef):
    """Run the block's reads in one read snapshot of the session's connection (an open block's own state).

    A search's queries then see one committed state even while other
    processes commit. Cheaper than `hestore._session.Session.snapshot`, which
    also reads the revision: a cold query on PostgreSQL pays about a
    millisecond per round trip it makes.
    """
    return ref.session.consistent()


def _in_rows(ref: MeshRef, family: Query, ids: Sequence[int], binds: dict | None = None) -> list[tuple]:
    """The rows of ``family(size)`` (a statement with ``IN (:i0 … :i{size-1})``) for ``ids``, in chunks.

    One statement per chunk of `MAX_IN` ids, compiled once per bucket size
    (`_LEAST_IN` at least); ``binds`` are its other parameters.
    """
    rows: list[tuple] = []
    for chunk, size in in_chunks(ids, _LEAST_IN):
        params = padded(chunk, size) if binds is None else {**padded(chunk, size), **binds}
        rows.extend(ref.session.fetch(ref, family(size), params))
    return rows


def _broken(ref: MeshRef, origin: int) -> InvariantViolationError:
    return InvariantViolationError(
        [Violation("REF", "vertex", (origin,), f"an outgoing half-edge of vertex {origin} in mesh "
                   f"{ref.name!r} has no twin; run check()")]
    )


def _stars(ref: MeshRef, ids: Sequence[int]) -> list[tuple[int, int, int]]:
    """``(origin, target, edge)`` of every outgoing half-edge of the vertices ``ids``: a query per `MAX_IN` of them."""
    rows = _in_rows(ref, stars.batch, ids)
    for origin, target, _edge in rows:
        if target is None:
            raise _broken(ref, origin)
    return rows


def vertex_rows(ref: MeshRef, ids: Sequence[int]) -> list[tuple]:
    """``(id, x, y, z)`` of each of the vertices ``ids`` (distinct), ascending; coordinates None without a position.

    Raises
    ------
    ElementNotFoundError
        One of them does not exist (`MeshNotFoundError`: the mesh is gone).
    """
    rows = sorted(_in_rows(ref, elements.vertices, ids))
    if len(rows) != len(ids):
        found = {r[0] for r in rows}
        raise missing(ref, "vertex", min(i for i in ids if i not in found))
    return rows


def halfedges_among(ref: MeshRef, ids: Sequence[int]) -> list[tuple]:
    """The half-edges between the vertices ``ids`` (origin and target both among them), ascending by id.

    Each row is ``(id, origin, twin, edge, polygon, target, edge's halfedge)``;
    ``polygon`` None where free. Read by origin, one query per `MAX_IN`
    vertices, and kept where the target is among ``ids`` too; the twin of a
    kept half-edge is kept, so every edge comes with both its half-edges.
    """
    among = set(ids)
    rows = _in_rows(ref, stars.among, ids)
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


# --------------------------------------------------------------------------
# k-ring


def k_ring(ref: MeshRef, v: int, k: int) -> set[int]:
    """The vertices within ``k`` edges of vertex ``v``, ``v`` included.

    A breadth-first search, one query per level for its whole frontier
    (`MAX_IN` vertices a query): ``k`` queries at most, however many
    vertices the levels hold. Self-loops and parallel edges change nothing.

    Parameters
    ----------
    ref : hestore._session.MeshRef
        The mesh (its identity: the facade passes its own, `hestore._session.identity`).
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

    >>> from hestore._session import identity
    >>> import hestore
    >>> xyz = [(i // 2, i % 2, 0) for i in range(6)]
    >>> mesh = hestore.open("sqlite://").import_arrays("strip", xyz, [[0, 2, 1], [1, 2, 3], [2, 4, 3], [3, 4, 5]]).mesh
    >>> sorted(k_ring(identity(mesh), 0, 1)), sorted(k_ring(identity(mesh), 0, 2))
    ([0, 1, 2], [0, 1, 2, 3, 4])
    >>> k_ring(identity(mesh), 5, 0)
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
            for _origin, target, _edge in stars:
                if target not in seen:
                    seen.add(target)
                    found.append(target)
            frontier = found
    return seen


# --------------------------------------------------------------------------
# Weights


def _weight_name(weight: object) -> str | None:
    """``weight`` of `shortest_path` and `path_weight`: None or a name, which the mesh's catalogue resolves."""
    if weight is None or isinstance(weight, str):
        return weight
    raise InvalidInputError(
        f"weight is None, {LENGTH!r} or the name of a numeric edge property, not {type(weight).__name__} "
        f"{shown(weight)}"
    )


def _numeric(prop: Property) -> bool:
    return prop.dtype in NUMERIC and not prop.shape


def _described(ref: MeshRef) -> str:
    at = "" if ref.revision is None else f" at revision {ref.revision}"
    return f"mesh {ref.name!r}{at}"


def _distance(p: tuple, q: tuple) -> float:
    return math.sqrt((p[0] - q[0]) ** 2 + (p[1] - q[1]) ** 2 + (p[2] - q[2]) ** 2)


class _Counts:
    """Every edge weighs 1 (`path_weight` without a weight; that search is `_bfs_path`)."""

    zero = 0

    def __init__(self, ref: MeshRef) -> None:
        self.ref = ref

    def rows(self, batch: Sequence[int]) -> list[tuple]:
        return _stars(self.ref, batch)

    def weigh(self, row: tuple) -> int | float:
        return 1


class _Lengths(_Counts):
    """Edges weighed by their Euclidean length (`LENGTH`); the estimate is the straight line to the goal (A*).

    ``place`` starts with the positions of the vertices given (`vertex_rows`)
    and learns each target's from the rows that reach it.
    """

    zero = 0.0

    def __init__(self, ref: MeshRef, vertices: list[tuple], goal: int | None) -> None:
        super().__init__(ref)
        self.place: dict[int, tuple | None] = {i: None if x is None else (x, y, z) for i, x, y, z in vertices}
        self.goal = None if goal is None else self.place[goal]

    def rows(self, batch: Sequence[int]) -> list[tuple]:
        return _in_rows(self.ref, stars.placed, batch)

    def weigh(self, row: tuple) -> float:
        origin, target, edge, x, y, z = row
        if self.place[origin] is None:
            raise self._unplaced(edge, origin)
        if x is None or y is None or z is None:
            raise self._unplaced(edge, target)
        return _distance(self.place[origin], self.place.setdefault(target, (x, y, z)))

    def estimate(self, v: int) -> float:
        return 0.0 if self.goal is None else _distance(self.place[v], self.goal)

    def _unplaced(self, edge: int, vertex: int) -> InvalidInputError:
        return InvalidInputError(
            f"cannot weigh the paths of {_described(self.ref)} by {LENGTH}: edge {edge} has no length: "
            f"vertex {vertex} has no position"
        )


class _Values:
    """Edges weighed by a numeric edge property: an edge's value, else the default; no estimate (Dijkstra)."""

    def __init__(self, ref: MeshRef, prop: Property) -> None:
        self.ref, self.prop = ref, prop
        self.number = float if prop.dtype == "float64" else int
        self.zero = self.number(0)
        self.table = values.table_of(prop.dtype)

    def rows(self, batch: Sequence[int]) -> list[tuple]:
        """``(origin, target, edge, has a value, value)``: the stars, then their edges' values, a query each."""
        out = _stars(self.ref, batch)
        edges = sorted({edge for _, _, edge in out})
        found = dict(_in_rows(self.ref, value_rows.of_edges(self.table), edges, {"q": self.prop.id}))
        return [(origin, target, edge, edge in found, found.get(edge)) for origin, target, edge in out]

    def weigh(self, row: tuple) -> int | float:
        edge, has, value = row[2:]
        name = self.prop.name
        if not has:
            value = self.prop.default
            if value is None:
                raise self._refused(f"edge {edge} has no value of property {name!r}, which has no default")
        value = math.nan if value is None else self.number(value)  # a float's NaN is stored as NULL
        if value != value:
            raise self._refused(f"edge {edge} has {name} NaN")
        if value < 0:
            raise self._refused(
                f"edge {edge} has a negative {name} ({value}); a shortest path needs weights of 0 or more"
            )
        return value

    def estimate(self, v: int) -> int | float:
        return self.zero

    def _refused(self, reason: str) -> InvalidInputError:
        # The mesh by its name alone ('w', not mesh 'w'): the words ``hestore graph … path --weight`` has always said.
        at = "" if self.ref.revision is None else f" at revision {self.ref.revision}"
        return InvalidInputError(f"cannot weigh the paths of {self.ref.name!r}{at} by {self.prop.name}: {reason}")


def _weigher(ref: MeshRef, weight: str | None, vertices: list[tuple], goal: int | None = None):
    """How ``weight`` weighs this mesh's edges: None (each 1), `_Lengths` or `_Values`; one catalogue read.

    ``vertices`` are the `vertex_rows` of the vertices the caller starts
    from, ``goal`` the vertex an A* search aims at.

    Raises
    ------
    PropertyNotFoundError
        ``weight`` is neither ``"length"`` nor an edge property.
    InvalidInputError
        ``weight`` is an edge property that is not a number (`NUMERIC`, no shape).

    Both carry ``weights``: the names a path of this mesh can be weighed by.
    """
    if weight is None:
        return None
    edge = properties.properties(ref, "edge")
    prop = edge.get(weight)
    if prop is None and weight == LENGTH:
        return _Lengths(ref, vertices, goal)
    if prop is not None and _numeric(prop):
        return _Values(ref, prop)
    if prop is None:
        exc = PropertyNotFoundError(f"mesh {ref.name!r} has no edge property named {shown(weight)}")
    else:
        shaped = f" of shape {prop.shape}" if prop.shape else ""
        exc = InvalidInputError(f"edge property {weight!r} of mesh {ref.name!r} is {prop.dtype}{shaped}, not a number")
    # An edge property named "length" is that property, as in to_networkx's attrs: the name is listed once.
    exc.weights = (LENGTH, *(name for name, p in edge.items() if _numeric(p) and name != LENGTH))
    raise exc


def _by_edge(row: tuple) -> tuple:
    """Rows in edge order: of several edges the search cannot weigh, it names the lowest id, on every backend."""
    return row[2], row[0]


# --------------------------------------------------------------------------
# Shortest paths


def shortest_path(ref: MeshRef, a: int, b: int, weight: str | None = None) -> list[int]:
    """A shortest path from vertex ``a`` to vertex ``b``, as its vertices.

    ``weight=None`` counts edges: a bidirectional breadth-first search that
    expands the smaller side's whole frontier with one query. A weight sums
    the weights of the path's edges, the lightest of parallel ones counting,
    in a search from ``a`` that expands the `_BATCH` vertices of least
    estimate with one query, which brings what weighs their edges along:

    ``"length"``
        The Euclidean length of an edge, from its ends' positions: an A*
        search whose estimate is the straight-line distance to ``b`` (never
        more than the length of any way there, since an edge's length is the
        straight-line distance between its ends).
    the name of an edge property
        Its value: an ``int64`` or ``float64`` property of one value per
        edge (`NUMERIC`, no shape); an edge without a value weighs the
        property's default. Dijkstra's search (no estimate). An edge
        property named ``"length"`` is that property, as in
        `hestore.graphs.to_networkx`'s ``attrs``.

    The search weighs every edge at every vertex it expands — self-loops
    and the parallel edges it does not take included; ``a`` itself and, by a
    property, at least every vertex nearer to ``a`` than ``b`` is, and at
    most a batch more (never ``b``) — and refuses the first one (the lowest
    edge id of a batch) that has no weight or cannot be one: a length with an end without a position, a
    property value unset without a default, NaN or below 0 (Dijkstra's
    search is only right for weights of 0 or more). ``inf`` is a weight: a
    path across such an edge weighs ``inf``, and is the answer only when no
    lighter one exists. Edges the search never reaches are never read, so
    what they hold does not matter.

    Parameters
    ----------
    ref : hestore._session.MeshRef
        The mesh (its identity: the facade passes its own, `hestore._session.identity`).
    a, b : int
        The ids of the first and the last vertex.
    weight : None, "length" or str
        What a path's length is: its number of edges, the sum of their
        Euclidean lengths, or the sum of their values of an edge property.

    Returns
    -------
    list of int
        Vertex ids from ``a`` to ``b``, consecutive ones joined by an edge; ``[a]`` when
        ``a == b``. As short as networkx's ``shortest_path`` on the mesh's
        multigraph (weighted: weighing each pair of vertices by its lightest
        edge); among paths of equal length, any one.

    Raises
    ------
    NoPathError
        No path joins them (they are in different components).
    ElementNotFoundError
        ``a`` or ``b`` does not exist.
    PropertyNotFoundError
        ``weight`` is a name other than ``"length"`` that no edge property
        has; its ``weights`` attribute lists the names that weigh.
    InvalidInputError
        ``weight`` is neither None nor a name; it names an edge property
        that is not a number (``weights`` lists the names that weigh); or
        the search meets an edge it cannot weigh (see above), as ``hestore
        graph NAME path --weight`` says it.

    Examples
    --------
    From ``a`` to ``c`` along the legs of a right triangle (9 + 12) or along
    its hypotenuse (15), cut into three edges of 5; the edge ``b``–``c``
    costs 5, every other one the default 1:

    >>> from hestore._session import identity
    >>> import hestore
    >>> mesh = hestore.open("sqlite://").create_mesh("m")
    >>> xyz = [(0, 0, 0), (9, 0, 0), (9, 12, 0), (6, 8, 0), (3, 4, 0)]
    >>> a, b, c, q, p = (mesh.add_vertex(position) for position in xyz)
    >>> pentagon = mesh.add_polygon([a, b, c, q, p])
    >>> _ = mesh.add_property("edge", "cost", "int64", default=1)
    >>> mesh.find_halfedge(b, c).edge["cost"] = 5
    >>> shortest_path(identity(mesh), a.id, c.id)  # the fewest edges
    [0, 1, 2]
    >>> shortest_path(identity(mesh), a.id, c.id, "length")  # the shortest
    [0, 4, 3, 2]
    >>> shortest_path(identity(mesh), a.id, c.id, "cost")  # the cheapest: 3, not 6
    [0, 4, 3, 2]
    >>> lone = mesh.add_vertex()
    >>> shortest_path(identity(mesh), a.id, lone.id)
    Traceback (most recent call last):
    ...
    hestore.errors.NoPathError: no path from vertex 0 to vertex 5 in mesh 'm': they are in different components
    """
    weight = _weight_name(weight)
    with _consistent(ref):
        vertices = vertex_rows(ref, sorted({a, b}))  # both there, in one query
        weigher = _weigher(ref, weight, vertices, goal=b)
        if a == b:
            path = [a]
        elif weigher is None:
            path = _bfs_path(ref, a, b)
        else:
            path = _least_path(ref, a, b, weigher)
    if path is None:
        raise NoPathError(
            f"no path from vertex {a} to vertex {b} in {_described(ref)}: they are in different components"
        )
    return path


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
        for origin, target, _edge in _stars(ref, frontier):
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


def _least_path(ref: MeshRef, a: int, b: int, weigher: _Lengths | _Values) -> list[int] | None:
    """Least total weight: A* with the weigher's estimate (Dijkstra: 0), `_BATCH` vertices a query.

    A vertex may be expanded before its least weight is known (it was in a
    batch with a better one); it is queued again when a lighter way to it
    turns up, and the search stops only when no queued estimate is below
    the least weight found to ``b`` — so the answer is exact. ``b`` itself
    is never expanded. Weights of ``inf`` are kept: a vertex first reached
    at ``inf`` is recorded and expanded like any other.
    """
    zero = weigher.zero
    dist = {a: zero}
    parents: dict[int, int | None] = {a: None}
    expanded: dict[int, int | float] = {}
    best = None  # the least weight found to b

    def promising(queue: list) -> bool:
        return bool(queue) and (best is None or queue[0][0] < best)

    queue = [(zero, zero, a)]
    while promising(queue):
        batch = []
        while len(batch) < _BATCH and promising(queue):
            _, d, v = heapq.heappop(queue)
            if d > dist[v] or expanded.get(v) == d:
                continue  # a stale entry, or expanded at this distance already
            expanded[v] = d
            batch.append(v)
        if not batch:
            continue
        for row in sorted(weigher.rows(batch), key=_by_edge):
            origin, target = row[0], row[1]
            if target is None:
                raise _broken(ref, origin)
            w = weigher.weigh(row)
            if target == origin:
                continue
            d = dist[origin] + w
            if target not in dist or d < dist[target]:
                dist[target] = d
                parents[target] = origin
                if target == b:
                    best = d
                else:
                    heapq.heappush(queue, (d + weigher.estimate(target), d, target))
    if best is None:
        return None
    return _walk(parents, b)[::-1]


def path_weight(ref: MeshRef, path: list[int], weight: str | None = None) -> int | float:
    """The weight of a path: its number of edges, or the sum of its edges' weights as `shortest_path` weighs them.

    Each step from one vertex to the next weighs its lightest edge; every
    edge between the two is weighed, so one that cannot be (see
    `shortest_path`) is refused even when a parallel one could. One query
    for the vertices, one for the catalogue (with a weight), one for the
    edges out of every `MAX_IN` of them.

    Parameters
    ----------
    ref : hestore._session.MeshRef
        The mesh (its identity: the facade passes its own, `hestore._session.identity`).
    path : list of int
        Vertex ids, at least one; consecutive ones must be joined by an edge.
    weight : None, "length" or str
        As `shortest_path`'s.

    Returns
    -------
    int or float
        An ``int`` for None and ``int64`` properties (``0`` for a path of one
        vertex), a ``float`` for ``"length"`` and ``float64`` ones.

    Raises
    ------
    ElementNotFoundError
        A vertex of the path does not exist.
    PropertyNotFoundError, InvalidInputError
        As `shortest_path`'s; and `InvalidInputError` for an empty path or
        two consecutive vertices that no edge joins.

    Examples
    --------
    >>> from hestore._session import identity
    >>> import hestore
    >>> mesh = hestore.open("sqlite://").create_mesh("m")
    >>> a, b, c = (mesh.add_vertex((x, 0, 0)) for x in (0, 3, 7))
    >>> ab, bc, again = mesh.add_edge(a, b), mesh.add_edge(b, c), mesh.add_edge(b, c)
    >>> _ = mesh.add_property("edge", "toll", "float64", default=2.5)
    >>> again["toll"] = 0.5
    >>> path = [a.id, b.id, c.id]
    >>> ref = identity(mesh)
    >>> path_weight(ref, path), path_weight(ref, path, "length"), path_weight(ref, path, "toll")
    (2, 7.0, 3.0)
    """
    weight = _weight_name(weight)
    if not path:
        raise InvalidInputError("a path is a list of vertices, at least one, not an empty one")
    steps = list(zip(path, path[1:]))
    with _consistent(ref):
        vertices = vertex_rows(ref, sorted(set(path)))
        weigher = _weigher(ref, weight, vertices) or _Counts(ref)
        between: dict[tuple[int, int], list[tuple]] = {}
        wanted = set(steps)
        for row in sorted(weigher.rows(sorted({u for u, _ in steps})), key=_by_edge):
            if row[1] is None:
                raise _broken(ref, row[0])
            if (row[0], row[1]) in wanted:
                between.setdefault((row[0], row[1]), []).append(row)
    total = weigher.zero
    for u, v in steps:
        if (u, v) not in between:
            raise InvalidInputError(f"vertices {u} and {v} of the path are not joined by an edge in {_described(ref)}")
        total += min(weigher.weigh(row) for row in between[u, v])
    return total
