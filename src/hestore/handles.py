"""Handles: small immutable references to the elements of a mesh.

A handle is a mesh and an id, nothing more. Handles are equal when mesh and
id are equal, hashable, and stay valid across transactions because ids are
never reused; a handle whose element was removed raises
`ElementNotFoundError` when used. Every property and method delegates to a
free function of `hestore.navigation`.

The seeds' alternative vocabularies are aliases of the primary names, listed
in each class's docstring: ``lnext``/``lprev``/``sym``/``org``/``dest``
(Guibas–Stolfi), ``pair``/``opposite``, ``face``, ``source``/``destination``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from hestore import navigation as nav

if TYPE_CHECKING:  # pragma: no cover
    from hestore.mesh import Mesh

__all__ = ["Vertex", "HalfEdge", "Edge", "Polygon"]


class _Handle:
    __slots__ = ("mesh", "id")

    mesh: "Mesh"
    id: int

    def __init__(self, mesh: "Mesh", id: int) -> None:
        object.__setattr__(self, "mesh", mesh)
        object.__setattr__(self, "id", int(id))

    def __setattr__(self, name, value):
        raise AttributeError(f"{type(self).__name__} handles are immutable")

    def __delattr__(self, name):
        raise AttributeError(f"{type(self).__name__} handles are immutable")

    def __eq__(self, other: object) -> bool:
        return type(other) is type(self) and other.id == self.id and other.mesh == self.mesh

    def __hash__(self) -> int:
        return hash((type(self).__name__, self.mesh, self.id))

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.id})"

    def __reduce__(self):
        raise TypeError(f"{type(self).__name__} handles are bound to an open store; pickle .id instead")


class Vertex(_Handle):
    """A vertex of a mesh.

    Examples
    --------
    >>> import hestore
    >>> mesh = hestore.open("sqlite://").create_mesh("m")
    >>> a, b, c = mesh.add_vertex((0, 0, 0)), mesh.add_vertex((1, 0, 0)), mesh.add_vertex((0, 1, 0))
    >>> _ = mesh.add_polygon([a, b, c])
    >>> a.neighbors(), a.degree, a.is_boundary, a.position
    ([Vertex(2), Vertex(1)], 2, True, (0.0, 0.0, 0.0))
    """

    __slots__ = ()

    @property
    def halfedge(self) -> "HalfEdge | None":
        """An outgoing half-edge, a free one if there is any; ``None`` if isolated."""
        return nav.vertex_halfedge(self)

    @property
    def position(self) -> tuple[float, float, float] | None:
        """``(x, y, z)``, or ``None``."""
        return nav.position(self)

    @property
    def degree(self) -> int:
        """Number of outgoing half-edges (a self-loop counts twice)."""
        return nav.degree(self)

    @property
    def is_isolated(self) -> bool:
        """Whether no edge touches this vertex."""
        return nav.is_isolated(self)

    @property
    def is_boundary(self) -> bool:
        """Whether a free half-edge leaves this vertex (or it is isolated)."""
        return nav.is_boundary_vertex(self)

    def outgoing(self) -> list["HalfEdge"]:
        """Outgoing half-edges, counter-clockwise from `halfedge`."""
        return nav.outgoing(self)

    def incoming(self) -> list["HalfEdge"]:
        """Incoming half-edges (twins of `outgoing`, same order)."""
        return nav.incoming(self)

    def neighbors(self) -> list["Vertex"]:
        """One neighbour per outgoing half-edge: repeats for parallel edges, self for a loop."""
        return nav.neighbors(self)

    def edges(self) -> list["Edge"]:
        """One edge per outgoing half-edge (a self-loop twice)."""
        return nav.vertex_edges(self)

    def polygons(self) -> list["Polygon"]:
        """Polygons around the vertex, counter-clockwise, free gaps skipped."""
        return nav.vertex_polygons(self)


class HalfEdge(_Handle):
    """A directed half of an edge; its polygon lies to its left.

    Aliases: ``lnext``/``lprev`` = `next`/`prev`; ``sym``, ``pair``,
    ``opposite`` = `twin`; ``org``, ``source`` = `origin`; ``dest``,
    ``destination`` = `target`; ``face``, ``left`` = `polygon`;
    ``is_border`` = `is_boundary`.

    Examples
    --------
    >>> import hestore
    >>> mesh = hestore.open("sqlite://").create_mesh("m")
    >>> a, b = mesh.add_vertex(), mesh.add_vertex()
    >>> h, t = mesh.add_edge(a, b).halfedges()
    >>> h.origin, h.target, h.twin == t, h.next == t, h.is_boundary
    (Vertex(0), Vertex(1), True, True, True)
    """

    __slots__ = ()

    @property
    def next(self) -> "HalfEdge":
        """Next half-edge around the left polygon (or boundary loop)."""
        return nav.next_halfedge(self)

    @property
    def prev(self) -> "HalfEdge":
        """Previous half-edge around the left polygon (or boundary loop)."""
        return nav.prev_halfedge(self)

    @property
    def twin(self) -> "HalfEdge":
        """The opposite half-edge."""
        return nav.twin(self)

    @property
    def origin(self) -> Vertex:
        """Start vertex."""
        return nav.origin(self)

    @property
    def target(self) -> Vertex:
        """End vertex."""
        return nav.target(self)

    @property
    def polygon(self) -> "Polygon | None":
        """Left polygon, ``None`` if free."""
        return nav.polygon(self)

    @property
    def edge(self) -> "Edge":
        """The edge this is half of."""
        return nav.edge(self)

    @property
    def is_boundary(self) -> bool:
        """Whether this half-edge is free (no polygon)."""
        return nav.is_boundary_halfedge(self)

    @property
    def onext(self) -> "HalfEdge":
        """``prev.twin``: next outgoing half-edge counter-clockwise around the origin."""
        return nav.onext(self)

    @property
    def oprev(self) -> "HalfEdge":
        """``twin.next``: next outgoing half-edge clockwise around the origin."""
        return nav.oprev(self)

    @property
    def dnext(self) -> "HalfEdge":
        """``twin.prev``: around the destination."""
        return nav.dnext(self)

    @property
    def dprev(self) -> "HalfEdge":
        """``next.twin``: around the destination."""
        return nav.dprev(self)

    @property
    def rnext(self) -> "HalfEdge":
        """``twin.next.twin``: around the right polygon."""
        return nav.rnext(self)

    @property
    def rprev(self) -> "HalfEdge":
        """``twin.prev.twin``: around the right polygon."""
        return nav.rprev(self)

    @property
    def vector(self) -> tuple[float, float, float] | None:
        """``target.position - origin.position``; ``None`` without positions."""
        return nav.vector(self)

    @property
    def length(self) -> float | None:
        """Euclidean length; ``None`` without positions."""
        return nav.length(self)

    # Guibas–Stolfi and other vocabularies (SPEC §3).
    lnext = next
    lprev = prev
    sym = pair = opposite = twin
    org = source = origin
    dest = destination = target
    face = left = polygon
    is_border = is_boundary


class Edge(_Handle):
    """An undirected edge: a pair of twin half-edges.

    Examples
    --------
    >>> import hestore
    >>> mesh = hestore.open("sqlite://").create_mesh("m")
    >>> v = mesh.add_vertex()
    >>> loop = mesh.add_edge(v, v)
    >>> loop.is_loop, loop.vertices(), v.degree
    (True, (Vertex(0), Vertex(0)), 2)
    """

    __slots__ = ()

    @property
    def halfedge(self) -> HalfEdge:
        """One of the two half-edges (the one from the first vertex given to ``add_edge``)."""
        return nav.edge_halfedge(self)

    @property
    def is_boundary(self) -> bool:
        """Whether at least one side is free."""
        return nav.is_boundary_edge(self)

    @property
    def is_loop(self) -> bool:
        """Whether both ends are the same vertex."""
        return nav.is_loop(self)

    @property
    def length(self) -> float | None:
        """Euclidean length; ``None`` without positions."""
        return nav.length(self.halfedge)

    def halfedges(self) -> tuple[HalfEdge, HalfEdge]:
        """``(halfedge, halfedge.twin)``."""
        return nav.edge_halfedges(self)

    def vertices(self) -> tuple[Vertex, Vertex]:
        """``(halfedge.origin, halfedge.target)``."""
        return nav.edge_vertices(self)

    def polygons(self) -> list["Polygon"]:
        """Polygons on its two sides, free sides skipped."""
        return nav.edge_polygons(self)


class Polygon(_Handle):
    """A polygon (face): a loop of half-edges, counter-clockwise.

    Alias: ``face``.

    Examples
    --------
    >>> import hestore
    >>> mesh = hestore.open("sqlite://").create_mesh("m")
    >>> vs = [mesh.add_vertex() for _ in range(4)]
    >>> quad = mesh.add_polygon(vs)
    >>> quad.degree, quad.vertices() == vs, quad.neighbors()
    (4, True, [])
    """

    __slots__ = ()

    @property
    def halfedge(self) -> HalfEdge:
        """One half-edge of its loop."""
        return nav.polygon_halfedge(self)

    @property
    def degree(self) -> int:
        """Number of half-edges (corners)."""
        return nav.polygon_degree(self)

    def halfedges(self) -> list[HalfEdge]:
        """Its half-edges in ``next`` order from `halfedge`."""
        return nav.polygon_halfedges(self)

    def vertices(self) -> list[Vertex]:
        """Its corners, counter-clockwise."""
        return nav.polygon_vertices(self)

    def edges(self) -> list[Edge]:
        """Its edges, in order."""
        return nav.polygon_edges(self)

    def neighbors(self) -> list["Polygon"]:
        """Polygons across its edges (``None`` sides skipped)."""
        return nav.polygon_neighbors(self)
