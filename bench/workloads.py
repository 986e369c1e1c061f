"""The workloads several benchmarks share: the triangulated grid, the shared large meshes, storing one, and the
gates run on a stored mesh.

Called by the benchmark scripts (``bench/<name>.py``), in their parents and in their steps; each keeps the
workloads only it uses (sites on the grid, edit plans, a broken grid) in its own file.
"""

from __future__ import annotations

import os
import time

import numpy as np

import hestore

#: The shared large meshes: the file of each, read in place from the meshes folder (``--meshes-dir``).
FILES = {"bunny": "stanford-bunny-subdiv2.obj", "igea": "igea-subdiv1.ply"}
#: What ``--only`` chooses from: the grid, which needs no file, and the files.
MESHES = ("grid", "bunny", "igea")


class Rollback(Exception):
    """Raised at the end of a measuring block to roll its transaction back."""


def grid_arrays(n: int, m: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The triangulated grid of n×n vertices (n×m: ``m`` rows of ``n``), counter-clockwise.

    Vertex ``j·n + i`` is at ``(i, j, 0)``; cell ``(i, j)``, ``c = j·(n-1) + i``, holds triangles ``2c``
    ``(v, v+1, v+n+1)`` and ``2c+1`` ``(v, v+n+1, v+n)`` with ``v = j·n + i``.

    Returns
    -------
    positions : ndarray
        Shape (nm, 3), float64.
    faces : ndarray
        Shape (2(n-1)(m-1), 3), int64.
    """
    m = n if m is None else m
    j, i = np.divmod(np.arange(n * m, dtype=np.int64), n)
    positions = np.column_stack([i, j, np.zeros(n * m)]).astype(np.float64)
    v = (np.arange(m - 1)[:, None] * n + np.arange(n - 1)[None, :]).ravel()
    faces = np.empty((2 * len(v), 3), dtype=np.int64)
    faces[0::2] = np.column_stack([v, v + 1, v + n + 1])
    faces[1::2] = np.column_stack([v, v + n + 1, v + n])
    return positions, faces


def grid_counts(nx: int, ny: int) -> tuple[int, int, int]:
    """Vertices, edges and triangles of the grid of nx×ny vertices: rows, columns and one diagonal per cell."""
    return nx * ny, (nx - 1) * ny + nx * (ny - 1) + (nx - 1) * (ny - 1), 2 * (nx - 1) * (ny - 1)


def triangles_label(nx: int, ny: int) -> str:
    """A grid as the figures' mesh column names it: its number of triangles."""
    return f"{grid_counts(nx, ny)[2]:,}"


def mesh_label(mesh: str, n: int, files: dict[str, str] = FILES) -> str:
    """A workload mesh as the figures' mesh column names it: the grid and its size, or the file."""
    if mesh == "grid":
        return f"grid {n}×{n}"
    return files[mesh]


def present(meshes: list[str], folder: str, files: dict[str, str] | None = None) -> tuple[list[str], list[str]]:
    """The meshes of ``--only`` whose file is in the meshes folder, and a line for each one that is not.

    Parameters
    ----------
    meshes : list of str
        The meshes asked for.
    folder : str
        The meshes folder.
    files : dict, optional
        The file of each mesh (default `FILES`; a benchmark's smaller stand-ins).

    Returns
    -------
    meshes : list of str
    skipped : list of str
    """
    files = FILES if files is None else files
    found, skipped = [], []
    for m in meshes:
        if m in files and not os.path.exists(os.path.join(folder, files[m])):
            skipped.append(f"{m}: {os.path.join(folder, files[m])} not found")
        else:
            found.append(m)
    return found, skipped


def import_mesh(store: hestore.Store, mesh: str, n: int, folder: str, grid: tuple | None = None, *,
                files: dict[str, str] = FILES, **options):
    """Store one workload mesh under its own name.

    Parameters
    ----------
    store : hestore.Store
    mesh : str
        ``"grid"`` (through ``store.import_arrays``) or a shared file (through ``store.import_file``).
    n : int
        The grid's vertices per side.
    folder : str
        The meshes folder.
    grid : tuple, optional
        The grid's arrays, when the caller made them before a timed region.
    files : dict
        The file of each mesh.
    **options
        Passed to the import (``on_error``, ``orient``, ...).

    Returns
    -------
    hestore's import report.
    """
    if mesh == "grid":
        positions, faces = grid if grid is not None else grid_arrays(n)
        return store.import_arrays("grid", positions, faces, **options)
    return store.import_file(os.path.join(folder, files[mesh]), mesh, **options)


def counts_text(counts) -> str:
    """Counts of vertices, half-edges, edges and polygons as ``V/H/E/P 1/2/3/4`` (with thousands separators)."""
    return "V/H/E/P " + "/".join(f"{c:,}" for c in counts)


def timed_check(store: hestore.Store, name: str) -> dict:
    """``mesh.check()`` of one stored mesh, timed (a correctness gate, not a figure).

    Returns
    -------
    dict
        ``seconds``, ``violations`` (how many), ``examples`` (the first five) and ``counts`` (V, H, E, P).
    """
    mesh = store.mesh(name)
    t0 = time.perf_counter()
    violations = mesh.check()
    seconds = time.perf_counter() - t0
    c = mesh.counts()
    return {"seconds": seconds, "violations": len(violations), "examples": [str(v) for v in violations[:5]],
            "counts": [c.vertices, c.halfedges, c.edges, c.polygons]}
