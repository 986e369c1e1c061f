"""Wavefront OBJ: reading and writing the geometry of polygon meshes.

What the reader accepts: ``v x y [z [w]]``, ``vt u [v [w]]``, ``vn x y z``
and ``f`` with the vertex references ``v``, ``v/vt``, ``v//vn`` and
``v/vt/vn``. Negative indices count back from the vertices (texture
coordinates, normals) defined so far. A position index is passed through
unchecked: index 0 (invalid in OBJ) becomes -1 so that the builder rejects
it as out of range. A texture coordinate or normal index is checked here: 0,
one that counts back past the first ``vt`` (``vn``) line, or one beyond the
last in the file is refused with its line (positive ones may refer to lines
further on).

When some face refers to a ``vt``, `PolygonSoup.corner_properties` has
``"uv"``: one (u, v) row per corner, aligned with the indices, NaN for a
corner without one (a ``vt``'s w is dropped, a missing v is 0). Likewise
``"normal"``, (x, y, z) rows, for ``vn``. ``#`` starts a comment. Every
other statement is skipped — ``g``, ``o``, ``s``, ``usemtl``, ``mtllib``,
``vp`` and also ``l`` (polylines) and ``p`` (points), which are not
polygons. Line continuations (a trailing ``\\``) on ``v``, ``vt``, ``vn``
and ``f`` lines are refused.

OBJ has no header, so the reader asks of a file that some line be an OBJ
statement: text (UTF-8, no control bytes) whose first word is one of the
format's statements (`_STATEMENTS`; unknown ones are skipped, but do not make
a file OBJ). A file with none is refused: as empty when it holds nothing but
whitespace and comments, as binary data when a NUL byte comes before the
first statement, and as not OBJ otherwise (base64, prose). A file of
statements without a vertex (``mtllib``, ``o``) is an empty mesh.

The writer writes ``v x y z`` lines, then ``f`` lines with 1-based indices
(an empty mesh: the lone statement ``g``).
Given per-corner ``"uv"`` or ``"normal"`` arrays, it also writes their
distinct rows as ``vt`` and ``vn`` lines (in order of first use) and refers
to them corner by corner (``v/vt``, ``v//vn`` or ``v/vt/vn``; a corner whose
row is NaN gets no reference). Numbers are written in their shortest
round-trip form, so reading the file back gives exactly the same arrays.
"""

from __future__ import annotations

import os
import re
from collections.abc import Mapping
from dataclasses import replace

import numpy as np

from hestore.errors import InvalidInputError
from hestore.io import common
from hestore.io.common import (
    SLASH,
    SPACE,
    WRITE_ROWS,
    WS,
    Chunk,
    Polygons,
    PolygonSoup,
    Progress,
    RowProgress,
    TextFile,
    checked_arrays,
    coordinate,
    created,
    empty,
    error,
    first3,
    integer,
    joined,
    read_file,
    show,
    token_starts,
    write_number_rows,
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
        polygon; the texture coordinates and normals that faces refer to as
        its corner properties ``"uv"`` and ``"normal"``.

    Raises
    ------
    InvalidInputError
        A malformed file, or a texture coordinate or normal index out of
        range; the message is ``"{path}:{line}: {what}"``.

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
    >>> soup
    PolygonSoup(vertices=4, polygons=1, corner properties: normal)
    >>> soup.corner_properties["normal"]
    array([[0., 0., 1.],
           [0., 0., 1.],
           [0., 0., 1.],
           [0., 0., 1.]])
    >>> _ = path.write_text("v 0 0 0\\nv 1 0 zero\\n")
    >>> read_obj(path)
    Traceback (most recent call last):
    ...
    hestore.errors.InvalidInputError: .../square.obj:2: expected a number, found 'zero'
    >>> _ = path.write_text("v 0 0 0\\nv 1 0 0\\nv 0 1 0\\nvt 0 0\\nf 1/1 2/1 3/2\\n")
    >>> read_obj(path)
    Traceback (most recent call last):
    ...
    hestore.errors.InvalidInputError: .../square.obj:5: texture coordinate index 2 is out of range for 1 vt lines
    >>> folder.cleanup()
    """
    return read_file(path, progress, lambda f, name, size, progress: _read(TextFile(f, name, size, progress)))


def write_obj(
    path: str | os.PathLike,
    positions,
    offsets,
    indices,
    *,
    progress: Progress | None = None,
    corner_properties: Mapping | None = None,
) -> None:
    """Write vertex positions and polygons, with texture coordinates and normals, as an OBJ file.

    Positions, texture coordinates and normals are written in their shortest
    round-trip form, so reading the file back gives exactly the same arrays.

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
    corner_properties : mapping of str to array_like, optional
        Per-corner data, aligned with ``indices``: ``"uv"`` of shape
        ``(len(indices), 2)`` is written as ``vt`` lines, ``"normal"`` of
        shape ``(len(indices), 3)`` as ``vn`` lines. A row of NaN is a
        corner without one. Other names are ignored: OBJ has no place for
        them.

    Raises
    ------
    InvalidInputError
        Arrays that do not describe polygons on these vertices, or a
        ``"uv"`` or ``"normal"`` array of the wrong shape or with a row
        neither finite nor all NaN. Nothing is written then.

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
    >>> nan = float("nan")
    >>> uv = [(0, 0), (1, 0), (1, 1), (nan, nan), (0, 0), (1, 1), (0, 0)]
    >>> normal = [(0, 0, 1)] * 3 + [(nan, nan, nan)] + [(0, 0, -1)] * 3
    >>> corners = {"uv": uv, "normal": normal}
    >>> write_obj(path, [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)], [0, 4, 7], [0, 1, 2, 3, 0, 2, 1],
    ...           corner_properties=corners)
    >>> print(path.read_text(), end="")
    v 0.0 0.0 0.0
    v 1.0 0.0 0.0
    v 1.0 1.0 0.0
    v 0.0 1.0 0.0
    vt 0.0 0.0
    vt 1.0 0.0
    vt 1.0 1.0
    vn 0.0 0.0 1.0
    vn 0.0 0.0 -1.0
    f 1/1/1 2/2/1 3/3/1 4
    f 1/1/2 3/3/2 2/1/2
    >>> read_obj(path).corner_properties["uv"][3]
    array([nan, nan])
    >>> folder.cleanup()
    """
    positions, offsets, indices = checked_arrays(positions, offsets, indices)
    uv, uv_refs = _distinct_rows(corner_properties, "uv", 2, len(indices))
    normals, normal_refs = _distinct_rows(corner_properties, "normal", 3, len(indices))
    report = RowProgress(progress, positions, offsets)
    with created(path) as f:
        if len(positions) == 0:
            # A file of no statement at all is refused as empty: an empty
            # mesh is the default group, which reads back as nothing.
            f.write(b"g\n")
        if uv_refs is None and normal_refs is None:
            write_text_rows(f, positions, offsets, indices, "v ", "f", 1, report)
        else:
            write_number_rows(f, positions, "v ", report)
            write_number_rows(f, uv, "vt ")
            write_number_rows(f, normals, "vn ")
            counts = np.diff(offsets)
            none = np.zeros(len(indices), np.int64)
            uv_refs = none if uv_refs is None else uv_refs
            normal_refs = none if normal_refs is None else normal_refs
            for lo in range(0, len(counts), WRITE_ROWS):
                hi = min(lo + WRITE_ROWS, len(counts))
                at = slice(offsets[lo], offsets[hi])
                f.write(_face_lines(counts[lo:hi], indices[at] + 1, uv_refs[at], normal_refs[at]).encode())
                report(len(positions) + hi)
    report.finish()


def _distinct_rows(named, name: str, width: int, n: int) -> tuple[np.ndarray, np.ndarray | None]:
    """The distinct rows of corner property ``name`` and every corner's 1-based row (0: none).

    Rows are distinct by their bits (0.0 and -0.0 differ), in order of first
    use. The references are None when no corner has a row.
    """
    empty = np.empty((0, width))
    if named is None:
        return empty, None
    if not isinstance(named, Mapping):
        raise InvalidInputError(f"corner properties must map names to arrays, not be a {type(named).__name__}")
    if name not in named:
        return empty, None
    array = np.asarray(named[name])
    if array.dtype.kind not in "fiu" or array.shape != (n, width):
        shape = f"({n}, {width})"
        raise InvalidInputError(
            f"corner property {name!r} must be numbers of shape {shape}, not {array.dtype} of shape {array.shape}"
        )
    array = np.ascontiguousarray(array, dtype=np.float64)
    absent = np.isnan(array).all(axis=1)
    bad = ~(absent | np.isfinite(array).all(axis=1))
    if bad.any():
        corner = int(np.argmax(bad))
        raise InvalidInputError(
            f"corner property {name!r} of corner {corner} is neither finite nor all NaN: {array[corner].tolist()}"
        )
    if absent.all():
        return empty, None
    bits, first, inverse = np.unique(
        array[~absent].view(np.uint64), axis=0, return_index=True, return_inverse=True
    )
    order = np.argsort(first)
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    refs = np.zeros(n, np.int64)
    refs[~absent] = rank[inverse.reshape(-1)] + 1
    return bits[order].view(np.float64), refs


_CORNER_FORMATS = np.array(["%d", "%d/%d", "%d//%d", "%d/%d/%d"], dtype=object)


def _face_lines(counts: np.ndarray, v: np.ndarray, vt: np.ndarray, vn: np.ndarray) -> str:
    """``f`` lines whose corners refer to a ``vt``, a ``vn``, both or neither (1-based; 0: none)."""
    has_vt, has_vn = vt > 0, vn > 0
    formats = _CORNER_FORMATS[has_vt + 2 * has_vn]
    first = np.cumsum(counts) - counts
    before = np.full(len(v), " ", dtype=object)
    before[first] = "f "
    after = np.full(len(v), "", dtype=object)
    after[first + counts - 1] = "\n"
    template = "".join((before + formats + after).tolist())
    # Each corner's numbers: its vertex, then its vt and vn if it has them.
    width = 1 + has_vt + has_vn
    at = np.cumsum(width) - width
    values = np.empty(int(width.sum()), dtype=object)
    values[at] = v.tolist()
    values[at[has_vt] + 1] = vt[has_vt].tolist()
    values[at[has_vn] + 1 + has_vt[has_vn]] = vn[has_vn].tolist()
    return template % tuple(values.tolist())


class _Corners:
    """``vt`` or ``vn``: the rows defined so far, and which one every corner refers to (-1: none)."""

    def __init__(self, keyword: str, what: str, width: int) -> None:
        self.keyword, self.what, self.width = keyword, what, width
        self.rows: list[np.ndarray] = []
        self.refs: list[np.ndarray | int] = []  # per chunk: references, or the number of corners without any
        self.defined = 0  # rows so far, the base of negative references
        self.referenced = False

    def add(self, rows: np.ndarray, refs: np.ndarray | None, corners: int) -> None:
        self.rows.append(rows)
        self.defined += len(rows)
        self.refs.append(corners if refs is None else refs)
        self.referenced |= refs is not None

    def array(self, soup: PolygonSoup, path: str) -> np.ndarray | None:
        """Every corner's row (NaN without a reference); None if no corner has a reference."""
        if not self.referenced:
            return None
        refs = np.concatenate([np.full(r, -1, np.int64) if isinstance(r, int) else r for r in self.refs])
        table = joined(self.rows, np.float64).reshape(-1, self.width)
        # References forward are resolved here, against every row of the file.
        beyond = refs >= len(table)
        if beyond.any():
            corner = int(np.argmax(beyond))
            line = int(soup.lines[np.searchsorted(soup.offsets, corner, side="right") - 1])
            what = f"{self.what} index {refs[corner] + 1} is out of range for {len(table)} {self.keyword} lines"
            raise error(path, line, what)
        out = np.full((len(refs), self.width), np.nan)
        has = refs >= 0
        out[has] = table[refs[has]]
        return out


def _read(src: TextFile) -> PolygonSoup:
    positions: list[np.ndarray] = []
    polygons = Polygons()
    defined = 0  # vertices so far, the base of negative indices
    texture = _Corners("vt", "texture coordinate", 2)
    normal = _Corners("vn", "normal", 3)
    statements = _Statements(src.path)
    for chunk in src.chunks():
        statements.look(chunk)
        found = _chunk_fast(chunk, defined, texture.defined, normal.defined)
        if found is None:
            found = _chunk_slow(chunk, defined, texture.defined, normal.defined, src.path)
        xyz, counts, indices, lines, (uv, uv_refs), (normals, normal_refs) = found
        positions.append(xyz)
        polygons.add(counts, indices, lines)
        defined += len(xyz)
        texture.add(uv, uv_refs, len(indices))
        normal.add(normals, normal_refs, len(indices))
    statements.finish(src)
    soup = polygons.soup(positions)
    corners = {}
    for name, kind in [("uv", texture), ("normal", normal)]:
        values = kind.array(soup, src.path)
        if values is not None:
            corners[name] = values
    return replace(soup, corner_properties=corners) if corners else soup


# Every statement of the OBJ format — vertex data, elements, grouping, display
# and render attributes, free-form geometry, and the superseded ones — as the
# first word of a line.
_STATEMENTS = (
    b"v vt vn vp f l p g o s mg usemtl mtllib usemap maplib lod bevel c_interp d_interp shadow_obj trace_obj "
    b"ctech stech cstype deg bmat step curv curv2 surf parm trim hole scrv sp end con call csh bsp bzp cdc cdp res"
).split()
_STATEMENT = re.compile(rb"^[^\S\n]*(?:" + b"|".join(_STATEMENTS) + rb")(?=[\s#]|\Z)", re.MULTILINE)
_CONTENT = re.compile(rb"^[^\S\n]*([^\s#]+)", re.MULTILINE)  # a line's first word
_CONTROL = re.compile(rb"[\x00-\x08\x0e-\x1f\x7f]")  # bytes that text does not hold


class _Statements:
    """Whether a file is OBJ at all, chunk by chunk until its first statement.

    Every line the reader does not know is skipped, so without this any file
    — binary data, base64, nothing at all — would read as an empty mesh.
    """

    def __init__(self, path: str) -> None:
        self.path = path
        self.found = False
        self.first: tuple[int, bytes] | None = None  # the first line holding a word, and the word

    def look(self, chunk: Chunk) -> None:
        """Find the chunk's first statement, before the reader parses it; refuse binary data that comes first."""
        if self.found:
            return
        data = chunk.data
        nul = data.find(b"\x00")
        for match in _STATEMENT.finditer(data, 0, len(data) if nul < 0 else nul):
            i = int(np.searchsorted(chunk.ends, match.start()))
            line = data[chunk.starts[i] : chunk.ends[i]].split(b"#", 1)[0]
            if _is_text(line):
                self.found = True
                return
        if nul >= 0:
            line = chunk.line0 + int(np.searchsorted(chunk.ends, nul))
            raise error(self.path, line, "not an OBJ file: binary data (a NUL byte) before any OBJ statement")
        if self.first is None:
            word = _CONTENT.search(data)
            if word is not None:
                self.first = chunk.line0 + int(np.searchsorted(chunk.ends, word.start())), word[1]

    def finish(self, src: TextFile) -> None:
        """Refuse the file read if no line of it was a statement."""
        if self.found:
            return
        if self.first is None:
            raise empty(self.path, src.last_line, "OBJ statements such as v and f")
        line, word = self.first
        what = f"not an OBJ file: no line is an OBJ statement (v, f, ...); this one starts with {show(word)}"
        raise error(self.path, line, what)


def _is_text(line: bytes) -> bool:
    if _CONTROL.search(line):
        return False
    try:
        line.decode("utf-8")
    except UnicodeDecodeError:
        return False
    return True


def _resolve(raw: np.ndarray, before: np.ndarray) -> np.ndarray:
    """1-based and negative (relative to ``before`` vertices) indices to 0-based; 0 to -1."""
    if (raw > 0).all():
        return raw - 1
    return np.where(raw > 0, raw - 1, np.where(raw < 0, before + raw, -1))


_NONE = (np.empty((0, 2)), None), (np.empty((0, 3)), None)


def _chunk_fast(chunk: Chunk, defined: int, vt_defined: int, vn_defined: int):
    if b"#" in chunk.data:
        chunk.strip_comments()
    chunk.tokenize()
    buf = chunk.buf
    has = chunk.ntokens > 0
    if not has.any():
        return np.empty((0, 3)), np.empty(0, np.int64), np.empty(0, np.int64), np.empty(0, np.int64), *_NONE
    lead = chunk.tokens[np.minimum(chunk.first, len(chunk.tokens) - 1)]
    keyword = buf[lead]
    single = WS[buf[lead + 1]]  # a one-letter keyword (the chunk ends in a newline)
    is_v = has & single & (keyword == ord("v"))
    is_f = has & single & (keyword == ord("f"))
    vlines, flines = np.flatnonzero(is_v), np.flatnonzero(is_f)
    # Two-letter keywords: their second letter is not a newline, so a third byte follows.
    # (Cheaper than searching the chunk's bytes for b"vt".)
    vtlines = vnlines = np.empty(0, np.int64)
    two = np.flatnonzero(has & ~single & (keyword == ord("v")))
    if len(two):
        two = two[WS[buf[lead[two] + 2]]]
        second = buf[lead[two] + 1]
        vtlines, vnlines = two[second == ord("t")], two[second == ord("n")]
    if b"\\" in chunk.data:
        line = np.searchsorted(chunk.ends, np.flatnonzero(buf == ord("\\")))
        ours = is_v | is_f
        ours[vtlines] = ours[vnlines] = True
        if ours[line].any():
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
    uv = _rows(chunk, vtlines, lead, 1, 2)
    normals = _rows(chunk, vnlines, lead, 3, 3)
    if uv is None or normals is None:
        return None

    if len(flines):
        buf[lead[flines]] = SPACE
        counts = chunk.ntokens[flines] - 1
        found = _face_references(chunk.text(flines), int(counts.sum()))
        if found is None:
            return None
        raw, raw_uv, raw_normal = found
        face = None  # the face (of flines) of every corner, when needed

        def before(lines: np.ndarray, base: int) -> np.ndarray:
            nonlocal face
            if face is None:
                face = np.repeat(np.arange(len(flines)), counts)
            return (base + np.searchsorted(lines, flines))[face]

        indices = _resolve(raw, before(vlines, defined) if (raw <= 0).any() else 0)
        uv_refs = _resolve_references(raw_uv, before, vtlines, vt_defined)
        normal_refs = _resolve_references(raw_normal, before, vnlines, vn_defined)
        if uv_refs is False or normal_refs is False:
            return None
    else:
        counts = indices = np.empty(0, np.int64)
        uv_refs = normal_refs = None
    return xyz, counts, indices, chunk.line0 + flines, (uv, uv_refs), (normals, normal_refs)


def _rows(chunk: Chunk, lines: np.ndarray, lead: np.ndarray, least: int, width: int) -> np.ndarray | None:
    """The first ``width`` numbers (missing ones 0) of ``vt`` or ``vn`` lines; None if one is malformed."""
    if len(lines) == 0:
        return np.empty((0, width))
    chunk.buf[lead[lines]] = SPACE
    chunk.buf[lead[lines] + 1] = SPACE
    counts = chunk.ntokens[lines] - 1
    values = common.parse(chunk.text(lines), int(counts.sum()), np.float64)
    if values is None or (counts < least).any():
        return None
    n, c = len(counts), int(counts[0])
    if c >= width and (counts == c).all():
        out = values.reshape(n, c)[:, :width].copy()
    else:
        row = np.cumsum(counts) - counts
        out = np.zeros((n, width))
        for j in range(width):
            there = counts > j
            out[there, j] = values[row[there] + j]
    return out if np.isfinite(out).all() else None


def _resolve_references(raw, before, lines: np.ndarray, base: int):
    """``vt`` or ``vn`` references (``(corners, values)`` or None) as 0-based rows per corner, -1 for none.

    None when no corner has a reference; False if one is 0 or counts back
    past the first row (the per-line reader names it).
    """
    if raw is None:
        return None
    corners, values = raw
    refs = np.full(len(corners), -1, np.int64)
    at = np.flatnonzero(corners)
    if (values <= 0).any():
        if (values == 0).any():
            return False
        resolved = np.where(values > 0, values - 1, before(lines, base)[at] + values)
        if (resolved < 0).any():
            return False
    else:
        resolved = values - 1
    refs[at] = resolved
    return refs


def _face_references(text: np.ndarray, total: int):
    """Every vertex reference (``v``, ``v/vt``, ``v//vn``, ``v/vt/vn``) of face lines; None if one is malformed.

    Returns ``(positions, vt, vn)``: the position index of every reference,
    and for texture coordinates and normals either None (no reference has
    one) or ``(which references have one: bool array, their numbers)``.
    """
    slash = text == SLASH
    if not slash.any():
        values = common.parse(text, total, np.int64)
        return None if values is None else (values, None, None)
    references = token_starts(text)
    text = text.copy()
    text[slash] = SPACE
    numbers = token_starts(text)
    values = common.parse(text, len(numbers), np.int64)
    if values is None or len(references) != total:
        return None
    # A reference's position index is the number that starts where it does;
    # a reference that starts with '/' has none.
    at = np.searchsorted(numbers, references)
    if (at >= len(numbers)).any() or (numbers[at] != references).any():
        return None
    if len(numbers) == len(references):
        return values[at], None, None  # only empty parts after slashes ("1//")
    # Which part of its reference each number is: the slashes between them.
    slashes = np.flatnonzero(slash)
    owner = np.searchsorted(references, numbers, side="right") - 1
    if (np.bincount(np.searchsorted(references, slashes, side="right") - 1, minlength=total) > 2).any():
        return None  # more than three parts: the per-line reader refuses it
    part = np.searchsorted(slashes, numbers) - np.searchsorted(slashes, references)[owner]
    found = []
    for k in (1, 2):
        mine = part == k
        if mine.any():
            corners = np.zeros(total, dtype=bool)
            corners[owner[mine]] = True
            found.append((corners, values[mine]))
        else:
            found.append(None)
    return values[at], found[0], found[1]


def _chunk_slow(chunk: Chunk, defined: int, vt_defined: int, vn_defined: int, path: str):
    xyz, counts, indices, lines = [], [], [], []
    uv, normals, uv_refs, normal_refs = [], [], [], []
    everything = np.arange(len(chunk.ends))
    for line, tokens in chunk.line_tokens(everything, comments=True):
        if not tokens or tokens[0] not in (b"v", b"f", b"vt", b"vn"):
            continue
        if tokens[-1].endswith(b"\\"):
            raise error(path, line, "line continuations ('\\') are not supported")
        if tokens[0] == b"v":
            if len(tokens) < 3:
                raise error(path, line, f"a vertex needs at least 2 coordinates, found {len(tokens) - 1}")
            coords = [coordinate(t, path, line) for t in tokens[1:4]]
            xyz.append(tuple(coords) if len(coords) == 3 else (*coords, 0.0))
            continue
        if tokens[0] == b"vt":
            if len(tokens) < 2:
                raise error(path, line, "a texture coordinate needs at least 1 number, found 0")
            coords = [coordinate(t, path, line) for t in tokens[1:3]]
            uv.append(tuple(coords) if len(coords) == 2 else (coords[0], 0.0))
            continue
        if tokens[0] == b"vn":
            if len(tokens) < 4:
                raise error(path, line, f"a normal needs 3 numbers, found {len(tokens) - 1}")
            normals.append(tuple(coordinate(t, path, line) for t in tokens[1:4]))
            continue
        before = defined + len(xyz)
        for token in tokens[1:]:
            parts = token.split(b"/")
            if len(parts) > 3:
                raise error(path, line, f"vertex reference {show(token)} has more than three parts")
            i = integer(parts[0], path, line, "vertex index")
            indices.append(i - 1 if i > 0 else before + i if i < 0 else -1)
            uv_refs.append(_reference(parts, 1, vt_defined + len(uv), path, line, "texture coordinate", "vt"))
            normal_refs.append(_reference(parts, 2, vn_defined + len(normals), path, line, "normal", "vn"))
        counts.append(len(tokens) - 1)
        lines.append(line)
    return (
        np.array(xyz, dtype=np.float64).reshape(-1, 3),
        counts,
        indices,
        lines,
        (np.array(uv, dtype=np.float64).reshape(-1, 2), _refs(uv_refs)),
        (np.array(normals, dtype=np.float64).reshape(-1, 3), _refs(normal_refs)),
    )


def _reference(parts: list[bytes], k: int, before: int, path: str, line: int, what: str, keyword: str) -> int:
    """Part ``k`` of a vertex reference as a 0-based row, -1 if it is absent."""
    if len(parts) <= k or not parts[k]:
        return -1
    i = integer(parts[k], path, line, f"{what} index")
    if i > 0:
        return i - 1
    if i == 0:
        raise error(path, line, f"{what} index 0 is invalid (OBJ indices start at 1)")
    if before + i < 0:
        raise error(path, line, f"{what} index {i} counts back past the first of the {before} {keyword} lines so far")
    return before + i


def _refs(refs: list[int]) -> np.ndarray | None:
    array = np.array(refs, dtype=np.int64)
    return array if (array >= 0).any() else None
