"""Interop with the mesh libraries users already have: trimesh and meshio (optional extras).

This module owns the conversions between a stored mesh and a
``trimesh.Trimesh`` or a ``meshio.Mesh``, and the file formats hestore reads
and writes through meshio (STL, VTK, VTU). Both libraries are optional
(``pip install "hestore[trimesh]"``, ``"hestore[meshio]"``); without them
these calls raise `MissingDependencyError` saying what to install.

Everything goes through `hestore.bulk`'s arrays: a mesh leaves as
`hestore.bulk.to_arrays` gives it (vertices in id order, polygons in id
order from their ``halfedge``) and comes back as a polygon soup that
`hestore.Store.import_arrays` stores (one transaction, the same checks and
``on_error``). What a library cannot hold is said, never lost silently:

* trimesh holds triangles only: other polygons are cut into fans from their
  first corner (k − 2 triangles for a k-gon), and ``metadata["polygon"]``
  maps each triangle to the polygon id it came from;
* meshio holds polygons of any arity in blocks (``triangle``, ``quad``,
  ``polygon`` per larger arity): nothing is cut, and reading one back keeps
  the blocks' order. STL holds triangles only and is written as fans too.
  Cells that are not polygons (lines, tetrahedra, …) are refused on import
  with `InvalidInputError` naming their types.
"""

from __future__ import annotations

import contextlib
import io
import warnings
from typing import Any

import numpy as np

from hestore import bulk, navigation
from hestore.errors import InvalidInputError, require
from hestore.io import file_errors
from hestore._session import MeshRef
from hestore.urls import check_path
from hestore._values import check_arraylike

__all__ = [
    "MESHIO_EXTENSIONS",
    "to_trimesh",
    "trimesh_soup",
    "to_meshio",
    "meshio_soup",
    "read_meshio_file",
    "write_meshio_file",
]

#: File extensions read and written through meshio.
MESHIO_EXTENSIONS = (".stl", ".vtk", ".vtu")

#: meshio's block names for polygons of a fixed arity (larger ones are "polygon").
_BLOCKS = {3: "triangle", 4: "quad"}


def _polygons(ref: MeshRef) -> tuple[np.ndarray, list[np.ndarray], np.ndarray, np.ndarray]:
    """Positions (every vertex positioned), polygons by corner rows, polygon ids, vertex ids."""
    arrays = bulk.to_arrays(ref)
    if len(arrays.positions) and np.isnan(arrays.positions).any():
        missing = int(arrays.vertex_ids[np.isnan(arrays.positions).any(axis=1)][0])
        raise InvalidInputError(f"vertex {missing} of mesh {ref.name!r} has no position: it cannot be exported")
    polygons = arrays.polygons
    rows = [np.asarray(p, dtype=np.int64) for p in polygons] if isinstance(polygons, list) else list(polygons)
    polygon_ids = np.array(navigation.ids(ref, "polygon"), dtype=np.int64)
    return arrays.positions, rows, polygon_ids, arrays.vertex_ids


def _fans(rows: list[np.ndarray], ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Triangles cutting each polygon into a fan from its first corner, and the polygon id of each."""
    tris, owner = [], []
    for pid, row in zip(ids.tolist(), rows):
        k = len(row)
        if k < 3:
            continue
        tris.append(np.stack([np.full(k - 2, row[0]), row[1:-1], row[2:]], axis=1))
        owner.append(np.full(k - 2, pid))
    if not tris:
        return np.zeros((0, 3), dtype=np.int64), np.zeros(0, dtype=np.int64)
    return np.concatenate(tris).astype(np.int64), np.concatenate(owner).astype(np.int64)


def to_trimesh(ref: MeshRef) -> Any:
    """The mesh as a ``trimesh.Trimesh`` (vertices in id order; non-triangles cut into fans).

    ``metadata["vertex_ids"]`` holds each trimesh vertex's id, and
    ``metadata["polygon"]`` each face's polygon id. trimesh does not merge or
    reorder anything (``process=False``). 1-gons and 2-gons have no triangle.

    Examples
    --------
    >>> import hestore
    >>> store = hestore.open("sqlite://")
    >>> quad = store.import_arrays("q", [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)], [[0, 1, 2, 3]]).mesh
    >>> tm = quad.to_trimesh()
    >>> tm.faces.tolist(), tm.metadata["polygon"].tolist()
    ([[0, 1, 2], [0, 2, 3]], [0, 0])
    """
    trimesh = require("trimesh")
    positions, rows, ids, vertex_ids = _polygons(ref)
    faces, owner = _fans(rows, ids)
    tm = trimesh.Trimesh(vertices=positions, faces=faces, process=False)
    tm.metadata["vertex_ids"] = vertex_ids
    tm.metadata["polygon"] = owner
    return tm


def trimesh_soup(tm: Any) -> tuple[Any, Any]:
    """A ``trimesh.Trimesh`` as a polygon soup ``(positions, triangles)``: what `hestore.Store.import_trimesh` stores.

    Vertex ``i`` and face ``j`` in its order.

    Examples
    --------
    >>> import trimesh
    >>> positions, triangles = trimesh_soup(trimesh.creation.box())
    >>> positions.shape, triangles.shape
    ((8, 3), (12, 3))
    """
    if not (hasattr(tm, "vertices") and hasattr(tm, "faces")):
        raise InvalidInputError(f"expected a trimesh.Trimesh, got {type(tm).__name__}")
    return tm.vertices, tm.faces


def _cells(rows: list[np.ndarray]) -> list[tuple[str, np.ndarray]]:
    """meshio cell blocks: consecutive polygons of one arity share a block, in polygon order."""
    blocks: list[tuple[str, list]] = []
    for row in rows:
        k = len(row)
        kind = _BLOCKS.get(k, "polygon")
        if not blocks or blocks[-1][0] != kind or len(blocks[-1][1][0]) != k:
            blocks.append((kind, []))
        blocks[-1][1].append(row)
    return [(kind, np.array(cells, dtype=np.int64)) for kind, cells in blocks]


def to_meshio(ref: MeshRef) -> Any:
    """The mesh as a ``meshio.Mesh``: every polygon kept, in blocks by arity, in polygon id order.

    Examples
    --------
    >>> import hestore
    >>> store = hestore.open("sqlite://")
    >>> xyz = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (2, 0, 0)]
    >>> m = store.import_arrays("m", xyz, [[0, 1, 2, 3], [1, 4, 2]]).mesh.to_meshio()
    >>> [(c.type, c.data.tolist()) for c in m.cells]
    [('quad', [[0, 1, 2, 3]]), ('triangle', [[1, 4, 2]])]
    """
    meshio = require("meshio")
    positions, rows, _ids, _vertex_ids = _polygons(ref)
    return meshio.Mesh(positions, [(kind, cells) for kind, cells in _cells([r for r in rows if len(r) >= 3])])


def _soup_of(m: Any, what: str) -> tuple[Any, list]:
    surface, other = [], []
    for block in m.cells:
        if block.type in ("triangle", "quad") or block.type.startswith("polygon"):
            cells = check_arraylike(block.data, f"{what}: {block.type} cells must be rows of indices", np.int64)
            surface.extend(cells.tolist())
        else:
            other.append(block.type)
    if other:
        raise InvalidInputError(
            f"{what} has cells that are not polygons ({', '.join(sorted(set(other)))}): hestore stores surfaces "
            f"and graphs of polygons; nothing was stored"
        )
    return m.points, surface


def meshio_soup(m: Any) -> tuple[Any, list]:
    """A ``meshio.Mesh`` of polygon cells (``triangle``, ``quad``, ``polygon``) as a polygon soup.

    What `hestore.Store.import_meshio` stores: ``(positions, polygons)``.
    Cells that are not polygons are refused.

    Examples
    --------
    >>> import meshio
    >>> m = meshio.Mesh([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [("triangle", [[0, 1, 2]])])
    >>> meshio_soup(m)[1]
    [[0, 1, 2]]
    """
    if not (hasattr(m, "points") and hasattr(m, "cells")):
        raise InvalidInputError(f"expected a meshio.Mesh, got {type(m).__name__}")
    return _soup_of(m, "the meshio mesh")


def read_meshio_file(path) -> tuple[Any, list]:
    """Read an STL, VTK or VTU file through meshio as a polygon soup (`hestore.Store.import_file` stores it)."""
    meshio = require("meshio")
    path = check_path(path)
    with file_errors(path, "read"), open(path, "rb"):
        pass  # the system's own reason (missing, a folder, no permission), not meshio's guess
    said = io.StringIO()
    try:
        # meshio prints its complaints and calls sys.exit on a file it cannot
        # parse, and its STL sniffing overflows harmlessly: keep all of that quiet.
        with contextlib.redirect_stdout(said), contextlib.redirect_stderr(said), warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            m = meshio.read(path)
    except (Exception, SystemExit) as exc:  # many exception types, and SystemExit, for one malformed file
        why = " ".join(said.getvalue().split()) or str(exc) or type(exc).__name__
        raise InvalidInputError(f"{path}: meshio cannot read it: {why}") from None
    return _soup_of(m, path)


def write_meshio_file(ref: MeshRef, path) -> None:
    """Write an STL (triangles: polygons cut into fans), VTK or VTU file through meshio."""
    meshio = require("meshio")
    path = check_path(path)
    if path.lower().endswith(".stl"):
        positions, rows, ids, _vertex_ids = _polygons(ref)
        faces, _owner = _fans(rows, ids)
        m = meshio.Mesh(positions, [("triangle", faces)])
    else:
        m = to_meshio(ref)
    with file_errors(path, "write"):
        meshio.write(path, m)
