"""The `Mesh` facade: one named half-edge structure in a store.

`Mesh` checks its arguments (types, ownership of handles, positions), then
delegates: edits to `hestore.kernel` inside the store's atomic edit scope,
reads to `hestore.navigation`, checks to `hestore.validation`. It holds no
state of its own beyond its identity and policy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Iterator, Sequence

import sqlalchemy as sa

from hestore import kernel, navigation, schema
from hestore.errors import (
    ElementNotFoundError,
    InvalidInputError,
    InvariantViolationError,
    MeshNotFoundError,
    TopologyError,
)
from hestore.handles import Edge, HalfEdge, Polygon, Vertex, _Handle

if TYPE_CHECKING:  # pragma: no cover
    from hestore.store import Store
    from hestore.summary import Stats
    from hestore.validation import Violation

__all__ = ["Mesh", "Counts"]

_KIND_OF = {"vertex": Vertex, "halfedge": HalfEdge, "edge": Edge, "polygon": Polygon}


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

    __slots__ = ("_store", "_id", "name", "allow_loops", "allow_multi_edges")

    def __init__(self, store: "Store", mesh_id: int, name: str, allow_loops: bool, allow_multi_edges: bool) -> None:
        self._store = store
        self._id = mesh_id
        self.name = name
        self.allow_loops = allow_loops
        self.allow_multi_edges = allow_multi_edges

    def __repr__(self) -> str:
        return f"Mesh({self.name!r})"

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Mesh) and other._store is self._store and other._id == self._id

    def __hash__(self) -> int:
        return hash((id(self._store), self._id))

    @property
    def store(self) -> "Store":
        """The store the mesh lives in."""
        return self._store

    # -- argument checking --------------------------------------------------

    def _own(self, handle: object, kind: type, what: str = "") -> int:
        if not isinstance(handle, kind):
            raise InvalidInputError(
                f"expected a {kind.__name__} handle{what}, got {type(handle).__name__} {handle!r}"
            )
        if handle.mesh != self:
            raise ElementNotFoundError(
                f"{handle!r} belongs to mesh {handle.mesh.name!r}, not to {self.name!r}"
            )
        return handle.id

    def _handles(self, exc: TopologyError) -> TopologyError:
        exc.elements = tuple(_KIND_OF[kind](self, i) for kind, i in exc.elements if kind in _KIND_OF)
        return exc

    # -- summaries ----------------------------------------------------------

    @property
    def revision(self) -> int:
        """Number of committed transactions that changed the mesh (plus the open one's, if it did)."""
        m = schema.meshes
        with self._store._read() as conn:
            rev = conn.execute(sa.select(m.c.revision).where(m.c.id == self._id)).scalar()
        if rev is None:
            raise self._deleted()
        return rev

    def counts(self) -> Counts:
        """Number of vertices, half-edges, edges and polygons.

        Examples
        --------
        >>> import hestore
        >>> mesh = hestore.open("sqlite://").create_mesh("m")
        >>> mesh.counts()
        Counts(vertices=0, halfedges=0, edges=0, polygons=0)
        """

        def count(t: sa.Table):
            return sa.select(sa.func.count()).select_from(t).where(t.c.mesh_id == self._id).scalar_subquery()

        m = schema.meshes
        stmt = sa.select(
            sa.select(m.c.id).where(m.c.id == self._id).scalar_subquery(),
            count(schema.vertices),
            count(schema.halfedges),
            count(schema.edges),
            count(schema.polygons),
        )
        with self._store._read() as conn:
            exists, *counts = conn.execute(stmt).one()
        if exists is None:
            raise self._deleted()
        return Counts(*counts)

    def _deleted(self) -> MeshNotFoundError:
        return MeshNotFoundError(f"mesh {self.name!r} has been deleted")

    # -- lookup and iteration -----------------------------------------------

    def _lookup(self, table: sa.Table, kind: type, what: str, i: int):
        if isinstance(i, bool) or not isinstance(i, int):
            raise InvalidInputError(f"{what} ids are integers, not {i!r}")
        with self._store._read() as conn:
            row = conn.execute(
                sa.select(table.c.id).where(table.c.mesh_id == self._id, table.c.id == i)
            ).first()
        if row is None:
            raise ElementNotFoundError(f"{what} {i} does not exist in mesh {self.name!r}")
        return kind(self, i)

    def vertex(self, id: int) -> Vertex:
        """The vertex with this id (`ElementNotFoundError` if there is none)."""
        return self._lookup(schema.vertices, Vertex, "vertex", id)

    def halfedge(self, id: int) -> HalfEdge:
        """The half-edge with this id (`ElementNotFoundError` if there is none)."""
        return self._lookup(schema.halfedges, HalfEdge, "half-edge", id)

    def edge(self, id: int) -> Edge:
        """The edge with this id (`ElementNotFoundError` if there is none)."""
        return self._lookup(schema.edges, Edge, "edge", id)

    def polygon(self, id: int) -> Polygon:
        """The polygon with this id (`ElementNotFoundError` if there is none)."""
        return self._lookup(schema.polygons, Polygon, "polygon", id)

    def _ids(self, table: sa.Table) -> list[int]:
        m = schema.meshes
        with self._store._read() as conn:
            if conn.execute(sa.select(m.c.id).where(m.c.id == self._id)).first() is None:
                raise self._deleted()
            return list(
                conn.execute(sa.select(table.c.id).where(table.c.mesh_id == self._id).order_by(table.c.id)).scalars()
            )

    def vertices(self) -> Iterator[Vertex]:
        """All vertices, in id order."""
        return (Vertex(self, i) for i in self._ids(schema.vertices))

    def halfedges(self) -> Iterator[HalfEdge]:
        """All half-edges, in id order."""
        return (HalfEdge(self, i) for i in self._ids(schema.halfedges))

    def edges(self) -> Iterator[Edge]:
        """All edges, in id order."""
        return (Edge(self, i) for i in self._ids(schema.edges))

    def polygons(self) -> Iterator[Polygon]:
        """All polygons, in id order."""
        return (Polygon(self, i) for i in self._ids(schema.polygons))

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
        self._own(a, Vertex)
        self._own(b, Vertex)
        return navigation.find_halfedge(a, b)

    # -- editing ------------------------------------------------------------

    @staticmethod
    def _position(position) -> tuple[float, float, float] | None:
        if position is None:
            return None
        try:
            xyz = tuple(float(c) for c in position)
        except (TypeError, ValueError):
            raise InvalidInputError(f"a position is three numbers (x, y, z), not {position!r}") from None
        if len(xyz) != 3:
            raise InvalidInputError(f"a position is three numbers (x, y, z), not {len(xyz)}: {position!r}")
        if not all(math.isfinite(c) for c in xyz):
            raise InvalidInputError(f"a position must be finite, not {position!r}")
        return xyz

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
        xyz = self._position(position)
        with self._store._editing(self._id) as uow:
            return Vertex(self, kernel.add_vertex(uow, xyz))

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
        hestore.errors.PolicyError: vertices 1 and 0 are already joined by edge 0; this mesh does not allow parallel edges
        """
        ia = self._own(a, Vertex, " for a")
        ib = self._own(b, Vertex, " for b")
        try:
            with self._store._editing(self._id) as uow:
                return Edge(self, kernel.add_edge(uow, ia, ib))
        except TopologyError as exc:
            raise self._handles(exc)

    def _loop_ids(self, loop: Sequence) -> tuple[str, list[int]]:
        if isinstance(loop, (str, bytes, _Handle)) or not hasattr(loop, "__iter__"):
            raise InvalidInputError(f"a polygon is a sequence of Vertex or of HalfEdge handles, not {loop!r}")
        items = list(loop)
        if not items:
            raise InvalidInputError("a polygon needs at least one vertex or half-edge")
        kind = type(items[0])
        if kind not in (Vertex, HalfEdge) or any(type(x) is not kind for x in items):
            raise InvalidInputError(
                "a polygon is given either by Vertex handles or by HalfEdge handles, all of one kind; got "
                + ", ".join(sorted({type(x).__name__ for x in items}))
            )
        return ("vertex" if kind is Vertex else "halfedge"), [self._own(x, kind) for x in items]

    def _add_polygon(self, loop: Sequence, dry_run: bool) -> int:
        kind, ids = self._loop_ids(loop)
        with self._store._editing(self._id, dry_run=dry_run) as uow:
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
        try:
            return Polygon(self, self._add_polygon(loop, dry_run=False))
        except TopologyError as exc:
            raise self._handles(exc)

    def can_add_polygon(self, loop: Sequence[Vertex] | Sequence[HalfEdge]) -> bool:
        """Whether `add_polygon` would succeed; nothing is written either way.

        Malformed input (not handles, handles of another mesh or of removed
        elements) still raises, as `add_polygon` would.

        Examples
        --------
        >>> import hestore
        >>> mesh = hestore.open("sqlite://").create_mesh("m")
        >>> a, b, c = (mesh.add_vertex() for _ in range(3))
        >>> _ = mesh.add_polygon([a, b, c])
        >>> mesh.can_add_polygon([a, b, c]), mesh.can_add_polygon([a, c, b])
        (False, True)
        """
        try:
            self._add_polygon(loop, dry_run=True)
        except TopologyError:
            return False
        return True

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
        with self._store._editing(self._id) as uow:
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
        with self._store._editing(self._id) as uow:
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
        with self._store._editing(self._id) as uow:
            kernel.remove_vertex(uow, iv)

    # -- summaries and graph views ---------------------------------------------

    def stats(self) -> "Stats":
        """Counts and topological invariants of the mesh; see `hestore.summary.stats`."""
        from hestore import summary

        return summary.stats(self)

    def boundary_loops(self) -> list[list[HalfEdge]]:
        """The cycles of free half-edges, each in ``next`` order; see `hestore.summary.boundary_loops`."""
        from hestore import summary

        return summary.boundary_loops(self)

    def components(self) -> list[set[Vertex]]:
        """Connected components of the vertex–edge graph; see `hestore.summary.components`."""
        from hestore import summary

        return summary.components(self)

    def to_networkx(self, kind: str = "multigraph"):
        """A frozen networkx graph of the committed state; see `hestore.graphs.to_networkx`."""
        from hestore import graphs

        return graphs.to_networkx(self, kind)

    # -- bulk export ----------------------------------------------------------

    def to_arrays(self):
        """``(positions, polygons, vertex_ids)``; see `hestore.bulk.to_arrays`.

        Examples
        --------
        >>> import hestore
        >>> mesh = hestore.open("sqlite://").import_arrays("t", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [[0, 1, 2]]).mesh
        >>> mesh.to_arrays().polygons.tolist()
        [[0, 1, 2]]
        """
        from hestore import bulk

        return bulk.to_arrays(self)

    def export(self, path, **options) -> None:
        """Write the mesh to an OFF, OBJ or PLY file; see `hestore.bulk.export`."""
        from hestore import bulk

        bulk.export(self, path, **options)

    # -- validation ---------------------------------------------------------

    def check(self) -> list["Violation"]:
        """Every invariant violation in the stored mesh (empty when valid); never repairs.

        Examples
        --------
        >>> import hestore
        >>> mesh = hestore.open("sqlite://").create_mesh("m")
        >>> _ = mesh.add_polygon([mesh.add_vertex() for _ in range(3)])
        >>> mesh.check()
        []
        """
        from hestore import validation

        return validation.check(self)

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
