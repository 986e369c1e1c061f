"""Handles: small immutable references to the elements of a mesh.

A handle is a mesh and an id, nothing more. Handles are equal when mesh and
id are equal, hashable, and stay valid across transactions because ids are
never reused; a handle whose element was removed raises
`ElementNotFoundError` when used. Every property and method delegates to a
free function of `hestore.navigation` and wraps the ids it returns;
``handle[name]`` reads and writes the element's value of a property through
`hestore.properties` (``del handle[name]`` unsets it).

The seeds' alternative vocabularies are aliases of the primary names, listed
in each class's docstring: ``lnext``/``lprev``/``sym``/``org``/``dest``
(Guibas–Stolfi), ``pair``/``opposite``, ``face``, ``source``/``destination``.
"""

from __future__ import annotations

from typing import Any

from hestore import navigation as nav
from hestore import properties as props
from hestore import schema
from hestore.errors import ElementNotFoundError, shown
from hestore._session import identity
from hestore._values import check_integer

__all__ = ["Vertex", "HalfEdge", "Edge", "Polygon", "Handle", "CLASSES", "element_id", "wrap"]

_ID_MIN, _ID_MAX = -(2**63), 2**63 - 1
_set = object.__setattr__


def element_id(value: object, what: str = "element") -> int:
    """``value`` as an element id: an integer (a numpy one too), never a bool, a float or a string.

    Raises
    ------
    InvalidInputError
        ``value`` is not an integer.
    ElementNotFoundError
        It is outside the 64-bit range ids are stored in, so no element has it.

    Examples
    --------
    >>> import numpy as np
    >>> element_id(np.int64(7)), element_id(3)
    (7, 3)
    >>> element_id(2**70, "vertex")
    Traceback (most recent call last):
    ...
    hestore.errors.ElementNotFoundError: there is no vertex 1180591620717411303424: ids are 64-bit integers
    """
    if type(value) is int and _ID_MIN <= value <= _ID_MAX:
        return value
    i = check_integer(value, f"the {what} id")
    if not _ID_MIN <= i <= _ID_MAX:
        raise ElementNotFoundError(f"there is no {what} {shown(i)}: ids are 64-bit integers")
    return i


class Handle:
    """Base of the element handles: a mesh and an id, immutable."""

    __slots__ = ("mesh", "id")

    #: The `hestore.Mesh` (or view of one) the element belongs to; a handle reads through its ``ref``.
    mesh: Any
    id: int

    def __init__(self, mesh: Any, id: int) -> None:
        if type(id) is not int or not _ID_MIN <= id <= _ID_MAX:
            id = element_id(id, type(self).__name__.lower())
        _set(self, "mesh", mesh)
        _set(self, "id", id)

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

    #: The element kind: its key in `hestore.schema.KINDS` (`CLASSES` maps it back to the class).
    kind: str = ""

    def __getitem__(self, name: str):
        """The element's value of property ``name`` (see `hestore.Mesh.add_property`)."""
        return props.value(identity(self.mesh), self.kind, self.id, name)

    def __setitem__(self, name: str, value) -> None:
        """Set the element's value of property ``name``: an edit like any other."""
        props.set_value(identity(self.mesh), self.kind, self.id, name, value)

    def __delitem__(self, name: str) -> None:
        """Unset the element's value of property ``name`` (back to the default)."""
        props.set_value(identity(self.mesh), self.kind, self.id, name, None)


#: The handle class of each element kind, by its key in `hestore.schema.KINDS` (each class registers itself).
CLASSES: dict[str, type[Handle]] = {}


def _of_kind(name: str):
    """Register a handle class as the one of element kind ``name``, a key of `hestore.schema.KINDS`."""

    def register(cls: type[Handle]) -> type[Handle]:
        cls.kind = schema.KINDS[name].name
        CLASSES[name] = cls
        return cls

    return register


_new = object.__new__
_set_mesh = Handle.mesh.__set__
_set_id = Handle.id.__set__


def wrap(cls: type, mesh: Any, i: int) -> Handle:
    """A handle of an id known to be an int in range (one read from the store): `Handle` without the checks.

    Examples
    --------
    >>> import hestore
    >>> mesh = hestore.open("sqlite://").create_mesh("m")
    >>> wrap(Vertex, mesh, 3) == Vertex(mesh, 3)
    True
    """
    h = _new(cls)
    _set_mesh(h, mesh)
    _set_id(h, i)
    return h


@_of_kind("vertex")
class Vertex(Handle):
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
        h = nav.vertex_row(identity(self.mesh), self.id)[0]
        return None if h is None else wrap(HalfEdge, self.mesh, h)

    @property
    def position(self) -> tuple[float, float, float] | None:
        """``(x, y, z)``, or ``None``."""
        row = nav.vertex_row(identity(self.mesh), self.id)
        return None if row[1] is None else (row[1], row[2], row[3])

    @property
    def degree(self) -> int:
        """Number of outgoing half-edges (a self-loop counts twice)."""
        return len(nav.star(identity(self.mesh), self.id))

    @property
    def is_isolated(self) -> bool:
        """Whether no edge touches this vertex."""
        return nav.vertex_row(identity(self.mesh), self.id)[0] is None

    @property
    def is_boundary(self) -> bool:
        """Whether a free half-edge leaves this vertex (or it is isolated)."""
        return nav.is_boundary_vertex(identity(self.mesh), self.id)

    def outgoing(self) -> list["HalfEdge"]:
        """Outgoing half-edges, counter-clockwise from `halfedge`."""
        m = self.mesh
        return [wrap(HalfEdge, m, r[nav.STAR_ID]) for r in nav.star(identity(m), self.id)]

    def incoming(self) -> list["HalfEdge"]:
        """Incoming half-edges (twins of `outgoing`, same order)."""
        m = self.mesh
        return [wrap(HalfEdge, m, r[nav.STAR_TWIN]) for r in nav.star(identity(m), self.id)]

    def neighbors(self) -> list["Vertex"]:
        """One neighbour per outgoing half-edge: repeats for parallel edges, self for a loop."""
        m = self.mesh
        return [wrap(Vertex, m, r[nav.STAR_TARGET]) for r in nav.star(identity(m), self.id, targets=True)]

    def edges(self) -> list["Edge"]:
        """One edge per outgoing half-edge (a self-loop twice)."""
        m = self.mesh
        return [wrap(Edge, m, r[nav.STAR_EDGE]) for r in nav.star(identity(m), self.id)]

    def polygons(self) -> list["Polygon"]:
        """Polygons around the vertex, counter-clockwise, free gaps skipped."""
        m = self.mesh
        polygon = nav.STAR_POLYGON
        return [wrap(Polygon, m, r[polygon]) for r in nav.star(identity(m), self.id) if r[polygon] is not None]


@_of_kind("halfedge")
class HalfEdge(Handle):
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

    def _record(self) -> tuple:
        return nav.halfedge_record(identity(self.mesh), self.id)

    @property
    def next(self) -> "HalfEdge":
        """Next half-edge around the left polygon (or boundary loop)."""
        return wrap(HalfEdge, self.mesh, self._record()[1])

    @property
    def prev(self) -> "HalfEdge":
        """Previous half-edge around the left polygon (or boundary loop)."""
        return wrap(HalfEdge, self.mesh, self._record()[2])

    @property
    def twin(self) -> "HalfEdge":
        """The opposite half-edge."""
        return wrap(HalfEdge, self.mesh, self._record()[3])

    @property
    def origin(self) -> Vertex:
        """Start vertex."""
        return wrap(Vertex, self.mesh, self._record()[0])

    @property
    def target(self) -> Vertex:
        """End vertex."""
        return wrap(Vertex, self.mesh, self._record()[6])

    @property
    def polygon(self) -> "Polygon | None":
        """Left polygon, ``None`` if free."""
        p = self._record()[5]
        return None if p is None else wrap(Polygon, self.mesh, p)

    @property
    def edge(self) -> "Edge":
        """The edge this is half of."""
        return wrap(Edge, self.mesh, self._record()[4])

    @property
    def is_boundary(self) -> bool:
        """Whether this half-edge is free (no polygon)."""
        return self._record()[5] is None

    @property
    def onext(self) -> "HalfEdge":
        """``prev.twin``: next outgoing half-edge counter-clockwise around the origin."""
        return self.prev.twin

    @property
    def oprev(self) -> "HalfEdge":
        """``twin.next``: next outgoing half-edge clockwise around the origin."""
        return self.twin.next

    @property
    def dnext(self) -> "HalfEdge":
        """``twin.prev``: around the destination."""
        return self.twin.prev

    @property
    def dprev(self) -> "HalfEdge":
        """``next.twin``: around the destination."""
        return self.next.twin

    @property
    def rnext(self) -> "HalfEdge":
        """``twin.next.twin``: around the right polygon."""
        return self.twin.next.twin

    @property
    def rprev(self) -> "HalfEdge":
        """``twin.prev.twin``: around the right polygon."""
        return self.twin.prev.twin

    @property
    def vector(self) -> tuple[float, float, float] | None:
        """``target.position - origin.position``; ``None`` without positions."""
        return nav.vector(identity(self.mesh), self.id)

    @property
    def length(self) -> float | None:
        """Euclidean length; ``None`` without positions."""
        return nav.length(identity(self.mesh), self.id)

    # Guibas–Stolfi and other vocabularies (SPEC §3).
    lnext = next
    lprev = prev
    sym = pair = opposite = twin
    org = source = origin
    dest = destination = target
    face = left = polygon
    is_border = is_boundary


@_of_kind("edge")
class Edge(Handle):
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

    def _row(self) -> tuple:
        return nav.edge_row(identity(self.mesh), self.id)

    @property
    def halfedge(self) -> HalfEdge:
        """One of the two half-edges (the one from the first vertex given to ``add_edge``)."""
        return wrap(HalfEdge, self.mesh, self._row()[0])

    @property
    def is_boundary(self) -> bool:
        """Whether at least one side is free."""
        row = self._row()
        return row[4] is None or row[5] is None

    @property
    def is_loop(self) -> bool:
        """Whether both ends are the same vertex."""
        row = self._row()
        return row[2] == row[3]

    @property
    def length(self) -> float | None:
        """Euclidean length; ``None`` without positions."""
        return nav.length(identity(self.mesh), self._row()[0])

    def halfedges(self) -> tuple[HalfEdge, HalfEdge]:
        """``(halfedge, halfedge.twin)``."""
        row = self._row()
        return wrap(HalfEdge, self.mesh, row[0]), wrap(HalfEdge, self.mesh, row[1])

    def vertices(self) -> tuple[Vertex, Vertex]:
        """``(halfedge.origin, halfedge.target)``."""
        row = self._row()
        return wrap(Vertex, self.mesh, row[2]), wrap(Vertex, self.mesh, row[3])

    def polygons(self) -> list["Polygon"]:
        """Polygons on its two sides, free sides skipped."""
        row = self._row()
        return [wrap(Polygon, self.mesh, p) for p in (row[4], row[5]) if p is not None]


@_of_kind("polygon")
class Polygon(Handle):
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
        return wrap(HalfEdge, self.mesh, nav.polygon_halfedge(identity(self.mesh), self.id))

    @property
    def degree(self) -> int:
        """Number of half-edges (corners)."""
        return len(nav.ring(identity(self.mesh), self.id))

    def halfedges(self) -> list[HalfEdge]:
        """Its half-edges in ``next`` order from `halfedge`."""
        m = self.mesh
        return [wrap(HalfEdge, m, r[0]) for r in nav.ring(identity(m), self.id)]

    def vertices(self) -> list[Vertex]:
        """Its corners, counter-clockwise."""
        m = self.mesh
        return [wrap(Vertex, m, r[2]) for r in nav.ring(identity(m), self.id)]

    def edges(self) -> list[Edge]:
        """Its edges, in order."""
        m = self.mesh
        return [wrap(Edge, m, r[3]) for r in nav.ring(identity(m), self.id)]

    def neighbors(self) -> list["Polygon"]:
        """Polygons across its edges (``None`` sides skipped; itself where it meets itself)."""
        m = self.mesh
        return [wrap(Polygon, m, r[4]) for r in nav.ring(identity(m), self.id) if r[4] is not None]
