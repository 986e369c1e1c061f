"""Typed errors raised by hestore, and the records they carry.

This module is the leaf of the package: it imports nothing from hestore, so
every other module can raise these. Every failure a user can cause has its
own class, says which elements are involved and why, and leaves the store
exactly as it was before the call. No exception of a database driver leaves a
public call: database-level problems are `StoreError`, with the driver's
exception chained as ``__cause__``.

Hierarchy::

    HestoreError
    ├── ElementNotFoundError (KeyError)      an id or handle that does not exist here
    │   └── MeshNotFoundError                no such mesh, or a deleted / rolled-back one
    ├── PropertyNotFoundError (KeyError)     no property of that name on that kind
    ├── InvalidInputError (ValueError)       malformed arguments, files, arrays, names, URLs
    │   └── MeshExistsError
    ├── TopologyError                        a valid request the structure cannot take
    │   ├── NotAChainError
    │   ├── HalfEdgeNotFreeError             OpenMesh's "complex edge"
    │   ├── NonManifoldError                 OpenMesh's "complex vertex"
    │   ├── VertexNotFreeError
    │   └── PolicyError                      loop or parallel edge forbidden
    ├── NoPathError                          `Mesh.shortest_path`: the two vertices are not connected
    ├── InvariantViolationError              `Mesh.validate` found violations
    ├── StoreError                           the database itself: unreadable, read-only, ...
    │   ├── StoreBusyError                   a lock could not be had in time
    │   ├── StoreNotFoundError               ``open(..., create=False)``: no hestore database there
    │   └── SchemaVersionError               the database needs ``hestore db upgrade``
    └── WrongThreadError                     a store used from a thread that did not open it

`Violation`, the record `Mesh.check` returns and `InvariantViolationError`
carries, lives here too, so that errors depend on nothing else; so does
`require`, the import of an optional library that raises
`MissingDependencyError` when it is missing, and `shown`, how a message
quotes a caller's value.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from types import ModuleType
from typing import Any

__all__ = [
    "HestoreError",
    "ElementNotFoundError",
    "MeshNotFoundError",
    "PropertyNotFoundError",
    "InvalidInputError",
    "MissingDependencyError",
    "RevisionNotFoundError",
    "MeshExistsError",
    "TopologyError",
    "NotAChainError",
    "HalfEdgeNotFreeError",
    "NonManifoldError",
    "VertexNotFreeError",
    "PolicyError",
    "EulerError",
    "NonOrientableError",
    "ReadOnlyError",
    "NoPathError",
    "InvariantViolationError",
    "StoreError",
    "StoreBusyError",
    "StoreNotFoundError",
    "SchemaVersionError",
    "WrongThreadError",
    "Violation",
    "require",
    "shown",
]

#: How much of a value a message quotes.
_SHOWN = 60


class HestoreError(Exception):
    """Base class of every error hestore raises on purpose."""


class ElementNotFoundError(HestoreError, KeyError):
    """An element (or handle) does not exist in this mesh.

    Raised for ids that were never allocated, for elements that have been
    removed (stale handles) and for handles that belong to another mesh.
    """

    def __str__(self) -> str:
        # KeyError would repr() the message and wrap it in quotes.
        return str(self.args[0]) if self.args else ""


class MeshNotFoundError(ElementNotFoundError):
    """No mesh of that name exists in the store, or the mesh is gone.

    A `Mesh` handle raises it once its mesh has been deleted, and once the
    transaction that created it has been rolled back (its id may then belong
    to another mesh, which the handle never touches).
    """


class PropertyNotFoundError(HestoreError, KeyError):
    """No property of that name is declared on that element kind of the mesh.

    Attributes
    ----------
    weights : tuple of str or None
        For a ``weight`` of `Mesh.shortest_path` or `Mesh.path_weight` that
        is no edge property: the names that weigh a path of that mesh
        (``"length"``, then its numeric edge properties). None otherwise.
    """

    weights: Any = None

    def __str__(self) -> str:
        return str(self.args[0]) if self.args else ""


class RevisionNotFoundError(HestoreError, KeyError):
    """A revision of a mesh that was never made or is no longer kept."""

    def __str__(self) -> str:  # KeyError would show the message quoted
        return str(self.args[0]) if self.args else ""


class MissingDependencyError(HestoreError, ImportError):
    """An optional library a call needs (trimesh, meshio) is not installed; the message says what to install."""


def require(module: str, extra: str | None = None) -> ModuleType:
    """Import an optional dependency, or raise `MissingDependencyError` saying how to install it.

    ``extra`` names hestore's extra that brings it (default: the module's own name).

    Examples
    --------
    >>> require("json").__name__
    'json'
    >>> try:
    ...     require("no_such_module", "plot")
    ... except MissingDependencyError as exc:
    ...     print(exc)
    no_such_module is not installed: pip install "hestore[plot]" (or pip install no_such_module)
    """
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        top = module.partition(".")[0]
        raise MissingDependencyError(
            f'{top} is not installed: pip install "hestore[{extra or top}]" (or pip install {top})'
        ) from exc


def shown(value: object) -> str:
    """``value`` as a message quotes it: its ``repr``, cut short; never raises.

    A caller's value may be anything: an int whose decimal form Python
    refuses to build (over 4300 digits), an object whose ``__repr__`` raises.
    A refusal must still say what it refused.

    Examples
    --------
    >>> shown("abc"), shown(2**70), shown(10**400)
    ("'abc'", '1180591620717411303424', 'an int of 1329 bits')
    >>> shown(list(range(30)))
    '[0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16,... (110 characters)'
    """
    if isinstance(value, int) and value.bit_length() > 3 * _SHOWN:
        return f"an int of {value.bit_length()} bits"
    try:
        text = repr(value)
    except Exception:  # noqa: BLE001 - a caller's __repr__ may raise anything; the message must not
        return f"a {type(value).__name__} that cannot be shown"
    return text if len(text) <= _SHOWN else f"{text[:_SHOWN - 2]}... ({len(text)} characters)"


class InvalidInputError(HestoreError, ValueError):
    """Arguments are malformed: wrong type, empty loop, NaN position, bad file, bad URL.

    Attributes
    ----------
    skipped : hestore.SkippedPolygon or None
        For an import with ``on_error="raise"`` refused because of one
        polygon (an index out of range, an empty polygon): that polygon.
        None otherwise.
    weights : tuple of str or None
        For a ``weight`` of `Mesh.shortest_path` or `Mesh.path_weight` that
        names an edge property that is not a number: the names that weigh a
        path of that mesh (``"length"``, then its numeric edge properties).
        None otherwise.
    """

    skipped: Any = None
    weights: Any = None


class MeshExistsError(InvalidInputError):
    """A mesh of that name already exists."""


class TopologyError(HestoreError):
    """A well-formed request that the half-edge structure cannot take.

    Parameters
    ----------
    message : str
        What was refused and why, naming the elements.
    refs : sequence of (str, int), optional
        The elements the refusal is about, most relevant first, as
        ``(kind, id)`` pairs (kind ``"vertex"``, ``"halfedge"``, ``"edge"``
        or ``"polygon"``).

    Attributes
    ----------
    elements : tuple of handles
        The elements of `refs` as `Vertex`, `HalfEdge`, `Edge` and `Polygon`
        handles of the mesh the operation ran on. Every error raised by a
        `Mesh` method has them; an error raised by an import (where nothing
        was stored, so there are no handles) has none.
    refs : tuple of (str, int)
        The same elements as ``(kind, id)`` pairs.
    skipped : hestore.SkippedPolygon or None
        For an import with ``on_error="raise"``: the polygon that was
        refused. None otherwise.

    Examples
    --------
    >>> exc = TopologyError("vertex 3 is not free", refs=[("vertex", 3)])
    >>> exc.refs, exc.elements, str(exc)
    ((('vertex', 3),), (), 'vertex 3 is not free')
    """

    skipped: Any = None

    def __init__(self, message: str, refs: Any = ()) -> None:
        super().__init__(message)
        self.refs: tuple[tuple[str, int], ...] = tuple((str(kind), int(i)) for kind, i in refs)
        self.elements: tuple = ()


class NotAChainError(TopologyError):
    """Consecutive half-edges of a loop do not meet (``target(h[i]) != origin(h[i+1])``)."""


class HalfEdgeNotFreeError(TopologyError):
    """A half-edge of the requested polygon already has a polygon ("complex edge")."""


class NonManifoldError(TopologyError):
    """No free gap is left around a vertex to reorder into ("complex vertex")."""


class VertexNotFreeError(TopologyError):
    """An edge end is a vertex whose outgoing half-edges all have polygons."""


class PolicyError(TopologyError):
    """The mesh's policy forbids self-loops or parallel edges."""


class ReadOnlyError(HestoreError):
    """An edit of a read-only view of a mesh (``mesh.at(r)``): views of earlier revisions cannot change."""


class NonOrientableError(TopologyError):
    """Polygons cannot be oriented consistently: a component of the soup is non-orientable (a Möbius strip)."""


class EulerError(TopologyError):
    """An Euler operator's precondition does not hold; nothing was changed.

    Parameters
    ----------
    message : str
        What was refused and why, naming the elements.
    refs : sequence of (str, int), optional
        The elements, as for `TopologyError`.
    reason : str
        A stable code for the precondition that failed, for programs to
        branch on: ``"boundary"`` (a side of the edge is free),
        ``"same-polygon"`` (both sides are one polygon), ``"not-triangle"``,
        ``"duplicate-edge"`` (the new edge would join vertices already
        joined), ``"degenerate"`` (the result would be a 1-gon, an empty
        polygon, a self-loop or a dangling edge), ``"link-condition"`` (the
        collapse would merge edges or polygons other than those beside the
        edge, or pinch the surface), ``"loop"`` (the edge is a self-loop),
        ``"not-corner"``, ``"adjacent-corners"``, ``"same-corner"``,
        ``"not-adjacent"`` (the edges share no vertex), ``"degree"`` (other
        edges meet at the shared vertex) or ``"same-edge"``.

    Examples
    --------
    >>> exc = EulerError("edge 3 is on the boundary", [("edge", 3)], reason="boundary")
    >>> exc.reason, exc.refs
    ('boundary', (('edge', 3),))
    """

    def __init__(self, message: str, refs: Any = (), *, reason: str = "") -> None:
        super().__init__(message, refs)
        self.reason = reason


@dataclass(frozen=True)
class Violation:
    """One broken invariant, about one element.

    Parameters
    ----------
    code : str
        The invariant's code, one of `hestore.validation.CODES`.
    kind : str
        The kind of the offending element: ``"halfedge"``, ``"vertex"``,
        ``"edge"`` or ``"polygon"`` — or ``"property"`` for a value row of a
        property that is not declared (``PROPERTY_REF``; ``ids`` is then the
        property id and the element id).
    ids : tuple of int
        The ids involved, the offending element's first; the others are the
        elements (of any kind, see `message`) the reason refers to.
    message : str
        The reason, naming the elements involved.

    Examples
    --------
    >>> v = Violation("H_TWIN", "halfedge", (12, 40, 41), "twin(twin(12)) = 41 (twin(12) = 40), expected 12")
    >>> str(v)
    'H_TWIN halfedge 12: twin(twin(12)) = 41 (twin(12) = 40), expected 12'
    >>> v.id
    12
    """

    code: str
    kind: str
    ids: tuple[int, ...]
    message: str

    @property
    def id(self) -> int:
        """The id of the offending element (``ids[0]``)."""
        return self.ids[0]

    def __str__(self) -> str:
        return f"{self.code} {self.kind} {self.ids[0]}: {self.message}"


class NoPathError(HestoreError):
    """No path joins the two vertices given to `Mesh.shortest_path`: they are in different components.

    The message names both vertices and the mesh.
    """


class InvariantViolationError(HestoreError):
    """Stored data breaks an invariant: `Mesh.validate` found violations.

    Also raised when an operation or a read meets a broken structure
    (a rotation that does not close, a dangling reference) on its way.

    Attributes
    ----------
    violations : list of Violation
        What was found (for `Mesh.validate`: what `Mesh.check` reported).
    """

    def __init__(self, violations: list) -> None:
        self.violations = list(violations)
        head = "; ".join(str(v) for v in self.violations[:5])
        more = len(self.violations) - 5
        tail = f" (and {more} more)" if more > 0 else ""
        super().__init__(f"{len(self.violations)} invariant violation(s): {head}{tail}")


class StoreError(HestoreError):
    """The database could not do what was asked: a problem of the store, not of the input.

    A file that is not a database, a read-only database, tables of another
    application in the way, a lost connection. The driver's own exception is
    chained as ``__cause__``. The call that raised it changed nothing.
    """


class StoreBusyError(StoreError):
    """Another writer held the lock longer than the store's busy timeout.

    The call that raised it changed nothing. Outside a transaction block it is
    safe to retry; inside one, the block may go on (the lock is taken in a
    savepoint), but a deadlock between two blocks aborts the whole block.
    """


class StoreNotFoundError(StoreError):
    """``hestore.open(url, create=False)`` found no hestore database to open.

    A SQLite file that does not exist (it is not created), or a database
    without hestore's tables: an empty file, an in-memory database, a new
    PostgreSQL database (no tables are created). Nothing was changed.
    """


class SchemaVersionError(StoreError):
    """The database schema is older (or newer) than this version of hestore."""


class WrongThreadError(HestoreError):
    """A `Store` (or one of its meshes or handles) was used from another thread.

    A store belongs to the thread that opened it; the call was refused before
    it touched the connection. Open one store per thread.
    """
