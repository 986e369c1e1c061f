"""Polygon mesh files: reading and writing OFF, OBJ and PLY.

This module owns the file formats and nothing else. `read` turns a file into a
`PolygonSoup` — vertex positions and polygons exactly as the file gives them —
and `write` turns arrays back into a file. It knows no half-edges and no
database: whether the polygons form a mesh, and whether their indices are in
range, is for the builder to decide. That is why indices are passed through
unchecked, and why every polygon of a text file keeps the line it came from:
the builder names that line when it rejects the polygon.

"Exactly as the file gives them" means:

* vertices and polygons keep the file's order;
* vertices are never welded by position, even where two share a position;
* polygons stay polygons (no triangulation), whatever their number of
  vertices, and degenerate ones (repeated or out-of-range indices, fewer than
  three vertices) are kept for the builder to judge;
* positions are float64; a 2-D position (no z) gets z = 0.

What each reader accepts:

OFF
    The keyword ``OFF``, optionally prefixed ``ST``, ``C``, ``N`` and ``n``
    (``nOFF`` gives the dimension, 2 or 3, on the next token), then the
    vertex, face and (ignored) edge counts, on the keyword's line or the next.
    ``#`` starts a comment anywhere, before the keyword too; blank lines are
    skipped. One vertex or face per line: values after x, y, z (colours,
    normals, texture coordinates) and after a face's indices (colours) are
    ignored, as is anything after the last face. Binary OFF and homogeneous
    ``4OFF`` are refused.
OBJ
    ``v x y [z [w]]`` and ``f`` with the vertex references ``v``, ``v/vt``,
    ``v//vn`` and ``v/vt/vn``; only the position index counts. Negative
    indices count back from the vertices defined so far; index 0 (invalid in
    OBJ) becomes -1 so that the builder rejects it as out of range. ``#``
    starts a comment. Every other statement is skipped — ``vt``, ``vn``,
    ``g``, ``o``, ``s``, ``usemtl``, ``mtllib`` and also ``l`` (polylines)
    and ``p`` (points), which are not polygons. Line continuations (a
    trailing ``\\``) on ``v`` and ``f`` lines are refused.
PLY
    ``ascii``, ``binary_little_endian`` and ``binary_big_endian``, every
    scalar type under its classic and its sized name (``uchar``/``uint8``,
    ``float``/``float32``, ...). The ``vertex`` element needs x and y (z is
    optional); its other properties are skipped. The ``face`` element needs a
    ``vertex_indices`` (or ``vertex_index``) list; its other properties are
    skipped. Other elements (``edge``, ``material``, even ``tristrips``) are
    skipped, as are ``comment`` and ``obj_info`` lines. A file without a
    ``face`` element is a point set: positions and no polygons.

Large files are read in chunks of whole lines, each parsed with numpy (the
per-line Python reader only runs on a chunk that the vectorised one cannot
take, and it is the one that finds and names a malformed line). Binary PLY
elements whose lists all have the same length are read as one structured
array.

A malformed file raises `~hestore.errors.InvalidInputError` with the message
``"{path}:{line}: {what}"`` — for binary PLY data ``"{path}:byte {offset}:
{what}"`` — and `read` returns nothing partial.

Examples
--------
>>> import pathlib, tempfile
>>> from hestore import io as formats
>>> folder = tempfile.TemporaryDirectory()
>>> path = pathlib.Path(folder.name) / "pyramid.off"
>>> positions = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0.5, 0.5, 1)]
>>> offsets, indices = [0, 4, 7, 10, 13, 16], [3, 2, 1, 0, 0, 1, 4, 1, 2, 4, 2, 3, 4, 3, 0, 4]
>>> formats.write(path, positions, offsets, indices)
>>> soup = formats.read(path)
>>> soup
PolygonSoup(vertices=5, polygons=5)
>>> soup.indices[soup.offsets[0]:soup.offsets[1]]
array([3, 2, 1, 0])
>>> folder.cleanup()
"""

from __future__ import annotations

import math
import os
import re
import struct
import warnings
from dataclasses import dataclass
from typing import Callable, Iterator

import numpy as np

from hestore.errors import InvalidInputError

__all__ = ["PolygonSoup", "FORMATS", "format_of", "read", "write"]

FORMATS = ("off", "obj", "ply")
"""The supported formats, named by their file extensions."""

Progress = Callable[[int, int], object]

# Big enough that numpy's per-call overhead vanishes, small enough that the
# temporary per-byte arrays of a chunk stay in the tens of megabytes.
_CHUNK_BYTES = 1 << 23

# Rows per block when writing text: bounds the size of the formatted strings.
_WRITE_ROWS = 1 << 16

_INT64_MAX = np.iinfo(np.int64).max
_INT64_MIN = np.iinfo(np.int64).min

# bytes.split() whitespace, the separators every reader here uses.
_WS = np.zeros(256, dtype=bool)
_WS[list(b" \t\n\r\x0b\x0c")] = True

_SPACE, _NEWLINE, _HASH, _SLASH = ord(" "), ord("\n"), ord("#"), ord("/")


@dataclass(frozen=True, eq=False)
class PolygonSoup:
    """Vertex positions and polygons as a file gives them.

    Attributes
    ----------
    positions : ndarray of float64, shape (V, 3)
        Vertex positions in the file's order.
    offsets : ndarray of int64, shape (F + 1,)
        ``offsets[0] == 0``; polygon ``i`` is ``indices[offsets[i]:offsets[i + 1]]``.
    indices : ndarray of int64
        Zero-based vertex indices, not range-checked: an out-of-range index
        is passed through for the builder to reject.
    lines : ndarray of int64, shape (F,), or None
        The 1-based line of each polygon in a text file; None for binary PLY.

    Examples
    --------
    >>> import numpy as np
    >>> soup = PolygonSoup(np.zeros((4, 3)), np.array([0, 3, 6]), np.array([0, 1, 2, 0, 2, 3]), None)
    >>> soup
    PolygonSoup(vertices=4, polygons=2)
    >>> np.diff(soup.offsets)  # the number of vertices of each polygon
    array([3, 3])
    """

    positions: np.ndarray
    offsets: np.ndarray
    indices: np.ndarray
    lines: np.ndarray | None

    def __repr__(self) -> str:
        return f"PolygonSoup(vertices={len(self.positions)}, polygons={len(self.offsets) - 1})"


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
        The extension is not one of `FORMATS` (case does not matter).

    Examples
    --------
    >>> format_of("bunny.OBJ")
    'obj'
    >>> format_of("bunny.stl")
    Traceback (most recent call last):
    ...
    hestore.errors.InvalidInputError: bunny.stl: unsupported file format '.stl'; supported: .off, .obj, .ply
    """
    name = os.fsdecode(path)
    ext = os.path.splitext(name)[1]
    fmt = ext[1:].lower()
    if fmt not in FORMATS:
        supported = ", ".join("." + f for f in FORMATS)
        shown = repr(ext) if ext else "(no extension)"
        raise InvalidInputError(f"{name}: unsupported file format {shown}; supported: {supported}")
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
        binary PLY data).
    OSError
        The file cannot be opened or read.

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
    fmt = format_of(path)
    name = os.fsdecode(path)
    with open(path, "rb") as f:
        size = os.fstat(f.fileno()).st_size
        if fmt == "ply":
            soup = _read_ply(f, name, size, progress)
        else:
            src = _TextFile(f, name, size, progress)
            soup = _read_off(src) if fmt == "off" else _read_obj(src)
    if progress is not None:
        progress(size, size)
    return soup


def write(
    path: str | os.PathLike,
    positions,
    offsets,
    indices,
    *,
    binary: bool = True,
    progress: Progress | None = None,
) -> None:
    """Write vertex positions and polygons as an OFF, OBJ or PLY file.

    The format comes from the extension. OFF and OBJ are text; PLY is
    binary little endian unless ``binary=False``. Positions are written as
    doubles — in text, in their shortest round-trip form — so reading the
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
    binary : bool, default True
        PLY only: binary little endian, or ASCII with ``binary=False``.
    progress : callable, optional
        Called as ``progress(done, total)`` now and then, counting vertices
        and polygons written, and at least once at the end.

    Raises
    ------
    InvalidInputError
        Unsupported extension, or arrays that do not describe polygons on
        these vertices. Nothing is written then.

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
    >>> write(path.with_suffix(".ply"), [(0, 0, 0)], [0, 1], [1])
    Traceback (most recent call last):
    ...
    hestore.errors.InvalidInputError: polygon 0 has vertex index 1, out of range for 1 vertices
    >>> folder.cleanup()
    """
    fmt = format_of(path)
    positions, offsets, indices = _checked_arrays(positions, offsets, indices)
    if fmt == "ply" and len(positions) > 2**31:
        raise InvalidInputError("PLY files written here hold at most 2**31 vertices (int vertex indices)")
    total = len(positions) + len(offsets) - 1
    report = (lambda done: progress(done, total)) if progress is not None else (lambda done: None)
    with open(path, "wb") as f:
        if fmt == "off":
            f.write(f"OFF\n{len(positions)} {len(offsets) - 1} 0\n".encode())
            _write_text_rows(f, positions, offsets, indices, "", None, 0, report)
        elif fmt == "obj":
            _write_text_rows(f, positions, offsets, indices, "v ", "f", 1, report)
        elif binary:
            _write_ply_binary(f, positions, offsets, indices, report)
        else:
            f.write(_ply_header("ascii", positions, offsets))
            _write_text_rows(f, positions, offsets, indices, "", None, 0, report)
    report(total)


# --------------------------------------------------------------------------
# Errors and small helpers


def _error(path: str, where, what: str) -> InvalidInputError:
    return InvalidInputError(f"{path}:{where}: {what}")


def _show(token: bytes) -> str:
    return repr(token.decode("utf-8", "replace"))


def _ranges(starts: np.ndarray, lengths: np.ndarray, step: int = 1) -> np.ndarray:
    """The concatenation of ``arange(s, s + n * step, step)`` for every ``(s, n)``."""
    total = int(lengths.sum())
    if total == 0:
        return np.empty(0, dtype=np.int64)
    within = np.arange(total, dtype=np.int64) - np.repeat(np.cumsum(lengths) - lengths, lengths)
    return np.repeat(starts, lengths) + within * step


def _token_starts(buf: np.ndarray) -> np.ndarray:
    """Positions of the bytes that start a whitespace-separated token."""
    ws = _WS[buf]
    start = ~ws
    start[1:] &= ws[:-1]
    return np.flatnonzero(start)


def _parse(text, total: int, dtype) -> np.ndarray | None:
    """All numbers of ``text``, or None unless there are exactly ``total``.

    The count check is what makes this safe: numpy stops (older versions
    silently) at the first token it cannot read, and reads whitespace alone
    as one bogus number.
    """
    if total == 0:
        return np.empty(0, dtype=dtype)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)
            values = np.fromstring(text, dtype=dtype, sep=" ")
    except ValueError:
        return None
    return values if values.size == total else None


def _as_indices(values: np.ndarray) -> np.ndarray | None:
    """Integer-valued numbers as int64, or None if one is not an integer."""
    if values.dtype.kind in "iu":
        return values.astype(np.int64, copy=False)
    with np.errstate(invalid="ignore"):
        ok = np.isfinite(values) & (values == np.floor(values)) & (np.abs(values) < 2.0**63)
    return values.astype(np.int64) if ok.all() else None


def _float(token: bytes, path: str, line: int) -> float:
    try:
        value = float(token)
    except ValueError:
        raise _error(path, line, f"expected a number, found {_show(token)}") from None
    if not math.isfinite(value):
        raise _error(path, line, f"coordinate {_show(token)} is not finite")
    return value


def _int(token: bytes, path: str, line: int, what: str) -> int:
    try:
        value = int(token)
    except ValueError:
        raise _error(path, line, f"{what} {_show(token)} is not an integer") from None
    # The vectorised reader saturates at the int64 limits; so does this one.
    return min(max(value, _INT64_MIN), _INT64_MAX)


def _whole(token: bytes, path: str, line: int, what: str) -> int:
    """An integer, also written as an integral float (``3.0``), as OFF and PLY writers sometimes do."""
    try:
        return _int(token, path, line, what)
    except InvalidInputError:
        try:
            value = float(token)
        except ValueError:
            value = math.nan
        if not (math.isfinite(value) and value == math.floor(value) and abs(value) < 2.0**63):
            raise
        return int(value)


class _Polygons:
    """Polygons gathered piece by piece."""

    def __init__(self) -> None:
        self.counts: list[np.ndarray] = []
        self.indices: list[np.ndarray] = []
        self.lines: list[np.ndarray] = []

    def add(self, counts, indices, lines=None) -> None:
        self.counts.append(np.asarray(counts, dtype=np.int64))
        self.indices.append(np.asarray(indices, dtype=np.int64))
        if lines is not None:
            self.lines.append(np.asarray(lines, dtype=np.int64))

    def soup(self, positions: list[np.ndarray], text: bool = True) -> PolygonSoup:
        counts = _joined(self.counts, np.int64)
        offsets = np.zeros(len(counts) + 1, dtype=np.int64)
        np.cumsum(counts, out=offsets[1:])
        lines = _joined(self.lines, np.int64) if text else None
        xyz = _joined(positions, np.float64).reshape(-1, 3)
        return PolygonSoup(xyz, offsets, _joined(self.indices, np.int64), lines)


def _joined(parts: list[np.ndarray], dtype) -> np.ndarray:
    if len(parts) == 1:  # the usual case for small files: no copy
        return np.ascontiguousarray(parts[0], dtype=dtype)
    return np.concatenate(parts).astype(dtype, copy=False) if parts else np.empty(0, dtype)


# --------------------------------------------------------------------------
# Text files: chunks of whole lines


class _TextFile:
    """A text file read line by line (headers) or in chunks of whole lines."""

    def __init__(self, f, path: str, size: int, progress: Progress | None, line: int = 1) -> None:
        self.f = f
        self.path = path
        self.size = size
        self.progress = progress
        self.line = line  # the number of the next line to be read
        self._bom = line == 1  # a byte order mark can only start the file

    def _strip_bom(self, data: bytes) -> bytes:
        if self._bom:
            self._bom = False
            if data.startswith(b"\xef\xbb\xbf"):
                return data[3:]
        return data

    def content_line(self, comments: bool) -> tuple[list[bytes], int] | None:
        """The tokens and number of the next line that has any, or None at the end."""
        while True:
            raw = self.f.readline()
            if not raw:
                return None
            number = self.line
            self.line += 1
            raw = self._strip_bom(raw)
            if comments:
                raw = raw.split(b"#", 1)[0]
            tokens = raw.split()
            if tokens:
                return tokens, number

    def chunks(self) -> Iterator[_Chunk]:
        carry = b""
        while True:
            block = self.f.read(_CHUNK_BYTES)
            if not block:
                break
            block = self._strip_bom(carry + block if carry else block)
            cut = block.rfind(b"\n") + 1
            if cut == 0:
                carry = block
                continue
            carry = block[cut:]
            yield self._chunk(block[:cut] if carry else block)
            if self.progress is not None:
                self.progress(self.f.tell() - len(carry), self.size)
        if carry:
            yield self._chunk(carry + b"\n")

    def _chunk(self, data: bytes) -> _Chunk:
        chunk = _Chunk(data, self.line)
        self.line += len(chunk.ends)
        return chunk

    @property
    def last_line(self) -> int:
        return max(self.line - 1, 1)


class _Chunk:
    """Whole lines of text as a byte array, with the position of every token.

    ``buf`` is a private, writable copy of ``data``: the vectorised readers
    blank out what they do not want parsed (comments, keywords, slashes),
    while the per-line reader works on the untouched ``data``.
    """

    def __init__(self, data: bytes, line0: int) -> None:
        self.data = data
        self.line0 = line0
        self.buf = np.frombuffer(data, dtype=np.uint8).copy()
        self.ends = np.flatnonzero(self.buf == _NEWLINE)
        self.starts = np.empty_like(self.ends)
        self.starts[:1] = 0
        self.starts[1:] = self.ends[:-1] + 1

    def strip_comments(self) -> None:
        """Blank every ``#`` and the rest of its line."""
        hashes = np.flatnonzero(self.buf == _HASH)
        if hashes.size == 0:
            return
        line = np.searchsorted(self.ends, hashes)
        first = np.ones(len(hashes), dtype=bool)
        first[1:] = line[1:] != line[:-1]
        hashes, line = hashes[first], line[first]
        self.buf[_ranges(hashes, self.ends[line] - hashes)] = _SPACE

    def tokenize(self) -> None:
        """Find every token: ``ntokens[i]`` per line, ``first[i]`` its first in ``tokens``."""
        self.tokens = _token_starts(self.buf)
        self.first = np.searchsorted(self.tokens, self.starts)
        self.ntokens = np.searchsorted(self.tokens, self.ends) - self.first

    def text(self, lines: np.ndarray) -> np.ndarray:
        """The bytes of ``lines`` (sorted), newlines kept, without other lines' tokens."""
        a, b = lines[0], lines[-1]
        if np.count_nonzero(self.ntokens[a : b + 1]) == len(lines):
            return self.buf[self.starts[a] : self.ends[b] + 1]
        starts = self.starts[lines]
        return self.buf[_ranges(starts, self.ends[lines] + 1 - starts)]

    def line_tokens(self, lines: np.ndarray, comments: bool) -> Iterator[tuple[int, list[bytes]]]:
        """``(line number, tokens)`` of ``lines``, read from the untouched text."""
        data = self.data
        for i, s, e in zip(lines.tolist(), self.starts[lines].tolist(), self.ends[lines].tolist()):
            raw = data[s:e]
            if comments:
                raw = raw.split(b"#", 1)[0]
            yield self.line0 + i, raw.split()


def _first3(values: np.ndarray, counts: np.ndarray) -> np.ndarray | None:
    """x, y, z from rows of 2 or more numbers (z = 0 for 2); None if a row is shorter."""
    n = len(counts)
    if n == 0:
        return np.empty((0, 3))
    c = int(counts[0])
    if c >= 3 and (counts == c).all():
        return values.reshape(n, c)[:, :3].copy()
    if (counts < 2).any():
        return None
    row = np.cumsum(counts) - counts
    xyz = np.zeros((n, 3))
    xyz[:, 0] = values[row]
    xyz[:, 1] = values[row + 1]
    has_z = counts >= 3
    xyz[has_z, 2] = values[row[has_z] + 2]
    return xyz


def _columns(values: np.ndarray, counts: np.ndarray, width: int, cols) -> np.ndarray | None:
    """Columns ``cols`` (None: zeros) of rows of exactly ``width`` numbers."""
    n = len(counts)
    if (counts != width).any():
        return None
    table = values.reshape(n, width)
    xyz = np.zeros((n, 3))
    for j, col in enumerate(cols):
        if col is not None:
            xyz[:, j] = table[:, col]
    return xyz


def _count_prefixed(values, counts, lead: int, trail: int, exact: bool):
    """Rows ``[lead values] k i_1 .. i_k [trail values]``: ``(k, indices)``, or None if malformed.

    With ``exact=False`` a row may have more than ``trail`` values after its
    indices (OFF face colours).
    """
    n = len(counts)
    if n == 0:
        return np.empty(0, np.int64), np.empty(0, np.int64)
    if (counts <= lead).any():
        return None
    row = np.cumsum(counts) - counts
    k = _as_indices(values[row + lead])
    if k is None or (k < 0).any():
        return None
    need = lead + 1 + k + trail
    if ((counts != need) if exact else (counts < need)).any():
        return None
    k0, c0 = int(k[0]), int(counts[0])
    if (k == k0).all() and (counts == c0).all():
        chosen = values.reshape(n, c0)[:, lead + 1 : lead + 1 + k0].ravel()
    else:
        chosen = values[_ranges(row + lead + 1, k)]
    indices = _as_indices(chosen)
    return None if indices is None else (k, indices)


# --------------------------------------------------------------------------
# Line-sectioned text (OFF, ASCII PLY): runs of lines of one kind each


class _Section:
    """``count`` consecutive content lines of one kind."""

    def __init__(self, count: int) -> None:
        self.count = count
        self.remaining = count

    def take(self, chunk: _Chunk, lines: np.ndarray, src: _TextFile, comments: bool) -> None:
        self.remaining -= len(lines)
        text = chunk.text(lines)
        counts = chunk.ntokens[lines]
        if not self.fast(chunk, lines, text, counts):
            self.slow(chunk.line_tokens(lines, comments), src.path, chunk.line0 + lines)


class _Skip(_Section):
    what = "records"

    def fast(self, chunk, lines, text, counts) -> bool:
        return True


class _Positions(_Section):
    """Vertex lines: OFF (``layout=None``: x y [z] and anything after) or PLY records."""

    what = "vertices"

    def __init__(self, count: int, layout: _Element | None = None) -> None:
        super().__init__(count)
        self.layout = layout
        self.parts: list[np.ndarray] = []

    def fast(self, chunk, lines, text, counts) -> bool:
        if self.layout is not None and self.layout.has_lists:
            return False
        values = _parse(text, int(counts.sum()), np.float64)
        if values is None:
            return False
        if self.layout is None:
            xyz = _first3(values, counts)
        else:
            xyz = _columns(values, counts, len(self.layout.properties), self.layout.xyz_columns)
        if xyz is None or not np.isfinite(xyz).all():
            return False
        self.parts.append(xyz)
        return True

    def slow(self, rows, path, numbers) -> None:
        xyz = []
        for line, tokens in rows:
            if self.layout is not None:
                record = self.layout.parse_record(tokens, path, line)
                coords = [0.0 if col is None else record[col] for col in self.layout.xyz_columns]
                if not all(map(math.isfinite, coords)):
                    raise _error(path, line, f"vertex {coords} has a non-finite coordinate")
                xyz.append(coords)
            elif len(tokens) < 2:
                raise _error(path, line, f"a vertex needs at least 2 coordinates, found {len(tokens)}")
            else:
                coords = [_float(t, path, line) for t in tokens[:3]]
                xyz.append(tuple(coords) if len(coords) == 3 else (*coords, 0.0))
        self.parts.append(np.array(xyz, dtype=np.float64).reshape(-1, 3))


class _Faces(_Section):
    """Face lines: OFF (``layout=None``: k i_1 .. i_k, colours ignored) or PLY records."""

    what = "faces"

    def __init__(self, count: int, polygons: _Polygons, layout: _Element | None = None) -> None:
        super().__init__(count)
        self.polygons = polygons
        self.layout = layout

    def fast(self, chunk, lines, text, counts) -> bool:
        if self.layout is None:
            lead, trail, exact = 0, 0, False
        elif self.layout.simple_list is None:
            return False
        else:
            lead, trail = self.layout.simple_list
            exact = True
        total = int(counts.sum())
        # Integers parse several times faster than floats; floats only when
        # some other value on the lines (a colour, a quality) needs them.
        values = _parse(text, total, np.int64)
        if values is None:
            values = _parse(text, total, np.float64)
        found = None if values is None else _count_prefixed(values, counts, lead, trail, exact)
        if found is None:
            return False
        self.polygons.add(found[0], found[1], chunk.line0 + lines)
        return True

    def slow(self, rows, path, numbers) -> None:
        counts, indices = [], []
        for line, tokens in rows:
            if self.layout is not None:
                polygon = self.layout.parse_record(tokens, path, line)[self.layout.index_list]
            else:
                k = _whole(tokens[0], path, line, "vertex count")
                if k < 0:
                    raise _error(path, line, f"negative vertex count {k}")
                if len(tokens) < k + 1:
                    raise _error(path, line, f"face of {k} vertices has only {len(tokens) - 1} indices")
                polygon = [_whole(t, path, line, "vertex index") for t in tokens[1 : k + 1]]
            counts.append(len(polygon))
            indices.extend(polygon)
        self.polygons.add(counts, indices, numbers)


def _read_sections(src: _TextFile, sections: list[_Section], comments: bool) -> None:
    """Feed the content lines of the rest of ``src`` to ``sections``, in order.

    Lines after the last section are not read.
    """
    pending = [s for s in sections if s.remaining > 0]
    for chunk in src.chunks():
        if not pending:
            break
        if comments and b"#" in chunk.data:
            chunk.strip_comments()
        chunk.tokenize()
        content = np.flatnonzero(chunk.ntokens > 0)
        at = 0
        while pending and at < len(content):
            section = pending[0]
            lines = content[at : at + section.remaining]
            section.take(chunk, lines, src, comments)
            at += len(lines)
            if section.remaining == 0:
                pending.pop(0)
    if pending:
        s = pending[0]
        raise _error(src.path, src.last_line, f"file ends after {s.count - s.remaining} of {s.count} {s.what}")


# --------------------------------------------------------------------------
# OFF

_OFF_KEYWORD = re.compile(rb"(ST)?(C)?(N)?(4)?(n)?OFF")


def _read_off(src: _TextFile) -> PolygonSoup:
    path = src.path
    first = src.content_line(comments=True)
    if first is None:
        raise _error(path, src.last_line, "empty file: expected the OFF keyword")
    tokens, line = first
    keyword = _OFF_KEYWORD.fullmatch(tokens[0])
    if keyword is None:
        raise _error(path, line, f"expected the OFF keyword, found {_show(tokens[0])}")
    if keyword[4]:
        raise _error(path, line, "homogeneous coordinates (4OFF) are not supported")
    rest = tokens[1:]
    if rest and rest[0].upper() == b"BINARY":
        raise _error(path, line, "binary OFF is not supported")

    def more() -> tuple[list[bytes], int]:
        nxt = src.content_line(comments=True)
        if nxt is None:
            raise _error(path, src.last_line, "file ends inside the OFF header")
        return nxt

    if keyword[5]:
        if not rest:
            rest, line = more()
        dimension = _int(rest[0], path, line, "dimension")
        if dimension not in (2, 3):
            raise _error(path, line, f"only 2- and 3-dimensional nOFF is supported, found {dimension}")
        rest = rest[1:]
    if not rest:
        rest, line = more()
    if len(rest) not in (2, 3):
        found = " ".join(t.decode("utf-8", "replace") for t in rest)
        raise _error(path, line, f"expected the vertex, face and edge counts, found {found!r}")
    nv, nf, *_ = (_int(t, path, line, "count") for t in rest)
    if nv < 0 or nf < 0:
        raise _error(path, line, f"negative count in the OFF header: {nv} vertices, {nf} faces")

    polygons = _Polygons()
    vertices = _Positions(nv)
    _read_sections(src, [vertices, _Faces(nf, polygons)], comments=True)
    return polygons.soup(vertices.parts)


# --------------------------------------------------------------------------
# OBJ


def _read_obj(src: _TextFile) -> PolygonSoup:
    positions: list[np.ndarray] = []
    polygons = _Polygons()
    defined = 0  # vertices so far, the base of negative indices
    for chunk in src.chunks():
        found = _obj_chunk_fast(chunk, defined)
        if found is None:
            found = _obj_chunk_slow(chunk, defined, src.path)
        xyz, counts, indices, lines = found
        positions.append(xyz)
        polygons.add(counts, indices, lines)
        defined += len(xyz)
    return polygons.soup(positions)


def _resolve_obj(raw: np.ndarray, before: np.ndarray) -> np.ndarray:
    """1-based and negative (relative to ``before`` vertices) indices to 0-based; 0 to -1."""
    if (raw > 0).all():
        return raw - 1
    return np.where(raw > 0, raw - 1, np.where(raw < 0, before + raw, -1))


def _obj_chunk_fast(chunk: _Chunk, defined: int):
    if b"#" in chunk.data:
        chunk.strip_comments()
    chunk.tokenize()
    buf = chunk.buf
    has = chunk.ntokens > 0
    if not has.any():
        return np.empty((0, 3)), np.empty(0, np.int64), np.empty(0, np.int64), np.empty(0, np.int64)
    lead = chunk.tokens[np.minimum(chunk.first, len(chunk.tokens) - 1)]
    keyword = buf[lead]
    single = _WS[buf[lead + 1]]  # a one-letter keyword (the chunk ends in a newline)
    is_v = has & single & (keyword == ord("v"))
    is_f = has & single & (keyword == ord("f"))
    vlines, flines = np.flatnonzero(is_v), np.flatnonzero(is_f)
    if b"\\" in chunk.data:
        line = np.searchsorted(chunk.ends, np.flatnonzero(buf == ord("\\")))
        if (is_v[line] | is_f[line]).any():
            return None  # a continuation: the per-line reader refuses it with the line number

    if len(vlines):
        buf[lead[vlines]] = _SPACE
        counts = chunk.ntokens[vlines] - 1
        values = _parse(chunk.text(vlines), int(counts.sum()), np.float64)
        xyz = None if values is None else _first3(values, counts)
        if xyz is None or not np.isfinite(xyz).all():
            return None
    else:
        xyz = np.empty((0, 3))

    if len(flines):
        buf[lead[flines]] = _SPACE
        counts = chunk.ntokens[flines] - 1
        raw = _obj_face_indices(chunk.text(flines), int(counts.sum()))
        if raw is None:
            return None
        before = 0
        if (raw <= 0).any():
            before = np.repeat(defined + np.searchsorted(vlines, flines), counts)
        indices = _resolve_obj(raw, before)
    else:
        counts = indices = np.empty(0, np.int64)
    return xyz, counts, indices, chunk.line0 + flines


def _obj_face_indices(text: np.ndarray, total: int) -> np.ndarray | None:
    """The position index of every vertex reference (``v``, ``v/vt``, ``v//vn``, ``v/vt/vn``)."""
    if not (text == _SLASH).any():
        return _parse(text, total, np.int64)
    references = _token_starts(text)
    text = text.copy()
    text[text == _SLASH] = _SPACE
    numbers = _token_starts(text)
    values = _parse(text, len(numbers), np.int64)
    if values is None or len(references) != total:
        return None
    # A reference's position index is the number that starts where it does;
    # a reference that starts with '/' has none.
    at = np.searchsorted(numbers, references)
    if (at >= len(numbers)).any() or (numbers[at] != references).any():
        return None
    return values[at]


def _obj_chunk_slow(chunk: _Chunk, defined: int, path: str):
    xyz, counts, indices, lines = [], [], [], []
    everything = np.arange(len(chunk.ends))
    for line, tokens in chunk.line_tokens(everything, comments=True):
        if not tokens or tokens[0] not in (b"v", b"f"):
            continue
        if tokens[-1].endswith(b"\\"):
            raise _error(path, line, "line continuations ('\\') are not supported")
        if tokens[0] == b"v":
            if len(tokens) < 3:
                raise _error(path, line, f"a vertex needs at least 2 coordinates, found {len(tokens) - 1}")
            coords = [_float(t, path, line) for t in tokens[1:4]]
            xyz.append(tuple(coords) if len(coords) == 3 else (*coords, 0.0))
            continue
        before = defined + len(xyz)
        for token in tokens[1:]:
            i = _int(token.split(b"/", 1)[0], path, line, "vertex index")
            indices.append(i - 1 if i > 0 else before + i if i < 0 else -1)
        counts.append(len(tokens) - 1)
        lines.append(line)
    return np.array(xyz, dtype=np.float64).reshape(-1, 3), counts, indices, lines


# --------------------------------------------------------------------------
# PLY

_PLY_TYPES = {
    "char": "i1", "int8": "i1",
    "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2",
    "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4",
    "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4",
    "double": "f8", "float64": "f8",
}  # fmt: skip

_PLY_FORMATS = {"ascii": None, "binary_little_endian": "<", "binary_big_endian": ">"}


@dataclass
class _Property:
    name: str
    type: str  # numpy type code of the value, or of the list items
    count_type: str | None = None  # numpy type code of a list's count

    @property
    def is_list(self) -> bool:
        return self.count_type is not None


@dataclass
class _Element:
    name: str
    count: int
    line: int
    properties: list[_Property]

    @property
    def has_lists(self) -> bool:
        return any(p.is_list for p in self.properties)

    def position(self, name: str) -> int | None:
        for i, p in enumerate(self.properties):
            if p.name == name:
                return i
        return None

    @property
    def xyz_columns(self) -> tuple[int | None, ...]:
        return tuple(self.position(c) for c in "xyz")

    @property
    def index_list(self) -> int | None:
        at = self.position("vertex_indices")
        return self.position("vertex_index") if at is None else at

    @property
    def simple_list(self) -> tuple[int, int] | None:
        """``(scalars before, scalars after)`` the index list when it is the only list."""
        at = self.index_list
        if sum(p.is_list for p in self.properties) != 1:
            return None
        return at, len(self.properties) - at - 1

    def parse_record(self, tokens: list[bytes], path: str, line: int) -> list:
        """One ASCII record, property by property: floats, and lists (of ints for the index list)."""
        record: list = []
        at = 0
        for i, prop in enumerate(self.properties):
            if at >= len(tokens):
                raise _error(path, line, f"{self.name} record ends before its property {prop.name!r}")
            if not prop.is_list:
                record.append(_float_value(tokens[at], path, line))
                at += 1
            else:
                k = _whole(tokens[at], path, line, f"{prop.name} count")
                if k < 0:
                    raise _error(path, line, f"negative {prop.name} count {k}")
                items = tokens[at + 1 : at + 1 + k]
                if len(items) < k:
                    raise _error(path, line, f"{prop.name} of {k} items has only {len(items)}")
                if i == self.index_list and self.name == "face":
                    record.append([_whole(t, path, line, "vertex index") for t in items])
                else:
                    record.append([_float_value(t, path, line) for t in items])
                at += 1 + k
        if at != len(tokens):
            raise _error(path, line, f"{self.name} record has {len(tokens) - at} values more than its properties")
        return record


def _float_value(token: bytes, path: str, line: int) -> float:
    try:
        return float(token)
    except ValueError:
        raise _error(path, line, f"expected a number, found {_show(token)}") from None


def _read_ply_header(f, path: str):
    """``(elements, byte order or None for ASCII, number of the first body line)``."""
    raw = f.readline()
    if raw.strip() != b"ply":
        raise _error(path, 1, "not a PLY file: the first line must be 'ply'")
    order = False
    elements: list[_Element] = []
    number = 1
    while True:
        raw = f.readline()
        number += 1
        if not raw:
            raise _error(path, number - 1, "file ends inside the PLY header (no end_header)")
        words = raw.decode("ascii", "replace").split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        key = words[0]
        if key == "end_header":
            break
        if key == "format":
            if len(words) != 3 or words[1] not in _PLY_FORMATS:
                raise _error(path, number, f"unknown PLY format {' '.join(words[1:])!r}")
            order = _PLY_FORMATS[words[1]]
        elif key == "element":
            if len(words) != 3 or not words[2].isdigit():
                raise _error(path, number, "expected 'element <name> <count>'")
            if any(e.name == words[1] for e in elements):
                raise _error(path, number, f"element {words[1]!r} is declared twice")
            elements.append(_Element(words[1], int(words[2]), number, []))
        elif key == "property":
            if not elements:
                raise _error(path, number, "property before any element")
            elements[-1].properties.append(_ply_property(words, path, number))
        else:
            raise _error(path, number, f"unknown PLY header keyword {key!r}")
    if order is False:
        raise _error(path, number, "the PLY header has no format line")
    _check_ply_elements(elements, path)
    return elements, order, number + 1


def _ply_property(words: list[str], path: str, number: int) -> _Property:
    def type_of(name: str) -> str:
        if name not in _PLY_TYPES:
            raise _error(path, number, f"unknown PLY property type {name!r}")
        return _PLY_TYPES[name]

    if len(words) == 5 and words[1] == "list":
        count_type = type_of(words[2])
        if count_type[0] == "f":
            raise _error(path, number, f"list count type must be an integer type, not {words[2]!r}")
        return _Property(words[4], type_of(words[3]), count_type)
    if len(words) == 3 and words[1] != "list":
        return _Property(words[2], type_of(words[1]))
    raise _error(path, number, "expected 'property <type> <name>' or 'property list <count type> <type> <name>'")


def _check_ply_elements(elements: list[_Element], path: str) -> None:
    named = {e.name: e for e in elements}
    vertex = named.get("vertex")
    if vertex is None:
        raise _error(path, elements[-1].line if elements else 1, "the PLY header declares no vertex element")
    for c in "xyz":
        at = vertex.position(c)
        if at is None and c != "z":
            raise _error(path, vertex.line, f"the vertex element has no {c} property")
        if at is not None and vertex.properties[at].is_list:
            raise _error(path, vertex.line, f"vertex property {c} is a list, not a number")
    face = named.get("face")
    if face is not None:
        at = face.index_list
        if at is None or not face.properties[at].is_list:
            raise _error(path, face.line, "the face element has no vertex_indices list")
        if face.properties[at].type[0] == "f":
            raise _error(path, face.line, "face vertex indices must have an integer type")


def _read_ply(f, path: str, size: int, progress: Progress | None) -> PolygonSoup:
    elements, order, body_line = _read_ply_header(f, path)
    if order is None:
        src = _TextFile(f, path, size, progress, line=body_line)
        polygons = _Polygons()
        vertices = None
        sections: list[_Section] = []
        for e in elements:
            if e.name == "vertex":
                vertices = _Positions(e.count, e)
                sections.append(vertices)
            elif e.name == "face":
                sections.append(_Faces(e.count, polygons, e))
            else:
                skip = _Skip(e.count if e.properties else 0)
                skip.what = f"{e.name} records"
                sections.append(skip)
        _read_sections(src, sections, comments=False)
        return polygons.soup(vertices.parts)
    return _read_ply_binary(_BinaryFile(f, path, size, progress), elements, order)


class _BinaryFile:
    def __init__(self, f, path: str, size: int, progress: Progress | None) -> None:
        self.f = f
        self.path = path
        self.size = size
        self.progress = progress

    def tell(self) -> int:
        return self.f.tell()

    def seek(self, pos: int) -> None:
        self.f.seek(pos)

    def peek(self, nbytes: int) -> bytes:
        pos = self.f.tell()
        data = self.f.read(nbytes)
        self.f.seek(pos)
        return data

    def records(self, dtype: np.dtype, n: int) -> tuple[np.ndarray, int]:
        """Up to ``n`` records; also how many were complete before the end of the file."""
        records = np.empty(n, dtype=dtype)
        if dtype.itemsize == 0 or n == 0:
            return records, n
        raw = records.view(np.uint8)
        done = 0
        while done < raw.size:
            step = self.f.readinto(raw[done : done + _CHUNK_BYTES])
            if not step:
                break
            done += step
            if self.progress is not None:
                self.progress(self.f.tell(), self.size)
        return records, done // dtype.itemsize


class _Records:
    """The properties of an element's binary records.

    Built either from one structured array (when every list has the same
    length in every record) or from the byte offsets found by `_walk`.
    """

    def __init__(self, element: _Element, order: str, start: int, *, array=None, buf=None, offsets=None, counts=None):
        self.element = element
        self.order = order
        self.start = start
        self.array = array
        self.buf, self.offsets, self.counts = buf, offsets, counts

    def byte(self, record: int) -> int:
        """The file offset of a record."""
        if self.array is not None:
            return self.start + record * self.array.dtype.itemsize
        return self.start + int(self.offsets[0][record])

    def scalar(self, p: int) -> np.ndarray:
        if self.array is not None:
            return self.array[f"p{p}"]
        return self._gather(self.offsets[p], np.dtype(self.order + self.element.properties[p].type))

    def list(self, p: int) -> tuple[np.ndarray, np.ndarray]:
        """Lengths and concatenated items of list property ``p``."""
        if self.array is not None:
            items = self.array[f"p{p}"]
            return np.full(len(items), items.shape[1], dtype=np.int64), items.ravel()
        prop = self.element.properties[p]
        item = np.dtype(self.order + prop.type)
        k = self.counts[p]
        first = self.offsets[p] + np.dtype(prop.count_type).itemsize
        return k, self._gather(_ranges(first, k, item.itemsize), item)

    def _gather(self, at: np.ndarray, dtype: np.dtype) -> np.ndarray:
        return self.buf[at[:, None] + np.arange(dtype.itemsize)].view(dtype).ravel()


def _read_ply_binary(src: _BinaryFile, elements: list[_Element], order: str) -> PolygonSoup:
    polygons = _Polygons()
    xyz = np.empty((0, 3))
    for element in elements:
        records = _binary_element(src, element, order)
        if element.name == "vertex":
            xyz = np.zeros((element.count, 3))
            for j, col in enumerate(element.xyz_columns):
                if col is not None:
                    xyz[:, j] = records.scalar(col)
            finite = np.isfinite(xyz).all(axis=1)
            if not finite.all():
                bad = int(np.argmin(finite))
                raise _error(src.path, f"byte {records.byte(bad)}", f"vertex {bad} has a non-finite coordinate")
        elif element.name == "face":
            counts, indices = records.list(element.index_list)
            polygons.add(counts, indices.astype(np.int64))
    return polygons.soup([xyz], text=False)


def _binary_element(src: _BinaryFile, element: _Element, order: str) -> _Records:
    start = src.tell()
    n = element.count
    props = element.properties
    if not element.has_lists:
        dtype = np.dtype([(f"p{i}", order + p.type) for i, p in enumerate(props)])
        array, complete = src.records(dtype, n)
        if complete < n:
            where = f"byte {start + complete * dtype.itemsize}"
            raise _error(src.path, where, f"file ends inside {element.name} {complete} of {n}")
        return _Records(element, order, start, array=array)

    # Guess that every record's lists are as long as the first record's, read
    # the element as one structured array, and check the guess.
    if n > 0:
        try:
            _, first, _ = _walk(src.peek(1 << 16), element, order, 1, src.path, start)
        except InvalidInputError:
            first = None  # the per-record walk below finds what is wrong
        if first is not None:
            fields = []
            for i, p in enumerate(props):
                if p.is_list:
                    fields.append((f"n{i}", order + p.count_type))
                    fields.append((f"p{i}", order + p.type, (int(first[i][0]),)))
                else:
                    fields.append((f"p{i}", order + p.type))
            array, complete = src.records(np.dtype(fields), n)
            lists = [i for i, p in enumerate(props) if p.is_list]
            if complete == n and all((array[f"n{i}"] == first[i][0]).all() for i in lists):
                return _Records(element, order, start, array=array)
            src.seek(start)

    data = src.f.read() if n else b""
    offsets, counts, end = _walk(data, element, order, n, src.path, start)
    src.seek(start + end)
    if src.progress is not None:
        src.progress(src.tell(), src.size)
    return _Records(element, order, start, buf=np.frombuffer(data, np.uint8), offsets=offsets, counts=counts)


def _walk(buf: bytes, element: _Element, order: str, n: int, path: str, start: int):
    """Find the records of an element whose lists vary in length, one by one.

    Returns ``(offsets, counts, end)``: per property, the byte offset in
    ``buf`` of its value (or list count) in every record; per list property,
    the lengths (None for scalars); and the offset just past the last record.
    ``start`` is the file offset of ``buf``, for messages.
    """
    props = element.properties
    # Runs of scalars between lists collapse into fixed steps, so that the
    # per-record loop only reads list counts.
    lists, fixed = [], [0]
    for p in props:
        if p.is_list:
            count = np.dtype(p.count_type)
            unpack = struct.Struct(order + count.char).unpack_from
            lists.append((unpack, count.itemsize, np.dtype(p.type).itemsize))
            fixed.append(0)
        else:
            fixed[-1] += np.dtype(p.type).itemsize
    head, tails = fixed[0], fixed[1:]
    starts = [0] * n
    lengths = [[0] * n for _ in lists]
    pos = r = 0
    try:
        if len(lists) == 1:
            (unpack, count, item), tail, ks = lists[0], tails[0], lengths[0]
            for r in range(n):
                starts[r] = pos
                k = ks[r] = unpack(buf, pos + head)[0]
                pos += head + count + k * item + tail
        else:
            for r in range(n):
                starts[r] = pos
                pos += head
                for j, (unpack, count, item) in enumerate(lists):
                    k = lengths[j][r] = unpack(buf, pos)[0]
                    pos += count + k * item + tails[j]
        r = n
    except struct.error:
        pass  # record r starts past the end of the data
    for ks in lengths:
        negative = np.flatnonzero(np.array(ks[: r + 1]) < 0)
        if negative.size:
            i = int(negative[0])
            where = f"byte {start + starts[i]}"
            raise _error(path, where, f"negative list count {ks[i]} in {element.name} {i}")
    if r < n or pos > len(buf):
        ends = starts[1 : r + 1] + ([pos] if r == n else [])
        bad = next((i for i, e in enumerate(ends) if e > len(buf)), min(r, n - 1))
        raise _error(path, f"byte {start + starts[bad]}", f"file ends inside {element.name} {bad} of {n}")

    at = np.array(starts, dtype=np.int64)
    offsets, counts, li = [], [], 0
    for p in props:
        offsets.append(at)
        if p.is_list:
            k = np.array(lengths[li], dtype=np.int64)
            li += 1
            counts.append(k)
            at = at + np.dtype(p.count_type).itemsize + k * np.dtype(p.type).itemsize
        else:
            counts.append(None)
            at = at + np.dtype(p.type).itemsize
    return offsets, counts, pos


# --------------------------------------------------------------------------
# Writing


def _checked_arrays(positions, offsets, indices):
    positions = np.asarray(positions, dtype=np.float64)
    if positions.ndim != 2 or positions.shape[1] != 3:
        if positions.size == 0:
            positions = positions.reshape(0, 3)
        else:
            raise InvalidInputError(f"positions must have shape (V, 3), not {positions.shape}")
    if not np.isfinite(positions).all():
        bad = int(np.argmin(np.isfinite(positions).all(axis=1)))
        raise InvalidInputError(f"position {bad} is not finite: {positions[bad].tolist()}")
    offsets = _integer_array(offsets, "offsets")
    indices = _integer_array(indices, "indices")
    if len(offsets) == 0 or offsets[0] != 0 or offsets[-1] != len(indices):
        raise InvalidInputError(f"offsets must run from 0 to len(indices) = {len(indices)}")
    counts = np.diff(offsets)
    if (counts < 1).any():
        raise InvalidInputError(f"polygon {int(np.argmax(counts < 1))} has no vertices")
    outside = (indices < 0) | (indices >= len(positions))
    if outside.any():
        at = int(np.argmax(outside))
        polygon = int(np.searchsorted(offsets, at, side="right")) - 1
        raise InvalidInputError(
            f"polygon {polygon} has vertex index {int(indices[at])}, out of range for {len(positions)} vertices"
        )
    return np.ascontiguousarray(positions), offsets, indices


def _integer_array(values, name: str) -> np.ndarray:
    array = np.asarray(values)
    if array.size == 0:
        return array.astype(np.int64).reshape(-1)
    if array.ndim != 1 or array.dtype.kind not in "iu":
        raise InvalidInputError(f"{name} must be a 1-D array of integers, not {array.dtype} of shape {array.shape}")
    return array.astype(np.int64, copy=False)


def _write_text_rows(f, positions, offsets, indices, vertex_prefix, keyword, base, report) -> None:
    """Vertex lines, then polygon lines (``keyword`` or, if None, the vertex count first)."""
    n = len(positions)
    for lo in range(0, n, _WRITE_ROWS):
        block = positions[lo : lo + _WRITE_ROWS]
        # %r is Python's shortest repr that reads back as the same double.
        f.write((((vertex_prefix + "%r %r %r\n") * len(block)) % tuple(block.ravel().tolist())).encode())
        report(lo + len(block))
    counts = np.diff(offsets)
    for lo in range(0, len(counts), _WRITE_ROWS):
        hi = min(lo + _WRITE_ROWS, len(counts))
        values = indices[offsets[lo] : offsets[hi]] + base
        f.write(_polygon_lines(counts[lo:hi], values, keyword).encode())
        report(n + hi)


def _polygon_lines(counts: np.ndarray, values: np.ndarray, keyword: str | None) -> str:
    arities, which = np.unique(counts, return_inverse=True)
    templates = [(keyword or str(k)) + " %d" * k + "\n" for k in arities.tolist()]
    if len(templates) == 1:
        template = templates[0] * len(counts)
    else:
        # One template per polygon, picked by arity, so that mixed arities
        # still take a single formatting pass.
        template = "".join(np.array(templates, dtype=object)[which].tolist())
    return template % tuple(values.tolist())


def _list_count_type(counts: np.ndarray) -> str:
    """The smallest PLY list count type that holds every polygon's vertex count."""
    return "uchar" if len(counts) == 0 or counts.max() <= 255 else "uint"


def _ply_header(fmt: str, positions: np.ndarray, offsets: np.ndarray) -> bytes:
    counts = np.diff(offsets)
    return (
        "ply\n"
        f"format {fmt} 1.0\n"
        f"element vertex {len(positions)}\n"
        "property double x\nproperty double y\nproperty double z\n"
        f"element face {len(counts)}\n"
        f"property list {_list_count_type(counts)} int vertex_indices\n"
        "end_header\n"
    ).encode("ascii")


def _write_ply_binary(f, positions, offsets, indices, report) -> None:
    f.write(_ply_header("binary_little_endian", positions, offsets))
    f.write(positions.astype("<f8").tobytes())
    report(len(positions))
    counts = np.diff(offsets)
    if len(counts) == 0:
        return
    count_type = np.dtype("<" + _PLY_TYPES[_list_count_type(counts)])
    k = int(counts[0])
    if (counts == k).all():
        records = np.empty(len(counts), dtype=[("n", count_type), ("i", "<i4", (k,))])
        records["n"] = k
        records["i"] = indices.reshape(-1, k)
        f.write(records.tobytes())
    else:
        # Record i starts after i counts and offsets[i] indices.
        cs = count_type.itemsize
        out = np.empty(len(counts) * cs + len(indices) * 4, dtype=np.uint8)
        record_at = np.arange(len(counts)) * cs + offsets[:-1] * 4
        out[record_at[:, None] + np.arange(cs)] = counts.astype(count_type).view(np.uint8).reshape(-1, cs)
        polygon = np.repeat(np.arange(len(counts)), counts)
        item_at = (polygon + 1) * cs + np.arange(len(indices)) * 4
        out[item_at[:, None] + np.arange(4)] = indices.astype("<i4").view(np.uint8).reshape(-1, 4)
        f.write(out.tobytes())
