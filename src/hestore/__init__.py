"""hestore: a persistent, transactional half-edge topology store.

Meshes and graphs — polygon meshes, wireframes and mixes of both, with
self-loops and parallel edges — are kept as SQL tables (a SQLite file by
default, PostgreSQL for shared and large deployments), edited with atomic,
validated topological operations, navigated with the full half-edge
vocabulary, and analysed with networkx.

>>> import hestore
>>> store = hestore.open("sqlite://")
>>> mesh = store.create_mesh("triangle")
>>> a, b, c = (mesh.add_vertex((x, y, 0.0)) for x, y in [(0, 0), (1, 0), (0, 1)])
>>> p = mesh.add_polygon([a, b, c])
>>> [v.id for v in p.vertices()]
[0, 1, 2]
>>> mesh.check()
[]
>>> store.close()
"""

from hestore.errors import (
    ElementNotFoundError,
    EulerError,
    MissingDependencyError,
    NonOrientableError,
    NoPathError,
    ReadOnlyError,
    RevisionNotFoundError,
    HalfEdgeNotFreeError,
    HestoreError,
    InvalidInputError,
    InvariantViolationError,
    MeshExistsError,
    MeshNotFoundError,
    NonManifoldError,
    NotAChainError,
    PolicyError,
    PropertyNotFoundError,
    SchemaVersionError,
    StoreBusyError,
    StoreError,
    TopologyError,
    VertexNotFreeError,
    Violation,
    WrongThreadError,
)
from hestore.bulk import ImportReport, MeshArrays, SkippedPolygon
from hestore.handles import Edge, HalfEdge, Polygon, Vertex
from hestore.history import Diff, Revision
from hestore.mesh import Counts, Mesh
from hestore.store import Store, open
from hestore.summary import Stats
from hestore._values import Property

__version__ = "0.1.0"

__all__ = [
    "open",
    "Store",
    "Mesh",
    "Counts",
    "Diff",
    "Revision",
    "Property",
    "Stats",
    "Vertex",
    "HalfEdge",
    "Edge",
    "Polygon",
    "Violation",
    "ImportReport",
    "SkippedPolygon",
    "MeshArrays",
    "HestoreError",
    "ElementNotFoundError",
    "PropertyNotFoundError",
    "MeshNotFoundError",
    "InvalidInputError",
    "MeshExistsError",
    "TopologyError",
    "NotAChainError",
    "HalfEdgeNotFreeError",
    "NonManifoldError",
    "VertexNotFreeError",
    "PolicyError",
    "EulerError",
    "MissingDependencyError",
    "NonOrientableError",
    "NoPathError",
    "ReadOnlyError",
    "RevisionNotFoundError",
    "InvariantViolationError",
    "StoreError",
    "StoreBusyError",
    "SchemaVersionError",
    "WrongThreadError",
]
