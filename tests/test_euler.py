"""The Euler operators (SPEC §3.1, issue 10), on SQLite and PostgreSQL.

* the facts the peers' own test suites assert (OpenMesh, pmp-library,
  PostGIS), restated on hestore's operators, each with its exact result;
* every refusal each operator can give: the typed error, its ``reason``, a
  message and ``elements`` naming the elements, the predicate answering
  False, and not one row (property values included) nor the revision
  changed, outside a transaction block and inside one that goes on;
* predicates never write and never wait for another store's writer lock;
* general meshes, operator by operator: loops, parallel edges, wire edges,
  1-gons and 2-gons, polygons passing a vertex twice, and meshes whose policy
  forbids loops or parallel edges;
* property values (positions included) through every operator, rollbacks and
  set-based writes in the same block;
* a real closed triangle mesh under a few hundred random operators in one
  transaction.

Successful operators go through `run`, which asks the predicate first (True,
and nothing written) and checks ``mesh.check() == []`` afterwards (the random
run checks once, at its end); refusals go through `refuse`, built on
`helpers.assert_refused`.
"""

from __future__ import annotations

import contextlib
import random
import re
import time

import numpy as np
import pytest
import sqlalchemy as sa

import hestore
from hestore import (
    ElementNotFoundError,
    EulerError,
    HalfEdgeNotFreeError,
    InvalidInputError,
    PolicyError,
    TopologyError,
)
from hestore.handles import Handle
from hestore.schema import VALUE_TABLES
from helpers import (
    OCTAHEDRON, OCTAHEDRON_POSITIONS, TETRAHEDRON, Rollback, assert_refused, build_faces, dump, grid,
)
from meshes import corpus_files


# --------------------------------------------------------------------------
# Helpers


def run(mesh: hestore.Mesh, op: str, *args, **kwargs):
    """``mesh.<op>(*args, **kwargs)``, after ``mesh.can_<op>(*args)`` said yes without writing.

    Checks that the operator made one revision (outside a block) and left a
    valid mesh: ``mesh.check() == []``.
    """
    store = mesh.store
    rev = mesh.revision
    before = dump(store)
    assert getattr(mesh, f"can_{op}")(*args) is True, f"can_{op} refused what {op} should do"
    assert mesh.revision == rev and dump(store) == before, f"can_{op} wrote"
    result = getattr(mesh, op)(*args, **kwargs)
    if not store.in_transaction:
        assert mesh.revision == rev + 1
    assert mesh.check() == []
    return result


def refuse(
    mesh: hestore.Mesh, op: str, *args, exc=EulerError, reason: str | None = None, names=(), elements=None, **kwargs
):
    """``mesh.<op>(*args, **kwargs)`` is refused with ``exc`` (and ``reason``), changing nothing.

    The predicate says False (or, for malformed input, raises the same
    error) without writing, outside a block and inside one. The refusal is
    checked by `helpers.assert_refused` (every table, the property values
    included, and the revision unchanged; inside a block that then goes on
    and commits). The message names every element of ``names`` by its id,
    and the error's ``elements`` are handles of ``mesh`` matching its
    ``refs`` and including ``elements`` (default: ``names``). Returns the error.
    """
    store = mesh.store
    can = getattr(mesh, f"can_{op}")
    rev, before = mesh.revision, dump(store)
    for in_block in (False, True):
        with store.transaction() if in_block else contextlib.nullcontext():
            if issubclass(exc, TopologyError):
                assert can(*args) is False, f"can_{op} said yes to what {op} refuses"
            else:
                with pytest.raises(exc):
                    can(*args)
            assert dump(store) == before, f"can_{op} wrote"
    assert mesh.revision == rev, f"can_{op} made a revision"
    err = assert_refused(store, mesh, lambda: getattr(mesh, op)(*args, **kwargs), exc).value
    assert type(err) is exc
    if reason is not None or exc is EulerError:
        assert err.reason == reason, f"{err.reason!r} != {reason!r}: {err}"
    message = str(err)
    for x in names:
        assert re.search(rf"(?<![0-9]){x.id}(?![0-9])", message), f"{x!r} not named in {message!r}"
    if isinstance(err, TopologyError):
        assert err.elements, "a refusal names no elements"
        assert all(isinstance(x, Handle) and x.mesh == mesh for x in err.elements)
        assert [(x.kind, x.id) for x in err.elements] == list(err.refs)
        wanted = names if elements is None else elements
        assert set(wanted) <= set(err.elements), f"{wanted} not all in {err.elements}"
    return err


def canon(ids) -> tuple:
    """A vertex cycle as the smallest of its rotations (orientation kept)."""
    ids = [getattr(x, "id", x) for x in ids]
    return min(tuple(ids[i:] + ids[:i]) for i in range(len(ids)))


def cycles(mesh: hestore.Mesh) -> list[tuple]:
    """Every polygon's vertex cycle, canonical, sorted."""
    return sorted(canon(p.vertices()) for p in mesh.polygons())


def cycle(p: hestore.Polygon) -> tuple:
    return canon(p.vertices())


def ends(e: hestore.Edge) -> tuple[int, int]:
    """The ids of an edge's ends, ``e.halfedge``'s origin first."""
    a, b = e.vertices()
    return a.id, b.id


def edge_pairs(mesh: hestore.Mesh) -> list[tuple[int, int]]:
    """Every edge as its sorted pair of end ids, sorted (a multiset: parallel edges repeat)."""
    return sorted(tuple(sorted(ends(e))) for e in mesh.edges())


def vef(mesh: hestore.Mesh) -> tuple[int, int, int]:
    c = mesh.counts()
    return c.vertices, c.edges, c.polygons


def chi(mesh: hestore.Mesh) -> int:
    v, e, f = vef(mesh)
    return v - e + f


def burn_ids(mesh: hestore.Mesh) -> None:
    """Use up ids, so that the elements a test makes next have ids that differ by kind.

    Afterwards vertices are numbered from 60, edges from 40 (half-edges
    from 80) and polygons from 10: a message naming ``vertex 61`` cannot be
    right by accident about edge 1.
    """
    with mesh.store.transaction():
        vs = [mesh.add_vertex() for _ in range(60)]
        for i in range(10):
            mesh.add_polygon(vs[3 * i: 3 * i + 3])
        for i in range(10):
            mesh.add_edge(vs[30 + 2 * i], vs[31 + 2 * i])
        for v in vs:
            mesh.remove_vertex(v)
    assert mesh.counts() == hestore.Counts(0, 0, 0, 0)


def faces(mesh: hestore.Mesh, n: int, loops, positions=None):
    """`helpers.build_faces` with positions ``(i, i² mod 7, 0)`` unless given."""
    positions = positions or [(float(i), float(i * i % 7), 0.0) for i in range(n)]
    return build_faces(mesh, n, loops, positions)


def common_polygon(x: hestore.Vertex, y: hestore.Vertex) -> hestore.Polygon:
    (p,) = set(x.polygons()) & set(y.polygons())
    return p


def corner(p: hestore.Polygon, v: hestore.Vertex) -> hestore.HalfEdge:
    """The half-edge of ``p`` whose origin is ``v`` (``v`` a corner of ``p`` once)."""
    (h,) = [h for h in p.halfedges() if h.origin == v]
    return h


def corner_values(mesh: hestore.Mesh, name: str) -> dict[tuple[int, int], object]:
    """``{(polygon id, vertex id): value}`` of a half-edge property, over every corner of every polygon."""
    return {(p.id, h.origin.id): h[name] for p in mesh.polygons() for h in p.halfedges()}


def value_rows(mesh: hestore.Mesh) -> set[tuple[int, int]]:
    """``(property id, element id)`` of every stored value row of the mesh."""
    with mesh.store.session.reading() as conn:
        return {
            (r[0], r[1])
            for t in VALUE_TABLES
            for r in conn.execute(sa.select(t.c.property, t.c.id).where(t.c.mesh_id == mesh.id))
        }


# --------------------------------------------------------------------------
# The peers' facts: flip


def test_flip_the_diagonal_of_two_triangles(mesh):
    vs, (p, q) = faces(mesh, 4, [(0, 1, 2), (0, 2, 3)], [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)])
    e = mesh.find_halfedge(vs[0], vs[2]).edge
    h = e.halfedge
    a, b, c, d = h.origin, h.target, h.prev.origin, h.twin.prev.origin
    first, second = h.polygon, h.twin.polygon
    assert {a, b} == {vs[0], vs[2]} and {c, d} == {vs[1], vs[3]}

    assert run(mesh, "flip_edge", e) == e

    assert mesh.find_halfedge(vs[0], vs[2]) is None
    assert sorted(v.id for v in e.vertices()) == [1, 3]
    assert mesh.counts() == hestore.Counts(vertices=4, halfedges=10, edges=5, polygons=2)
    # OpenMesh's flip: e.halfedge is now d→c in the first polygon (d, c, a), its twin c→d in (c, d, b)
    assert (e.halfedge.origin, e.halfedge.target) == (d, c)
    assert e.halfedge.polygon == first and e.halfedge.twin.polygon == second
    assert cycle(first) == canon([d, c, a]) and cycle(second) == canon([c, d, b])
    assert {first, second} == {p, q}
    # the boundary edges cannot be flipped
    for x in mesh.edges():
        assert mesh.can_flip_edge(x) is (x == e)
    rim = mesh.find_halfedge(vs[0], vs[1]).edge
    refuse(mesh, "flip_edge", rim, reason="boundary", names=(rim,))
    # flipping back restores the original diagonal
    run(mesh, "flip_edge", e)
    assert sorted(v.id for v in e.vertices()) == [0, 2]
    assert cycles(mesh) == [(0, 1, 2), (0, 2, 3)]


def test_no_edge_of_a_tetrahedron_can_be_flipped(mesh):
    burn_ids(mesh)
    vs, _ = faces(mesh, 4, TETRAHEDRON)
    assert [mesh.can_flip_edge(e) for e in mesh.edges()] == [False] * 6
    for e in mesh.edges():
        h = e.halfedge
        c, d = h.prev.origin, h.twin.prev.origin
        f = mesh.find_halfedge(c, d).edge
        err = refuse(mesh, "flip_edge", e, reason="duplicate-edge", names=(e, f, c, d))
    assert "already joined" in str(err)


def edge_onering(mesh):
    """pmp's ``edge_onering``: a centre edge a–b whose ends each have a full one-ring, 10 triangles.

    Returns ``(vertices by name, centre edge)``.
    """
    names = ["a", "b", "t0", "t1", "t2", "u0", "u1", "u2", "l", "r"]
    xy = [(0, 0), (1, 0), (-0.5, 1), (0.5, 1), (1.5, 1), (-0.5, -1), (0.5, -1), (1.5, -1), (-1, 0), (2, 0)]
    v = {n: mesh.add_vertex((x, y, 0.0)) for n, (x, y) in zip(names, xy)}
    loops = [
        ("a", "b", "t1"), ("a", "t1", "t0"), ("a", "t0", "l"), ("a", "l", "u0"), ("a", "u0", "u1"), ("a", "u1", "b"),
        ("b", "t2", "t1"), ("b", "r", "t2"), ("b", "u2", "r"), ("b", "u1", "u2"),
    ]
    with mesh.store.transaction():
        for loop in loops:
            mesh.add_polygon([v[n] for n in loop])
    return v, mesh.find_halfedge(v["a"], v["b"]).edge


def test_flip_the_centre_edge_of_edge_onering(mesh):
    v, e = edge_onering(mesh)
    assert not v["a"].is_boundary and not v["b"].is_boundary
    assert (v["a"].degree, v["b"].degree) == (6, 6)
    before = vef(mesh)
    assert before == (10, 19, 10)

    run(mesh, "flip_edge", e)

    assert vef(mesh) == before
    assert {x.id for x in e.vertices()} == {v["t1"].id, v["u1"].id}
    assert mesh.find_halfedge(v["a"], v["b"]) is None
    assert (v["a"].degree, v["b"].degree, v["t1"].degree, v["u1"].degree) == (5, 5, 5, 5)
    assert {canon([v[n] for n in t]) for t in [("u1", "t1", "a"), ("t1", "u1", "b")]} <= set(cycles(mesh))


# --------------------------------------------------------------------------
# The peers' facts: join


def test_join_two_triangles_into_a_quad(mesh):
    vs, (p, q) = faces(mesh, 4, [(0, 1, 2), (0, 2, 3)])
    e = mesh.find_halfedge(vs[0], vs[2]).edge
    survivor, other = e.halfedge.polygon, e.halfedge.twin.polygon

    assert run(mesh, "join_polygons", e) == survivor

    assert survivor.degree == 4 and cycle(survivor) == (0, 1, 2, 3)
    assert mesh.counts() == hestore.Counts(vertices=4, halfedges=8, edges=4, polygons=1)
    for stale in (e, other):
        with pytest.raises(ElementNotFoundError):
            stale.halfedge
    # the quad's edges are all boundary now: nothing is left to join
    assert [mesh.can_join_polygons(x) for x in mesh.edges()] == [False] * 4


def test_a_boundary_edge_of_a_lone_triangle_cannot_be_joined(mesh):
    burn_ids(mesh)
    vs, (p,) = faces(mesh, 3, [(0, 1, 2)])
    for e in p.edges():
        h = e.halfedge.twin if e.halfedge.polygon is not None else e.halfedge
        refuse(mesh, "join_polygons", e, reason="boundary", names=(e, h))


def test_join_two_quads_into_a_hexagon(mesh):
    V, Q = grid(mesh, 2, 1)
    e = mesh.find_halfedge(V[1][0], V[1][1]).edge
    survivor, other = e.halfedge.polygon, e.halfedge.twin.polygon
    assert {survivor, other} == {Q[0][0], Q[1][0]}

    assert run(mesh, "join_polygons", e) == survivor

    assert cycles(mesh) == [canon([V[0][0], V[1][0], V[2][0], V[2][1], V[1][1], V[0][1]])]
    assert list(mesh.polygons()) == [survivor]
    assert vef(mesh) == (6, 6, 1)


# --------------------------------------------------------------------------
# The peers' facts: poke and split


def test_poke_a_quad(mesh):
    V, Q = grid(mesh, 1, 1)
    p = Q[0][0]
    start = p.halfedge
    corners = p.vertices()

    c = run(mesh, "poke_polygon", p)

    assert c.degree == 4 and not c.is_boundary
    assert c.position == (0.5, 0.5, 0.0)
    assert vef(mesh) == (5, 8, 4)
    assert cycles(mesh) == sorted(canon([corners[i], corners[(i + 1) % 4], c]) for i in range(4))
    assert start.polygon == p  # p keeps the triangle on its half-edge
    assert all(q.degree == 3 for q in mesh.polygons())


def test_split_an_edge_of_a_lone_triangle(mesh):
    vs, (p,) = faces(mesh, 3, [(0, 1, 2)], [(0, 0, 0), (2, 0, 0), (0, 2, 0)])
    e = mesh.find_halfedge(vs[0], vs[1]).edge
    a, b = e.vertices()
    chi0 = chi(mesh)

    v = run(mesh, "split_edge", e)

    assert v.position == (1.0, 0.0, 0.0)
    assert vef(mesh) == (4, 4, 1) and chi(mesh) == chi0
    assert cycle(p) == canon([vs[0], v, vs[1], vs[2]])
    assert e.vertices() == (a, v)  # e keeps its id and ends at the new vertex
    (new,) = [x for x in mesh.edges() if x.id not in (0, 1, 2)]
    assert new.vertices() == (v, b) and new.halfedge.origin == v


def test_split_an_edge_of_a_lone_triangle_into_two_triangles(mesh):
    """pmp's and OpenMesh's triangle split: V 3→4, E 3→5, F 1→2, χ unchanged."""
    vs, (p,) = faces(mesh, 3, [(0, 1, 2)], [(0, 0, 0), (2, 0, 0), (0, 2, 0)])
    e = mesh.find_halfedge(vs[0], vs[1]).edge
    chi0 = chi(mesh)

    v = run(mesh, "split_edge", e, triangulate=True)

    assert vef(mesh) == (4, 5, 2) and chi(mesh) == chi0
    assert cycles(mesh) == sorted([canon([vs[0], v, vs[2]]), canon([v, vs[1], vs[2]])])
    assert e.vertices() == (vs[0], v)
    assert mesh.find_halfedge(v, vs[2]) is not None
    assert v.degree == 3


def test_split_an_edge_between_two_triangles_both_gain_a_corner(mesh):
    vs, (p, q) = faces(mesh, 4, [(0, 1, 2), (0, 2, 3)])
    e = mesh.find_halfedge(vs[0], vs[2]).edge
    a, b = e.vertices()

    v = run(mesh, "split_edge", e)

    assert e.vertices() == (a, v)
    assert cycles(mesh) == sorted([canon([vs[0], vs[1], vs[2], v]), canon([vs[0], v, vs[2], vs[3]])])
    assert (p.degree, q.degree) == (4, 4)
    assert v.degree == 2 and not v.is_boundary
    assert vef(mesh) == (5, 6, 2)

    # with triangulate, both quads would have been cut: here, cut them now and compare
    run(mesh, "split_polygon", p, v, vs[1])
    run(mesh, "split_polygon", q, v, vs[3])
    assert all(x.degree == 3 for x in mesh.polygons()) and vef(mesh) == (5, 8, 4)


def test_split_edge_between_two_triangles_with_triangulate(mesh):
    vs, (p, q) = faces(mesh, 4, [(0, 1, 2), (0, 2, 3)])
    e = mesh.find_halfedge(vs[0], vs[2]).edge

    v = run(mesh, "split_edge", e, triangulate=True)

    assert vef(mesh) == (5, 8, 4)
    assert v.degree == 4 and not v.is_boundary
    assert cycles(mesh) == sorted(
        canon([v, *t]) for t in [(vs[0], vs[1]), (vs[1], vs[2]), (vs[2], vs[3]), (vs[3], vs[0])]
    )


def test_split_a_loop_edge_gives_two_parallel_edges(mesh):
    v = mesh.add_vertex((0.0, 0.0, 0.0))
    loop = mesh.add_edge(v, v)

    w = run(mesh, "split_edge", loop)

    assert w.position == (0.0, 0.0, 0.0)
    assert not loop.is_loop
    assert edge_pairs(mesh) == [(0, 1), (0, 1)]
    assert sorted(x.id for x in v.neighbors()) == [1, 1] and w.degree == 2
    assert mesh.stats().parallel_edges == 1 and mesh.stats().loops == 0


def test_cut_a_quad_between_opposite_corners(mesh):
    burn_ids(mesh)
    V, Q = grid(mesh, 1, 1)
    p = Q[0][0]
    a, b, c, d = p.vertices()
    v0, e0, f0 = vef(mesh)

    e = run(mesh, "split_polygon", p, a, c)

    assert vef(mesh) == (v0, e0 + 1, f0 + 1)
    assert e.vertices() == (a, c)
    (q,) = [x for x in mesh.polygons() if x != p]
    assert sorted([cycle(p), cycle(q)]) == sorted([canon([a, b, c]), canon([c, d, a])])
    assert p.halfedge.polygon == p
    # adjacent corners are refused (on the quad and on each triangle)
    refuse(mesh, "split_polygon", q, *q.vertices()[:2], reason="adjacent-corners", names=(q,))
    quad = run(mesh, "join_polygons", e)
    for x, y in [(a, b), (b, c), (c, d), (d, a)]:
        refuse(mesh, "split_polygon", quad, x, y, reason="adjacent-corners", names=(quad, x, y),
               elements=(quad, corner(quad, x), corner(quad, y)))


# --------------------------------------------------------------------------
# The peers' facts: collapse


def test_collapse_quad_with_center(mesh):
    """OpenMesh's CollapseQuadWithCenter."""
    vs, _ = faces(mesh, 5, [(0, 2, 1), (0, 3, 2), (4, 2, 3), (4, 1, 2)],
                  [(0, 1, 0), (1, 0, 0), (1, 1, 0), (1, 2, 0), (2, 1, 0)])

    w = run(mesh, "collapse_edge", mesh.find_halfedge(vs[2], vs[1]))

    assert w == vs[1] and w.position == (1.0, 0.0, 0.0)
    assert vef(mesh) == (4, 5, 2)
    assert cycles(mesh) == [(0, 3, 1), (1, 3, 4)]
    with pytest.raises(ElementNotFoundError):
        vs[2].position


def test_collapse_in_a_triangle_strip(mesh):
    """OpenMesh's DeletedStatus: an interior collapse removes V 1, E 3, F 2."""
    vs, ps = faces(mesh, 6, [(0, 2, 1), (0, 3, 2), (0, 4, 3), (5, 1, 2), (5, 2, 3), (5, 3, 4)])
    h = mesh.find_halfedge(vs[2], vs[3])
    beside = [h.edge, h.polygon, h.twin.polygon]
    e02, e25 = mesh.find_halfedge(vs[2], vs[0]).edge, mesh.find_halfedge(vs[5], vs[2]).edge
    e03, e35 = mesh.find_halfedge(vs[0], vs[3]).edge, mesh.find_halfedge(vs[3], vs[5]).edge
    v0, e0, f0 = vef(mesh)

    assert run(mesh, "collapse_edge", h) == vs[3]

    assert vef(mesh) == (v0 - 1, e0 - 3, f0 - 2)
    for gone in [vs[2], e02, e25, *beside]:
        with pytest.raises(ElementNotFoundError):
            gone.halfedge
    assert e03.vertices() in ((vs[0], vs[3]), (vs[3], vs[0]))
    assert e35.vertices() in ((vs[3], vs[5]), (vs[5], vs[3]))
    assert cycles(mesh) == [(0, 3, 1), (0, 4, 3), (1, 3, 5), (3, 4, 5)]


def test_large_collapse_half_edge(mesh):
    """OpenMesh's LargeCollapseHalfEdge: 1 → 4 is allowed, 1 goes, 4 stays."""
    vs, _ = faces(mesh, 7, [(0, 5, 1), (1, 5, 3), (0, 1, 2), (1, 3, 4), (2, 1, 4), (2, 4, 6)])

    assert run(mesh, "collapse_edge", mesh.find_halfedge(vs[1], vs[4])) == vs[4]

    assert [v.id for v in mesh.vertices()] == [0, 2, 3, 4, 5, 6]
    assert cycles(mesh) == [(0, 4, 2), (0, 5, 4), (2, 4, 6), (3, 4, 5)]
    assert vef(mesh) == (6, 9, 4)


def test_no_half_edge_of_a_double_sided_triangle_collapses(mesh):
    burn_ids(mesh)
    vs, (p, q) = faces(mesh, 3, [(0, 1, 2), (0, 2, 1)])
    assert [mesh.can_collapse_edge(h) for h in mesh.halfedges()] == [False] * 6
    for h in mesh.halfedges():
        refuse(mesh, "collapse_edge", h, reason="degenerate", names=(h.polygon, h.twin.polygon))


def test_collapse_an_open_pyramid_down_to_a_lone_triangle(mesh):
    """OpenMesh's CollapseTetrahedron: 0 → 4, then 4 → 2, then nothing."""
    burn_ids(mesh)
    vs, _ = faces(mesh, 5, [(0, 4, 2), (3, 4, 0), (2, 4, 3), (2, 1, 0), (0, 1, 3)])
    a, b, c, d, e = vs
    assert run(mesh, "collapse_edge", mesh.find_halfedge(a, e)) == e
    assert cycles(mesh) == sorted([canon([c, e, d]), canon([c, b, e]), canon([e, b, d])])
    assert run(mesh, "collapse_edge", mesh.find_halfedge(e, c)) == c
    assert cycles(mesh) == [canon([c, b, d])]
    assert vef(mesh) == (3, 3, 1)
    assert [mesh.can_collapse_edge(h) for h in mesh.halfedges()] == [False] * 6
    for h in mesh.halfedges():
        p = h.polygon or h.twin.polygon
        refuse(mesh, "collapse_edge", h, reason="degenerate", names=(p,))


def test_collapse_a_tetrahedron_edge_leaves_the_pillow(mesh):
    burn_ids(mesh)
    vs, _ = faces(mesh, 4, TETRAHEDRON)
    assert all(mesh.can_collapse_edge(h) for h in mesh.halfedges())
    h = mesh.find_halfedge(vs[0], vs[1])

    w = run(mesh, "collapse_edge", h)

    assert w == vs[1]
    stats = mesh.stats()
    assert (stats.vertices, stats.edges, stats.polygons, stats.is_closed) == (3, 3, 2, True)
    assert cycles(mesh) == sorted([canon([vs[1], vs[2], vs[3]]), canon([vs[1], vs[3], vs[2]])])
    assert [mesh.can_collapse_edge(x) for x in mesh.halfedges()] == [False] * 6
    for x in mesh.halfedges():
        refuse(mesh, "collapse_edge", x, reason="degenerate", names=(x.polygon, x.twin.polygon))


# --------------------------------------------------------------------------
# The peers' facts: heal


def test_heal_two_edges_through_a_vertex_of_degree_two(mesh):
    a, v, b = (mesh.add_vertex((float(i), 0.0, 0.0)) for i in range(3))
    e1, e2 = mesh.add_edge(a, v), mesh.add_edge(v, b)

    assert run(mesh, "heal_edges", e1, e2) == e1

    assert e1.vertices() == (a, b)
    for gone in (v, e2):
        with pytest.raises(ElementNotFoundError):
            gone.halfedge
    assert vef(mesh) == (2, 1, 0)


def test_heal_restores_a_split_edge_of_a_triangle(mesh):
    vs, (p,) = faces(mesh, 3, [(0, 1, 2)])
    e1 = mesh.find_halfedge(vs[0], vs[1]).edge
    v = run(mesh, "split_edge", e1)
    (e2,) = [e for e in v.edges() if e != e1]

    assert run(mesh, "heal_edges", e1, e2) == e1
    assert cycles(mesh) == [(0, 1, 2)] and e1.vertices() == (vs[0], vs[1])
    # the order of the arguments decides which id survives
    v = run(mesh, "split_edge", e1)
    (e3,) = [e for e in v.edges() if e != e1]
    assert run(mesh, "heal_edges", e3, e1) == e3
    assert cycles(mesh) == [(0, 1, 2)] and set(e3.vertices()) == {vs[0], vs[1]}
    assert sorted(e.id for e in mesh.edges()) == sorted([1, 2, e3.id])


def test_heal_refusals(store):
    mesh = store.create_mesh("m")
    burn_ids(mesh)
    a, b, c, d, x = (mesh.add_vertex() for _ in range(5))
    ab, bc, cd = mesh.add_edge(a, b), mesh.add_edge(b, c), mesh.add_edge(c, d)
    bx = mesh.add_edge(b, x)
    loop = mesh.add_edge(d, d)
    refuse(mesh, "heal_edges", ab, cd, reason="not-adjacent", names=(ab, cd))
    refuse(mesh, "heal_edges", ab, bc, reason="degree", names=(ab, bc, b))
    refuse(mesh, "heal_edges", cd, loop, reason="loop", names=(loop,))
    refuse(mesh, "heal_edges", loop, cd, reason="loop", names=(loop,))
    refuse(mesh, "heal_edges", ab, ab, reason="same-edge", names=(ab,))
    # once b has degree 2, the same pair heals
    mesh.remove_edge(bx)
    run(mesh, "heal_edges", ab, bc)
    assert ab.vertices() == (a, c)


# --------------------------------------------------------------------------
# The peers' facts: 1-to-4 splits


def one_to_four(mesh: hestore.Mesh, corners, midpoints: dict) -> list[hestore.Vertex]:
    """Split each edge of the triangle with these corners, then cut off its three corners; return the new vertices.

    An edge is split once: ``midpoints`` remembers the splits, so that a
    neighbour split earlier (whose split made this triangle a polygon with
    more corners) is reused.
    """
    a, b, c = corners
    mids = []
    for x, y in [(a, b), (b, c), (c, a)]:
        key = frozenset((x.id, y.id))
        if key not in midpoints:
            midpoints[key] = run(mesh, "split_edge", mesh.find_halfedge(x, y).edge)
        mids.append(midpoints[key])
    for x, y in [(mids[0], mids[1]), (mids[1], mids[2]), (mids[2], mids[0])]:
        run(mesh, "split_polygon", common_polygon(x, y), x, y)
    return mids


def test_one_to_four_split_of_a_lone_triangle(mesh):
    vs, (p,) = faces(mesh, 3, [(0, 1, 2)], [(0, 0, 0), (2, 0, 0), (0, 2, 0)])
    chi0 = chi(mesh)
    mids = one_to_four(mesh, p.vertices(), {})
    assert vef(mesh) == (6, 9, 4) and chi(mesh) == chi0
    assert all(q.degree == 3 for q in mesh.polygons())
    m_ab, m_bc, m_ca = mids
    assert cycles(mesh) == sorted([
        canon([vs[0], m_ab, m_ca]), canon([m_ab, vs[1], m_bc]), canon([m_ca, m_bc, vs[2]]), canon([m_ab, m_bc, m_ca]),
    ])
    assert [m.position for m in mids] == [(1.0, 0.0, 0.0), (1.0, 1.0, 0.0), (0.0, 1.0, 0.0)]
    assert len(mesh.boundary_loops()) == 1 and len(mesh.boundary_loops()[0]) == 6


def test_one_to_four_split_inside_a_closed_octahedron(mesh):
    vs, ps = build_faces(mesh, 6, OCTAHEDRON, OCTAHEDRON_POSITIONS)
    triangles = [p.vertices() for p in ps]
    midpoints = {}
    # one face first: its pieces are triangles, its three neighbours have gained a corner, χ is kept
    one_to_four(mesh, triangles[0], midpoints)
    assert sorted(q.degree for q in mesh.polygons()) == [3] * 4 + [3] * 4 + [4] * 3
    assert chi(mesh) == 2 and mesh.stats().is_closed
    # the whole mesh, in one transaction: every polygon a triangle, V + E, 2E + 3F, 4F
    with mesh.store.transaction():
        for corners in triangles[1:]:
            one_to_four(mesh, corners, midpoints)
    assert vef(mesh) == (6 + 12, 2 * 12 + 3 * 8, 4 * 8)
    assert all(q.degree == 3 for q in mesh.polygons())
    stats = mesh.stats()
    assert (stats.euler_characteristic, stats.is_closed, stats.is_manifold, stats.genus) == (2, True, True, 0)
    assert sorted(v.degree for v in mesh.vertices()) == [4] * 6 + [6] * 12


# --------------------------------------------------------------------------
# Refusals, operator by operator: every reason, on meshes whose ids differ by kind


def halfedge_from(e: hestore.Edge, a: hestore.Vertex) -> hestore.HalfEdge:
    """The half-edge of ``e`` leaving ``a``."""
    (h,) = [h for h in e.halfedges() if h.origin == a][:1]
    return h


def two_gon(mesh: hestore.Mesh, a: hestore.Vertex, b: hestore.Vertex) -> hestore.Polygon:
    """A 2-gon a→b→a on two parallel edges (``add_polygon([a, b])`` would take both halves of one edge)."""
    e1, e2 = mesh.add_edge(a, b), mesh.add_edge(b, a)
    p = mesh.add_polygon([halfedge_from(e1, a), halfedge_from(e2, b)])
    assert p.edges() == [e1, e2]
    return p


def figure_eight(mesh: hestore.Mesh):
    """A hexagon through one vertex twice: (v, 1, 2, v, 3, 4); returns ``(v, others, polygon)``."""
    v, *others = (mesh.add_vertex((float(i), float(i % 3), 0.0)) for i in range(5))
    p = mesh.add_polygon([v, others[0], others[1], v, others[2], others[3]])
    assert [x.id for x in p.vertices()] == [v.id, others[0].id, others[1].id, v.id, others[2].id, others[3].id]
    return v, others, p


def test_split_edge_refusals(store):
    mesh = store.create_mesh("m", allow_multi_edges=False)
    burn_ids(mesh)
    v = mesh.add_vertex()
    loop = mesh.add_edge(v, v)
    err = refuse(mesh, "split_edge", loop, exc=PolicyError, names=(loop, v))
    assert "parallel" in str(err)
    mesh.add_polygon([loop.halfedge])  # a 1-gon on it: still refused
    refuse(mesh, "split_edge", loop, exc=PolicyError, names=(loop, v))
    # any other edge splits, also in this mesh
    w = mesh.add_vertex()
    e = mesh.add_edge(v, w)
    x = run(mesh, "split_edge", e)
    assert edge_pairs(mesh) == sorted([(v.id, v.id), (v.id, x.id), tuple(sorted((x.id, w.id)))])


def test_split_polygon_refusals(store):
    mesh = store.create_mesh("m")
    burn_ids(mesh)
    vs, (p, q) = faces(mesh, 6, [(0, 1, 2, 3), (4, 1, 0)])
    a, b, c, d, x, _lone = vs
    refuse(mesh, "split_polygon", p, x, c, reason="not-corner", names=(x, p))
    refuse(mesh, "split_polygon", p, a, _lone, reason="not-corner", names=(_lone, p))
    foreign = corner(q, x)  # a half-edge of another polygon
    refuse(mesh, "split_polygon", p, foreign, c, reason="not-corner", names=(foreign, p))
    free = corner(p, a).twin.twin.prev.twin  # the free half-edge d→... outside p
    assert free.polygon is None
    refuse(mesh, "split_polygon", p, a, free, reason="not-corner", names=(free, p))
    refuse(mesh, "split_polygon", p, a, a, reason="same-corner", names=(p,), elements=(p, corner(p, a)))
    refuse(mesh, "split_polygon", p, corner(p, c), c, reason="same-corner", names=(p,), elements=(p, corner(p, c)))
    for poly, m, n in [(p, a, b), (p, d, corner(p, a)), (q, x, a)]:
        hm, hn = (y if isinstance(y, hestore.HalfEdge) else corner(poly, y) for y in (m, n))
        refuse(mesh, "split_polygon", poly, m, n, reason="adjacent-corners", names=(poly, hm.origin, hn.origin),
               elements=(poly, hm, hn))
    # a vertex that is two corners of the polygon must be named by its half-edge
    v, others, r = figure_eight(mesh)
    twice = [h for h in r.halfedges() if h.origin == v]
    err = refuse(mesh, "split_polygon", r, v, others[1], exc=InvalidInputError, names=(v, r, *twice))
    assert "half-edge" in str(err)
    refuse(mesh, "split_polygon", r, others[1], v, exc=InvalidInputError, names=(v, r))
    # malformed corners
    refuse(mesh, "split_polygon", p, a, p.edges()[0], exc=InvalidInputError)
    refuse(mesh, "split_polygon", p, a.id, c, exc=InvalidInputError)
    refuse(mesh, "split_polygon", p.halfedge, a, c, exc=InvalidInputError)
    # and the right request goes through
    run(mesh, "split_polygon", p, corner(p, a), c)
    assert sorted(x.degree for x in mesh.polygons()) == [3, 3, 3, 6]


def test_split_polygon_refused_by_the_policy(store):
    strict = store.create_mesh("strict", allow_loops=False, allow_multi_edges=False)
    burn_ids(strict)
    v, others, r = figure_eight(strict)
    h0, h3 = [h for h in r.halfedges() if h.origin == v]
    err = refuse(strict, "split_polygon", r, h0, h3, exc=PolicyError, names=(v,))
    assert "self-loop" in str(err)
    vs, (p,) = faces(strict, 4, [(0, 1, 2, 3)])
    diagonal = strict.add_edge(vs[0], vs[2])  # outside the quad
    err = refuse(strict, "split_polygon", p, vs[0], vs[2], exc=PolicyError, names=(vs[0], vs[2], diagonal))
    assert "parallel" in str(err)
    run(strict, "split_polygon", p, vs[1], vs[3])


def test_join_polygons_refusals(mesh):
    burn_ids(mesh)
    vs, (p,) = faces(mesh, 3, [(0, 1, 2)])
    a, b = mesh.add_vertex(), mesh.add_vertex()
    wire = mesh.add_edge(a, b)
    refuse(mesh, "join_polygons", wire, reason="boundary", names=(wire, wire.halfedge))
    e = p.edges()[0]
    refuse(mesh, "join_polygons", e, reason="boundary", names=(e, e.halfedge.twin))
    # a polygon on both sides of an edge: a triangle with a dangling edge inside, (0, 1, 2, 3, 2)
    c, d, f, g = (mesh.add_vertex() for _ in range(4))
    q = mesh.add_polygon([c, d, f, g, f])
    dangling = mesh.find_halfedge(f, g).edge
    assert dangling.halfedge.polygon == dangling.halfedge.twin.polygon == q
    refuse(mesh, "join_polygons", dangling, reason="same-polygon", names=(dangling, q))
    # a sphere of two 1-gons: joining them would leave an empty polygon
    v = mesh.add_vertex()
    one, other = mesh.add_polygon([v]), mesh.add_polygon([v])
    (loop,) = one.edges()
    refuse(mesh, "join_polygons", loop, reason="degenerate", names=(loop, one, other))


def test_poke_polygon_refusals(store):
    strict = store.create_mesh("strict", allow_loops=False, allow_multi_edges=False)
    burn_ids(strict)
    v, others, r = figure_eight(strict)
    err = refuse(strict, "poke_polygon", r, exc=PolicyError, names=(r, v))
    assert "parallel" in str(err)
    refuse(strict, "poke_polygon", r, exc=PolicyError, names=(r, v), position=(0.0, 0.0, 0.0))
    vs, (p,) = faces(strict, 4, [(0, 1, 2, 3)])
    c = run(strict, "poke_polygon", p)
    assert c.degree == 4


def test_flip_edge_refusals(mesh):
    burn_ids(mesh)
    V, Q = grid(mesh, 2, 1)
    e = mesh.find_halfedge(V[1][0], V[1][1]).edge
    boundary = mesh.find_halfedge(V[0][0], V[1][0]).edge
    refuse(mesh, "flip_edge", boundary, reason="boundary", names=(boundary, boundary.halfedge.twin))
    err = refuse(mesh, "flip_edge", e, reason="not-triangle", names=(e,))
    assert set(err.elements) & {Q[0][0], Q[1][0]}
    # a triangle beside a quad is still refused
    run(mesh, "split_polygon", Q[0][0], V[0][0], V[1][1])
    err = refuse(mesh, "flip_edge", e, reason="not-triangle", names=(e, Q[1][0]))
    # a polygon on both sides: the dangling edge of (c, d, f, g, f)
    c, d, f, g = (mesh.add_vertex() for _ in range(4))
    q = mesh.add_polygon([c, d, f, g, f])
    dangling = mesh.find_halfedge(f, g).edge
    refuse(mesh, "flip_edge", dangling, reason="same-polygon", names=(dangling, q))
    # a double-sided triangle: both triangles have the same third corner
    vs, (t1, t2) = faces(mesh, 3, [(0, 1, 2), (0, 2, 1)])
    for x in t1.edges():
        third = [v for v in vs if v not in x.vertices()][0]
        refuse(mesh, "flip_edge", x, reason="degenerate", names=(x, third))
    # a 2-gon beside a triangle
    a, b, x = (mesh.add_vertex() for _ in range(3))
    two = two_gon(mesh, a, b)
    h = corner(two, a)
    mesh.add_polygon([h.twin, mesh.add_edge(a, x).halfedge, mesh.add_edge(x, b).halfedge])
    refuse(mesh, "flip_edge", h.edge, reason="not-triangle", names=(h.edge, two))


def test_flip_refuses_to_duplicate_an_edge_even_where_parallel_edges_are_allowed(mesh):
    burn_ids(mesh)
    vs, _ = faces(mesh, 4, [(0, 1, 2), (0, 2, 3)])
    extra = mesh.add_edge(vs[1], vs[3])  # the new diagonal exists already, as a wire edge
    e = mesh.find_halfedge(vs[0], vs[2]).edge
    assert mesh.allow_multi_edges
    refuse(mesh, "flip_edge", e, reason="duplicate-edge", names=(e, extra, vs[1], vs[3]))
    mesh.remove_edge(extra)
    run(mesh, "flip_edge", e)


def test_collapse_edge_refusals(mesh):
    burn_ids(mesh)
    # a loop
    v = mesh.add_vertex()
    one = mesh.add_polygon([v])
    (loop,) = one.edges()
    for h in loop.halfedges():
        refuse(mesh, "collapse_edge", h, reason="loop", names=(loop, v), elements=(loop,))
    # both sides one polygon
    c, d, f, g = (mesh.add_vertex() for _ in range(4))
    q = mesh.add_polygon([c, d, f, g, f])
    dangling = mesh.find_halfedge(f, g).edge
    refuse(mesh, "collapse_edge", dangling.halfedge, reason="same-polygon", names=(dangling, q))
    # a 2-gon beside
    a, b = mesh.add_vertex(), mesh.add_vertex()
    two = two_gon(mesh, a, b)
    for h in two.halfedges():
        refuse(mesh, "collapse_edge", h, reason="degenerate", names=(h.edge, two))
        refuse(mesh, "collapse_edge", h.twin, reason="degenerate", names=(h.edge, two))
    # an ear: a lone triangle
    vs, (t,) = faces(mesh, 3, [(0, 1, 2)])
    refuse(mesh, "collapse_edge", t.halfedge, reason="degenerate", names=(t,))
    # two wire edges between u and w
    u, w = mesh.add_vertex(), mesh.add_vertex()
    e1, _e2 = mesh.add_edge(u, w), mesh.add_edge(u, w)
    err = refuse(mesh, "collapse_edge", halfedge_from(e1, u), reason="link-condition", names=(u, w),
                 elements=(e1, u, w))
    assert "2 edges" in str(err)
    # a wire triangle: the third vertex is a common neighbour without a triangle
    x, y, z = (mesh.add_vertex() for _ in range(3))
    xy, _yz, _zx = mesh.add_edge(x, y), mesh.add_edge(y, z), mesh.add_edge(z, x)
    refuse(mesh, "collapse_edge", halfedge_from(xy, x), reason="link-condition", names=(xy, x, y, z))
    # a hexagon with a wire diagonal outside it: the hexagon would pass w twice
    hexagon = mesh.add_polygon([mesh.add_vertex() for _ in range(6)])
    h0, h3 = hexagon.vertices()[0], hexagon.vertices()[3]
    diagonal = mesh.add_edge(h0, h3)
    refuse(mesh, "collapse_edge", halfedge_from(diagonal, h0), reason="link-condition",
           names=(diagonal, h0, h3, hexagon))


def test_collapse_refused_where_both_ends_are_on_the_boundary(mesh):
    burn_ids(mesh)
    V, Q = grid(mesh, 2, 1)
    h = mesh.find_halfedge(V[1][0], V[1][1])
    err = refuse(mesh, "collapse_edge", h, reason="link-condition", names=(h.edge, V[1][0], V[1][1]))
    assert "boundary" in str(err)
    # the same in a strip of triangles (pmp: an interior edge between two boundary vertices)
    vs, _ = faces(mesh, 6, [(0, 1, 2), (1, 3, 2), (2, 3, 4), (3, 5, 4)])
    h = mesh.find_halfedge(vs[2], vs[3])
    refuse(mesh, "collapse_edge", h, reason="link-condition", names=(h.edge, vs[2], vs[3]))


def test_collapse_refused_where_both_triangles_share_their_third_corner(mesh):
    """Triangles (a, b, c) and (b, a, c) through parallel edges b–c and c–a: the collapse of a–b would flatten them."""
    burn_ids(mesh)
    a, b, c, x, y = (mesh.add_vertex() for _ in range(5))
    ab = mesh.add_edge(a, b)
    f1, f2 = mesh.add_edge(b, c), mesh.add_edge(b, c)
    g1, g2 = mesh.add_edge(c, a), mesh.add_edge(c, a)
    mesh.add_polygon([halfedge_from(ab, a), halfedge_from(f1, b), halfedge_from(g1, c)])
    mesh.add_polygon([halfedge_from(ab, b), halfedge_from(g2, a), halfedge_from(f2, c)])
    # outer polygons on one other edge of each triangle, so neither is an ear
    mesh.add_polygon([halfedge_from(f1, c), mesh.add_edge(b, x).halfedge, mesh.add_edge(x, c).halfedge])
    mesh.add_polygon([halfedge_from(f2, b), mesh.add_edge(c, y).halfedge, mesh.add_edge(y, b).halfedge])
    assert mesh.check() == []
    for h in ab.halfedges():
        refuse(mesh, "collapse_edge", h, reason="link-condition", names=(ab, c))


def test_fill_hole_refusals(mesh):
    burn_ids(mesh)
    vs, (p,) = faces(mesh, 3, [(0, 1, 2)])
    for h in p.halfedges():
        refuse(mesh, "fill_hole", h, exc=HalfEdgeNotFreeError, names=(h, p))
    q = run(mesh, "fill_hole", p.halfedge.twin)
    for h in q.halfedges():
        refuse(mesh, "fill_hole", h, exc=HalfEdgeNotFreeError, names=(h, q))


def test_triangulate_polygon_refused_by_the_policy(store):
    strict = store.create_mesh("strict", allow_loops=False, allow_multi_edges=False)
    burn_ids(strict)
    vs, (p,) = faces(strict, 5, [(0, 1, 2, 3, 4)])
    o = p.halfedge.origin
    k = p.vertices().index(o)
    opposite = p.vertices()[(k + 2) % 5]
    wire = strict.add_edge(o, opposite)
    err = refuse(strict, "triangulate_polygon", p, exc=PolicyError, names=(o, opposite, wire))
    assert "parallel" in str(err)
    # a polygon through a vertex twice, away from the fan's corner: two diagonals to it
    o, a, v, b, c, d = (strict.add_vertex() for _ in range(6))
    r = strict.add_polygon([o, a, v, b, c, v, d])
    assert r.halfedge.origin == o
    refuse(strict, "triangulate_polygon", r, exc=PolicyError, names=(r, v))
    # loops forbidden: a fan from a vertex the polygon passes twice
    noloops = store.create_mesh("noloops", allow_loops=False)
    burn_ids(noloops)
    v, others, r = figure_eight(noloops)
    assert r.halfedge.origin == v
    err = refuse(noloops, "triangulate_polygon", r, exc=PolicyError, names=(v,))
    assert "self-loop" in str(err)


def test_heal_edges_refused_by_the_policy(store):
    strict = store.create_mesh("strict", allow_loops=False, allow_multi_edges=False)
    burn_ids(strict)
    vs, (t,) = faces(strict, 3, [(0, 1, 2)])
    a, v, b = vs
    e1, e2 = strict.find_halfedge(a, v).edge, strict.find_halfedge(v, b).edge
    ba = strict.find_halfedge(b, a).edge
    err = refuse(strict, "heal_edges", e1, e2, exc=PolicyError, names=(a, b, ba))
    assert "parallel" in str(err)
    noloops = store.create_mesh("noloops", allow_loops=False)
    burn_ids(noloops)
    a, v = noloops.add_vertex(), noloops.add_vertex()
    two = two_gon(noloops, a, v)
    e1, e2 = two.edges()
    err = refuse(noloops, "heal_edges", e1, e2, exc=PolicyError, names=(a,))
    assert "self-loop" in str(err)


def test_split_edge_with_triangulate_where_both_cuts_reach_one_vertex(store):
    """A double-sided triangle: both triangles beside the edge have the same third corner c.

    The two cuts of ``triangulate=True`` both join the new vertex to c. Where
    parallel edges are allowed that is what happens; where they are not, the
    split must be refused with `PolicyError` like every other operator that
    would make a forbidden parallel edge — not leave a mesh that `check`
    reports (``POLICY``).
    """
    mesh = store.create_mesh("m")
    (a, b, c), _ = faces(mesh, 3, [(0, 1, 2), (0, 2, 1)])
    v = run(mesh, "split_edge", mesh.find_halfedge(a, b).edge, triangulate=True)
    assert cycles(mesh) == sorted([canon([a, v, c]), canon([v, b, c]), canon([v, a, c]), canon([b, v, c])])
    assert sorted(x.id for x in v.neighbors()).count(c.id) == 2 and mesh.stats().parallel_edges == 1

    strict = store.create_mesh("strict", allow_multi_edges=False)
    (a, b, c), _ = faces(strict, 3, [(0, 1, 2), (0, 2, 1)])
    e = strict.find_halfedge(a, b).edge
    assert_refused(store, strict, lambda: strict.split_edge(e, triangulate=True), PolicyError)
    assert strict.check() == []
    v = run(strict, "split_edge", e)  # without the cuts it is fine
    assert cycles(strict) == sorted([canon([a, v, b, c]), canon([a, c, b, v])])


def test_collapse_edge_between_two_loops(store):
    """u and w each carry a loop: the collapse puts both loops at w.

    Where parallel edges are allowed, w then has two loops; where they are
    not, two loops at one vertex are parallel edges and the collapse must be
    refused (predicate False, a `TopologyError`, nothing changed).
    """
    mesh = store.create_mesh("m")
    u, w = mesh.add_vertex(), mesh.add_vertex()
    e = mesh.add_edge(u, w)
    lu, lw = mesh.add_edge(u, u), mesh.add_edge(w, w)
    assert run(mesh, "collapse_edge", halfedge_from(e, u)) == w
    assert lu.vertices() == (w, w) and lw.vertices() == (w, w)
    assert edge_pairs(mesh) == [(w.id, w.id), (w.id, w.id)] and mesh.stats().loops == 2

    strict = store.create_mesh("strict", allow_multi_edges=False)
    u, w = strict.add_vertex(), strict.add_vertex()
    e = strict.add_edge(u, w)
    strict.add_edge(u, u), strict.add_edge(w, w)
    h = halfedge_from(e, u)
    assert strict.can_collapse_edge(h) is False, "the collapse would make parallel loops at w"
    assert_refused(store, strict, lambda: strict.collapse_edge(h), TopologyError)
    assert strict.check() == []


# --------------------------------------------------------------------------
# Malformed, stale and foreign arguments: every operator and predicate


def test_stale_foreign_and_malformed_arguments(store):
    mesh, other = store.create_mesh("m"), store.create_mesh("n")
    vs, (p, q) = faces(mesh, 4, [(0, 1, 2), (0, 2, 3)])
    ws, (r, _s) = faces(other, 4, [(0, 1, 2), (0, 2, 3)])
    gone_v = mesh.add_vertex()
    gone_p = mesh.add_polygon([gone_v, mesh.add_vertex(), mesh.add_vertex()])
    gone_e, gone_h = gone_p.edges()[0], gone_p.halfedge
    mesh.remove_vertex(gone_v)
    e = mesh.find_halfedge(vs[0], vs[2]).edge
    e_other = other.find_halfedge(ws[0], ws[2]).edge
    cases = [
        ("split_edge", (gone_e,), ElementNotFoundError, gone_e),
        ("split_edge", (e_other,), ElementNotFoundError, e_other),
        ("split_edge", (vs[0],), InvalidInputError, None),
        ("split_polygon", (gone_p, vs[0], vs[2]), ElementNotFoundError, gone_p),
        ("split_polygon", (r, ws[0], ws[1]), ElementNotFoundError, r),
        ("split_polygon", (p, ws[0], vs[2]), ElementNotFoundError, ws[0]),
        ("split_polygon", (p, vs[0], gone_h), ElementNotFoundError, gone_h),
        ("split_polygon", (p, vs[0], gone_v), ElementNotFoundError, gone_v),
        ("join_polygons", (gone_e,), ElementNotFoundError, gone_e),
        ("join_polygons", (e_other,), ElementNotFoundError, e_other),
        ("join_polygons", (p,), InvalidInputError, None),
        ("poke_polygon", (gone_p,), ElementNotFoundError, gone_p),
        ("poke_polygon", (r,), ElementNotFoundError, r),
        ("poke_polygon", (p.id,), InvalidInputError, None),
        ("flip_edge", (gone_e,), ElementNotFoundError, gone_e),
        ("flip_edge", (e_other,), ElementNotFoundError, e_other),
        ("flip_edge", (e.halfedge,), InvalidInputError, None),
        ("collapse_edge", (gone_h,), ElementNotFoundError, gone_h),
        ("collapse_edge", (r.halfedge,), ElementNotFoundError, r.halfedge),
        ("collapse_edge", (e,), InvalidInputError, None),
        ("heal_edges", (e, gone_e), ElementNotFoundError, gone_e),
        ("heal_edges", (gone_e, e), ElementNotFoundError, gone_e),
        ("heal_edges", (e, e_other), ElementNotFoundError, e_other),
        ("heal_edges", (e, vs[0]), InvalidInputError, None),
        ("fill_hole", (gone_h,), ElementNotFoundError, gone_h),
        ("fill_hole", (r.halfedge.twin,), ElementNotFoundError, r.halfedge.twin),
        ("fill_hole", (e,), InvalidInputError, None),
        ("triangulate_polygon", (gone_p,), ElementNotFoundError, gone_p),
        ("triangulate_polygon", (r,), ElementNotFoundError, r),
        ("triangulate_polygon", ([p],), InvalidInputError, None),
    ]
    for op, args, exc, named in cases:
        refuse(mesh, op, *args, exc=exc, names=() if named is None else (named,))
    # keyword arguments the predicates do not take
    nan = float("nan")
    for op, arg, kwargs in [
        ("split_edge", e, {"position": (nan, 0.0, 0.0)}),
        ("split_edge", e, {"position": (1.0, 2.0)}),
        ("split_edge", e, {"triangulate": "yes"}),
        ("poke_polygon", p, {"position": (0.0, float("inf"), 0.0)}),
        ("poke_polygon", p, {"position": "centre"}),
    ]:
        assert getattr(mesh, f"can_{op}")(arg) is True
        assert_refused(store, mesh, lambda: getattr(mesh, op)(arg, **kwargs), InvalidInputError)
    assert mesh.check() == [] and other.check() == []


# --------------------------------------------------------------------------
# Predicates never write and never wait for a writer


def _questions(mesh, vs, quad, corner_pair):
    """Every predicate, on the committed two triangles (0, 1, 2), (0, 2, 3) and a quad; with the right answers."""
    diagonal = mesh.find_halfedge(vs[0], vs[2]).edge
    rim = mesh.find_halfedge(vs[0], vs[1]).edge
    return [
        (lambda: mesh.can_split_edge(diagonal), True),
        (lambda: mesh.can_split_polygon(quad, *corner_pair), True),
        (lambda: mesh.can_split_polygon(quad, quad.vertices()[0], quad.vertices()[1]), False),
        (lambda: mesh.can_join_polygons(diagonal), True),
        (lambda: mesh.can_join_polygons(rim), False),
        (lambda: mesh.can_poke_polygon(quad), True),
        (lambda: mesh.can_flip_edge(diagonal), True),
        (lambda: mesh.can_flip_edge(rim), False),
        (lambda: mesh.can_collapse_edge(halfedge_from(rim, vs[0])), True),
        (lambda: mesh.can_collapse_edge(halfedge_from(diagonal, vs[0])), False),
        (lambda: mesh.can_heal_edges(rim, rim), False),
        (lambda: mesh.can_fill_hole(rim.halfedge.twin), True),
        (lambda: mesh.can_fill_hole(rim.halfedge), False),
        (lambda: mesh.can_triangulate_polygon(quad), True),
    ]


#: The asker's busy_timeout below: a predicate that waited for the writer's lock would wait this long.
ASKER_WAITS = 60.0


def test_predicates_never_wait_for_a_writer(db_url, backend):
    with hestore.open(db_url, busy_timeout=ASKER_WAITS) as asker, hestore.open(db_url, busy_timeout=3) as writer:
        mesh = asker.create_mesh("m")
        vs, (p, q) = faces(mesh, 4, [(0, 1, 2), (0, 2, 3)])
        (quad,) = faces(mesh, 4, [(0, 1, 2, 3)])[1]
        corners = (quad.vertices()[0], quad.vertices()[2])
        questions = _questions(mesh, vs, quad, corners)
        rev = mesh.revision
        theirs = writer.mesh("m")
        with writer.transaction():
            # the writer holds the lock now (SQLite: the database's, PostgreSQL: the mesh's),
            # and has changed what some answers would be
            theirs.split_polygon(theirs.polygon(quad.id), *(theirs.vertex(v.id) for v in corners))
            survivor = theirs.join_polygons(theirs.edge(mesh.find_halfedge(vs[0], vs[2]).edge.id))
            before = dump(db_url)
            t0 = time.monotonic()
            answers = [ask() for ask, _ in questions]
            if backend == "postgresql":
                # inside the asker's own block too (SQLite takes the write lock when a block begins)
                with asker.transaction():
                    answers_in_block = [ask() for ask, _ in questions]
                assert answers_in_block == [want for _, want in questions]
            elapsed = time.monotonic() - t0
            assert dump(db_url) == before
            theirs.poke_polygon(survivor)  # the writer goes on
            assert theirs.check() == []
        # A wait for the lock would have lasted the whole busy_timeout (the writer holds it until the
        # predicates are done), then raised StoreBusyError or, with a fallback, answered late: the
        # honest answers take a small part of it however busy the machine.
        assert elapsed < ASKER_WAITS, f"the predicates took {elapsed:.2f} s while another store held the lock"
        assert answers == [want for _, want in questions]  # the committed state, not the writer's
        assert mesh.revision == rev + 1
        # now the writer's state: the diagonal is gone, the quad is cut, p is poked
        assert mesh.counts().polygons == 4 + 2
        assert mesh.can_split_polygon(quad, *corners) is False
        assert mesh.check() == []


def test_predicates_inside_a_block_see_the_block_and_write_nothing(store, mesh):
    vs, (p, q) = faces(mesh, 4, [(0, 1, 2), (0, 2, 3)])
    e = mesh.find_halfedge(vs[0], vs[2]).edge
    rev = mesh.revision
    with store.transaction():
        assert mesh.can_join_polygons(e) and mesh.can_flip_edge(e)
        survivor = run(mesh, "join_polygons", e)
        before = dump(store)
        quad_corners = survivor.vertices()
        assert mesh.can_split_polygon(survivor, quad_corners[0], quad_corners[2])
        assert not mesh.can_split_polygon(survivor, quad_corners[0], quad_corners[1])
        assert mesh.can_poke_polygon(survivor) and mesh.can_triangulate_polygon(survivor)
        assert not any(mesh.can_flip_edge(x) or mesh.can_join_polygons(x) for x in mesh.edges())
        assert dump(store) == before
        run(mesh, "triangulate_polygon", survivor)
        assert all(x.degree == 3 for x in mesh.polygons())
    assert mesh.revision == rev + 1
    assert mesh.check() == []


# --------------------------------------------------------------------------
# General meshes, operator by operator


def test_split_edge_on_general_meshes(mesh):
    # a wire edge: a path of two wire edges
    a, b = mesh.add_vertex((0.0, 0.0, 0.0)), mesh.add_vertex((4.0, 0.0, 0.0))
    wire = mesh.add_edge(a, b)
    v = run(mesh, "split_edge", wire, triangulate=True)  # nothing to triangulate
    assert v.position == (2.0, 0.0, 0.0)
    assert wire.vertices() == (a, v)
    assert sorted(x.id for x in v.neighbors()) == [a.id, b.id]
    assert mesh.stats().wire_edges == 2 and mesh.counts().polygons == 0
    # the sphere of two 1-gons: both become 2-gons on the two parallel edges
    c = mesh.add_vertex((1.0, 1.0, 1.0))
    one, other = mesh.add_polygon([c]), mesh.add_polygon([c])
    (loop,) = one.edges()
    w = run(mesh, "split_edge", loop)
    assert w.position == (1.0, 1.0, 1.0)
    assert cycle(one) == cycle(other) == canon([c, w])
    assert set(one.edges()) == {loop, *w.edges()} and len(w.edges()) == 2
    for e in w.edges():
        assert {h.polygon for h in e.halfedges()} == {one, other}
    assert not c.is_boundary and not w.is_boundary and w.degree == 2
    # a 2-gon on parallel edges becomes a triangle
    d, f = mesh.add_vertex(), mesh.add_vertex()
    two = two_gon(mesh, d, f)
    e1 = two.edges()[0]
    x = run(mesh, "split_edge", e1, triangulate=True)  # a 2-gon is not a triangle: no cut
    assert x.position is None
    assert cycle(two) == canon([d, x, f]) and e1.vertices() == (d, x)
    # a polygon through a vertex twice gains the corner where the edge was
    v8, others, r = figure_eight(mesh)
    e = mesh.find_halfedge(v8, others[0]).edge
    y = run(mesh, "split_edge", e)
    assert cycle(r) == canon([v8, y, others[0], others[1], v8, others[2], others[3]])
    stats = mesh.stats()
    assert (stats.loops, stats.parallel_edges) == (0, 1)  # the 2-gons of the sphere


def test_split_polygon_on_general_meshes(mesh):
    # between the two corners at one vertex: a loop cuts the figure eight in two
    v, (a, b, c, d), r = figure_eight(mesh)
    h0, h3 = [h for h in r.halfedges() if h.origin == v]
    e = run(mesh, "split_polygon", r, h0, h3)
    assert e.is_loop and e.vertices() == (v, v)
    (s,) = [x for x in mesh.polygons() if x != r]
    assert sorted([cycle(r), cycle(s)]) == sorted([canon([v, a, b, v]), canon([v, c, d, v])])
    # between corners across the vertex: one part holds both of v's corners
    v, (a, b, c, d), r = figure_eight(mesh)
    run(mesh, "split_polygon", r, a, c)
    (s,) = [x for x in mesh.polygons() if x not in (r,) and x.degree == 4 and a in x.vertices() and b in x.vertices()]
    assert sorted([cycle(r), cycle(s)]) == sorted([canon([a, b, v, c]), canon([c, d, v, a])])
    # where an edge joins the corners already: a parallel edge
    vs, (p,) = faces(mesh, 4, [(0, 1, 2, 3)])
    wire = mesh.add_edge(vs[0], vs[2])
    e = run(mesh, "split_polygon", p, vs[0], vs[2])
    assert e != wire and {*e.vertices()} == {*wire.vertices()}
    assert mesh.stats().parallel_edges == 1
    # 1-gons and 2-gons have no two corners that are neither equal nor adjacent
    x = mesh.add_vertex()
    one = mesh.add_polygon([x])
    refuse(mesh, "split_polygon", one, x, x, reason="same-corner", names=(one,))
    y, z = mesh.add_vertex(), mesh.add_vertex()
    two = two_gon(mesh, y, z)
    refuse(mesh, "split_polygon", two, y, z, reason="adjacent-corners", names=(two, y, z),
           elements=(two, corner(two, y), corner(two, z)))


def test_join_polygons_on_general_meshes(mesh):
    # a 1-gon inside a triangle, across its loop: the triangle is left
    a, b, c = (mesh.add_vertex() for _ in range(3))
    ab, bc, ca = mesh.add_edge(a, b), mesh.add_edge(b, c), mesh.add_edge(c, a)
    loop = mesh.add_edge(a, a)
    l1, l2 = loop.halfedges()
    one = mesh.add_polygon([l1])
    big = mesh.add_polygon([l2, halfedge_from(ab, a), halfedge_from(bc, b), halfedge_from(ca, c)])
    assert cycle(big) == canon([a, a, b, c])
    left = loop.halfedge.polygon
    survivor = run(mesh, "join_polygons", loop)
    assert survivor == left and survivor in (one, big)
    assert cycles(mesh) == [canon([a, b, c])] and list(mesh.polygons()) == [survivor]
    assert mesh.stats().loops == 0
    # a pillow of two 2-gons: joining across one edge leaves one 2-gon on both sides of the other
    x, y = mesh.add_vertex(), mesh.add_vertex()
    p = two_gon(mesh, x, y)
    q = mesh.add_polygon([h.twin for h in reversed(p.halfedges())])
    e1, e2 = p.edges()
    left = e1.halfedge.polygon
    survivor = run(mesh, "join_polygons", e1)
    assert survivor == left and list(mesh.polygons())[-1] == survivor and survivor in (p, q)
    assert cycle(survivor) == canon([x, y])
    assert survivor.edges() == [e2, e2]
    assert [h.polygon for h in e2.halfedges()] == [survivor, survivor]
    # ... which cannot be joined with itself
    refuse(mesh, "join_polygons", e2, reason="same-polygon", names=(e2, survivor))
    # the triangles all round a vertex c0, joined: the polygon passes ring[0] twice, its spoke on both sides
    c0 = mesh.add_vertex()
    ring = [mesh.add_vertex() for _ in range(4)]
    fan = [mesh.add_polygon([c0, ring[i], ring[(i + 1) % 4]]) for i in range(4)]
    for i in (1, 2, 3):
        run(mesh, "join_polygons", mesh.find_halfedge(c0, ring[i]).edge)
    (merged,) = set(fan) & set(mesh.polygons())
    assert cycle(merged) == canon([c0, *ring, ring[0]])
    spoke = mesh.find_halfedge(c0, ring[0]).edge
    refuse(mesh, "join_polygons", spoke, reason="same-polygon", names=(spoke, merged))


def test_poke_polygon_on_general_meshes(mesh):
    # a 1-gon: one triangle (v, v, c) whose spoke has it on both sides
    v = mesh.add_vertex((2.0, 2.0, 2.0))
    one = mesh.add_polygon([v])
    c = run(mesh, "poke_polygon", one)
    assert c.position == (2.0, 2.0, 2.0)
    assert cycles(mesh) == [canon([v, v, c])] and c.degree == 1
    (spoke,) = c.edges()
    assert [h.polygon for h in spoke.halfedges()] == [one, one]
    # a 2-gon: two triangles
    a, b = mesh.add_vertex(), mesh.add_vertex()
    two = two_gon(mesh, a, b)
    m = run(mesh, "poke_polygon", two)
    assert m.position is None
    assert sorted(canon(p.vertices()) for p in mesh.polygons() if m in p.vertices()) == sorted(
        [canon([a, b, m]), canon([b, a, m])])
    # a polygon through a vertex twice: two parallel spokes to it
    w, others, r = figure_eight(mesh)
    k = run(mesh, "poke_polygon", r)
    assert k.degree == 6 and sorted(x.id for x in k.neighbors()).count(w.id) == 2
    loop = [w, others[0], others[1], w, others[2], others[3]]
    assert sorted(canon(p.vertices()) for p in mesh.polygons() if k in p.vertices()) == sorted(
        canon([loop[i], loop[(i + 1) % 6], k]) for i in range(6))
    assert mesh.stats().parallel_edges == 2  # the 2-gon's, and the second spoke to w


def test_flip_edge_on_general_meshes(mesh):
    # the spoke of a poked 1-gon has one polygon on both sides
    v = mesh.add_vertex()
    c = run(mesh, "poke_polygon", mesh.add_polygon([v]))
    (spoke,) = c.edges()
    refuse(mesh, "flip_edge", spoke, reason="same-polygon", names=(spoke,))
    # two triangles beside an edge in a mesh with loops and parallel edges elsewhere flip as usual
    vs, (p, q) = faces(mesh, 4, [(0, 1, 2), (0, 2, 3)])
    mesh.add_edge(vs[1], vs[1])
    mesh.add_edge(vs[0], vs[3])  # parallel to the rim edge 3–0
    e = mesh.find_halfedge(vs[0], vs[2]).edge
    run(mesh, "flip_edge", e)
    assert {*e.vertices()} == {vs[1], vs[3]}
    assert sorted([cycle(p), cycle(q)]) == sorted([canon([vs[0], vs[1], vs[3]]), canon([vs[1], vs[2], vs[3]])])
    # a wire edge has no triangles
    wire = mesh.add_edge(mesh.add_vertex(), mesh.add_vertex())
    refuse(mesh, "flip_edge", wire, reason="boundary", names=(wire,))


def test_collapse_edge_on_general_meshes(mesh):
    # wire edges contract like a graph: u's other edges move to w, keeping their ids
    u, w, x, y = (mesh.add_vertex((float(i), 0.0, 0.0)) for i in range(4))
    uw, ux, uy = mesh.add_edge(u, w), mesh.add_edge(u, x), mesh.add_edge(y, u)
    loop = mesh.add_edge(u, u)
    assert run(mesh, "collapse_edge", halfedge_from(uw, u)) == w
    assert w.position == (1.0, 0.0, 0.0)
    assert sorted(ends(e) for e in [ux, uy]) == sorted([(w.id, x.id), (y.id, w.id)])
    assert loop.vertices() == (w, w)
    assert [v.id for v in mesh.vertices()] == [w.id, x.id, y.id]
    assert edge_pairs(mesh) == sorted([(w.id, w.id), (w.id, x.id), tuple(sorted((w.id, y.id)))])
    # a boundary edge of a quad: the quad becomes a triangle
    V, Q = grid(mesh, 2, 1)
    h = mesh.find_halfedge(V[0][0], V[1][0])
    assert run(mesh, "collapse_edge", h) == V[1][0]
    assert cycles(mesh) == sorted([canon([V[1][0], V[1][1], V[0][1]]),
                                   canon([V[1][0], V[2][0], V[2][1], V[1][1]])])
    # an edge between a triangle and a quad: the triangle vanishes, the quad loses a corner
    V, Q = grid(mesh, 2, 2)
    run(mesh, "split_polygon", Q[0][0], V[0][0], V[1][1])
    u, w = V[1][0], V[1][1]
    h = mesh.find_halfedge(u, w)
    triangle, quad = h.polygon, h.twin.polygon
    assert (triangle.degree, quad, w.is_boundary) == (3, Q[1][0], False)
    kept, gone = mesh.find_halfedge(w, V[0][0]).edge, mesh.find_halfedge(V[0][0], u).edge
    (across,) = [p for p in kept.polygons() if p != triangle]
    moved = mesh.find_halfedge(u, V[2][0]).edge
    v0, e0, f0 = vef(mesh)
    assert run(mesh, "collapse_edge", h) == w
    assert vef(mesh) == (v0 - 1, e0 - 2, f0 - 1)
    assert cycle(quad) == canon([V[2][0], V[2][1], w])
    assert ends(moved) in ((w.id, V[2][0].id), (V[2][0].id, w.id))
    assert {*kept.vertices()} == {w, V[0][0]} and kept.polygons() == [across]
    for x in (triangle, gone, u):
        with pytest.raises(ElementNotFoundError):
            x.halfedge


def test_heal_edges_on_general_meshes(mesh):
    # the healed edge may be parallel to another: a triangle becomes a 2-gon
    vs, (t,) = faces(mesh, 3, [(0, 1, 2)])
    a, v, b = vs
    e1, e2 = mesh.find_halfedge(a, v).edge, mesh.find_halfedge(v, b).edge
    assert run(mesh, "heal_edges", e1, e2) == e1
    assert cycle(t) == canon([a, b]) and e1.vertices() == (a, b)
    assert mesh.stats().parallel_edges == 1
    # ... and then a loop, through either end: the 2-gon becomes a 1-gon
    (ba,) = [e for e in t.edges() if e != e1]
    assert run(mesh, "heal_edges", e1, ba) == e1
    assert e1.is_loop and cycle(t) == (a.id,) and t.edges() == [e1]
    assert [x.id for x in mesh.vertices()] == [a.id]
    # a wire path: the first argument survives, whichever end of the path it is
    p, q = (mesh.add_vertex() for _ in range(2))
    mid = mesh.add_vertex()
    g1, g2 = mesh.add_edge(p, mid), mesh.add_edge(mid, q)
    assert run(mesh, "heal_edges", g2, g1) == g2
    assert set(g2.vertices()) == {p, q}


def test_fill_hole_on_general_meshes(mesh):
    # the back of a lone triangle: the closed pillow
    vs, (t,) = faces(mesh, 3, [(0, 1, 2)])
    back = run(mesh, "fill_hole", t.halfedge.twin)
    assert cycle(back) == canon([vs[0], vs[2], vs[1]])
    # a wire edge: a 2-gon on both of its half-edges
    a, b = mesh.add_vertex(), mesh.add_vertex()
    wire = mesh.add_edge(a, b)
    p = run(mesh, "fill_hole", wire.halfedge)
    assert cycle(p) == canon([a, b]) and p.edges() == [wire, wire]
    # a bare loop: a 1-gon on one side
    v = mesh.add_vertex()
    loop = mesh.add_edge(v, v)
    one = run(mesh, "fill_hole", loop.halfedge)
    assert cycle(one) == (v.id,) and one.halfedges() == [loop.halfedge]
    assert run(mesh, "fill_hole", loop.halfedge.twin).halfedges() == [loop.halfedge.twin]
    # a wire path: its boundary walks out and back
    x, y, z = (mesh.add_vertex() for _ in range(3))
    xy, _yz = mesh.add_edge(x, y), mesh.add_edge(y, z)
    path = run(mesh, "fill_hole", halfedge_from(xy, x))
    assert cycle(path) == canon([x, y, z, y])
    # the hole of a grid
    V, Q = grid(mesh, 3, 3)
    mesh.remove_polygon(Q[1][1])
    hole = run(mesh, "fill_hole", mesh.find_halfedge(V[1][2], V[1][1]))
    assert cycle(hole) == canon([V[1][1], V[2][1], V[2][2], V[1][2]])
    assert mesh.stats().pinched_vertices == 0


def test_triangulate_polygon_on_general_meshes(mesh):
    # a hexagon: a fan from p.halfedge's corner, p first
    hexagon = mesh.add_polygon([mesh.add_vertex() for _ in range(6)])
    corners = hexagon.vertices()
    triangles = run(mesh, "triangulate_polygon", hexagon)
    assert triangles[0] == hexagon and len(triangles) == 4
    assert [cycle(x) for x in triangles] == [canon([corners[0], corners[i], corners[i + 1]]) for i in range(1, 5)]
    # triangles, 2-gons and 1-gons come back unchanged, and no revision is made
    one, two = mesh.add_polygon([mesh.add_vertex()]), two_gon(mesh, mesh.add_vertex(), mesh.add_vertex())
    for p in (triangles[1], one, two):
        rev, before = mesh.revision, dump(mesh.store)
        assert mesh.can_triangulate_polygon(p) is True
        assert mesh.triangulate_polygon(p) == [p]
        assert dump(mesh.store) == before and mesh.revision == rev
        assert mesh.check() == []
    # a polygon through its fan corner twice: the fan makes a loop and a parallel edge
    v, others, r = figure_eight(mesh)
    loop = [v, *others[:2], v, *others[2:]]
    triangles = run(mesh, "triangulate_polygon", r)
    assert [cycle(x) for x in triangles] == [canon([v, loop[i], loop[i + 1]]) for i in range(1, 5)]
    stats = mesh.stats()
    # the 1-gon's loop and the 2-gon's parallel edge, and the fan's loop at v and its diagonals to corners 2 and 4
    assert (stats.loops, stats.parallel_edges) == (1 + 1, 1 + 2)


# --------------------------------------------------------------------------
# Properties through the operators (SPEC §3.1, last paragraph)


def declare(mesh: hestore.Mesh) -> None:
    """Vertex float64 scalar (no default) and (3,), int64 and str; edge float64; polygon str; corner uv (2,)."""
    mesh.add_property("vertex", "w", "float64")
    mesh.add_property("vertex", "n", "float64", shape=(3,), default=(0.0, 0.0, 1.0))
    mesh.add_property("vertex", "k", "int64", default=-1)
    mesh.add_property("vertex", "tag", "str")
    mesh.add_property("edge", "cost", "float64", default=1.0)
    mesh.add_property("polygon", "label", "str", default="")
    mesh.add_property("halfedge", "uv", "float64", shape=(2,))


def valued(mesh: hestore.Mesh, n: int, loops, positions=None):
    """`faces` with every property of `declare` set on every element (corners: on half-edges with a polygon).

    Vertex ``i``: w ``10 i``, n ``(i, 2i, 3i)``, k ``100 + i``, tag ``"v<i>"``;
    edge ``e``: cost ``0.5 + e``; polygon ``p``: label ``"p<p>"``; corner
    half-edge ``h``: uv ``(h + 0.25, -h)``.
    """
    declare(mesh)
    vs, ps = faces(mesh, n, loops, positions)
    with mesh.store.transaction():
        ids = np.array([v.id for v in vs])
        mesh.set_property_array("vertex", "w", ids, 10.0 * ids)
        mesh.set_property_array("vertex", "n", ids, np.outer(ids, [1.0, 2.0, 3.0]))
        mesh.set_property_array("vertex", "k", ids, 100 + ids)
        mesh.set_property_array("vertex", "tag", ids, np.array([f"v{i}" for i in ids], dtype=object))
        es = np.array([e.id for e in mesh.edges()])
        mesh.set_property_array("edge", "cost", es, 0.5 + es)
        pids = np.array([p.id for p in ps])
        mesh.set_property_array("polygon", "label", pids, np.array([f"p{i}" for i in pids], dtype=object))
        hs = np.array([h.id for h in mesh.halfedges() if h.polygon is not None])
        mesh.set_property_array("halfedge", "uv", hs, np.stack([hs + 0.25, -hs.astype(float)], axis=1))
    return vs, ps


def vertex_values(v: hestore.Vertex) -> tuple:
    return v["w"], v["n"], v["k"], v["tag"]


def mean(*xs):
    if isinstance(xs[0], tuple):
        return tuple(sum(x[k] for x in xs) / len(xs) for k in range(len(xs[0])))
    return sum(xs) / len(xs)


def assert_no_values_of_removed_elements(mesh: hestore.Mesh) -> None:
    """Every value row belongs to a live element of its property's kind (what ``PROPERTY_REF`` checks)."""
    live = {
        "vertex": {x.id for x in mesh.vertices()},
        "halfedge": {x.id for x in mesh.halfedges()},
        "edge": {x.id for x in mesh.edges()},
        "polygon": {x.id for x in mesh.polygons()},
    }
    kind_of = {prop.id: kind for kind in live for prop in mesh.properties(kind).values()}
    rows = value_rows(mesh)
    assert rows, "no value rows at all: the test would prove nothing"
    assert {(pid, i) for pid, i in rows if i not in live[kind_of[pid]]} == set()
    assert not [x for x in mesh.check() if x.code == "PROPERTY_REF"]


STRIP = [(0, 2, 1), (0, 3, 2), (0, 4, 3), (5, 1, 2), (5, 2, 3), (5, 3, 4)]
STRIP_XY = [(0, 2, 0), (-1, 0, 0), (1, 0, 0), (3, 0, 0), (5, 0, 0), (2, -2, 0)]


def test_properties_through_split_edge(mesh):
    vs, ps = valued(mesh, 6, STRIP, STRIP_XY)
    e = mesh.find_halfedge(vs[2], vs[3]).edge
    h, t = e.halfedges()
    a, b = e.vertices()
    P, Q = h.polygon, t.polygon
    corners = corner_values(mesh, "uv")

    v = run(mesh, "split_edge", e)

    assert v.position == mean(a.position, b.position)
    assert vertex_values(v) == (mean(a["w"], b["w"]), mean(a["n"], b["n"]), a["k"], a["tag"])
    (new,) = [x for x in v.edges() if x != e]
    assert new["cost"] == e["cost"] == 0.5 + e.id
    assert (P["label"], Q["label"]) == (f"p{P.id}", f"p{Q.id}")
    after = corner_values(mesh, "uv")
    for key, value in corners.items():
        assert after[key] == value, f"corner {key} changed"
    assert after[P.id, v.id] == mean(corners[P.id, a.id], corners[P.id, b.id])
    assert after[Q.id, v.id] == mean(corners[Q.id, a.id], corners[Q.id, b.id])
    assert len(after) == len(corners) + 2

    # given positions win; an end without a position, w or tag gives none
    f = mesh.find_halfedge(vs[0], vs[2]).edge
    x = run(mesh, "split_edge", f, position=(7.0, 8.0, 9.0))
    assert x.position == (7.0, 8.0, 9.0)
    first, second = f.vertices()
    mesh.set_position(second, None)
    del first["tag"]
    del second["w"]
    y = run(mesh, "split_edge", f)
    assert y.position is None
    assert (y["w"], y["tag"], y["k"], y["n"]) == (None, None, first["k"], mean(first["n"], second["n"]))
    assert_no_values_of_removed_elements(mesh)


def test_properties_through_split_edge_with_triangulate(mesh):
    vs, ps = valued(mesh, 6, STRIP, STRIP_XY)
    e = mesh.find_halfedge(vs[2], vs[3]).edge
    h, t = e.halfedges()
    a, b = e.vertices()
    label_of = {p.id: p["label"] for p in mesh.polygons()}
    sides = {h.polygon.id, t.polygon.id}
    corners = corner_values(mesh, "uv")

    v = run(mesh, "split_edge", e, triangulate=True)

    assert v.degree == 4 and all(p.degree == 3 for p in mesh.polygons())
    after = corner_values(mesh, "uv")
    for p in mesh.polygons():
        # new triangles copy the label of the polygon they were cut from: that tells which it is
        (origin,) = [q for q, label in label_of.items() if label == p["label"]]
        for x in p.vertices():
            if x == v:
                assert after[p.id, x.id] == mean(corners[origin, a.id], corners[origin, b.id])
            else:
                assert after[p.id, x.id] == corners[origin, x.id]
        assert origin in sides or p.id == origin
    cuts = [x for x in v.edges() if set(x.vertices()) not in ({v, a}, {v, b})]
    assert len(cuts) == 2 and [x["cost"] for x in cuts] == [1.0, 1.0]  # new edges: the default


def test_properties_through_split_polygon(mesh):
    vs, (p,) = valued(mesh, 5, [(0, 1, 2, 3, 4)])
    corners = corner_values(mesh, "uv")
    edges_before = {x.id: x["cost"] for x in mesh.edges()}

    e = run(mesh, "split_polygon", p, vs[1], vs[3])

    (q,) = [x for x in mesh.polygons() if x != p]
    assert p["label"] == q["label"] == f"p{p.id}"
    assert e["cost"] == 1.0
    assert {x.id: x["cost"] for x in mesh.edges() if x != e} == edges_before
    after = corner_values(mesh, "uv")
    for poly in (p, q):
        for x in poly.vertices():
            assert after[poly.id, x.id] == corners[p.id, x.id]
    x, y = e.halfedges()
    assert x.origin == vs[1] and x["uv"] == corners[p.id, vs[1].id]
    assert y.origin == vs[3] and y["uv"] == corners[p.id, vs[3].id]


def test_properties_through_join_polygons(mesh):
    vs, ps = valued(mesh, 6, STRIP, STRIP_XY)
    e = mesh.find_halfedge(vs[2], vs[3]).edge
    h, t = e.halfedges()
    P, Q = h.polygon, t.polygon
    uv = {x.id: x["uv"] for x in mesh.halfedges()}
    vertices = {v.id: vertex_values(v) for v in vs}

    assert run(mesh, "join_polygons", e) == P

    assert P["label"] == f"p{P.id}"
    assert {x.id: x["uv"] for x in mesh.halfedges()} == {i: value for i, value in uv.items() if i not in (h.id, t.id)}
    assert {v.id: vertex_values(v) for v in vs} == vertices
    assert_no_values_of_removed_elements(mesh)
    with pytest.raises(ElementNotFoundError):
        Q["label"]


def test_properties_through_poke_polygon(mesh):
    vs, (p,) = valued(mesh, 4, [(0, 1, 2, 3)], [(0, 0, 0), (2, 0, 0), (2, 2, 0), (0, 2, 0)])
    corners = corner_values(mesh, "uv")
    first = p.halfedge.origin
    loop = p.vertices()

    c = run(mesh, "poke_polygon", p)

    assert c.position == (1.0, 1.0, 0.0)
    assert vertex_values(c) == (mean(*(v["w"] for v in loop)), mean(*(v["n"] for v in loop)), first["k"], first["tag"])
    assert all(q["label"] == f"p{p.id}" for q in mesh.polygons())
    assert [x["cost"] for x in c.edges()] == [1.0] * 4
    after = corner_values(mesh, "uv")
    centre = mean(*(corners[p.id, v.id] for v in loop))
    for q in mesh.polygons():
        for x in q.vertices():
            assert after[q.id, x.id] == (centre if x == c else corners[p.id, x.id])
    # given position wins; a corner without a position gives none
    mesh.set_position(vs[0], None)
    q = next(x for x in mesh.polygons() if x != p and vs[0] in x.vertices())
    assert run(mesh, "poke_polygon", q).position is None
    assert run(mesh, "poke_polygon", p, position=(5.0, 5.0, 5.0)).position == (5.0, 5.0, 5.0)


def test_properties_through_flip_edge(mesh):
    vs, ps = valued(mesh, 6, STRIP, STRIP_XY)
    e = mesh.find_halfedge(vs[2], vs[3]).edge
    h = e.halfedge
    P, Q = h.polygon, h.twin.polygon
    a, b, c, d = h.origin, h.target, h.prev.origin, h.twin.prev.origin
    corners = corner_values(mesh, "uv")
    cost = e["cost"]

    run(mesh, "flip_edge", e)

    assert e["cost"] == cost and (P["label"], Q["label"]) == (f"p{P.id}", f"p{Q.id}")
    after = corner_values(mesh, "uv")
    # each polygon keeps its corners; its new corner copies the other polygon's corner at that vertex
    assert {x: after[P.id, x.id] for x in (d, c, a)} == {
        a: corners[P.id, a.id], c: corners[P.id, c.id], d: corners[Q.id, d.id]}
    assert {x: after[Q.id, x.id] for x in (c, d, b)} == {
        b: corners[Q.id, b.id], d: corners[Q.id, d.id], c: corners[P.id, c.id]}


def test_properties_through_collapse_edge(mesh):
    vs, ps = valued(mesh, 6, STRIP, STRIP_XY)
    h = mesh.find_halfedge(vs[2], vs[3])
    u, w = h.origin, h.target
    beside = {h.polygon.id, h.twin.polygon.id}
    corners = corner_values(mesh, "uv")
    kept_values = vertex_values(w), w.position
    costs = {x.id: x["cost"] for x in mesh.edges()}

    assert run(mesh, "collapse_edge", h) == w

    assert (vertex_values(w), w.position) == kept_values
    after = corner_values(mesh, "uv")
    for (p, x), value in after.items():
        assert p not in beside
        assert value == corners[p, u.id if x == w.id and (p, w.id) not in corners else x], f"corner {(p, x)}"
    live = {x.id for x in mesh.edges()}
    assert len(live) == len(costs) - 3
    assert {x.id: x["cost"] for x in mesh.edges()} == {i: c for i, c in costs.items() if i in live}
    assert_no_values_of_removed_elements(mesh)
    with pytest.raises(ElementNotFoundError):
        u["w"]


def test_properties_through_heal_edges(mesh):
    vs, (p,) = valued(mesh, 4, [(0, 1, 2, 3)])
    e1, e2 = mesh.find_halfedge(vs[0], vs[1]).edge, mesh.find_halfedge(vs[1], vs[2]).edge
    outside = p.halfedge.twin.polygon
    assert outside is None
    back = run(mesh, "fill_hole", p.halfedge.twin)  # corners on both sides
    back["label"] = "back"
    for x in back.halfedges():
        x["uv"] = (float(x.id), 1.0)
    corners = corner_values(mesh, "uv")
    cost = e1["cost"]

    assert run(mesh, "heal_edges", e1, e2) == e1

    assert e1["cost"] == cost
    after = corner_values(mesh, "uv")
    assert after == {key: value for key, value in corners.items() if key[1] != vs[1].id}
    assert_no_values_of_removed_elements(mesh)


def test_properties_through_fill_hole_and_triangulate(mesh):
    vs, (p,) = valued(mesh, 5, [(0, 1, 2, 3, 4)])
    corners = corner_values(mesh, "uv")
    q = run(mesh, "fill_hole", p.halfedge.twin)
    assert q["label"] == "" and [x["uv"] for x in q.halfedges()] == [None] * 5
    assert [x["cost"] for x in q.edges()] == [0.5 + x.id for x in q.edges()]

    triangles = run(mesh, "triangulate_polygon", p)

    assert [t["label"] for t in triangles] == [f"p{p.id}"] * 3
    after = corner_values(mesh, "uv")
    for t in triangles:
        for x in t.vertices():
            assert after[t.id, x.id] == corners[p.id, x.id]
    diagonals = [x for x in mesh.edges() if x.id >= 5]
    assert len(diagonals) == 2 and [x["cost"] for x in diagonals] == [1.0, 1.0]


def test_properties_rolled_back_with_the_block(store, mesh):
    vs, ps = valued(mesh, 6, STRIP, STRIP_XY)
    before, rev = dump(store), mesh.revision
    h = mesh.find_halfedge(vs[2], vs[3])
    with pytest.raises(Rollback):
        with store.transaction():
            v = run(mesh, "split_edge", mesh.find_halfedge(vs[0], vs[2]).edge)
            assert v["w"] == mean(vs[0]["w"], vs[2]["w"])
            run(mesh, "collapse_edge", h)
            run(mesh, "poke_polygon", next(mesh.polygons()))
            assert mesh.check() == []
            raise Rollback
    assert dump(store) == before and mesh.revision == rev
    assert vertex_values(vs[2]) == (20.0, (2.0, 4.0, 6.0), 102, "v2")
    assert mesh.check() == []
    # a savepoint rolled back inside a block that commits
    with store.transaction():
        with pytest.raises(Rollback):
            with store.transaction():
                run(mesh, "flip_edge", h.edge)
                raise Rollback
        assert dump(store) == before
        v = run(mesh, "split_edge", h.edge)
    assert mesh.revision == rev + 1 and v["k"] == h.edge.vertices()[0]["k"]
    assert mesh.check() == []


def test_refusals_leave_property_values_alone(store):
    """Refusals on meshes with values: the value tables are part of the unchanged dump, also mid-block."""
    mesh = store.create_mesh("m")
    vs, ps = valued(mesh, 6, STRIP, STRIP_XY)
    rim = mesh.find_halfedge(vs[0], vs[1]).edge
    inner = mesh.find_halfedge(vs[2], vs[3])
    refuse(mesh, "flip_edge", rim, reason="boundary", names=(rim,))
    refuse(mesh, "join_polygons", rim, reason="boundary", names=(rim,))
    refuse(mesh, "split_polygon", inner.polygon, inner.origin, inner.target, reason="adjacent-corners",
           names=(inner.polygon,), elements=(inner.polygon, inner))
    refuse(mesh, "heal_edges", rim, inner.edge, reason="not-adjacent", names=(rim, inner.edge))
    refuse(mesh, "fill_hole", inner, exc=HalfEdgeNotFreeError, names=(inner,))
    u, w = mesh.add_vertex(), mesh.add_vertex()
    twice = mesh.add_edge(u, w)
    twice["cost"] = 7.0
    mesh.add_edge(w, u)
    refuse(mesh, "collapse_edge", halfedge_from(twice, u), reason="link-condition", names=(u, w))
    strict = store.create_mesh("strict", allow_loops=False, allow_multi_edges=False)
    declare(strict)
    v, others, r = figure_eight(strict)
    r["label"] = "eight"
    for h in r.halfedges():
        h["uv"] = (float(h.id), 0.5)
    v["w"] = 3.0
    refuse(strict, "poke_polygon", r, exc=PolicyError, names=(r, v))
    refuse(strict, "triangulate_polygon", r, exc=PolicyError, names=(v,))
    # a refusal after an operator in the same block keeps the operator's derived values
    a, b = inner.edge.vertices()
    with store.transaction():
        x = run(mesh, "split_edge", inner.edge)
        pending = dump(store)
        with pytest.raises(EulerError):
            mesh.flip_edge(rim)
        assert dump(store) == pending
        assert x["w"] == mean(a["w"], b["w"]) == 25.0
    assert (x["w"], x["tag"]) == (25.0, a["tag"])
    assert mesh.check() == [] and strict.check() == []


def test_set_property_array_then_an_operator_in_the_same_block(store, mesh):
    vs, ps = valued(mesh, 6, STRIP, STRIP_XY)
    e = mesh.find_halfedge(vs[2], vs[3]).edge
    a, b = e.vertices()
    P = e.halfedge.polygon
    ha, hb = corner(P, a), corner(P, b)
    with store.transaction():
        mesh.set_property_array("vertex", "w", [a, b], np.array([1.0, 4.0]))
        mesh.set_property_array("vertex", "n", [a, b], np.array([[1.0, 1.0, 1.0], [3.0, 5.0, 7.0]]))
        mesh.set_property_array("halfedge", "uv", [ha, hb], np.array([[0.0, 0.0], [1.0, 2.0]]))
        mesh.set_property_array("edge", "cost", [e], np.array([42.0]))
        v = run(mesh, "split_edge", e)
        assert (v["w"], v["n"]) == (2.5, (2.0, 3.0, 4.0))
        assert corner(P, v)["uv"] == (0.5, 1.0)
        # the bulk write then the operator then another bulk write to the new elements
        mesh.set_property_array("vertex", "w", [v], np.array([-1.0]))
        (new,) = [x for x in v.edges() if x != e]
        assert new["cost"] == 42.0
        x = run(mesh, "split_edge", new)
        assert x["w"] == mean(-1.0, b["w"])
    assert (v["w"], v["n"], new["cost"], x["w"]) == (-1.0, (2.0, 3.0, 4.0), 42.0, 1.5)
    assert corner(P, v)["uv"] == (0.5, 1.0)
    assert mesh.check() == []


# --------------------------------------------------------------------------
# A real mesh under a few hundred random operators, in one transaction


def _delta(op: str, target) -> tuple[int, int, int]:
    """The known (ΔV, ΔE, ΔF) of an operator about to succeed, from the mesh before it."""
    name, args, kwargs = op, target[0], target[1]
    if name == "split_edge":
        e = args[0]
        k = sum(1 for h in e.halfedges() if h.polygon is not None and h.polygon.degree == 3)
        return (1, 1 + k, k) if kwargs.get("triangulate") else (1, 1, 0)
    if name == "split_polygon":
        return 0, 1, 1
    if name == "join_polygons":
        return 0, -1, -1
    if name == "poke_polygon":
        d = args[0].degree
        return 1, d, d - 1
    if name == "flip_edge":
        return 0, 0, 0
    if name == "collapse_edge":
        h = args[0]
        k = sum(1 for x in (h, h.twin) if x.polygon is not None and x.polygon.degree == 3)
        return -1, -1 - k, -k
    if name == "heal_edges":
        return -1, -1, 0
    if name == "fill_hole":
        return 0, 0, 1
    if name == "triangulate_polygon":
        d = args[0].degree
        return (0, d - 3, d - 3) if d > 3 else (0, 0, 0)
    raise AssertionError(name)


def _pick(rng: random.Random, mesh: hestore.Mesh, ids: dict, kind: str):
    """A live element of ``kind``, drawn from the ids seen so far (removed ones are dropped)."""
    lookup = {"vertex": mesh.vertex, "halfedge": mesh.halfedge, "edge": mesh.edge, "polygon": mesh.polygon}[kind]
    pool = ids[kind]
    while True:
        i = rng.randrange(pool["next"])
        if i in pool["gone"]:
            continue
        try:
            return lookup(i)
        except ElementNotFoundError:
            pool["gone"].add(i)


def _random_request(rng: random.Random, mesh: hestore.Mesh, ids: dict):
    """``(operator, args, kwargs)``, drawn with weights that keep the mesh mostly triangles."""
    op = rng.choices(
        ["split_edge", "split_polygon", "join_polygons", "poke_polygon", "flip_edge", "collapse_edge",
         "heal_edges", "fill_hole", "triangulate_polygon"],
        weights=[3, 2, 1, 1, 4, 5, 1, 1, 2],
    )[0]
    if op in ("split_edge", "join_polygons", "flip_edge"):
        e = _pick(rng, mesh, ids, "edge")
        return op, (e,), ({"triangulate": rng.random() < 0.6} if op == "split_edge" else {})
    if op in ("poke_polygon", "triangulate_polygon"):
        return op, (_pick(rng, mesh, ids, "polygon"),), {}
    if op == "split_polygon":
        for _ in range(10):  # prefer a polygon that can be cut: most are triangles
            p = _pick(rng, mesh, ids, "polygon")
            if p.degree > 3:
                break
        hs = p.halfedges()
        a, b = rng.choice(hs), rng.choice(hs)
        # corners as half-edges (always unambiguous) or as vertices
        return op, (p, *(x if rng.random() < 0.5 else x.origin for x in (a, b))), {}
    if op in ("collapse_edge", "fill_hole"):
        return op, (_pick(rng, mesh, ids, "halfedge"),), {}
    # heal: mostly at a vertex an edge split made, whose degree may still be 2
    recent = [x for x in ids["split"] if x.id not in ids["vertex"]["gone"]]
    v = rng.choice(recent) if recent and rng.random() < 0.7 else _pick(rng, mesh, ids, "vertex")
    try:
        edges = v.edges()
    except ElementNotFoundError:
        ids["vertex"]["gone"].add(v.id)
        edges = []
    if len(edges) >= 2 and rng.random() < 0.8:
        e1, e2 = rng.sample(edges, 2)
    else:
        e1, e2 = _pick(rng, mesh, ids, "edge"), _pick(rng, mesh, ids, "edge")
    return op, (e1, e2), {}


def _note_new(ids: dict, result) -> None:
    """Widen the id ranges to the elements an operator made."""
    for x in result if isinstance(result, list) else [result]:
        kinds = [x.kind] + (["halfedge"] if x.kind == "edge" else [])
        for kind in kinds:
            top = 2 * x.id + 2 if kind == "halfedge" else x.id + 1
            ids[kind]["next"] = max(ids[kind]["next"], top)


@pytest.mark.parametrize("corpus_file", corpus_files(only=["sphere840.ply"]))
def test_random_operators_on_a_real_closed_mesh(corpus, corpus_file):
    mesh = corpus.copy(corpus_file)  # the corpus's import of the scan, the test's own to edit
    store = mesh.store
    declare(mesh)
    start = vef(mesh)
    assert start == (422, 1260, 840) and mesh.stats().is_closed
    ids = {
        "vertex": {"next": start[0], "gone": set()},
        "edge": {"next": start[1], "gone": set()},
        "halfedge": {"next": 2 * start[1], "gone": set()},
        "polygon": {"next": start[2], "gone": set()},
        "split": [],
    }
    rng = random.Random(20240610)
    rev = mesh.revision
    expected = list(start)
    done: dict[str, int] = {}
    refused: dict[str, int] = {}
    t0 = time.process_time()  # this process's: a busy machine does not add to it
    with store.transaction():
        for _ in range(400):
            op, args, kwargs = _random_request(rng, mesh, ids)
            try:
                answer = getattr(mesh, f"can_{op}")(*args)
            except InvalidInputError:
                # a vertex that is two corners of the polygon: the operator refuses it the same way
                with pytest.raises(InvalidInputError):
                    getattr(mesh, op)(*args, **kwargs)
                refused[op] = refused.get(op, 0) + 1
                continue
            if not answer:
                counts = mesh.counts()
                with pytest.raises(TopologyError):
                    getattr(mesh, op)(*args, **kwargs)
                assert mesh.counts() == counts
                refused[op] = refused.get(op, 0) + 1
                continue
            delta = _delta(op, (args, kwargs))
            result = getattr(mesh, op)(*args, **kwargs)
            _note_new(ids, result)
            if op == "split_edge":
                _note_new(ids, [x for x in result.edges()] + [p for p in result.polygons()])
                ids["split"].append(result)
            elif op == "poke_polygon":
                _note_new(ids, result.edges() + result.polygons())
            elif op == "split_polygon":
                _note_new(ids, result.polygons())
            expected = [x + d for x, d in zip(expected, delta)]
            done[op] = done.get(op, 0) + 1
            assert list(vef(mesh)) == expected, f"{op}{args}: {vef(mesh)} != {expected}"
        assert mesh.check() == []
    elapsed = time.process_time() - t0
    assert mesh.revision == rev + 1
    assert mesh.check() == []
    v, e, f = vef(mesh)
    assert [v, e, f] == expected
    fills = done.get("fill_hole", 0)
    assert v - e + f == 2 + fills == mesh.stats().euler_characteristic
    # the run did exercise the operators, and their refusals
    assert sum(done.values()) >= 100 and len(done) >= 6, done
    assert sum(refused.values()) >= 30, refused
    assert elapsed < 120, f"400 operators took {elapsed:.1f} s of processor time"
