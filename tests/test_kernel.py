"""The topological operations (seed 000's algorithms) through the `Mesh` API.

Every test runs on SQLite and on PostgreSQL (the ``mesh``/``store`` fixtures).
Every refused operation goes through `helpers.assert_refused`: the typed error,
and not one row nor the revision changed — outside a transaction block, and
inside one that then goes on and commits another edit.
"""

from __future__ import annotations

import random

import pytest

import hestore
from hestore import (
    ElementNotFoundError,
    HalfEdgeNotFreeError,
    InvalidInputError,
    NonManifoldError,
    PolicyError,
    TopologyError,
    VertexNotFreeError,
)
from helpers import (
    OCTAHEDRON,
    OCTAHEDRON_POSITIONS,
    TETRAHEDRON,
    assert_refused,
    build_faces,
    committed_url,
    dump,
    free_in_out,
    grid,
)


def assert_chained(p: hestore.Polygon) -> None:
    """``p``'s half-edges form a closed ``next``/``prev`` loop, all on ``p``."""
    hs = p.halfedges()
    n = len(hs)
    assert len(set(hs)) == n
    for i, h in enumerate(hs):
        assert h.polygon == p
        assert h.next == hs[(i + 1) % n]
        assert h.prev == hs[(i - 1) % n]
        assert h.target == hs[(i + 1) % n].origin


def all_ids(mesh):
    return (
        [v.id for v in mesh.vertices()],
        [h.id for h in mesh.halfedges()],
        [e.id for e in mesh.edges()],
        [p.id for p in mesh.polygons()],
    )


# -- building polygons ----------------------------------------------------------


def test_wire_triangle_becomes_polygon_of_its_halfedges(mesh):
    a, b, c = (mesh.add_vertex() for _ in range(3))
    e_ab, e_bc, e_ca = mesh.add_edge(a, b), mesh.add_edge(b, c), mesh.add_edge(c, a)
    loop = [e_ab.halfedge, e_bc.halfedge, e_ca.halfedge]
    assert [h.origin for h in loop] == [a, b, c]
    assert all(h.is_boundary and h.twin.is_boundary for h in loop)
    assert mesh.check() == []

    p = mesh.add_polygon(loop)

    assert p.halfedge == loop[0]
    assert p.halfedges() == loop
    assert p.vertices() == [a, b, c]
    assert p.edges() == [e_ab, e_bc, e_ca]
    assert_chained(p)
    assert all(h.twin.is_boundary for h in loop)
    # the outer side is one boundary loop a->c->b->a
    outer = [h.twin for h in reversed(loop)]
    for i, h in enumerate(outer):
        assert h.next == outer[(i + 1) % 3]
    assert mesh.counts() == hestore.Counts(vertices=3, halfedges=6, edges=3, polygons=1)
    assert mesh.check() == []
    # the back side too: a closed "pillow" of two triangles
    q = mesh.add_polygon(outer)
    assert_chained(q)
    assert p.neighbors() == [q, q, q]
    assert not any(v.is_boundary for v in (a, b, c))
    assert mesh.check() == []


def test_two_triangles_sharing_an_edge(mesh):
    a, b, c, d = (mesh.add_vertex() for _ in range(4))
    p = mesh.add_polygon([a, b, c])
    q = mesh.add_polygon([b, a, d])
    assert mesh.counts() == hestore.Counts(vertices=4, halfedges=10, edges=5, polygons=2)
    h_ab = mesh.find_halfedge(a, b)
    assert h_ab.polygon == p and h_ab.twin.polygon == q
    assert sorted(h_ab.edge.polygons(), key=lambda x: x.id) == [p, q]
    assert not h_ab.edge.is_boundary
    assert p.neighbors() == [q] and q.neighbors() == [p]
    assert_chained(p)
    assert_chained(q)
    for v in (a, b, c, d):
        assert v.is_boundary and v.halfedge.is_boundary
    assert mesh.check() == []


def test_one_gon_from_a_vertex_loop(mesh):
    v = mesh.add_vertex()
    p = mesh.add_polygon([v])
    assert p.degree == 1
    (h,) = p.halfedges()
    (e,) = p.edges()
    assert e.is_loop and h.origin == v and h.target == v
    assert h.next == h and h.prev == h
    assert h.twin.is_boundary and h.twin.next == h.twin
    assert v.degree == 2 and v.is_boundary and v.halfedge == h.twin
    assert mesh.counts() == hestore.Counts(vertices=1, halfedges=2, edges=1, polygons=1)
    assert mesh.check() == []
    # the other side of the loop takes a second 1-gon: a closed sphere of two 1-gons
    q = mesh.add_polygon([v])
    assert q.halfedges() == [h.twin]
    assert mesh.counts().edges == 1
    assert not v.is_boundary
    assert v.polygons() in ([p, q], [q, p])
    assert mesh.check() == []
    # and no third: the loop edge is taken on both sides
    info = assert_refused(mesh.store, mesh, lambda: mesh.add_polygon([v]), HalfEdgeNotFreeError)
    assert f"{v.id}" in str(info.value)


@pytest.mark.parametrize("side", [0, 1])
def test_one_gon_on_either_halfedge_of_a_loop_edge(mesh, side):
    v, w = mesh.add_vertex(), mesh.add_vertex()
    mesh.add_edge(v, w)
    loop = mesh.add_edge(v, v)
    h = loop.halfedges()[side]
    assert h.origin == v and h.target == v
    assert mesh.check() == []
    p = mesh.add_polygon([h])
    assert p.halfedges() == [h]
    assert h.next == h and h.polygon == p
    assert h.twin.polygon is None
    assert v.halfedge.is_boundary
    assert v.degree == 3
    assert sorted(n.id for n in v.neighbors()) == sorted([v.id, v.id, w.id])
    assert mesh.check() == []


def test_two_gon_on_two_parallel_edges(mesh):
    a, b = mesh.add_vertex(), mesh.add_vertex()
    e1, e2 = mesh.add_edge(a, b), mesh.add_edge(a, b)
    h_ab = e1.halfedge
    h_ba = e2.halfedge.twin
    assert (h_ab.origin, h_ab.target, h_ba.origin, h_ba.target) == (a, b, b, a)
    p = mesh.add_polygon([h_ab, h_ba])
    assert p.degree == 2
    assert p.halfedges() == [h_ab, h_ba]
    assert p.vertices() == [a, b]
    assert p.edges() == [e1, e2]
    assert_chained(p)
    assert e1.halfedge.twin.is_boundary and e2.halfedge.is_boundary
    assert mesh.counts() == hestore.Counts(vertices=2, halfedges=4, edges=2, polygons=1)
    assert mesh.check() == []


def test_two_gon_from_vertices_uses_the_two_parallel_edges(mesh):
    a, b = mesh.add_vertex(), mesh.add_vertex()
    e1, e2 = mesh.add_edge(a, b), mesh.add_edge(a, b)
    p = mesh.add_polygon([a, b])
    assert sorted(p.edges(), key=lambda e: e.id) == [e1, e2]
    assert mesh.counts().edges == 2
    assert mesh.check() == []


def test_polygons_meeting_at_one_vertex(mesh):
    v = mesh.add_vertex()
    a, b, c, d = (mesh.add_vertex() for _ in range(4))
    p = mesh.add_polygon([v, a, b])
    q = mesh.add_polygon([v, c, d])
    assert sorted(v.polygons(), key=lambda x: x.id) == [p, q]
    assert v.degree == 4
    assert v.is_boundary and v.halfedge.is_boundary
    ins, outs = free_in_out(v)
    assert len(ins) == 2 and len(outs) == 2
    assert mesh.check() == []


@pytest.mark.parametrize("by", ["vertices", "halfedges"])
def test_joining_fans_needs_make_adjacent(mesh, by):
    """Three single-triangle fans around a hub; joining two that are not neighbours in
    the hub's rotation moves the third fan into another free gap."""
    v = mesh.add_vertex()
    fans = []
    for _ in range(3):
        x1, x2 = mesh.add_vertex(), mesh.add_vertex()
        fans.append((mesh.add_polygon([v, x1, x2]), x1, x2))
    # Fan X's free outgoing is v->x2, fan Y's free incoming is y1->v.
    pairs = [
        (X, Y)
        for X in range(3)
        for Y in range(3)
        if X != Y and mesh.find_halfedge(fans[Y][1], v).next != mesh.find_halfedge(v, fans[X][2])
    ]
    assert pairs, "with three fans some pair is never adjacent in the rotation"
    X, Y = pairs[0]
    out = mesh.find_halfedge(v, fans[X][2])
    inn = mesh.find_halfedge(fans[Y][1], v)
    assert out.is_boundary and inn.is_boundary and inn.next != out

    if by == "vertices":
        join = mesh.add_polygon([v, fans[X][2], fans[Y][1]])
    else:
        bridge = mesh.add_edge(fans[X][2], fans[Y][1])
        join = mesh.add_polygon([out, bridge.halfedge, inn])

    assert inn.next == out and out.prev == inn
    assert join.halfedges()[0] == out
    assert_chained(join)
    assert mesh.check() == []
    assert sorted(p.id for p in v.polygons()) == sorted([f[0].id for f in fans] + [join.id])

    # Close the remaining two gaps; v ends up interior.
    added = []
    while v.is_boundary:
        ins, _ = free_in_out(v)
        i = ins[0]
        o = i.next
        assert o.is_boundary and o.origin == v
        added.append(mesh.add_polygon([v, o.target, i.origin]))
        assert mesh.check() == []
    assert len(added) == 2
    polys = v.polygons()
    assert len(polys) == len(set(polys)) == 6
    assert set(polys) == {f[0] for f in fans} | {join} | set(added)
    outs = v.outgoing()
    for k, h in enumerate(outs):
        assert h.onext == outs[(k + 1) % len(outs)]
        assert h.polygon is not None
    for p in polys:
        assert_chained(p)


# -- refusals -------------------------------------------------------------------


def test_third_polygon_on_an_edge_is_a_complex_edge(mesh):
    a, b, c, d, x = (mesh.add_vertex() for _ in range(5))
    mesh.add_polygon([a, b, c])
    mesh.add_polygon([b, a, d])
    h_ab = mesh.find_halfedge(a, b)
    info = assert_refused(mesh.store, mesh, lambda: mesh.add_polygon([a, b, x]), HalfEdgeNotFreeError)
    msg = str(info.value)
    assert f"{a.id}" in msg and f"{b.id}" in msg and f"{h_ab.id}" in msg
    assert h_ab in info.value.elements
    info = assert_refused(mesh.store, mesh, lambda: mesh.add_polygon([b, a, x]), HalfEdgeNotFreeError)
    assert h_ab.twin in info.value.elements


def test_taken_halfedge_in_a_halfedge_loop_is_a_complex_edge(mesh):
    a, b, c, x = (mesh.add_vertex() for _ in range(4))
    p = mesh.add_polygon([a, b, c])
    h_ab = mesh.find_halfedge(a, b)
    e_bx, e_xa = mesh.add_edge(b, x), mesh.add_edge(x, a)
    loop = [h_ab, e_bx.halfedge, e_xa.halfedge]
    info = assert_refused(mesh.store, mesh, lambda: mesh.add_polygon(loop), HalfEdgeNotFreeError)
    msg = str(info.value)
    assert f"half-edge {h_ab.id}" in msg
    assert f"edge {h_ab.edge.id}" in msg
    assert f"polygon {p.id}" in msg
    assert h_ab in info.value.elements


def _two_fans(mesh):
    """Hub v with two separate fans of two triangles each: (v,a0,a1),(v,a1,a2) and (v,b0,b1),(v,b1,b2)."""
    v = mesh.add_vertex()
    A = [mesh.add_vertex() for _ in range(3)]
    B = [mesh.add_vertex() for _ in range(3)]
    mesh.add_polygon([v, A[0], A[1]])
    mesh.add_polygon([v, A[1], A[2]])
    mesh.add_polygon([v, B[0], B[1]])
    mesh.add_polygon([v, B[1], B[2]])
    return v, A, B


def test_closing_one_fan_while_another_hangs_is_a_complex_vertex(mesh):
    v, A, B = _two_fans(mesh)
    assert mesh.check() == []
    # (v, a2, a0) would close fan A into a disk around v; fan B has nowhere to go.
    info = assert_refused(mesh.store, mesh, lambda: mesh.add_polygon([v, A[2], A[0]]), NonManifoldError)
    assert f"vertex {v.id}" in str(info.value)
    assert v in info.value.elements
    assert mesh.counts().edges == 10  # the edge a2-a0 the attempt created is gone again


def _complex_vertex_loop_with_relinking(mesh):
    """Two fans at v, the edge a2-a0, and wire edges at a2 added before it, so that
    the loop (v->a2, a2->a0, a0->v) needs makeAdjacent at a2 before it fails at v."""
    v, A, B = _two_fans(mesh)
    for _ in range(2):
        mesh.add_edge(A[2], mesh.add_vertex())
    mesh.add_edge(A[2], A[0])
    loop = [mesh.find_halfedge(v, A[2]), mesh.find_halfedge(A[2], A[0]), mesh.find_halfedge(A[0], v)]
    assert all(h.is_boundary for h in loop)
    if loop[0].next == loop[1]:  # pragma: no cover - depends on where add_edge links
        pytest.skip("setup did not produce a corner that needs reordering")
    assert mesh.check() == []
    return v, loop


def test_complex_vertex_with_halfedge_loop_after_relinking_another_corner(mesh):
    v, loop = _complex_vertex_loop_with_relinking(mesh)
    info = assert_refused(mesh.store, mesh, lambda: mesh.add_polygon(loop), NonManifoldError)
    assert f"vertex {v.id}" in str(info.value)


@pytest.mark.parametrize("closing", ["b3,t0,b0,t3", "t3,b0,t0,b3"])
@pytest.mark.parametrize("by", ["vertices", "halfedges"])
def test_moebius_strip_closing_quad_is_refused(mesh, closing, by):
    b = [mesh.add_vertex() for _ in range(4)]
    t = [mesh.add_vertex() for _ in range(4)]
    for i in range(3):
        mesh.add_polygon([b[i], b[i + 1], t[i + 1], t[i]])
    assert mesh.check() == []
    names = {f"b{i}": b[i] for i in range(4)} | {f"t{i}": t[i] for i in range(4)}
    corners = [names[n] for n in closing.split(",")]
    if by == "vertices":
        loop = corners
    else:
        # the twisted edges exist; every other side uses whatever a->b half-edge there is
        mesh.add_edge(b[3], t[0])
        mesh.add_edge(b[0], t[3])
        loop = [mesh.find_halfedge(corners[i], corners[(i + 1) % 4]) for i in range(4)]
    assert_refused(mesh.store, mesh, lambda: mesh.add_polygon(loop), TopologyError)
    assert not mesh.can_add_polygon(loop)
    # The untwisted ring closes fine (an annulus).
    assert mesh.can_add_polygon([b[3], b[0], t[0], t[3]])
    mesh.add_polygon([b[3], b[0], t[0], t[3]])
    assert mesh.check() == []


def test_vertex_not_free_inside_a_closed_fan(mesh):
    v = mesh.add_vertex()
    ring = [mesh.add_vertex() for _ in range(4)]
    for i in range(4):
        mesh.add_polygon([v, ring[i], ring[(i + 1) % 4]])
    assert not v.is_boundary
    w = mesh.add_vertex()
    info = assert_refused(mesh.store, mesh, lambda: mesh.add_edge(v, w), VertexNotFreeError)
    assert f"vertex {v.id}" in str(info.value) and info.value.elements == (v,)
    assert_refused(mesh.store, mesh, lambda: mesh.add_edge(w, v), VertexNotFreeError)
    assert_refused(mesh.store, mesh, lambda: mesh.add_edge(v, v), VertexNotFreeError)
    assert_refused(mesh.store, mesh, lambda: mesh.add_polygon([v, w, ring[0]]), VertexNotFreeError)
    assert_refused(mesh.store, mesh, lambda: mesh.add_polygon([v]), VertexNotFreeError)
    # a ring vertex is still free
    mesh.add_edge(ring[0], w)
    assert mesh.check() == []


def test_policy_no_loops(store):
    mesh = store.create_mesh("noloops", allow_loops=False)
    v, w = mesh.add_vertex(), mesh.add_vertex()
    info = assert_refused(store, mesh, lambda: mesh.add_edge(v, v), PolicyError)
    assert f"vertex {v.id}" in str(info.value) and "loop" in str(info.value)
    assert_refused(store, mesh, lambda: mesh.add_polygon([v]), PolicyError)
    mesh.add_edge(v, w)
    mesh.add_edge(v, w)  # parallel edges are allowed here
    assert mesh.counts().edges == 2
    assert mesh.check() == []


def test_policy_no_multi_edges(store):
    mesh = store.create_mesh("nomulti", allow_multi_edges=False)
    a, b, c, d, x = (mesh.add_vertex() for _ in range(5))
    e = mesh.add_edge(a, b)
    info = assert_refused(store, mesh, lambda: mesh.add_edge(a, b), PolicyError)
    assert f"edge {e.id}" in str(info.value)
    assert_refused(store, mesh, lambda: mesh.add_edge(b, a), PolicyError)
    # polygons reuse the edge instead
    p = mesh.add_polygon([a, b, c])
    q = mesh.add_polygon([b, a, d])
    assert e in p.edges() and e in q.edges()
    assert mesh.counts().edges == 5
    # with both sides taken the answer is a complex edge, never a parallel edge
    assert_refused(store, mesh, lambda: mesh.add_polygon([a, b, x]), HalfEdgeNotFreeError)
    mesh.add_edge(x, x)  # loops are allowed here
    assert mesh.check() == []


def test_policy_is_per_mesh(store):
    strict = store.create_mesh("strict", allow_loops=False, allow_multi_edges=False)
    loose = store.create_mesh("loose")
    v = loose.add_vertex()
    loose.add_edge(v, v)
    w = strict.add_vertex()
    assert_refused(store, strict, lambda: strict.add_edge(w, w), PolicyError)
    assert store.mesh("strict").allow_loops is False
    assert store.mesh("loose").allow_loops is True


# -- stale and foreign handles, malformed input ------------------------------------


def test_stale_handles_are_refused_for_editing(mesh):
    a, b, c, d = (mesh.add_vertex() for _ in range(4))
    p = mesh.add_polygon([a, b, c])
    h = mesh.find_halfedge(a, b)
    e = h.edge
    mesh.remove_vertex(d)
    mesh.remove_polygon(p)
    loop = [mesh.find_halfedge(a, b), mesh.find_halfedge(b, c), mesh.find_halfedge(c, a)]
    mesh.remove_edge(e)
    store = mesh.store
    assert_refused(store, mesh, lambda: mesh.remove_vertex(d), ElementNotFoundError)
    assert_refused(store, mesh, lambda: mesh.add_edge(a, d), ElementNotFoundError)
    assert_refused(store, mesh, lambda: mesh.add_edge(d, d), ElementNotFoundError)
    assert_refused(store, mesh, lambda: mesh.add_polygon([a, b, d]), ElementNotFoundError)
    assert_refused(store, mesh, lambda: mesh.add_polygon([d, a, b]), ElementNotFoundError)
    assert_refused(store, mesh, lambda: mesh.add_polygon(loop), ElementNotFoundError)
    assert_refused(store, mesh, lambda: mesh.can_add_polygon(loop), ElementNotFoundError)
    assert_refused(store, mesh, lambda: mesh.remove_polygon(p), ElementNotFoundError)
    assert_refused(store, mesh, lambda: mesh.remove_edge(e), ElementNotFoundError)
    assert_refused(store, mesh, lambda: mesh.find_halfedge(a, d), ElementNotFoundError)
    with pytest.raises(ElementNotFoundError):
        mesh.vertex(d.id)
    with pytest.raises(ElementNotFoundError):
        mesh.edge(e.id)
    with pytest.raises(ElementNotFoundError):
        mesh.halfedge(h.id)
    with pytest.raises(ElementNotFoundError):
        mesh.polygon(p.id)
    assert mesh.check() == []


def test_handles_of_another_mesh_are_refused(store, mesh):
    other = store.create_mesh("other")
    a, b, c = (mesh.add_vertex() for _ in range(3))
    x, y, z = (other.add_vertex() for _ in range(3))
    q = other.add_polygon([x, y, z])
    hx = other.find_halfedge(x, y)
    mesh.add_polygon([a, b, c])
    # same ids in both meshes
    assert (a.id, b.id, c.id) == (x.id, y.id, z.id)
    before_other = list(other.vertices())
    info = assert_refused(store, mesh, lambda: mesh.add_edge(a, y), ElementNotFoundError)
    assert "other" in str(info.value)
    assert_refused(store, mesh, lambda: mesh.add_edge(x, a), ElementNotFoundError)
    assert_refused(store, mesh, lambda: mesh.add_polygon([a, b, z]), ElementNotFoundError)
    assert_refused(store, mesh, lambda: mesh.add_polygon([hx, hx.next, hx.prev]), ElementNotFoundError)
    assert_refused(store, mesh, lambda: mesh.can_add_polygon([x, y, z]), ElementNotFoundError)
    assert_refused(store, mesh, lambda: mesh.remove_polygon(q), ElementNotFoundError)
    assert_refused(store, mesh, lambda: mesh.remove_edge(hx.edge), ElementNotFoundError)
    assert_refused(store, mesh, lambda: mesh.remove_vertex(x), ElementNotFoundError)
    assert_refused(store, mesh, lambda: mesh.find_halfedge(a, y), ElementNotFoundError)
    assert list(other.vertices()) == before_other
    assert q.degree == 3
    assert other.check() == [] and mesh.check() == []


def _malformed_cases():
    nan, inf = float("nan"), float("inf")
    return {
        "empty loop": lambda m, a, b, c, h: m.add_polygon([]),
        "empty tuple": lambda m, a, b, c, h: m.add_polygon(()),
        "mixed vertex/halfedge": lambda m, a, b, c, h: m.add_polygon([a, h]),
        "mixed halfedge/vertex": lambda m, a, b, c, h: m.add_polygon([h, h.next, c]),
        "ints": lambda m, a, b, c, h: m.add_polygon([0, 1, 2]),
        "edge handles": lambda m, a, b, c, h: m.add_polygon([h.edge]),
        "a single handle": lambda m, a, b, c, h: m.add_polygon(a),
        "a string": lambda m, a, b, c, h: m.add_polygon("abc"),
        "None loop": lambda m, a, b, c, h: m.add_polygon(None),
        "repeated halfedge": lambda m, a, b, c, h: m.add_polygon([h, h]),
        "can_add empty": lambda m, a, b, c, h: m.can_add_polygon([]),
        "can_add mixed": lambda m, a, b, c, h: m.can_add_polygon([a, h]),
        "edge to int": lambda m, a, b, c, h: m.add_edge(a, 1),
        "edge from halfedge": lambda m, a, b, c, h: m.add_edge(h, a),
        "edge None": lambda m, a, b, c, h: m.add_edge(None, a),
        "NaN position": lambda m, a, b, c, h: m.add_vertex((nan, 0, 0)),
        "inf position": lambda m, a, b, c, h: m.add_vertex((0, inf, 0)),
        "2 coordinates": lambda m, a, b, c, h: m.add_vertex((1, 2)),
        "4 coordinates": lambda m, a, b, c, h: m.add_vertex((1, 2, 3, 4)),
        "string position": lambda m, a, b, c, h: m.add_vertex("xyz"),
        "scalar position": lambda m, a, b, c, h: m.add_vertex(5),
        "None coordinate": lambda m, a, b, c, h: m.add_vertex((1, None, 2)),
        "remove_polygon(vertex)": lambda m, a, b, c, h: m.remove_polygon(a),
        "remove_edge(halfedge)": lambda m, a, b, c, h: m.remove_edge(h),
        "remove_vertex(int)": lambda m, a, b, c, h: m.remove_vertex(0),
        "find_halfedge(int)": lambda m, a, b, c, h: m.find_halfedge(a, 1),
    }


@pytest.mark.parametrize("case", sorted(_malformed_cases()))
def test_malformed_input_is_invalid_input(mesh, case):
    a, b, c = (mesh.add_vertex((i, 0, 0)) for i in range(3))
    mesh.add_edge(a, b)
    mesh.add_edge(b, c)
    h = mesh.find_halfedge(a, b)
    op = _malformed_cases()[case]
    info = assert_refused(mesh.store, mesh, lambda: op(mesh, a, b, c, h), InvalidInputError)
    assert isinstance(info.value, ValueError)
    assert str(info.value)


# -- removing ---------------------------------------------------------------------


def test_remove_edge_inside_a_mesh(mesh):
    V, Q = grid(mesh, 3)
    left, right = Q[1][1], Q[2][1]
    e = mesh.find_halfedge(V[2][1], V[2][2]).edge
    assert set(e.polygons()) == {left, right}
    h, t = e.halfedges()
    before = mesh.counts()
    mesh.remove_edge(e)
    assert mesh.counts() == hestore.Counts(
        vertices=before.vertices, halfedges=before.halfedges - 2, edges=before.edges - 1, polygons=before.polygons - 2
    )
    for gone in (left, right):
        with pytest.raises(ElementNotFoundError):
            gone.halfedges()
    for gone in (e, ):
        with pytest.raises(ElementNotFoundError):
            gone.halfedges()
    for gone in (h, t):
        with pytest.raises(ElementNotFoundError):
            gone.next
    for i in range(3):
        for j in range(3):
            if Q[i][j] not in (left, right):
                assert Q[i][j].degree == 4
                assert_chained(Q[i][j])
    for v in (V[2][1], V[2][2]):
        assert v.is_boundary and v.halfedge.is_boundary
        assert mesh.find_halfedge(V[2][1], V[2][2]) is None
    # the hole is one boundary loop of six half-edges
    hole = mesh.find_halfedge(V[1][1], V[1][2]).twin
    assert hole.is_boundary
    walk, h = [hole], hole.next
    while h != hole:
        walk.append(h)
        h = h.next
    assert len(walk) == 6 and all(x.is_boundary for x in walk)
    assert mesh.check() == []


def test_remove_boundary_and_wire_edges(mesh):
    V, Q = grid(mesh, 2)
    e = mesh.find_halfedge(V[0][0], V[1][0]).edge  # bottom boundary edge of Q[0][0]
    mesh.remove_edge(e)
    with pytest.raises(ElementNotFoundError):
        Q[0][0].degree
    assert Q[1][0].degree == 4
    assert mesh.check() == []
    w = mesh.add_vertex()
    wire = mesh.add_edge(V[0][0], w)
    mesh.remove_edge(wire)
    assert w.is_isolated and w.halfedge is None
    assert mesh.check() == []


def test_remove_polygon_keeps_edges_and_frees_halfedges(mesh):
    V, Q = grid(mesh, 2)
    p = Q[1][1]
    hs = p.halfedges()
    mesh.remove_polygon(p)
    assert mesh.counts() == hestore.Counts(vertices=9, halfedges=24, edges=12, polygons=3)
    assert all(h.is_boundary for h in hs)
    assert V[1][1].is_boundary and V[1][1].halfedge.is_boundary
    assert mesh.check() == []
    # and the freed loop takes a polygon again
    again = mesh.add_polygon(hs)
    assert again.id > p.id and again.halfedges() == hs
    assert not V[1][1].is_boundary
    assert mesh.check() == []


@pytest.mark.parametrize("one_gons", [0, 1])
def test_remove_vertex_carrying_a_loop_edge(mesh, one_gons):
    v, w, x = (mesh.add_vertex() for _ in range(3))
    tri = mesh.add_polygon([v, w, x])
    loop = mesh.add_edge(v, v)
    gons = [mesh.add_polygon([v]) for _ in range(one_gons)]
    assert v.degree == 4
    assert v.is_boundary
    assert mesh.check() == []
    mesh.remove_vertex(v)
    assert mesh.counts() == hestore.Counts(vertices=2, halfedges=2, edges=1, polygons=0)
    for gone in [v, tri, loop] + gons:
        with pytest.raises(ElementNotFoundError):
            gone.halfedge
    assert w.neighbors() == [x] and x.neighbors() == [w]
    assert mesh.check() == []


def test_one_gons_on_both_sides_of_a_loop_leave_no_gap_for_other_edges(mesh):
    """Two 1-gons on one loop edge close v completely, so with a triangle at v the
    second one is a complex vertex."""
    v, w, x = (mesh.add_vertex() for _ in range(3))
    mesh.add_polygon([v, w, x])
    p = mesh.add_polygon([v])
    (h,) = p.halfedges()
    assert_refused(mesh.store, mesh, lambda: mesh.add_polygon([h.twin]), NonManifoldError)
    assert_refused(mesh.store, mesh, lambda: mesh.add_polygon([v]), NonManifoldError)
    assert mesh.check() == []


def test_remove_loop_edge_with_its_one_gon(mesh):
    v, w = mesh.add_vertex(), mesh.add_vertex()
    mesh.add_edge(v, w)
    p = mesh.add_polygon([v])
    (loop,) = p.edges()
    mesh.remove_edge(loop)
    assert v.degree == 1 and v.neighbors() == [w]
    assert mesh.counts() == hestore.Counts(vertices=2, halfedges=2, edges=1, polygons=0)
    assert mesh.check() == []


def test_remove_isolated_vertex(mesh):
    v = mesh.add_vertex()
    mesh.remove_vertex(v)
    assert mesh.counts().vertices == 0
    with pytest.raises(ElementNotFoundError):
        v.position


def test_ids_are_never_reused(db_url):
    store = hestore.open(db_url)
    mesh = store.create_mesh("m")
    a, b, c = (mesh.add_vertex() for _ in range(3))
    p = mesh.add_polygon([a, b, c])
    assert all_ids(mesh) == ([0, 1, 2], [0, 1, 2, 3, 4, 5], [0, 1, 2], [0])

    mesh.remove_polygon(p)  # the highest (only) polygon id
    assert mesh.add_polygon([a, b, c]).id == 1

    top_edge = max(mesh.edges(), key=lambda e: e.id)
    assert top_edge.id == 2
    mesh.remove_edge(top_edge)  # takes polygon 1 with it
    assert all_ids(mesh) == ([0, 1, 2], [0, 1, 2, 3], [0, 1], [])
    e3 = mesh.add_edge(c, a)
    assert e3.id == 3
    assert sorted(h.id for h in e3.halfedges()) == [6, 7]

    mesh.remove_vertex(c)  # the highest vertex id, with edges 1 and 3
    assert all_ids(mesh) == ([0, 1], [0, 1], [0], [])
    d = mesh.add_vertex()
    assert d.id == 3
    p3 = mesh.add_polygon([a, b, d])  # reuses edge 0, adds two new edges
    assert p3.id == 2
    assert sorted(e.id for e in p3.edges()) == [0, 4, 5]

    # a refused operation consumes no ids (and changes nothing)
    before = dump(store)
    with pytest.raises(HalfEdgeNotFreeError):
        mesh.add_polygon([a, b, d])
    assert dump(store) == before
    # a rolled-back block neither
    with pytest.raises(RuntimeError):
        with store.transaction():
            assert mesh.add_vertex().id == 4
            raise RuntimeError
    assert dump(store) == before
    store.close()

    # the counters survive reopening the database
    store = hestore.open(db_url)
    mesh = store.mesh("m")
    assert mesh.add_vertex().id == 4
    assert mesh.add_edge(mesh.vertex(0), mesh.vertex(4)).id == 6
    assert mesh.add_polygon([mesh.vertex(0), mesh.vertex(4), mesh.vertex(1)]).id == 3
    assert mesh.check() == []
    store.close()


# -- can_add_polygon ------------------------------------------------------------------


def _can_add_setup(mesh):
    """A fixture mesh for the can_add_polygon questions; returns named loops and answers."""
    v, A, B = _two_fans(mesh)
    a, b, c, d, x = (mesh.add_vertex() for _ in range(5))
    mesh.add_polygon([a, b, c])
    mesh.add_polygon([b, a, d])
    y, z = mesh.add_vertex(), mesh.add_vertex()
    e_yz = mesh.add_edge(y, z)
    r = [mesh.add_vertex() for _ in range(3)]
    mesh.add_polygon(r)
    return {
        "new triangle": ([x, y, c], True),
        "complex edge": ([a, b, x], False),
        "complex vertex": ([v, A[2], A[0]], False),
        "join the fans": ([v, A[2], B[0]], True),
        "back of a lone triangle": ([r[2], r[1], r[0]], True),
        "back of a triangle whose edge is taken": ([c, b, a], False),
        "one-gon": ([x], True),
        "wire edge both sides": ([e_yz.halfedge, e_yz.halfedge.twin], True),
        "not a chain": ([e_yz.halfedge, e_yz.halfedge], None),
    }


def test_can_add_polygon_answers_and_writes_nothing(mesh):
    store = mesh.store
    cases = _can_add_setup(mesh)
    url = committed_url(store)
    for name, (loop, expected) in cases.items():
        if expected is None:
            continue
        before, rev = dump(store), mesh.revision
        assert mesh.can_add_polygon(loop) is expected, name
        assert dump(store) == before, name
        assert dump(url) == before, name
        assert mesh.revision == rev, name


def test_can_add_polygon_inside_a_block_writes_nothing(mesh):
    store = mesh.store
    cases = _can_add_setup(mesh)
    url = committed_url(store)
    before, rev = dump(store), mesh.revision
    with store.transaction():
        for name, (loop, expected) in cases.items():
            if expected is None:
                continue
            assert mesh.can_add_polygon(loop) is expected, name
            assert dump(store) == before, name
    assert dump(url) == before
    assert mesh.revision == rev


def test_can_add_polygon_inside_a_block_then_other_edits_commit(mesh):
    store = mesh.store
    a, b, c = (mesh.add_vertex() for _ in range(3))
    with store.transaction():
        assert mesh.can_add_polygon([a, b, c])
        assert mesh.counts().edges == 0
        d = mesh.add_vertex()
        p = mesh.add_polygon([a, b, d])
    assert mesh.counts() == hestore.Counts(vertices=4, halfedges=6, edges=3, polygons=1)
    assert p.vertices() == [a, b, d]
    assert mesh.check() == []


def test_can_add_polygon_agrees_with_add_polygon(mesh):
    cases = _can_add_setup(mesh)
    for name, (loop, expected) in cases.items():
        if expected is None:
            continue
        answer = mesh.can_add_polygon(loop)
        if answer:
            mesh.add_polygon(loop)
        else:
            with pytest.raises(TopologyError):
                mesh.add_polygon(loop)
        assert mesh.check() == [], name


def test_block_with_only_a_refused_edit_keeps_the_revision(mesh):
    """A transaction whose one edit was refused changed nothing: same rows, same revision."""
    v, loop = _complex_vertex_loop_with_relinking(mesh)
    store = mesh.store
    before, rev = dump(store), mesh.revision
    with store.transaction():
        with pytest.raises(NonManifoldError):
            mesh.add_polygon(loop)
    assert mesh.revision == rev
    assert dump(store) == before


def test_block_with_only_can_add_polygon_keeps_the_revision(mesh):
    v = mesh.add_vertex()
    fans = []
    for _ in range(3):
        x1, x2 = mesh.add_vertex(), mesh.add_vertex()
        fans.append((x1, x2))
        mesh.add_polygon([v, x1, x2])
    # a join that needs makeAdjacent (relinking only, no new element)
    for X in range(3):
        for Y in range(3):
            if X != Y:
                mesh.add_edge(fans[X][1], fans[Y][0])
    loops = [
        [
            mesh.find_halfedge(v, fans[X][1]),
            mesh.find_halfedge(fans[X][1], fans[Y][0]),
            mesh.find_halfedge(fans[Y][0], v),
        ]
        for X in range(3)
        for Y in range(3)
        if X != Y
    ]
    store = mesh.store
    before, rev = dump(store), mesh.revision
    with store.transaction():
        assert all(mesh.can_add_polygon(loop) for loop in loops)
    assert mesh.revision == rev
    assert dump(store) == before


# -- closed surfaces --------------------------------------------------------------


def _closed_checks(mesh, vs, ps, degree):
    assert mesh.check() == []
    for v in vs:
        assert not v.is_boundary
        assert v.halfedge.polygon is not None
        assert v.degree == degree
        assert len(v.polygons()) == degree
    for e in mesh.edges():
        assert not e.is_boundary and len(e.polygons()) == 2
    for p in ps:
        assert_chained(p)


def _remove_and_restore(mesh, vs, ps):
    p = ps[0]
    corners = set(p.vertices())
    hs = p.halfedges()
    mesh.remove_polygon(p)
    assert mesh.check() == []
    for v in vs:
        assert v.is_boundary == (v in corners)
        if v in corners:
            assert v.halfedge.is_boundary  # V_BOUNDARY
    assert all(h.is_boundary for h in hs)
    assert mesh.add_polygon(hs).halfedges() == hs
    assert not any(v.is_boundary for v in vs)
    assert mesh.check() == []


@pytest.mark.parametrize("seed", [None, 1, 2])
def test_closed_tetrahedron(mesh, seed):
    faces = list(TETRAHEDRON)
    if seed is not None:
        random.Random(seed).shuffle(faces)
    vs, ps = build_faces(mesh, 4, faces)
    assert mesh.counts() == hestore.Counts(vertices=4, halfedges=12, edges=6, polygons=4)
    _closed_checks(mesh, vs, ps, 3)
    _remove_and_restore(mesh, vs, ps)


@pytest.mark.parametrize("seed", [None, 1, 2, 3, 4])
def test_closed_octahedron(mesh, seed):
    faces = list(OCTAHEDRON)
    if seed is not None:
        random.Random(seed).shuffle(faces)
    vs, ps = build_faces(mesh, 6, faces, OCTAHEDRON_POSITIONS)
    assert mesh.counts() == hestore.Counts(vertices=6, halfedges=24, edges=12, polygons=8)
    _closed_checks(mesh, vs, ps, 4)
    _remove_and_restore(mesh, vs, ps)


def test_octahedron_opposite_faces_first(mesh):
    """Top and bottom faces first (they share no vertex), then the rest: fans meet
    at single vertices and must be reordered."""
    order = [0, 6, 2, 4, 1, 3, 5, 7]
    vs, ps = build_faces(mesh, 6, [OCTAHEDRON[i] for i in order])
    _closed_checks(mesh, vs, ps, 4)


@pytest.mark.parametrize("seed", range(4))
def test_wireframe_first_then_polygons_from_halfedges(mesh, seed):
    """All edges first (arbitrary rotations), then the faces by half-edges in random
    order: every corner may need makeAdjacent."""
    rng = random.Random(seed)
    vs = [mesh.add_vertex(p) for p in OCTAHEDRON_POSITIONS]
    edges = sorted({tuple(sorted((f[i], f[(i + 1) % 3]))) for f in OCTAHEDRON for i in range(3)})
    rng.shuffle(edges)
    for a, b in edges:
        if rng.random() < 0.5:
            a, b = b, a
        mesh.add_edge(vs[a], vs[b])
    assert mesh.check() == []
    faces = list(OCTAHEDRON)
    rng.shuffle(faces)
    ps = []
    for f in faces:
        loop = [mesh.find_halfedge(vs[f[i]], vs[f[(i + 1) % 3]]) for i in range(3)]
        ps.append(mesh.add_polygon(loop))
        assert ps[-1].halfedges() == loop
        assert mesh.check() == []
    assert mesh.counts().edges == 12
    _closed_checks(mesh, vs, ps, 4)


@pytest.mark.parametrize("seed", range(3))
def test_grid_faces_in_random_order(mesh, seed):
    rng = random.Random(seed)
    n = 3
    V = [[mesh.add_vertex((i, j, 0)) for j in range(n + 1)] for i in range(n + 1)]
    cells = [(i, j) for i in range(n) for j in range(n)]
    rng.shuffle(cells)
    ps = []
    for i, j in cells:
        ps.append(mesh.add_polygon([V[i][j], V[i + 1][j], V[i + 1][j + 1], V[i][j + 1]]))
        assert mesh.check() == []
    assert mesh.counts() == hestore.Counts(vertices=16, halfedges=48, edges=24, polygons=9)
    for i in (1, 2):
        for j in (1, 2):
            assert not V[i][j].is_boundary and V[i][j].degree == 4
    for p in ps:
        assert_chained(p)


def test_remove_edge_of_octahedron_opens_a_quad_hole(mesh):
    vs, ps = build_faces(mesh, 6, OCTAHEDRON)
    e = mesh.find_halfedge(vs[0], vs[2]).edge
    mesh.remove_edge(e)
    assert mesh.counts() == hestore.Counts(vertices=6, halfedges=22, edges=11, polygons=6)
    assert vs[0].is_boundary and vs[2].is_boundary and vs[4].is_boundary and vs[5].is_boundary
    assert not vs[1].is_boundary and not vs[3].is_boundary
    assert mesh.check() == []
    # the hole is a quad 0 -> 5 -> 2 -> 4 in some rotation; fill it by vertices
    hole = [h for h in mesh.halfedges() if h.is_boundary]
    assert len(hole) == 4
    start = hole[0]
    loop, h = [start], start.next
    while h != start:
        loop.append(h)
        h = h.next
    assert set(loop) == set(hole)
    mesh.add_polygon(loop)
    assert all(not v.is_boundary for v in vs)
    assert mesh.check() == []


# -- loops that pass a vertex twice ----------------------------------------------------


@pytest.mark.parametrize("how", ["vertices", "halfedges, wire first", "halfedges, wire last"])
def test_polygon_around_a_loop_edge_leaves_the_other_side_free(mesh, how):
    """a->b, the loop b->b, b->a: the polygon passes b twice; a wire edge b-c at b
    fits on the free side of the loop, so the polygon is representable."""
    a, b, c = (mesh.add_vertex() for _ in range(3))
    if how == "vertices":
        wire = mesh.add_edge(b, c)
        p = mesh.add_polygon([a, b, b])
    else:
        if how == "halfedges, wire first":
            wire = mesh.add_edge(b, c)
        e, loop = mesh.add_edge(a, b), mesh.add_edge(b, b)
        if how == "halfedges, wire last":
            wire = mesh.add_edge(b, c)
        p = mesh.add_polygon([e.halfedge, loop.halfedge, e.halfedge.twin])
    assert mesh.check() == []
    assert p.degree == 3 and p.vertices() == rotated_to([a, b, b], p.halfedge.origin)
    assert_chained(p)
    assert all(h.is_boundary for h in wire.halfedges())
    assert b.degree == 4 and b.is_boundary and b.halfedge.is_boundary


def rotated_to(seq, first):
    k = seq.index(first)
    return seq[k:] + seq[:k]


def test_slit_polygon_alone_is_valid(mesh):
    a, b, c = (mesh.add_vertex() for _ in range(3))
    p = mesh.add_polygon([a, b, c, b])  # the path a-b-c, both sides
    assert p.degree == 4 and mesh.counts().edges == 2
    assert_chained(p)
    assert mesh.check() == []


def test_slit_polygon_around_a_wire_edge_is_a_complex_vertex(mesh):
    """Both corners of the slit polygon at b are its own; a wire edge b-d has no gap left."""
    a, b, c, d = (mesh.add_vertex() for _ in range(4))
    mesh.add_edge(b, d)
    assert_refused(mesh.store, mesh, lambda: mesh.add_polygon([a, b, c, b]), NonManifoldError)
    assert not mesh.can_add_polygon([a, b, c, b])
    assert mesh.check() == []


def test_figure_eight_polygon_through_a_vertex_with_a_wire_edge(mesh):
    v, a, b, c, d, x = (mesh.add_vertex() for _ in range(6))
    mesh.add_edge(v, x)
    p = mesh.add_polygon([v, a, b, v, c, d])
    assert p.degree == 6 and v.polygons() == [p, p]
    assert_chained(p)
    assert mesh.check() == []


# -- random edit sequences -----------------------------------------------------------


def _random_loop(rng, mesh, vs):
    if rng.random() < 0.3:
        free = [h for h in mesh.halfedges() if h.is_boundary]
        if free:
            start = rng.choice(free)
            loop, h = [start], start.next
            while h != start and len(loop) < 8:
                loop.append(h)
                h = h.next
            return loop if h == start else loop[:3]
    return [rng.choice(vs) for _ in range(rng.choice([1, 2, 3, 3, 3, 4, 4, 5]))]


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(6))
def test_random_edit_sequences_keep_every_invariant(mesh, seed):
    """Every edit either succeeds and leaves a valid mesh, or raises a TopologyError
    and changes nothing; can_add_polygon predicts add_polygon and writes nothing."""
    rng = random.Random(seed)
    store = mesh.store
    for step in range(100):
        vs = list(mesh.vertices())
        r = rng.random()
        what = None
        try:
            if r < 0.15 or len(vs) < 3:
                what = "add_vertex"
                mesh.add_vertex()
            elif r < 0.35:
                a, b = rng.choice(vs), rng.choice(vs)
                what = f"add_edge({a}, {b})"
                before = dump(store)
                try:
                    mesh.add_edge(a, b)
                except TopologyError:
                    assert dump(store) == before, what
                    raise
            elif r < 0.7:
                loop = _random_loop(rng, mesh, vs)
                what = f"add_polygon({loop})"
                before, rev = dump(store), mesh.revision
                can = mesh.can_add_polygon(loop)
                assert dump(store) == before and mesh.revision == rev, what
                try:
                    mesh.add_polygon(loop)
                except TopologyError:
                    assert not can, what
                    assert dump(store) == before, what
                    raise
                assert can, what
            elif r < 0.8:
                ps = list(mesh.polygons())
                if ps:
                    what = "remove_polygon"
                    mesh.remove_polygon(rng.choice(ps))
            elif r < 0.92:
                es = list(mesh.edges())
                if es:
                    what = "remove_edge"
                    mesh.remove_edge(rng.choice(es))
            else:
                what = "remove_vertex"
                mesh.remove_vertex(rng.choice(vs))
        except TopologyError:
            pass
        assert mesh.check() == [], f"step {step}: {what}"
