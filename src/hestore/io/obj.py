"""Wavefront OBJ: reading and writing the geometry of polygon meshes.

What the reader accepts: ``v x y [z [w]]`` and ``f`` with the vertex
references ``v``, ``v/vt``, ``v//vn`` and ``v/vt/vn``; only the position
index counts. Negative indices count back from the vertices defined so far;
index 0 (invalid in OBJ) becomes -1 so that the builder rejects it as out of
range. ``#`` starts a comment. Every other statement is skipped — ``vt``,
``vn``, ``g``, ``o``, ``s``, ``usemtl``, ``mtllib`` and also ``l``
(polylines) and ``p`` (points), which are not polygons. Line continuations (a
trailing ``\\``) on ``v`` and ``f`` lines are refused.

The writer writes ``v x y z`` lines, then ``f`` lines with 1-based indices.
"""

from __future__ import annotations

import os

import numpy as np

from hestore.io import common
from hestore.io.common import (
    SLASH,
    SPACE,
    WS,
    Chunk,
    Polygons,
    PolygonSoup,
    Progress,
    RowProgress,
    TextFile,
    checked_arrays,
    coordinate,
    error,
    first3,
    integer,
    read_file,
    token_starts,
    write_text_rows,
)

__all__ = ["read_obj", "write_obj"]


def read_obj(path: str | os.PathLike, *, progress: Progress | None = None) -> PolygonSoup:
    """Read the vertices and faces of an OBJ file as they are stored, whatever its extension.

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
    OSError
        The file cannot be opened or read.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> folder = tempfile.TemporaryDirectory()
    >>> path = pathlib.Path(folder.name) / "square.obj"
    >>> text = "# a unit square\\nv 0 0 0\\nv 1 0 0\\nv 1 1 0\\nv 0 1 0\\nvn 0 0 1\\nf 1//1 2//1 -2//1 -1//1\\n"
    >>> _ = path.write_text(text)
    >>> soup = read_obj(path)
    >>> soup.positions.shape, soup.offsets, soup.indices, soup.lines
    ((4, 3), array([0, 4]), array([0, 1, 2, 3]), array([7]))
    >>> _ = path.write_text("v 0 0 0\\nv 1 0 zero\\n")
    >>> read_obj(path)
    Traceback (most recent call last):
    ...
    hestore.errors.InvalidInputError: .../square.obj:2: expected a number, found 'zero'
    >>> folder.cleanup()
    """
    return read_file(path, progress, lambda f, name, size, progress: _read(TextFile(f, name, size, progress)))


def write_obj(path: str | os.PathLike, positions, offsets, indices, *, progress: Progress | None = None) -> None:
    """Write vertex positions and polygons as an OBJ file.

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
    >>> path = pathlib.Path(folder.name) / "square.obj"
    >>> write_obj(path, [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0.1)], [0, 4], [0, 1, 2, 3])
    >>> print(path.read_text(), end="")
    v 0.0 0.0 0.0
    v 1.0 0.0 0.0
    v 1.0 1.0 0.0
    v 0.0 1.0 0.1
    f 1 2 3 4
    >>> folder.cleanup()
    """
    positions, offsets, indices = checked_arrays(positions, offsets, indices)
    report = RowProgress(progress, positions, offsets)
    with open(path, "wb") as f:
        write_text_rows(f, positions, offsets, indices, "v ", "f", 1, report)
    report.finish()


def _read(src: TextFile) -> PolygonSoup:
    positions: list[np.ndarray] = []
    polygons = Polygons()
    defined = 0  # vertices so far, the base of negative indices
    for chunk in src.chunks():
        found = _chunk_fast(chunk, defined)
        if found is None:
            found = _chunk_slow(chunk, defined, src.path)
        xyz, counts, indices, lines = found
        positions.append(xyz)
        polygons.add(counts, indices, lines)
        defined += len(xyz)
    return polygons.soup(positions)


def _resolve(raw: np.ndarray, before: np.ndarray) -> np.ndarray:
    """1-based and negative (relative to ``before`` vertices) indices to 0-based; 0 to -1."""
    if (raw > 0).all():
        return raw - 1
    return np.where(raw > 0, raw - 1, np.where(raw < 0, before + raw, -1))


def _chunk_fast(chunk: Chunk, defined: int):
    if b"#" in chunk.data:
        chunk.strip_comments()
    chunk.tokenize()
    buf = chunk.buf
    has = chunk.ntokens > 0
    if not has.any():
        return np.empty((0, 3)), np.empty(0, np.int64), np.empty(0, np.int64), np.empty(0, np.int64)
    lead = chunk.tokens[np.minimum(chunk.first, len(chunk.tokens) - 1)]
    keyword = buf[lead]
    single = WS[buf[lead + 1]]  # a one-letter keyword (the chunk ends in a newline)
    is_v = has & single & (keyword == ord("v"))
    is_f = has & single & (keyword == ord("f"))
    vlines, flines = np.flatnonzero(is_v), np.flatnonzero(is_f)
    if b"\\" in chunk.data:
        line = np.searchsorted(chunk.ends, np.flatnonzero(buf == ord("\\")))
        if (is_v[line] | is_f[line]).any():
            return None  # a continuation: the per-line reader refuses it with the line number

    if len(vlines):
        buf[lead[vlines]] = SPACE
        counts = chunk.ntokens[vlines] - 1
        values = common.parse(chunk.text(vlines), int(counts.sum()), np.float64)
        xyz = None if values is None else first3(values, counts)
        if xyz is None or not np.isfinite(xyz).all():
            return None
    else:
        xyz = np.empty((0, 3))

    if len(flines):
        buf[lead[flines]] = SPACE
        counts = chunk.ntokens[flines] - 1
        raw = _face_indices(chunk.text(flines), int(counts.sum()))
        if raw is None:
            return None
        before = 0
        if (raw <= 0).any():
            before = np.repeat(defined + np.searchsorted(vlines, flines), counts)
        indices = _resolve(raw, before)
    else:
        counts = indices = np.empty(0, np.int64)
    return xyz, counts, indices, chunk.line0 + flines


def _face_indices(text: np.ndarray, total: int) -> np.ndarray | None:
    """The position index of every vertex reference (``v``, ``v/vt``, ``v//vn``, ``v/vt/vn``)."""
    if not (text == SLASH).any():
        return common.parse(text, total, np.int64)
    references = token_starts(text)
    text = text.copy()
    text[text == SLASH] = SPACE
    numbers = token_starts(text)
    values = common.parse(text, len(numbers), np.int64)
    if values is None or len(references) != total:
        return None
    # A reference's position index is the number that starts where it does;
    # a reference that starts with '/' has none.
    at = np.searchsorted(numbers, references)
    if (at >= len(numbers)).any() or (numbers[at] != references).any():
        return None
    return values[at]


def _chunk_slow(chunk: Chunk, defined: int, path: str):
    xyz, counts, indices, lines = [], [], [], []
    everything = np.arange(len(chunk.ends))
    for line, tokens in chunk.line_tokens(everything, comments=True):
        if not tokens or tokens[0] not in (b"v", b"f"):
            continue
        if tokens[-1].endswith(b"\\"):
            raise error(path, line, "line continuations ('\\') are not supported")
        if tokens[0] == b"v":
            if len(tokens) < 3:
                raise error(path, line, f"a vertex needs at least 2 coordinates, found {len(tokens) - 1}")
            coords = [coordinate(t, path, line) for t in tokens[1:4]]
            xyz.append(tuple(coords) if len(coords) == 3 else (*coords, 0.0))
            continue
        before = defined + len(xyz)
        for token in tokens[1:]:
            i = integer(token.split(b"/", 1)[0], path, line, "vertex index")
            indices.append(i - 1 if i > 0 else before + i if i < 0 else -1)
        counts.append(len(tokens) - 1)
        lines.append(line)
    return np.array(xyz, dtype=np.float64).reshape(-1, 3), counts, indices, lines

