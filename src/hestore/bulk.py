"""Bulk import and export: polygon soups and mesh files in, arrays and files out.

This module owns moving whole meshes in and out of a store:
`import_arrays` and `import_file` (SPEC §5) decide and build the half-edge
structure with `hestore.build` and write every table in large batches with
`hestore.columns`, bypassing the per-edit unit of work; `to_arrays` and
`export` read the tables back as columns and walk the polygon loops with
numpy. File formats are `hestore.formats`'s.

An import is one transaction: it stores the whole mesh or nothing. With
``on_error="raise"`` the first polygon the structure cannot take is reported
before anything is written; with ``on_error="skip"`` every such polygon is
left out and listed in the `ImportReport`.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Callable, NamedTuple

import numpy as np
import sqlalchemy as sa

from hestore import build as _build
from hestore import io as mesh_io
from hestore import schema
from hestore.columns import read_columns, uses_copy, write_columns
from hestore.errors import InvalidInputError, MeshExistsError

if TYPE_CHECKING:  # pragma: no cover
    from hestore.mesh import Mesh
    from hestore.store import Store

__all__ = ["SkippedPolygon", "ImportReport", "MeshArrays", "import_arrays", "import_file", "to_arrays", "export"]

#: ``progress(stage, done, total)``: stage is ``"read"`` (bytes), ``"build"`` or ``"write"`` (rows).
Progress = Callable[[str, int, int], None]

ON_ERROR = ("raise", "skip")


class SkippedPolygon(NamedTuple):
    """A polygon an import left out: its input index, its file line (or None) and why."""

    index: int
    line: int | None
    reason: str

    def __str__(self) -> str:
        where = f" (line {self.line})" if self.line is not None else ""
        return f"polygon {self.index}{where}: {self.reason}"


@dataclass(frozen=True)
class ImportReport:
    """What an import stored and what it left out.

    Attributes
    ----------
    mesh : Mesh
        The new mesh.
    vertices, edges, polygons : int
        How many of each were stored.
    skipped : list of SkippedPolygon
        Every polygon left out, in input order (empty with ``on_error="raise"``).
    source : str or None
        The file imported, if any.
    """

    mesh: "Mesh"
    vertices: int
    edges: int
    polygons: int
    skipped: list = field(default_factory=list)
    source: str | None = None

    def summary(self, limit: int = 20) -> str:
        """A few lines for people: counts, then up to ``limit`` skipped polygons."""
        head = f"{self.mesh.name}: {self.vertices} vertices, {self.edges} edges, {self.polygons} polygons"
        if self.source:
            head += f" from {self.source}"
        lines = [head]
        if self.skipped:
            lines.append(f"skipped {len(self.skipped)} polygon(s) the half-edge structure cannot take:")
            lines.extend(f"  {s}" for s in self.skipped[:limit])
            if len(self.skipped) > limit:
                lines.append(f"  ... and {len(self.skipped) - limit} more")
        return "\n".join(lines)


class MeshArrays(NamedTuple):
    """A mesh as arrays: row ``i`` of ``positions`` is vertex ``vertex_ids[i]``.

    ``polygons`` index rows: an ``(F, k)`` int64 array when every polygon has
    ``k`` corners, else a list of lists. A vertex without a position has a
    row of NaN.
    """

    positions: np.ndarray
    polygons: np.ndarray | list
    vertex_ids: np.ndarray


def _check_on_error(on_error: str) -> None:
    if on_error not in ON_ERROR:
        raise InvalidInputError(f"on_error must be 'raise' or 'skip', not {on_error!r}")


def _as_positions(positions) -> np.ndarray:
    try:
        pos = np.asarray(positions, dtype=np.float64)
    except (TypeError, ValueError):
        raise InvalidInputError("positions must be an (V, 3) or (V, 2) array of numbers") from None
    if pos.ndim == 2 and pos.shape[1] == 2:
        pos = np.column_stack([pos, np.zeros(len(pos))])
    if pos.ndim != 2 or pos.shape[1] != 3:
        if pos.size == 0:
            return np.zeros((0, 3))
        raise InvalidInputError(f"positions must be an (V, 3) or (V, 2) array, not of shape {pos.shape}")
    bad = ~np.isfinite(pos).all(axis=1)
    if bad.any():
        row = int(np.flatnonzero(bad)[0])
        raise InvalidInputError(f"position {row} is {pos[row].tolist()}: coordinates must be finite")
    return pos


def import_arrays(
    store: "Store",
    name: str,
    positions,
    polygons,
    *,
    on_error: str = "raise",
    allow_loops: bool = True,
    allow_multi_edges: bool = True,
    progress: Progress | None = None,
) -> ImportReport:
    """Store a polygon soup as a new mesh, built set-based.

    The result is the topology that `Mesh.add_polygon` would give, called on
    the polygons one by one in order (up to the order of free gaps around a
    vertex where several fans meet): vertex ``i`` is ``positions[i]``,
    polygon ids follow input order among the polygons kept, and vertices no
    polygon uses are kept as isolated vertices.

    Parameters
    ----------
    store : Store
    name : str
        The new mesh's name.
    positions : array_like, shape (V, 3) or (V, 2)
        Finite coordinates.
    polygons : array_like, shape (F, k), or sequence of sequences of int
        Corners of each polygon, counter-clockwise, as row indices of
        ``positions``.
    on_error : {"raise", "skip"}
        What to do with a polygon the structure cannot take (an edge that
        would get a third polygon, an orientation that contradicts a
        neighbour's, a repeated vertex it cannot hold, an index out of range,
        no vertices at all, a closed fan meeting other polygons at a vertex):
        raise, storing nothing, or leave it out and report it.
    allow_loops, allow_multi_edges : bool
        The new mesh's policy (see `Store.create_mesh`).
    progress : callable, optional
        ``progress(stage, done, total)``.

    Returns
    -------
    ImportReport

    Raises
    ------
    InvalidInputError, HalfEdgeNotFreeError, NonManifoldError, PolicyError
        With ``on_error="raise"``, for the first bad polygon; the error's
        ``skipped`` attribute is its `SkippedPolygon`.
    MeshExistsError
        A mesh of that name exists.

    Examples
    --------
    >>> import hestore
    >>> store = hestore.open("sqlite://")
    >>> square = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]
    >>> report = store.import_arrays("square", square, [[0, 1, 2], [0, 2, 3]])
    >>> report.polygons, report.edges, report.mesh.check()
    (2, 5, [])
    >>> report = store.import_arrays("bad", square, [[0, 1, 2], [0, 1, 3]], on_error="skip")
    >>> report.polygons, report.skipped[0].index
    (1, 1)
    """
    _check_on_error(on_error)
    _check_name(store, name)
    return _import(store, name, _as_positions(positions), _build.ragged(polygons), on_error, allow_loops, allow_multi_edges, progress)


def _check_name(store: "Store", name: str) -> None:
    store._check_open()
    if name in store.meshes():
        raise MeshExistsError(f"a mesh named {name!r} already exists; choose another name")


def _import(store, name, pos, soup, on_error, allow_loops, allow_multi_edges, progress, *, lines=None, source=None, index_base=0):
    """Decide, then write: nothing is stored unless every check has passed."""
    if progress is not None:
        progress("build", 0, 1)
    built = _build.build(len(pos), soup, allow_loops=allow_loops, index_base=index_base)
    if progress is not None:
        progress("build", 1, 1)
    skipped = [
        SkippedPolygon(r.index, None if lines is None else int(lines[r.index]), r.reason) for r in built.refused
    ]
    if skipped and on_error == "raise":
        first, error = skipped[0], built.refused[0].error
        prefix = f"{source}: " if source else ""
        exc = error(f"{prefix}{first}; nothing was stored (on_error='skip' would leave it out)")
        exc.skipped = first
        raise exc
    mesh = _write(store, name, pos, built, allow_loops, allow_multi_edges, progress)
    return ImportReport(mesh, len(pos), built.arrays.edges, len(built.accepted), skipped, source)


def _write(store, name, pos, built, allow_loops, allow_multi_edges, progress) -> "Mesh":
    """Create the mesh and write its four tables in one transaction."""
    a = built.arrays
    n_v, n_h, n_e, n_p = len(pos), a.halfedges, a.edges, len(built.accepted)
    ids = np.arange(n_h, dtype=np.int64)
    tables = [
        (schema.vertices, {"id": np.arange(n_v), "halfedge": a.vertex_halfedge, "x": pos[:, 0], "y": pos[:, 1], "z": pos[:, 2]}),
        (schema.halfedges, {"id": ids, "origin": a.origin, "next": a.next, "prev": a.prev, "twin": ids ^ 1, "edge": ids >> 1, "polygon": a.polygon}),
        (schema.edges, {"id": np.arange(n_e), "halfedge": 2 * np.arange(n_e)}),
        (schema.polygons, {"id": np.arange(n_p), "halfedge": a.polygon_halfedge}),
    ]
    total = n_v + n_h + n_e + n_p
    done = 0
    outer = not store.in_transaction
    dialect = store._engine.dialect
    with store.transaction():
        mesh = store.create_mesh(name, allow_loops=allow_loops, allow_multi_edges=allow_multi_edges)
        cursor = store._cursor()
        for table, columns in tables:
            report = None
            if progress is not None:
                report = lambda rows, base=done: progress("write", base + rows, total)  # noqa: E731
            write_columns(cursor, dialect, table, mesh._id, columns, progress=report)
            done += len(columns["id"])
        m = schema.meshes
        stmt = (
            sa.update(m)
            .where(m.c.id == mesh._id)
            .values(next_vertex=n_v, next_edge=n_e, next_polygon=n_p, revision=m.c.revision + 1)
        )
        store._conn.execute(stmt)
        store._bumped.add(mesh._id)
    if outer and uses_copy(dialect):
        # Fresh statistics, so the planner knows how large the tables just became.
        for table, _ in tables:
            store._raw_exec(f"ANALYZE {table.name}")
    if progress is not None:
        progress("write", total, total)
    return mesh


def import_file(
    store: "Store",
    path,
    name: str | None = None,
    *,
    on_error: str = "raise",
    allow_loops: bool = True,
    allow_multi_edges: bool = True,
    progress: Progress | None = None,
) -> ImportReport:
    """Import an OFF, OBJ or PLY file (ASCII or binary) as a new mesh.

    The file's vertex and polygon order are kept, vertices are never welded
    by position and polygons are never triangulated; see `import_arrays` for
    what is built and how bad polygons are handled (each `SkippedPolygon`
    carries its file line for ASCII files).

    Parameters
    ----------
    store : Store
    path : str or os.PathLike
        The file; its format comes from its extension.
    name : str, optional
        The new mesh's name; by default the file name without extension.
    on_error, allow_loops, allow_multi_edges, progress
        As for `import_arrays`.

    Returns
    -------
    ImportReport

    Raises
    ------
    InvalidInputError
        The file is malformed (bad header, non-numeric or non-finite values,
        truncated); the message names the file and line. Nothing is stored.

    Examples
    --------
    >>> import hestore, tempfile, pathlib
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> _ = (folder / "tri.off").write_text("OFF\\n3 1 0\\n0 0 0\\n1 0 0\\n0 1 0\\n3 0 1 2\\n")
    >>> store = hestore.open("sqlite://")
    >>> report = store.import_file(folder / "tri.off")
    >>> report.mesh.name, report.vertices, report.polygons
    ('tri', 3, 1)
    """
    _check_on_error(on_error)
    path = os.fspath(path)
    kind = mesh_io.format_of(path)
    if name is None:
        name = os.path.splitext(os.path.basename(path))[0]
    _check_name(store, name)
    read_progress = None
    if progress is not None:
        read_progress = lambda done, total: progress("read", done, total)  # noqa: E731
    soup = mesh_io.read(path, progress=read_progress)
    return _import(
        store,
        name,
        soup.positions,
        _build.Ragged(soup.offsets, soup.indices),
        on_error,
        allow_loops,
        allow_multi_edges,
        progress,
        lines=soup.lines,
        source=path,
        index_base=1 if kind == "obj" else 0,  # OBJ counts vertices from 1; say so in messages
    )


def _soup(mesh: "Mesh") -> tuple[np.ndarray, _build.Ragged, np.ndarray]:
    """Positions, polygon loops (as rows) and vertex ids of the committed-or-own state."""
    mesh.revision  # raises MeshNotFoundError for a deleted mesh
    v, h, p = schema.vertices, schema.halfedges, schema.polygons
    nan_free = [sa.func.coalesce(v.c[k], 0.0) for k in "xyz"]
    missing = sa.case((v.c.x.is_(None) | v.c.y.is_(None) | v.c.z.is_(None), 1), else_=0)
    with mesh._store._read() as conn:
        (v_id, vx, vy, vz, v_missing), (h_id, h_origin, h_next), (p_id, p_he) = read_columns(
            conn,
            mesh._id,
            [(v, [v.c.id, *nan_free, missing]), (h, [h.c.id, h.c.origin, h.c.next]), (p, [p.c.id, p.c.halfedge])],
        )
    positions = np.column_stack([vx, vy, vz])
    positions[v_missing.astype(bool)] = np.nan
    # Rows instead of ids: ids are never reused, so after deletions they have gaps.
    next_row = np.searchsorted(h_id, h_next)
    origin_row = np.searchsorted(v_id, h_origin)
    start = np.searchsorted(h_id, p_he)
    steps_v, steps_p = [], []
    cur = start.copy()
    active = np.arange(len(p_id))
    for _ in range(len(h_id) + 1):
        if not len(active):
            break
        steps_v.append(origin_row[cur])
        steps_p.append(active)
        cur = next_row[cur]
        going = cur != start[active]
        active, cur = active[going], cur[going]
    poly = np.concatenate(steps_p) if steps_p else np.zeros(0, dtype=np.int64)
    verts = np.concatenate(steps_v) if steps_v else np.zeros(0, dtype=np.int64)
    order = np.argsort(poly, kind="stable")  # steps were appended in loop order
    counts = np.bincount(poly, minlength=len(p_id))
    offsets = np.zeros(len(p_id) + 1, dtype=np.int64)
    np.cumsum(counts, out=offsets[1:])
    return positions, _build.Ragged(offsets, verts[order]), v_id


def to_arrays(mesh: "Mesh") -> MeshArrays:
    """The mesh's vertices and polygons as arrays.

    Polygons are in id order, each starting at its ``halfedge`` and running
    along ``next`` (so an imported mesh gives back its input loops). Wire
    edges are not polygons and do not appear.

    Returns
    -------
    MeshArrays
        ``(positions, polygons, vertex_ids)``.

    Examples
    --------
    >>> import hestore
    >>> store = hestore.open("sqlite://")
    >>> mesh = store.import_arrays("q", [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)], [[0, 1, 2, 3]]).mesh
    >>> arrays = mesh.to_arrays()
    >>> arrays.polygons.tolist(), arrays.vertex_ids.tolist(), arrays.positions.shape
    ([[0, 1, 2, 3]], [0, 1, 2, 3], (4, 3))
    """
    positions, soup, vertex_ids = _soup(mesh)
    counts = np.diff(soup.offsets)
    if len(counts) and (counts == counts[0]).all():
        polygons = soup.indices.reshape(len(counts), int(counts[0]))
    elif not len(counts):
        polygons = np.zeros((0, 3), dtype=np.int64)
    else:
        polygons = [soup.indices[a:b].tolist() for a, b in zip(soup.offsets[:-1].tolist(), soup.offsets[1:].tolist())]
    return MeshArrays(positions, polygons, vertex_ids)


def export(mesh: "Mesh", path, *, binary: bool = True, progress: Progress | None = None) -> None:
    """Write the mesh's vertices and polygons to an OFF, OBJ or PLY file.

    The format comes from the extension; ``binary`` applies to PLY (binary
    little endian, else ASCII). Vertices are written in id order and
    polygons as `to_arrays` gives them, so importing the file again gives a
    mesh with the same counts and topology. Wire edges are not written.

    Raises
    ------
    InvalidInputError
        A vertex has no position, or the extension is not a known format.

    Examples
    --------
    >>> import hestore, tempfile, pathlib
    >>> store = hestore.open("sqlite://")
    >>> mesh = store.import_arrays("t", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [[0, 1, 2]]).mesh
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "t.ply"
    >>> mesh.export(path)
    >>> store.import_file(path, "again").mesh.to_arrays().polygons.tolist()
    [[0, 1, 2]]
    """
    mesh_io.format_of(path)
    if progress is not None:
        progress("read", 0, 1)
    positions, soup, vertex_ids = _soup(mesh)
    if progress is not None:
        progress("read", 1, 1)
    unplaced = np.isnan(positions).any(axis=1)
    if unplaced.any():
        ids = vertex_ids[unplaced][:5].tolist()
        raise InvalidInputError(
            f"cannot export {mesh.name!r}: {int(unplaced.sum())} vertices have no position (ids {ids}...)"
        )
    write_progress = None
    if progress is not None:
        write_progress = lambda done, total: progress("write", done, total)  # noqa: E731
    mesh_io.write(path, positions, soup.offsets, soup.indices, binary=binary, progress=write_progress)
