"""OFF, OBJ and PLY reading and writing (`hestore.io`); no database needed.

Most text-file tests run three ways (the ``reader`` fixture): as a user calls
`formats.read`; with chunks of a few dozen bytes, so that every chunk
boundary, carried-over line and line-number offset is exercised; and with
the vectorised parser disabled, so that the per-line reader — the one that
names malformed lines — must give the same arrays and the same errors.
"""

from __future__ import annotations

import math
import os
import pathlib
import random
import re
import struct
import threading
import time
import tracemalloc
import warnings

import numpy as np
import pytest

from hestore import io as formats
from hestore.io import common
from hestore.io import ply as ply_module
from hestore.errors import InvalidInputError
from helpers import assert_read_refused, put
from meshes import require_shared_meshes, shared_meshes


def polygons(soup) -> list[list[int]]:
    return [soup.indices[a:b].tolist() for a, b in zip(soup.offsets[:-1].tolist(), soup.offsets[1:].tolist())]


def assert_soup(soup, positions, polys, lines="skip") -> None:
    assert soup.positions.dtype == np.float64 and soup.positions.shape == (len(positions), 3)
    assert soup.offsets.dtype == np.int64 and soup.indices.dtype == np.int64
    np.testing.assert_array_equal(soup.positions, np.array(positions, dtype=float).reshape(-1, 3))
    assert polygons(soup) == polys
    if lines is None:
        assert soup.lines is None
    elif lines != "skip":
        assert soup.lines.dtype == np.int64
        assert soup.lines.tolist() == lines


# -- format_of ----------------------------------------------------------------


def test_format_of_is_by_extension_case_insensitive():
    assert formats.FORMATS == ("off", "obj", "ply")
    assert [formats.format_of(p) for p in ["a.off", "b.OBJ", pathlib.Path("c/d.Ply")]] == ["off", "obj", "ply"]
    for bad in ["mesh.stl", "mesh", "mesh.obj.gz"]:
        with pytest.raises(InvalidInputError, match=r"unsupported file format.*\.off, \.obj, \.ply"):
            formats.format_of(bad)


# -- round trips --------------------------------------------------------------

# Floats whose text form is easy to get wrong, and polygons of every arity
# from 1 to 300 (more than a PLY uchar count holds).
AWKWARD = np.array(
    [
        [0.1, 1 / 3, -0.0],
        [1e-300, 1e300, -2.5],
        [math.pi, -math.e, 7.0],
        [0.30000000000000004, 5e-324, 123456789.12345679],
        [-1.7976931348623157e308, 2.2250738585072014e-308, 1e16],
        [1.0, 2.0, 3.0],
    ]
)
MIXED = [[0, 1, 2], [2, 3, 4, 0], [4], [1, 3], [5, 4, 3, 2, 1], [i % 6 for i in range(300)], [0, 0, 0]]


def ragged(polys):
    offsets = np.zeros(len(polys) + 1, dtype=np.int64)
    offsets[1:] = np.cumsum([len(p) for p in polys])
    return offsets, np.array([i for p in polys for i in p], dtype=np.int64)


def header_lines(path: pathlib.Path) -> int:
    data = path.read_bytes()
    return data[: data.index(b"end_header\n")].count(b"\n") + 1


@pytest.mark.parametrize("name, binary", [("m.off", True), ("m.obj", True), ("m.ply", True), ("m.ply", False)])
def test_round_trip_keeps_positions_and_polygons_exactly(tmp_path, name, binary):
    path = tmp_path / name
    offsets, indices = ragged(MIXED)
    formats.write(path, AWKWARD, offsets, indices, binary=binary)
    soup = formats.read(path)
    before = {"m.off": 2 + len(AWKWARD), "m.obj": len(AWKWARD)}.get(name)
    if name == "m.ply" and not binary:
        before = header_lines(path) + len(AWKWARD)
    expected_lines = None if before is None else [before + i + 1 for i in range(len(MIXED))]
    assert_soup(soup, AWKWARD, MIXED, expected_lines)
    assert np.signbit(soup.positions[0, 2])  # -0.0 stays -0.0


@pytest.mark.parametrize("name, binary", [("m.off", True), ("m.obj", True), ("m.ply", True), ("m.ply", False)])
def test_round_trip_of_uniform_and_empty_meshes(tmp_path, name, binary):
    rng = np.random.default_rng(7)
    positions = rng.normal(size=(500, 3))
    for arity, n in [(3, 2000), (4, 700), (1, 0)]:
        indices = rng.integers(0, len(positions), size=arity * n)
        offsets = np.arange(n + 1) * arity
        formats.write(tmp_path / name, positions, offsets, indices, binary=binary)
        soup = formats.read(tmp_path / name)
        np.testing.assert_array_equal(soup.positions, positions)
        np.testing.assert_array_equal(soup.offsets, offsets)
        np.testing.assert_array_equal(soup.indices, indices)
    formats.write(tmp_path / name, np.empty((0, 3)), [0], [], binary=binary)
    assert_soup(formats.read(tmp_path / name), [], [])


def test_written_files_look_as_documented(tmp_path):
    square = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]
    offsets, indices = [0, 3, 6], [0, 1, 2, 0, 2, 3]
    formats.write(tmp_path / "s.off", square, offsets, indices)
    assert (tmp_path / "s.off").read_text().splitlines()[:3] == ["OFF", "4 2 0", "0.0 0.0 0.0"]
    assert (tmp_path / "s.off").read_text().splitlines()[-1] == "3 0 2 3"
    formats.write(tmp_path / "s.obj", square, offsets, indices)
    assert (tmp_path / "s.obj").read_text().splitlines()[-2:] == ["f 1 2 3", "f 1 3 4"]
    formats.write(tmp_path / "s.ply", square, offsets, indices)
    head = (tmp_path / "s.ply").read_bytes()
    assert head.startswith(
        b"ply\nformat binary_little_endian 1.0\nelement vertex 4\n"
        b"property double x\nproperty double y\nproperty double z\n"
        b"element face 2\nproperty list uchar int vertex_indices\nend_header\n"
    )
    assert len(head) == head.index(b"end_header\n") + 11 + 4 * 24 + 2 * (1 + 3 * 4)
    formats.write(tmp_path / "big.ply", square, [0, 300], [i % 4 for i in range(300)], binary=False)
    text = (tmp_path / "big.ply").read_text()
    assert "format ascii 1.0" in text and "property list uint int vertex_indices" in text


def test_writer_refuses_bad_arrays_and_writes_nothing(tmp_path):
    good = np.zeros((3, 3))
    cases = [
        (np.zeros((3, 2)), [0, 3], [0, 1, 2], "shape (V, 3)"),
        ([[0, 0, 0], [1, 1, math.nan], [2, 2, 2]], [0, 3], [0, 1, 2], "position 1 is not finite"),
        (good, [1, 3], [0, 1, 2], "offsets must run from 0"),
        (good, [0, 2], [0, 1, 2], "offsets must run from 0"),
        (good, [0, 0, 3], [0, 1, 2], "polygon 0 has no vertices"),
        (good, [0, 3], [0, 1, 3], "polygon 0 has vertex index 3, out of range for 3 vertices"),
        (good, [0, 1, 3], [0, -1, 2], "polygon 1 has vertex index -1"),
        (good, [0, 3], [0.0, 1.0, 2.0], "indices must be a 1-D array of integers"),
    ]
    for positions, offsets, indices, fragment in cases:
        for name in ["x.off", "x.obj", "x.ply"]:
            with pytest.raises(InvalidInputError, match=re.escape(fragment)):
                formats.write(tmp_path / name, positions, offsets, indices)
            assert not (tmp_path / name).exists()
    with pytest.raises(InvalidInputError, match="unsupported file format"):
        formats.write(tmp_path / "x.stl", good, [0, 3], [0, 1, 2])
    assert list(tmp_path.iterdir()) == []


def test_progress_is_reported_and_ends_complete(tmp_path, monkeypatch):
    monkeypatch.setattr(common, "CHUNK_BYTES", 64)
    monkeypatch.setattr(common, "WRITE_ROWS", 5)
    offsets, indices = ragged(MIXED)
    for name, binary in [("p.obj", True), ("p.off", True), ("p.ply", False), ("p.ply", True)]:
        written = []
        formats.write(tmp_path / name, AWKWARD, offsets, indices, binary=binary, progress=lambda *a: written.append(a))
        total = len(AWKWARD) + len(MIXED)
        assert written[-1] == (total, total) and len(written) > 1
        assert all(a[0] <= b[0] <= total for a, b in zip(written, written[1:]))
        seen = []
        formats.read(tmp_path / name, progress=lambda *a: seen.append(a))
        size = (tmp_path / name).stat().st_size
        assert seen[-1] == (size, size)
        assert all(a[0] <= b[0] <= size and b[1] == size for a, b in zip(seen, seen[1:]))
        if name != "p.ply" or not binary:
            assert len(seen) > 2  # chunk by chunk


# -- OBJ ----------------------------------------------------------------------

OBJ_SYNTAXES = """\
# every vertex reference syntax, in one file
mtllib nothing.mtl
o thing
v 0 0 0
v 1 0 0
vt 0.5 0.5
vn 0 0 1
v 1 1 0
  v\t0 1 0
g group
s off
usemtl none
f 1 2 3
f 1/1 2/1 3/1 4/1
f 1//1 3//1 4//1
f 4/1/1 3/1/1 2/1/1 1/1/1
l 1 2 3
p 4
f -4 -3 -2   # relative to the four vertices so far
v 0 0 1
f -1 -2/1 -3//1 -4/1/1
\tf 5 1 2
vp 0.5
f 1 2 3 4 5 1 2
"""


def test_obj_face_syntaxes_negative_indices_and_ignored_statements(tmp_path, reader):
    soup = formats.read(put(tmp_path, "s.obj", OBJ_SYNTAXES))
    positions = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1)]
    expected = [
        [0, 1, 2],
        [0, 1, 2, 3],
        [0, 2, 3],
        [3, 2, 1, 0],
        [0, 1, 2],
        [4, 3, 2, 1],
        [4, 0, 1],
        [0, 1, 2, 3, 4, 0, 1],
    ]
    assert_soup(soup, positions, expected, [13, 14, 15, 16, 19, 21, 22, 24])


def test_obj_indices_are_passed_through_unchecked(tmp_path, reader):
    text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 99\nf 0 1 2\nf -7 1 2\nf 3 3 3\nf 1 2\nf\n"
    soup = formats.read(put(tmp_path, "u.obj", text))
    # 99 is out of range, 0 (invalid in OBJ) becomes -1, -7 counts back past the first vertex.
    assert polygons(soup) == [[0, 1, 98], [-1, 0, 1], [-4, 0, 1], [2, 2, 2], [0, 1], []]
    assert soup.lines.tolist() == [4, 5, 6, 7, 8, 9]


def test_obj_vertex_variants_crlf_comments_and_no_final_newline(tmp_path, reader):
    text = (
        "\ufeffv 1 2\r\nv 1 2 3 0.5\r\nv 4 5 6 0.1 0.2 0.3 # coloured\r\nv 7 8 9#x\r\n"
        "f 1 2 3 4\r\n\r\n#f 1 2 3\r\nf 4 3 2"
    )
    soup = formats.read(put(tmp_path, "v.obj", text))
    assert_soup(soup, [(1, 2, 0), (1, 2, 3), (4, 5, 6), (7, 8, 9)], [[0, 1, 2, 3], [3, 2, 1]], [5, 8])


def test_obj_without_faces_and_obj_of_statements_without_geometry(tmp_path, reader):
    assert_soup(formats.read(put(tmp_path, "p.obj", "# points\nv 1 2 3\nl 1 1\n")), [(1, 2, 3)], [], [])
    # OBJ has no header: statements without a vertex are its empty mesh.
    assert_soup(formats.read(put(tmp_path, "e.obj", "# nothing yet\nmtllib none.mtl\no empty\n")), [], [], [])
    assert_soup(formats.read(put(tmp_path, "g.obj", "\n\ng\n")), [], [], [])


@pytest.mark.parametrize(
    "text, line, fragment",
    [
        ("v 0 0 0\nv 1 zero 0\n", 2, "expected a number, found 'zero'"),
        ("v 0 0 0\n\nv 1 nan 0\n", 3, "coordinate 'nan' is not finite"),
        ("v 0 0 0\nv inf 0 0\n", 2, "coordinate 'inf' is not finite"),
        ("v 0 0 0\nv 1e999 0 0\n", 2, "is not finite"),
        ("v 0 0 0\n# x\nv 1\n", 3, "a vertex needs at least 2 coordinates, found 1"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n", 4, "vertex index 'x' is not an integer"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3.0\n", 4, "vertex index '3.0' is not an integer"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/1 2/1 /3\n", 4, "vertex index '' is not an integer"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 \\\n 3\n", 4, "line continuations"),
    ],
)
def test_malformed_obj_names_file_and_line(tmp_path, reader, text, line, fragment):
    # Padding pushes the bad line into a later chunk when chunks are tiny.
    padding = "# padding\n" * 7 + "vt 0 0\n" * 5
    assert_read_refused(put(tmp_path, "bad.obj", padding + text), line + 12, fragment)


# -- OFF ----------------------------------------------------------------------


def test_off_comments_anywhere_counts_on_keyword_line_and_edge_count(tmp_path, reader):
    text = """# written by hand
   # indented comment

OFF   # the keyword
4 2 6  # nonzero edge count, ignored
# vertices
0 0 0
1 0 0 # trailing
  1 1 0

0 1 0
# faces
3 0 1 2
3 0 2 3  # closes the square
this line and anything after the last face is ignored
"""
    soup = formats.read(put(tmp_path, "c.off", text))
    assert_soup(soup, [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)], [[0, 1, 2], [0, 2, 3]], [13, 14])
    soup = formats.read(put(tmp_path, "k.off", "OFF 3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2"))
    assert_soup(soup, [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [[0, 1, 2]], [5])


def test_off_header_variants_and_extra_values(tmp_path, reader):
    coff = (
        "COFF\n3 2 0\n0 0 0 255 0 0 255\n1 0 0 0 255 0 255\n0 1 0 0.5 0.5 0.5 1\n"
        "3 0 1 2 255 0 0\n4 0 1 2 0 0.25 0.5 0.75\n"
    )
    soup = formats.read(put(tmp_path, "c.off", coff))
    assert_soup(soup, [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [[0, 1, 2], [0, 1, 2, 0]], [6, 7])
    noff = "NOFF\r\n3 1 0\r\n0 0 0 0 0 1\r\n1 0 0 0 0 1\r\n0 1 0 0 0 1\r\n3 2 1 0\r\n"
    assert_soup(formats.read(put(tmp_path, "n.off", noff)), [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [[2, 1, 0]], [6])
    stcnoff = "STCNOFF\n2 1 0\n1 2 3 0 0 1 1 1 1 1 0.5 0.5\n4 5 6 0 0 1 1 1 1 1 0.5 0.5\n2 0 1\n"
    assert_soup(formats.read(put(tmp_path, "st.off", stcnoff)), [(1, 2, 3), (4, 5, 6)], [[0, 1]], [5])
    planar = "nOFF\n2\n3 1 0\n0 0\n1 0\n0 1\n3 0 1 2\n"
    assert_soup(formats.read(put(tmp_path, "p.off", planar)), [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [[0, 1, 2]], [7])
    floats = "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3.0 0 1.0 2 0.5\n"  # integral floats, as some writers emit
    assert_soup(formats.read(put(tmp_path, "f.off", floats)), [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [[0, 1, 2]], [6])
    empty = "OFF\n0 0 0\n"
    assert_soup(formats.read(put(tmp_path, "e.off", empty)), [], [], [])
    degenerate = "OFF\n2 3 0\n0 0 0\n1 0 0\n0\n1 7\n2 0 -1\n"
    assert_soup(formats.read(put(tmp_path, "d.off", degenerate)), [(0, 0, 0), (1, 0, 0)], [[], [7], [0, -1]], [5, 6, 7])


@pytest.mark.parametrize(
    "text, line, fragment",
    [
        ("", 1, "the file is empty"),
        ("# only a comment\n", 1, "the file is empty"),
        ("# c\nOFX\n3 1 0\n", 2, "expected the OFF keyword, found 'OFX'"),
        ("3 1 0\n0 0 0\n", 1, "expected the OFF keyword, found '3'"),
        ("OFF BINARY\n3 1 0\n", 1, "binary OFF is not supported"),
        ("4OFF\n3 1 0\n", 1, "homogeneous"),
        ("nOFF\n5\n3 1 0\n", 2, "only 2- and 3-dimensional nOFF is supported, found '5'"),
        ("nOFF\n99999999999999999999\n3 1 0\n", 2, "found '99999999999999999999'"),
        ("OFF\n\n3 x 0\n", 3, "count 'x' is not an integer"),
        ("OFF\n3\n0 0 0\n", 2, "expected the vertex, face and edge counts, found '3'"),
        ("OFF\n3 -1 0\n", 2, "count '-1' is negative"),
        ("OFF\n", 1, "file ends inside the OFF header"),
        ("OFF\n3 1 0\n0 0 0\n1 0 0\n", 4, "file ends after 2 of 3 vertices"),
        ("OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n# end\n", 7, "file ends after 1 of 2 faces"),
        ("OFF\n3 1 0\n0 0 0\n1 0 0 # ok\n0 one 0\n3 0 1 2\n", 5, "expected a number, found 'one'"),
        ("OFF\n3 1 0\n0 0 0\n1 0 0\n0 nan 0\n3 0 1 2\n", 5, "coordinate 'nan' is not finite"),
        ("OFF\n3 1 0\n0 0 0\n1 0 0\n0 -inf 0\n3 0 1 2\n", 5, "coordinate '-inf' is not finite"),
        ("OFF\n3 1 0\n0 0 0\n1 0 0\n0\n3 0 1 2\n", 5, "a vertex needs at least 2 coordinates, found 1"),
        ("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2.5\n", 6, "vertex index '2.5' is not an integer"),
        ("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 b\n", 6, "vertex index 'b' is not an integer"),
        ("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n-3 0 1 2\n", 6, "negative vertex count -3"),
        ("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n4 0 1 2\n", 6, "face of 4 vertices has only 3 indices"),
        ("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\nthree 0 1 2\n", 6, "vertex count 'three' is not an integer"),
    ],
)
def test_malformed_off_names_file_and_line(tmp_path, reader, text, line, fragment):
    assert_read_refused(put(tmp_path, "bad.off", text), line, fragment)


def test_malformed_off_line_numbers_deep_in_a_large_file(tmp_path, reader):
    n = 400
    rows = [f"{i} {i} {i}" for i in range(n)]
    rows[317] = "1 2 x"
    text = "OFF\n# a comment line\n" + f"{n} 1 0\n" + "\n".join(rows) + "\n3 0 1 2\n"
    assert_read_refused(put(tmp_path, "deep.off", text), 3 + 318, "found 'x'")


# -- PLY ----------------------------------------------------------------------

_STRUCT = {
    "char": "b", "int8": "b", "uchar": "B", "uint8": "B",
    "short": "h", "int16": "h", "ushort": "H", "uint16": "H",
    "int": "i", "int32": "i", "uint": "I", "uint32": "I",
    "float": "f", "float32": "f", "double": "d", "float64": "d",
}  # fmt: skip


def ply(fmt: str, elements, comments=("comment made by hand", "obj_info test")) -> bytes:
    """A PLY file written independently of hestore: ``elements`` are
    ``(name, properties, records)``, a property ``(type, name)`` or
    ``("list", count type, item type, name)``, a record one value per property."""
    head = ["ply", f"format {fmt} 1.0", *comments]
    for name, props, records in elements:
        head.append(f"element {name} {len(records)}")
        head += [f"property {' '.join(p)}" for p in props]
    out = ("\n".join(head) + "\nend_header\n").encode()
    order = {"binary_little_endian": "<", "binary_big_endian": ">"}.get(fmt)
    for _, props, records in elements:
        for record in records:
            if order is None:
                words = []
                for p, value in zip(props, record):
                    words += [str(len(value)), *map(str, value)] if p[0] == "list" else [str(value)]
                out += (" ".join(words) + "\n").encode()
                continue
            for p, value in zip(props, record):
                if p[0] == "list":
                    out += struct.pack(order + _STRUCT[p[1]], len(value))
                    out += struct.pack(order + _STRUCT[p[2]] * len(value), *value)
                else:
                    out += struct.pack(order + _STRUCT[p[0]], value)
    return out


PLY_FORMATS = ["ascii", "binary_little_endian", "binary_big_endian"]
XYZ = [("float", "x"), ("float", "y"), ("float", "z")]
TRIANGLE = [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0)]


@pytest.mark.parametrize("fmt", PLY_FORMATS)
def test_ply_every_type_name_and_skipped_properties_and_elements(tmp_path, reader, fmt):
    types = list(_STRUCT)
    vertex_props = [(types[0], "first"), ("float32", "x"), ("double", "y"), ("int16", "z")]
    vertex_props += [(t, f"extra_{t}") for t in types] + [("list", "uchar", "float", "normal")]
    vertices = [[-1, 0.5, 0.25, 3] + [i] * len(types) + [[0.0, 0.0, 1.0]] for i in range(4)]
    face_props = [("uint8", "flags"), ("list", "uint8", "int32", "vertex_indices"), ("float", "quality")]
    face_props += [("list", "ushort", "double", "texcoord")]
    faces = [[1, [0, 1, 2], 0.5, [0.1, 0.2]], [2, [3, 2, 1, 0], 1.5, []], [3, [1], 0.0, [1.0]]]
    edges = [[0, 1], [1, 2]]
    elements = [
        ("material", [("uchar", "red")], [[1], [2]]),
        ("vertex", vertex_props, vertices),
        ("edge", [("int", "vertex1"), ("int", "vertex2")], edges),
        ("face", face_props, faces),
        ("extra", [("list", "int", "int", "stuff"), ("char", "c")], [[[1, 2, 3], -1]]),
    ]
    soup = formats.read(put(tmp_path, "all.ply", ply(fmt, elements)))
    lines = None
    if fmt == "ascii":
        first = header_lines(tmp_path / "all.ply") + 2 + 4 + 2 + 1
        lines = [first, first + 1, first + 2]
    assert_soup(soup, [(0.5, 0.25, 3)] * 4, [[0, 1, 2], [3, 2, 1, 0], [1]], lines)


@pytest.mark.parametrize("fmt", PLY_FORMATS)
@pytest.mark.parametrize("arities", [[3, 3, 3], [4, 3, 5], [300, 3]])
def test_ply_uniform_and_varying_lists_and_index_names(tmp_path, reader, fmt, arities):
    polys = [[(i + j) % 3 for j in range(k)] for i, k in enumerate(arities)]
    count = "uint" if max(arities) > 255 else "uchar"
    for name in ["vertex_indices", "vertex_index"]:
        elements = [("vertex", XYZ, TRIANGLE), ("face", [("list", count, "uint", name)], [[p] for p in polys])]
        soup = formats.read(put(tmp_path, "v.ply", ply(fmt, elements)))
        assert_soup(soup, TRIANGLE, polys)


@pytest.mark.parametrize("fmt", PLY_FORMATS)
def test_ply_two_dimensional_and_point_sets_and_quirky_headers(tmp_path, reader, fmt):
    elements = [("vertex", [("double", "x"), ("double", "y")], [(1.5, 2.5), (3.0, 4.0)])]
    assert_soup(
        formats.read(put(tmp_path, "p.ply", ply(fmt, elements))),
        [(1.5, 2.5, 0), (3, 4, 0)],
        [],
        None if fmt != "ascii" else [],
    )
    elements = [("face", [("list", "uchar", "int", "vertex_indices")], [[[0, 1, 2]]]), ("vertex", XYZ, TRIANGLE)]
    data = ply(fmt, elements).replace(b"\n", b"\r\n", 12) if fmt == "ascii" else ply(fmt, elements)
    assert_soup(formats.read(put(tmp_path, "f.ply", data)), TRIANGLE, [[0, 1, 2]])


def test_ply_ascii_integral_float_indices_and_blank_lines(tmp_path, reader):
    text = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
    text += "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n\n1 0 0\n0 1 0\n3 0.0 1 2.0\n"
    assert_soup(formats.read(put(tmp_path, "b.ply", text)), TRIANGLE, [[0, 1, 2]], [14])


PLY_HEAD = (
    "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
    "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
)
NO_VERTICES = "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nelement face 0\n"


@pytest.mark.parametrize(
    "text, line, fragment",
    [
        ("plyx\nformat ascii 1.0\nend_header\n", 1, "not a PLY file"),
        ("ply\nformat ascii 2.0 x\nend_header\n", 2, "unknown PLY format"),
        ("ply\nformat binary_middle_endian 1.0\nend_header\n", 2, "unknown PLY format"),
        ("ply\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n0 0\n", 5, "no format line"),
        ("ply\nformat ascii 1.0\nproperty float x\n", 3, "property before any element"),
        ("ply\nformat ascii 1.0\nelement vertex 1\nproperty float128 x\n", 4, "unknown PLY property type 'float128'"),
        ("ply\nformat ascii 1.0\nelement vertex -1\n", 3, "element vertex count '-1' is negative"),
        ("ply\nformat ascii 1.0\nelement vertex 3\nelement face\n", 4, "expected 'element <name> <count>'"),
        (
            "ply\nformat ascii 1.0\nelement vertex 1\nproperty list float int x\n",
            4,
            "list count type must be an integer",
        ),
        ("ply\nformat ascii 1.0\nelement vertex 1\nproperty float\n", 4, "expected 'property <type> <name>'"),
        ("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n", 5, "no end_header"),
        ("ply\nformat ascii 1.0\nbogus\nend_header\n", 3, "unknown PLY header keyword 'bogus'"),
        (
            "ply\nformat ascii 1.0\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n",
            3,
            "no vertex element",
        ),
        (
            "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float z\nend_header\n",
            3,
            "no y property",
        ),
        (
            "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty list uchar float y\nend_header\n",
            3,
            "vertex property y is a list",
        ),
        (
            NO_VERTICES + "property int vertex_indices\nend_header\n",
            6,
            "no vertex_indices list",
        ),
        (
            NO_VERTICES + "property list uchar float vertex_indices\nend_header\n",
            6,
            "integer type",
        ),
        (PLY_HEAD + "0 0 0\n1 0 0\n", 11, "file ends after 2 of 3 vertices"),
        (PLY_HEAD + "0 0 0\n1 0 0\n0 1 0\n", 12, "file ends after 0 of 1 faces"),
        (PLY_HEAD + "0 0 0\n1 0 0\n0 one 0\n3 0 1 2\n", 12, "expected a number, found 'one'"),
        (PLY_HEAD + "0 0 0\n1 0 0\n0 NaN 0\n3 0 1 2\n", 12, "non-finite"),
        (PLY_HEAD + "0 0 0\n1 0 0\n0 1\n3 0 1 2\n", 12, "vertex record ends before its property 'z'"),
        (PLY_HEAD + "0 0 0\n1 0 0 7\n0 1 0\n3 0 1 2\n", 11, "vertex record has 1 values more"),
        (PLY_HEAD + "0 0 0\n1 0 0\n0 1 0\n-3 0 1 2\n", 13, "negative vertex_indices count -3"),
        (PLY_HEAD + "0 0 0\n1 0 0\n0 1 0\n3 0 1\n", 13, "vertex_indices of 3 items has only 2"),
        (PLY_HEAD + "0 0 0\n1 0 0\n0 1 0\n3 0 1 2.5\n", 13, "vertex index '2.5' is not an integer"),
        (PLY_HEAD + "0 0 0\n1 0 0\n0 1 0\n3 0 1 2 9\n", 13, "face record has 1 values more"),
    ],
)
def test_malformed_ascii_ply_names_file_and_line(tmp_path, reader, text, line, fragment):
    assert_read_refused(put(tmp_path, "bad.ply", text), line, fragment)


@pytest.mark.parametrize("fmt", ["binary_little_endian", "binary_big_endian"])
def test_malformed_binary_ply_names_file_and_byte(tmp_path, fmt):
    faces = [[[0, 1, 2]], [[2, 1, 0]], [[0, 2, 1]]]
    elements = [("vertex", XYZ, TRIANGLE), ("face", [("list", "char", "int", "vertex_indices")], faces)]
    data = ply(fmt, elements)
    body = data.index(b"end_header\n") + 11
    face_data = body + 3 * 12

    assert_read_refused(
        put(tmp_path, "v.ply", data[: body + 30]), f"byte {body + 24}", "file ends inside vertex 2 of 3"
    )
    assert_read_refused(put(tmp_path, "f.ply", data[:-1]), f"byte {face_data + 26}", "file ends inside face 2 of 3")
    assert_read_refused(
        put(tmp_path, "g.ply", data[: face_data + 13]), f"byte {face_data + 13}", "file ends inside face 1 of 3"
    )

    negative = bytearray(data)
    negative[face_data + 13] = 0xFF  # a char count of -1
    assert_read_refused(
        put(tmp_path, "n.ply", bytes(negative)), f"byte {face_data + 13}", "negative list count -1 in face 1"
    )

    order = "<" if fmt == "binary_little_endian" else ">"
    not_finite = bytearray(data)
    not_finite[body + 16 : body + 20] = struct.pack(order + "f", math.inf)
    assert_read_refused(
        put(tmp_path, "i.ply", bytes(not_finite)), f"byte {body + 12}", "vertex 1 has a non-finite coordinate"
    )


def test_binary_ply_extra_bytes_and_files_without_faces(tmp_path):
    elements = [("vertex", XYZ, TRIANGLE), ("face", [("list", "uchar", "int", "vertex_indices")], [[[0, 1, 2]]])]
    soup = formats.read(put(tmp_path, "x.ply", ply("binary_little_endian", elements) + b"trailing"))
    assert_soup(soup, TRIANGLE, [[0, 1, 2]], None)
    soup = formats.read(put(tmp_path, "p.ply", ply("binary_big_endian", elements[:1])))
    assert_soup(soup, TRIANGLE, [], None)


# -- untrusted input: typed errors, bounded work ---------------------------------

# A read of a file of a few KB needs a few MB (the soup, the parsing
# temporaries, an 8 MB read buffer); one that trusts a header count asks for
# gigabytes. tracemalloc sees numpy's allocations too.
SMALL_PEAK = 32 << 20


def refused_cheaply(path: pathlib.Path, where, fragment: str) -> None:
    """Like `assert_read_refused`, and the read allocated little and took little time on the way.

    The time is this process's processor time, which other processes on a busy machine do not add to.
    """
    tracemalloc.start()
    started = time.process_time()
    try:
        assert_read_refused(path, where, fragment)
    finally:
        seconds = time.process_time() - started
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    assert peak < SMALL_PEAK, f"allocated {peak / 2**20:.0f} MiB before refusing"
    assert seconds < 2, f"took {seconds:.1f} s to refuse"


def binary_ply_head(vertices, faces=None, face_props="property list uchar int vertex_indices\n") -> bytes:
    head = f"ply\nformat binary_little_endian 1.0\nelement vertex {vertices}\n"
    head += "property float x\nproperty float y\nproperty float z\n"
    if faces is not None:
        head += f"element face {faces}\n" + face_props
    return (head + "end_header\n").encode()


ASCII_XYZ = "property float x\nproperty float y\nproperty float z\n"


def test_huge_binary_ply_vertex_count_in_a_tiny_file_is_refused_without_allocating(tmp_path):
    # 4294967296 records of 12 bytes: 48 GiB, which the reader used to allocate first.
    head = binary_ply_head(4294967296)
    path = put(tmp_path, "big.ply", head + bytes(10_000))
    refused_cheaply(path, f"byte {len(head) + 833 * 12}", "file ends inside vertex 833 of 4294967296")


def test_huge_binary_ply_face_counts_are_refused_without_allocating(tmp_path):
    triangle = struct.pack("<9f", 0, 0, 0, 1, 0, 0, 0, 1, 0)
    one_face = struct.pack("<B3i", 3, 0, 1, 2)
    # Uniform lists: the structured-array guess must not be allocated for the declared count.
    head = binary_ply_head(3, 2**32)
    path = put(tmp_path, "uniform.ply", head + triangle + one_face * 500)
    refused_cheaply(path, f"byte {len(head) + 36 + 500 * 13}", "file ends inside face 500 of 4294967296")
    # A first list of 200 items makes a 801-byte guessed record; 10**8 of them would be 75 GiB.
    head = binary_ply_head(3, 10**8)
    path = put(tmp_path, "guess.ply", head + triangle + struct.pack("<B", 200) + bytes(800) + one_face * 20)
    refused_cheaply(path, f"byte {len(head) + 36 + 801 + 20 * 13}", "file ends inside face 21 of 100000000")
    # Varying lists: the record walk must stop where the data ends, not at the count.
    data = head + triangle + one_face + struct.pack("<B4i", 4, 0, 1, 2, 0) + bytes(3000)
    refused_cheaply(put(tmp_path, "walk.ply", data), f"byte {len(data)}", "file ends inside face 3002 of 100000000")
    # A list count of 2**32 - 1 items in a small file.
    head = binary_ply_head(3, 1, "property list uint int vertex_indices\n")
    path = put(tmp_path, "list.ply", head + triangle + struct.pack("<I", 2**32 - 1) + bytes(64))
    refused_cheaply(path, f"byte {len(head) + 36}", "file ends inside face 0 of 1")


@pytest.mark.parametrize("count", ["4294967296", str(2**62)])
def test_huge_ascii_ply_counts_are_refused_at_their_header_line(tmp_path, count):
    text = f"ply\nformat ascii 1.0\nelement vertex {count}\n{ASCII_XYZ}end_header\n" + "0 0 0\n" * 1000
    refused_cheaply(put(tmp_path, "big.ply", text), 3, f"{count} vertex records cannot fit in the 6000 bytes left")
    text = f"ply\nformat ascii 1.0\nelement vertex 3\n{ASCII_XYZ}element face {count}\n"
    text += "property list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"
    refused_cheaply(put(tmp_path, "faces.ply", text), 7, f"{count} face records cannot fit")


@pytest.mark.parametrize("count", [str(2**63), "18446744073709551616", "99999999999999999999", "0" + "9" * 20])
def test_counts_beyond_int64_are_refused_with_file_and_line(tmp_path, count):
    refused_cheaply(put(tmp_path, "v.off", f"OFF\n{count} 1 0\n0 0 0\n"), 2, f"count '{count}' is too large")
    refused_cheaply(put(tmp_path, "f.off", f"OFF\n# c\n3 {count} 0\n0 0 0\n"), 3, f"count '{count}' is too large")
    text = f"ply\nformat ascii 1.0\nelement vertex {count}\n{ASCII_XYZ}end_header\n"
    refused_cheaply(put(tmp_path, "v.ply", text), 3, f"element vertex count '{count}' is too large")
    data = binary_ply_head(3).replace(b"end_header", f"element edge {count}\nend_header".encode()) + bytes(36)
    refused_cheaply(put(tmp_path, "e.ply", data), 7, f"element edge count '{count}' is too large")


def test_a_count_of_thousands_of_digits_is_refused_and_shown_short(tmp_path):
    digits = "9" * 5000  # past Python's int() digit limit, which raised a bare ValueError
    text = f"ply\nformat ascii 1.0\nelement vertex {digits}\n{ASCII_XYZ}end_header\n"
    with pytest.raises(InvalidInputError, match=r"v\.ply:3: element vertex count '9{40}'\.\.\. \(5000 bytes\)") as e:
        formats.read(put(tmp_path, "v.ply", text))
    assert len(str(e.value)) < 200 + len(str(tmp_path))
    refused_cheaply(put(tmp_path, "v.off", f"OFF\n3 {digits} 0\n"), 2, "(5000 bytes) is too large")


@pytest.mark.parametrize("count", [str(2**63 - 1), str(2**40)])
def test_off_counts_that_fit_int64_but_not_the_file_are_refused_at_the_header(tmp_path, count):
    refused_cheaply(put(tmp_path, "v.off", f"OFF\n{count} 1 0\n0 0 0\n"), 2, f"{count} vertices cannot fit")
    text = f"OFF\n3 {count} 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"
    refused_cheaply(put(tmp_path, "f.off", text), 2, f"{count} faces after the vertices cannot fit")


def test_counts_that_exactly_fit_are_accepted(tmp_path):
    # The bound is a true one: the shortest records, the last without its line break.
    assert_soup(formats.read(put(tmp_path, "p.off", "OFF\n2 1\n0 0\n1 1\n0")), [(0, 0, 0), (1, 1, 0)], [[]], [5])
    text = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nelement c 2\n"
    text += "property uchar c\nend_header\n1 2\n3 4\n5\n6"
    assert_soup(formats.read(put(tmp_path, "p.ply", text)), [(1, 2, 0), (3, 4, 0)], [], [])


@pytest.mark.parametrize(
    "text, line, fragment",
    [
        ("OFF\n-3 1 0\n", 2, "count '-3' is negative"),
        ("OFF\n3 -9223372036854775809 0\n", 2, "count '-9223372036854775809' is negative"),
        ("OFF\n3.0 1 0\n", 2, "count '3.0' is not an integer"),
        ("OFF\n+3 1 0\n", 2, "count '+3' is not an integer"),
        ("OFF\n3_0 1 0\n", 2, "count '3_0' is not an integer"),
        ("OFF\n0x3 1 0\n", 2, "count '0x3' is not an integer"),
        ("OFF\n\u0663 1 0\n", 2, "count '\\xd9\\xa3' is not an integer"),  # UTF-8 bytes, escaped
        ("OFF\n3 1 0\x00\n", 2, "is not an integer"),
        ("ply\nformat ascii 1.0\nelement vertex -0\n", 3, "element vertex count '-0' is negative"),
        ("ply\nformat ascii 1.0\nelement vertex 1e3\n", 3, "element vertex count '1e3' is not an integer"),
        ("ply\nformat ascii 1.0\nelement vertex \u00b2\n", 3, "is not an integer"),  # a superscript two
        ("ply\nformat ascii 1.0\nelement vertex 3\x00\n", 3, "is not an integer"),
    ],
)
def test_negative_and_non_integer_header_counts_name_file_and_line(tmp_path, text, line, fragment):
    refused_cheaply(put(tmp_path, "bad" + (".off" if text.startswith("OFF") else ".ply"), text), line, fragment)


def test_a_face_count_near_2_63_is_refused_not_wrapped_around(tmp_path, reader):
    # The vectorised reader's "enough values for k indices?" check used to
    # overflow and return a polygon of 2**63 - 1 vertices holding 3 indices.
    for k in [2**63 - 1, 2**63 - 2, 2**62]:
        text = f"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n{k} 0 1 2\n"
        assert_read_refused(put(tmp_path, "k.off", text), 6, f"face of {k} vertices has only 3 indices")
        text = PLY_HEAD + f"0 0 0\n1 0 0\n0 1 0\n{k} 0 1 2\n"
        assert_read_refused(put(tmp_path, "k.ply", text), 13, f"vertex_indices of {k} items has only 3")


@pytest.mark.parametrize("fmt", PLY_FORMATS)
def test_ply_without_vertex_and_face_elements_is_an_empty_soup(tmp_path, fmt):
    lines = None if fmt != "ascii" else []
    assert_soup(formats.read(put(tmp_path, "e.ply", ply(fmt, []))), [], [], lines)
    # Other elements are still read (and skipped), as OpenMesh does.
    elements = [("material", [("uchar", "red"), ("list", "uchar", "float", "k")], [[1, [0.5]], [2, []]])]
    assert_soup(formats.read(put(tmp_path, "m.ply", ply(fmt, elements))), [], [], lines)
    truncated = ply(fmt, elements)[:-4]  # into the last material record
    with pytest.raises(InvalidInputError, match="material"):
        formats.read(put(tmp_path, "t.ply", truncated))


@pytest.mark.parametrize("fmt", PLY_FORMATS)
def test_ply_face_element_without_vertex_element_is_refused(tmp_path, fmt):
    elements = [("face", [("list", "uchar", "int", "vertex_indices")], [[[0, 1, 2]]])]
    refused_cheaply(put(tmp_path, "f.ply", ply(fmt, elements)), 5, "declares a face element but no vertex element")


@pytest.mark.parametrize("fmt", PLY_FORMATS)
def test_ply_elements_without_properties_take_no_room_whatever_their_count(tmp_path, fmt):
    elements = [("vertex", XYZ, TRIANGLE)]
    data = ply(fmt, elements).replace(b"end_header", f"element nothing {2**62}\nend_header".encode())
    tracemalloc.start()
    try:
        soup = formats.read(put(tmp_path, "n.ply", data))
    finally:
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    assert_soup(soup, TRIANGLE, [])
    assert peak < SMALL_PEAK


def test_non_utf8_and_nul_bytes_give_typed_errors(tmp_path):
    head = b"ply\nformat ascii 1.0\n"
    refused_cheaply(put(tmp_path, "k.ply", head + b"\xff\xfe\x00 vertex 1\n"), 3, "unknown PLY header keyword")
    bad_type = head + b"element vertex 1\nproperty fl\xc3oat x\n"
    refused_cheaply(put(tmp_path, "t.ply", bad_type), 4, "unknown PLY property")
    refused_cheaply(put(tmp_path, "n.ply", b"ply\x00\n"), 1, "not a PLY file")
    soup = formats.read(put(tmp_path, "c.ply", head + b"comment caf\xe9 \x00\nelement vertex 0\nproperty float x\n"
                            b"property float y\nend_header\n"))
    assert_soup(soup, [], [], [])
    refused_cheaply(put(tmp_path, "o.off", b"\xffOFF\n3 1 0\n"), 1, "expected the OFF keyword")
    refused_cheaply(put(tmp_path, "z.off", b"OFF\n1 0 0\n0 0\x00 0\n"), 3, "expected a number")
    refused_cheaply(put(tmp_path, "z.obj", b"v 0 0 0\nv 1 \xff 0\n"), 2, "expected a number")
    refused_cheaply(put(tmp_path, "f.obj", b"v 0 0 0\nf 1 \x00 1\n"), 2, "is not an integer")


def test_a_long_header_line_is_not_quoted_whole(tmp_path):
    path = put(tmp_path, "x.ply", b"ply\nformat ascii 1.0\n" + b"x" * 1_000_000 + b"\nend_header\n")
    with pytest.raises(InvalidInputError, match=r"unknown PLY header keyword 'x{40}'\.\.\. \(1000000 bytes\)") as e:
        formats.read(path)
    assert len(str(e.value)) < 200 + len(str(path))


# -- files that are not meshes, empty files, and the bytes messages quote -----


def refusal(path: pathlib.Path) -> str:
    """The message of the `InvalidInputError` that reading ``path`` raises, checked to name the file and a line."""
    with pytest.raises(InvalidInputError) as info:
        formats.read(path)
    message = str(info.value)
    assert re.match(re.escape(str(path)) + r":(\d+|byte \d+): ", message), message
    return message


def random_bytes(seed: str, n: int) -> bytes:
    return random.Random(seed).randbytes(n)


def test_obj_reader_refuses_random_bytes(tmp_path, reader):
    for seed in range(5):
        data = random_bytes(f"garbage:{seed}", 200_000)
        message = refusal(put(tmp_path, "garbage.obj", data))
        assert "not an OBJ file: binary data (a NUL byte) before any OBJ statement" in message, message


def test_obj_reader_refuses_text_without_any_obj_statement(tmp_path, reader):
    import base64

    data = base64.encodebytes(random_bytes("base64", 30_000))
    assert_read_refused(put(tmp_path, "b64.obj", data), 1, "not an OBJ file: no line is an OBJ statement")
    prose = "\n# a note\nThis is not a mesh.\nNor is this.\n"
    expected = "no line is an OBJ statement (v, f, ...); this one starts with 'This'"
    assert_read_refused(put(tmp_path, "note.obj", prose), 3, expected)
    # UTF-16 text has a NUL byte in every ASCII character.
    utf16 = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n".encode("utf-16")
    assert_read_refused(put(tmp_path, "wide.obj", utf16), 1, "binary data (a NUL byte)")
    # A statement keyword on a line that is not text does not make the file OBJ.
    assert_read_refused(put(tmp_path, "g.obj", b"g \x01\x02\xff\nzz\n"), 1, "no line is an OBJ statement")


def test_obj_reader_keeps_unknown_statements_and_non_utf8_text_in_real_files(tmp_path, reader):
    text = b"# caf\xe9 (Latin-1)\nvendor_thing 1 2 3\ng caf\xe9\nv 0 0 0\nv 1 0 0\nv 0 1 0\ncurv 0 1 1 2\nf 1 2 3\n"
    assert_soup(formats.read(put(tmp_path, "l.obj", text)), TRIANGLE, [[0, 1, 2]], [8])
    # Unknown statements before the first known one, and more than a chunk of them.
    text = "xyz 1\n" * 20 + "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"
    assert_soup(formats.read(put(tmp_path, "u.obj", text)), TRIANGLE, [[0, 1, 2]], [24])


@pytest.mark.parametrize(
    "name, text, line",
    [
        ("e.off", "", 1),
        ("e.off", "\n  \n\t\n", 3),
        ("e.off", "# nothing\n  # at all", 2),
        ("e.obj", "", 1),
        ("e.obj", "\r\n \n", 2),
        ("e.obj", "# nothing\n\n  # at all\n", 3),
        ("e.ply", "", 1),
        ("e.ply", "\n \t\n\n", 3),
    ],
)
def test_a_file_with_nothing_in_it_is_refused_as_empty(tmp_path, reader, name, text, line):
    """One rule for every format: no bytes, or only whitespace and comments, is not a mesh file at all."""
    assert_read_refused(put(tmp_path, name, text), line, "the file is empty")


@pytest.mark.parametrize("fmt", PLY_FORMATS)
def test_a_file_that_declares_nothing_is_an_empty_mesh(tmp_path, reader, fmt):
    """The other half of the rule: a well-formed header (or statement) with zero vertices and faces is read."""
    lines = None if fmt != "ascii" else []
    nothing = [("vertex", XYZ, []), ("face", [("list", "uchar", "int", "vertex_indices")], [])]
    assert_soup(formats.read(put(tmp_path, "z.ply", ply(fmt, nothing))), [], [], lines)
    assert_soup(formats.read(put(tmp_path, "z.off", "# declared empty\nOFF\n0 0 0\n")), [], [], [])
    assert_soup(formats.read(put(tmp_path, "z.off", "OFF 0 0")), [], [], [])
    assert_soup(formats.read(put(tmp_path, "z.obj", "mtllib none.mtl\n")), [], [], [])


def test_show_escapes_and_cuts_what_it_quotes():
    assert common.show(b"zero") == "'zero'"
    assert common.show(b"\x1b[31m\x00\xff\t'\\") == "'\\x1b[31m\\x00\\xff\\t\\'\\\\'"
    assert common.show("café".encode()) == "'caf\\xc3\\xa9'"  # text too: printable ASCII only
    assert common.show(b"x" * 41) == "'" + "x" * 40 + "'... (41 bytes)"
    cut = common.show(b"\xff" * 100)
    assert cut == "'" + "\\xff" * 10 + "'... (100 bytes)"


def _garbage(seed: str, n: int, word: bool = False) -> bytes:
    """Random bytes on one line; a single word (no whitespace) if ``word``."""
    rng = random.Random(seed)
    banned = set(b" \t\r\x0b\x0c\n#") if word else {ord("\n")}
    allowed = [b for b in range(256) if b not in banned]
    return bytes([rng.choice(b"qQ~")]) + bytes(rng.choice(allowed) for _ in range(n - 1))


_PLY_ASCII = b"ply\nformat ascii 1.0\n"
_PLY_BINARY = b"ply\nformat binary_little_endian 1.0\n"
GARBLED = {
    "keyword.off": lambda g, w: g + b"\n3 1 0\n",
    "counts.off": lambda g, w: b"OFF\n" + g + b"\n",
    "dimension.off": lambda g, w: b"nOFF\n" + w + b"\n3 1 0\n",
    "vertex.off": lambda g, w: b"OFF\n1 0 0\n0 " + g + b"\n",
    "face.off": lambda g, w: b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 " + g + b"\n",
    "lines.obj": lambda g, w: g + b"\n" + g + b"\n",
    "vertex.obj": lambda g, w: b"v 0 0 0\nv 1 " + g + b"\n",
    "face.obj": lambda g, w: b"v 0 0 0\nf 1 " + g + b"\n",
    "uv.obj": lambda g, w: b"v 0 0 0\nvt 0 0\nf 1/" + w + b"\n",
    "keyword.ply": lambda g, w: _PLY_ASCII + g + b"\nend_header\n",
    "format.ply": lambda g, w: b"ply\nformat " + g + b"\nend_header\n",
    "count.ply": lambda g, w: _PLY_ASCII + b"element vertex " + w + b"\nend_header\n",
    "type.ply": lambda g, w: _PLY_ASCII + b"element vertex 1\nproperty " + w + b" x\nend_header\n",
    "name.ply": lambda g, w: _PLY_ASCII
    + b"element vertex 1\nproperty float x\nproperty float y\nproperty uchar "
    + w
    + b"\nend_header\n0 0 300\n",
    "element.ply": lambda g, w: _PLY_ASCII + b"element " + w + b" 1\nproperty float q\nend_header\n",
    "binary-element.ply": lambda g, w: _PLY_BINARY + b"element " + w + b" 1\nproperty float q\nend_header\n",
    "list.ply": lambda g, w: _PLY_BINARY
    + b"element "
    + w
    + b" 1\nproperty list uchar int "
    + w
    + b"\nend_header\n\x05",
}


@pytest.mark.parametrize("name", list(GARBLED))
def test_quoted_file_content_is_one_short_printable_line(tmp_path, name):
    for seed in range(10):
        garbage, word = _garbage(f"{name}:{seed}", 300), _garbage(f"{name}:{seed}:word", 300, word=True)
        path = put(tmp_path, name, GARBLED[name](garbage, word))
        what = refusal(path)[len(str(path)) :]
        context = f"seed {seed}: {what!r}"
        assert what.isascii() and what.isprintable(), context  # one line, no control or escape sequences
        assert len(what) <= 200, context  # two quoted pieces at most, each cut short


def test_a_line_longer_than_many_chunks_is_read_in_linear_time(tmp_path, monkeypatch):
    # Every chunk without a line break used to be re-copied with all the
    # ones before it: quadratic in the line's length.
    monkeypatch.setattr(common, "CHUNK_BYTES", 64)
    text = "v 0 0 0\n# " + "x" * 4_000_000 + "\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"
    started = time.process_time()  # this process's: a busy machine does not add to it
    soup = formats.read(put(tmp_path, "long.obj", text))
    assert time.process_time() - started < 5
    assert_soup(soup, TRIANGLE, [[0, 1, 2]], [5])


def test_binary_ply_signalling_nan_is_refused_without_a_warning(tmp_path):
    data = binary_ply_head(1) + struct.pack("<fI f", 0.0, 0x7FA00000, 0.0)  # x, a signalling NaN, z
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        refused_cheaply(put(tmp_path, "s.ply", data), f"byte {len(data) - 12}", "vertex 0 has a non-finite coordinate")


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no named pipes here")
@pytest.mark.parametrize("name", ["p.off", "p.ply"])
def test_a_named_pipe_is_read_whole_as_it_has_no_size(tmp_path, name):
    source = tmp_path / ("source" + name[1:])
    formats.write(source, TRIANGLE, [0, 3], [0, 1, 2])
    pipe = tmp_path / name
    os.mkfifo(pipe)
    writer = threading.Thread(target=lambda: pipe.write_bytes(source.read_bytes()))
    writer.start()
    try:
        assert_soup(formats.read(pipe), TRIANGLE, [[0, 1, 2]])
    finally:
        writer.join(timeout=10)


# -- the shared outside meshes ----------------------------------------------------


def naive_read(path: pathlib.Path, keep=lambda i: True):
    """The independent check: a deliberately plain reader, one line or record at a time.

    It shares no code with `hestore.io` and uses no numpy, so agreeing
    with it means something. Returns ``(vertex count, {i: position},
    polygon count, {i: (indices, line)})`` for the vertices and polygons
    that ``keep(i)`` selects (lines are None in binary PLY).
    """
    data = path.read_bytes()
    vertices, faces = {}, {}
    nv = nf = 0
    ext = path.suffix.lower()
    if ext == ".obj":
        for number, line in enumerate(data.split(b"\n"), start=1):
            head = line.lstrip()[:2]
            if head in (b"v ", b"v\t"):
                if keep(nv):
                    vertices[nv] = tuple(float(t) for t in line.split(b"#")[0].split()[1:4])
                nv += 1
            elif head in (b"f ", b"f\t"):
                if keep(nf):
                    refs = [int(t.split(b"/")[0]) for t in line.split(b"#")[0].split()[1:]]
                    faces[nf] = ([r - 1 if r > 0 else nv + r for r in refs], number)
                nf += 1
        return nv, vertices, nf, faces
    if ext == ".off":
        content = []
        for number, line in enumerate(data.split(b"\n"), start=1):
            tokens = line.split(b"#")[0].split()
            if tokens:
                content.append((number, tokens))
        keyword = content[0][1]
        assert keyword[0].endswith(b"OFF")
        counts, at = (keyword[1:], 1) if len(keyword) > 1 else (content[1][1], 2)
        nv, nf = int(counts[0]), int(counts[1])
        for i, (_, tokens) in enumerate(content[at : at + nv]):
            if keep(i):
                vertices[i] = tuple(float(t) for t in tokens[:3])
        for i, (number, tokens) in enumerate(content[at + nv : at + nv + nf]):
            if keep(i):
                faces[i] = ([int(t) for t in tokens[1 : 1 + int(tokens[0])]], number)
        return nv, vertices, nf, faces
    # PLY
    end = data.index(b"end_header") + len(b"end_header")
    end = data.index(b"\n", end) + 1
    header = data[:end].decode().split("\n")
    fmt, elements = None, []
    for line in header:
        words = line.split()
        if words and words[0] == "format":
            fmt = words[1]
        elif words and words[0] == "element":
            elements.append((words[1], int(words[2]), []))
        elif words and words[0] == "property":
            elements[-1][2].append(words[1:])
    first_line = len(header)
    if fmt == "ascii":
        records = iter(enumerate(data[end:].decode().split("\n"), start=first_line))
    else:
        order = "<" if fmt == "binary_little_endian" else ">"
        pos = end

        def value(kind):
            nonlocal pos
            (v,) = struct.unpack_from(order + _STRUCT[kind], data, pos)
            pos += struct.calcsize(_STRUCT[kind])
            return v

    for name, count, props in elements:
        size = {kind: struct.calcsize(code) for kind, code in _STRUCT.items()}
        for i in range(count):
            if fmt != "ascii" and not keep(i):  # only step over the record
                for p in props:
                    step = value(p[1]) * size[p[2]] if p[0] == "list" else size[p[0]]
                    pos += step
                continue
            if fmt == "ascii":
                number, line = next(records)
                tokens = iter(line.split())
                record = {}
                for p in props:
                    if p[0] == "list":
                        record[p[-1]] = [float(next(tokens)) for _ in range(int(next(tokens)))]
                    else:
                        record[p[-1]] = float(next(tokens))
            else:
                number, record = None, {}
                for p in props:
                    if p[0] == "list":
                        record[p[-1]] = [value(p[2]) for _ in range(value(p[1]))]
                    else:
                        record[p[-1]] = value(p[0])
            if name == "vertex" and keep(i):
                vertices[i] = (record["x"], record["y"], record.get("z", 0.0))
            elif name == "face" and keep(i):
                indices = record.get("vertex_indices", record.get("vertex_index"))
                faces[i] = ([int(v) for v in indices], number)
        if name == "vertex":
            nv = count
        elif name == "face":
            nf = count
    return nv, vertices, nf, faces


def _shared_files() -> list[str | None]:
    folder = shared_meshes()
    if folder is None:
        return [None]  # one test that skips (or fails under CI) saying why
    return sorted(p.name for p in folder.iterdir() if p.suffix.lower() in (".off", ".obj", ".ply"))


LARGE = 5_000_000  # bytes; above this only a sample of the elements is compared


@pytest.mark.parametrize("name", _shared_files())
def test_shared_mesh_matches_the_naive_reader(name):
    path = require_shared_meshes() / name
    soup = formats.read(path)
    if path.stat().st_size > LARGE:
        keep = lambda i: i < 5 or i % 9973 == 0  # noqa: E731
    else:
        keep = lambda i: True  # noqa: E731
    nv, vertices, nf, faces = naive_read(path, keep)
    assert len(soup.positions) == nv and len(soup.offsets) - 1 == nf
    assert len(soup.indices) == soup.offsets[-1]
    for i, xyz in vertices.items():
        assert tuple(soup.positions[i]) == xyz, i
    for i, (indices, line) in faces.items():
        assert soup.indices[soup.offsets[i] : soup.offsets[i + 1]].tolist() == indices, i
        if soup.lines is not None:
            assert soup.lines[i] == line
    binary_ply = path.suffix == ".ply" and b"format ascii" not in path.read_bytes()[:100]
    assert (soup.lines is None) == binary_ply


@pytest.mark.parametrize(
    "name", [n for n in _shared_files() if n is None or not n.startswith(("stanford-bunny-subdiv2", "igea"))]
)
def test_shared_mesh_per_line_reader_agrees(name, monkeypatch):
    path = require_shared_meshes() / name
    vectorised = formats.read(path)
    monkeypatch.setattr(common, "parse", lambda text, total, dtype: None)
    monkeypatch.setattr(ply_module._BinaryFile, "peek", lambda self, n: b"")  # binary PLY: the record walk
    per_line = formats.read(path)
    for field in ("positions", "offsets", "indices", "lines"):
        a, b = getattr(vectorised, field), getattr(per_line, field)
        assert (a is None and b is None) or np.array_equal(a, b), field


def test_shared_meshes_folder_holds_every_manifest_file():
    folder = require_shared_meshes()
    listed = set(re.findall(r"^\| ([\w.-]+\.(?:off|obj|ply)) \|", (folder / "MANIFEST.md").read_text(), re.M))
    found = {p.name for p in folder.iterdir() if p.suffix in (".off", ".obj", ".ply")}
    assert listed == found and len(found) == 29


def test_shared_off_quirks_from_the_manifest():
    folder = require_shared_meshes()
    shuffled = formats.read(folder / "cube-shuffled.off")  # comments before the keyword
    assert len(shuffled.positions) == 8 and polygons(shuffled)[:2] == [[3, 1, 0], [3, 1, 2]]
    poly = formats.read(folder / "cube_poly.off")  # comments inside the body, mixed arities
    assert np.diff(poly.offsets).tolist() == [3, 3, 4, 4, 4, 4, 4] and polygons(poly)[-1] == [4, 5, 6, 7]
    assert poly.lines.tolist() == [13, 14, 15, 16, 17, 18, 19]
    torus = formats.read(folder / "torus_quad.off")  # edge count 50 in the header
    assert len(torus.positions) == 25 and set(np.diff(torus.offsets).tolist()) == {4} and len(torus.lines) == 25
