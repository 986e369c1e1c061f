"""Typed errors raised by hestore.

Every failure a user can cause has its own class, says which elements are
involved and why, and leaves the store exactly as it was before the call.

Hierarchy::

    HestoreError
    ├── ElementNotFoundError (KeyError)      an id or handle that does not exist here
    │   └── MeshNotFoundError
    ├── InvalidInputError (ValueError)       malformed arguments
    │   └── MeshExistsError
    ├── TopologyError                        a valid request the structure cannot take
    │   ├── NotAChainError
    │   ├── HalfEdgeNotFreeError             OpenMesh's "complex edge"
    │   ├── NonManifoldError                 OpenMesh's "complex vertex"
    │   ├── VertexNotFreeError
    │   └── PolicyError                      loop or parallel edge forbidden
    ├── InvariantViolationError              `Mesh.validate` found violations
    ├── StoreBusyError                       a lock could not be had in time
    └── SchemaVersionError                   the database needs ``hestore db upgrade``
"""

from __future__ import annotations

__all__ = [
    "HestoreError",
    "ElementNotFoundError",
    "MeshNotFoundError",
    "InvalidInputError",
    "MeshExistsError",
    "TopologyError",
    "NotAChainError",
    "HalfEdgeNotFreeError",
    "NonManifoldError",
    "VertexNotFreeError",
    "PolicyError",
    "InvariantViolationError",
    "StoreBusyError",
    "SchemaVersionError",
]


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
    """No mesh of that name exists in the store."""


class InvalidInputError(HestoreError, ValueError):
    """Arguments are malformed (wrong type, empty loop, NaN position, ...)."""


class MeshExistsError(InvalidInputError):
    """A mesh of that name already exists."""


class TopologyError(HestoreError):
    """A well-formed request that the half-edge structure cannot take.

    Attributes
    ----------
    elements : tuple
        The handles the refusal is about, most relevant first.
    """

    def __init__(self, message: str, elements: tuple = ()) -> None:
        super().__init__(message)
        self.elements = tuple(elements)


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


class InvariantViolationError(HestoreError):
    """`Mesh.validate` found stored data that breaks an invariant.

    Attributes
    ----------
    violations : list of Violation
        What `Mesh.check` reported.
    """

    def __init__(self, violations: list) -> None:
        self.violations = list(violations)
        head = "; ".join(str(v) for v in self.violations[:5])
        more = len(self.violations) - 5
        tail = f" (and {more} more)" if more > 0 else ""
        super().__init__(f"{len(self.violations)} invariant violation(s): {head}{tail}")


class StoreBusyError(HestoreError):
    """Another writer held the lock longer than the store's busy timeout.

    The call that raised it changed nothing. Outside a transaction block it is
    safe to retry; inside one, the block may go on (the lock is taken in a
    savepoint), but a deadlock between two blocks aborts the whole block.
    """


class SchemaVersionError(HestoreError):
    """The database schema is older (or newer) than this version of hestore."""
