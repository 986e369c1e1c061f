"""PLY (Polygon File Format, Stanford): reading and writing.

What the reader accepts: ``ascii``, ``binary_little_endian`` and
``binary_big_endian``, every scalar type under its classic and its sized name
(``uchar``/``uint8``, ``float``/``float32``, ...). The ``vertex`` element
needs x and y (z is optional); its other scalar properties (colours,
normals, quality, ...) become `PolygonSoup.vertex_properties` of the same
names. The ``face`` element needs a ``vertex_indices`` (or ``vertex_index``)
list; its other scalar properties become `PolygonSoup.polygon_properties`.
Integer types give int64 arrays, ``float`` and ``double`` float64 ones; in
ASCII, a value of an integer property must be an integer (``3.0`` is taken)
within its type's range. Property names must be unique within the vertex
and face elements. List properties other than the index list are skipped.
Other elements (``edge``, ``material``, even
``tristrips``) are skipped, as are ``comment`` and ``obj_info`` lines. A file
without a ``face`` element is a point set: positions and no polygons; one
with neither a ``vertex`` nor a ``face`` element is empty, as OpenMesh reads
it, and so is one whose elements have counts of 0; a file with no header at
all (no bytes, or only whitespace) is refused as empty. Element counts are at
most 2**63 - 1 and must fit in the bytes after the header (ASCII: a line of
at least two bytes per record; binary: checked element by element against
the bytes that remain). Names from the header are quoted in messages as
`hestore.io.common.named` writes them.

ASCII PLY is read like OFF, as sections of lines (`hestore.io.common`).
Binary elements whose lists all have the same length are read as one
structured array; otherwise the records are walked one by one to find where
each starts. Errors in binary data name the byte offset of the record:
``"{path}:byte {offset}: {what}"``. Binary faces carry no line numbers:
their `PolygonSoup.lines` is None.

The writer writes binary little endian (or ASCII) PLY with double x, y, z
and an ``int`` ``vertex_indices`` list whose count type is ``uchar`` unless
some polygon has more than 255 vertices. Vertex and polygon properties
follow x, y, z and the index list: float arrays as ``double``, integer
arrays as ``int`` (every value must fit in 32 bits), bool arrays as
``uchar`` 0/1. An array of shape ``(n, k)`` becomes the ``k`` properties
``{name}_0`` .. ``{name}_{k-1}``, and is read back as those ``k`` arrays.
"""

from __future__ import annotations

import os
import struct
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from hestore.errors import InvalidInputError
from hestore.io import common
from hestore.io.common import (
    TEXT_RECORD_BYTES,
    Carried,
    Faces,
    Polygons,
    PolygonSoup,
    Positions,
    Progress,
    RowProgress,
    Section,
    Skip,
    TextFile,
    check_room,
    checked_arrays,
    count,
    created,
    empty,
    error,
    named,
    ranges,
    read_file,
    read_sections,
    show,
    whole,
    write_text_rows,
)

__all__ = ["read_ply", "write_ply"]


def read_ply(path: str | os.PathLike, *, progress: Progress | None = None) -> PolygonSoup:
    """Read an ASCII or binary PLY file as it is stored, whatever its extension.

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
        Positions and polygons in the file's order; the line of each polygon
        for ASCII PLY, None for binary PLY; the other scalar properties of
        vertices and faces as its ``vertex_properties`` and
        ``polygon_properties``.

    Raises
    ------
    InvalidInputError
        A malformed file; the message is ``"{path}:{line}: {what}"``, or
        ``"{path}:byte {offset}: {what}"`` in binary data.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> folder = tempfile.TemporaryDirectory()
    >>> path = pathlib.Path(folder.name) / "segment.ply"
    >>> header = "ply\\nformat ascii 1.0\\nelement vertex 2\\nproperty float x\\nproperty float y\\n"
    >>> header += "element face 1\\nproperty list uchar int vertex_indices\\nend_header\\n"
    >>> _ = path.write_text(header + "0 0\\n1 0.5\\n2 0 1\\n")
    >>> soup = read_ply(path)
    >>> soup.positions.tolist(), soup.indices, soup.lines
    ([[0.0, 0.0, 0.0], [1.0, 0.5, 0.0]], array([0, 1]), array([11]))
    >>> _ = path.write_text(header + "0 0\\n1 0.5\\n2 0\\n")
    >>> read_ply(path)
    Traceback (most recent call last):
    ...
    hestore.errors.InvalidInputError: .../segment.ply:11: vertex_indices of 2 items has only 1
    >>> coloured = header.replace("property float y\\n", "property float y\\nproperty uchar red\\n")
    >>> _ = path.write_text(coloured + "0 0 255\\n1 0.5 7\\n2 0 1\\n")
    >>> soup = read_ply(path)
    >>> soup
    PolygonSoup(vertices=2, polygons=1, vertex properties: red)
    >>> soup.vertex_properties["red"]
    array([255,   7])
    >>> folder.cleanup()
    """
    return read_file(path, progress, _read)


def write_ply(
    path: str | os.PathLike,
    positions,
    offsets,
    indices,
    *,
    binary: bool = True,
    progress: Progress | None = None,
    vertex_properties: Mapping | None = None,
    polygon_properties: Mapping | None = None,
) -> None:
    """Write vertex positions and polygons, with per-element data, as a PLY file.

    Positions and float properties are written as doubles — in ASCII, in
    their shortest round-trip form — so reading the file back gives exactly
    the same arrays.

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
        Binary little endian, or ASCII with ``binary=False``.
    progress : callable, optional
        Called as ``progress(done, total)`` now and then, counting vertices
        and polygons written, and at least once at the end.
    vertex_properties : mapping of str to array_like, optional
        Per-vertex data, each of shape ``(V,)`` or ``(V, k)``, written after
        x, y, z in the mapping's order: float arrays as ``double``, integer
        ones as ``int``, bool ones as ``uchar``. A ``(V, k)`` array becomes
        the properties ``{name}_0`` .. ``{name}_{k-1}``, which is how
        `read_ply` gives it back.
    polygon_properties : mapping of str to array_like, optional
        Per-polygon data, each of shape ``(F,)`` or ``(F, k)``, written after
        the index list, as for ``vertex_properties``.

    Raises
    ------
    InvalidInputError
        Arrays that do not describe polygons on these vertices, or more than
        2**31 vertices (the indices are written as ``int``); a property name
        that is not a PLY word (printable ASCII, no spaces) or that is taken
        (x, y, z; vertex_indices, vertex_index; another property's); a
        property of the wrong length or type, or an integer one with a value
        beyond 32 bits. Nothing is written then.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> folder = tempfile.TemporaryDirectory()
    >>> path = pathlib.Path(folder.name) / "segment.ply"
    >>> write_ply(path, [(0, 0, 0), (1, 0.5, 0)], [0, 2], [0, 1], binary=False)
    >>> print(path.read_text(), end="")
    ply
    format ascii 1.0
    element vertex 2
    property double x
    property double y
    property double z
    element face 1
    property list uchar int vertex_indices
    end_header
    0.0 0.0 0.0
    1.0 0.5 0.0
    2 0 1
    >>> write_ply(path, [(0, 0, 0)], [0, 1], [1])
    Traceback (most recent call last):
    ...
    hestore.errors.InvalidInputError: polygon 0 has vertex index 1, out of range for 1 vertices
    >>> write_ply(path, [(0, 0, 0), (1, 0.5, 0)], [0, 2], [0, 1], binary=False,
    ...           vertex_properties={"uv": [(0.25, 1), (0.5, 0)]}, polygon_properties={"label": [7]})
    >>> print(path.read_text(), end="")
    ply
    format ascii 1.0
    element vertex 2
    property double x
    property double y
    property double z
    property double uv_0
    property double uv_1
    element face 1
    property list uchar int vertex_indices
    property int label
    end_header
    0.0 0.0 0.0 0.25 1.0
    1.0 0.5 0.0 0.5 0.0
    2 0 1 7
    >>> sorted(read_ply(path).vertex_properties)
    ['uv_0', 'uv_1']
    >>> write_ply(path, [(0, 0, 0)], [0, 1], [0], polygon_properties={"vertex_indices": [1]})
    Traceback (most recent call last):
    ...
    hestore.errors.InvalidInputError: face property name 'vertex_indices' is taken by the index list
    >>> folder.cleanup()
    """
    positions, offsets, indices = checked_arrays(positions, offsets, indices)
    if len(positions) > 2**31:
        raise InvalidInputError("PLY files written here hold at most 2**31 vertices (int vertex indices)")
    vertex_columns = _property_columns(vertex_properties, len(positions), "vertex", _VERTEX_WORDS)
    face_columns = _property_columns(polygon_properties, len(offsets) - 1, "face", _FACE_WORDS)
    report = RowProgress(progress, positions, offsets)
    with created(path) as f:
        if binary:
            _write_binary(f, positions, offsets, indices, report, vertex_columns, face_columns)
        else:
            f.write(_header("ascii", positions, offsets, vertex_columns, face_columns))
            vertex_extra = [values for _, _, values in vertex_columns]
            face_extra = [values for _, _, values in face_columns]
            write_text_rows(f, positions, offsets, indices, "", None, 0, report, vertex_extra, face_extra)
    report.finish()


# --------------------------------------------------------------------------
# The header


_TYPES = {
    "char": "i1", "int8": "i1",
    "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2",
    "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4",
    "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4",
    "double": "f8", "float64": "f8",
}  # fmt: skip

_FORMATS = {"ascii": None, "binary_little_endian": "<", "binary_big_endian": ">"}


class _Named:
    raw: bytes

    @property
    def label(self) -> str:
        """The name as messages write it: itself, or quoted and escaped if it is not a plain word."""
        return named(self.raw)


@dataclass
class _Property(_Named):
    name: str
    type: str  # numpy type code of the value, or of the list items
    count_type: str | None = None  # numpy type code of a list's count
    raw: bytes = b""  # the name as the file has it, for messages

    @property
    def is_list(self) -> bool:
        return self.count_type is not None


@dataclass
class _Element(_Named):
    name: str
    count: int
    line: int
    properties: list[_Property]
    raw: bytes = b""  # the name as the file has it, for messages

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

    @cached_property
    def carried(self) -> list[Carried]:
        """The scalar properties kept as per-element data: all but x, y, z of vertices and the face index list.

        Read once the header is complete.
        """
        if self.name == "vertex":
            taken = set(self.xyz_columns)
        elif self.name == "face":
            taken = {self.index_list}
        else:
            return []
        kept = []
        for i, p in enumerate(self.properties):
            if not p.is_list and i not in taken:
                bounds = None if p.type[0] == "f" else (int(np.iinfo(p.type).min), int(np.iinfo(p.type).max))
                kept.append(Carried(i, p.name, bounds))
        return kept

    @cached_property
    def _integers(self) -> dict[int, Carried]:
        return {c.column: c for c in self.carried if c.bounds is not None}

    def parse_record(self, tokens: list[bytes], path: str, line: int) -> list:
        """One ASCII record, property by property: numbers, and lists (of ints for the index list).

        Numbers are floats, except for carried integer properties: ints
        within their type's range.
        """
        record: list = []
        at = 0
        integers = self._integers
        for i, prop in enumerate(self.properties):
            if at >= len(tokens):
                raise error(path, line, f"{self.label} record ends before its property {show(prop.raw)}")
            if not prop.is_list:
                if i in integers:
                    record.append(_int_value(tokens[at], path, line, prop, integers[i].bounds))
                else:
                    record.append(_float_value(tokens[at], path, line))
                at += 1
            else:
                k = whole(tokens[at], path, line, f"{prop.label} count")
                if k < 0:
                    raise error(path, line, f"negative {prop.label} count {k}")
                items = tokens[at + 1 : at + 1 + k]
                if len(items) < k:
                    raise error(path, line, f"{prop.label} of {k} items has only {len(items)}")
                if i == self.index_list and self.name == "face":
                    record.append([whole(t, path, line, "vertex index") for t in items])
                else:
                    record.append([_float_value(t, path, line) for t in items])
                at += 1 + k
        if at != len(tokens):
            raise error(path, line, f"{self.label} record has {len(tokens) - at} values more than its properties")
        return record


def _float_value(token: bytes, path: str, line: int) -> float:
    try:
        return float(token)
    except ValueError:
        raise error(path, line, f"expected a number, found {show(token)}") from None


def _int_value(token: bytes, path: str, line: int, prop: _Property, bounds: tuple[int, int]) -> int:
    value = whole(token, path, line, f"{prop.label} value")
    if not bounds[0] <= value <= bounds[1]:
        name = next(k for k, v in _TYPES.items() if v == prop.type)
        raise error(path, line, f"{prop.label} value {show(token)} is out of range for {name}")
    return value


def _text(token: bytes) -> str:
    return token.decode("ascii", "replace")


def _read_header(f, path: str):
    """``(elements, byte order or None for ASCII, number of the first body line)``."""
    raw = f.readline()
    if raw.strip() != b"ply":
        if not raw.strip():
            rest = TextFile(f, path, 0, None, line=2)
            if rest.content_line(comments=False) is None:
                raise empty(path, rest.last_line, "the first line 'ply'")
        raise error(path, 1, "not a PLY file: the first line must be 'ply'")
    order = False
    elements: dict[str, _Element] = {}
    number = 1
    while True:
        raw = f.readline()
        number += 1
        if not raw:
            raise error(path, number - 1, "file ends inside the PLY header (no end_header)")
        # Split as bytes, as the body is; messages quote these raw words.
        words = raw.split()
        if not words or words[0] in (b"comment", b"obj_info"):
            continue
        key = words[0]
        if key == b"end_header":
            break
        if key == b"format":
            if len(words) != 3 or _text(words[1]) not in _FORMATS:
                raise error(path, number, f"unknown PLY format {show(b' '.join(words[1:]))}")
            order = _FORMATS[_text(words[1])]
        elif key == b"element":
            if len(words) != 3:
                raise error(path, number, "expected 'element <name> <count>'")
            name = _text(words[1])
            if name in elements:
                raise error(path, number, f"element {show(words[1])} is declared twice")
            n = count(words[2], path, number, f"element {named(words[1])} count")
            elements[name] = last = _Element(name, n, number, [], words[1])
        elif key == b"property":
            if not elements:
                raise error(path, number, "property before any element")
            last.properties.append(_property(words, path, number))
        else:
            raise error(path, number, f"unknown PLY header keyword {show(key)}")
    if order is False:
        raise error(path, number, "the PLY header has no format line")
    _check_elements(elements, path)
    return list(elements.values()), order, number + 1


def _property(words: list[bytes], path: str, number: int) -> _Property:
    def type_of(word: bytes) -> str:
        name = _text(word)
        if name not in _TYPES:
            raise error(path, number, f"unknown PLY property type {show(word)}")
        return _TYPES[name]

    if len(words) == 5 and words[1] == b"list":
        count_type = type_of(words[2])
        if count_type[0] == "f":
            raise error(path, number, f"list count type must be an integer type, not {show(words[2])}")
        return _Property(_text(words[4]), type_of(words[3]), count_type, words[4])
    if len(words) == 3 and words[1] != b"list":
        return _Property(_text(words[2]), type_of(words[1]), raw=words[2])
    raise error(path, number, "expected 'property <type> <name>' or 'property list <count type> <type> <name>'")


def _check_elements(declared: dict[str, _Element], path: str) -> None:
    vertex = declared.get("vertex")
    face = declared.get("face")
    if vertex is None:
        # Neither vertices nor faces is an empty mesh, as OpenMesh reads it.
        if face is not None:
            raise error(path, face.line, "the PLY header declares a face element but no vertex element")
        return
    for c in "xyz":
        at = vertex.position(c)
        if at is None and c != "z":
            raise error(path, vertex.line, f"the vertex element has no {c} property")
        if at is not None and vertex.properties[at].is_list:
            raise error(path, vertex.line, f"vertex property {c} is a list, not a number")
    if face is not None:
        at = face.index_list
        if at is None or not face.properties[at].is_list:
            raise error(path, face.line, "the face element has no vertex_indices list")
        if face.properties[at].type[0] == "f":
            raise error(path, face.line, "face vertex indices must have an integer type")
    # Their properties become arrays by name: a name used twice is ambiguous.
    for element in (vertex, face):
        if element is not None:
            names = [p.name for p in element.properties]
            twice = next((p for i, p in enumerate(element.properties) if p.name in names[:i]), None)
            if twice is not None:
                raise error(path, element.line, f"the {element.name} element has two properties {show(twice.raw)}")


# --------------------------------------------------------------------------
# Reading


def _read(f, path: str, size: int, progress: Progress | None) -> PolygonSoup:
    elements, order, body_line = _read_header(f, path)
    if order is None:
        room = size - f.tell()
        for e in elements:
            if e.properties:  # records of no properties take no line
                check_room(path, e.line, e.count, f"{e.label} records", room, TEXT_RECORD_BYTES, slack=1)
                room -= e.count * TEXT_RECORD_BYTES
        src = TextFile(f, path, size, progress, line=body_line)
        polygons = Polygons()
        vertices = faces = None
        sections: list[Section] = []
        for e in elements:
            if e.name == "vertex":
                vertices = Positions(e.count, e)
                sections.append(vertices)
            elif e.name == "face":
                faces = Faces(e.count, polygons, e)
                sections.append(faces)
            else:
                skip = Skip(e.count if e.properties else 0)
                skip.what = f"{e.label} records"
                sections.append(skip)
        read_sections(src, sections, comments=False)
        return polygons.soup(
            vertices.parts if vertices is not None else [],
            vertex_properties=vertices.properties() if vertices is not None else {},
            polygon_properties=faces.properties() if faces is not None else {},
        )
    return _read_binary(_BinaryFile(f, path, size, progress), elements, order)


# --------------------------------------------------------------------------
# Binary data


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

    def remaining(self) -> int:
        return max(self.size - self.f.tell(), 0)

    def records(self, dtype: np.dtype, n: int) -> tuple[np.ndarray, int]:
        """Up to ``n`` records (``dtype.itemsize > 0``); also how many were complete before the end of the file."""
        # No more than the rest of the file holds: the count comes from the
        # header, and allocating it unchecked is how a 10 KB file asks for 48 GiB.
        records = np.empty(min(n, self.remaining() // dtype.itemsize), dtype=dtype)
        raw = records.view(np.uint8)
        done = 0
        while done < raw.size:
            step = self.f.readinto(raw[done : done + common.CHUNK_BYTES])
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
        return k, self._gather(ranges(first, k, item.itemsize), item)

    def _gather(self, at: np.ndarray, dtype: np.dtype) -> np.ndarray:
        return self.buf[at[:, None] + np.arange(dtype.itemsize)].view(dtype).ravel()


def _read_binary(src: _BinaryFile, elements: list[_Element], order: str) -> PolygonSoup:
    polygons = Polygons()
    xyz = np.empty((0, 3))
    carried: dict[str, dict[str, np.ndarray]] = {"vertex": {}, "face": {}}
    for element in elements:
        if not element.properties:
            continue  # records of no bytes, however many
        records = _binary_element(src, element, order)
        if element.name == "vertex":
            xyz = np.zeros((element.count, 3))
            # Casting a signalling NaN sets the invalid flag; non-finite
            # coordinates are refused just below, with their byte offset.
            with np.errstate(invalid="ignore"):
                for j, col in enumerate(element.xyz_columns):
                    if col is not None:
                        xyz[:, j] = records.scalar(col)
            finite = np.isfinite(xyz).all(axis=1)
            if not finite.all():
                bad = int(np.argmin(finite))
                raise error(src.path, f"byte {records.byte(bad)}", f"vertex {bad} has a non-finite coordinate")
        elif element.name == "face":
            counts, indices = records.list(element.index_list)
            polygons.add(counts, indices.astype(np.int64))
        if element.name in carried:
            with np.errstate(invalid="ignore"):  # a signalling NaN, kept as the NaN it is
                carried[element.name] = {
                    c.name: records.scalar(c.column).astype(np.float64 if c.bounds is None else np.int64)
                    for c in element.carried
                }
    return polygons.soup(
        [xyz], text=False, vertex_properties=carried["vertex"], polygon_properties=carried["face"]
    )


def _binary_element(src: _BinaryFile, element: _Element, order: str) -> _Records:
    start = src.tell()
    n = element.count
    props = element.properties
    if not element.has_lists:
        dtype = np.dtype([(f"p{i}", order + p.type) for i, p in enumerate(props)])
        array, complete = src.records(dtype, n)
        if complete < n:
            where = f"byte {start + complete * dtype.itemsize}"
            raise error(src.path, where, f"file ends inside {element.label} {complete} of {n}")
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
            dtype = np.dtype(fields)
            if n * dtype.itemsize <= src.remaining():  # else the guess is wrong, or the file truncated
                array, complete = src.records(dtype, n)
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
            width = np.dtype(p.count_type)
            unpack = struct.Struct(order + width.char).unpack_from
            lists.append((unpack, width.itemsize, np.dtype(p.type).itemsize))
            fixed.append(0)
        else:
            fixed[-1] += np.dtype(p.type).itemsize
    head, tails = fixed[0], fixed[1:]
    # Every record takes at least its scalars and list counts, so walking one
    # record more than ``buf`` can hold is sure to find where it ends: the
    # walk, and its lists, stay within the data whatever the header says.
    smallest = head + sum(width for _, width, _ in lists) + sum(tails)
    limit = min(n, len(buf) // smallest + 1)
    starts = [0] * limit
    lengths = [[0] * limit for _ in lists]
    pos = r = 0
    try:
        if len(lists) == 1:
            (unpack, width, item), tail, ks = lists[0], tails[0], lengths[0]
            for r in range(limit):
                starts[r] = pos
                k = ks[r] = unpack(buf, pos + head)[0]
                pos += head + width + k * item + tail
        else:
            for r in range(limit):
                starts[r] = pos
                pos += head
                for j, (unpack, width, item) in enumerate(lists):
                    k = lengths[j][r] = unpack(buf, pos)[0]
                    pos += width + k * item + tails[j]
        r = limit
    except struct.error:
        pass  # record r starts past the end of the data
    for ks in lengths:
        negative = np.flatnonzero(np.array(ks[: r + 1]) < 0)
        if negative.size:
            i = int(negative[0])
            where = f"byte {start + starts[i]}"
            raise error(path, where, f"negative list count {ks[i]} in {element.label} {i}")
    if r < n or pos > len(buf):
        ends = starts[1 : r + 1] + ([pos] if r == limit else [])
        bad = next((i for i, e in enumerate(ends) if e > len(buf)), min(r, limit - 1))
        raise error(path, f"byte {start + starts[bad]}", f"file ends inside {element.label} {bad} of {n}")

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

# The names the writer uses itself, with what they are for.
_VERTEX_WORDS = {"x": "the positions", "y": "the positions", "z": "the positions"}
_FACE_WORDS = {"vertex_indices": "the index list", "vertex_index": "the index list"}

# PLY type and numpy type (little endian) of a written property column.
_WRITTEN = {"double": "<f8", "int": "<i4", "uchar": "u1"}


def _property_columns(named, n: int, element: str, words: dict[str, str]) -> list[tuple[str, str, np.ndarray]]:
    """``(name, PLY type, values)`` of every property written for one element, checked."""
    if named is None:
        return []
    if not isinstance(named, Mapping):
        raise InvalidInputError(f"{element} properties must map names to arrays, not be a {type(named).__name__}")
    columns: list[tuple[str, str, np.ndarray]] = []
    taken = dict(words)
    for name, values in named.items():
        if not (isinstance(name, str) and name and all("!" <= ch <= "~" for ch in name)):
            raise InvalidInputError(
                f"{element} property name {name!r} is not a PLY word (printable ASCII, no spaces, not empty)"
            )
        array = np.asarray(values)
        if array.ndim not in (1, 2) or len(array) != n or (array.ndim == 2 and array.shape[1] == 0):
            shape = f"({n},) or ({n}, k)"
            raise InvalidInputError(f"{element} property {name!r} must have shape {shape}, not {array.shape}")
        kind = array.dtype.kind
        if kind == "b":
            ply_type = "uchar"
        elif kind in "iu":
            if array.size and (array.min() < -(2**31) or array.max() > 2**31 - 1):
                raise InvalidInputError(
                    f"{element} property {name!r} has values beyond the 32 bits of a PLY int "
                    f"(from {array.min()} to {array.max()})"
                )
            ply_type = "int"
        elif kind == "f":
            ply_type = "double"
        else:
            raise InvalidInputError(f"{element} property {name!r} must be of numbers or bools, not {array.dtype}")
        array = array.astype(_WRITTEN[ply_type])
        if array.ndim == 1:
            split = [(name, array)]
        else:
            split = [(f"{name}_{j}", array[:, j]) for j in range(array.shape[1])]
        for column_name, column in split:
            if column_name in taken:
                raise InvalidInputError(f"{element} property name {column_name!r} is taken by {taken[column_name]}")
            taken[column_name] = f"property {name!r}"
            columns.append((column_name, ply_type, column))
    return columns


def _records(columns: list[tuple[str, str, np.ndarray]], n: int) -> np.ndarray:
    """The columns as one little-endian structured array of ``n`` records."""
    records = np.empty(n, dtype=[(f"p{j}", _WRITTEN[t]) for j, (_, t, _) in enumerate(columns)])
    for j, (_, _, values) in enumerate(columns):
        records[f"p{j}"] = values
    return records


def _list_count_type(counts: np.ndarray) -> str:
    """The smallest PLY list count type that holds every polygon's vertex count."""
    return "uchar" if len(counts) == 0 or counts.max() <= 255 else "uint"


def _header(fmt: str, positions: np.ndarray, offsets: np.ndarray, vertex_columns=(), face_columns=()) -> bytes:
    counts = np.diff(offsets)
    vertex_lines = "".join(f"property {t} {name}\n" for name, t, _ in vertex_columns)
    face_lines = "".join(f"property {t} {name}\n" for name, t, _ in face_columns)
    return (
        "ply\n"
        f"format {fmt} 1.0\n"
        f"element vertex {len(positions)}\n"
        "property double x\nproperty double y\nproperty double z\n"
        f"{vertex_lines}"
        f"element face {len(counts)}\n"
        f"property list {_list_count_type(counts)} int vertex_indices\n"
        f"{face_lines}"
        "end_header\n"
    ).encode("ascii")


def _write_binary(f, positions, offsets, indices, report, vertex_columns, face_columns) -> None:
    f.write(_header("binary_little_endian", positions, offsets, vertex_columns, face_columns))
    if vertex_columns:
        extra = _records(vertex_columns, len(positions))
        records = np.empty(len(positions), dtype=[("xyz", "<f8", (3,)), ("extra", extra.dtype)])
        records["xyz"] = positions
        records["extra"] = extra
        f.write(records.tobytes())
    else:
        f.write(positions.astype("<f8").tobytes())
    report(len(positions))
    counts = np.diff(offsets)
    if len(counts) == 0:
        return
    count_type = np.dtype("<" + _TYPES[_list_count_type(counts)])
    tail = _records(face_columns, len(counts))  # the properties after the index list
    k = int(counts[0])
    if (counts == k).all():
        fields = [("n", count_type), ("i", "<i4", (k,))]
        records = np.empty(len(counts), dtype=fields + ([("extra", tail.dtype)] if face_columns else []))
        records["n"] = k
        records["i"] = indices.reshape(-1, k)
        if face_columns:
            records["extra"] = tail
        f.write(records.tobytes())
    else:
        # Record i starts after i counts, i property tails and offsets[i] indices.
        cs, ts = count_type.itemsize, tail.dtype.itemsize
        out = np.empty(len(counts) * (cs + ts) + len(indices) * 4, dtype=np.uint8)
        record_at = np.arange(len(counts)) * (cs + ts) + offsets[:-1] * 4
        out[record_at[:, None] + np.arange(cs)] = counts.astype(count_type).view(np.uint8).reshape(-1, cs)
        polygon = np.repeat(np.arange(len(counts)), counts)
        item_at = (polygon + 1) * cs + polygon * ts + np.arange(len(indices)) * 4
        out[item_at[:, None] + np.arange(4)] = indices.astype("<i4").view(np.uint8).reshape(-1, 4)
        if ts:
            tail_at = record_at + cs + counts * 4
            out[tail_at[:, None] + np.arange(ts)] = tail.view(np.uint8).reshape(-1, ts)
        f.write(out.tobytes())
