"""Tests of hestore.validation: the invariants and their set-based check.

Most tests build small topologies by hand as `TopologyArrays` (no database),
check that they are valid, then break one thing at a time and assert exactly
which invariant codes and element ids are reported. The last tests store a
mesh's rows with SQLAlchemy Core on both backends and read them back with
`load_arrays`.
"""

from __future__ import annotations

import time
from collections import Counter

import numpy as np
import pytest
import sqlalchemy as sa
from sqlalchemy import event
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hestore import schema
from hestore import _columns as columns
from hestore.arrays import Index, TopologyArrays, cycles
from hestore.errors import InvalidInputError, Violation
from hestore.validation import (
    CODE_DESCRIPTIONS,
    CODES,
    KINDS,
    check_arrays,
    load_arrays,
)

# --------------------------------------------------------------------------
# Builders (test code: plain Python loops are fine here)

FREE = -1


def build(n_vertices, edges, polygons=()):
    """Topology arrays from edges and polygons given by half-edge.

    Edge ``k = (a, b)`` has half-edges ``2k`` (a -> b) and ``2k + 1`` (b -> a).
    A polygon is a list of half-edges in ``next`` order (counter-clockwise).
    Free half-edges are linked around each vertex so that the fans there form
    one rotation cycle (the boundary convention of seed 000). Vertex ``v``'s
    halfedge is its lowest free outgoing half-edge, else its lowest outgoing.
    """
    nh = 2 * len(edges)
    origin = [0] * nh
    for k, (a, b) in enumerate(edges):
        origin[2 * k], origin[2 * k + 1] = a, b
    twin = [h ^ 1 for h in range(nh)]
    nxt = [None] * nh
    polygon = [FREE] * nh
    for p, loop in enumerate(polygons):
        for i, h in enumerate(loop):
            assert polygon[h] == FREE, f"half-edge {h} used twice"
            polygon[h] = p
            nxt[h] = loop[(i + 1) % len(loop)]
    for h in range(nh):
        if polygon[h] != FREE:
            assert origin[nxt[h]] == origin[twin[h]], f"polygon loop does not chain at {h}"
    # Link the fans around each vertex: a fan starts at a free outgoing
    # half-edge o and, rotating h -> next(twin(h)) through polygons, ends at the
    # outgoing e whose twin is free; twin(e_k) is then linked to o_{k+1}.
    for v in range(n_vertices):
        starts = [h for h in range(nh) if origin[h] == v and polygon[h] == FREE]
        ends = []
        for o in starts:
            h = o
            while polygon[twin[h]] != FREE:
                h = nxt[twin[h]]
            ends.append(h)
        for k, e in enumerate(ends):
            nxt[twin[e]] = starts[(k + 1) % len(starts)]
    assert None not in nxt
    prev = [0] * nh
    for h in range(nh):
        prev[nxt[h]] = h
    v_halfedge = []
    for v in range(n_vertices):
        out = [h for h in range(nh) if origin[h] == v]
        free = [h for h in out if polygon[h] == FREE]
        v_halfedge.append(free[0] if free else out[0] if out else FREE)
    a = lambda x: np.array(x, dtype=np.int64).reshape(-1)  # noqa: E731
    return TopologyArrays(
        he_id=a(range(nh)),
        he_origin=a(origin),
        he_next=a(nxt),
        he_prev=a(prev),
        he_twin=a(twin),
        he_edge=a([h // 2 for h in range(nh)]),
        he_polygon=a(polygon),
        v_id=a(range(n_vertices)),
        v_halfedge=a(v_halfedge),
        e_id=a(range(len(edges))),
        e_halfedge=a([2 * k for k in range(len(edges))]),
        p_id=a(range(len(polygons))),
        p_halfedge=a([loop[0] for loop in polygons]),
    )


def build_faces(n_vertices, faces, extra_edges=()):
    """`build` from polygons given by vertex loops (edges found by vertex pair)."""
    edges, polygons, index = [], [], {}
    for a, b in extra_edges:
        index.setdefault(frozenset((a, b)), len(edges))
        edges.append((a, b))
    for face in faces:
        loop = []
        for i, a in enumerate(face):
            b = face[(i + 1) % len(face)]
            key = frozenset((a, b))
            if key not in index:
                index[key] = len(edges)
                edges.append((a, b))
            k = index[key]
            loop.append(2 * k if edges[k][0] == a else 2 * k + 1)
        polygons.append(loop)
    return build(n_vertices, edges, polygons)


def grid_arrays(n):
    """The triangulated n x n grid (2 triangles per cell), built with numpy.

    Half-edges ``2e``/``2e + 1`` form edge ``e``; the one boundary loop of
    free half-edges is linked with ``next(f) = the free half-edge leaving
    target(f)`` (every boundary vertex has exactly one).
    """
    side = n + 1
    nv = side * side
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    a = (i * side + j).ravel()
    b = a + side
    c = b + 1
    d = a + 1
    tris = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return arrays_from_triangles(nv, tris)


def arrays_from_triangles(nv, tris):
    """Half-edge arrays of an oriented manifold triangle list, set-based."""
    tris = np.asarray(tris, dtype=np.int64)
    nt = len(tris)
    corner = np.arange(3)
    org = tris.ravel()
    dst = tris[:, (corner + 1) % 3].ravel()
    k = np.arange(3 * nt)
    nxt = 3 * (k // 3) + (k + 1) % 3
    pol = k // 3
    # twin matching by directed vertex pair
    key = org * nv + dst
    order = np.argsort(key)
    rev = dst * nv + org
    pos = np.minimum(np.searchsorted(key[order], rev), len(k) - 1)
    matched = key[order][pos] == rev
    twin = np.where(matched, order[pos], -1)
    # boundary: a free twin for each unmatched inner half-edge
    u = np.flatnonzero(~matched)
    nb = len(u)
    f = 3 * nt + np.arange(nb)
    twin[u] = f
    twin = np.concatenate([twin, u])
    org = np.concatenate([org, dst[u]])
    dst = np.concatenate([dst, tris.ravel()[u]])
    free_out = np.full(nv, -1)
    free_out[org[f]] = f
    nxt = np.concatenate([nxt, free_out[dst[f]]])
    pol = np.concatenate([pol, np.full(nb, -1)])
    n = len(org)
    # edges: the lower of each twin pair is half-edge 2e, the other 2e + 1
    lower = np.flatnonzero(np.arange(n) < twin)
    new = np.empty(n, dtype=np.int64)
    new[lower] = 2 * np.arange(len(lower))
    new[twin[lower]] = new[lower] + 1
    inv = np.empty(n, dtype=np.int64)
    inv[new] = np.arange(n)
    he_next = new[nxt][inv]
    he_prev = np.empty(n, dtype=np.int64)
    he_prev[he_next] = np.arange(n)
    he_origin = org[inv]
    he_polygon = pol[inv]
    # vertex halfedge: a free outgoing one where there is one
    v_halfedge = np.full(nv, -1)
    v_halfedge[he_origin] = np.arange(n)
    free = np.flatnonzero(he_polygon == -1)
    v_halfedge[he_origin[free]] = free
    p_halfedge = np.empty(nt, dtype=np.int64)
    p_halfedge[he_polygon[he_polygon >= 0]] = np.flatnonzero(he_polygon >= 0)
    ne = n // 2
    return TopologyArrays(
        he_id=np.arange(n),
        he_origin=he_origin,
        he_next=he_next,
        he_prev=he_prev,
        he_twin=np.arange(n) ^ 1,
        he_edge=np.arange(n) // 2,
        he_polygon=he_polygon,
        v_id=np.arange(nv),
        v_halfedge=v_halfedge,
        e_id=np.arange(ne),
        e_halfedge=2 * np.arange(ne),
        p_id=np.arange(nt),
        p_halfedge=p_halfedge,
    )


def relabel(arrays, seed=0, spread=10):
    """The same topology under random sparse ids, each table in random row order."""
    rng = np.random.default_rng(seed)
    maps = {}
    for kind, col in (("h", "he_id"), ("v", "v_id"), ("e", "e_id"), ("p", "p_id")):
        n = len(getattr(arrays, col))
        fresh = rng.choice(spread * n + 50, size=n, replace=False).astype(np.int64)
        maps[kind] = fresh

    def m(kind, values):
        values = np.asarray(values)
        out = values.copy()
        ok = values >= 0
        out[ok] = maps[kind][values[ok]]
        return out

    new = arrays._replace(
        he_id=m("h", arrays.he_id),
        he_origin=m("v", arrays.he_origin),
        he_next=m("h", arrays.he_next),
        he_prev=m("h", arrays.he_prev),
        he_twin=m("h", arrays.he_twin),
        he_edge=m("e", arrays.he_edge),
        he_polygon=m("p", arrays.he_polygon),
        v_id=m("v", arrays.v_id),
        v_halfedge=m("h", arrays.v_halfedge),
        e_id=m("e", arrays.e_id),
        e_halfedge=m("h", arrays.e_halfedge),
        p_id=m("p", arrays.p_id),
        p_halfedge=m("h", arrays.p_halfedge),
    )
    # shuffle the rows of each table (check_arrays sorts them)
    out = new._asdict()
    for prefix in ("he_", "v_", "e_", "p_"):
        names = [k for k in out if k.startswith(prefix)]
        perm = rng.permutation(len(out[names[0]]))
        for k in names:
            out[k] = out[k][perm]
    return TopologyArrays(**out), maps


def sorted_arrays(arrays):
    """The arrays with each table sorted by id (what load_arrays returns)."""
    out = arrays._asdict()
    for prefix in ("he_", "v_", "e_", "p_"):
        names = [k for k in out if k.startswith(prefix)]
        order = np.argsort(out[names[0]], kind="stable")
        for k in names:
            out[k] = np.asarray(out[k], dtype=np.int64)[order]
    return TopologyArrays(**out)


def edit(arrays, **changes):
    """A copy of ``arrays`` with ``column={id: value}`` changes (ids = row numbers)."""
    out = {k: np.array(v, dtype=np.int64, copy=True) for k, v in arrays._asdict().items()}
    for column, values in changes.items():
        for row, value in values.items():
            out[column][row] = value
    return TopologyArrays(**out)


def codes(violations):
    return [v.code for v in violations]


def found(violations):
    """{(code, kind, id)} of a report."""
    return {(v.code, v.kind, v.ids[0]) for v in violations}


def tetrahedron():
    return build_faces(4, [(0, 2, 1), (0, 1, 3), (1, 2, 3), (0, 3, 2)])


def octahedron():
    # vertices: 0 +x, 1 -x, 2 +y, 3 -y, 4 +z, 5 -z; faces counter-clockwise seen from outside
    faces = [(0, 2, 4), (2, 1, 4), (1, 3, 4), (3, 0, 4), (2, 0, 5), (1, 2, 5), (3, 1, 5), (0, 3, 5)]
    return build_faces(6, faces)


def open_fan():
    return build_faces(6, [(0, 1, 2), (0, 2, 3), (0, 3, 4), (0, 4, 5)])


def bowtie():
    return build_faces(5, [(0, 1, 2), (0, 3, 4)])


VALID = {
    "empty": lambda: TopologyArrays.empty(),
    "isolated vertices": lambda: build(3, []),
    "tetrahedron": tetrahedron,
    "octahedron": octahedron,
    "open triangle fan": open_fan,
    "quad and triangle": lambda: build_faces(5, [(0, 1, 2, 3), (1, 4, 2)]),
    "wire edge and isolated vertex": lambda: build(3, [(0, 1)]),
    "wire path": lambda: build(4, [(0, 1), (1, 2), (2, 3), (1, 3)]),
    "self-loop at isolated vertex": lambda: build(1, [(0, 0)]),
    "two self-loops at one vertex": lambda: build(1, [(0, 0), (0, 0)]),
    "1-gon on a loop": lambda: build(1, [(0, 0)], [[0]]),
    "2-gon on one edge": lambda: build(2, [(0, 1)], [[0, 1]]),
    "2-gon on parallel edges": lambda: build(2, [(0, 1), (0, 1)], [[0, 3]]),
    "three parallel edges": lambda: build(2, [(0, 1), (0, 1), (1, 0)]),
    "bowtie (two triangles at one vertex)": bowtie,
    "triangle with dangling wire and loop": lambda: build_faces(5, [(0, 1, 2)], extra_edges=[(0, 3), (3, 3), (2, 4)]),
    "triangle beside a parallel wire edge": lambda: build(3, [(0, 1), (1, 2), (2, 0), (0, 1)], [[0, 2, 4]]),
    # a square whose loop goes out along a dangling edge and back (both its half-edges)
    "polygon around a dangling edge": lambda: build(5, [(0, 1), (1, 2), (2, 3), (3, 0), (0, 4)], [[0, 2, 4, 6, 8, 9]]),
    "grid 3x3": lambda: grid_arrays(3),
}


# --------------------------------------------------------------------------
# Codes and the Violation record


def test_codes_are_ordered_and_described():
    assert CODES == (
        "H_TWIN",
        "H_NEXT_PREV",
        "H_ORIGIN",
        "H_EDGE",
        "H_POLYGON",
        "P_LOOP",
        "V_HALFEDGE",
        "V_ROTATION",
        "V_BOUNDARY",
        "REF",
        "POLICY",
        "PROPERTY_REF",
        "HISTORY",
    )
    assert list(CODE_DESCRIPTIONS) == list(CODES)
    assert all(isinstance(d, str) and d and "\n" not in d for d in CODE_DESCRIPTIONS.values())
    assert KINDS == ("halfedge", "vertex", "edge", "polygon", "property", "revision")


def test_violation_is_frozen_and_formats():
    v = Violation("H_TWIN", "halfedge", (12, 40), "twin(twin(12)) = 40, expected 12")
    assert str(v) == "H_TWIN halfedge 12: twin(twin(12)) = 40, expected 12"
    assert v.id == 12
    assert v == Violation("H_TWIN", "halfedge", (12, 40), "twin(twin(12)) = 40, expected 12")
    assert hash(v) == hash(Violation("H_TWIN", "halfedge", (12, 40), "twin(twin(12)) = 40, expected 12"))
    with pytest.raises(AttributeError):
        v.code = "REF"


# --------------------------------------------------------------------------
# Valid topologies


@pytest.mark.parametrize("name", list(VALID))
def test_valid_topologies_pass(name):
    arrays = VALID[name]()
    assert check_arrays(arrays) == []
    # ids are arbitrary: sparse, and rows need not come sorted
    shuffled, _ = relabel(arrays, seed=len(name))
    assert check_arrays(shuffled) == []


def test_builders_make_what_the_brief_says():
    loop = build(1, [(0, 0)])
    assert list(loop.he_next) == [0, 1]  # each half-edge of an isolated loop is its own next
    wire = build(2, [(0, 1)])
    assert list(wire.he_next) == list(wire.he_twin)
    one_gon = build(1, [(0, 0)], [[0]])
    assert one_gon.he_next[0] == 0 and one_gon.he_polygon[0] == 0
    two_gon = build(2, [(0, 1)], [[0, 1]])
    assert list(two_gon.he_polygon) == [0, 0]
    # bowtie: one boundary loop of 6 free half-edges through vertex 0 twice
    tie = bowtie()
    free = np.flatnonzero(tie.he_polygon == -1)
    assert len(free) == 6
    h, seen = free[0], []
    while h not in seen:
        seen.append(h)
        h = tie.he_next[h]
    assert sorted(seen) == sorted(free)


def test_check_never_modifies_its_input():
    arrays = edit(tetrahedron(), he_next={0: 5}, v_halfedge={1: -1})
    before = {k: v.copy() for k, v in arrays._asdict().items()}
    assert check_arrays(arrays)
    for k, v in arrays._asdict().items():
        np.testing.assert_array_equal(v, before[k])


# --------------------------------------------------------------------------
# One corruption at a time


def test_broken_next_and_prev():
    base = tetrahedron()
    # next(0) and next(n2) swapped: prev is stale on both ends
    n0 = int(base.he_next[0])
    other = int(np.flatnonzero((base.he_polygon != base.he_polygon[0]))[0])
    n1 = int(base.he_next[other])
    arrays = edit(base, he_next={0: n1, other: n0})
    report = check_arrays(arrays)
    assert ("H_NEXT_PREV", "halfedge", 0) in found(report)
    assert ("H_NEXT_PREV", "halfedge", other) in found(report)
    first = [v for v in report if v.code == "H_NEXT_PREV" and v.id == 0][0]
    assert first.ids == (0, n1, other)
    assert str(first) == f"H_NEXT_PREV halfedge 0: prev(next(0)) = {other} (next(0) = {n1}), expected 0"
    # fixing prev as well still breaks the polygons (loops of the wrong polygon)
    arrays = edit(arrays, he_prev={n1: 0, n0: other})
    report = check_arrays(arrays)
    assert "H_NEXT_PREV" not in codes(report)
    assert {"H_POLYGON", "P_LOOP", "H_ORIGIN"} <= set(codes(report))


def test_broken_prev_only():
    base = open_fan()
    p = int(base.he_prev[3])
    arrays = edit(base, he_prev={3: int(base.he_prev[p])})
    report = check_arrays(arrays)
    assert set(codes(report)) == {"H_NEXT_PREV"}
    assert ("H_NEXT_PREV", "halfedge", 3) in found(report)


def test_broken_twin():
    base = tetrahedron()
    arrays = edit(base, he_twin={0: 2})
    report = check_arrays(arrays)
    twin_reports = [v for v in report if v.code == "H_TWIN"]
    # 0 -> 2 -> 3 breaks at 0, and 1 -> 0 -> 2 at 1
    assert [v.id for v in twin_reports] == [0, 1]
    assert twin_reports[0].ids == (0, 2, 3)
    assert twin_reports[1].ids == (1, 0, 2)
    assert "twin(twin(0)) = 3 (twin(0) = 2), expected 0" in twin_reports[0].message
    assert "H_EDGE" in codes(report)  # edge(0) != edge(2)
    # a half-edge that is its own twin
    report = check_arrays(edit(base, he_twin={5: 5}))
    assert ("H_TWIN", "halfedge", 5) in found(report)
    assert any("cannot be its own twin" in v.message for v in report)


def test_broken_origin():
    base = octahedron()
    arrays = edit(base, he_origin={6: 5 if base.he_origin[6] != 5 else 4})
    report = check_arrays(arrays)
    assert "H_ORIGIN" in codes(report)
    # the half-edge before 6 and the twin of 6 see the inconsistent destination
    assert ("H_ORIGIN", "halfedge", int(base.he_prev[6])) in found(report)
    assert ("H_ORIGIN", "halfedge", 7) in found(report)
    assert "V_ROTATION" in codes(report)


def test_vertex_halfedge_not_outgoing():
    base = tetrahedron()
    incoming = int(np.flatnonzero(base.he_origin != 0)[0])
    report = check_arrays(edit(base, v_halfedge={0: incoming}))
    assert codes(report) == ["V_HALFEDGE"]
    v = report[0]
    assert v.kind == "vertex" and v.ids == (0, incoming)
    assert f"halfedge = {incoming}, but origin({incoming}) = vertex {base.he_origin[incoming]}" in v.message


def test_vertex_halfedge_null_with_outgoing():
    report = check_arrays(edit(open_fan(), v_halfedge={2: -1}))
    assert codes(report) == ["V_HALFEDGE"]
    assert report[0].id == 2
    assert "halfedge is NULL, but 3 half-edge(s) start at vertex 2" in report[0].message


def test_isolated_vertex_with_halfedge():
    base = build(3, [(0, 1)])
    report = check_arrays(edit(base, v_halfedge={2: 0}))
    assert found(report) == {("V_HALFEDGE", "vertex", 2)}
    assert "no half-edge starts at vertex 2" in report[0].message


def test_boundary_vertex_must_point_at_a_free_halfedge():
    base = open_fan()
    # vertex 0 (the fan's centre) has a free outgoing half-edge and reserved ones
    reserved = int(np.flatnonzero((base.he_origin == 0) & (base.he_polygon != -1))[0])
    free = int(base.v_halfedge[0])
    assert base.he_polygon[free] == -1
    report = check_arrays(edit(base, v_halfedge={0: reserved}))
    assert codes(report) == ["V_BOUNDARY"]
    assert report[0].ids == (0, reserved, free)
    assert f"free half-edge(s) start at vertex 0 (e.g. {free})" in report[0].message


def test_polygon_label_on_another_loop():
    base = octahedron()
    # give a half-edge of polygon 3's loop the label of polygon 0
    h = int(np.flatnonzero(base.he_polygon == 3)[0])
    report = check_arrays(edit(base, he_polygon={h: 0}))
    assert {"H_POLYGON", "P_LOOP"} == set(codes(report))
    loops = {v.id: v for v in report if v.code == "P_LOOP"}
    assert set(loops) == {0, 3}
    assert loops[0].message.endswith(f"has 3 half-edge(s), but polygon 0 has 4; 1 not on the loop (e.g. {h})")
    x = int(base.he_prev[h])
    assert loops[3].ids == (3, int(base.p_halfedge[3]), x, h)
    assert loops[3].message.endswith(f"leaves the polygon: next({x}) = {h} lies in polygon 0")


def test_polygon_halfedge_of_another_polygon():
    base = tetrahedron()
    h = int(base.p_halfedge[1])
    report = check_arrays(edit(base, p_halfedge={0: h}))
    assert found(report) == {("P_LOOP", "polygon", 0)}
    assert report[0].message == f"halfedge = {h}, but polygon({h}) = 1"


def test_polygon_pointing_at_a_free_loop():
    base = open_fan()
    free = int(np.flatnonzero(base.he_polygon == -1)[0])
    report = check_arrays(edit(base, p_halfedge={2: free}))
    assert found(report) == {("P_LOOP", "polygon", 2)}
    assert "polygon(" in report[0].message and "NULL" in report[0].message


def test_free_loop_labelled_as_polygon():
    # a whole boundary loop gets polygon 0's label: P_LOOP, no H_POLYGON inside it
    base = build_faces(3, [(0, 1, 2)])
    free = np.flatnonzero(base.he_polygon == -1)
    report = check_arrays(edit(base, he_polygon={int(h): 0 for h in free}))
    assert found(report) == {("P_LOOP", "polygon", 0)}
    assert "but polygon 0 has 6; 3 not on the loop" in report[0].message


def test_two_rotation_cycles_at_a_bowtie_vertex():
    base = bowtie()
    # relink the one boundary loop into two: each triangle gets its own loop
    free = np.flatnonzero(base.he_polygon == -1)
    into0 = [int(h) for h in free if base.he_origin[base.he_twin[h]] == 0]  # free half-edges ending at 0
    a, b = into0
    na, nb = int(base.he_next[a]), int(base.he_next[b])
    arrays = edit(base, he_next={a: nb, b: na}, he_prev={nb: a, na: b})
    report = check_arrays(arrays)
    assert codes(report) == ["V_ROTATION"]
    v = report[0]
    assert v.kind == "vertex" and v.id == 0
    assert "visits 2 half-edge(s), but 4 start at vertex 0" in v.message
    assert "2 not visited (e.g." in v.message


def test_dangling_references_of_every_kind():
    base = build_faces(4, [(0, 1, 2)], extra_edges=[(2, 3)])
    cases = [
        ("he_origin", 0, 99, "halfedge", "origin = 99, but there is no vertex 99"),
        ("he_next", 1, 98, "halfedge", "next = 98, but there is no halfedge 98"),
        ("he_prev", 2, 97, "halfedge", "prev = 97, but there is no halfedge 97"),
        ("he_twin", 3, 96, "halfedge", "twin = 96, but there is no halfedge 96"),
        ("he_edge", 4, 95, "halfedge", "edge = 95, but there is no edge 95"),
        ("he_polygon", 5, 94, "halfedge", "polygon = 94, but there is no polygon 94"),
        ("v_halfedge", 1, 93, "vertex", "halfedge = 93, but there is no halfedge 93"),
        ("e_halfedge", 2, 92, "edge", "halfedge = 92, but there is no halfedge 92"),
        ("p_halfedge", 0, 91, "polygon", "halfedge = 91, but there is no halfedge 91"),
    ]
    for column, row, value, kind, message in cases:
        report = check_arrays(edit(base, **{column: {row: value}}))
        refs = [v for v in report if v.code == "REF"]
        assert len(refs) == 1, (column, report)
        assert refs[0].kind == kind and refs[0].ids == (row, value), (column, refs)
        assert refs[0].message.startswith(message), refs[0].message
    # all at once: nothing crashes, every one is reported, in id order
    changes = {}
    for column, row, value, *_ in cases:
        changes.setdefault(column, {})[row] = value
    report = check_arrays(edit(base, **changes))
    refs = [v for v in report if v.code == "REF"]
    assert len(refs) == len(cases)
    assert [v.id for v in refs] == sorted(v.id for v in refs)


def test_dangling_next_is_reported_once():
    # the walks that would follow it (polygon loop, rotations) are skipped
    base = tetrahedron()
    report = check_arrays(edit(base, he_next={0: 1000}))
    assert codes(report) == ["REF"]
    report = check_arrays(edit(base, he_twin={0: 1000}))
    assert codes(report) == ["REF"]
    report = check_arrays(edit(base, he_origin={0: 1000}))
    assert codes(report) == ["REF"]


def test_references_to_another_mesh_are_dangling():
    # ids that do not exist in *this* mesh's arrays, whatever another mesh has
    base = tetrahedron()
    report = check_arrays(edit(base, he_edge={0: -7}))
    assert ("REF", "halfedge", 0) in found(report)


def test_edge_with_wrong_halfedge_count_and_back_pointer():
    base = build(3, [(0, 1), (1, 2)])
    # edge 1's half-edges both claim edge 0
    arrays = edit(base, he_edge={2: 0, 3: 0})
    report = check_arrays(arrays)
    assert ("H_EDGE", "edge", 0) in found(report)
    assert ("H_EDGE", "edge", 1) in found(report)
    messages = [(v.id, v.message) for v in report if v.kind == "edge"]
    assert messages == [
        (0, "has 4 half-edge(s) (0, 1, 2, 3), expected 2"),
        (1, "halfedge = 2, but edge(2) = 0, not 1"),
        (1, "has 0 half-edge(s), expected 2"),
    ]
    # edge.halfedge pointing at another edge's half-edge
    report = check_arrays(edit(base, e_halfedge={0: 2}))
    assert found(report) == {("H_EDGE", "edge", 0)}


def test_edge_mismatch_across_twins():
    base = tetrahedron()
    report = check_arrays(edit(base, he_edge={0: 1}))
    assert ("H_EDGE", "halfedge", 0) in found(report)
    assert ("H_EDGE", "halfedge", 1) in found(report)
    assert ("H_EDGE", "edge", 0) in found(report)  # edge 0 now has one half-edge
    assert ("H_EDGE", "edge", 1) in found(report)  # edge 1 three


def test_policy_loops_and_parallel_edges():
    loops = build(2, [(0, 1), (1, 1)])
    assert check_arrays(loops) == []
    report = check_arrays(loops, allow_loops=False)
    assert found(report) == {("POLICY", "edge", 1)}
    assert report[0].message == "is a self-loop at vertex 1, but the mesh does not allow loops"
    assert check_arrays(loops, allow_multi_edges=False) == []

    parallel = build(3, [(0, 1), (1, 2), (1, 0), (0, 1)])
    assert check_arrays(parallel) == []
    report = check_arrays(parallel, allow_multi_edges=False)
    assert [(v.code, v.id) for v in report] == [("POLICY", 2), ("POLICY", 3)]
    assert report[0].ids == (2, 0)
    assert "joins vertices 0 and 1 like edge 0" in report[0].message
    assert check_arrays(parallel, allow_loops=False) == []

    # two loops at one vertex are parallel edges too (as in networkx)
    two_loops = build(1, [(0, 0), (0, 0)])
    assert found(check_arrays(two_loops, allow_multi_edges=False)) == {("POLICY", "edge", 1)}
    report = check_arrays(two_loops, allow_loops=False, allow_multi_edges=False)
    assert [(v.id, "loop" in v.message) for v in report] == [(0, True), (1, True), (1, False)]


# --------------------------------------------------------------------------
# Ordering, limit, input handling


def test_report_order_and_limit():
    base = octahedron()
    arrays = edit(
        base,
        he_twin={9: 9},
        he_next={20: 3000},
        v_halfedge={4: -1},
        he_edge={14: 0},
    )
    report = check_arrays(arrays, allow_loops=False)
    assert len(report) >= 4
    keys = [(CODES.index(v.code), v.id) for v in report]
    assert keys == sorted(keys)
    for limit in range(len(report) + 2):
        assert check_arrays(arrays, allow_loops=False, limit=limit) == report[:limit]
    with pytest.raises(InvalidInputError):
        check_arrays(arrays, limit=-1)


def test_same_report_under_other_ids():
    base = octahedron()
    arrays = edit(base, he_next={0: int(base.he_next[10]), 10: int(base.he_next[0])}, v_halfedge={2: 1})
    report = check_arrays(arrays)
    shuffled, maps = relabel(arrays, seed=3)
    other = check_arrays(shuffled)
    assert Counter((v.code, v.kind) for v in report) == Counter((v.code, v.kind) for v in other)
    table = {"halfedge": maps["h"], "vertex": maps["v"], "edge": maps["e"], "polygon": maps["p"]}
    assert sorted((v.code, int(table[v.kind][v.id])) for v in report) == sorted((v.code, v.id) for v in other)


def test_malformed_arrays_are_refused():
    base = tetrahedron()
    with pytest.raises(InvalidInputError, match="different lengths"):
        check_arrays(base._replace(he_next=base.he_next[:-1]))
    with pytest.raises(InvalidInputError, match="duplicate vertex id 1"):
        check_arrays(base._replace(v_id=np.array([0, 1, 1, 3])))
    with pytest.raises(InvalidInputError):
        check_arrays(base._replace(he_polygon=base.he_polygon.astype(float) + 0.5))


def test_plain_lists_are_accepted():
    arrays = TopologyArrays(*[list(map(int, col)) for col in tetrahedron()])
    assert check_arrays(arrays) == []


# --------------------------------------------------------------------------
# Random corruption (hypothesis)

_GRID = grid_arrays(3)
_COLUMNS = [name for name in TopologyArrays._fields if name not in ("he_id", "v_id", "e_id", "p_id")]


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_permuting_one_column_is_always_detected(data):
    """Every stored column is determined by the others: any change is caught."""
    column = data.draw(st.sampled_from(_COLUMNS), label="column")
    values = np.array(getattr(_GRID, column), copy=True)
    rows = data.draw(
        st.lists(st.integers(0, len(values) - 1), min_size=2, max_size=6, unique=True),
        label="rows",
    )
    perm = data.draw(st.permutations(rows), label="perm")
    values[rows] = values[perm]
    arrays = _GRID._replace(**{column: values})
    report = check_arrays(arrays)
    changed = not np.array_equal(values, getattr(_GRID, column))
    if changed:
        assert report, f"{column}: rows {rows} -> {perm} went unnoticed"
    else:
        assert report == []


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_arbitrary_corruption_never_crashes(data):
    arrays = {k: np.array(v, copy=True) for k, v in _GRID._asdict().items()}
    dangling = False
    for _ in range(data.draw(st.integers(1, 8), label="edits")):
        column = data.draw(st.sampled_from(_COLUMNS), label="column")
        row = data.draw(st.integers(0, len(arrays[column]) - 1), label="row")
        value = data.draw(st.integers(-3, 2 * len(arrays["he_id"])), label="value")
        arrays[column][row] = value
    table = {"he_origin": "v_id", "he_next": "he_id", "he_prev": "he_id", "he_twin": "he_id", "he_edge": "e_id",
             "he_polygon": "p_id", "v_halfedge": "he_id", "e_halfedge": "he_id", "p_halfedge": "he_id"}
    for column, target in table.items():
        refs = arrays[column]
        nullable = column in ("he_polygon", "v_halfedge")
        missing = ~np.isin(refs, arrays[target]) & ~((refs == -1) & nullable)
        dangling |= bool(missing.any())
    report = check_arrays(TopologyArrays(**arrays))
    for v in report:
        assert v.code in CODES and v.kind in KINDS and v.message
        assert all(isinstance(x, int) for x in v.ids)
        assert str(v).startswith(f"{v.code} {v.kind} {v.id}: ")
    keys = [(CODES.index(v.code), v.id) for v in report]
    assert keys == sorted(keys)
    assert ("REF" in codes(report)) == dangling
    assert check_arrays(TopologyArrays(**arrays), limit=3) == report[:3]


@settings(max_examples=100, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_random_next_functions_never_hang(seed):
    """next/twin may be any function (not a permutation): the check terminates."""
    rng = np.random.default_rng(seed)
    base = grid_arrays(2)
    n = len(base.he_id)
    arrays = base._replace(he_next=rng.integers(0, n, n), he_twin=rng.integers(0, n, n))
    report = check_arrays(arrays)
    assert "H_NEXT_PREV" in codes(report) or np.array_equal(arrays.he_next, base.he_next)


def test_cycles_labels_functional_graphs():
    # 0 -> 1 -> 2 -> 0 is a cycle, 3 -> 4 -> 1 a tail into it, 5 a fixed point, 6 -> 5
    f = np.array([1, 2, 0, 4, 1, 5, 5])
    label, on_cycle, end = cycles(f)
    assert list(on_cycle) == [True, True, True, False, False, True, False]
    assert list(label[:3]) == [0, 0, 0] and label[5] == 5
    assert f[end[3]] in (0, 1, 2) and end[6] == 5
    # a permutation with long cycles
    rng = np.random.default_rng(1)
    perm = rng.permutation(1000)
    label, on_cycle, end = cycles(perm)
    assert on_cycle.all()
    assert np.array_equal(label[perm], label)  # constant along cycles
    # the least element of each cycle is its own label
    assert (label <= np.arange(1000)).all()
    assert len(np.unique(label)) == len(np.unique(label[label == np.arange(1000)]))


# --------------------------------------------------------------------------
# Scale


def test_grid_200_checks_fast():
    arrays = grid_arrays(200)
    assert len(arrays.p_id) == 80_000
    start = time.process_time()  # this process's: a busy machine does not add to it
    report = check_arrays(arrays)
    elapsed = time.process_time() - start
    assert report == []
    assert elapsed < 5.0, f"check_arrays took {elapsed:.2f} s on 80k triangles"
    # one corruption in a big mesh is found and named
    h = 123_457
    arrays = arrays._replace(he_twin=arrays.he_twin.copy())
    arrays.he_twin[h] = h
    assert ("H_TWIN", "halfedge", h) in found(check_arrays(arrays))


# --------------------------------------------------------------------------
# load_arrays on both backends


def _insert(conn, mesh_id, arrays):
    a = arrays
    conn.execute(
        schema.vertices.insert(),
        [
            {"mesh_id": mesh_id, "id": int(i), "halfedge": None if h == -1 else int(h), "x": 0.0, "y": 0.0, "z": 0.0}
            for i, h in zip(a.v_id, a.v_halfedge)
        ],
    )
    conn.execute(
        schema.halfedges.insert(),
        [
            {
                "mesh_id": mesh_id,
                "id": int(row[0]),
                "origin": int(row[1]),
                "next": int(row[2]),
                "prev": int(row[3]),
                "twin": int(row[4]),
                "edge": int(row[5]),
                "polygon": None if row[6] == -1 else int(row[6]),
            }
            for row in zip(a.he_id, a.he_origin, a.he_next, a.he_prev, a.he_twin, a.he_edge, a.he_polygon)
        ],
    )
    for table, ids, halfedge in ((schema.edges, a.e_id, a.e_halfedge), (schema.polygons, a.p_id, a.p_halfedge)):
        if len(ids):
            rows = [{"mesh_id": mesh_id, "id": int(i), "halfedge": int(h)} for i, h in zip(ids, halfedge)]
            conn.execute(table.insert(), rows)


def _new_mesh(conn, name):
    return conn.execute(
        schema.meshes.insert().returning(schema.meshes.c.id),
        {
            "name": name,
            "allow_loops": True,
            "allow_multi_edges": True,
            "revision": 0,
            "next_vertex": 0,
            "next_edge": 0,
            "next_polygon": 0,
        },
    ).scalar_one()


def _sample_mesh():
    # a tetrahedron-like closed part, a fan with a wire, a loop, an isolated vertex
    mixed = build_faces(
        9,
        [(0, 2, 1), (0, 1, 3), (1, 2, 3), (0, 3, 2), (4, 5, 6), (4, 6, 7)],
        extra_edges=[(7, 8), (8, 8)],
    )
    extra_vertex = mixed._replace(v_id=np.append(mixed.v_id, 9), v_halfedge=np.append(mixed.v_halfedge, -1))
    assert check_arrays(extra_vertex) == []
    shuffled, _ = relabel(extra_vertex, seed=11)
    return shuffled


def _backend_uses_copy(backend):
    return [False, True] if backend == "postgresql" else [False]


def test_load_arrays_round_trip_and_corruption(db_url, backend, monkeypatch):
    engine = sa.create_engine(db_url)
    try:
        schema.metadata.create_all(engine)
        arrays = _sample_mesh()
        with engine.begin() as conn:
            mesh_id = _new_mesh(conn, "m")
            other_id = _new_mesh(conn, "other")
            empty_id = _new_mesh(conn, "empty")
            _insert(conn, mesh_id, arrays)
            _insert(conn, other_id, grid_arrays(2))  # same ids, another mesh
        expected = sorted_arrays(arrays)
        for use_copy in _backend_uses_copy(backend):
            # small fetch blocks, so the chunked paths are exercised
            monkeypatch.setattr(columns, "_FETCH_ROWS", 7)
            with engine.connect() as conn:
                loaded = load_arrays(conn, mesh_id, use_copy=use_copy)
                empty = load_arrays(conn, empty_id, use_copy=use_copy)
                missing = load_arrays(conn, 12345, use_copy=use_copy)
            monkeypatch.undo()
            assert isinstance(loaded, TopologyArrays)
            for name in TopologyArrays._fields:
                got = getattr(loaded, name)
                assert got.dtype == np.int64, name
                np.testing.assert_array_equal(got, getattr(expected, name), err_msg=name)
            assert check_arrays(loaded) == []
            for result in (empty, missing):
                assert all(len(col) == 0 and col.dtype == np.int64 for col in result)
                assert check_arrays(result) == []
        with engine.connect() as conn:
            other = load_arrays(conn, other_id)  # the other mesh reads on its own
        for name in TopologyArrays._fields:
            np.testing.assert_array_equal(getattr(other, name), getattr(grid_arrays(2), name), err_msg=name)

        # corrupt stored rows, one at a time, and read them back
        h = schema.halfedges.c
        v = schema.vertices.c
        he_ids = expected.he_id
        target = int(he_ids[5])
        t = int(expected.he_twin[5])
        nxt = int(expected.he_next[5])
        other_next = int(expected.he_next[expected.he_next != nxt][0])
        vertex = int(expected.v_id[0])
        incoming = int(expected.he_id[expected.he_origin != vertex][0])
        he_row = schema.halfedges.update().where(h.mesh_id == mesh_id, h.id == target)
        corruptions = [
            (he_row.values(next=other_next), {"H_NEXT_PREV"}, target),
            (he_row.values(twin=target), {"H_TWIN"}, target),
            (
                schema.vertices.update().where(v.mesh_id == mesh_id, v.id == vertex).values(halfedge=incoming),
                {"V_HALFEDGE"},
                vertex,
            ),
            (schema.halfedges.update().where(h.mesh_id == mesh_id, h.id == t).values(origin=10_000), {"REF"}, t),
        ]
        for statement, expected_codes, element in corruptions:
            for use_copy in _backend_uses_copy(backend):
                with engine.connect() as conn:
                    conn.execute(statement)
                    report = check_arrays(load_arrays(conn, mesh_id, use_copy=use_copy))
                    conn.rollback()
                assert expected_codes <= set(codes(report)), (statement, report)
                assert any(x.code in expected_codes and x.id == element for x in report), report
                if expected_codes == {"V_HALFEDGE"} or expected_codes == {"REF"}:
                    assert set(codes(report)) == expected_codes
        with engine.connect() as conn:
            assert check_arrays(load_arrays(conn, mesh_id)) == []  # nothing was committed
    finally:
        engine.dispose()


def test_load_arrays_grid(db_url, backend):
    """A larger mesh through both fetch paths (several default-size blocks on COPY)."""
    engine = sa.create_engine(db_url)
    try:
        schema.metadata.create_all(engine)
        arrays = grid_arrays(30)
        with engine.begin() as conn:
            mesh_id = _new_mesh(conn, "grid")
            _insert(conn, mesh_id, arrays)
        for use_copy in _backend_uses_copy(backend):
            with engine.connect() as conn:
                loaded = load_arrays(conn, mesh_id, use_copy=use_copy)
            for name in TopologyArrays._fields:
                np.testing.assert_array_equal(getattr(loaded, name), getattr(arrays, name), err_msg=name)
            assert check_arrays(loaded) == []
    finally:
        engine.dispose()


def test_load_arrays_reads_one_snapshot(db_url, backend):
    """A commit by another connection between the per-table selects is not seen."""
    engine = sa.create_engine(db_url, isolation_level="AUTOCOMMIT")
    writer = sa.create_engine(db_url)
    try:
        schema.metadata.create_all(engine)
        if backend == "sqlite":
            with writer.connect() as conn:
                conn.exec_driver_sql("PRAGMA journal_mode=WAL")
        arrays = tetrahedron()
        with writer.begin() as conn:
            mesh_id = _new_mesh(conn, "m")
            _insert(conn, mesh_id, arrays)
        incoming = int(np.flatnonzero(arrays.he_origin != 0)[0])
        fired = []

        def commit_in_between(conn, cursor, statement, parameters, context, executemany):
            if "FROM halfedges" in statement and not fired:
                fired.append(statement)
                with writer.begin() as w:
                    v = schema.vertices.c
                    w.execute(schema.vertices.update().where(v.mesh_id == mesh_id, v.id == 0).values(halfedge=incoming))

        event.listen(engine, "after_cursor_execute", commit_in_between)
        with engine.connect() as conn:
            loaded = load_arrays(conn, mesh_id, use_copy=False)
            dbapi = conn.connection.dbapi_connection
            if backend == "sqlite":
                assert not dbapi.in_transaction  # the read transaction is closed again
            else:
                assert dbapi.info.transaction_status == 0  # idle
        event.remove(engine, "after_cursor_execute", commit_in_between)
        assert fired
        assert check_arrays(loaded) == []
        # the change is there for the next read, on either path
        for use_copy in _backend_uses_copy(backend):
            with engine.connect() as conn:
                report = check_arrays(load_arrays(conn, mesh_id, use_copy=use_copy))
            assert found(report) == {("V_HALFEDGE", "vertex", 0)}
    finally:
        engine.dispose()
        writer.dispose()


def test_index_modes():
    rng = np.random.default_rng(5)
    for ids in (
        np.arange(10, 20),  # contiguous: subtraction
        np.sort(rng.choice(100, 40, replace=False)),  # lookup table
        np.sort(rng.choice(10**12, 3000, replace=False)),  # sparse: sorted search
        np.array([], dtype=np.int64),
    ):
        index = Index(ids.astype(np.int64))
        refs = np.concatenate([ids, ids[::-1], [-1, -5, 10**13, 7, 15, 99]]).astype(np.int64)
        rows, ok = index.find(refs)
        expected_ok = np.isin(refs, ids)
        np.testing.assert_array_equal(ok, expected_ok)
        np.testing.assert_array_equal(ids[rows[ok]], refs[ok])
        assert (rows[~ok] == 0).all()


def test_very_sparse_ids():
    arrays, _ = relabel(octahedron(), seed=9, spread=10**9)
    assert check_arrays(arrays) == []
    broken = arrays._replace(he_twin=arrays.he_twin.copy())
    broken.he_twin[0] = broken.he_id[0]
    assert ("H_TWIN", "halfedge", int(arrays.he_id[0])) in found(check_arrays(broken))
