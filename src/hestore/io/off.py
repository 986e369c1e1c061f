"""OFF (Object File Format): reading and writing.

What the reader accepts: the keyword ``OFF``, optionally prefixed ``ST``,
``C``, ``N`` and ``n`` (``nOFF`` gives the dimension, 2 or 3, on the next
token), then the vertex, face and (ignored) edge counts, on the keyword's line
or the next. ``#`` starts a comment anywhere, before the keyword too; blank
lines are skipped. A file of nothing but comments and blank lines is refused
as empty; ``OFF`` with counts of 0 is an empty mesh. One vertex or face per
line: values after x, y, z (colours, normals, texture coordinates) and after
a face's indices (colours) are ignored, as is anything after the last face.
Binary OFF and homogeneous ``4OFF`` are refused. The counts are at most
2**63 - 1, and every vertex and face takes a line, so they must fit in the
bytes after the header. The soup's property dicts stay empty: OFF colours and
normals are not kept.

The writer writes ``OFF``, the counts with an edge count of 0, one vertex per
line (x y z) and one polygon per line (its vertex count, then its indices).
"""

from __future__ import annotations

import os
import re

from hestore.io.common import (
    TEXT_RECORD_BYTES,
    Faces,
    Polygons,
    PolygonSoup,
    Positions,
    Progress,
    RowProgress,
    TextFile,
    check_room,
    checked_arrays,
    count,
    created,
    empty,
    error,
    integer,
    read_file,
    read_sections,
    show,
    write_text_rows,
)

__all__ = ["read_off", "write_off"]

_KEYWORD = re.compile(rb"(ST)?(C)?(N)?(4)?(n)?OFF")


def read_off(path: str | os.PathLike, *, progress: Progress | None = None) -> PolygonSoup:
    """Read an OFF file as it is stored, whatever its extension.

    Parameters
    ----------
    path : str or path-like
        The file.
    progress : callable, optional
        Called as ``progress(done_bytes, total_bytes)`` now and then, and at
        least once at the end with ``done_bytes == total_bytes``.

    Returns
    -------
    PolygonSoup
        Positions and polygons in the file's order, with the line of each
        polygon.

    Raises
    ------
    InvalidInputError
        A malformed file; the message is ``"{path}:{line}: {what}"``.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> folder = tempfile.TemporaryDirectory()
    >>> path = pathlib.Path(folder.name) / "triangle.off"
    >>> text = "COFF\\n# a coloured triangle\\n3 1 0\\n0 0 0 255 0 0\\n1 0 0 0 255 0\\n0 1 0 0 0 255\\n3 0 1 2\\n"
    >>> _ = path.write_text(text)
    >>> soup = read_off(path)
    >>> soup.positions.tolist(), soup.indices, soup.lines
    ([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], array([0, 1, 2]), array([7]))
    >>> _ = path.write_text("OFF\\n3 1 0\\n0 0 0\\n1 0 0\\n")
    >>> read_off(path)
    Traceback (most recent call last):
    ...
    hestore.errors.InvalidInputError: .../triangle.off:4: file ends after 2 of 3 vertices
    >>> folder.cleanup()
    """
    return read_file(path, progress, lambda f, name, size, progress: _read(TextFile(f, name, size, progress)))


def write_off(path: str | os.PathLike, positions, offsets, indices, *, progress: Progress | None = None) -> None:
    """Write vertex positions and polygons as an OFF file.

    Positions are written in their shortest round-trip form, so reading the
    file back gives exactly the same arrays.

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
    progress : callable, optional
        Called as ``progress(done, total)`` now and then, counting vertices
        and polygons written, and at least once at the end.

    Raises
    ------
    InvalidInputError
        Arrays that do not describe polygons on these vertices. Nothing is
        written then.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> folder = tempfile.TemporaryDirectory()
    >>> path = pathlib.Path(folder.name) / "triangle.off"
    >>> write_off(path, [(0, 0, 0), (1, 0, 0), (0, 1, 0.5)], [0, 3], [0, 1, 2])
    >>> print(path.read_text(), end="")
    OFF
    3 1 0
    0.0 0.0 0.0
    1.0 0.0 0.0
    0.0 1.0 0.5
    3 0 1 2
    >>> folder.cleanup()
    """
    positions, offsets, indices = checked_arrays(positions, offsets, indices)
    report = RowProgress(progress, positions, offsets)
    with created(path) as f:
        f.write(f"OFF\n{len(positions)} {len(offsets) - 1} 0\n".encode())
        write_text_rows(f, positions, offsets, indices, "", None, 0, report)
    report.finish()


def _read(src: TextFile) -> PolygonSoup:
    path = src.path
    first = src.content_line(comments=True)
    if first is None:
        raise empty(path, src.last_line, "the OFF keyword")
    tokens, line = first
    keyword = _KEYWORD.fullmatch(tokens[0])
    if keyword is None:
        raise error(path, line, f"expected the OFF keyword, found {show(tokens[0])}")
    if keyword[4]:
        raise error(path, line, "homogeneous coordinates (4OFF) are not supported")
    rest = tokens[1:]
    if rest and rest[0].upper() == b"BINARY":
        raise error(path, line, "binary OFF is not supported")

    def more() -> tuple[list[bytes], int]:
        nxt = src.content_line(comments=True)
        if nxt is None:
            raise error(path, src.last_line, "file ends inside the OFF header")
        return nxt

    if keyword[5]:
        if not rest:
            rest, line = more()
        dimension = integer(rest[0], path, line, "dimension")
        if dimension not in (2, 3):
            raise error(path, line, f"only 2- and 3-dimensional nOFF is supported, found {show(rest[0])}")
        rest = rest[1:]
    if not rest:
        rest, line = more()
    if len(rest) not in (2, 3):
        raise error(path, line, f"expected the vertex, face and edge counts, found {show(b' '.join(rest))}")
    nv, nf, *_ = (count(t, path, line, "count") for t in rest)
    # Every vertex and face takes a line of its own after the header.
    room = src.size - src.f.tell()
    check_room(path, line, nv, "vertices", room, TEXT_RECORD_BYTES, slack=1)
    room -= nv * TEXT_RECORD_BYTES
    check_room(path, line, nf, "faces after the vertices", room, TEXT_RECORD_BYTES, slack=1)

    polygons = Polygons()
    vertices = Positions(nv)
    read_sections(src, [vertices, Faces(nf, polygons)], comments=True)
    return polygons.soup(vertices.parts)
