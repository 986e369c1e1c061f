"""Navigation through handles: SPEC §3's names and aliases, circulators, handles.

Most tests use a 2×2 grid of counter-clockwise quads with positions (x, y, 0),
so every answer is known in advance and rotation order can be checked
geometrically. Every test runs on SQLite and on PostgreSQL.
"""

from __future__ import annotations

import math
import random

import pytest

import hestore
from hestore import ElementNotFoundError, Edge, HalfEdge, Polygon, Vertex
from helpers import angle, grid

TAU = 2 * math.pi


@pytest.fixture
def g(mesh):
    """The 2×2 grid: ``(V, Q)`` with ``V[i][j]`` at ``(i, j, 0)``."""
    return grid(mesh, 2)


def he(mesh, a, b):
    h = mesh.find_halfedge(a, b)
    assert h is not None
    return h


def rotated(seq, first):
    k = seq.index(first)
    return seq[k:] + seq[:k]


# -- half-edges -------------------------------------------------------------------


def test_halfedge_references_on_the_grid(mesh, g):
    V, Q = g
    h = he(mesh, V[0][0], V[1][0])
    assert h.origin == V[0][0] and h.target == V[1][0]
    assert h.polygon == Q[0][0]
    assert h.next == he(mesh, V[1][0], V[1][1])
    assert h.prev == he(mesh, V[0][1], V[0][0])
    assert h.twin == he(mesh, V[1][0], V[0][0])
    assert h.edge == h.twin.edge
    assert not h.is_boundary
    t = h.twin
    assert t.is_boundary and t.polygon is None
    # boundary loop runs clockwise around the outside
    assert t.next == he(mesh, V[0][0], V[0][1])
    assert t.prev == he(mesh, V[2][0], V[1][0])
    # the inner edge between Q00 and Q10
    m = he(mesh, V[1][0], V[1][1])
    assert m.polygon == Q[0][0] and m.twin.polygon == Q[1][0]


def test_halfedge_invariants_hold_for_every_halfedge(mesh, g):
    hs = list(mesh.halfedges())
    assert len(hs) == 24
    for h in hs:
        assert h.next.prev == h and h.prev.next == h
        assert h.twin.twin == h and h.twin != h
        assert h.target == h.twin.origin == h.next.origin
        assert h.edge == h.twin.edge
        assert h in h.edge.halfedges()
        assert h.polygon == h.next.polygon
        assert h.is_boundary == (h.polygon is None)


ROTATIONS = {
    "onext": lambda h: h.prev.twin,
    "oprev": lambda h: h.twin.next,
    "dnext": lambda h: h.twin.prev,
    "dprev": lambda h: h.next.twin,
    "rnext": lambda h: h.twin.next.twin,
    "rprev": lambda h: h.twin.prev.twin,
}


@pytest.mark.parametrize("name", sorted(ROTATIONS))
def test_rotation_names_are_their_definitions(mesh, g, name):
    for h in mesh.halfedges():
        assert getattr(h, name) == ROTATIONS[name](h), (name, h)


def test_onext_and_oprev_are_inverse_rotations_around_the_origin(mesh, g):
    for h in mesh.halfedges():
        assert h.onext.origin == h.origin and h.oprev.origin == h.origin
        assert h.onext.oprev == h and h.oprev.onext == h
        assert h.dnext.target == h.target and h.dprev.target == h.target
        assert h.dnext.dprev == h


ALIASES = {
    "lnext": "next",
    "lprev": "prev",
    "sym": "twin",
    "pair": "twin",
    "opposite": "twin",
    "org": "origin",
    "source": "origin",
    "dest": "target",
    "destination": "target",
    "face": "polygon",
    "left": "polygon",
    "is_border": "is_boundary",
}


@pytest.mark.parametrize("alias", sorted(ALIASES))
def test_halfedge_aliases(mesh, g, alias):
    primary = ALIASES[alias]
    hs = list(mesh.halfedges())
    assert any(getattr(h, primary) is None for h in hs) == (primary == "polygon")
    for h in hs:
        assert getattr(h, alias) == getattr(h, primary), (alias, h)


def test_length_and_vector(mesh, g):
    V, Q = g
    h = he(mesh, V[0][0], V[1][0])
    assert h.vector == (1.0, 0.0, 0.0)
    assert h.twin.vector == (-1.0, 0.0, 0.0)
    assert h.length == pytest.approx(1.0)
    assert h.edge.length == pytest.approx(1.0)
    a = mesh.add_vertex((0.0, 0.0, 0.0))
    b = mesh.add_vertex((3.0, 4.0, 12.0))
    e = mesh.add_edge(a, b)
    assert e.halfedge.vector == (3.0, 4.0, 12.0)
    assert e.length == pytest.approx(13.0)
    assert e.halfedge.twin.length == pytest.approx(13.0)


def test_length_and_vector_are_none_without_positions(mesh):
    a, b, c = mesh.add_vertex(), mesh.add_vertex(), mesh.add_vertex((1, 2, 3))
    e, f = mesh.add_edge(a, b), mesh.add_edge(b, c)
    assert e.halfedge.vector is None and e.halfedge.length is None and e.length is None
    assert f.halfedge.vector is None and f.halfedge.twin.length is None and f.length is None
    assert a.position is None and c.position == (1.0, 2.0, 3.0)


# -- vertices ---------------------------------------------------------------------


def _assert_ccw(v: Vertex) -> None:
    """The outgoing half-edges of ``v`` turn counter-clockwise, once around."""
    outs = v.outgoing()
    if len(outs) < 2:
        return
    angles = [angle(h) for h in outs]
    steps = [(angles[(k + 1) % len(angles)] - angles[k]) % TAU for k in range(len(angles))]
    assert all(s > 1e-9 for s in steps), (v, angles)
    assert sum(steps) == pytest.approx(TAU), (v, angles)


def test_vertex_circulators_on_the_grid(mesh, g):
    V, Q = g
    for i in range(3):
        for j in range(3):
            v = V[i][j]
            outs = v.outgoing()
            assert outs[0] == v.halfedge
            assert all(h.origin == v for h in outs)
            for k, h in enumerate(outs):
                assert h.onext == outs[(k + 1) % len(outs)]
            assert v.incoming() == [h.twin for h in outs]
            assert v.neighbors() == [h.target for h in outs]
            assert v.edges() == [h.edge for h in outs]
            assert v.polygons() == [h.polygon for h in outs if h.polygon is not None]
            corner, side = i in (0, 2) and j in (0, 2), i in (0, 2) or j in (0, 2)
            assert v.degree == len(outs) == (2 if corner else 3 if side else 4)
            assert not v.is_isolated
            assert v.is_boundary == ((i, j) != (1, 1))
            if v.is_boundary:
                assert v.halfedge.is_boundary
            assert v.position == (float(i), float(j), 0.0)
            _assert_ccw(v)


def test_interior_vertex_rotation_is_counter_clockwise(mesh, g):
    V, Q = g
    c = V[1][1]
    east, north, west, south = V[2][1], V[1][2], V[0][1], V[1][0]
    assert c.neighbors() == rotated([east, north, west, south], c.halfedge.target)
    # polygons follow: the one left of c->east is Q11, then Q01, Q00, Q10
    assert c.polygons() == rotated([Q[1][1], Q[0][1], Q[0][0], Q[1][0]], c.halfedge.polygon)
    assert not c.is_boundary and c.degree == 4


def test_boundary_vertex_starts_at_its_free_halfedge(mesh, g):
    V, Q = g
    v = V[1][0]
    assert v.halfedge == he(mesh, V[1][0], V[0][0])
    assert v.neighbors() == [V[0][0], V[2][0], V[1][1]]
    assert v.polygons() == [Q[1][0], Q[0][0]]  # the free gap is skipped
    corner = V[0][0]
    assert corner.outgoing() == [he(mesh, V[0][0], V[0][1]), he(mesh, V[0][0], V[1][0])]
    assert corner.polygons() == [Q[0][0]]


@pytest.mark.parametrize("seed", range(3))
def test_irregular_fan_is_counter_clockwise(mesh, seed):
    """A hub with 7 neighbours at irregular angles, triangles added in random order."""
    rng = random.Random(seed)
    degrees = [0, 40, 95, 130, 200, 250, 310]
    hub = mesh.add_vertex((0.0, 0.0, 0.0))
    ring = [mesh.add_vertex((math.cos(math.radians(d)), math.sin(math.radians(d)), 0.0)) for d in degrees]
    cells = list(range(len(ring)))
    rng.shuffle(cells)
    for k in cells[:-1]:
        mesh.add_polygon([hub, ring[k], ring[(k + 1) % len(ring)]])
        _assert_ccw(hub)
        for v in ring:
            _assert_ccw(v)
    assert hub.is_boundary
    mesh.add_polygon([hub, ring[cells[-1]], ring[(cells[-1] + 1) % len(ring)]])
    assert not hub.is_boundary
    _assert_ccw(hub)
    assert hub.neighbors() == rotated(ring, hub.halfedge.target)
    assert len(hub.polygons()) == 7
    assert mesh.check() == []


def test_parallel_edges_and_loops_in_vertex_circulators(mesh):
    v, w = mesh.add_vertex(), mesh.add_vertex()
    e1, e2 = mesh.add_edge(v, w), mesh.add_edge(v, w)
    loop = mesh.add_edge(v, v)
    assert v.degree == 4  # the loop counts twice
    assert sorted(x.id for x in v.neighbors()) == sorted([w.id, w.id, v.id, v.id])
    assert v.neighbors().count(w) == 2 and v.neighbors().count(v) == 2
    assert sorted(e.id for e in v.edges()) == sorted([e1.id, e2.id, loop.id, loop.id])
    assert w.degree == 2 and w.neighbors() == [v, v]
    assert set(v.outgoing()) == {e1.halfedge, e2.halfedge, *loop.halfedges()}
    assert v.polygons() == []
    assert loop.is_loop and not e1.is_loop
    assert loop.vertices() == (v, v)
    assert mesh.check() == []


def test_isolated_vertex(mesh):
    v = mesh.add_vertex()
    assert v.is_isolated and v.halfedge is None
    assert v.outgoing() == [] and v.incoming() == [] and v.neighbors() == []
    assert v.edges() == [] and v.polygons() == [] and v.degree == 0
    assert v.is_boundary  # as in OpenMesh: no polygon closes around it
    assert v.position is None
    w = mesh.add_vertex((1, 2, 3))
    mesh.add_edge(v, w)
    assert not v.is_isolated and v.degree == 1 and v.neighbors() == [w]


# -- polygons and edges -------------------------------------------------------------


def test_polygon_circulators(mesh, g):
    V, Q = g
    p = Q[0][0]
    corners = [V[0][0], V[1][0], V[1][1], V[0][1]]
    hs = p.halfedges()
    assert hs[0] == p.halfedge
    assert p.vertices() == rotated(corners, p.halfedge.origin)
    assert hs == [he(mesh, a, b) for a, b in zip(p.vertices(), p.vertices()[1:] + p.vertices()[:1])]
    assert p.edges() == [h.edge for h in hs]
    assert p.degree == 4
    assert p.neighbors() == [h.twin.polygon for h in hs if h.twin.polygon is not None]
    assert set(p.neighbors()) == {Q[1][0], Q[0][1]} and len(p.neighbors()) == 2
    # counter-clockwise: positive signed area
    pts = [v.position for v in p.vertices()]
    area = sum(pts[k][0] * pts[(k + 1) % 4][1] - pts[(k + 1) % 4][0] * pts[k][1] for k in range(4)) / 2
    assert area == pytest.approx(1.0)
    assert set(Q[1][1].neighbors()) == {Q[0][1], Q[1][0]}


def test_edge_accessors(mesh, g):
    V, Q = g
    inner = he(mesh, V[1][0], V[1][1]).edge
    h, t = inner.halfedges()
    assert h == inner.halfedge and t == h.twin
    assert inner.vertices() == (h.origin, h.target)
    assert set(inner.vertices()) == {V[1][0], V[1][1]}
    assert set(inner.polygons()) == {Q[0][0], Q[1][0]}
    assert not inner.is_boundary and not inner.is_loop
    outer = he(mesh, V[0][0], V[1][0]).edge
    assert outer.polygons() == [Q[0][0]]
    assert outer.is_boundary
    boundary_edges = [e for e in mesh.edges() if e.is_boundary]
    assert len(boundary_edges) == 8


def test_edge_halfedge_runs_from_the_first_vertex_given(mesh):
    a, b = mesh.add_vertex(), mesh.add_vertex()
    e = mesh.add_edge(b, a)
    assert e.halfedge.origin == b and e.vertices() == (b, a)
    assert e.polygons() == [] and e.is_boundary


# -- mesh level ---------------------------------------------------------------------


def test_mesh_iterators_are_in_id_order(mesh, g):
    V, Q = g
    mesh.remove_vertex(V[1][1])
    mesh.add_vertex()
    mesh.add_polygon([V[0][0], V[1][0], V[2][0]][::-1])
    for items in (mesh.vertices(), mesh.halfedges(), mesh.edges(), mesh.polygons()):
        ids = [x.id for x in items]
        assert ids == sorted(ids) and len(set(ids)) == len(ids)
    counts = mesh.counts()
    assert len(list(mesh.vertices())) == counts.vertices == 9
    assert len(list(mesh.halfedges())) == counts.halfedges
    assert len(list(mesh.edges())) == counts.edges
    assert len(list(mesh.polygons())) == counts.polygons
    assert V[1][1] not in list(mesh.vertices())
    assert all(type(x) is Vertex for x in mesh.vertices())
    assert all(type(x) is HalfEdge for x in mesh.halfedges())
    assert all(type(x) is Edge for x in mesh.edges())
    assert all(type(x) is Polygon for x in mesh.polygons())


def test_lookup_by_id(mesh, g):
    V, Q = g
    assert mesh.vertex(V[1][1].id) == V[1][1]
    h = he(mesh, V[0][0], V[1][0])
    assert mesh.halfedge(h.id) == h
    assert mesh.edge(h.edge.id) == h.edge
    assert mesh.polygon(Q[1][1].id) == Q[1][1]
    with pytest.raises(ElementNotFoundError):
        mesh.vertex(999)
    with pytest.raises(hestore.InvalidInputError):
        mesh.vertex("0")


def test_find_halfedge_prefers_a_free_halfedge(mesh):
    a, b, c = (mesh.add_vertex() for _ in range(3))
    p = mesh.add_polygon([a, b, c])
    taken = he(mesh, a, b)
    assert taken.polygon == p
    e = mesh.add_edge(a, b)
    assert mesh.find_halfedge(a, b) == e.halfedge
    assert mesh.find_halfedge(a, b).is_boundary
    back = mesh.find_halfedge(b, a)
    assert back.is_boundary and back.origin == b and back.target == a
    assert mesh.find_halfedge(a, a) is None
    loop = mesh.add_edge(a, a)
    assert mesh.find_halfedge(a, a) in loop.halfedges()
    one_gon = mesh.add_polygon([loop.halfedge])
    assert mesh.find_halfedge(a, a) == loop.halfedge.twin  # the free side
    assert one_gon.halfedges() == [loop.halfedge]
    d = mesh.add_vertex()
    assert mesh.find_halfedge(a, d) is None and mesh.find_halfedge(d, a) is None


def test_find_halfedge_returns_a_taken_one_when_no_free_one(mesh):
    a, b, c = (mesh.add_vertex() for _ in range(3))
    p = mesh.add_polygon([a, b, c])
    h = mesh.find_halfedge(a, b)
    assert h is not None and h.polygon == p


# -- handles ------------------------------------------------------------------------


def test_handle_equality_hash_and_repr(mesh):
    vs = [mesh.add_vertex() for _ in range(13)]
    v = vs[12]
    assert repr(v) == "Vertex(12)"
    assert mesh.vertex(12) == v and mesh.vertex(12) is not v
    assert hash(mesh.vertex(12)) == hash(v)
    assert len({v, mesh.vertex(12), vs[11]}) == 2
    e = mesh.add_edge(vs[0], vs[1])
    assert repr(e) == f"Edge({e.id})"
    assert repr(e.halfedge) == f"HalfEdge({e.halfedge.id})"
    p = mesh.add_polygon([vs[2], vs[3], vs[4]])
    assert repr(p) == f"Polygon({p.id})"
    # different kinds with the same id are different handles
    assert Vertex(mesh, 0) != HalfEdge(mesh, 0) != Edge(mesh, 0)
    assert Polygon(mesh, 0) != Vertex(mesh, 0)
    # a second Mesh object for the same mesh of the same store gives equal handles
    again = mesh.store.mesh(mesh.name)
    assert again.vertex(12) == v and hash(again.vertex(12)) == hash(v)


def test_handles_are_immutable(mesh):
    v = mesh.add_vertex()
    with pytest.raises(AttributeError):
        v.id = 5
    with pytest.raises(AttributeError):
        v.mesh = None
    with pytest.raises(AttributeError):
        del v.id
    with pytest.raises(AttributeError):
        v.color = "red"
    assert v.id == 0


def test_handles_of_two_meshes_with_equal_ids_differ(store, mesh):
    other = store.create_mesh("other")
    a, b = mesh.add_vertex(), other.add_vertex()
    assert a.id == b.id
    assert a != b and {a, b} == {a, b} and len({a, b}) == 2
    ea = mesh.add_edge(a, mesh.add_vertex())
    eb = other.add_edge(b, other.add_vertex())
    assert ea.id == eb.id and ea != eb
    assert ea.halfedge != eb.halfedge


def test_handles_of_two_stores_with_equal_ids_differ(db_url, store, mesh):
    v = mesh.add_vertex()
    second = hestore.open(db_url)
    try:
        w = second.mesh(mesh.name).vertex(v.id)
        assert w.id == v.id
        assert w != v
        assert len({v, w}) == 2
    finally:
        second.close()


# -- stale handles -------------------------------------------------------------------

STALE_READS = {
    "vertex": [
        lambda v: v.halfedge, lambda v: v.position, lambda v: v.degree, lambda v: v.is_isolated,
        lambda v: v.is_boundary, lambda v: v.outgoing(), lambda v: v.incoming(), lambda v: v.neighbors(),
        lambda v: v.edges(), lambda v: v.polygons(),
    ],
    "halfedge": [
        lambda h: h.next, lambda h: h.prev, lambda h: h.twin, lambda h: h.origin, lambda h: h.target,
        lambda h: h.polygon, lambda h: h.edge, lambda h: h.is_boundary, lambda h: h.onext, lambda h: h.oprev,
        lambda h: h.dnext, lambda h: h.dprev, lambda h: h.rnext, lambda h: h.rprev, lambda h: h.vector,
        lambda h: h.length, lambda h: h.lnext, lambda h: h.sym, lambda h: h.dest, lambda h: h.face,
    ],
    "edge": [
        lambda e: e.halfedge, lambda e: e.is_boundary, lambda e: e.is_loop, lambda e: e.length,
        lambda e: e.halfedges(), lambda e: e.vertices(), lambda e: e.polygons(),
    ],
    "polygon": [
        lambda p: p.halfedge, lambda p: p.degree, lambda p: p.halfedges(), lambda p: p.vertices(),
        lambda p: p.edges(), lambda p: p.neighbors(),
    ],
}


@pytest.mark.parametrize("kind", sorted(STALE_READS))
def test_stale_handles_raise_on_navigation(mesh, g, kind):
    V, Q = g
    h = he(mesh, V[1][1], V[2][1])
    stale = {"vertex": V[1][1], "halfedge": h, "edge": h.edge, "polygon": Q[1][1]}[kind]
    mesh.remove_vertex(V[1][1])
    for k, read in enumerate(STALE_READS[kind]):
        with pytest.raises(ElementNotFoundError) as info:
            read(stale)
        assert isinstance(info.value, KeyError)
        assert str(stale.id) in str(info.value), k
    assert mesh.check() == []


# -- transactions ---------------------------------------------------------------------


def test_reads_see_own_uncommitted_writes(db_url, store, mesh):
    a = mesh.add_vertex((0, 0, 0))
    reader = hestore.open(db_url)
    try:
        with store.transaction():
            b, c = mesh.add_vertex((1, 0, 0)), mesh.add_vertex((0, 1, 0))
            p = mesh.add_polygon([a, b, c])
            assert p.vertices() == [a, b, c]
            assert a.neighbors() == [b, c] or set(a.neighbors()) == {b, c}
            assert a.polygons() == [p]
            assert mesh.find_halfedge(a, b).polygon == p
            assert [v.id for v in mesh.vertices()] == [a.id, b.id, c.id]
            assert mesh.counts().polygons == 1
            assert b.position == (1.0, 0.0, 0.0)
            # another connection sees only the committed state
            other = reader.mesh(mesh.name)
            assert other.counts() == hestore.Counts(vertices=1, halfedges=0, edges=0, polygons=0)
            mesh.remove_polygon(p)
            assert a.polygons() == [] and mesh.find_halfedge(a, b).is_boundary
            q = mesh.add_polygon([a, c, b])
            assert a.polygons() == [q]
        assert reader.mesh(mesh.name).counts() == hestore.Counts(vertices=3, halfedges=6, edges=3, polygons=1)
        assert q.vertices() == [a, c, b]
    finally:
        reader.close()
