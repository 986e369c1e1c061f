"""The `Mesh` facade: one named half-edge structure in a store.

This module owns `Mesh`, the object users hold: it checks its arguments
(types, ownership of handles, positions), then delegates — edits to
`hestore._kernel` inside the session's atomic edit scope, reads to
`hestore.navigation`, summaries to `hestore.summary`, checks to
`hestore.validation`, bulk export to `hestore.bulk`, graph views to
`hestore.graphs`, pictures to `hestore.render` — and turns the ``(kind, id)`` pairs of a refused
operation's `TopologyError` into handles. It holds no state beyond its
identity (`hestore._session.MeshRef`) and policy.
"""

from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Iterable, Iterator, Sequence

from hestore import bulk, history, interop, navigation, properties, render, schema, summary, traversal, validation
from hestore import _euler as euler, _kernel as kernel, _values as values
from hestore.errors import (
    ElementNotFoundError,
    InvalidInputError,
    InvariantViolationError,
    ReadOnlyError,
    TopologyError,
    Violation,
    shown,
)
from hestore.handles import CLASSES, Edge, HalfEdge, Handle, Polygon, Vertex, element_id, wrap
from hestore._queries import Query, elements
from hestore._values import Property
from hestore._session import MeshRef
from hestore._unitofwork import UnitOfWork
from hestore.urls import check_path

if TYPE_CHECKING:  # pragma: no cover
    import networkx as nx

__all__ = ["Mesh", "Counts"]


@dataclass(frozen=True)
class Counts:
    """How many elements of each kind a mesh has."""

    vertices: int
    halfedges: int
    edges: int
    polygons: int


class Mesh:
    """A named mesh in a `Store`: create it with `Store.create_mesh`.

    Every editing method is atomic: it succeeds completely or raises and
    changes nothing (inside a transaction block too, which may go on).

    Attributes
    ----------
    store : Store
        The store the mesh lives in.
    allow_loops, allow_multi_edges : bool
        The mesh's policy (read-only: it is the mesh's identity's).

    Examples
    --------
    >>> import hestore
    >>> store = hestore.open("sqlite://")
    >>> mesh = store.create_mesh("fan")
    >>> c = mesh.add_vertex((0, 0, 0))
    >>> ring = [mesh.add_vertex((x, y, 0)) for x, y in [(1, 0), (0, 1), (-1, 0), (0, -1)]]
    >>> fan = [mesh.add_polygon([c, ring[i], ring[(i + 1) % 4]]) for i in range(4)]
    >>> mesh.counts()
    Counts(vertices=5, halfedges=16, edges=8, polygons=4)
    >>> c.is_boundary, len(c.polygons())
    (False, 4)
    """

    # The session and the mesh's identity in it are the engine's, not the API: the layers below the facade
    # read the identity through `hestore._session.identity`.
    __slots__ = ("store", "_session", "_ref")

    def __init__(self, store: Any, ref: MeshRef) -> None:
        self.store = store
        self._session = ref.session
        self._ref = ref

    @property
    def allow_loops(self) -> bool:
        """Whether self-loop edges may be added."""
        return self._ref.allow_loops

    @property
    def allow_multi_edges(self) -> bool:
        """Whether parallel edges may be added."""
        return self._ref.allow_multi_edges

    @property
    def id(self) -> int:
        """The mesh's id in its store's ``meshes`` table (the ``mesh_id`` of its rows)."""
        return self._ref.id

    @property
    def name(self) -> str:
        """The mesh's name."""
        return self._ref.name

    def __repr__(self) -> str:
        at = "" if self._ref.revision is None else f".at({self._ref.revision})"
        return f"Mesh({self.name!r}){at}"

    def _described(self) -> str:
        at = "" if self._ref.revision is None else f" at revision {self._ref.revision}"
        return f"mesh {self.name!r}{at}"

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Mesh) and other._ref is self._ref

    def __hash__(self) -> int:
        return hash(self._ref)

    # -- argument checking --------------------------------------------------

    def _own(self, handle: object, kind: type, what: str = "") -> int:
        if not isinstance(handle, kind):
            raise InvalidInputError(
                f"expected a {kind.__name__} handle{what}, got {type(handle).__name__} {shown(handle)}"
            )
        if handle.mesh != self:
            raise ElementNotFoundError(
                f"{handle!r} belongs to {handle.mesh._described()}, not to {self._described()}"
            )
        return handle.id

    @contextmanager
    def _edit(self, *, dry_run: bool = False) -> Iterator[UnitOfWork]:
        """The session's edit scope (or dry run), with a refusal's elements as handles of this mesh."""
        try:
            with (self._session.dry_run if dry_run else self._session.editing)(self._ref) as uow:
                yield uow
        except TopologyError as exc:
            exc.elements = tuple(CLASSES[kind](self, i) for kind, i in exc.refs if kind in CLASSES)
            raise

    def _fetch(self, query: Query) -> list[tuple]:
        return self._session.fetch(self._ref, query, {})

    # -- summaries ----------------------------------------------------------

    @property
    def revision(self) -> int:
        """Number of committed transactions that changed the mesh (plus the open one's, if it did).

        For a view of the past (`at`), the revision it shows.
        """
        if self._ref.revision is not None:
            self._session.check()
            return self._ref.revision
        rows = self._fetch(elements.revision)
        if not rows:
            raise self._session.missing(self._ref)
        return rows[0][0]

    # -- history (SPEC §4.1) -------------------------------------------------

    @property
    def is_view(self) -> bool:
        """Whether this is a read-only view of a past revision (`at`)."""
        return self._ref.revision is not None

    def at(self, revision: int) -> "Mesh":
        """A read-only view of the mesh as it was at ``revision`` (``at(0)`` is empty).

        The view has the whole read API — handles, navigation, `stats`,
        `check`, `to_arrays`, `to_networkx`, `export`, properties — and its
        handles belong to it. Its reads cost in proportion to what changed
        since ``revision``. Any edit raises `ReadOnlyError`.

        Raises
        ------
        RevisionNotFoundError
            The revision was never made or is no longer kept.

        Examples
        --------
        >>> import hestore
        >>> store = hestore.open("sqlite://")
        >>> mesh = store.import_arrays("tri", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [[0, 1, 2]]).mesh
        >>> mesh.remove_polygon(mesh.polygon(0))
        >>> mesh.counts().polygons, mesh.at(1).counts().polygons, mesh.at(0).counts().vertices
        (0, 1, 0)
        """
        base = self._ref.base or self._ref
        number = values.check_revision(revision)
        return Mesh(self.store, self._session.view(base, number))

    def history(self, limit: int | None = None) -> list[history.Revision]:
        """The kept revisions from 1 up, newest first; see `hestore.history.history`."""
        return history.history(self._base(), limit)

    def diff(self, a: int, b: int) -> history.Diff:
        """What differs between revisions ``a`` and ``b``; see `hestore.history.diff`."""
        return history.diff(self._base(), a, b)

    def undo(self) -> int:
        """Undo the most recent change not yet undone, as a new revision (returned); see `hestore.history.undo`."""
        return history.undo(self._writable())

    def redo(self) -> int:
        """Re-apply the most recently undone change, as a new revision (returned); see `hestore.history.redo`."""
        return history.redo(self._writable())

    def revert(self, revision: int) -> int:
        """Make the mesh equal to ``at(revision)``, as a new revision (returned); see `hestore.history.revert`."""
        return history.revert(self._writable(), revision)

    def prune_history(self, keep: int) -> int:
        """Keep only the newest ``keep`` revisions (the current one included); return the oldest kept.

        Older revisions can no longer be viewed, diffed, reverted or undone
        to; the rows that recorded them are deleted.

        Examples
        --------
        >>> import hestore
        >>> store = hestore.open("sqlite://")
        >>> mesh = store.create_mesh("m")
        >>> for _ in range(3):
        ...     _ = mesh.add_vertex()
        >>> mesh.prune_history(keep=1), [r.number for r in mesh.history()]
        (3, [3])
        """
        return history.prune(self._writable(), keep)

    def _base(self) -> MeshRef:
        """The identity of the mesh itself (of a view: of the mesh it shows)."""
        return self._ref.base or self._ref

    def _writable(self) -> MeshRef:
        """The mesh's identity, for an edit: `ReadOnlyError` for a view."""
        if self._ref.revision is not None:
            self._session.lock(self._ref)  # raises ReadOnlyError
        return self._ref

    def counts(self) -> Counts:
        """Number of vertices, half-edges, edges and polygons.

        Examples
        --------
        >>> import hestore
        >>> mesh = hestore.open("sqlite://").create_mesh("m")
        >>> mesh.counts()
        Counts(vertices=0, halfedges=0, edges=0, polygons=0)
        """
        exists, *counts = self._fetch(elements.counts)[0]
        if exists is None:
            raise self._session.missing(self._ref)
        return Counts(*counts)

    def stats(self, progress=None) -> summary.Stats:
        """Counts and topological invariants of the mesh; see `hestore.summary.stats` (and its ``progress``)."""
        return summary.stats(self._ref, progress)

    def boundary_loops(self) -> list[list[HalfEdge]]:
        """The cycles of free half-edges, each in ``next`` order; see `hestore.summary.boundary_loops`."""
        return [[wrap(HalfEdge, self, h) for h in loop] for loop in summary.boundary_loops(self._ref)]

    def components(self, progress=None) -> list[set[Vertex]]:
        """Connected components of the vertex–edge graph; see `hestore.summary.components` (and its ``progress``)."""
        return [{wrap(Vertex, self, v) for v in part} for part in summary.components(self._ref, progress)]

    # -- lookup and iteration -----------------------------------------------

    def _lookup(self, kind: str, i: object) -> Handle:
        i = element_id(i, schema.KINDS[kind].label)  # refuses what cannot be an id
        navigation.exists(self._ref, kind, i)
        return wrap(CLASSES[kind], self, i)

    def vertex(self, id: int) -> Vertex:
        """The vertex with this id (`ElementNotFoundError` if there is none).

        Examples
        --------
        >>> import hestore
        >>> mesh = hestore.open("sqlite://").create_mesh("m")
        >>> v = mesh.add_vertex()
        >>> mesh.vertex(0) == v
        True
        >>> mesh.vertex(1)
        Traceback (most recent call last):
        ...
        hestore.errors.ElementNotFoundError: vertex 1 does not exist in mesh 'm' (removed, or never created)
        """
        return self._lookup("vertex", id)

    def halfedge(self, id: int) -> HalfEdge:
        """The half-edge with this id (`ElementNotFoundError` if there is none)."""
        return self._lookup("halfedge", id)

    def edge(self, id: int) -> Edge:
        """The edge with this id (`ElementNotFoundError` if there is none)."""
        return self._lookup("edge", id)

    def polygon(self, id: int) -> Polygon:
        """The polygon with this id (`ElementNotFoundError` if there is none)."""
        return self._lookup("polygon", id)

    def vertices(self) -> Iterator[Vertex]:
        """All vertices, in id order."""
        return (Vertex(self, i) for i in navigation.ids(self._ref, "vertex"))

    def halfedges(self) -> Iterator[HalfEdge]:
        """All half-edges, in id order."""
        return (HalfEdge(self, i) for i in navigation.ids(self._ref, "halfedge"))

    def edges(self) -> Iterator[Edge]:
        """All edges, in id order."""
        return (Edge(self, i) for i in navigation.ids(self._ref, "edge"))

    def polygons(self) -> Iterator[Polygon]:
        """All polygons, in id order."""
        return (Polygon(self, i) for i in navigation.ids(self._ref, "polygon"))

    def find_halfedge(self, a: Vertex, b: Vertex) -> HalfEdge | None:
        """A half-edge from ``a`` to ``b``, preferring a free one; ``None`` if there is none.

        Examples
        --------
        >>> import hestore
        >>> mesh = hestore.open("sqlite://").create_mesh("m")
        >>> a, b, c = (mesh.add_vertex() for _ in range(3))
        >>> _ = mesh.add_edge(a, b)
        >>> mesh.find_halfedge(a, b), mesh.find_halfedge(a, c)
        (HalfEdge(0), None)
        """
        h = navigation.find_halfedge(self._ref, self._own(a, Vertex), self._own(b, Vertex))
        return None if h is None else HalfEdge(self, h)

    # -- editing ------------------------------------------------------------

    def add_vertex(self, position=None) -> Vertex:
        """Add an isolated vertex, optionally at ``position = (x, y, z)``.

        Examples
        --------
        >>> import hestore
        >>> mesh = hestore.open("sqlite://").create_mesh("m")
        >>> v = mesh.add_vertex((1, 2, 3))
        >>> v, v.position, v.is_isolated
        (Vertex(0), (1.0, 2.0, 3.0), True)
        """
        xyz = properties.check_position(position)
        with self._edit() as uow:
            return Vertex(self, kernel.add_vertex(uow, xyz))

    def _edge_ends(self, a: Vertex, b: Vertex) -> tuple[int, int]:
        return self._own(a, Vertex, " for a"), self._own(b, Vertex, " for b")

    def add_edge(self, a: Vertex, b: Vertex) -> Edge:
        """Add an edge from ``a`` to ``b`` (``a is b`` gives a self-loop).

        Both vertices must be free (isolated, or with a free outgoing
        half-edge). The edge's `Edge.halfedge` runs from ``a`` to ``b``.

        Raises
        ------
        VertexNotFreeError
            Every half-edge leaving ``a`` or ``b`` has a polygon.
        PolicyError
            The mesh forbids self-loops or parallel edges and this is one.

        Examples
        --------
        >>> import hestore
        >>> mesh = hestore.open("sqlite://").create_mesh("m", allow_multi_edges=False)
        >>> a, b = mesh.add_vertex(), mesh.add_vertex()
        >>> mesh.add_edge(a, b)
        Edge(0)
        >>> mesh.add_edge(b, a)
        Traceback (most recent call last):
        ...
        hestore.errors.PolicyError: vertices 1 and 0 are already joined by edge 0; this mesh does not allow ...
        """
        ia, ib = self._edge_ends(a, b)
        with self._edit() as uow:
            return Edge(self, kernel.add_edge(uow, ia, ib))

    def can_add_edge(self, a: Vertex, b: Vertex) -> bool:
        """Whether `add_edge` would succeed; nothing is written and no lock is taken.

        The answer is from the same checks `add_edge` runs, on the state this
        store sees now (another writer may change it before an `add_edge`).
        Malformed input raises as `add_edge` would.

        Examples
        --------
        >>> import hestore
        >>> mesh = hestore.open("sqlite://").create_mesh("m", allow_loops=False)
        >>> a, b = mesh.add_vertex(), mesh.add_vertex()
        >>> mesh.can_add_edge(a, b), mesh.can_add_edge(a, a)
        (True, False)
        """
        return self._can(kernel.add_edge, *self._edge_ends(a, b))

    def _loop_ids(self, loop: Sequence) -> tuple[str, list[int]]:
        items = values.check_items(loop, "a polygon is a sequence of Vertex or of HalfEdge handles")
        if not items:
            raise InvalidInputError("a polygon needs at least one vertex or half-edge")
        kind = type(items[0])
        if kind not in (Vertex, HalfEdge) or any(type(x) is not kind for x in items):
            raise InvalidInputError(
                "a polygon is given either by Vertex handles or by HalfEdge handles, all of one kind; got "
                + ", ".join(sorted({type(x).__name__ for x in items}))
            )
        return ("vertex" if kind is Vertex else "halfedge"), [self._own(x, kind) for x in items]

    @staticmethod
    def _add_polygon(uow: UnitOfWork, kind: str, ids: list[int]) -> int:
        if kind == "vertex":
            return kernel.add_polygon_from_vertices(uow, ids)
        return kernel.add_polygon(uow, ids)

    def add_polygon(self, loop: Sequence[Vertex] | Sequence[HalfEdge]) -> Polygon:
        """Add a polygon to the left of a loop of half-edges or through a cycle of vertices.

        ``loop`` is either a sequence of `HalfEdge` that chain (each ends where
        the next starts, cyclically) and are all free, or a sequence of
        `Vertex` in counter-clockwise order. For vertices, between
        consecutive ones a free half-edge is used if there is one; a new edge
        is created only where no edge joins them at all. Links around each
        corner are reordered (the seed's ``makeAdjacent``) when needed.

        Raises
        ------
        NotAChainError
            Consecutive half-edges do not meet.
        HalfEdgeNotFreeError
            A half-edge already has a polygon, or every half-edge between two
            consecutive vertices does ("complex edge").
        NonManifoldError
            A corner has no free gap to reorder into ("complex vertex").
        VertexNotFreeError, PolicyError
            A needed new edge cannot be added.

        Examples
        --------
        >>> import hestore
        >>> mesh = hestore.open("sqlite://").create_mesh("m")
        >>> v = mesh.add_vertex()
        >>> one_gon = mesh.add_polygon([v])          # a 1-gon on a new self-loop
        >>> one_gon.degree, one_gon.edges()[0].is_loop
        (1, True)
        """
        kind, ids = self._loop_ids(loop)
        with self._edit() as uow:
            return Polygon(self, self._add_polygon(uow, kind, ids))

    def can_add_polygon(self, loop: Sequence[Vertex] | Sequence[HalfEdge]) -> bool:
        """Whether `add_polygon` would succeed; nothing is written and no lock is taken.

        The answer is from the same checks `add_polygon` runs (it runs the
        operation and throws it away), on the state this store sees now:
        outside a block in a read-only transaction, so the question never
        waits for a writer and never raises `StoreBusyError`. Malformed input
        (not handles, handles of another mesh or of removed elements) still
        raises, as `add_polygon` would.

        Examples
        --------
        >>> import hestore
        >>> mesh = hestore.open("sqlite://").create_mesh("m")
        >>> a, b, c = (mesh.add_vertex() for _ in range(3))
        >>> _ = mesh.add_polygon([a, b, c])
        >>> mesh.can_add_polygon([a, b, c]), mesh.can_add_polygon([a, c, b])
        (False, True)
        """
        return self._can(self._add_polygon, *self._loop_ids(loop))

    def remove_polygon(self, p: Polygon) -> None:
        """Remove a polygon; its half-edges become free and its edges stay.

        Examples
        --------
        >>> import hestore
        >>> mesh = hestore.open("sqlite://").create_mesh("m")
        >>> p = mesh.add_polygon([mesh.add_vertex() for _ in range(3)])
        >>> mesh.remove_polygon(p); mesh.counts()
        Counts(vertices=3, halfedges=6, edges=3, polygons=0)
        """
        ip = self._own(p, Polygon)
        with self._edit() as uow:
            kernel.remove_polygon(uow, ip)

    def remove_edge(self, e: Edge) -> None:
        """Remove an edge together with the polygons on both of its sides.

        Examples
        --------
        >>> import hestore
        >>> mesh = hestore.open("sqlite://").create_mesh("m")
        >>> p = mesh.add_polygon([mesh.add_vertex() for _ in range(3)])
        >>> mesh.remove_edge(p.edges()[0]); mesh.counts()
        Counts(vertices=3, halfedges=4, edges=2, polygons=0)
        """
        ie = self._own(e, Edge)
        with self._edit() as uow:
            kernel.remove_edge(uow, ie)

    def remove_vertex(self, v: Vertex) -> None:
        """Remove a vertex with every edge (and so every polygon) touching it.

        Examples
        --------
        >>> import hestore
        >>> mesh = hestore.open("sqlite://").create_mesh("m")
        >>> vs = [mesh.add_vertex() for _ in range(3)]
        >>> _ = mesh.add_polygon(vs)
        >>> mesh.remove_vertex(vs[0]); mesh.counts()
        Counts(vertices=2, halfedges=2, edges=1, polygons=0)
        """
        iv = self._own(v, Vertex)
        with self._edit() as uow:
            kernel.remove_vertex(uow, iv)

    # -- Euler operators ----------------------------------------------------

    def _can(self, check, *args) -> bool:
        """Whether an operation's checks pass: run in a dry run, nothing written, no lock taken.

        On a view of the past (`at`) every operation would raise `ReadOnlyError`: the answer is False.
        """
        try:
            with self._edit(dry_run=True) as uow:
                check(uow, *args)
        except (TopologyError, ReadOnlyError):
            return False
        return True

    def _corner_arg(self, x: object, name: str) -> tuple[str, int]:
        if isinstance(x, Vertex):
            return "vertex", self._own(x, Vertex)
        if isinstance(x, HalfEdge):
            return "halfedge", self._own(x, HalfEdge)
        raise InvalidInputError(f"{name} is a corner: a Vertex or a HalfEdge handle, not {type(x).__name__} {shown(x)}")

    def split_edge(self, e: Edge, position=None, *, triangulate: bool = False) -> Vertex:
        """Put a new vertex on an edge; each polygon beside it gains that corner.

        ``e`` keeps its id and now ends at the new vertex; a new edge runs
        from the new vertex to ``e``'s old end (PostGIS ``ST_ModEdgeSplit``).
        A self-loop becomes two parallel edges. The new vertex is at
        ``position``, else at the midpoint of the ends when both have one;
        its properties are the ends' mean (``float64``) or the first end's.

        With ``triangulate=True`` each triangle beside ``e`` is also cut from
        the new vertex to its opposite corner, so a triangle mesh stays one
        (pmp's and OpenMesh's triangle ``split``: a lone triangle gives
        V 3→4, E 3→5, F 1→2). The cut-off triangle is a new polygon with
        the old one's values.

        Raises
        ------
        PolicyError
            ``e`` is a loop and the mesh forbids parallel edges.

        Examples
        --------
        >>> import hestore
        >>> mesh = hestore.open("sqlite://").create_mesh("m")
        >>> a, b, c = (mesh.add_vertex(xyz) for xyz in [(0, 0, 0), (2, 0, 0), (0, 2, 0)])
        >>> t = mesh.add_polygon([a, b, c])
        >>> v = mesh.split_edge(mesh.find_halfedge(a, b).edge)
        >>> v.position, t.degree, mesh.counts()
        ((1.0, 0.0, 0.0), 4, Counts(vertices=4, halfedges=8, edges=4, polygons=1))
        >>> _ = mesh.split_polygon(t, v, c)  # the same as split_edge(..., triangulate=True)
        >>> sorted(p.degree for p in mesh.polygons()), mesh.counts().edges
        ([3, 3], 5)
        """
        ie = self._own(e, Edge)
        xyz = properties.check_position(position)
        triangulate = values.check_flag(triangulate, "triangulate")
        with self._edit() as uow:
            return Vertex(self, euler.split_edge(uow, ie, xyz, triangulate))

    def can_split_edge(self, e: Edge, *, triangulate: bool = False) -> bool:
        """Whether `split_edge` would succeed; nothing is written and no lock is taken.

        Only a mesh that forbids parallel edges refuses a split: of a loop,
        or with ``triangulate`` where a cut would double an edge.
        """
        triangulate = values.check_flag(triangulate, "triangulate")
        return self._can(euler.check_split_edge, self._own(e, Edge), triangulate)

    def split_polygon(self, p: Polygon, a: Vertex | HalfEdge, b: Vertex | HalfEdge) -> Edge:
        """Cut a polygon in two with a new edge between two of its corners; return the edge.

        ``a`` and ``b`` are corners of ``p``: vertices, or half-edges of ``p``
        (whose origins are the corners) where a vertex is a corner more than
        once. ``p`` keeps the part holding ``p.halfedge``; the other part is
        a new polygon with ``p``'s property values. The new edge runs from
        ``a`` to ``b``.

        Raises
        ------
        EulerError
            ``a`` or ``b`` is not a corner of ``p`` (``"not-corner"``), they are
            the same corner (``"same-corner"``) or adjacent (``"adjacent-corners"``).
        PolicyError
            The new edge would be a loop or a parallel edge the mesh forbids.

        Examples
        --------
        >>> import hestore
        >>> mesh = hestore.open("sqlite://").create_mesh("m")
        >>> vs = [mesh.add_vertex() for _ in range(4)]
        >>> quad = mesh.add_polygon(vs)
        >>> e = mesh.split_polygon(quad, vs[0], vs[2])
        >>> [p.degree for p in mesh.polygons()], mesh.can_split_polygon(quad, vs[0], vs[1])
        ([3, 3], False)
        """
        ip = self._own(p, Polygon)
        ca, cb = self._corner_arg(a, "a"), self._corner_arg(b, "b")
        with self._edit() as uow:
            return Edge(self, euler.split_polygon(uow, ip, ca, cb))

    def can_split_polygon(self, p: Polygon, a: Vertex | HalfEdge, b: Vertex | HalfEdge) -> bool:
        """Whether `split_polygon` would succeed; nothing is written and no lock is taken."""
        corners = self._corner_arg(a, "a"), self._corner_arg(b, "b")
        return self._can(euler.check_split_polygon, self._own(p, Polygon), *corners)

    def join_polygons(self, e: Edge) -> Polygon:
        """Remove an edge and merge the two polygons beside it into the one left of ``e.halfedge``.

        The other polygon is removed (PostGIS ``ST_RemEdgeModFace``); the
        survivor keeps its property values.

        Raises
        ------
        EulerError
            A side of ``e`` is free (``"boundary"``), both sides are one
            polygon (``"same-polygon"``), or both are 1-gons on a loop
            (``"degenerate"``: nothing would be left).

        Examples
        --------
        >>> import hestore
        >>> mesh = hestore.open("sqlite://").create_mesh("m")
        >>> vs = [mesh.add_vertex() for _ in range(4)]
        >>> t1, t2 = mesh.add_polygon([vs[0], vs[1], vs[2]]), mesh.add_polygon([vs[0], vs[2], vs[3]])
        >>> quad = mesh.join_polygons(mesh.find_halfedge(vs[0], vs[2]).edge)
        >>> quad == t1, quad.degree, mesh.counts().edges
        (True, 4, 4)
        """
        ie = self._own(e, Edge)
        with self._edit() as uow:
            return Polygon(self, euler.join_polygons(uow, ie))

    def can_join_polygons(self, e: Edge) -> bool:
        """Whether `join_polygons` would succeed; nothing is written and no lock is taken."""
        return self._can(euler.check_join_polygons, self._own(e, Edge))

    def poke_polygon(self, p: Polygon, position=None) -> Vertex:
        """Put a new vertex inside a polygon, joined to every corner: ``p.degree`` triangles.

        ``p`` keeps the triangle on ``p.halfedge``; the others are new
        polygons with ``p``'s values. The vertex is at ``position``, else at
        the centroid of the corners when all have positions.

        Raises
        ------
        PolicyError
            ``p`` passes a vertex twice and the mesh forbids parallel edges.

        Examples
        --------
        >>> import hestore
        >>> mesh = hestore.open("sqlite://").create_mesh("m")
        >>> quad = mesh.add_polygon([mesh.add_vertex(xyz) for xyz in [(0, 0, 0), (2, 0, 0), (2, 2, 0), (0, 2, 0)]])
        >>> c = mesh.poke_polygon(quad)
        >>> c.position, c.degree, sorted(p.degree for p in mesh.polygons())
        ((1.0, 1.0, 0.0), 4, [3, 3, 3, 3])
        """
        ip = self._own(p, Polygon)
        xyz = properties.check_position(position)
        with self._edit() as uow:
            return Vertex(self, euler.poke_polygon(uow, ip, xyz))

    def can_poke_polygon(self, p: Polygon) -> bool:
        """Whether `poke_polygon` would succeed; nothing is written and no lock is taken."""
        return self._can(euler.check_poke_polygon, self._own(p, Polygon))

    def flip_edge(self, e: Edge) -> Edge:
        """Turn the diagonal of the two triangles beside an edge; every id is kept.

        Raises
        ------
        EulerError
            A side is free (``"boundary"``), not a triangle (``"not-triangle"``),
            both sides are one polygon (``"same-polygon"``), the triangles share
            their third vertex (``"degenerate"``), or the new edge would join
            two vertices already joined (``"duplicate-edge"``, pmp's ``is_flip_ok``).

        Examples
        --------
        >>> import hestore
        >>> mesh = hestore.open("sqlite://").create_mesh("m")
        >>> vs = [mesh.add_vertex() for _ in range(4)]
        >>> _ = mesh.add_polygon([vs[0], vs[1], vs[2]]), mesh.add_polygon([vs[0], vs[2], vs[3]])
        >>> e = mesh.flip_edge(mesh.find_halfedge(vs[0], vs[2]).edge)
        >>> sorted(v.id for v in e.vertices()), mesh.find_halfedge(vs[0], vs[2])
        ([1, 3], None)
        """
        ie = self._own(e, Edge)
        with self._edit() as uow:
            return Edge(self, euler.flip_edge(uow, ie))

    def can_flip_edge(self, e: Edge) -> bool:
        """Whether `flip_edge` would succeed; nothing is written and no lock is taken."""
        return self._can(euler.check_flip_edge, self._own(e, Edge))

    def collapse_edge(self, h: HalfEdge) -> Vertex:
        """Merge ``h.origin`` into ``h.target``, which survives with its position and values.

        Polygons beside the edge lose a corner; a triangle beside it vanishes
        and its two other edges become one (the one at the target stays):
        inside a triangle mesh, V − 1, E − 3, F − 2 (OpenMesh's ``collapse``).

        Raises
        ------
        EulerError
            The result would not be representable or would degenerate — the
            link condition of OpenMesh's ``is_collapse_ok``, generalised:
            ``"loop"``, ``"same-polygon"``, ``"degenerate"`` (a 1-gon, a
            dangling edge), ``"link-condition"`` (edges or polygons away from
            the edge would merge, or the surface would pinch).

        Examples
        --------
        >>> import hestore
        >>> mesh = hestore.open("sqlite://").create_mesh("m")
        >>> vs = [mesh.add_vertex(xyz) for xyz in [(0, 1, 0), (1, 0, 0), (1, 1, 0), (1, 2, 0), (2, 1, 0)]]
        >>> fan = [mesh.add_polygon([vs[i] for i in t]) for t in [(0, 2, 1), (0, 3, 2), (4, 2, 3), (4, 1, 2)]]
        >>> w = mesh.collapse_edge(mesh.find_halfedge(vs[2], vs[1]))
        >>> w, w.position, mesh.counts()
        (Vertex(1), (1.0, 0.0, 0.0), Counts(vertices=4, halfedges=10, edges=5, polygons=2))
        >>> [[v.id for v in p.vertices()] for p in mesh.polygons()], mesh.check()
        ([[0, 3, 1], [4, 1, 3]], [])
        """
        ih = self._own(h, HalfEdge)
        with self._edit() as uow:
            return Vertex(self, euler.collapse_edge(uow, ih))

    def can_collapse_edge(self, h: HalfEdge) -> bool:
        """Whether `collapse_edge` would succeed; nothing is written and no lock is taken."""
        return self._can(euler.check_collapse_edge, self._own(h, HalfEdge))

    def heal_edges(self, e1: Edge, e2: Edge) -> Edge:
        """Merge two edges that meet at a vertex of degree 2 into ``e1``; that vertex is removed.

        Polygons through the vertex lose that corner (PostGIS ``ST_ModEdgeHeal``).

        Raises
        ------
        EulerError
            ``e1 == e2`` (``"same-edge"``), either is a loop (``"loop"``), they
            share no vertex (``"not-adjacent"``) or other edges meet there (``"degree"``).
        PolicyError
            The healed edge would be a loop or a parallel edge the mesh forbids.

        Examples
        --------
        >>> import hestore
        >>> mesh = hestore.open("sqlite://").create_mesh("m")
        >>> a, b, c = (mesh.add_vertex() for _ in range(3))
        >>> e1, e2 = mesh.add_edge(a, b), mesh.add_edge(b, c)
        >>> mesh.heal_edges(e1, e2), e1.vertices(), mesh.counts().vertices
        (Edge(0), (Vertex(0), Vertex(2)), 2)
        """
        i1, i2 = self._own(e1, Edge, " for e1"), self._own(e2, Edge, " for e2")
        with self._edit() as uow:
            return Edge(self, euler.heal_edges(uow, i1, i2))

    def can_heal_edges(self, e1: Edge, e2: Edge) -> bool:
        """Whether `heal_edges` would succeed; nothing is written and no lock is taken."""
        return self._can(euler.check_heal_edges, self._own(e1, Edge, " for e1"), self._own(e2, Edge, " for e2"))

    def fill_hole(self, h: HalfEdge) -> Polygon:
        """Give the boundary loop of the free half-edge ``h`` a new polygon.

        Raises
        ------
        HalfEdgeNotFreeError
            ``h`` already has a polygon.

        Examples
        --------
        >>> import hestore
        >>> mesh = hestore.open("sqlite://").create_mesh("m")
        >>> p = mesh.add_polygon([mesh.add_vertex() for _ in range(5)])
        >>> q = mesh.fill_hole(p.halfedge.twin)
        >>> q.degree, mesh.stats().is_closed
        (5, True)
        """
        ih = self._own(h, HalfEdge)
        with self._edit() as uow:
            return Polygon(self, euler.fill_hole(uow, ih))

    def can_fill_hole(self, h: HalfEdge) -> bool:
        """Whether `fill_hole` would succeed (whether ``h`` is free); nothing is written."""
        return self._can(euler.check_fill_hole, self._own(h, HalfEdge))

    def triangulate_polygon(self, p: Polygon) -> list[Polygon]:
        """Cut a polygon into a fan of triangles from the corner of ``p.halfedge``.

        ``p`` keeps its id as the first triangle; the others are new polygons
        with ``p``'s values. A triangle (or a 1-gon or 2-gon, which cannot be
        cut) is returned as ``[p]``.

        Raises
        ------
        PolicyError
            A diagonal of the fan would be a loop or a parallel edge the mesh forbids.

        Examples
        --------
        >>> import hestore
        >>> mesh = hestore.open("sqlite://").create_mesh("m")
        >>> hexagon = mesh.add_polygon([mesh.add_vertex() for _ in range(6)])
        >>> triangles = mesh.triangulate_polygon(hexagon)
        >>> triangles[0] == hexagon, [t.degree for t in triangles]
        (True, [3, 3, 3, 3])
        """
        ip = self._own(p, Polygon)
        with self._edit() as uow:
            return [Polygon(self, q) for q in euler.triangulate_polygon(uow, ip)]

    def can_triangulate_polygon(self, p: Polygon) -> bool:
        """Whether `triangulate_polygon` would succeed; nothing is written and no lock is taken."""
        return self._can(euler.check_triangulate_polygon, self._own(p, Polygon))

    def separate_nonmanifold_vertices(self) -> dict[Vertex, list[Vertex]]:
        """Give each polygon fan of every pinched vertex a vertex of its own, in one transaction.

        A pinched vertex is one where more than one fan of polygons meets
        (`Stats.pinched_vertices`). Its first fan, and any wire edges, stay;
        every other fan moves to a new vertex with the same position and
        property values. No polygon, edge or half-edge changes; afterwards
        ``stats().pinched_vertices`` is 0.

        Returns
        -------
        dict
            Each pinched vertex, with the vertices made for its other fans.

        Examples
        --------
        Two triangles meeting only at vertex 0 (a "bowtie") come apart:

        >>> import hestore
        >>> store = hestore.open("sqlite://")
        >>> xyz = [(0, 0, 0), (1, 1, 0), (-1, 1, 0), (-1, -1, 0), (1, -1, 0)]
        >>> mesh = store.import_arrays("bowtie", xyz, [[0, 1, 2], [0, 3, 4]]).mesh
        >>> mesh.separate_nonmanifold_vertices()
        {Vertex(0): [Vertex(5)]}
        >>> mesh.vertex(5).position, mesh.stats().pinched_vertices, mesh.stats().components
        ((0.0, 0.0, 0.0), 0, 2)
        """
        pinched = summary.pinched_vertices(self._writable())
        if not pinched:
            return {}
        with self._edit() as uow:
            made = {v: euler.separate_fans(uow, v) for v in pinched}
        return {Vertex(self, v): [Vertex(self, w) for w in ws] for v, ws in made.items() if ws}

    # -- positions and properties -------------------------------------------

    def _element(self, handle: object, kind: type) -> int:
        """A handle of this mesh, or an id, as an id."""
        return self._own(handle, kind) if isinstance(handle, Handle) else element_id(handle, kind.kind)

    def _elements(self, items: object, kind: type) -> object:
        """A sequence of handles of this mesh as ids; anything else is left for the callee to check."""
        if isinstance(items, (list, tuple)) and any(isinstance(x, Handle) for x in items):
            return [self._own(x, kind) for x in items]
        return items

    def set_position(self, v: Vertex, position) -> None:
        """Move a vertex to ``position = (x, y, z)``, or take its position away with None.

        An edit like any other: atomic, inside or outside a block, rolled back
        with it, counted in `revision`. Coordinates must be finite.

        Examples
        --------
        >>> import hestore
        >>> mesh = hestore.open("sqlite://").create_mesh("m")
        >>> v = mesh.add_vertex((0, 0, 0))
        >>> mesh.set_position(v, (1, 2, 3)); v.position
        (1.0, 2.0, 3.0)
        >>> mesh.set_position(v, None); v.position is None
        True
        """
        properties.set_position(self._ref, self._element(v, Vertex), position)

    def set_positions(self, vertices, positions) -> None:
        """Move many vertices at once: one set-based write; see `hestore.properties.set_positions`.

        ``vertices`` are `Vertex` handles or ids (each once), ``positions``
        an ``(n, 3)`` array of finite numbers.

        Examples
        --------
        >>> import hestore
        >>> store = hestore.open("sqlite://")
        >>> mesh = store.import_arrays("t", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [[0, 1, 2]]).mesh
        >>> arrays = mesh.to_arrays()
        >>> mesh.set_positions(arrays.vertex_ids, arrays.positions * 2)
        >>> mesh.vertex(1).position
        (2.0, 0.0, 0.0)
        """
        properties.set_positions(self._writable(), self._elements(vertices, Vertex), positions)

    def add_property(self, kind: str, name: str, dtype: str, *, shape: tuple = (), default=None) -> Property:
        """Declare a property on every element of a kind; see `hestore.properties.add_property`.

        Examples
        --------
        >>> import hestore
        >>> mesh = hestore.open("sqlite://").create_mesh("m")
        >>> mesh.add_property("polygon", "label", "str", default="")
        Property(kind='polygon', name='label', dtype='str', shape=(), default='')
        """
        return properties.add_property(self._ref, kind, name, dtype, shape=shape, default=default)

    def properties(self, kind: str) -> dict[str, Property]:
        """The properties declared on a kind, by name; see `hestore.properties.properties`."""
        return properties.properties(self._ref, kind)

    def remove_property(self, kind: str, name: str) -> None:
        """Remove a property with all its values; see `hestore.properties.remove_property`."""
        properties.remove_property(self._ref, kind, name)

    def property_array(self, kind: str, name: str):
        """``(ids, values)`` of every live element of a kind; see `hestore.properties.property_array`."""
        return properties.property_array(self._ref, kind, name)

    def set_property_array(self, kind: str, name: str, ids, values) -> None:
        """Set many elements' values at once; see `hestore.properties.set_property_array`.

        ``ids`` are ids, or handles of the kind.
        """
        cls = CLASSES.get(kind, Handle) if isinstance(kind, str) else Handle  # a bad kind is the callee's to refuse
        properties.set_property_array(self._ref, kind, name, self._elements(ids, cls), values)

    # -- graph views and bulk export -------------------------------------------

    def to_networkx(
        self,
        kind: str = "multigraph",
        attrs: Iterable[str] | None = None,
        *,
        vertices: Iterable[Vertex] | None = None,
        progress=None,
    ) -> "nx.Graph":
        """A frozen networkx graph of the committed state; see `hestore.graphs.to_networkx`.

        Parameters
        ----------
        kind : {"multigraph", "graph", "halfedge", "dual"}
        attrs : list of str, optional
            Properties to put on nodes and edges, by name, and ``"length"``
            (the Euclidean length of each edge, from its ends' positions).
            An element without a value (a property without a default,
            unset) has no such attribute. An unknown name raises
            `hestore.PropertyNotFoundError`.
        vertices : iterable of Vertex, optional
            For the vertex kinds: the view induced by these vertices, equal
            to the whole view's ``subgraph`` of their ids, read from their
            rows only (a local query: it sees an open block's edits, as
            `k_ring` does). A handle of another mesh or of a removed vertex
            raises `hestore.ElementNotFoundError`; anything but handles,
            or ``kind="dual"``, `hestore.InvalidInputError`.

        Examples
        --------
        A weighted shortest path: the lighter way round a square of side 1,
        where the top edge weighs 5:

        >>> import hestore, networkx as nx
        >>> mesh = hestore.open("sqlite://").create_mesh("m")
        >>> vs = [mesh.add_vertex(xyz) for xyz in [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]]
        >>> square = mesh.add_polygon(vs)
        >>> _ = mesh.add_property("edge", "cost", "float64", default=1.0)
        >>> mesh.find_halfedge(vs[2], vs[3]).edge["cost"] = 5.0
        >>> G = mesh.to_networkx(attrs=["cost", "length"])
        >>> nx.shortest_path(G, 3, 2, weight="cost"), nx.shortest_path(G, 3, 2, weight="length")
        ([3, 0, 1, 2], [3, 2])
        """
        # Imported here, not at the top: it imports networkx, which `import hestore` need not pay for.
        from hestore import graphs

        ids = None if vertices is None else self._vertex_ids(vertices, "vertices")
        return graphs.to_networkx(self._ref, kind, attrs, ids, progress)

    def _vertex_ids(self, vertices: object, what: str) -> list[int]:
        """The ids of an iterable of `Vertex` handles of this mesh."""
        items = values.check_items(vertices, f"{what} is an iterable of Vertex handles", ordered=False)
        return [self._own(v, Vertex, f" in {what}") for v in items]

    # -- local graph queries ----------------------------------------------------

    def k_ring(self, v: Vertex, k: int) -> set[Vertex]:
        """The vertices within ``k`` edges of ``v``, ``v`` included; see `hestore.traversal.k_ring`.

        Examples
        --------
        >>> import hestore
        >>> mesh = hestore.open("sqlite://").create_mesh("m")
        >>> a, b, c, d = (mesh.add_vertex() for _ in range(4))
        >>> ab, bc, loop = mesh.add_edge(a, b), mesh.add_edge(b, c), mesh.add_edge(a, a)
        >>> sorted(v.id for v in mesh.k_ring(a, 1)), sorted(v.id for v in mesh.k_ring(a, 5))
        ([0, 1], [0, 1, 2])
        """
        return {wrap(Vertex, self, i) for i in traversal.k_ring(self._ref, self._own(v, Vertex, " for v"), k)}

    def shortest_path(self, a: Vertex, b: Vertex, weight: str | None = None) -> list[Vertex]:
        """A shortest path from ``a`` to ``b``: fewest edges, least total ``"length"``, or least total value of
        a numeric edge property; see `hestore.traversal.shortest_path`.

        Raises `hestore.NoPathError` when no path joins them.

        Examples
        --------
        >>> import hestore
        >>> mesh = hestore.open("sqlite://").create_mesh("m")
        >>> a, b, c = (mesh.add_vertex((x, 0, 0)) for x in (0, 1, 3))
        >>> ab, bc, ac = mesh.add_edge(a, b), mesh.add_edge(b, c), mesh.add_edge(a, c)
        >>> mesh.shortest_path(a, c), mesh.shortest_path(a, c, weight="length"), mesh.shortest_path(b, b)
        ([Vertex(0), Vertex(2)], [Vertex(0), Vertex(2)], [Vertex(1)])
        >>> _ = mesh.add_property("edge", "cost", "float64", default=1.0)
        >>> ac["cost"] = 5.0
        >>> mesh.shortest_path(a, c, weight="cost")
        [Vertex(0), Vertex(1), Vertex(2)]
        """
        a, b = self._own(a, Vertex, " for a"), self._own(b, Vertex, " for b")
        path = traversal.shortest_path(self._ref, a, b, weight)
        return [wrap(Vertex, self, i) for i in path]

    def path_weight(self, path: Sequence[Vertex], weight: str | None = None) -> int | float:
        """The weight of a path of `Vertex` handles, as `shortest_path` weighs it: its number of edges
        (``weight=None``), or the sum of its edges' lengths or values; see `hestore.traversal.path_weight`.

        Examples
        --------
        >>> import hestore
        >>> mesh = hestore.open("sqlite://").create_mesh("m")
        >>> a, b, c = (mesh.add_vertex((x, 0, 0)) for x in (0, 1, 3))
        >>> ab, bc, ac = mesh.add_edge(a, b), mesh.add_edge(b, c), mesh.add_edge(a, c)
        >>> _ = mesh.add_property("edge", "cost", "int64", default=2)
        >>> path = mesh.shortest_path(a, c, weight="cost")
        >>> path, mesh.path_weight(path), mesh.path_weight(path, "length"), mesh.path_weight(path, "cost")
        ([Vertex(0), Vertex(2)], 1, 3.0, 2)
        """
        ids = [self._own(v, Vertex, " in the path") for v in values.check_items(path, "a path is a list of Vertex")]
        return traversal.path_weight(self._ref, ids, weight)

    def dual(self, name: str) -> "Mesh":
        """Store the dual of this closed mesh as a new mesh called ``name``, and return it; see `hestore.bulk.dual`.

        Stored like an import (`hestore.Store.import_arrays`): one
        transaction; a taken name is `MeshExistsError`.

        Examples
        --------
        The dual of an octahedron is a cube:

        >>> import hestore
        >>> store = hestore.open("sqlite://")
        >>> xyz = [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)]
        >>> faces = [[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]]
        >>> cube = store.import_arrays("octahedron", xyz, faces).mesh.dual("cube")
        >>> cube.counts(), cube.stats().polygon_sizes, cube.check()
        (Counts(vertices=8, halfedges=24, edges=12, polygons=6), {4: 6}, [])
        """
        name = values.check_name(name, "a mesh name")  # before the dual is computed
        return self.store.import_arrays(name, *bulk.dual(self._ref)).mesh

    def to_arrays(self) -> bulk.MeshArrays:
        """``(positions, polygons, vertex_ids)``; see `hestore.bulk.to_arrays`.

        Examples
        --------
        >>> import hestore
        >>> mesh = hestore.open("sqlite://").import_arrays("t", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [[0, 1, 2]]).mesh
        >>> mesh.to_arrays().polygons.tolist()
        [[0, 1, 2]]
        """
        return bulk.to_arrays(self._ref)

    def export(self, path, **options) -> None:
        """Write the mesh to an OFF, OBJ or PLY file (`hestore.bulk.export`), or STL, VTK, VTU through meshio.

        STL holds triangles only: other polygons are written as fans
        (`hestore.interop.write_meshio_file`).
        """
        path = check_path(path)
        if path.lower().endswith(interop.MESHIO_EXTENSIONS):
            interop.write_meshio_file(self._ref, path)
            return
        bulk.export(self._ref, path, **options)

    def to_trimesh(self):
        """The mesh as a ``trimesh.Trimesh`` (needs trimesh); see `hestore.interop.to_trimesh`."""
        return interop.to_trimesh(self._ref)

    def to_meshio(self):
        """The mesh as a ``meshio.Mesh`` (needs meshio); see `hestore.interop.to_meshio`."""
        return interop.to_meshio(self._ref)

    # -- pictures -----------------------------------------------------------

    def plot(self, ax=None, **options):
        """Draw the mesh on a matplotlib Axes (needs matplotlib) and return it; see `hestore.render.plot`.

        Examples
        --------
        >>> import matplotlib
        >>> matplotlib.use("Agg")
        >>> import hestore
        >>> mesh = hestore.open("sqlite://").import_arrays("t", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [[0, 1, 2]]).mesh
        >>> ax = mesh.plot(view="top")
        >>> [c.get_gid() for c in ax.collections]
        ['polygons', 'boundary_loops']
        """
        return render.plot(self._ref, ax, **options)

    def render(self, path, **options) -> None:
        """Write a picture of the mesh to a PNG or SVG file (needs matplotlib); see `hestore.render.render`."""
        render.render(self._ref, path, **options)

    # -- validation ---------------------------------------------------------

    def check(self, progress=None) -> list[Violation]:
        """Every invariant violation in the stored mesh (empty when valid); never repairs.

        ``progress(stage, done, total)`` is told of each stage (see `hestore.validation.check`).

        Raises
        ------
        MeshNotFoundError
            The mesh has been deleted.

        Examples
        --------
        >>> import hestore
        >>> mesh = hestore.open("sqlite://").create_mesh("m")
        >>> _ = mesh.add_polygon([mesh.add_vertex() for _ in range(3)])
        >>> mesh.check()
        []
        """
        return validation.check(self._ref, progress)

    def validate(self) -> None:
        """Raise `InvariantViolationError` (carrying `check`'s list) unless the mesh is valid.

        Examples
        --------
        >>> import hestore
        >>> mesh = hestore.open("sqlite://").create_mesh("m")
        >>> mesh.validate()
        """
        violations = self.check()
        if violations:
            raise InvariantViolationError(violations)
