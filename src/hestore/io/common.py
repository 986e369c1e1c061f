"""What the readers and writers of every format share.

This module belongs to `hestore.io` and is not public API, apart from
`PolygonSoup`, which the package re-exports. It owns:

* `PolygonSoup`, the one result type of every reader, and the per-element
  data it carries (`Carried` describes a PLY property that becomes such data);
* the error helpers: every malformed file raises
  `~hestore.errors.InvalidInputError` as ``"{path}:{where}: {what}"``, and
  every file the system refuses (missing, a folder, no permission, a full
  disk) as ``"cannot read {path}: {reason}"`` (`file_errors`, which the
  package re-exports for every module that reads or writes files); the
  refusal of an empty file (`empty`), the same rule in every format; and the
  one way a message quotes the file's content (`show`, and `named` for
  header names), escaped and cut short;
* number tokens: the strict per-token conversions of the per-line readers
  and the vectorised `parse` of whole chunks;
* header counts: `count` parses them strictly and `check_room` bounds them
  by the bytes left in the file, before any reader allocates for them;
* text read in chunks of whole lines (`TextFile`, `Chunk`) and tokenised
  with numpy;
* the section machinery that OFF and ASCII PLY share: runs of content lines
  of one kind (`Positions`, `Faces`, `Skip`) fed in order by `read_sections`;
* polygon accumulation (`Polygons`);
* the writers' shared argument checks and text row formatting.

The text readers parse each chunk with numpy first; the per-line reader runs
only on a chunk that the vectorised one cannot take, and it is the one that
finds and names a malformed line. Both must give the same arrays.
"""

from __future__ import annotations

import io
import math
import os
import stat
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import BinaryIO, Protocol

import numpy as np

from hestore.arrays import as_integers
from hestore.errors import InvalidInputError
from hestore.urls import check_path

Progress = Callable[[int, int], object]

# Big enough that numpy's per-call overhead vanishes, small enough that the
# temporary per-byte arrays of a chunk stay in the tens of megabytes. The
# format modules read it (and `parse`) as ``common.X`` at call time, so that
# tests can shrink the chunks or disable the vectorised parser.
CHUNK_BYTES = 1 << 23

# Rows per block when writing text: bounds the size of the formatted strings.
WRITE_ROWS = 1 << 16

INT64_MAX = np.iinfo(np.int64).max
INT64_MIN = np.iinfo(np.int64).min

# bytes.split() whitespace, the separators every reader here uses.
WS = np.zeros(256, dtype=bool)
WS[list(b" \t\n\r\x0b\x0c")] = True

SPACE, NEWLINE, HASH, SLASH = ord(" "), ord("\n"), ord("#"), ord("/")


@dataclass(frozen=True, eq=False)
class PolygonSoup:
    """Vertex positions and polygons as a file gives them, with their per-element data.

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
    vertex_properties : dict of str to ndarray
        Per-vertex data by name (PLY vertex properties other than x, y, z):
        arrays of first axis V.
    polygon_properties : dict of str to ndarray
        Per-polygon data by name (PLY face properties other than the index
        list): arrays of first axis F.
    corner_properties : dict of str to ndarray
        Per-corner data by name (OBJ ``"uv"`` and ``"normal"``): arrays of
        first axis ``len(indices)``, aligned with `indices` — corner ``k`` of
        polygon ``i`` is row ``offsets[i] + k``. A corner without a value is
        a row of NaN.

    Every property array is float64 or int64, of shape ``(n,)`` or ``(n, k)``.
    A reader gives empty dicts for a file that holds no such data.

    Examples
    --------
    >>> import numpy as np
    >>> soup = PolygonSoup(np.zeros((4, 3)), np.array([0, 3, 6]), np.array([0, 1, 2, 0, 2, 3]), None)
    >>> soup
    PolygonSoup(vertices=4, polygons=2)
    >>> np.diff(soup.offsets)  # the number of vertices of each polygon
    array([3, 3])
    >>> soup.vertex_properties
    {}
    >>> red = np.array([255, 0, 0, 9])
    >>> PolygonSoup(soup.positions, soup.offsets, soup.indices, None, vertex_properties={"red": red})
    PolygonSoup(vertices=4, polygons=2, vertex properties: red)
    """

    positions: np.ndarray
    offsets: np.ndarray
    indices: np.ndarray
    lines: np.ndarray | None
    vertex_properties: dict[str, np.ndarray] = field(default_factory=dict)
    polygon_properties: dict[str, np.ndarray] = field(default_factory=dict)
    corner_properties: dict[str, np.ndarray] = field(default_factory=dict)

    def __repr__(self) -> str:
        text = f"PolygonSoup(vertices={len(self.positions)}, polygons={len(self.offsets) - 1}"
        for kind, named in [
            ("vertex", self.vertex_properties),
            ("polygon", self.polygon_properties),
            ("corner", self.corner_properties),
        ]:
            if named:
                text += f", {kind} properties: {', '.join(named)}"
        return text + ")"


@dataclass(frozen=True)
class Carried:
    """A scalar PLY property that a reader keeps as per-element data.

    ``bounds`` is ``(lowest, highest)`` for an integer type (the data is
    int64), None for a floating-point one (float64).
    """

    column: int  # the property's position in its element's records
    name: str
    bounds: tuple[int, int] | None


def carried_columns(carried: list[Carried], values: np.ndarray, at) -> list[np.ndarray] | None:
    """The carried properties of rows of parsed numbers; None if one cannot be taken as it is.

    ``at(column)`` is the position in ``values`` of that column in every row.
    None (the per-line reader then names the bad value) for an integer
    property whose value is not an integer of its type, or a float property
    parsed as int64 — exact, but int64 parsing reads ``-0`` as ``0``.
    """
    out = []
    for c in carried:
        column = values[at(c.column)]
        if c.bounds is None:
            if values.dtype.kind != "f":
                return None
            out.append(column.astype(np.float64, copy=False))
            continue
        if values.dtype.kind == "f":
            with np.errstate(invalid="ignore"):
                if not (np.isfinite(column) & (column == np.floor(column))).all():
                    return None
        lo, hi = c.bounds
        if len(column) and (column.min() < lo or column.max() > hi):
            return None
        out.append(column.astype(np.int64))
    return out


def carried_arrays(carried: list[Carried], parts: list[list]) -> dict[str, np.ndarray]:
    """Per property, its pieces (arrays or lists of values) joined as int64 or float64."""
    named = {}
    for c, pieces in zip(carried, parts):
        dtype = np.float64 if c.bounds is None else np.int64
        named[c.name] = joined([np.asarray(piece, dtype=dtype) for piece in pieces], dtype)
    return named


# --------------------------------------------------------------------------
# Opening files and reporting progress


def read_file(path: str | os.PathLike, progress: Progress | None, reader) -> PolygonSoup:
    """``reader(f, name, size, progress)`` on the opened file, then the final progress report.

    Every reader ends with ``progress(size, size)``, however it stepped
    through the file, so a caller's progress bar always completes.
    """
    name = check_path(path)
    with file_errors(name, "read"), open(name, "rb") as f:
        info = os.fstat(f.fileno())
        if stat.S_ISREG(info.st_mode):
            size = info.st_size
            soup = reader(f, name, size, progress)
        else:
            # A pipe or device reports no size to bound header counts by, and
            # cannot seek (binary PLY peeks): read it whole first.
            data = f.read()
            size = len(data)
            soup = reader(io.BytesIO(data), name, size, progress)
    if progress is not None:
        progress(size, size)
    return soup


@contextmanager
def file_errors(path: str, doing: str) -> Iterator[None]:
    """The OS's refusal of a file inside the block as `InvalidInputError`: ``"cannot {doing} {path}: {reason}"``.

    A missing file or folder, a folder where a file should be, no
    permission, a full disk: the file a caller named cannot be used, which
    is bad input like a malformed file. The `OSError` is the ``__cause__``.

    Examples
    --------
    >>> with file_errors("/no/such/folder/x.off", "write"):
    ...     open("/no/such/folder/x.off", "wb")
    Traceback (most recent call last):
    ...
    hestore.errors.InvalidInputError: cannot write /no/such/folder/x.off: No such file or directory
    """
    try:
        yield
    except OSError as exc:
        raise InvalidInputError(f"cannot {doing} {path}: {exc.strerror or exc}") from exc


@contextmanager
def created(path: str | os.PathLike) -> Iterator[BinaryIO]:
    """``path`` opened for writing, created or emptied; the path checked and the OS's refusals typed."""
    name = check_path(path)
    with file_errors(name, "write"), open(name, "wb") as f:
        yield f


class RowProgress:
    """A writer's progress, counted in vertices and polygons written."""

    def __init__(self, progress: Progress | None, positions: np.ndarray, offsets: np.ndarray) -> None:
        self.progress = progress
        self.total = len(positions) + len(offsets) - 1

    def __call__(self, done: int) -> None:
        if self.progress is not None:
            self.progress(done, self.total)

    def finish(self) -> None:
        self(self.total)


# --------------------------------------------------------------------------
# Errors and small helpers


def error(path: str, where, what: str) -> InvalidInputError:
    return InvalidInputError(f"{path}:{where}: {what}")


def empty(path: str, line: int, expected: str) -> InvalidInputError:
    """The refusal of a file with nothing in it, worded alike by every reader.

    The one rule for all formats: a file with no bytes, or only whitespace
    and comments, holds no mesh — not even an empty one — and is refused; a
    file that declares zero vertices and faces (``OFF 0 0 0``, PLY elements
    of count 0, OBJ statements without a vertex) is an empty mesh.
    """
    return error(path, line, f"the file is empty (nothing but whitespace or comments): expected {expected}")


# The most characters of a file's content that a message quotes.
SHOWN = 40


def _escape(code: int) -> str:
    """How `show` writes a byte: printable ASCII as itself, any other as ``repr`` escapes it."""
    char = chr(code)
    if char in "\\'":
        return "\\" + char
    return char if 0x20 <= code < 0x7F else ascii(char)[1:-1]


def show(piece: bytes) -> str:
    """A piece of a file as messages quote it: escaped to printable ASCII, and cut short.

    Every reader quotes what it found through here, so that a message stays
    one short printable line whatever the file holds (a binary blob, terminal
    escape sequences, a runaway number). ``repr``-like: printable ASCII is
    kept and every other byte is an escape (``\\x00``, ``\\n``, ``\\xff``). At
    most `SHOWN` characters are quoted, each escape whole; what is cut is
    followed by ``...`` and the size of the whole.

    Examples
    --------
    >>> print(show(b"zero"), show(b"\\x1b[31m\\x00\\xff"), show("café".encode()))
    'zero' '\\x1b[31m\\x00\\xff' 'caf\\xc3\\xa9'
    >>> print(show(b"9" * 5000))
    '9999999999999999999999999999999999999999'... (5000 bytes)
    """
    out: list[str] = []
    used = 0
    # No escape is shorter than one character: SHOWN bytes are all that can be quoted.
    for code in piece[:SHOWN]:
        text = _escape(code)
        if used + len(text) > SHOWN:
            break
        out.append(text)
        used += len(text)
    quoted = "'" + "".join(out) + "'"
    return quoted if len(out) == len(piece) else f"{quoted}... ({len(piece)} bytes)"


def named(name: bytes) -> str:
    """A name from a file's header (a PLY element or property) as messages use it unquoted.

    The name itself when it is a short word of printable ASCII, as names are;
    any other is quoted by `show`.
    """
    if 0 < len(name) <= SHOWN and all(0x20 < code < 0x7F for code in name):
        return name.decode("ascii")
    return show(name)


def ranges(starts: np.ndarray, lengths: np.ndarray, step: int = 1) -> np.ndarray:
    """The concatenation of ``arange(s, s + n * step, step)`` for every ``(s, n)``."""
    total = int(lengths.sum())
    if total == 0:
        return np.empty(0, dtype=np.int64)
    within = np.arange(total, dtype=np.int64) - np.repeat(np.cumsum(lengths) - lengths, lengths)
    return np.repeat(starts, lengths) + within * step


def token_starts(buf: np.ndarray) -> np.ndarray:
    """Positions of the bytes that start a whitespace-separated token."""
    ws = WS[buf]
    start = ~ws
    start[1:] &= ws[:-1]
    return np.flatnonzero(start)


def parse(text, total: int, dtype) -> np.ndarray | None:
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


def coordinate(token: bytes, path: str, line: int) -> float:
    try:
        value = float(token)
    except ValueError:
        raise error(path, line, f"expected a number, found {show(token)}") from None
    if not math.isfinite(value):
        raise error(path, line, f"coordinate {show(token)} is not finite")
    return value


def integer(token: bytes, path: str, line: int, what: str) -> int:
    try:
        value = int(token)
    except ValueError:
        raise error(path, line, f"{what} {show(token)} is not an integer") from None
    # The vectorised reader saturates at the int64 limits; so does this one.
    return min(max(value, INT64_MIN), INT64_MAX)


def count(token: bytes, path: str, line: int, what: str) -> int:
    """A header's record count: a non-negative integer that fits in int64.

    Stricter than `integer`: no saturation (the count shown in a later
    message is the one in the file) and no sign, underscores or non-ASCII
    digits, which Python's ``int`` would take.
    """
    digits = token[1:] if token[:1] == b"-" else token
    if not digits.isdigit():  # bytes.isdigit: ASCII digits only
        raise error(path, line, f"{what} {show(token)} is not an integer")
    if digits is not token:
        raise error(path, line, f"{what} {show(token)} is negative")
    significant = digits.lstrip(b"0")
    # Checked by length first: int() of thousands of digits is slow, and past
    # 4300 digits it raises a ValueError of its own.
    if len(significant) > 19 or int(significant or b"0") > INT64_MAX:
        raise error(path, line, f"{what} {show(token)} is too large")
    return int(significant or b"0")


def check_room(path: str, line: int, records: int, what: str, room: int, per_record: int, slack: int = 0) -> None:
    """Refuse ``records`` records of at least ``per_record`` bytes each in ``room`` (+ ``slack``) bytes.

    Header counts are never trusted: a count checked here cannot make a
    reader allocate or loop beyond a small multiple of the file's size.
    """
    if records * per_record > room + slack:
        left = max(room, 0)
        raise error(path, line, f"{records} {what} cannot fit in the {left} bytes left (each needs {per_record})")


# The fewest bytes a record of a text file takes: a character and a line
# break. The last line may lack its line break: text callers pass slack=1.
TEXT_RECORD_BYTES = 2


def whole(token: bytes, path: str, line: int, what: str) -> int:
    """An integer, also written as an integral float (``3.0``), as OFF and PLY writers sometimes do."""
    try:
        return integer(token, path, line, what)
    except InvalidInputError:
        try:
            value = float(token)
        except ValueError:
            value = math.nan
        if not (math.isfinite(value) and value == math.floor(value) and abs(value) < 2.0**63):
            raise
        return int(value)


class Polygons:
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

    def soup(self, positions: list[np.ndarray], text: bool = True, **properties) -> PolygonSoup:
        """The soup of the polygons gathered; ``properties`` are `PolygonSoup`'s property dicts."""
        counts = joined(self.counts, np.int64)
        offsets = np.zeros(len(counts) + 1, dtype=np.int64)
        np.cumsum(counts, out=offsets[1:])
        lines = joined(self.lines, np.int64) if text else None
        xyz = joined(positions, np.float64).reshape(-1, 3)
        return PolygonSoup(xyz, offsets, joined(self.indices, np.int64), lines, **properties)


def joined(parts: list[np.ndarray], dtype) -> np.ndarray:
    if len(parts) == 1:  # the usual case for small files: no copy
        return np.ascontiguousarray(parts[0], dtype=dtype)
    return np.concatenate(parts).astype(dtype, copy=False) if parts else np.empty(0, dtype)


# --------------------------------------------------------------------------
# Text files: chunks of whole lines


class TextFile:
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

    def chunks(self) -> Iterator[Chunk]:
        # The start of a line longer than a block, kept in pieces: joining
        # them once, when the line ends, keeps reading a file that is one
        # huge line linear rather than quadratic.
        pieces: list[bytes] = []
        held = 0
        while True:
            block = self.f.read(CHUNK_BYTES)
            if not block:
                break
            cut = block.rfind(b"\n") + 1
            if cut == 0:
                pieces.append(block)
                held += len(block)
                continue
            data = b"".join([*pieces, block[:cut]]) if pieces else block[:cut]
            pieces, held = ([block[cut:]], len(block) - cut) if cut < len(block) else ([], 0)
            yield self._chunk(self._strip_bom(data))
            if self.progress is not None:
                self.progress(self.f.tell() - held, self.size)
        if pieces:
            yield self._chunk(self._strip_bom(b"".join(pieces) + b"\n"))

    def _chunk(self, data: bytes) -> Chunk:
        chunk = Chunk(data, self.line)
        self.line += len(chunk.ends)
        return chunk

    @property
    def last_line(self) -> int:
        return max(self.line - 1, 1)


class Chunk:
    """Whole lines of text as a byte array, with the position of every token.

    ``buf`` is a private, writable copy of ``data``: the vectorised readers
    blank out what they do not want parsed (comments, keywords, slashes),
    while the per-line reader works on the untouched ``data``.
    """

    def __init__(self, data: bytes, line0: int) -> None:
        self.data = data
        self.line0 = line0
        self.buf = np.frombuffer(data, dtype=np.uint8).copy()
        self.ends = np.flatnonzero(self.buf == NEWLINE)
        self.starts = np.empty_like(self.ends)
        self.starts[:1] = 0
        self.starts[1:] = self.ends[:-1] + 1

    def strip_comments(self) -> None:
        """Blank every ``#`` and the rest of its line."""
        hashes = np.flatnonzero(self.buf == HASH)
        if hashes.size == 0:
            return
        line = np.searchsorted(self.ends, hashes)
        first = np.ones(len(hashes), dtype=bool)
        first[1:] = line[1:] != line[:-1]
        hashes, line = hashes[first], line[first]
        self.buf[ranges(hashes, self.ends[line] - hashes)] = SPACE

    def tokenize(self) -> None:
        """Find every token: ``ntokens[i]`` per line, ``first[i]`` its first in ``tokens``."""
        self.tokens = token_starts(self.buf)
        self.first = np.searchsorted(self.tokens, self.starts)
        self.ntokens = np.searchsorted(self.tokens, self.ends) - self.first

    def text(self, lines: np.ndarray) -> np.ndarray:
        """The bytes of ``lines`` (sorted), newlines kept, without other lines' tokens."""
        a, b = lines[0], lines[-1]
        if np.count_nonzero(self.ntokens[a : b + 1]) == len(lines):
            return self.buf[self.starts[a] : self.ends[b] + 1]
        starts = self.starts[lines]
        return self.buf[ranges(starts, self.ends[lines] + 1 - starts)]

    def line_tokens(self, lines: np.ndarray, comments: bool) -> Iterator[tuple[int, list[bytes]]]:
        """``(line number, tokens)`` of ``lines``, read from the untouched text."""
        data = self.data
        for i, s, e in zip(lines.tolist(), self.starts[lines].tolist(), self.ends[lines].tolist()):
            raw = data[s:e]
            if comments:
                raw = raw.split(b"#", 1)[0]
            yield self.line0 + i, raw.split()


def first3(values: np.ndarray, counts: np.ndarray) -> np.ndarray | None:
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


def columns(values: np.ndarray, counts: np.ndarray, width: int, cols) -> np.ndarray | None:
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


def count_prefixed(values, counts, lead: int, trail: int, exact: bool):
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
    k = as_integers(values[row + lead])
    # A count beyond the row's length is malformed, and refusing it here also
    # keeps ``need`` below from wrapping around for a count near 2**63.
    if k is None or (k < 0).any() or (k >= counts).any():
        return None
    need = lead + 1 + k + trail
    if ((counts != need) if exact else (counts < need)).any():
        return None
    k0, c0 = int(k[0]), int(counts[0])
    if (k == k0).all() and (counts == c0).all():
        chosen = values.reshape(n, c0)[:, lead + 1 : lead + 1 + k0].ravel()
    else:
        chosen = values[ranges(row + lead + 1, k)]
    indices = as_integers(chosen)
    return None if indices is None else (k, indices)


# --------------------------------------------------------------------------
# Line-sectioned text (OFF, ASCII PLY): runs of lines of one kind each


class RecordLayout(Protocol):
    """What the sections need to know of an ASCII PLY element's records (`hestore.io.ply`)."""

    properties: list
    has_lists: bool
    xyz_columns: tuple[int | None, ...]
    index_list: int | None
    simple_list: tuple[int, int] | None
    carried: list[Carried]

    def parse_record(self, tokens: list[bytes], path: str, line: int) -> list: ...


class Section:
    """``count`` consecutive content lines of one kind."""

    def __init__(self, count: int) -> None:
        self.count = count
        self.remaining = count

    def take(self, chunk: Chunk, lines: np.ndarray, src: TextFile, comments: bool) -> None:
        self.remaining -= len(lines)
        text = chunk.text(lines)
        counts = chunk.ntokens[lines]
        if not self.fast(chunk, lines, text, counts):
            self.slow(chunk.line_tokens(lines, comments), src.path, chunk.line0 + lines)


class Skip(Section):
    what = "records"

    def fast(self, chunk, lines, text, counts) -> bool:
        return True


class Positions(Section):
    """Vertex lines: OFF (``layout=None``: x y [z] and anything after) or PLY records."""

    what = "vertices"

    def __init__(self, count: int, layout: RecordLayout | None = None) -> None:
        super().__init__(count)
        self.layout = layout
        self.parts: list[np.ndarray] = []
        self.carried = [] if layout is None else layout.carried
        self.carried_parts: list[list] = [[] for _ in self.carried]

    def fast(self, chunk, lines, text, counts) -> bool:
        if self.layout is not None and self.layout.has_lists:
            return False
        values = parse(text, int(counts.sum()), np.float64)
        if values is None:
            return False
        if self.layout is None:
            xyz = first3(values, counts)
        else:
            width = len(self.layout.properties)
            xyz = columns(values, counts, width, self.layout.xyz_columns)
            if xyz is not None and self.carried:
                row = np.arange(len(counts)) * width
                found = carried_columns(self.carried, values, lambda column: row + column)
                if found is None:
                    return False
                for parts, column in zip(self.carried_parts, found):
                    parts.append(column)
        if xyz is None or not np.isfinite(xyz).all():
            return False
        self.parts.append(xyz)
        return True

    def slow(self, rows, path, numbers) -> None:
        xyz = []
        carried = [[] for _ in self.carried]
        for line, tokens in rows:
            if self.layout is not None:
                record = self.layout.parse_record(tokens, path, line)
                coords = [0.0 if col is None else record[col] for col in self.layout.xyz_columns]
                if not all(map(math.isfinite, coords)):
                    raise error(path, line, f"vertex {coords} has a non-finite coordinate")
                xyz.append(coords)
                for values, c in zip(carried, self.carried):
                    values.append(record[c.column])
            elif len(tokens) < 2:
                raise error(path, line, f"a vertex needs at least 2 coordinates, found {len(tokens)}")
            else:
                coords = [coordinate(t, path, line) for t in tokens[:3]]
                xyz.append(tuple(coords) if len(coords) == 3 else (*coords, 0.0))
        self.parts.append(np.array(xyz, dtype=np.float64).reshape(-1, 3))
        for parts, values in zip(self.carried_parts, carried):
            parts.append(values)

    def properties(self) -> dict[str, np.ndarray]:
        """The carried properties of every vertex read, by name."""
        return carried_arrays(self.carried, self.carried_parts)


class Faces(Section):
    """Face lines: OFF (``layout=None``: k i_1 .. i_k, colours ignored) or PLY records."""

    what = "faces"

    def __init__(self, count: int, polygons: Polygons, layout: RecordLayout | None = None) -> None:
        super().__init__(count)
        self.polygons = polygons
        self.layout = layout
        self.carried = [] if layout is None else layout.carried
        self.carried_parts: list[list] = [[] for _ in self.carried]

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
        # some other value on the lines (a colour, a quality) needs them, or
        # when a float property is kept (int64 parsing reads -0 as 0).
        values = None
        if not any(c.bounds is None for c in self.carried):
            values = parse(text, total, np.int64)
        if values is None:
            values = parse(text, total, np.float64)
        found = None if values is None else count_prefixed(values, counts, lead, trail, exact)
        if found is None:
            return False
        if self.carried:
            # A scalar after the index list is k items further along its row.
            row, k = np.cumsum(counts) - counts, found[0]
            taken = carried_columns(
                self.carried, values, lambda column: row + column if column < lead else row + column + k
            )
            if taken is None:
                return False
            for parts, column in zip(self.carried_parts, taken):
                parts.append(column)
        self.polygons.add(found[0], found[1], chunk.line0 + lines)
        return True

    def slow(self, rows, path, numbers) -> None:
        counts, indices = [], []
        carried = [[] for _ in self.carried]
        for line, tokens in rows:
            if self.layout is not None:
                record = self.layout.parse_record(tokens, path, line)
                polygon = record[self.layout.index_list]
                for values, c in zip(carried, self.carried):
                    values.append(record[c.column])
            else:
                k = whole(tokens[0], path, line, "vertex count")
                if k < 0:
                    raise error(path, line, f"negative vertex count {k}")
                if len(tokens) < k + 1:
                    raise error(path, line, f"face of {k} vertices has only {len(tokens) - 1} indices")
                polygon = [whole(t, path, line, "vertex index") for t in tokens[1 : k + 1]]
            counts.append(len(polygon))
            indices.extend(polygon)
        self.polygons.add(counts, indices, numbers)
        for parts, values in zip(self.carried_parts, carried):
            parts.append(values)

    def properties(self) -> dict[str, np.ndarray]:
        """The carried properties of every polygon read, by name."""
        return carried_arrays(self.carried, self.carried_parts)


def read_sections(src: TextFile, sections: list[Section], comments: bool) -> None:
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
        raise error(src.path, src.last_line, f"file ends after {s.count - s.remaining} of {s.count} {s.what}")


# --------------------------------------------------------------------------
# Writing


def checked_arrays(positions, offsets, indices):
    positions = np.asarray(positions, dtype=np.float64)
    if positions.ndim != 2 or positions.shape[1] != 3:
        if positions.size == 0:
            positions = positions.reshape(0, 3)
        else:
            raise InvalidInputError(f"positions must have shape (V, 3), not {positions.shape}")
    if not np.isfinite(positions).all():
        bad = int(np.argmin(np.isfinite(positions).all(axis=1)))
        raise InvalidInputError(f"position {bad} is not finite: {positions[bad].tolist()}")
    offsets = integer_array(offsets, "offsets")
    indices = integer_array(indices, "indices")
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


def integer_array(values, name: str) -> np.ndarray:
    array = np.asarray(values)
    if array.size == 0:
        return array.astype(np.int64).reshape(-1)
    if array.ndim != 1 or array.dtype.kind not in "iu":
        raise InvalidInputError(f"{name} must be a 1-D array of integers, not {array.dtype} of shape {array.shape}")
    return array.astype(np.int64, copy=False)


def write_text_rows(
    f, positions, offsets, indices, vertex_prefix, keyword, base, report, vertex_extra=(), polygon_extra=()
) -> None:
    """Vertex lines, then polygon lines (``keyword`` or, if None, the vertex count first).

    ``vertex_extra`` and ``polygon_extra`` are 1-D int64 or float64 arrays,
    one value per vertex (polygon) each, written after its coordinates
    (indices) in order.
    """
    write_number_rows(f, positions, vertex_prefix, report, vertex_extra)
    n = len(positions)
    counts = np.diff(offsets)
    for lo in range(0, len(counts), WRITE_ROWS):
        hi = min(lo + WRITE_ROWS, len(counts))
        values = indices[offsets[lo] : offsets[hi]] + base
        extra = [e[lo:hi] for e in polygon_extra]
        f.write(polygon_lines(counts[lo:hi], values, keyword, extra).encode())
        report(n + hi)


def write_number_rows(f, rows: np.ndarray, prefix: str, report=None, extra=()) -> None:
    """One line per row of ``rows`` (then of the 1-D ``extra`` arrays): ``prefix`` and its numbers.

    Numbers are written as ``%r``: Python's shortest repr that reads back as
    the same double (and an int's digits).
    """
    for lo in range(0, len(rows), WRITE_ROWS):
        block = rows[lo : lo + WRITE_ROWS]
        if extra:
            table = np.empty((len(block), block.shape[1] + len(extra)), dtype=object)
            for j, column in enumerate([*block.T, *(e[lo : lo + WRITE_ROWS] for e in extra)]):
                table[:, j] = column.tolist()
            values = table.ravel().tolist()
        else:
            values = block.ravel().tolist()
        row = prefix + " ".join(["%r"] * (block.shape[1] + len(extra))) + "\n"
        f.write(((row * len(block)) % tuple(values)).encode())
        if report is not None:
            report(lo + len(block))


def polygon_lines(counts: np.ndarray, values: np.ndarray, keyword: str | None, extra=()) -> str:
    """Polygon lines: ``keyword`` (or the count), the indices, then one value of each ``extra`` array."""
    arities, which = np.unique(counts, return_inverse=True)
    tail = " %r" * len(extra) + "\n"
    templates = [(keyword or str(k)) + " %d" * k + tail for k in arities.tolist()]
    if len(templates) == 1:
        template = templates[0] * len(counts)
    else:
        # One template per polygon, picked by arity, so that mixed arities
        # still take a single formatting pass.
        template = "".join(np.array(templates, dtype=object)[which.reshape(-1)].tolist())
    if not extra:
        return template % tuple(values.tolist())
    # Each polygon's indices, then its extra values, in one flat sequence.
    c = len(extra)
    starts = np.cumsum(counts) - counts + np.arange(len(counts)) * c
    flat = np.empty(len(values) + len(counts) * c, dtype=object)
    flat[ranges(starts, counts)] = values.tolist()
    for j, column in enumerate(extra):
        flat[starts + counts + j] = column.tolist()
    return template % tuple(flat.tolist())

