"""Per-element data through the mesh file readers and writers (`hestore.io`); no database needed.

PLY vertex and face properties become `PolygonSoup.vertex_properties` and
``polygon_properties``; OBJ ``vt`` and ``vn`` references become the corner
properties ``"uv"`` and ``"normal"``. Text files are read three ways (the
``reader`` fixture, as in ``test_formats``): whole, in tiny chunks, and line
by line only, which must all give the same arrays and errors.
"""

from __future__ import annotations

import numpy as np
import pytest

from hestore import io as mesh_io
from hestore.errors import InvalidInputError
from hestore.io import common
from hestore.io import obj as obj_module
from hestore.io.common import PolygonSoup
from hestore.io.obj import read_obj, write_obj
from hestore.io.ply import read_ply, write_ply

from helpers import assert_read_refused, put
from meshes import require_shared_meshes

NAN = float("nan")


def same_bits(a: np.ndarray, b: np.ndarray) -> None:
    """Equal dtype, shape and bits (so -0.0 differs from 0.0, and NaN equals NaN)."""
    a, b = np.asarray(a), np.asarray(b)
    assert a.dtype == b.dtype and a.shape == b.shape, (a.dtype, a.shape, b.dtype, b.shape)
    assert a.tobytes() == b.tobytes(), (a, b)


def awkward_floats(rng: np.random.Generator, n: int) -> np.ndarray:
    """Random doubles of every magnitude, with subnormals, extremes, -0.0 and infinities."""
    values = rng.standard_normal(n) * 10.0 ** rng.integers(-300, 300, n)
    special = [0.0, -0.0, 5e-324, -2.2250738585072014e-308, 1.7976931308623157e308, np.inf, -np.inf, 0.1, 1 / 3]
    values[: len(special)] = special[:n]
    return values


# A mixed-arity soup: a triangle, a quad and a pentagon on 7 vertices.
POSITIONS = np.array([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (2, 0, 0), (2, 1, 0.5), (3, 2, 1)], dtype=float)
OFFSETS = np.array([0, 3, 7, 12])
INDICES = np.array([0, 1, 2, 0, 2, 3, 1, 1, 4, 5, 6, 2])


# -- PolygonSoup ---------------------------------------------------------------


def test_soup_fields_default_to_empty_dicts_and_repr_names_properties():
    soup = PolygonSoup(np.zeros((3, 3)), np.array([0, 3]), np.array([0, 1, 2]), None)
    assert soup.vertex_properties == {} and soup.polygon_properties == {} and soup.corner_properties == {}
    assert repr(soup) == "PolygonSoup(vertices=3, polygons=1)"
    full = PolygonSoup(
        soup.positions,
        soup.offsets,
        soup.indices,
        None,
        vertex_properties={"red": np.zeros(3, np.int64), "green": np.zeros(3, np.int64)},
        polygon_properties={"label": np.zeros(1, np.int64)},
        corner_properties={"uv": np.zeros((3, 2))},
    )
    assert repr(full) == (
        "PolygonSoup(vertices=3, polygons=1, vertex properties: red, green, "
        "polygon properties: label, corner properties: uv)"
    )


def test_files_without_properties_give_empty_dicts(tmp_path, reader):
    texts = {
        "a.off": "COFF\n3 1 0\n0 0 0 255 0 0\n1 0 0 0 255 0\n0 1 0 0 0 255\n3 0 1 2 9 9 9\n",
        "b.obj": "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\nf 1 2 3\n",  # vt and vn, but no face uses them
        "c.ply": "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
        "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
    }
    for name, text in texts.items():
        soup = mesh_io.read(put(tmp_path, name, text))
        assert (soup.vertex_properties, soup.polygon_properties, soup.corner_properties) == ({}, {}, {}), name
    path = tmp_path / "d.ply"
    write_ply(path, POSITIONS, OFFSETS, INDICES)
    soup = read_ply(path)
    assert (soup.vertex_properties, soup.polygon_properties, soup.corner_properties) == ({}, {}, {})


# -- PLY reading ------------------------------------------------------------------


def test_meshlab_ply_vertex_colours():
    soup = mesh_io.read(require_shared_meshes() / "meshlab.ply")
    assert list(soup.vertex_properties) == ["red", "green", "blue", "alpha"]
    assert soup.polygon_properties == {} and soup.corner_properties == {}
    for name, value in [("red", 0), ("green", 0), ("blue", 255), ("alpha", 255)]:
        column = soup.vertex_properties[name]
        assert column.dtype == np.int64 and column.shape == (8,)
        assert (column == value).all(), (name, column)


def test_shared_plys_without_properties():
    folder = require_shared_meshes()
    for name in ["cube-minimal.ply", "sphere840.ply", "bob_small.ply"]:
        soup = mesh_io.read(folder / name)
        assert soup.vertex_properties == {} and soup.polygon_properties == {}, name


ASCII_HEADER = """\
ply
format ascii 1.0
comment per-element data of every type
element vertex 3
property uchar red
property float x
property int8 flag
property float y
property double quality
property float z
property list uchar float extra
element edge 1
property int vertex1
property int vertex2
element face 2
property short before
property list uchar int vertex_indices
property float weight
property uint32 label
end_header
"""


def test_ascii_ply_properties_of_every_type(tmp_path, reader):
    body = (
        "255 0 -128 0 0.25 0 0\n"
        "0 1 127 0 -1e-300 0 2 9 9\n"
        "7 0 0 1 1e300 0.5 1 -0.0\n"
        "0 1\n"
        "-32768 3 0 1 2 0.5 4294967295\n"
        "32767 4 0 1 2 1 1.5 0\n"
    )
    soup = mesh_io.read(put(tmp_path, "t.ply", ASCII_HEADER + body))
    assert list(soup.vertex_properties) == ["red", "flag", "quality"]
    assert list(soup.polygon_properties) == ["before", "weight", "label"]
    v, f = soup.vertex_properties, soup.polygon_properties
    same_bits(v["red"], np.array([255, 0, 7]))
    same_bits(v["flag"], np.array([-128, 127, 0]))
    same_bits(v["quality"], np.array([0.25, -1e-300, 1e300]))
    same_bits(f["before"], np.array([-32768, 32767]))
    same_bits(f["weight"], np.array([0.5, 1.5]))
    same_bits(f["label"], np.array([4294967295, 0]))
    assert soup.positions.tolist() == [[0, 0, 0], [1, 0, 0], [0, 1, 0.5]]
    assert soup.indices.tolist() == [0, 1, 2, 0, 1, 2, 1]
    assert soup.lines.tolist() == [25, 26]


def test_ascii_ply_integral_floats_for_integer_properties_and_negative_zero(tmp_path, reader):
    header = (
        "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty uchar red\n"
        "property double q\nelement face 1\nproperty list uchar int vertex_indices\nproperty double w\n"
        "property int n\nend_header\n"
    )
    soup = mesh_io.read(put(tmp_path, "t.ply", header + "0 0 3.0 -0\n1 1 1e2 -0.0\n2 0 1 -0 -0\n"))
    same_bits(soup.vertex_properties["red"], np.array([3, 100]))
    same_bits(soup.vertex_properties["q"], np.array([-0.0, -0.0]))
    same_bits(soup.polygon_properties["w"], np.array([-0.0]))
    same_bits(soup.polygon_properties["n"], np.array([0]))


@pytest.mark.parametrize(
    "vertex, face, line, fragment",
    [
        ("0 0 0 255\n1 0 0 red\n", "3 0 1 0 1.5\n", 15, "red value 'red' is not an integer"),
        ("0 0 0 255\n1 0 0 1.5\n", "3 0 1 0 1.5\n", 15, "red value '1.5' is not an integer"),
        ("0 0 0 256\n1 0 0 0\n", "3 0 1 0 1.5\n", 14, "red value '256' is out of range for uchar"),
        ("0 0 0 -1\n1 0 0 0\n", "3 0 1 0 1.5\n", 14, "red value '-1' is out of range for uchar"),
        ("0 0 0 nan\n1 0 0 0\n", "3 0 1 0 1.5\n", 14, "red value 'nan' is not an integer"),
        ("0 0 0 1\n1 0 0 0\n", "3 0 1 0 heavy\n", 16, "expected a number, found 'heavy'"),
        ("0 0 0 1\n1 0 0 0\n", "3 0 1 0\n", 16, "face record ends before its property 'weight'"),
    ],
)
def test_malformed_ascii_ply_property_values_name_the_line(tmp_path, reader, vertex, face, line, fragment):
    header = (
        "ply\nformat ascii 1.0\ncomment padding\ncomment padding\nelement vertex 2\nproperty float x\n"
        "property float y\nproperty float z\nproperty uchar red\nelement face 1\n"
        "property list uchar int vertex_indices\nproperty float weight\nend_header\n"
    )
    assert_read_refused(put(tmp_path, "bad.ply", header + vertex + face), line, fragment)


def test_ply_property_declared_twice_is_refused(tmp_path):
    header = (
        "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty uchar red\n"
        "property uchar red\nend_header\n0 0 1 2\n"
    )
    assert_read_refused(put(tmp_path, "twice.ply", header), 3, "the vertex element has two properties 'red'")


BINARY_TYPES = ["char", "uchar", "short", "ushort", "int", "uint", "float", "double", "int8", "uint16", "float32"]
NUMPY_TYPES = {
    "char": "i1", "uchar": "u1", "short": "i2", "ushort": "u2", "int": "i4", "uint": "u4",
    "float": "f4", "double": "f8", "int8": "i1", "uint16": "u2", "float32": "f4",
}  # fmt: skip


def binary_ply(order: str, vertex_columns: dict, faces: list[list[int]], face_columns: dict) -> bytes:
    """A binary PLY (``order`` "<" or ">") with the given property columns (PLY type, values) around the lists."""
    fmt = {"<": "binary_little_endian", ">": "binary_big_endian"}[order]
    header = f"ply\nformat {fmt} 1.0\nelement vertex {len(next(iter(vertex_columns.values()))[1])}\n"
    header += "property float x\nproperty double y\n"
    header += "".join(f"property {t} {name}\n" for name, (t, _) in vertex_columns.items())
    header += "property float z\n"
    header += f"element face {len(faces)}\nproperty uchar first\nproperty list uchar int vertex_indices\n"
    header += "".join(f"property {t} {name}\n" for name, (t, _) in face_columns.items())
    header += "end_header\n"
    n = len(next(iter(vertex_columns.values()))[1])
    fields = [("x", order + "f4"), ("y", order + "f8")]
    fields += [(name, order + NUMPY_TYPES[t]) for name, (t, _) in vertex_columns.items()]
    fields += [("z", order + "f4")]
    vertices = np.zeros(n, dtype=fields)
    vertices["x"] = np.arange(n)
    for name, (_, values) in vertex_columns.items():
        vertices[name] = values
    body = vertices.tobytes()
    for i, polygon in enumerate(faces):
        body += np.array([i % 256, len(polygon)], dtype="u1").tobytes()
        body += np.array(polygon, dtype=order + "i4").tobytes()
        for t, values in face_columns.values():
            body += np.array([values[i]], dtype=order + NUMPY_TYPES[t]).tobytes()
    return header.encode() + body


@pytest.mark.parametrize("order", ["<", ">"])
@pytest.mark.parametrize("arities", ["uniform", "mixed"])  # a structured array, or the record walk
def test_binary_ply_properties_of_every_type_both_byte_orders(tmp_path, order, arities):
    rng = np.random.default_rng(7)
    n = 6
    vertex_columns = {}
    for t in BINARY_TYPES:
        dtype = np.dtype(NUMPY_TYPES[t])
        if dtype.kind == "f":
            with np.errstate(over="ignore"):  # huge doubles become infinite floats
                values = awkward_floats(rng, n).astype(dtype)
        else:
            info = np.iinfo(dtype)
            values = np.array([info.min, info.max, 0, 1, -1 if info.min < 0 else 2, 3], dtype=dtype)
        vertex_columns[f"v_{t}"] = (t, values)
    faces = [[0, 1, 2], [2, 3, 4], [4, 5, 0]] if arities == "uniform" else [[0, 1, 2], [2, 3, 4, 5], [5, 0]]
    face_columns = {"quality": ("double", awkward_floats(rng, 3)), "label": ("int", [-(2**31), 2**31 - 1, 5])}
    path = put(tmp_path, "b.ply", binary_ply(order, vertex_columns, faces, face_columns))
    with np.errstate(over="ignore"):
        soup = mesh_io.read(path)
    assert soup.lines is None
    assert list(soup.vertex_properties) == list(vertex_columns)
    for name, (t, values) in vertex_columns.items():
        kind = np.float64 if np.dtype(NUMPY_TYPES[t]).kind == "f" else np.int64
        same_bits(soup.vertex_properties[name], values.astype(kind))
    assert list(soup.polygon_properties) == ["first", "quality", "label"]
    same_bits(soup.polygon_properties["first"], np.array([0, 1, 2]))
    same_bits(soup.polygon_properties["quality"], face_columns["quality"][1])
    same_bits(soup.polygon_properties["label"], np.array([-(2**31), 2**31 - 1, 5]))
    assert [soup.indices[a:b].tolist() for a, b in zip(soup.offsets[:-1], soup.offsets[1:])] == faces
    assert soup.positions[:, 0].tolist() == list(range(n))


# -- PLY writing ------------------------------------------------------------------


@pytest.mark.parametrize("binary", [True, False])
@pytest.mark.parametrize("uniform", [True, False])
def test_ply_round_trip_is_bit_exact(tmp_path, reader, binary, uniform):
    rng = np.random.default_rng(11)
    offsets, indices = OFFSETS, INDICES
    if uniform:
        offsets, indices = np.array([0, 3, 6, 9]), np.array([0, 1, 2, 2, 3, 4, 4, 5, 6])
    vertex_properties = {
        "quality": awkward_floats(rng, 7),
        "normal": rng.standard_normal((7, 3)),
        "id": rng.integers(-(2**31), 2**31, 7),
        "mark": np.array([True, False, True, True, False, False, True]),
        "count": np.arange(7, dtype=np.uint16),
        "single": np.float32([0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7]),
    }
    polygon_properties = {"area": awkward_floats(rng, 3), "group": np.array([[1, 2], [3, 4], [-5, 6]])}
    path = tmp_path / "r.ply"
    write_ply(
        path,
        POSITIONS,
        offsets,
        indices,
        binary=binary,
        vertex_properties=vertex_properties,
        polygon_properties=polygon_properties,
    )
    soup = read_ply(path)
    same_bits(soup.positions, POSITIONS)
    same_bits(soup.offsets, offsets)
    same_bits(soup.indices, indices)
    v, f = soup.vertex_properties, soup.polygon_properties
    assert list(v) == ["quality", "normal_0", "normal_1", "normal_2", "id", "mark", "count", "single"]
    same_bits(v["quality"], vertex_properties["quality"])
    for j in range(3):
        same_bits(v[f"normal_{j}"], vertex_properties["normal"][:, j])
    same_bits(v["id"], vertex_properties["id"])
    same_bits(v["mark"], np.array([1, 0, 1, 1, 0, 0, 1]))
    same_bits(v["count"], np.arange(7))
    same_bits(v["single"], vertex_properties["single"].astype(np.float64))
    assert list(f) == ["area", "group_0", "group_1"]
    same_bits(f["area"], polygon_properties["area"])
    same_bits(f["group_0"], np.array([1, 3, -5]))
    same_bits(f["group_1"], np.array([2, 4, 6]))


def test_ply_round_trip_keeps_nan(tmp_path):
    for binary in (True, False):
        write_ply(tmp_path / "n.ply", POSITIONS, OFFSETS, INDICES, binary=binary,
                  vertex_properties={"q": [NAN, 1, NAN, 2, 3, 4, 5]})  # fmt: skip
        q = read_ply(tmp_path / "n.ply").vertex_properties["q"]
        assert np.isnan(q[[0, 2]]).all() and q[[1, 3, 4, 5, 6]].tolist() == [1, 2, 3, 4, 5]


def test_ply_writes_properties_after_coordinates_and_index_list(tmp_path):
    path = tmp_path / "h.ply"
    write_ply(path, POSITIONS[:3], [0, 3], [0, 1, 2], binary=False,
              vertex_properties={"c": np.array([[1, 2], [3, 4], [5, 6]], dtype=np.int8)},
              polygon_properties={"on": [True], "w": [0.1]})  # fmt: skip
    assert path.read_text().splitlines()[2:] == [
        "element vertex 3",
        "property double x",
        "property double y",
        "property double z",
        "property int c_0",
        "property int c_1",
        "element face 1",
        "property list uchar int vertex_indices",
        "property uchar on",
        "property double w",
        "end_header",
        "0.0 0.0 0.0 1 2",
        "1.0 0.0 0.0 3 4",
        "1.0 1.0 0.0 5 6",
        "3 0 1 2 1 0.1",
    ]


@pytest.mark.parametrize(
    "vertex_properties, polygon_properties, fragment",
    [
        ({"": [0] * 7}, None, "vertex property name '' is not a PLY word"),
        ({"has space": [0] * 7}, None, "vertex property name 'has space' is not a PLY word"),
        ({"tab\tbed": [0] * 7}, None, "is not a PLY word"),
        ({"rouge\u00e9": [0] * 7}, None, "is not a PLY word"),
        ({3: [0] * 7}, None, "vertex property name 3 is not a PLY word"),
        ({"x": [0] * 7}, None, "vertex property name 'x' is taken by the positions"),
        ({"p": np.zeros((7, 3)), "p_1": [0] * 7}, None, "vertex property name 'p_1' is taken by property 'p'"),
        (None, {"vertex_indices": [0] * 3}, "face property name 'vertex_indices' is taken by the index list"),
        (None, {"vertex_index": [0] * 3}, "face property name 'vertex_index' is taken by the index list"),
        ({"short": [0] * 6}, None, "vertex property 'short' must have shape (7,) or (7, k), not (6,)"),
        ({"flat": np.zeros((7, 0))}, None, "vertex property 'flat' must have shape (7,) or (7, k), not (7, 0)"),
        ({"cube": np.zeros((7, 2, 2))}, None, "must have shape (7,) or (7, k), not (7, 2, 2)"),
        ({"scalar": 3.0}, None, "must have shape (7,) or (7, k), not ()"),
        (None, {"big": [0, 2**31, 1]}, "face property 'big' has values beyond the 32 bits of a PLY int"),
        (None, {"small": [0, -(2**31) - 1, 1]}, "face property 'small' has values beyond the 32 bits"),
        (None, {"text": ["a", "b", "c"]}, "face property 'text' must be of numbers or bools, not <U1"),
        (None, {"z": [1 + 2j] * 3}, "must be of numbers or bools, not complex128"),
        ([("red", [0] * 7)], None, "vertex properties must map names to arrays, not be a list"),
    ],
)
def test_ply_writer_refuses_bad_properties_and_writes_nothing(
    tmp_path, vertex_properties, polygon_properties, fragment
):
    path = tmp_path / "bad.ply"
    for binary in (True, False):
        with pytest.raises(InvalidInputError) as info:
            write_ply(path, POSITIONS, OFFSETS, INDICES, binary=binary,
                      vertex_properties=vertex_properties, polygon_properties=polygon_properties)  # fmt: skip
        assert fragment in str(info.value), str(info.value)
        assert not path.exists()


def test_ply_vertex_and_face_properties_may_share_names(tmp_path):
    path = tmp_path / "s.ply"
    write_ply(path, POSITIONS, OFFSETS, INDICES, vertex_properties={"id": np.arange(7)},
              polygon_properties={"id": np.arange(3), "x": [1.0, 2.0, 3.0]})  # fmt: skip
    soup = read_ply(path)
    same_bits(soup.vertex_properties["id"], np.arange(7))
    same_bits(soup.polygon_properties["id"], np.arange(3))
    same_bits(soup.polygon_properties["x"], np.array([1.0, 2.0, 3.0]))


# -- OBJ reading ------------------------------------------------------------------


def test_spot_obj_texture_coordinates():
    path = require_shared_meshes() / "spot.obj"
    soup = mesh_io.read(path)
    assert list(soup.corner_properties) == ["uv"]
    uv = soup.corner_properties["uv"]
    assert uv.dtype == np.float64 and uv.shape == (len(soup.indices), 2)
    assert np.isfinite(uv).all()  # every corner of spot refers to a vt
    # A texture atlas: in [0, 1] but for a few vt lines just outside it (-0.05 .. 1.0007).
    assert ((uv > -0.06) & (uv < 1.001)).all()
    assert 0.9 < np.mean((uv >= 0) & (uv <= 1)) < 1
    vt = np.array(
        [line.split()[1:3] for line in path.read_text().splitlines() if line.startswith("vt ")], dtype=float
    )
    assert len(vt) == 3225
    assert len(np.unique(uv, axis=0)) <= len(vt)
    assert uv.min() == vt.min() and uv.max() == vt.max()
    # Corner by corner, the uv is the vt row the face refers to.
    refs = [
        int(ref.split("/")[1]) - 1
        for line in path.read_text().splitlines()
        if line.startswith("f ")
        for ref in line.split()[1:]
    ]
    same_bits(uv, vt[refs])


def test_shared_objs_with_normals():
    folder = require_shared_meshes()
    quadknot = mesh_io.read(folder / "quadknot.obj")
    assert list(quadknot.corner_properties) == ["uv", "normal"]
    assert quadknot.corner_properties["uv"].shape == (len(quadknot.indices), 2)
    normal = quadknot.corner_properties["normal"]
    assert normal.shape == (len(quadknot.indices), 3) and np.isfinite(normal).all()
    np.testing.assert_allclose(np.linalg.norm(normal, axis=1), 1, atol=1e-5)
    for name in ["cube-minimal-degenerated.obj", "joined_tetrahedra.obj"]:
        soup = mesh_io.read(folder / name)
        assert list(soup.corner_properties) == ["normal"], name
        assert soup.corner_properties["normal"].shape == (len(soup.indices), 3)
        assert np.isfinite(soup.corner_properties["normal"]).all()
    joined = mesh_io.read(folder / "joined_tetrahedra.obj")
    assert joined.corner_properties["normal"][:3].tolist() == [[1, 0, 0]] * 3


OBJ_CORNERS = """\
v 0 0 0
v 1 0 0
vt 0.5 0.25
vn 0 0 1
v 1 1 0
v 0 1 0
vt 0.125
vt 1 2 3
vn 0 1 0 # a comment
vn 1 0 0 9
f 1/1 2/2 3/3
f 1//1 2//3 3//2 4
f 4/1/1 3/2/2 2/3/3 1
f -1/-1/-1 -2/-2 -3//-3
vt 7 8
f 1/4 2/-1 3/3/1
f 1/5 2 3
vt 9 10
"""


def test_obj_corner_references_every_syntax(tmp_path, reader):
    soup = mesh_io.read(put(tmp_path, "c.obj", "# padding\n" * 5 + OBJ_CORNERS))
    assert soup.indices.tolist() == [0, 1, 2, 0, 1, 2, 3, 3, 2, 1, 0, 3, 2, 1, 0, 1, 2, 0, 1, 2]
    uv = soup.corner_properties["uv"]
    normal = soup.corner_properties["normal"]
    a, b, c, d, e = [0.5, 0.25], [0.125, 0.0], [1.0, 2.0], [7.0, 8.0], [9.0, 10.0]
    x, y, z = [0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]
    no2, no3 = [NAN] * 2, [NAN] * 3
    expected_uv = [a, b, c] + [no2] * 4 + [a, b, c, no2] + [c, b, no2] + [d, d, c] + [e, no2, no2]
    expected_normal = [no3] * 3 + [x, z, y, no3] + [x, y, z, no3] + [z, no3, x] + [no3, no3, x] + [no3] * 3
    same_bits(uv, np.array(expected_uv))
    same_bits(normal, np.array(expected_normal))


@pytest.mark.parametrize(
    "face, line, fragment",
    [
        ("f 1/3 2/1 3/1\n", 10, "texture coordinate index 3 is out of range for 2 vt lines"),
        ("f 1//1 2//1 3//4\n", 10, "normal index 4 is out of range for 1 vn lines"),
        ("f 1/0 2/1 3/1\n", 10, "texture coordinate index 0 is invalid"),
        ("f 1//0 2//1 3//1\n", 10, "normal index 0 is invalid"),
        ("f 1/-3 2/1 3/1\n", 10, "texture coordinate index -3 counts back past the first of the 2 vt lines so far"),
        ("f 1//1 2//-2 3//1\n", 10, "normal index -2 counts back past the first of the 1 vn lines so far"),
        ("f 1/1 2/x 3/1\n", 10, "texture coordinate index 'x' is not an integer"),
        ("f 1/1 2/1.5 3/1\n", 10, "texture coordinate index '1.5' is not an integer"),
        ("f 1//1 2//1 3//n\n", 10, "normal index 'n' is not an integer"),
        ("f 1/1/1/1 2 3\n", 10, "vertex reference '1/1/1/1' has more than three parts"),
        ("f 1/1/1/ 2 3\n", 10, "vertex reference '1/1/1/' has more than three parts"),
        ("f 1/99999999999999999999 2 3\n", 10, "texture coordinate index 9223372036854775807 is out of range"),
        ("vt\n", 10, "a texture coordinate needs at least 1 number, found 0"),
        ("vt 0 nan\n", 10, "coordinate 'nan' is not finite"),
        ("vt 0 zero\n", 10, "expected a number, found 'zero'"),
        ("vn 0 1\n", 10, "a normal needs 3 numbers, found 2"),
        ("vn 0 1 inf\n", 10, "coordinate 'inf' is not finite"),
        ("vt 0 1 \\\n 2\n", 10, "line continuations"),
    ],
)
def test_malformed_obj_corner_references_name_file_and_line(tmp_path, reader, face, line, fragment):
    text = "# padding\n" * 3 + "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 1\nvn 0 0 1\n" + face + "f 1 2 3\n"
    assert_read_refused(put(tmp_path, "bad.obj", text), line, fragment)


def test_obj_forward_texture_references_resolve_against_the_whole_file(tmp_path, reader):
    soup = mesh_io.read(put(tmp_path, "f.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/2 2/1 3\nvt 0 0\nvt 1 1\n"))
    same_bits(soup.corner_properties["uv"], np.array([[1.0, 1.0], [0.0, 0.0], [NAN, NAN]]))
    # Out of range however far the file goes: the line of the face is named.
    obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/3 2/1 3\nvt 0 0\nvt 1 1\n"
    assert_read_refused(put(tmp_path, "g.obj", obj), 4, "index 3")


# -- OBJ writing ------------------------------------------------------------------


def corner_data(rng: np.random.Generator, n: int, width: int, missing: np.ndarray) -> np.ndarray:
    values = awkward_floats(rng, n * width).reshape(n, width)
    values[~np.isfinite(values)] = 0.5
    values[missing] = NAN
    return values


@pytest.mark.parametrize("which", ["uv", "normal", "both"])
def test_obj_round_trip_is_bit_exact(tmp_path, reader, which):
    rng = np.random.default_rng(5)
    n = len(INDICES)
    corners = {}
    if which in ("uv", "both"):
        uv = corner_data(rng, n, 2, rng.random(n) < 0.3)
        uv[5] = uv[1]  # shared rows are written once
        uv[6] = [0.0, -0.0]  # and -0.0 is not 0.0
        uv[7] = [0.0, 0.0]
        corners["uv"] = uv
    if which in ("normal", "both"):
        corners["normal"] = corner_data(rng, n, 3, rng.random(n) < 0.3)
    corners["colour"] = np.zeros((n, 3))  # ignored by OBJ
    path = tmp_path / "r.obj"
    write_obj(path, POSITIONS, OFFSETS, INDICES, corner_properties=corners)
    soup = read_obj(path)
    same_bits(soup.positions, POSITIONS)
    same_bits(soup.offsets, OFFSETS)
    same_bits(soup.indices, INDICES)
    assert list(soup.corner_properties) == [k for k in ("uv", "normal") if k in corners]
    for name, values in soup.corner_properties.items():
        same_bits(values, corners[name])
    text = path.read_text()
    if "uv" in corners:
        present = corners["uv"][~np.isnan(corners["uv"]).all(axis=1)]
        distinct = {tuple(row) for row in present.view(np.uint64).tolist()}
        assert text.count("\nvt ") == len(distinct)


def test_obj_writer_per_corner_references(tmp_path):
    path = tmp_path / "m.obj"
    uv = [(0, 0), (NAN, NAN), (0, 0), (1, 0)]
    normal = [(NAN, NAN, NAN), (0, 0, 1), (0, 0, 1), (NAN, NAN, NAN)]
    write_obj(path, POSITIONS[:4], [0, 4], [0, 1, 2, 3], corner_properties={"uv": uv, "normal": normal})
    assert path.read_text().splitlines()[4:] == ["vt 0.0 0.0", "vt 1.0 0.0", "vn 0.0 0.0 1.0", "f 1/1 2//1 3/1/1 4/2"]
    # All-NaN corner data writes no references, and reads back as none.
    write_obj(path, POSITIONS[:4], [0, 4], [0, 1, 2, 3], corner_properties={"uv": np.full((4, 2), NAN)})
    assert path.read_text().splitlines()[-1] == "f 1 2 3 4"
    assert read_obj(path).corner_properties == {}


@pytest.mark.parametrize(
    "corners, fragment",
    [
        ({"uv": np.zeros((12, 3))}, "property 'uv' must be numbers of shape (12, 2), not float64 of shape (12, 3)"),
        ({"normal": np.zeros(12)}, "corner property 'normal' must be numbers of shape (12, 3)"),
        ({"uv": np.zeros((11, 2))}, "of shape (11, 2)"),
        ({"uv": np.full((12, 2), "a")}, "must be numbers of shape (12, 2), not <U1"),
        ({"uv": np.array([[0.0, NAN]] + [[0, 0]] * 11)}, "property 'uv' of corner 0 is neither finite nor all NaN"),
        ({"normal": np.array([[0, 0, 1]] * 5 + [[0, np.inf, 0]] + [[0, 0, 1]] * 6)}, "of corner 5 is neither finite"),
        ([("uv", np.zeros((12, 2)))], "corner properties must map names to arrays, not be a list"),
    ],
)
def test_obj_writer_refuses_bad_corner_data_and_writes_nothing(tmp_path, corners, fragment):
    path = tmp_path / "bad.obj"
    with pytest.raises(InvalidInputError) as info:
        write_obj(path, POSITIONS, OFFSETS, INDICES, corner_properties=corners)
    assert fragment in str(info.value), str(info.value)
    assert not path.exists()


# -- hestore.io.write ------------------------------------------------------------


def test_write_passes_each_format_what_it_holds(tmp_path):
    rng = np.random.default_rng(3)
    vertex = {"q": rng.random(7)}
    polygon = {"label": np.array([1, 2, 3])}
    corner = {"uv": rng.random((len(INDICES), 2))}
    for name in ["m.ply", "m.obj", "m.off"]:
        path = tmp_path / name
        mesh_io.write(path, POSITIONS, OFFSETS, INDICES, vertex_properties=vertex, polygon_properties=polygon,
                      corner_properties=corner)  # fmt: skip
        soup = mesh_io.read(path)
        same_bits(soup.positions, POSITIONS)
        if name.endswith(".ply"):
            assert list(soup.vertex_properties) == ["q"] and list(soup.polygon_properties) == ["label"]
            same_bits(soup.vertex_properties["q"], vertex["q"])
            assert soup.corner_properties == {}
        elif name.endswith(".obj"):
            assert soup.vertex_properties == {} and soup.polygon_properties == {}
            same_bits(soup.corner_properties["uv"], corner["uv"])
        else:
            assert (soup.vertex_properties, soup.polygon_properties, soup.corner_properties) == ({}, {}, {})
    mesh_io.write(tmp_path / "a.ply", POSITIONS, OFFSETS, INDICES, binary=False, vertex_properties=vertex)
    assert "format ascii" in (tmp_path / "a.ply").read_text()
    with pytest.raises(InvalidInputError, match="not a PLY word"):
        mesh_io.write(tmp_path / "b.ply", POSITIONS, OFFSETS, INDICES, vertex_properties={"a b": rng.random(7)})
    # A format ignores what it cannot hold, malformed or not.
    mesh_io.write(tmp_path / "b.off", POSITIONS, OFFSETS, INDICES, vertex_properties={"a b": [1]})


# -- The vectorised readers take properties without the per-line reader ----------


def test_vectorised_readers_take_properties_themselves(tmp_path, monkeypatch):
    def per_line(*args):
        raise AssertionError("the per-line reader ran")

    monkeypatch.setattr(obj_module, "_chunk_slow", per_line)
    monkeypatch.setattr(common.Positions, "slow", per_line)
    monkeypatch.setattr(common.Faces, "slow", per_line)
    folder = require_shared_meshes()
    for name in ["spot.obj", "quadknot.obj", "cube-minimal-degenerated.obj", "joined_tetrahedra.obj", "meshlab.ply"]:
        mesh_io.read(folder / name)
    soup = mesh_io.read(put(tmp_path, "c.obj", OBJ_CORNERS))
    assert list(soup.corner_properties) == ["uv", "normal"]
    rng = np.random.default_rng(2)
    path = tmp_path / "r.obj"
    corners = {"uv": rng.random((len(INDICES), 2)), "normal": rng.random((len(INDICES), 3))}
    corners["uv"][[1, 4]] = NAN
    write_obj(path, POSITIONS, OFFSETS, INDICES, corner_properties=corners)
    assert read_obj(path).corner_properties.keys() == corners.keys()
    write_ply(tmp_path / "r.ply", POSITIONS, OFFSETS, INDICES, binary=False,
              vertex_properties={"q": rng.random(7), "i": np.arange(7)},
              polygon_properties={"w": rng.random(3), "i": np.arange(3)})  # fmt: skip
    assert list(read_ply(tmp_path / "r.ply").polygon_properties) == ["w", "i"]
