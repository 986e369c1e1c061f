"""Bulk import and export: polygon soups and mesh files in, arrays and files out.

This module owns moving whole meshes in and out of a store, below the
catalogue: `build_arrays` and `build_file` decide and build the half-edge
structure of an import with `hestore.build` (`BuiltImport`, under one
`ImportOptions`), and `write` hands its whole tables to the unit of work of
the mesh `hestore.Store` created for it (`UnitOfWork.insert_bulk`), whose
flush writes them in large batches (`hestore._columns`) like any other
change. `to_arrays` and `export` read the tables back as columns in one
snapshot and walk the polygon loops with numpy; `dual` computes the dual's
polygon soup. Every function here is handed a mesh's identity
(`hestore._session.MeshRef`) or arrays, never the store: the store decides
names and creates meshes. File formats are `hestore.io`'s.

File data other than positions and polygons travels as properties
(SPEC §3.2): a file's vertex and polygon properties (PLY) and its corner
properties (OBJ ``vt``/``vn`` as half-edge ``uv``/``normal``) are declared on
the new mesh and written by the same flush, set-based; `export` writes back
what the format can hold.

An import is one transaction: it stores the whole mesh or nothing. With
``on_error="raise"`` the first polygon the structure cannot take is reported
before anything is written; with ``on_error="skip"`` every such polygon is
left out and listed in the `ImportReport`; with ``on_error="split"`` it is
kept on copies of the vertices where it does not fit
(`hestore.build.separate`). ``orient=True`` reverses polygons first
(`hestore.build.orient`). Every repair is decided on the arrays before
anything is written, and reported.
"""

from __future__ import annotations

import os
import warnings
from dataclasses import dataclass, field
from typing import Any, Callable, NamedTuple

import numpy as np

from hestore import build as _build
from hestore import io as mesh_io
from hestore import properties as props
from hestore import schema
from hestore import _values as values
from hestore.arrays import (
    Index,
    Ragged,
    TopologyArrays,
    cycle_positions,
    cycles,
    polygon_halfedges,
    positions as position_array,
    ragged,
)
from hestore._columns import position_request, request
from hestore.errors import InvalidInputError, NonOrientableError, TopologyError
from hestore.progress import check_progress
from hestore._session import MeshRef
from hestore._unitofwork import BulkRows, BulkValues
from hestore.urls import check_path
from hestore._values import Property

__all__ = [
    "SkippedPolygon", "ImportReport", "ImportOptions", "BuiltImport", "MeshArrays", "name_of", "build_arrays",
    "build_file", "write", "WRITTEN", "dual", "to_arrays", "export",
]

#: ``progress(stage, done, total)``: stage is ``"read"`` (bytes), ``"build"`` or ``"write"`` (rows).
Progress = Callable[[str, int, int], None]

ON_ERROR = ("raise", "skip", "split")


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
    mesh : hestore.Mesh
        The new mesh.
    vertices, edges, polygons : int
        How many of each were stored.
    skipped : list of SkippedPolygon
        Every polygon left out, in input order (empty with ``on_error="raise"``;
        with ``"split"``, only polygons malformed in themselves).
    source : str or None
        The file imported, if any.
    properties : list of Property
        The properties the file's data became (PLY vertex and face
        properties, OBJ corner ``uv`` and ``normal``).
    flipped : list of int
        With ``orient=True``: the input polygons that were reversed, in
        input order (their corner data reversed with them).
    split : dict of int to list of int
        With ``on_error="split"``: each input vertex that was copied, and
        the ids of its copies (which take its position and properties).
    cut : list of (int, int)
        With ``orient=True`` and ``on_error="split"``: the edges, as input
        vertex pairs, along which components that cannot be oriented were
        cut (one of each edge's polygons is on a copy of a vertex, in
        ``split``).
    """

    mesh: Any
    vertices: int
    edges: int
    polygons: int
    skipped: list = field(default_factory=list)
    source: str | None = None
    properties: list = field(default_factory=list)
    flipped: list = field(default_factory=list)
    split: dict = field(default_factory=dict)
    cut: list = field(default_factory=list)

    def summary(self, limit: int = 20) -> str:
        """A few lines for people: counts, then up to ``limit`` skipped polygons."""
        head = f"{self.mesh.name}: {self.vertices} vertices, {self.edges} edges, {self.polygons} polygons"
        if self.source:
            head += f" from {self.source}"
        lines = [head]
        if self.properties:
            lines.append("properties: " + ", ".join(map(_described, self.properties)))
        if self.flipped:
            shown = ", ".join(map(str, self.flipped[:limit])) + (", ..." if len(self.flipped) > limit else "")
            lines.append(f"reversed {len(self.flipped)} polygon(s) to orient every component consistently: {shown}")
        if self.cut:
            shown = _listed([f"{a}–{b}" for a, b in self.cut[:limit]], len(self.cut))
            lines.append(f"cut {len(self.cut)} edge(s) so that every component could be oriented: {shown}")
        if self.split:
            copies = sum(map(len, self.split.values()))
            items = list(self.split.items())[:limit]
            shown = _listed([f"{v} → {', '.join(map(str, c))}" for v, c in items], len(self.split))
            lines.append(
                f"copied {len(self.split)} vertex(es) into {copies} new one(s) so that every polygon fits: {shown}"
            )
        if self.skipped:
            lines.append(f"skipped {len(self.skipped)} polygon(s) the half-edge structure cannot take:")
            lines.extend(f"  {s}" for s in self.skipped[:limit])
            if len(self.skipped) > limit:
                lines.append(f"  ... and {len(self.skipped) - limit} more")
        return "\n".join(lines)


def _listed(shown: list, total: int) -> str:
    return "; ".join(shown) + ("; ..." if total > len(shown) else "")


def _described(p: Property) -> str:
    shape = f", shape {p.shape}" if p.shape else ""
    return f"{p.kind} {p.name!r} ({p.dtype}{shape})"


class MeshArrays(NamedTuple):
    """A mesh as arrays: row ``i`` of ``positions`` is vertex ``vertex_ids[i]``.

    ``polygons`` index rows: an ``(F, k)`` int64 array when every polygon has
    ``k`` corners, else a list of lists. A vertex without a position has a
    row of NaN.
    """

    positions: np.ndarray
    polygons: np.ndarray | list
    vertex_ids: np.ndarray


def _as_positions(positions) -> np.ndarray:
    what = "positions must be a (V, 3) or (V, 2) array of real numbers"
    pos = values.check_arraylike(positions, what)
    if pos.dtype.kind in "iuO":
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("error")  # numpy warns, and drops the imaginary part, for complex values
                pos = pos.astype(np.float64)
        except Exception:  # noqa: BLE001 - text, complex, ints beyond floats, or the items' own __float__
            raise InvalidInputError(f"{what}; these are not") from None
    if pos.size == 0:
        return np.zeros((0, 3))
    if pos.dtype.kind != "f":
        raise InvalidInputError(f"{what}, not of {pos.dtype} values ({pos.reshape(-1)[:3].tolist()}...)")
    pos = pos.astype(np.float64, copy=False)
    if pos.ndim == 2 and pos.shape[1] == 2:
        pos = np.column_stack([pos, np.zeros(len(pos))])
    if pos.ndim != 2 or pos.shape[1] != 3:
        raise InvalidInputError(f"{what}, not of shape {pos.shape}")
    bad = ~np.isfinite(pos).all(axis=1)
    if bad.any():
        row = int(np.flatnonzero(bad)[0])
        raise InvalidInputError(f"position {row} is {pos[row].tolist()}: coordinates must be finite")
    return pos


@dataclass(frozen=True)
class ImportOptions:
    """How an import builds and stores a mesh: one record for every import (arrays, files, trimesh, meshio).

    Checked when made: an option of the wrong kind is `InvalidInputError`
    before anything is read, built or written.

    Attributes
    ----------
    on_error : {"raise", "skip", "split"}
        What to do with a polygon the structure cannot take (an edge that
        would get a third polygon, an orientation that contradicts a
        neighbour's, a repeated vertex it cannot hold, an index out of range,
        no vertices at all, a closed fan meeting other polygons at a vertex):
        raise, storing nothing; leave it out and report it; or, with
        ``"split"``, keep it on its own copies of the vertices where it does
        not fit (`hestore.build.separate`: a cut edge copies the vertex it
        starts from, a closed fan that meets others moves whole), reported in
        ``report.split``. ``"split"`` still leaves out, and reports, a
        polygon malformed in itself (no vertices, an index out of range, a
        self-loop the policy forbids). A soup that imports with ``"raise"``
        gives the same mesh with ``"split"``.
    allow_loops, allow_multi_edges : bool
        The new mesh's policy (see `Store.create_mesh`).
    progress : callable, optional
        ``progress(stage, done, total)``: stage is ``"read"`` (bytes),
        ``"build"`` or ``"write"`` (rows).
    replace : bool
        Replace a mesh of that name, in the same transaction as the import:
        the old mesh goes only if the new one is stored.
    orient : bool
        Reverse polygons, before building, so that each component is
        consistently oriented where it can be (`hestore.build.orient`: the
        lowest polygon of each component keeps its orientation); the
        reversed ones are in ``report.flipped``. A component that cannot be
        oriented (a Möbius strip) raises `NonOrientableError` naming a
        polygon, and nothing is stored; with ``on_error="split"`` it is
        oriented along a spanning tree of its polygons instead and cut along
        the edges where its polygons then disagree (``report.cut``).
    history : bool
        Whether the new mesh keeps its revisions (`Store.create_mesh`); the
        import is its revision 1 either way.

    Examples
    --------
    >>> ImportOptions(on_error="skip").orient
    False
    >>> ImportOptions(orient="yes")
    Traceback (most recent call last):
    ...
    hestore.errors.InvalidInputError: orient is True or False, not str 'yes'
    """

    on_error: str = "raise"
    allow_loops: bool = True
    allow_multi_edges: bool = True
    progress: Progress | None = None
    replace: bool = False
    orient: bool = False
    history: bool = True

    def __post_init__(self) -> None:
        checked = {"on_error": values.check_choice(self.on_error, ON_ERROR, "on_error")}
        check_progress(self.progress)
        for flag in ("allow_loops", "allow_multi_edges", "replace", "orient", "history"):
            checked[flag] = values.check_flag(getattr(self, flag), flag)
        for name, value in checked.items():
            object.__setattr__(self, name, value)


@dataclass(frozen=True)
class BuiltImport:
    """An import decided and built, not yet stored: the tables to write and what the report will say.

    What `build_arrays` and `build_file` return and `write` stores; every
    check has passed by the time one exists.
    """

    positions: np.ndarray
    arrays: TopologyArrays
    #: ``(Property, ids, values)`` of every column of file data, for the elements kept.
    columns: list
    polygons: int
    skipped: list
    source: str | None
    flipped: list
    split: dict
    cut: list

    def report(self, mesh: Any) -> ImportReport:
        """The `ImportReport` of this import, stored as ``mesh`` (a `hestore.Mesh`)."""
        declared = [spec for spec, _, _ in self.columns]
        return ImportReport(
            mesh, len(self.positions), len(self.arrays.e_id), self.polygons, self.skipped, self.source, declared,
            self.flipped, self.split, self.cut,
        )


def name_of(path: str) -> str:
    """The name a file's mesh gets when none is given: the file name without its extension.

    Examples
    --------
    >>> name_of("scans/bunny.ply")
    'bunny'
    """
    return os.path.splitext(os.path.basename(path))[0]


def build_arrays(positions, polygons, options: ImportOptions) -> BuiltImport:
    """Decide and build the import of a polygon soup (`hestore.Store.import_arrays`): nothing is written.

    The result is the topology that `Mesh.add_polygon` would give, called on
    the polygons one by one in order (up to the order of free gaps around a
    vertex where several fans meet): vertex ``i`` is ``positions[i]``,
    polygon ids follow input order among the polygons kept, and vertices no
    polygon uses are kept as isolated vertices.

    Parameters
    ----------
    positions : array_like, shape (V, 3) or (V, 2)
        Finite coordinates.
    polygons : array_like, shape (F, k), or sequence of sequences of int
        Corners of each polygon, counter-clockwise, as row indices of
        ``positions``.
    options : ImportOptions

    Raises
    ------
    InvalidInputError, HalfEdgeNotFreeError, NonManifoldError, PolicyError
        With ``on_error="raise"``, for the first bad polygon; the error's
        ``skipped`` attribute is its `SkippedPolygon`.

    Examples
    --------
    >>> square = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]
    >>> built = build_arrays(square, [[0, 1, 2], [0, 1, 3]], ImportOptions(on_error="skip"))
    >>> built.polygons, built.skipped[0].index
    (1, 1)
    """
    return _built(_as_positions(positions), ragged(polygons), options)


class FileData(NamedTuple):
    """Per-element data of a file, keyed by property name: `hestore.io.PolygonSoup`'s."""

    vertex: dict
    polygon: dict
    corner: dict


def _spec(kind: str, name: str, array: np.ndarray, source: str | None) -> Property:
    """The property a file's column becomes: integers as int64, floats as float64."""
    dtype = {"f": "float64", "i": "int64", "u": "int64", "b": "bool"}.get(array.dtype.kind)
    if dtype is None or array.ndim not in (1, 2):
        raise InvalidInputError(f"{source or 'input'}: {kind} data {name!r} is not a column of numbers")
    shape = () if array.ndim == 1 else (int(array.shape[1]),)
    try:
        kind, name, dtype, shape = values.check_spec(kind, name, dtype, shape)
    except InvalidInputError as exc:
        raise InvalidInputError(f"{source or 'input'}: {exc}") from None
    return Property(kind, name, dtype, shape, None)


def _file_properties(data: FileData, built, soup: Ragged, source: str | None) -> list[tuple]:
    """``(Property, ids, values)`` of every column of ``data``, for the elements the import keeps.

    Polygon values follow the kept polygons; corner values go to the
    half-edge leaving each kept corner, and a corner whose values are all NaN
    (no ``vt``/``vn`` reference) gets none.
    """
    out = []
    a = built.arrays
    for name, column in data.vertex.items():
        out.append((_spec("vertex", name, column, source), a.v_id, column))
    for name, column in data.polygon.items():
        out.append((_spec("polygon", name, column, source), a.p_id, column[built.accepted]))
    if data.corner:
        kept = np.zeros(len(soup.offsets) - 1, dtype=bool)
        kept[built.accepted] = True
        corner_kept = np.repeat(kept, np.diff(soup.offsets))
        halfedges = a.he_id[polygon_halfedges(a.he_id, a.he_next, a.p_halfedge).indices]
        for name, column in data.corner.items():
            column = column[corner_kept]
            valid = ~np.isnan(column.reshape(len(column), -1)).all(axis=1) if column.dtype.kind == "f" else None
            ids = halfedges if valid is None else halfedges[valid]
            out.append((_spec("halfedge", name, column, source), ids, column if valid is None else column[valid]))
    return out


def _built(
    pos, soup, options: ImportOptions, *, lines=None, source=None, index_base=0, data: FileData | None = None,
) -> BuiltImport:
    """Decide and build: every check an import makes, before anything is written."""
    progress = options.progress
    if progress is not None:
        progress("build", 0, 1)
    flipped: list = []
    cut: list = []
    split = options.on_error == "split"
    if options.orient:
        ok = _build.well_formed(len(pos), soup, allow_loops=options.allow_loops)
        turn = _build.orient(soup, cut=split, ok=ok)
        cut = turn.cut.tolist()
        if turn.conflict is not None:
            where = f"line {int(lines[turn.conflict])}, " if lines is not None else ""
            prefix = f"{source}: " if source else ""
            raise NonOrientableError(
                f"{prefix}polygon {turn.conflict} ({where}input order) is in a component that cannot be oriented "
                "consistently (a Möbius strip or the like); nothing was stored (on_error='split' would cut it "
                "along edges until it can be oriented)"
            )
        soup = Ragged(soup.offsets, soup.indices[turn.order])
        if data is not None and data.corner:
            data = data._replace(corner={k: v[turn.order] for k, v in data.corner.items()})
        flipped = np.flatnonzero(turn.flip).tolist()
    built = _build.build(len(pos), soup, allow_loops=options.allow_loops, index_base=index_base, split=split)
    copies: dict = {}
    if len(built.copied):
        pos = np.concatenate([pos, pos[built.copied]])
        if data is not None:
            data = data._replace(vertex={k: np.concatenate([v, v[built.copied]]) for k, v in data.vertex.items()})
        first = len(pos) - len(built.copied)
        for original, copy in sorted(zip(built.copied.tolist(), range(first, len(pos)))):
            copies.setdefault(original, []).append(copy)
    if progress is not None:
        progress("build", 1, 1)
    skipped = [
        SkippedPolygon(r.index, None if lines is None else int(lines[r.index]), r.reason) for r in built.refused
    ]
    if skipped and options.on_error == "raise":
        first, error = skipped[0], built.refused[0].error
        prefix = f"{source}: " if source else ""
        exc = error(f"{prefix}{first}; nothing was stored (on_error='skip' would leave it out)")
        exc.skipped = first
        raise exc
    columns = _file_properties(data, built, soup, source) if data is not None else []
    return BuiltImport(pos, built.arrays, columns, len(built.accepted), skipped, source, flipped, copies, cut)


#: The tables an import writes (their statistics are refreshed afterwards: `hestore.Store.import_arrays`).
WRITTEN = (schema.vertices, schema.halfedges, schema.edges, schema.polygons)


def write(ref: MeshRef, built: BuiltImport, progress: Progress | None = None) -> None:
    """Write a built import into the new, empty mesh ``ref``: its four tables and file data, set-based.

    One edit of the mesh's unit of work, whose flush writes the tables in
    large batches (`hestore._columns`); the caller's scope makes the creation
    of the mesh and this one step.
    """
    a, pos = built.arrays, built.positions
    tables = {
        "vertices": {"id": a.v_id, "halfedge": a.v_halfedge, "x": pos[:, 0], "y": pos[:, 1], "z": pos[:, 2]},
        "halfedges": {
            "id": a.he_id, "origin": a.he_origin, "next": a.he_next, "prev": a.he_prev,
            "twin": a.he_twin, "edge": a.he_edge, "polygon": a.he_polygon,
        },
        "edges": {"id": a.e_id, "halfedge": a.e_halfedge},
        "polygons": {"id": a.p_id, "halfedge": a.p_halfedge},
    }
    counters = (len(a.v_id), len(a.e_id), len(a.p_id))
    total = sum(len(columns["id"]) for columns in tables.values())
    report = None
    if progress is not None:
        report = lambda done, _total: progress("write", done, total)  # noqa: E731
    with ref.session.editing(ref) as uow:
        uow.insert_bulk(BulkRows(tables, report), counters)
        for spec, ids, data in built.columns:
            prop = uow.values.add_property(spec)
            uow.values.stage(BulkValues(prop, ids, values.columns_of(prop, ids, data), None, replace_all=True))
    if progress is not None:
        progress("write", total, total)


def build_file(path: str, options: ImportOptions) -> BuiltImport:
    """Read an OFF, OBJ or PLY file (ASCII or binary) and decide and build its import (`hestore.Store.import_file`).

    The file's vertex and polygon order are kept, vertices are never welded
    by position and polygons are never triangulated; see `build_arrays` for
    what is built and how bad polygons are handled (each `SkippedPolygon`
    carries its file line for ASCII files). Its vertex and polygon
    properties (PLY) and corner ``uv``/``normal`` (OBJ) come along as the
    new mesh's properties.

    Raises
    ------
    InvalidInputError
        The file is malformed (bad header, non-numeric or non-finite values,
        truncated): the message names the file and line. The file cannot be
        read (missing, a folder, no permission: ``"cannot read {path}:
        {reason}"``), or the path cannot be one.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "tri.off"
    >>> _ = path.write_text("OFF\\n3 1 0\\n0 0 0\\n1 0 0\\n0 1 0\\n3 0 1 2\\n")
    >>> build_file(str(path), ImportOptions()).polygons
    1
    """
    path = check_path(path)
    kind = mesh_io.format_of(path)
    progress = options.progress
    read_progress = None
    if progress is not None:
        read_progress = lambda done, total: progress("read", done, total)  # noqa: E731
    soup = mesh_io.read(path, progress=read_progress)
    return _built(
        soup.positions,
        Ragged(soup.offsets, soup.indices),
        options,
        lines=soup.lines,
        source=path,
        index_base=1 if kind == "obj" else 0,  # OBJ counts vertices from 1; say so in messages
        data=FileData(soup.vertex_properties, soup.polygon_properties, soup.corner_properties),
    )


def _soup(ref: MeshRef) -> tuple[np.ndarray, Ragged, np.ndarray, np.ndarray]:
    """Positions, polygon loops (as rows), vertex ids and each corner's half-edge id, read in one snapshot.

    A block's own edits are included.
    """
    with ref.session.snapshot(ref) as snap:
        (v_id, vx, vy, vz, v_missing), (h_id, h_origin, h_next), (_p_id, p_he) = snap.columns(
            [position_request(), request("halfedges", "origin", "next"), request("polygons", "halfedge")]
        )
    loops = polygon_halfedges(h_id, h_next, p_he)
    corners = Ragged(loops.offsets, Index(v_id).find(h_origin[loops.indices])[0])
    return position_array(vx, vy, vz, v_missing), corners, v_id, h_id[loops.indices]


def dual(ref: MeshRef) -> tuple[np.ndarray, Ragged]:
    """The dual of a closed mesh as a polygon soup: ``(positions, polygons)``, what `Mesh.dual` stores.

    The dual has a vertex at the centroid of each polygon (in polygon id
    order) and a polygon for each fan of polygons around a vertex, its
    corners the fan's polygons counter-clockwise (so it faces the way the
    mesh does); a pinched vertex gives one polygon per fan. Each edge of the
    mesh becomes the dual edge between the polygons on its two sides.
    Everything is computed set-based on the mesh's arrays, read in one
    snapshot; `Mesh.dual` stores it like an import (one transaction).

    Raises
    ------
    TopologyError
        The mesh has a free half-edge (a boundary or a wire edge): only a
        closed mesh has a dual here.
    InvalidInputError
        A polygon's corner has no position.

    Examples
    --------
    >>> from hestore._session import identity
    >>> import hestore
    >>> store = hestore.open("sqlite://")
    >>> tetra = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)]
    >>> mesh = store.import_arrays("tetra", tetra, [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]).mesh
    >>> positions, polygons = dual(identity(mesh))
    >>> positions.shape, polygons.offsets.tolist()
    ((4, 3), [0, 3, 6, 9, 12])
    """
    with ref.session.snapshot(ref) as snap:
        (v_id, vx, vy, vz, v_missing), (h_id, h_origin, h_prev, h_twin, h_polygon), (p_id,) = snap.columns(
            [position_request(), request("halfedges", "origin", "prev", "twin", "polygon"), request("polygons")]
        )
    free = np.flatnonzero(h_polygon < 0)
    if len(free):
        first = int(h_id[free[0]])
        raise TopologyError(
            f"mesh {ref.name!r} is not closed ({len(free)} free half-edges, e.g. {first}): only a closed mesh "
            f"has a dual",
            (("halfedge", first),),
        )
    positions = position_array(vx, vy, vz, v_missing)
    # Rows of references, each of which exists on a valid mesh (`check` reports any other).
    corner_vertex = Index(v_id).find(h_origin)[0]
    if np.isnan(positions[corner_vertex]).any():
        raise InvalidInputError(f"mesh {ref.name!r} has polygon corners without a position: the dual needs them")
    # Dual vertices: polygon centroids (a polygon's corners are its half-edges' origins).
    poly = Index(p_id).find(h_polygon)[0]
    degree = np.bincount(poly, minlength=len(p_id))
    centroids = np.stack(
        [np.bincount(poly, weights=positions[corner_vertex, k], minlength=len(p_id)) / degree for k in range(3)], axis=1
    )
    # Dual polygons: the cycles of onext(h) = twin(prev(h)), counter-clockwise around each origin.
    halfedges = Index(h_id)
    onext = halfedges.find(h_twin[halfedges.find(h_prev)[0]])[0]
    label, _on_cycle, _end = cycles(onext)
    step = cycle_positions(onext, label)
    order = np.lexsort((step, label, h_origin[label]))
    starts = np.flatnonzero(np.r_[True, label[order][1:] != label[order][:-1]])
    soup = Ragged(np.r_[starts, len(order)].astype(np.int64), poly[order].astype(np.int64))
    return centroids, soup


def to_arrays(ref: MeshRef) -> MeshArrays:
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
    positions, soup, vertex_ids, _ = _soup(ref)
    counts = np.diff(soup.offsets)
    if len(counts) and (counts == counts[0]).all():
        polygons = soup.indices.reshape(len(counts), int(counts[0]))
    elif not len(counts):
        polygons = np.zeros((0, 3), dtype=np.int64)
    else:
        polygons = [soup.indices[a:b].tolist() for a, b in zip(soup.offsets[:-1].tolist(), soup.offsets[1:].tolist())]
    return MeshArrays(positions, polygons, vertex_ids)


def export(ref: MeshRef, path, *, binary: bool = True, progress: Progress | None = None) -> None:
    """Write the mesh's vertices and polygons to an OFF, OBJ or PLY file.

    The format comes from the extension; ``binary`` applies to PLY (binary
    little endian, else ASCII). Vertices are written in id order and
    polygons as `to_arrays` gives them, so importing the file again gives a
    mesh with the same counts and topology. Wire edges are not written.

    Raises
    ------
    InvalidInputError
        A vertex has no position, the extension is not a known format, the
        path cannot be one, or the file cannot be written (``"cannot write
        {path}: {reason}"``).

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
    path = check_path(path)
    mesh_io.format_of(path)
    binary = values.check_flag(binary, "binary")
    check_progress(progress)
    if progress is not None:
        progress("read", 0, 1)
    with ref.session.snapshot(ref):  # one state for the topology and every property read
        positions, soup, vertex_ids, corner_halfedges = _soup(ref)
        data = _export_data(ref, mesh_io.format_of(path), corner_halfedges)
    if progress is not None:
        progress("read", 1, 1)
    unplaced = np.isnan(positions).any(axis=1)
    if unplaced.any():
        ids = vertex_ids[unplaced][:5].tolist()
        raise InvalidInputError(
            f"cannot export {ref.name!r}: {int(unplaced.sum())} vertices have no position (ids {ids}...)"
        )
    write_progress = None
    if progress is not None:
        write_progress = lambda done, total: progress("write", done, total)  # noqa: E731
    mesh_io.write(
        path, positions, soup.offsets, soup.indices, binary=binary, progress=write_progress,
        vertex_properties=data.vertex, polygon_properties=data.polygon, corner_properties=data.corner,
    )


def _filled(array: np.ndarray) -> np.ndarray:
    """A property array for a file: unset entries (masked) as NaN, or 0 for integers and booleans."""
    if not isinstance(array, np.ma.MaskedArray):
        return np.asarray(array)
    return array.filled(np.nan if array.dtype.kind == "f" else 0)


def _export_data(ref: MeshRef, fmt: str, corner_halfedges: np.ndarray) -> FileData:
    """The properties a format can hold: PLY vertex and polygon numbers, OBJ corner ``uv`` and ``normal``."""
    data = FileData({}, {}, {})
    if fmt == "ply":
        for kind, out in (("vertex", data.vertex), ("polygon", data.polygon)):
            for name, prop in props.properties(ref, kind).items():
                if prop.dtype != "str":
                    out[name] = _filled(props.property_array(ref, kind, name)[1])
    elif fmt == "obj":
        found = props.properties(ref, "halfedge")
        for name, width in (("uv", 2), ("normal", 3)):
            prop = found.get(name)
            if prop is None or prop.dtype != "float64" or prop.shape != (width,):
                continue
            ids, array = props.property_array(ref, "halfedge", name)
            at = Index(ids).find(corner_halfedges)[0]
            data.corner[name] = _filled(array)[at] if len(ids) else np.full((0, width), np.nan)
    return data
