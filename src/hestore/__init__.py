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

``import hestore`` loads nothing: each name below is imported from its
module on first use (`__getattr__`), so that the command line's entry point
(`hestore.__main__`) runs before SQLAlchemy, numpy and the library load and
can handle a Ctrl-C while they do. ``hestore.open`` and the rest behave as
if imported here; so do ``hestore.bulk`` and the other modules.
"""

# Not typing's: importing typing takes longer than the rest of this module. Type checkers know the name.
TYPE_CHECKING = False

__version__ = "0.1.0"

#: Each public name's module: `__getattr__` imports it from there on first use. The same imports, written out
#: under ``TYPE_CHECKING`` below, are what tools that read the source see (the documentation, type checkers);
#: tests/test_architecture.py checks that the two and ``__all__`` name the same things.
_HOMES = {
    "hestore.store": ("open", "Store"),
    "hestore.mesh": ("Mesh", "Counts"),
    "hestore.history": ("Diff", "Revision"),
    "hestore._values": ("Property",),
    "hestore.summary": ("Stats",),
    "hestore.handles": ("Vertex", "HalfEdge", "Edge", "Polygon"),
    "hestore.bulk": ("ImportReport", "SkippedPolygon", "MeshArrays"),
    "hestore.errors": (
        "Violation", "HestoreError", "ElementNotFoundError", "PropertyNotFoundError", "MeshNotFoundError",
        "InvalidInputError", "MeshExistsError", "TopologyError", "NotAChainError", "HalfEdgeNotFreeError",
        "NonManifoldError", "VertexNotFreeError", "PolicyError", "EulerError", "MissingDependencyError",
        "NonOrientableError", "NoPathError", "ReadOnlyError", "RevisionNotFoundError", "InvariantViolationError",
        "StoreError", "StoreBusyError", "StoreNotFoundError", "SchemaVersionError", "WrongThreadError",
    ),
}
_HOME = {name: module for module, names in _HOMES.items() for name in names}

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
    "StoreNotFoundError",
    "SchemaVersionError",
    "WrongThreadError",
]

if TYPE_CHECKING:
    from hestore.store import Store, open
    from hestore.mesh import Counts, Mesh
    from hestore.history import Diff, Revision
    from hestore._values import Property
    from hestore.summary import Stats
    from hestore.handles import Edge, HalfEdge, Polygon, Vertex
    from hestore.bulk import ImportReport, MeshArrays, SkippedPolygon
    from hestore.errors import (
        ElementNotFoundError,
        EulerError,
        HalfEdgeNotFreeError,
        HestoreError,
        InvalidInputError,
        InvariantViolationError,
        MeshExistsError,
        MeshNotFoundError,
        MissingDependencyError,
        NoPathError,
        NonManifoldError,
        NonOrientableError,
        NotAChainError,
        PolicyError,
        PropertyNotFoundError,
        ReadOnlyError,
        RevisionNotFoundError,
        SchemaVersionError,
        StoreBusyError,
        StoreError,
        StoreNotFoundError,
        TopologyError,
        VertexNotFreeError,
        Violation,
        WrongThreadError,
    )


def __getattr__(name: str):
    """A public name, imported from its module on first use; or a module of the package (``hestore.bulk``)."""
    import importlib

    module = _HOME.get(name)
    if module is not None:
        value = getattr(importlib.import_module(module), name)
        globals()[name] = value  # found here from now on, without this call
        return value
    if name.startswith("__"):  # what tools ask of any module (``__wrapped__``, ...): never a module of ours
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    try:
        return importlib.import_module(f"{__name__}.{name}")
    except ModuleNotFoundError as exc:
        if exc.name != f"{__name__}.{name}":
            raise
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})
