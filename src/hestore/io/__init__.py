"""Polygon mesh files: reading and writing OFF, OBJ and PLY.

This package owns the file formats and nothing else. `read` turns a file into
a `PolygonSoup` — vertex positions and polygons exactly as the file gives
them — and `write` turns arrays back into a file. It knows no half-edges and
no database: whether the polygons form a mesh, and whether their indices are
in range, is for the builder to decide. That is why indices are passed
through unchecked, and why every polygon of a text file keeps the line it
came from: the builder names that line when it rejects the polygon.

"Exactly as the file gives them" means:

* vertices and polygons keep the file's order;
* vertices are never welded by position, even where two share a position;
* polygons stay polygons (no triangulation), whatever their number of
  vertices, and degenerate ones (repeated or out-of-range indices, fewer than
  three vertices) are kept for the builder to judge;
* positions are float64; a 2-D position (no z) gets z = 0.

Beyond positions and polygons, each format keeps some per-element data, as
the property dicts of `PolygonSoup` (arrays by name, float64 or int64):

========  ======================================  ====================================
format    read                                    written by `write`
========  ======================================  ====================================
PLY       every scalar vertex property but x, y,  ``vertex_properties`` and
          z (``vertex_properties``) and every     ``polygon_properties``; an (n, k)
          scalar face property but the index      array as k properties
          list (``polygon_properties``)           ``{name}_0`` .. ``{name}_{k-1}``
OBJ       ``vt`` and ``vn`` referred to by faces  ``corner_properties["uv"]`` and
          (``corner_properties["uv"]`` and        ``["normal"]``
          ``["normal"]``)
OFF       nothing (colours are skipped)           nothing
========  ======================================  ====================================

`write` passes each format what it can hold and ignores the rest. Texture
coordinates and normals are per corner (one row per entry of
`PolygonSoup.indices`, NaN where a corner has none), as OBJ refers to them.

The modules:

`hestore.io.off`, `hestore.io.obj`, `hestore.io.ply`
    One per format, each with its reader and writer (``read_off``,
    ``write_off``, ...) and the description of what it accepts.
`hestore.io.common`
    What they share: `PolygonSoup`, errors, chunked text reading, the
    sections of OFF and ASCII PLY, the writers' argument checks.

This module picks the format by the file's extension (`format_of`).

Large files are read in chunks of whole lines, each parsed with numpy (the
per-line Python reader only runs on a chunk that the vectorised one cannot
take, and it is the one that finds and names a malformed line). Binary PLY
elements whose lists all have the same length are read as one structured
array.

A malformed file raises `~hestore.errors.InvalidInputError` with the message
``"{path}:{line}: {what}"`` — for binary PLY data ``"{path}:byte {offset}:
{what}"`` — and `read` returns nothing partial. So does a path that cannot
be one (not a str, bytes or path object, a NUL character:
`hestore.urls.check_path`) and a file the system refuses — missing, a
folder, no permission, a full disk — as ``"cannot read {path}: {reason}"``
(``"cannot write …"``), the `OSError` chained (`file_errors`, which every
module that touches a file uses). A malformed file makes a
reader raise nothing else, and header counts are never trusted: each is
checked against what the rest of the file can hold before anything is
allocated for it, so memory and time stay within a small multiple of the
file's size. What a message quotes of the file is escaped to printable
ASCII and cut short (`hestore.io.common.show`). Every format refuses an
empty file — no bytes, or only whitespace and comments — and reads one that
declares zero vertices and faces as an empty soup.

Examples
--------
>>> import pathlib, tempfile
>>> from hestore import io as mesh_io
>>> folder = tempfile.TemporaryDirectory()
>>> path = pathlib.Path(folder.name) / "pyramid.off"
>>> positions = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0.5, 0.5, 1)]
>>> offsets, indices = [0, 4, 7, 10, 13, 16], [3, 2, 1, 0, 0, 1, 4, 1, 2, 4, 2, 3, 4, 3, 0, 4]
>>> mesh_io.write(path, positions, offsets, indices)
>>> soup = mesh_io.read(path)
>>> soup
PolygonSoup(vertices=5, polygons=5)
>>> soup.indices[soup.offsets[0]:soup.offsets[1]]
array([3, 2, 1, 0])
>>> folder.cleanup()
"""

from __future__ import annotations

import os
from collections.abc import Mapping

from hestore.errors import InvalidInputError
from hestore.io.common import PolygonSoup, Progress, file_errors
from hestore.io.obj import read_obj, write_obj
from hestore.io.off import read_off, write_off
from hestore.io.ply import read_ply, write_ply
from hestore.urls import check_path

__all__ = ["FORMATS", "PolygonSoup", "file_errors", "format_of", "read", "write"]

FORMATS = ("off", "obj", "ply")
"""The supported formats, named by their file extensions."""

_READERS = {"off": read_off, "obj": read_obj, "ply": read_ply}


def format_of(path: str | os.PathLike) -> str:
    """The format of a mesh file, from its extension.

    Parameters
    ----------
    path : str or path-like
        The file name; the file itself is not opened.

    Returns
    -------
    str
        One of `FORMATS`.

    Raises
    ------
    InvalidInputError
        The extension is not one of `FORMATS` (case does not matter), or
        ``path`` cannot be a path (`hestore.urls.check_path`).

    Examples
    --------
    >>> format_of("bunny.OBJ")
    'obj'
    >>> format_of("bunny.xyz")
    Traceback (most recent call last):
    ...
    hestore.errors.InvalidInputError: bunny.xyz: unsupported file format '.xyz'; supported: .off, .obj, .ply (and ...)
    """
    name = check_path(path)
    ext = os.path.splitext(name)[1]
    fmt = ext[1:].lower()
    if fmt not in FORMATS:
        supported = ", ".join("." + f for f in FORMATS)
        shown = repr(ext) if ext else "(no extension)"
        raise InvalidInputError(
            f"{name}: unsupported file format {shown}; supported: {supported} (and .stl, .vtk, .vtu through meshio)"
        )
    return fmt


def read(path: str | os.PathLike, *, progress: Progress | None = None) -> PolygonSoup:
    """Read an OFF, OBJ or PLY file (chosen by extension) as it is stored.

    Parameters
    ----------
    path : str or path-like
        The file; its extension picks the format (see `format_of`).
    progress : callable, optional
        Called as ``progress(done_bytes, total_bytes)`` now and then while
        reading, and at least once at the end with ``done_bytes ==
        total_bytes``.

    Returns
    -------
    PolygonSoup
        Positions and polygons in the file's order, unwelded, untriangulated.

    Raises
    ------
    InvalidInputError
        Unsupported extension, or a malformed file; the message is
        ``"{path}:{line}: {what}"`` (``"{path}:byte {offset}: {what}"`` in
        binary PLY data). A path that cannot be one, or a file that cannot
        be opened or read: ``"cannot read {path}: {reason}"``.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> folder = tempfile.TemporaryDirectory()
    >>> path = pathlib.Path(folder.name) / "square.obj"
    >>> text = "# a unit square\\nv 0 0 0\\nv 1 0 0\\nv 1 1 0\\nv 0 1 0\\nvn 0 0 1\\nf 1//1 2//1 -2//1 -1//1\\n"
    >>> _ = path.write_text(text)
    >>> soup = read(path)
    >>> soup.positions.shape, soup.offsets, soup.indices, soup.lines
    ((4, 3), array([0, 4]), array([0, 1, 2, 3]), array([7]))
    >>> _ = path.write_text("v 0 0 0\\nv 1 0 zero\\n")
    >>> read(path)
    Traceback (most recent call last):
    ...
    hestore.errors.InvalidInputError: .../square.obj:2: expected a number, found 'zero'
    >>> folder.cleanup()
    """
    return _READERS[format_of(path)](path, progress=progress)


def write(
    path: str | os.PathLike,
    positions,
    offsets,
    indices,
    *,
    binary: bool = True,
    progress: Progress | None = None,
    vertex_properties: Mapping | None = None,
    polygon_properties: Mapping | None = None,
    corner_properties: Mapping | None = None,
) -> None:
    """Write vertex positions, polygons and the per-element data the format holds as an OFF, OBJ or PLY file.

    The format comes from the extension. OFF and OBJ are text; PLY is
    binary little endian unless ``binary=False``. Positions (and float
    properties) are written as doubles — in text, in their shortest
    round-trip form — so reading the file back gives exactly the same
    arrays. PLY keeps the vertex and polygon properties, OBJ the corner
    properties ``"uv"`` and ``"normal"``, OFF none; the rest are ignored.

    Parameters
    ----------
    path : str or path-like
        The file to create (or overwrite).
    positions : array_like of float, shape (V, 3)
        Vertex positions, all finite.
    offsets : array_like of int, shape (F + 1,)
        ``offsets[0] == 0``, increasing: polygon ``i`` is
        ``indices[offsets[i]:offsets[i + 1]]`` and has at least one vertex.
    indices : array_like of int
        Zero-based vertex indices, each in ``range(V)``.
    binary : bool, default True
        PLY only: binary little endian, or ASCII with ``binary=False``.
    progress : callable, optional
        Called as ``progress(done, total)`` now and then, counting vertices
        and polygons written, and at least once at the end.
    vertex_properties, polygon_properties : mapping of str to array_like, optional
        PLY only: per-vertex (per-polygon) data, arrays of shape ``(V,)`` or
        ``(V, k)`` (``(F,)`` or ``(F, k)``); see `hestore.io.ply.write_ply`.
    corner_properties : mapping of str to array_like, optional
        OBJ only: ``"uv"`` of shape ``(len(indices), 2)`` and ``"normal"`` of
        shape ``(len(indices), 3)``, NaN rows for corners without; see
        `hestore.io.obj.write_obj`.

    Raises
    ------
    InvalidInputError
        Unsupported extension, arrays that do not describe polygons on
        these vertices, or properties the format would hold but that are
        malformed: nothing is written then. A path that cannot be one, or a
        file that cannot be written: ``"cannot write {path}: {reason}"``.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> folder = tempfile.TemporaryDirectory()
    >>> path = pathlib.Path(folder.name) / "square.obj"
    >>> write(path, [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0.1)], [0, 4], [0, 1, 2, 3])
    >>> print(path.read_text(), end="")
    v 0.0 0.0 0.0
    v 1.0 0.0 0.0
    v 1.0 1.0 0.0
    v 0.0 1.0 0.1
    f 1 2 3 4
    >>> ply = path.with_suffix(".ply")
    >>> write(ply, [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [0, 3], [0, 1, 2], vertex_properties={"red": [255, 0, 0]})
    >>> read(ply).vertex_properties
    {'red': array([255,   0,   0])}
    >>> write(path.with_suffix(".ply"), [(0, 0, 0)], [0, 1], [1])
    Traceback (most recent call last):
    ...
    hestore.errors.InvalidInputError: polygon 0 has vertex index 1, out of range for 1 vertices
    >>> folder.cleanup()
    """
    fmt = format_of(path)
    if fmt == "ply":
        write_ply(
            path,
            positions,
            offsets,
            indices,
            binary=binary,
            progress=progress,
            vertex_properties=vertex_properties,
            polygon_properties=polygon_properties,
        )
    elif fmt == "obj":
        write_obj(path, positions, offsets, indices, progress=progress, corner_properties=corner_properties)
    else:
        write_off(path, positions, offsets, indices, progress=progress)
