"""Properties and positions (SPEC §3 "Geometry", §3.2, §4), on SQLite and PostgreSQL.

* every dtype × shape × kind: declaring, defaults (and none: None / masked),
  per-element and set-based reads and writes, each path reading what the
  other wrote; shapes that cross the four-components-per-row boundary;
* bit-exact round trips: float64 specials and random bit patterns, int64
  extremes, unicode and long text;
* strict value checks, per element and set-based: the typed error, a message
  naming the property and the element, and nothing written;
* `PropertyNotFoundError` for unknown names; duplicate names;
* transactions: rollbacks, savepoints, revision counting, isolation from
  another connection; the order of single and set-based writes in one block;
* removing elements (and properties) removes their value rows; new elements
  read the default;
* positions: single and set-based writes, refusals, rollback, ordering;
* `mesh.check()` stays clean, and reports value rows of missing elements.
"""

from __future__ import annotations

import contextlib
import math
import re

import numpy as np
import pytest
import sqlalchemy as sa

import hestore
from hestore import schema
from hestore.errors import ElementNotFoundError, HestoreError, InvalidInputError, PropertyNotFoundError
from hestore._values import Property

from helpers import Rollback

KINDS = ("vertex", "halfedge", "edge", "polygon")
WHAT = {"vertex": "vertex", "halfedge": r"half-?edge", "edge": "edge", "polygon": "polygon"}
ALL_TABLES = (
    schema.meshes, schema.vertices, schema.halfedges, schema.edges, schema.polygons,
    schema.properties, schema.property_reals, schema.property_integers, schema.property_texts,
)
VALUE_TABLES = (schema.property_reals, schema.property_integers, schema.property_texts)
ITER = {"vertex": "vertices", "halfedge": "halfedges", "edge": "edges", "polygon": "polygons"}
NUMPY_DTYPE = {"float64": np.float64, "int64": np.int64, "bool": np.bool_, "str": object}


# --------------------------------------------------------------------------
# Helpers


def build(mesh):
    """Two triangles sharing an edge, a wire edge and an isolated vertex.

    Vertices 0..5, edges 0..5 (half-edges 0..11), polygons 0 and 1.
    """
    a, b, c, d, e, f = (mesh.add_vertex((float(i), float(i % 2), 0.0)) for i in range(6))
    mesh.add_polygon([a, b, c])
    mesh.add_polygon([a, c, d])
    mesh.add_edge(d, e)
    return [a, b, c, d, e, f]


def element_ids(mesh, kind: str) -> list[int]:
    return [h.id for h in getattr(mesh, ITER[kind])()]


def handle(mesh, kind: str, i: int):
    return getattr(mesh, kind)(i)


def everything(store) -> dict[str, list[tuple]]:
    """Every row of every table (topology, positions, catalogue, values), through the store's connection.

    Without ``rev``, the revision that wrote a row: a rewrite of equal values is a revision of its own.
    """
    with store.session.reading() as conn:
        return {
            t.name: sorted(tuple(r) for r in conn.execute(sa.select(*(c for c in t.c if c.name != "rev"))))
            for t in ALL_TABLES
        }


def value_keys(store, mesh, prop=None) -> set[tuple[int, int]]:
    """``(property id, element id)`` of every stored value row of the mesh (of one property)."""
    out = set()
    with store.session.reading() as conn:
        for t in VALUE_TABLES:
            q = sa.select(t.c.property, t.c.id).where(t.c.mesh_id == mesh.id)
            if prop is not None:
                q = q.where(t.c.property == prop.id)
            out |= {(int(p), int(i)) for p, i in conn.execute(q)}
    return out


def as_values(array) -> list:
    """An array from `property_array` as a list of Python values (tuples for shaped, None where masked)."""

    def one(x):
        if not isinstance(x, list):
            return x
        return None if all(c is None for c in x) else tuple(x)

    return [one(x) for x in array.tolist()]


def sample(dtype: str, shape: tuple, i: int, salt: int = 0):
    """A distinct value of a dtype and shape for element ``i``."""

    def one(c: int):
        if dtype == "float64":
            return (i + 1) * 1.25 + c * 0.5 - 4.0 + salt * 100.0
        if dtype == "int64":
            return (i + 1) * 1000 - c * 7 - 3 + salt * 10**6
        if dtype == "bool":
            return (i + c + salt) % 2 == 0
        return f"é{i}-✓-{c}-{salt}"

    return one(0) if not shape else tuple(one(c) for c in range(shape[0]))


def default_of(dtype: str, shape: tuple):
    one = {"float64": -1.5, "int64": -(2**40), "bool": True, "str": "none"}[dtype]
    return one if not shape else tuple(one for _ in range(shape[0]))


def to_array(dtype: str, shape: tuple, vals: list):
    if dtype == "str":
        out = np.empty(len(vals), dtype=object)
        out[:] = vals
        return out
    return np.array(vals, dtype=NUMPY_DTYPE[dtype]).reshape((len(vals),) + shape)


def assert_array(mesh, kind, name, expected: dict, prop):
    """`property_array` and every handle read give ``expected`` (id -> value; missing: default)."""
    ids, arr = mesh.property_array(kind, name)
    live = element_ids(mesh, kind)
    assert ids.tolist() == live
    assert ids.dtype.kind == "i"
    assert arr.shape == (len(live),) + prop.shape
    assert arr.dtype == np.dtype(NUMPY_DTYPE[prop.dtype])
    want = [expected.get(i, prop.default) for i in live]
    assert isinstance(arr, np.ma.MaskedArray) == (prop.default is None)
    if prop.default is None:
        mask = np.ma.getmaskarray(arr).reshape(len(live), -1)
        assert mask.all(axis=1).tolist() == [w is None for w in want]
        assert (mask.any(axis=1) == mask.all(axis=1)).all()
    assert as_values(arr) == want
    some = sorted({0, 1, len(live) - 1}) if len(live) > 3 else range(len(live))
    assert [handle(mesh, kind, live[j])[name] for j in some] == [want[j] for j in some]


def assert_bits(got, want) -> None:
    got, want = np.asarray(got, dtype=np.float64), np.asarray(want, dtype=np.float64)
    assert got.shape == want.shape
    assert np.array_equal(got, want, equal_nan=True)
    real = ~np.isnan(want)
    assert np.isnan(got[~real]).all()
    assert np.array_equal(got[real].view(np.int64), want[real].view(np.int64))


# --------------------------------------------------------------------------
# Every dtype × shape × kind

CASES = (
    [("float64", ())] + [("float64", (k,)) for k in (1, 2, 3, 4, 5, 9)]
    + [("int64", ())] + [("int64", (k,)) for k in (1, 2, 3, 4, 5, 9)]
    + [("bool", ()), ("str", ())]
)


@pytest.mark.parametrize("dtype,shape", CASES, ids=[f"{d}{list(s)}" for d, s in CASES])
def test_every_dtype_shape_and_kind(store, mesh, dtype, shape):
    build(mesh)
    for kind in KINDS:
        default = default_of(dtype, shape)
        rev = mesh.revision
        d = mesh.add_property(kind, "d", dtype, shape=shape, default=default)
        n = mesh.add_property(kind, "n", dtype, shape=shape)
        assert d == Property(kind, "d", dtype, shape, default)
        assert (d.kind, d.name, d.dtype, d.shape, d.default) == (kind, "d", dtype, shape, default)
        assert (n.kind, n.name, n.dtype, n.shape, n.default) == (kind, "n", dtype, shape, None)
        assert mesh.properties(kind) == {"d": d, "n": n}
        assert list(mesh.properties(kind)) == ["d", "n"]
        assert mesh.revision > rev
        live = element_ids(mesh, kind)
        expect = {"d": {}, "n": {}}
        for name, prop in (("d", d), ("n", n)):
            assert_array(mesh, kind, name, {}, prop)
        # per element: every other element, read back both ways ("n" in one block, whose reads see its writes)
        for name, prop in (("d", d), ("n", n)):
            rev = mesh.revision
            with store.transaction() if name == "n" else contextlib.nullcontext():
                for j, i in enumerate(live[::2]):
                    value = sample(dtype, shape, i)
                    handle(mesh, kind, i)[name] = value
                    assert mesh.revision == rev + (1 if name == "n" else j + 1)
                    expect[name][i] = value
                    assert handle(mesh, kind, i)[name] == value
                assert_array(mesh, kind, name, expect[name], prop)
            assert mesh.revision == rev + (1 if name == "n" else len(live[::2]))
        # set-based: the others (handles for one property, ids for the other), read back both ways
        for name, prop in (("d", d), ("n", n)):
            chosen = live[1::2]
            vals = [sample(dtype, shape, i, salt=1) for i in chosen]
            targets = [handle(mesh, kind, i) for i in chosen] if name == "d" else np.array(chosen)
            rev = mesh.revision
            mesh.set_property_array(kind, name, targets, to_array(dtype, shape, vals))
            assert mesh.revision == rev + 1
            expect[name].update(zip(chosen, vals))
            for i, value in zip(chosen, vals):
                assert handle(mesh, kind, i)[name] == value
            assert_array(mesh, kind, name, expect[name], prop)
        # set-based over everything, overwriting per-element values; some entries unset (masked)
        for name, prop in (("d", d), ("n", n)):
            vals = [sample(dtype, shape, i, salt=2) for i in live]
            arr = to_array(dtype, shape, vals)
            unset = np.array([j % 3 == 1 for j in range(len(live))])
            if dtype == "str" and name == "n":
                arr[unset] = None  # None in a str array unsets too
            else:
                mask = np.broadcast_to(unset.reshape((-1,) + (1,) * len(shape)), arr.shape)
                arr = np.ma.MaskedArray(arr, mask=mask.copy())
            mesh.set_property_array(kind, name, live, arr)
            expect[name] = {i: v for i, v, u in zip(live, vals, unset) if not u}
            assert_array(mesh, kind, name, expect[name], prop)
        # per element again after the set-based writes, then unset one
        i = live[0]
        handle(mesh, kind, i)["d"] = sample(dtype, shape, i, salt=3)
        expect["d"][i] = sample(dtype, shape, i, salt=3)
        assert_array(mesh, kind, "d", expect["d"], d)
        del handle(mesh, kind, i)["d"]
        expect["d"].pop(i)
        handle(mesh, kind, live[-1])["n"] = None  # None unsets as well
        expect["n"].pop(live[-1], None)
        for name, prop in (("d", d), ("n", n)):
            assert_array(mesh, kind, name, expect[name], prop)
        # a set-based read fed back into a set-based write changes nothing
        before = everything(store)
        ids, arr = mesh.property_array(kind, "n")
        mesh.set_property_array(kind, "n", ids, arr)
        assert_array(mesh, kind, "n", expect["n"], n)
        assert everything(store)["property_reals" if dtype == "float64" else
                                 "property_texts" if dtype == "str" else "property_integers"] == \
            before["property_reals" if dtype == "float64" else
                   "property_texts" if dtype == "str" else "property_integers"]
    assert mesh.check() == []


def test_reads_give_python_values(mesh):
    v = mesh.add_vertex()
    mesh.add_property("vertex", "f", "float64", default=0)
    mesh.add_property("vertex", "i", "int64", shape=(2,), default=(1, 2))
    mesh.add_property("vertex", "b", "bool", default=False)
    mesh.add_property("vertex", "s", "str", default="")
    assert type(v["f"]) is float and v["f"] == 0.0
    assert v["i"] == (1, 2) and all(type(x) is int for x in v["i"])
    assert v["b"] is False
    assert v["s"] == ""
    v["f"], v["i"], v["b"], v["s"] = np.int64(3), np.array([4, 5]), np.bool_(True), "x"
    assert type(v["f"]) is float and v["f"] == 3.0
    assert v["i"] == (4, 5) and all(type(x) is int for x in v["i"])
    assert v["b"] is True
    assert v["s"] == "x"
    assert mesh.properties("vertex")["i"].default == (1, 2)


def test_defaults_of_every_dtype(mesh):
    vs = [mesh.add_vertex() for _ in range(3)]
    cases = {
        "f": ("float64", (), 2.5), "fnan": ("float64", (), math.nan), "finf": ("float64", (3,), (math.inf, -1, 0)),
        "i": ("int64", (), -(2**63)), "i5": ("int64", (5,), (2**63 - 1, 0, -1, 1, 7)),
        "b": ("bool", (), False), "s": ("str", (), "dé✓faut"), "e": ("str", (), ""),
    }
    for name, (dtype, shape, default) in cases.items():
        mesh.add_property("vertex", name, dtype, shape=shape, default=default)
    for name, (dtype, shape, default) in cases.items():
        prop = mesh.properties("vertex")[name]
        want = tuple(float(x) for x in default) if dtype == "float64" and shape else default
        if name == "fnan":
            assert math.isnan(prop.default) and math.isnan(vs[1][name])
            assert np.isnan(mesh.property_array("vertex", name)[1]).all()
            continue
        assert prop.default == want
        assert vs[1][name] == want
        ids, arr = mesh.property_array("vertex", name)
        assert as_values(arr) == [want] * 3
    # a default must fit the property
    for dtype, shape, bad in [("float64", (), "0"), ("int64", (), 0.5), ("bool", (), 1), ("str", (), 0),
                              ("float64", (2,), (1.0,)), ("int64", (3,), 3), ("str", (), "a\x00")]:
        with pytest.raises(InvalidInputError):
            mesh.add_property("edge", "bad", dtype, shape=shape, default=bad)
    assert mesh.properties("edge") == {}


@pytest.mark.parametrize("dtype,shape,why", [
    ("str", (2,), "shaped str"), ("bool", (1,), "shaped bool"), ("float64", (0,), "k = 0"),
    ("float64", (1025,), "k > 1024"), ("int64", (2, 2), "2-D"), ("float64", [3], "a list"),
    ("float32", (), "dtype"), ("object", (), "dtype"), ("float64", (2.0,), "float k"), ("int64", (True,), "bool k"),
])
def test_bad_declarations(mesh, dtype, shape, why):
    rev = mesh.revision
    with pytest.raises(InvalidInputError):
        mesh.add_property("vertex", "p", dtype, shape=shape)
    assert mesh.properties("vertex") == {}
    assert mesh.revision == rev


def test_bad_names_and_kinds(mesh):
    for name in ["", "   ", "a\x00b", "tab\there", 5, None, "x" * 256]:
        with pytest.raises(InvalidInputError):
            mesh.add_property("vertex", name, "float64")
    for kind in ["face", "Vertex", "vertices", None]:
        with pytest.raises(InvalidInputError):
            mesh.add_property(kind, "p", "float64")
    assert mesh.properties("vertex") == {}
    assert mesh.add_property("vertex", "x" * 255, "float64").name == "x" * 255
    assert mesh.add_property("vertex", "é ✓ name", "float64").name == "é ✓ name"


def test_largest_shape(store, mesh):
    vs = [mesh.add_vertex() for _ in range(3)]
    mesh.add_property("vertex", "big", "float64", shape=(1024,))
    mesh.add_property("vertex", "bigi", "int64", shape=(1023,), default=tuple(range(1023)))
    rng = np.random.default_rng(7)
    data = rng.standard_normal((3, 1024))
    mesh.set_property_array("vertex", "big", vs, data)
    vs[1]["bigi"] = tuple(range(1023, 0, -1))
    _, got = mesh.property_array("vertex", "big")
    assert_bits(np.ma.getdata(got), data)
    assert vs[2]["big"] == tuple(data[2].tolist())
    assert as_values(mesh.property_array("vertex", "bigi")[1]) == [
        tuple(range(1023)), tuple(range(1023, 0, -1)), tuple(range(1023))]
    assert mesh.check() == []


# --------------------------------------------------------------------------
# Bit-exact round trips

FLOAT_SPECIALS = [
    0.0, 5e-324, -5e-324, 2.2250738585072014e-308, 2.225073858507201e-308, -2.225073858507201e-308,
    1.7976931348623157e308, -1.7976931348623157e308, math.inf, -math.inf, math.nan, 1e-300, -1e300,
    0.1, 1 / 3, math.pi, 2.0**53 + 2, -(2.0**-1074) * 3, 1.0000000000000002, 123456789.123456789,
]


def _random_floats(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    scaled = rng.standard_normal(n) * 10.0 ** rng.integers(-310, 308, n)
    bits = rng.integers(-(2**63), 2**63 - 1, n, dtype=np.int64, endpoint=True).view(np.float64)
    subnormal = rng.integers(1, 2**52, n, dtype=np.int64).view(np.float64) * rng.choice([-1.0, 1.0], n)
    return np.concatenate([np.array(FLOAT_SPECIALS), scaled, bits, subnormal])


def test_float_round_trips_are_bit_exact(store, mesh):
    values = _random_floats(25, seed=1)  # 20 specials + 75 random
    n = len(values)
    vs = [mesh.add_vertex() for _ in range(n)]
    mesh.add_property("vertex", "f", "float64")
    mesh.add_property("vertex", "g", "float64")
    mesh.add_property("vertex", "f9", "float64", shape=(9,), default=tuple([0.0] * 9))
    # "f": per element; "g": set-based; then each read both ways
    for v, x in zip(vs, values):
        v["f"] = float(x)
    mesh.set_property_array("vertex", "g", vs, values)
    for name in ("f", "g"):
        ids, got = mesh.property_array("vertex", name)
        assert not np.ma.getmaskarray(got).any(), "a NaN value is a value, not unset"
        assert_bits(np.ma.getdata(got), values)
        assert_bits([v[name] for v in vs], values)
    # shape (9,): values crossing row boundaries, both paths
    shaped = np.resize(values[::-1], (n, 9))
    mesh.set_property_array("vertex", "f9", vs[: n // 2], shaped[: n // 2])
    for v, row in zip(vs[n // 2:], shaped[n // 2:]):
        v["f9"] = row
    assert_bits(mesh.property_array("vertex", "f9")[1], shaped)
    assert_bits([v["f9"] for v in vs], shaped)
    # and after a fresh connection
    with hestore.open(store.url.render_as_string(hide_password=False)) as other:
        m = other.mesh("m")
        assert_bits(np.ma.getdata(m.property_array("vertex", "g")[1]), values)
        assert_bits(m.property_array("vertex", "f9")[1], shaped)
    assert mesh.check() == []


def test_nan_is_a_value_and_masked_is_unset(mesh):
    vs = [mesh.add_vertex() for _ in range(3)]
    mesh.add_property("vertex", "t", "float64", shape=(5,))
    vs[0]["t"] = (math.nan,) * 5
    vs[1]["t"] = (1.0, math.nan, 3.0, 4.0, math.nan)
    ids, arr = mesh.property_array("vertex", "t")
    assert np.ma.getmaskarray(arr).tolist() == [[False] * 5, [False] * 5, [True] * 5]
    assert np.isnan(np.ma.getdata(arr)[0]).all()
    assert vs[2]["t"] is None
    assert math.isnan(vs[1]["t"][1]) and vs[1]["t"][2] == 3.0
    # written back set-based, the same
    mesh.set_property_array("vertex", "t", ids, arr)
    ids2, arr2 = mesh.property_array("vertex", "t")
    assert np.ma.getmaskarray(arr2).tolist() == np.ma.getmaskarray(arr).tolist()
    assert np.array_equal(np.ma.getdata(arr2)[:2], np.ma.getdata(arr)[:2], equal_nan=True)


def test_negative_zero_keeps_its_sign(store, mesh):
    # SQLite's REAL affinity would store -0.0 as the integer 0: hestore's float columns have none.
    vs = [mesh.add_vertex() for _ in range(2)]
    mesh.add_property("vertex", "z", "float64", default=1.0)
    mesh.add_property("vertex", "z3", "float64", shape=(3,))
    vs[0]["z"] = -0.0
    mesh.set_property_array("vertex", "z", [vs[1]], np.array([-0.0]))
    mesh.set_property_array("vertex", "z3", vs, np.array([[-0.0, 0.0, -0.0]] * 2))
    got = [vs[0]["z"], vs[1]["z"], *mesh.property_array("vertex", "z")[1].tolist()]
    assert [math.copysign(1.0, x) for x in got] == [-1.0] * 4
    assert [math.copysign(1.0, x) for x in vs[0]["z3"]] == [-1.0, 1.0, -1.0]
    assert_bits(mesh.property_array("vertex", "z3")[1], [[-0.0, 0.0, -0.0]] * 2)


def test_negative_zero_position_keeps_its_sign(store, mesh):
    a = mesh.add_vertex((-0.0, 1.0, 1.0))
    b, c = mesh.add_vertex(), mesh.add_vertex()
    mesh.set_position(b, (1.0, -0.0, 1.0))
    mesh.set_positions([c], [[1.0, 1.0, -0.0]])
    signs = [math.copysign(1.0, x) for v in (a, b, c) for x in v.position]
    assert signs == [-1.0, 1.0, 1.0, 1.0, -1.0, 1.0, 1.0, 1.0, -1.0]


INT_EXTREMES = [-(2**63), 2**63 - 1, -1, 0, 1, 2**62, -(2**62) + 1, 2**53 + 1, -(2**53) - 1, 2**31, -(2**31) - 1]


def test_int64_extremes_round_trip(store, mesh):
    n = len(INT_EXTREMES)
    vs = [mesh.add_vertex() for _ in range(n)]
    mesh.add_property("vertex", "i", "int64", default=-(2**63))
    mesh.add_property("vertex", "j", "int64")
    mesh.add_property("vertex", "i5", "int64", shape=(5,))
    for v, x in zip(vs, INT_EXTREMES):
        v["i"] = x
    mesh.set_property_array("vertex", "j", vs, np.array(INT_EXTREMES, dtype=np.int64))
    shaped = np.resize(np.array(INT_EXTREMES[::-1], dtype=np.int64), (n, 5))
    mesh.set_property_array("vertex", "i5", vs[::2], shaped[::2])
    for v, row in zip(vs[1::2], shaped[1::2]):
        v["i5"] = tuple(int(x) for x in row)
    for name in ("i", "j"):
        ids, got = mesh.property_array("vertex", name)
        assert got.dtype == np.int64
        assert np.ma.getdata(got).tolist() == INT_EXTREMES
        assert [v[name] for v in vs] == INT_EXTREMES
    assert np.array_equal(np.ma.getdata(mesh.property_array("vertex", "i5")[1]), shaped)
    assert [v["i5"] for v in vs] == [tuple(r) for r in shaped.tolist()]
    # uint64 input that fits is taken; one that does not is refused
    mesh.set_property_array("vertex", "j", vs[:1], np.array([2**63 - 1], dtype=np.uint64))
    assert vs[0]["j"] == 2**63 - 1
    with pytest.raises(InvalidInputError):
        mesh.set_property_array("vertex", "j", vs[:1], np.array([2**63], dtype=np.uint64))
    assert vs[0]["j"] == 2**63 - 1


TEXTS = ["", "a", "é✓🙂 中文 עברית", "x" * 100_000, "line\nbreak\ttab\r\n", "'; DROP TABLE meshes; --",
         "\u200b\ufeff", "𝔘𝔫𝔦𝔠𝔬𝔡𝔢", "\\N", "NULL", " leading and trailing "]


def test_text_round_trips(store, mesh):
    n = len(TEXTS)
    vs = [mesh.add_vertex() for _ in range(n + 1)]
    mesh.add_property("vertex", "s", "str")
    mesh.add_property("vertex", "t", "str", default="default")
    for v, x in zip(vs, TEXTS):
        v["s"] = x
    mesh.set_property_array("vertex", "t", vs[:n], np.array(TEXTS, dtype=object))
    for name, last in (("s", None), ("t", "default")):
        ids, got = mesh.property_array("vertex", name)
        assert as_values(got) == TEXTS + [last]
        assert [v[name] for v in vs] == TEXTS + [last]
    # the empty string is a value, not unset
    assert np.ma.getmaskarray(mesh.property_array("vertex", "s")[1]).tolist() == [False] * n + [True]
    with hestore.open(store.url.render_as_string(hide_password=False)) as other:
        assert as_values(other.mesh("m").property_array("vertex", "t")[1]) == TEXTS + ["default"]


# --------------------------------------------------------------------------
# Strict value checks


def _props(mesh):
    specs = {
        "f": ("float64", (), 0.0), "f3": ("float64", (3,), None), "i": ("int64", (), 0),
        "i3": ("int64", (3,), (0, 0, 0)), "b": ("bool", (), False), "s": ("str", (), ""),
    }
    for kind in ("vertex", "halfedge"):
        for name, (dtype, shape, default) in specs.items():
            mesh.add_property(kind, name, dtype, shape=shape, default=default)


REFUSED = [
    ("f", "1.0"), ("f", b"1"), ("f", True), ("f", np.bool_(False)), ("f", 1j), ("f", [1.0]), ("f", np.array([1.0])),
    ("f", object()), ("f", {"x": 1}),
    ("f3", (1.0, 2.0)), ("f3", (1.0, 2.0, 3.0, 4.0)), ("f3", 1.0), ("f3", "abc"), ("f3", b"abc"),
    ("f3", [[1.0, 2.0, 3.0]]), ("f3", np.zeros((1, 3))), ("f3", (1.0, "2", 3.0)), ("f3", (1.0, None, 3.0)),
    ("f3", {1.0, 2.0, 3.0}),
    ("i", 1.5), ("i", np.float64(2.5)), ("i", "2"), ("i", b"2"), ("i", 2**63), ("i", -(2**63) - 1),
    ("i", math.nan), ("i", math.inf), ("i", True), ("i", 1e19),
    ("i3", (1, 2)), ("i3", (1, 2.5, 3)), ("i3", (1, 2, "3")),
    ("b", 1), ("b", 0), ("b", "true"), ("b", np.int64(1)), ("b", 1.0), ("b", (True,)),
    ("s", 5), ("s", b"x"), ("s", "a\x00b"), ("s", "\ud800"), ("s", ["x"]), ("s", 1.5),
]


def test_refused_values_name_property_and_element_and_change_nothing(store, mesh):
    vs = build(mesh)
    _props(mesh)
    v = vs[3]
    h = mesh.halfedge(5)
    for target in (v, h):
        target["f"], target["f3"], target["i"], target["i3"], target["b"], target["s"] = (
            7.5, (1.0, 2.0, 3.0), 7, (1, 2, 3), True, "kept")
    before, rev = everything(store), mesh.revision
    names = [(k, n) for k in ("vertex", "halfedge") for n in ("f", "f3", "i", "i3", "b", "s")]
    arrays = {(k, n): as_values(mesh.property_array(k, n)[1]) for k, n in names}
    for target, kind in ((v, "vertex"), (h, "halfedge")):
        for name, bad in REFUSED:
            with pytest.raises(InvalidInputError) as info:
                target[name] = bad
            msg = str(info.value)
            assert repr(name) in msg or f'"{name}"' in msg, f"{msg!r} does not name property {name!r}"
            assert re.search(rf"{WHAT[kind]} {target.id}\b", msg), f"{msg!r} does not name {kind} {target.id}"
    assert everything(store) == before
    assert mesh.revision == rev
    assert {(k, n): as_values(mesh.property_array(k, n)[1]) for k, n in arrays} == arrays
    # inside a block: refused, the block sees nothing changed, goes on and commits
    with store.transaction():
        for name, bad in REFUSED[::3]:
            with pytest.raises(InvalidInputError):
                v[name] = bad
        assert everything(store) == before
        v["f"] = 8.5
    assert v["f"] == 8.5 and mesh.revision == rev + 1
    assert mesh.check() == []


def test_accepted_values_are_converted_exactly(mesh):
    v = mesh.add_vertex()
    _props(mesh)
    accepted = [
        ("f", 3, 3.0), ("f", np.int64(-4), -4.0), ("f", np.float32(0.5), 0.5), ("f", 2**70, float(2**70)),
        ("f", np.uint8(7), 7.0), ("f3", [1, 2, 3], (1.0, 2.0, 3.0)), ("f3", np.array([1, 2, 3]), (1.0, 2.0, 3.0)),
        ("i", 2.0, 2), ("i", np.float64(-3.0), -3), ("i", np.int32(5), 5), ("i", -(2.0**63), -(2**63)),
        ("i3", (1.0, 2, np.int16(3)), (1, 2, 3)), ("i3", range(3), (0, 1, 2)),
        ("b", True, True), ("b", np.bool_(False), False), ("s", "ok", "ok"), ("s", "", ""),
        ("f", np.array(2.5), 2.5),
    ]
    for name, given, want in accepted:
        v[name] = given
        got = v[name]
        assert got == want and type(got) is type(want), (name, given, got)
        if isinstance(want, tuple):
            assert [type(x) for x in got] == [type(x) for x in want]


def test_refused_set_based_writes_change_nothing(store, mesh):
    vs = build(mesh)
    other = store.create_mesh("other")
    ov = [other.add_vertex() for _ in range(3)]
    _props(mesh)
    mesh.add_property("edge", "w", "float64", default=0.0)
    mesh.set_property_array("vertex", "f3", vs, np.arange(18.0).reshape(6, 3))
    mesh.set_property_array("vertex", "s", vs, np.array(list("abcdef"), dtype=object))
    gone = mesh.add_vertex()
    gone["f"] = 1.0
    mesh.remove_vertex(gone)
    e = mesh.add_edge(vs[0], vs[4])
    mesh.remove_edge(e)
    n = len(vs)
    ids = [v.id for v in vs]
    cases = [
        # (exception, kind, name, ids, values)
        (InvalidInputError, "vertex", "f3", ids, np.zeros(n)),
        (InvalidInputError, "vertex", "f3", ids, np.zeros((n, 2))),
        (InvalidInputError, "vertex", "f3", ids, np.zeros((n + 1, 3))),
        (InvalidInputError, "vertex", "f3", ids, np.zeros((n, 3, 1))),
        (InvalidInputError, "vertex", "f3", ids, np.zeros((n - 1, 3))),
        (InvalidInputError, "vertex", "f3", ids, np.full((n, 3), "1")),
        (InvalidInputError, "vertex", "f3", ids, np.full((n, 3), b"1")),
        (InvalidInputError, "vertex", "f3", ids, np.ones((n, 3), dtype=bool)),
        (InvalidInputError, "vertex", "f3", ids, np.full((n, 3), None, dtype=object)),
        (InvalidInputError, "vertex", "f3", ids, [[1.0, 2.0, 3.0]] * (n - 1) + [[1.0, 2.0]]),
        (InvalidInputError, "vertex", "f", ids, "abcdef"),
        (InvalidInputError, "vertex", "f", ids, 1.0),
        (InvalidInputError, "vertex", "f", ids, np.array([1.0 + 1j] * n)),
        (InvalidInputError, "vertex", "i", ids, np.array([1.0] * (n - 1) + [1.5])),
        (InvalidInputError, "vertex", "i", ids, np.array([1.0] * (n - 1) + [math.nan])),
        (InvalidInputError, "vertex", "i", ids, np.array([1.0] * (n - 1) + [2.0**63])),
        (InvalidInputError, "vertex", "i", ids, np.array([1] * n, dtype=np.uint64) * np.uint64(2**63)),
        (InvalidInputError, "vertex", "i", ids, np.array(["1"] * n)),
        (InvalidInputError, "vertex", "i3", ids, np.zeros((n, 4), dtype=np.int64)),
        (InvalidInputError, "vertex", "b", ids, np.array([0, 1] * (n // 2))),
        (InvalidInputError, "vertex", "b", ids, np.array([0.0] * n)),
        (InvalidInputError, "vertex", "s", ids, np.array([1] * n)),
        (InvalidInputError, "vertex", "s", ids, np.array(["a"] * (n - 1) + ["a\x00"], dtype=object)),
        (InvalidInputError, "vertex", "s", ids, np.array(["a"] * (n - 1) + [b"a"], dtype=object)),
        (InvalidInputError, "vertex", "s", ids, np.array(["a"] * (n - 1) + [1.5], dtype=object)),
        # ids
        (InvalidInputError, "vertex", "f", [0, 1, 1], np.zeros(3)),
        (InvalidInputError, "vertex", "f", [vs[2], vs[2]], np.zeros(2)),
        (InvalidInputError, "vertex", "f", np.array([0.0, 1.0]), np.zeros(2)),
        (InvalidInputError, "vertex", "f", np.array([[0, 1]]), np.zeros((1, 2))),
        (InvalidInputError, "vertex", "f", "01", np.zeros(2)),
        (InvalidInputError, "vertex", "f", 3, np.zeros(1)),
        (InvalidInputError, "vertex", "f", [mesh.halfedge(0), mesh.halfedge(1)], np.zeros(2)),
        (InvalidInputError, "edge", "w", [vs[0]], np.zeros(1)),
        (ElementNotFoundError, "vertex", "f", [0, gone.id], np.zeros(2)),
        (ElementNotFoundError, "vertex", "f", [gone], np.zeros(1)),
        (ElementNotFoundError, "vertex", "f", [0, 10**6], np.zeros(2)),
        (ElementNotFoundError, "vertex", "f", [-1], np.zeros(1)),
        (ElementNotFoundError, "vertex", "f", np.array([2**64 - 1], dtype=np.uint64), np.zeros(1)),
        (ElementNotFoundError, "edge", "w", [e.id], np.zeros(1)),
        (ElementNotFoundError, "halfedge", "f", [0, 12], np.zeros(2)),
        (ElementNotFoundError, "vertex", "f", [vs[0], ov[1]], np.zeros(2)),
        (ElementNotFoundError, "vertex", "f", ov, np.zeros(3)),
        (PropertyNotFoundError, "vertex", "nope", ids, np.zeros(n)),
        (PropertyNotFoundError, "edge", "f", [0], np.zeros(1)),
    ]
    before, rev = everything(store), mesh.revision
    for exc, kind, name, targets, values in cases:
        with pytest.raises(exc):
            mesh.set_property_array(kind, name, targets, values)
    assert everything(store) == before
    assert mesh.revision == rev
    with store.transaction():
        for exc, kind, name, targets, values in cases[::4]:
            with pytest.raises(exc):
                mesh.set_property_array(kind, name, targets, values)
        assert everything(store) == before
    assert mesh.revision == rev
    assert as_values(mesh.property_array("vertex", "s")[1]) == list("abcdef")
    assert mesh.check() == []


def test_single_writes_on_missing_elements(store, mesh):
    vs = build(mesh)
    mesh.add_property("vertex", "t", "float64", default=0.0)
    mesh.add_property("polygon", "t", "float64", default=0.0)
    mesh.add_property("edge", "t", "float64", default=0.0)
    p = mesh.polygon(1)
    stale = vs[5]
    mesh.remove_vertex(stale)
    mesh.remove_polygon(p)
    before, rev = everything(store), mesh.revision
    for h in (stale, p, hestore.Vertex(mesh, 10**6), hestore.Edge(mesh, 99)):
        with pytest.raises(ElementNotFoundError):
            h["t"] = 1.0
        with pytest.raises(ElementNotFoundError):
            del h["t"]
    for h in (stale, p, hestore.Vertex(mesh, 10**6)):
        with pytest.raises(ElementNotFoundError):
            h["t"]
    assert everything(store) == before and mesh.revision == rev


# --------------------------------------------------------------------------
# Unknown and duplicate names


def test_property_not_found(store, mesh):
    vs = build(mesh)
    assert issubclass(PropertyNotFoundError, KeyError)
    assert issubclass(PropertyNotFoundError, HestoreError)
    assert hestore.PropertyNotFoundError is PropertyNotFoundError
    assert "PropertyNotFoundError" in hestore.__all__
    mesh.add_property("vertex", "t", "float64", default=0.0)
    before, rev = everything(store), mesh.revision
    calls = [
        lambda: vs[0]["nope"],
        lambda: vs[0].__setitem__("nope", 1.0),
        lambda: vs[0].__delitem__("nope"),
        lambda: vs[0][5],
        lambda: vs[0][None],
        lambda: mesh.edge(0)["t"],  # the name exists, on another kind
        lambda: mesh.edge(0).__setitem__("t", 1.0),
        lambda: mesh.property_array("vertex", "nope"),
        lambda: mesh.property_array("edge", "t"),
        lambda: mesh.set_property_array("vertex", "nope", [0], np.zeros(1)),
        lambda: mesh.set_property_array("polygon", "t", [0], np.zeros(1)),
        lambda: mesh.remove_property("vertex", "nope"),
        lambda: mesh.remove_property("halfedge", "t"),
        lambda: mesh.remove_property("vertex", "T"),
    ]
    for call in calls:
        with pytest.raises(PropertyNotFoundError) as info:
            call()
        assert isinstance(info.value, KeyError) and isinstance(info.value, HestoreError)
    with pytest.raises(KeyError):
        vs[0]["nope"]
    assert everything(store) == before and mesh.revision == rev
    with pytest.raises(InvalidInputError):
        mesh.property_array("face", "t")
    assert mesh.properties("edge") == {}


def test_duplicate_names(store, mesh):
    vs = build(mesh)
    mesh.add_property("vertex", "t", "float64", default=0.0)
    vs[0]["t"] = 3.0
    before, rev = everything(store), mesh.revision
    for dtype, shape in (("float64", ()), ("int64", ()), ("str", ()), ("float64", (3,))):
        with pytest.raises(InvalidInputError):
            mesh.add_property("vertex", "t", dtype, shape=shape)
    assert everything(store) == before and mesh.revision == rev
    # same name on the other kinds: independent properties
    for kind, dtype, default in (("halfedge", "int64", 1), ("edge", "str", "e"), ("polygon", "bool", True)):
        mesh.add_property(kind, "t", dtype, default=default)
    mesh.edge(2)["t"] = "two"
    mesh.halfedge(0)["t"] = 9
    assert vs[0]["t"] == 3.0 and vs[1]["t"] == 0.0
    assert mesh.halfedge(0)["t"] == 9 and mesh.halfedge(1)["t"] == 1
    assert mesh.edge(2)["t"] == "two" and mesh.edge(0)["t"] == "e"
    assert mesh.polygon(0)["t"] is True
    mesh.remove_property("edge", "t")
    assert vs[0]["t"] == 3.0 and mesh.halfedge(0)["t"] == 9
    assert set(mesh.properties("vertex")) == {"t"} and mesh.properties("edge") == {}
    # a removed name can be declared again: a new property, without the old values
    mesh.remove_property("vertex", "t")
    mesh.add_property("vertex", "t", "str", default="new")
    assert vs[0]["t"] == "new"
    assert mesh.check() == []


# --------------------------------------------------------------------------
# Transactions


def test_rolled_back_writes_are_gone(store, mesh):
    vs = build(mesh)
    mesh.add_property("vertex", "t", "float64", default=0.0)
    mesh.add_property("halfedge", "uv", "float64", shape=(2,))
    vs[0]["t"] = 1.0
    before, rev = everything(store), mesh.revision
    with pytest.raises(Rollback):
        with store.transaction():
            vs[0]["t"] = 2.0
            vs[1]["t"] = 3.0
            del vs[0]["t"]
            mesh.set_property_array("halfedge", "uv", range(12), np.ones((12, 2)))
            mesh.halfedge(3)["uv"] = (5.0, 6.0)
            mesh.set_position(vs[2], (9.0, 9.0, 9.0))
            mesh.set_positions([0, 1], np.zeros((2, 3)))
            assert vs[0]["t"] == 0.0 and vs[1]["t"] == 3.0
            assert mesh.halfedge(3)["uv"] == (5.0, 6.0) and mesh.halfedge(4)["uv"] == (1.0, 1.0)
            assert vs[2].position == (9.0, 9.0, 9.0)
            raise Rollback
    assert everything(store) == before and mesh.revision == rev
    assert vs[0]["t"] == 1.0 and vs[1]["t"] == 0.0
    assert mesh.halfedge(3)["uv"] is None
    assert vs[2].position == (2.0, 0.0, 0.0)
    assert mesh.check() == []


def test_nested_savepoint_rollback_restores_inner_writes_only(store, mesh):
    vs = build(mesh)
    mesh.add_property("vertex", "t", "float64", default=0.0)
    mesh.add_property("edge", "w", "int64", shape=(5,), default=(0,) * 5)
    url = store.url.render_as_string(hide_password=False)
    rev = mesh.revision
    with store.transaction():
        vs[0]["t"] = 1.0
        mesh.set_property_array("edge", "w", [0, 1], np.array([[1] * 5, [2] * 5]))
        mesh.set_position(vs[0], (10.0, 0.0, 0.0))
        with pytest.raises(Rollback):
            with store.transaction():
                vs[0]["t"] = 2.0  # overwrites the outer block's value
                vs[1]["t"] = 3.0
                mesh.edge(0)["w"] = (7,) * 5
                mesh.set_property_array("edge", "w", [2, 3], np.full((2, 5), 9))
                mesh.set_position(vs[0], (20.0, 0.0, 0.0))
                mesh.set_positions([vs[1]], [[21.0, 0.0, 0.0]])
                assert vs[0]["t"] == 2.0
                raise Rollback
        assert vs[0]["t"] == 1.0 and vs[1]["t"] == 0.0
        assert as_values(mesh.property_array("edge", "w")[1]) == [(1,) * 5, (2,) * 5] + [(0,) * 5] * 4
        assert vs[0].position == (10.0, 0.0, 0.0) and vs[1].position == (1.0, 1.0, 0.0)
        with store.transaction():  # a committed savepoint stays
            vs[5]["t"] = 5.0
        with pytest.raises(Rollback):  # a savepoint that only rolls back a flushed write
            with store.transaction():
                vs[5]["t"] = 6.0
                assert mesh.property_array("vertex", "t")[1][5] == 6.0
                raise Rollback
        assert vs[5]["t"] == 5.0
    assert mesh.revision == rev + 1
    with hestore.open(url) as other:
        m = other.mesh("m")
        assert as_values(m.property_array("vertex", "t")[1]) == [1.0, 0.0, 0.0, 0.0, 0.0, 5.0]
        assert as_values(m.property_array("edge", "w")[1]) == [(1,) * 5, (2,) * 5] + [(0,) * 5] * 4
        assert m.vertex(0).position == (10.0, 0.0, 0.0) and m.vertex(1).position == (1.0, 1.0, 0.0)
    assert mesh.check() == []


def test_declaring_and_removing_properties_roll_back(store, mesh):
    vs = build(mesh)
    mesh.add_property("vertex", "keep", "str", default="")
    vs[0]["keep"] = "kept"
    before, rev = everything(store), mesh.revision
    with pytest.raises(Rollback):
        with store.transaction():
            mesh.add_property("vertex", "new", "float64", default=1.0)
            vs[1]["new"] = 2.0
            mesh.remove_property("vertex", "keep")
            assert set(mesh.properties("vertex")) == {"new"}
            with pytest.raises(PropertyNotFoundError):
                vs[0]["keep"]
            mesh.add_property("vertex", "keep", "int64", default=5)  # same name again, another dtype
            assert vs[0]["keep"] == 5
            raise Rollback
    assert everything(store) == before and mesh.revision == rev
    assert set(mesh.properties("vertex")) == {"keep"}
    assert vs[0]["keep"] == "kept"
    with pytest.raises(PropertyNotFoundError):
        vs[1]["new"]
    # savepoint: the inner declaration goes, the outer stays
    with store.transaction():
        mesh.add_property("edge", "outer", "float64")
        with pytest.raises(Rollback):
            with store.transaction():
                mesh.add_property("edge", "inner", "float64")
                mesh.remove_property("edge", "outer")
                raise Rollback
        assert set(mesh.properties("edge")) == {"outer"}
    assert set(mesh.properties("edge")) == {"outer"}
    # a property declared, written and removed in one block leaves nothing
    keys = value_keys(store, mesh)
    with store.transaction():
        mesh.add_property("polygon", "tmp", "float64", shape=(6,))
        mesh.set_property_array("polygon", "tmp", [0, 1], np.ones((2, 6)))
        mesh.polygon(0)["tmp"] = (2.0,) * 6
        mesh.remove_property("polygon", "tmp")
    assert value_keys(store, mesh) == keys
    assert mesh.properties("polygon") == {}
    assert mesh.check() == []


def test_revision_counts_committed_transactions(store, mesh):
    vs = build(mesh)
    mesh.add_property("vertex", "t", "float64", default=0.0)
    rev = mesh.revision
    vs[0]["t"] = 1.0
    assert mesh.revision == rev + 1
    mesh.set_property_array("vertex", "t", vs[:3], np.ones(3))
    assert mesh.revision == rev + 2
    del vs[0]["t"]
    assert mesh.revision == rev + 3
    mesh.set_position(vs[0], (5.0, 5.0, 5.0))
    assert mesh.revision == rev + 4
    mesh.set_positions(vs[:2], np.zeros((2, 3)))
    assert mesh.revision == rev + 5
    with store.transaction():
        for i, v in enumerate(vs):
            v["t"] = float(i)
            mesh.set_position(v, (i, i, i))
        mesh.set_property_array("vertex", "t", vs, np.arange(6.0))
    assert mesh.revision == rev + 6
    with store.transaction():  # reads only
        mesh.property_array("vertex", "t")
        vs[0]["t"]
    assert mesh.revision == rev + 6
    with pytest.raises(Rollback):
        with store.transaction():
            vs[0]["t"] = 9.0
            raise Rollback
    assert mesh.revision == rev + 6
    with store.transaction():  # only refused writes
        with pytest.raises(InvalidInputError):
            vs[0]["t"] = "x"
        with pytest.raises(InvalidInputError):
            mesh.set_position(vs[0], (math.nan, 0, 0))
    assert mesh.revision == rev + 6


def test_empty_set_property_array_writes_nothing(store, mesh):
    vs = build(mesh)
    mesh.add_property("vertex", "t", "float64", default=0.0)
    before, rev = everything(store), mesh.revision
    mesh.set_property_array("vertex", "t", [], np.zeros(0))
    assert everything(store) == before and mesh.revision == rev
    assert vs[0]["t"] == 0.0


def test_set_property_array_with_every_entry_masked_unsets(store, mesh):
    vs = build(mesh)
    mesh.add_property("vertex", "t", "float64", default=0.0)
    vs[0]["t"], vs[1]["t"] = 1.0, 2.0
    mesh.set_property_array("vertex", "t", [0, 1], np.ma.MaskedArray([5.0, 6.0], mask=[True, True]))
    assert vs[0]["t"] == 0.0 and vs[1]["t"] == 0.0


def test_masked_str_and_none_unset(store, mesh):
    vs = build(mesh)
    mesh.add_property("vertex", "s", "str", default="d")
    vs[0]["s"], vs[1]["s"] = "a", "b"
    mesh.set_property_array("vertex", "s", [0, 1], np.ma.MaskedArray(np.array(["x", "y"], dtype=object),
                                                                      mask=[True, True]))
    assert vs[0]["s"] == "d" and vs[1]["s"] == "d"
    assert value_keys(store, mesh) == set()


@pytest.mark.parametrize("what", ["positions", "str values"])
def test_empty_set_based_writes_do_not_bump_the_revision(store, mesh, what):
    build(mesh)
    mesh.add_property("vertex", "s", "str")
    before, rev = everything(store), mesh.revision
    if what == "positions":
        mesh.set_positions([], np.zeros((0, 3)))
    else:
        mesh.set_property_array("vertex", "s", [], np.array([], dtype=object))
    assert everything(store)["property_texts"] == before["property_texts"]
    assert mesh.revision == rev


def test_reads_inside_a_block_see_its_writes_and_other_connections_only_commits(store, mesh, db_url):
    vs = build(mesh)
    mesh.add_property("vertex", "t", "float64", default=0.0)
    mesh.add_property("polygon", "label", "str", default="")
    with hestore.open(db_url) as other:
        seen = other.mesh("m")
        with store.transaction():
            vs[0]["t"] = 1.0
            mesh.set_property_array("polygon", "label", [0, 1], np.array(["a", "b"], dtype=object))
            mesh.set_position(vs[1], (7.0, 7.0, 7.0))
            mesh.add_property("edge", "w", "int64", default=3)
            assert vs[0]["t"] == 1.0
            assert mesh.property_array("vertex", "t")[1].tolist() == [1.0] + [0.0] * 5
            assert as_values(mesh.property_array("polygon", "label")[1]) == ["a", "b"]
            assert mesh.polygon(1)["label"] == "b"
            assert vs[1].position == (7.0, 7.0, 7.0)
            assert mesh.edge(0)["w"] == 3
            # the other connection: the committed state only
            assert seen.vertex(0)["t"] == 0.0
            assert seen.property_array("vertex", "t")[1].tolist() == [0.0] * 6
            assert as_values(seen.property_array("polygon", "label")[1]) == ["", ""]
            assert seen.vertex(1).position == (1.0, 1.0, 0.0)
            assert "w" not in seen.properties("edge")
            with pytest.raises(PropertyNotFoundError):
                seen.edge(0)["w"]
        assert seen.vertex(0)["t"] == 1.0
        assert as_values(seen.property_array("polygon", "label")[1]) == ["a", "b"]
        assert seen.vertex(1).position == (7.0, 7.0, 7.0)
        assert seen.edge(0)["w"] == 3
        assert seen.revision == mesh.revision


def test_order_of_single_and_set_based_writes_in_one_block(store, mesh, db_url):
    vs = build(mesh)
    mesh.add_property("vertex", "t", "float64", default=0.0)
    mesh.add_property("vertex", "s", "str")
    with store.transaction():  # no reads in between: every write waits for one flush
        mesh.set_property_array("vertex", "t", [0, 1, 2], np.array([1.0, 1.0, 1.0]))
        vs[0]["t"] = 2.0  # single after set-based: wins
        vs[1]["t"] = 3.0
        mesh.set_property_array("vertex", "t", [1], np.array([4.0]))  # set-based after single: wins
        del vs[2]["t"]  # unset after set-based
        vs[3]["t"] = 5.0
        vs[5]["t"] = 8.0
        mesh.set_property_array("vertex", "t", [3, 5], np.ma.MaskedArray([0.0, 9.0], mask=[True, False]))
        mesh.set_property_array("vertex", "s", [0, 1, 2, 3, 4, 5], np.array(list("abcdef"), dtype=object))
        vs[4]["s"] = "x"
        mesh.set_property_array("vertex", "s", [0, 1, 2, 3, 4, 5], np.array(list("ghijkl"), dtype=object))
        vs[5]["s"] = "y"
        new = mesh.add_vertex()
        new["t"] = 6.0
        mesh.set_property_array("vertex", "t", [new], np.array([7.0]))
    expected_t = [2.0, 4.0, 0.0, 0.0, 0.0, 9.0, 7.0]
    expected_s = list("ghijk") + ["y", None]
    assert mesh.property_array("vertex", "t")[1].tolist() == expected_t
    assert as_values(mesh.property_array("vertex", "s")[1]) == expected_s
    with hestore.open(db_url) as other:
        assert other.mesh("m").property_array("vertex", "t")[1].tolist() == expected_t
        assert as_values(other.mesh("m").property_array("vertex", "s")[1]) == expected_s
    assert mesh.check() == []


# --------------------------------------------------------------------------
# Values go with their elements


def _declare_and_fill(store, mesh):
    """One property per kind (all three value tables, multi-row values), every element set."""
    props = {
        "vertex": mesh.add_property("vertex", "vf", "float64", shape=(6,), default=(0.0,) * 6),
        "halfedge": mesh.add_property("halfedge", "uv", "int64", shape=(2,)),
        "edge": mesh.add_property("edge", "label", "str", default=""),
        "polygon": mesh.add_property("polygon", "flag", "bool", default=False),
    }
    vals = {
        "vertex": lambda i: tuple(float(i * 10 + c) for c in range(6)),
        "halfedge": lambda i: (i, -i),
        "edge": lambda i: f"edge {i}",
        "polygon": lambda i: True,
    }
    for kind, prop in props.items():
        ids = element_ids(mesh, kind)
        mesh.set_property_array(kind, prop.name, ids, to_array(prop.dtype, prop.shape, [vals[kind](i) for i in ids]))
    return props, vals


def _stored_ids(store, mesh, prop) -> set[int]:
    return {i for _p, i in value_keys(store, mesh, prop)}


def test_removing_elements_removes_their_value_rows(store, mesh):
    vs = build(mesh)
    props, vals = _declare_and_fill(store, mesh)
    for kind, prop in props.items():
        assert _stored_ids(store, mesh, prop) == set(element_ids(mesh, kind))
    # remove_polygon: the polygon's values go; its half-edges stay, with their (corner) values
    p1_halfedges = [h.id for h in mesh.polygon(1).halfedges()]
    mesh.remove_polygon(mesh.polygon(1))
    assert _stored_ids(store, mesh, props["polygon"]) == {0}
    assert _stored_ids(store, mesh, props["halfedge"]) == set(range(12))
    assert [mesh.halfedge(h)["uv"] for h in p1_halfedges] == [(h, -h) for h in p1_halfedges]
    # remove_edge: the edge, its two half-edges and the polygon beside it
    e = mesh.find_halfedge(vs[0], vs[1]).edge
    gone_he = {h.id for h in e.halfedges()}
    mesh.remove_edge(e)
    assert _stored_ids(store, mesh, props["edge"]) == set(range(6)) - {e.id}
    assert _stored_ids(store, mesh, props["halfedge"]) == set(range(12)) - gone_he
    assert _stored_ids(store, mesh, props["polygon"]) == set()
    # remove_vertex: the vertex and every incident edge
    incident = {x.id for x in vs[3].edges()}
    incident_he = {h.id for x in vs[3].edges() for h in x.halfedges()}
    mesh.remove_vertex(vs[3])
    assert _stored_ids(store, mesh, props["vertex"]) == {0, 1, 2, 4, 5}
    assert _stored_ids(store, mesh, props["edge"]) == set(range(6)) - {e.id} - incident
    assert _stored_ids(store, mesh, props["halfedge"]) == set(range(12)) - gone_he - incident_he
    # everything left keeps its values, exactly
    for kind, prop in props.items():
        ids, arr = mesh.property_array(kind, prop.name)
        assert as_values(arr) == [vals[kind](i) for i in ids.tolist()]
    assert mesh.check() == []


def test_values_written_and_removed_in_one_block_leave_no_rows(store, mesh):
    vs = build(mesh)
    props, vals = _declare_and_fill(store, mesh)
    keys = value_keys(store, mesh)
    with store.transaction():
        v = mesh.add_vertex()
        w = mesh.add_vertex()
        e = mesh.add_edge(v, w)
        p = mesh.add_polygon([vs[4], vs[3], vs[5]])
        v["vf"] = (1.0,) * 6
        mesh.set_property_array("vertex", "vf", [w], np.ones((1, 6)))
        e["label"] = "new"
        mesh.set_property_array("halfedge", "uv", [h.id for h in e.halfedges()], np.ones((2, 2), dtype=np.int64))
        p["flag"] = True
        vs[5]["vf"] = (2.0,) * 6  # an existing vertex, removed below
        mesh.remove_vertex(v)
        mesh.remove_vertex(w)
        mesh.remove_polygon(p)
        mesh.remove_vertex(vs[5])
    assert value_keys(store, mesh) == keys - {(props["vertex"].id, 5)}
    assert mesh.check() == []


def test_removal_rolled_back_restores_values(store, mesh):
    build(mesh)
    props, vals = _declare_and_fill(store, mesh)
    before = everything(store)
    with pytest.raises(Rollback):
        with store.transaction():
            mesh.remove_polygon(mesh.polygon(1))
            mesh.remove_vertex(mesh.vertex(4))
            mesh.remove_vertex(mesh.vertex(0))
            raise Rollback
    assert everything(store) == before
    for kind, prop in props.items():
        ids, arr = mesh.property_array(kind, prop.name)
        assert as_values(arr) == [vals[kind](i) for i in ids.tolist()]


def test_new_elements_read_the_default(store, mesh):
    vs = build(mesh)
    props, vals = _declare_and_fill(store, mesh)
    v = mesh.add_vertex((0.0, 0.0, 1.0))
    e = mesh.add_edge(v, vs[5])
    p = mesh.add_polygon([vs[4], vs[3], vs[5]])
    assert v["vf"] == (0.0,) * 6 and e["label"] == "" and p["flag"] is False
    assert [h["uv"] for h in e.halfedges()] == [None, None]
    ids, arr = mesh.property_array("halfedge", "uv")
    assert [h.id for h in e.halfedges()] == [12, 13]
    assert 11 in [h.id for h in p.halfedges()]  # an old half-edge, with its value
    assert mesh.halfedge(11)["uv"] == (11, -11)
    assert ids.tolist() == list(range(18))
    assert np.ma.getmaskarray(arr).any(axis=1).tolist() == [False] * 12 + [True] * 6
    assert mesh.property_array("vertex", "vf")[1][-1].tolist() == [0.0] * 6
    assert mesh.check() == []


def test_remove_property_deletes_every_value_row(store, mesh):
    build(mesh)
    props, _ = _declare_and_fill(store, mesh)
    keep = mesh.add_property("vertex", "keep", "float64", default=0.0)
    mesh.set_property_array("vertex", "keep", range(6), np.arange(6.0))
    for kind, prop in props.items():
        assert _stored_ids(store, mesh, prop)
        mesh.remove_property(kind, prop.name)
        assert _stored_ids(store, mesh, prop) == set()
        assert mesh.properties(kind) == ({"keep": keep} if kind == "vertex" else {})
    assert value_keys(store, mesh) == {(keep.id, i) for i in range(6)}
    with store.session.reading() as conn:
        rows = conn.execute(sa.select(schema.properties.c.name).where(schema.properties.c.mesh_id == mesh.id)).all()
    assert [r[0] for r in rows] == ["keep"]
    assert mesh.check() == []


def test_delete_mesh_removes_its_values(store, mesh):
    build(mesh)
    _declare_and_fill(store, mesh)
    other = store.create_mesh("other")
    ov = other.add_vertex()
    other.add_property("vertex", "vf", "float64", shape=(6,))
    ov["vf"] = (1.0,) * 6
    store.delete_mesh("m")
    with store.session.reading() as conn:
        for t in VALUE_TABLES + (schema.properties,):
            assert {r[0] for r in conn.execute(sa.select(t.c.mesh_id))} <= {other.id}
    assert ov["vf"] == (1.0,) * 6


# --------------------------------------------------------------------------
# Positions


def test_positions(store, mesh):
    vs = [mesh.add_vertex() for _ in range(4)]
    assert vs[0].position is None
    mesh.set_position(vs[0], (1, 2, 3))
    assert vs[0].position == (1.0, 2.0, 3.0) and all(type(c) is float for c in vs[0].position)
    mesh.set_position(vs[0], np.array([0.5, -0.0, 1e300]))
    assert vs[0].position == (0.5, 0.0, 1e300)
    mesh.set_position(vs[0], None)
    assert vs[0].position is None
    mesh.set_positions(vs[1:3], np.array([[1.0, 1.0, 1.0], [2.0, 2.0, 2.0]]))
    assert [v.position for v in vs] == [None, (1.0, 1.0, 1.0), (2.0, 2.0, 2.0), None]
    mesh.set_positions(np.array([3, 0]), [[3, 3, 3], [0, 0, 0]])  # ids, ints
    assert [v.position for v in vs] == [(0.0, 0.0, 0.0), (1.0, 1.0, 1.0), (2.0, 2.0, 2.0), (3.0, 3.0, 3.0)]
    mesh.set_positions([2], np.array([[5e-324, -1.7976931348623157e308, 0.1]]))
    assert vs[2].position == (5e-324, -1.7976931348623157e308, 0.1)
    arrays = mesh.to_arrays()
    assert arrays.positions.tolist() == [list(v.position) for v in vs]
    assert mesh.check() == []


def test_refused_positions_change_nothing(store, mesh):
    vs = [mesh.add_vertex((float(i), 0.0, 0.0)) for i in range(4)]
    other = store.create_mesh("other")
    ov = other.add_vertex()
    gone = mesh.add_vertex()
    mesh.remove_vertex(gone)
    before, rev = everything(store), mesh.revision
    single = [
        (InvalidInputError, vs[0], (math.nan, 0, 0)), (InvalidInputError, vs[0], (0, math.inf, 0)),
        (InvalidInputError, vs[0], (0, 0, -math.inf)), (InvalidInputError, vs[0], (1, 2)),
        (InvalidInputError, vs[0], (1, 2, 3, 4)), (InvalidInputError, vs[0], "abc"),
        (InvalidInputError, vs[0], (1, "2", 3)), (InvalidInputError, vs[0], (True, 0, 0)),
        (InvalidInputError, vs[0], 5.0), (InvalidInputError, vs[0], (math.nan,) * 3),
        (ElementNotFoundError, gone, (0, 0, 0)), (ElementNotFoundError, ov, (0, 0, 0)),
        (ElementNotFoundError, 10**6, (0, 0, 0)),
    ]
    for exc, v, xyz in single:
        with pytest.raises(exc):
            mesh.set_position(v, xyz)
    bulk = [
        (InvalidInputError, vs[:2], [[0, 0, 0], [math.nan, 0, 0]]),
        (InvalidInputError, vs[:2], [[0, 0, 0], [0, 0, math.inf]]),
        (InvalidInputError, vs[:2], np.zeros((2, 2))),
        (InvalidInputError, vs[:2], np.zeros((3, 3))),
        (InvalidInputError, vs[:2], np.zeros((1, 3))),
        (InvalidInputError, vs[:2], np.zeros((2, 3, 1))),
        (InvalidInputError, vs[:2], np.zeros(6)),
        (InvalidInputError, vs[:2], np.full((2, 3), "1")),
        (InvalidInputError, vs[:2], np.ones((2, 3), dtype=bool)),
        (InvalidInputError, vs[:2], None),
        (InvalidInputError, [vs[0], vs[0]], np.zeros((2, 3))),
        (InvalidInputError, [1, 2, 1], np.zeros((3, 3))),
        (InvalidInputError, np.array([0.0, 1.0]), np.zeros((2, 3))),
        (ElementNotFoundError, [0, gone.id], np.zeros((2, 3))),
        (ElementNotFoundError, [gone], np.zeros((1, 3))),
        (ElementNotFoundError, [0, 10**6], np.zeros((2, 3))),
        (ElementNotFoundError, [vs[0], ov], np.zeros((2, 3))),
    ]
    for exc, ids, xyz in bulk:
        with pytest.raises(exc):
            mesh.set_positions(ids, xyz)
    assert everything(store) == before and mesh.revision == rev
    with store.transaction():
        for exc, ids, xyz in bulk[::3]:
            with pytest.raises(exc):
                mesh.set_positions(ids, xyz)
        for exc, v, xyz in single[::3]:
            with pytest.raises(exc):
                mesh.set_position(v, xyz)
        assert everything(store) == before
    assert mesh.revision == rev
    assert [v.position for v in vs] == [(float(i), 0.0, 0.0) for i in range(4)]


def test_positions_roll_back(store, mesh):
    vs = [mesh.add_vertex((float(i), 0.0, 0.0)) for i in range(4)]
    before, rev = everything(store), mesh.revision
    with pytest.raises(Rollback):
        with store.transaction():
            mesh.set_positions(vs, np.ones((4, 3)))
            mesh.set_position(vs[0], None)
            with store.transaction():
                mesh.set_position(vs[1], (5.0, 5.0, 5.0))
            raise Rollback
    assert everything(store) == before and mesh.revision == rev
    with store.transaction():
        mesh.set_position(vs[0], (9.0, 9.0, 9.0))
        with pytest.raises(Rollback):
            with store.transaction():
                mesh.set_positions(vs[:2], np.full((2, 3), 7.0))
                mesh.set_position(vs[0], None)
                raise Rollback
        assert [v.position for v in vs[:2]] == [(9.0, 9.0, 9.0), (1.0, 0.0, 0.0)]
    assert [v.position for v in vs] == [(9.0, 9.0, 9.0), (1.0, 0.0, 0.0), (2.0, 0.0, 0.0), (3.0, 0.0, 0.0)]
    assert mesh.revision == rev + 1


@pytest.mark.parametrize("new_vertex", [False, True], ids=["existing", "created in the block"])
def test_position_writes_in_one_block_last_call_wins(store, mesh, db_url, new_vertex):
    vs = [mesh.add_vertex((0.0, 0.0, 0.0)) for _ in range(2)]
    rev = mesh.revision
    with store.transaction():  # no reads in between
        a = mesh.add_vertex((-1.0, -1.0, -1.0)) if new_vertex else vs[0]
        b = mesh.add_vertex() if new_vertex else vs[1]
        mesh.set_positions([a, b], [[1, 1, 1], [1, 1, 1]])
        mesh.set_position(a, (2.0, 2.0, 2.0))  # single after set-based: wins
        mesh.set_position(b, (3.0, 3.0, 3.0))
        mesh.set_positions([b], [[4, 4, 4]])  # set-based after single: wins
    assert (a.position, b.position) == ((2.0, 2.0, 2.0), (4.0, 4.0, 4.0))
    with store.transaction():
        mesh.set_position(a, None)
        mesh.set_positions([a], [[5, 5, 5]])
        mesh.set_positions([b], [[6, 6, 6]])
        mesh.set_position(b, None)
        c = mesh.add_vertex((7.0, 7.0, 7.0))
        mesh.set_position(c, (8.0, 8.0, 8.0))
        mesh.set_positions([c], [[9, 9, 9]])
        d = mesh.add_vertex()
        mesh.set_positions([d], [[10, 10, 10]])
        mesh.set_position(d, None)
    assert mesh.revision == rev + 2
    expected = [(5.0, 5.0, 5.0), None, (9.0, 9.0, 9.0), None]
    assert [x.position for x in (a, b, c, d)] == expected
    with hestore.open(db_url) as other:
        m = other.mesh("m")
        assert [m.vertex(x.id).position for x in (a, b, c, d)] == expected
    assert mesh.check() == []


# --------------------------------------------------------------------------
# check()


def test_check_stays_clean_with_values(store, mesh):
    build(mesh)
    _declare_and_fill(store, mesh)
    assert mesh.check() == []
    mesh.remove_polygon(mesh.polygon(0))
    mesh.remove_vertex(mesh.vertex(2))
    assert mesh.check() == []
    mesh.validate()


@pytest.mark.parametrize("dtype", ["float64", "int64", "str"])
def test_check_reports_values_of_missing_elements(store, mesh, db_url, dtype):
    vs = build(mesh)
    prop = mesh.add_property("vertex", "t", dtype)
    vs[0]["t"] = {"float64": 1.0, "int64": 1, "str": "x"}[dtype]
    table = {"float64": "property_reals", "int64": "property_integers", "str": "property_texts"}[dtype]
    value = {"float64": "1.0", "int64": "1", "str": "'x'"}[dtype]
    engine = sa.create_engine(db_url, poolclass=sa.pool.NullPool)
    try:
        with engine.begin() as conn:
            conn.execute(sa.text(
                f"INSERT INTO {table} (mesh_id, property, id, part, v0) VALUES ({mesh.id}, {prop.id}, 999, 0, {value})"
            ))
    finally:
        engine.dispose()
    violations = mesh.check()
    assert any(v.code == "PROPERTY_REF" for v in violations), violations
