"""Topological summaries: `Mesh.stats`, `Mesh.boundary_loops`, `Mesh.components`.

Hand-made hard cases check every field against values worked out by hand and,
for every case, against `walked`, a second computation that walks the stored
structure one handle at a time (the navigation API, not `hestore.summary`'s
numpy) with networkx for the components.

`test_shared_meshes` reads every file in the shared meshes folder, as the
corpus imported it (``conftest.corpus``), and checks the figures against a
computation from the polygons that were stored (`mesh.to_arrays()`), written
here in plain Python with networkx for the components, and against facts
known about the files.
"""

from __future__ import annotations

import json
import math
from collections import Counter

import networkx as nx
import numpy as np
import pytest

import hestore
from hestore import MeshNotFoundError, Stats
from hestore.arrays import cycle_positions as _cycle_positions
from hestore.arrays import component_roots

from helpers import OCTAHEDRON, OCTAHEDRON_POSITIONS, TETRAHEDRON, build_faces, grid
from meshes import corpus_files


# -- the second computation, through handles ------------------------------------------


def free_cycles(halfedges) -> list[list[hestore.HalfEdge]]:
    """The cycles of ``next`` through the given free half-edges, walked one handle at a time."""
    seen, cycles = set(), []
    for start in sorted(halfedges, key=lambda h: h.id):
        if start in seen:
            continue
        cycle, h = [], start
        while h not in seen:
            seen.add(h)
            cycle.append(h)
            h = h.next
        assert h == start, f"walking next from {start} does not come back to it"
        cycles.append(cycle)
    return cycles


def fans(v: hestore.Vertex) -> int:
    """Fans at ``v``: runs of polygon corners in the counter-clockwise order of its outgoing half-edges.

    Two corners next to each other in that order share the edge between them
    exactly when both outgoing half-edges have a polygon.
    """
    has = [h.polygon is not None for h in v.outgoing()]
    if has and all(has):
        return 1
    return sum(1 for i, x in enumerate(has) if x and not has[i - 1])


def walked(mesh: hestore.Mesh) -> Stats:
    """Every `Stats` field, from handles (small meshes only)."""
    vertices, halfedges = list(mesh.vertices()), list(mesh.halfedges())
    edges, polygons = list(mesh.edges()), list(mesh.polygons())
    pairs = [tuple(sorted(v.id for v in e.vertices())) for e in edges]
    free_sides = [sum(h.polygon is None for h in e.halfedges()) for e in edges]
    free = [h for h in halfedges if h.polygon is None]
    graph = nx.Graph()
    graph.add_nodes_from(v.id for v in vertices)
    graph.add_edges_from(pairs)
    isolated = sum(v.is_isolated for v in vertices)
    b = len(free_cycles(free))
    c = nx.number_connected_components(graph)
    chi = len(vertices) - len(edges) + len(polygons)
    wire = free_sides.count(2)
    pinched = sum(fans(v) > 1 for v in vertices)
    genus = None if wire or pinched else (2 * (c - isolated) - (chi - isolated) - b) // 2
    return Stats(
        vertices=len(vertices),
        isolated_vertices=isolated,
        edges=len(edges),
        loops=sum(a == z for a, z in pairs),
        parallel_edges=len(pairs) - len(set(pairs)),
        halfedges=len(halfedges),
        polygons=len(polygons),
        polygon_sizes=dict(sorted(Counter(p.degree for p in polygons).items())),
        boundary_edges=free_sides.count(1),
        wire_edges=wire,
        boundary_loops=b,
        components=c,
        euler_characteristic=chi,
        genus=genus,
        pinched_vertices=pinched,
        is_closed=not free,
        is_manifold=not pinched and not wire,
    )


def assert_loops_well_formed(mesh: hestore.Mesh, loops, free=None) -> None:
    """Each loop free and in ``next`` order from its smallest id; loops sorted; all free half-edges once.

    ``free``: the mesh's free half-edges, if known (else every half-edge is asked).
    """
    for loop in loops:
        assert loop[0].id == min(h.id for h in loop)
        for i, h in enumerate(loop):
            assert h.polygon is None
            assert h.next == loop[(i + 1) % len(loop)]
    firsts = [loop[0].id for loop in loops]
    assert firsts == sorted(firsts)
    listed = [h for loop in loops for h in loop]
    assert len(listed) == len(set(listed))
    if free is None:
        free = [h for h in mesh.halfedges() if h.polygon is None]
    assert set(listed) == set(free)


def summarise(mesh: hestore.Mesh, **expected) -> Stats:
    """``mesh.stats()``, checked against ``expected``, `walked`, and the other two summaries."""
    s = mesh.stats()
    for field, value in expected.items():
        assert getattr(s, field) == value, f"{field}: {getattr(s, field)!r}, expected {value!r}"
    assert s == walked(mesh)
    loops = mesh.boundary_loops()
    assert_loops_well_formed(mesh, loops)
    assert len(loops) == s.boundary_loops
    parts = mesh.components()
    assert len(parts) == s.components
    graph = nx.Graph()
    graph.add_nodes_from(mesh.vertices())
    graph.add_edges_from(e.vertices() for e in mesh.edges())
    assert sorted(map(frozenset, parts), key=lambda p: min(v.id for v in p)) == [frozenset(p) for p in parts]
    assert {frozenset(p) for p in parts} == {frozenset(p) for p in nx.connected_components(graph)}
    assert all(isinstance(v, hestore.Vertex) and v.mesh == mesh for p in parts for v in p)
    json.dumps(s.as_dict())
    assert s.halfedges == 2 * s.edges and s.euler_characteristic == s.vertices - s.edges + s.polygons
    return s


# -- hand-made cases ------------------------------------------------------------------


def test_empty_mesh(mesh):
    # Closed: no free half-edge, vacuously. Genus 0: the sum over no surface.
    s = summarise(
        mesh, vertices=0, isolated_vertices=0, edges=0, halfedges=0, polygons=0, polygon_sizes={},
        boundary_edges=0, wire_edges=0, boundary_loops=0, components=0, euler_characteristic=0,
        genus=0, pinched_vertices=0, is_closed=True, is_manifold=True,
    )
    assert s.as_dict() == {f: getattr(s, f) for f in Stats.__dataclass_fields__}
    assert mesh.boundary_loops() == [] and mesh.components() == []


def test_isolated_vertices_only(mesh):
    vs = [mesh.add_vertex() for _ in range(3)]
    summarise(
        mesh, vertices=3, isolated_vertices=3, edges=0, components=3, euler_characteristic=3,
        genus=0, boundary_loops=0, is_closed=True, is_manifold=True,
    )
    assert mesh.components() == [{v} for v in vs]


def test_wireframe_with_loops_and_parallel_edges(mesh):
    a, b, c, d = (mesh.add_vertex() for _ in range(4))
    mesh.add_edge(a, b)
    mesh.add_edge(b, a)  # parallel to a-b, the other way round
    mesh.add_edge(b, c)
    mesh.add_edge(c, c)
    mesh.add_edge(c, c)  # two self-loops at one vertex: one of them is parallel
    summarise(
        mesh, vertices=4, isolated_vertices=1, edges=5, loops=2, parallel_edges=2, halfedges=10,
        polygons=0, polygon_sizes={}, boundary_edges=0, wire_edges=5, components=2,
        euler_characteristic=-1, genus=None, pinched_vertices=0, is_closed=False, is_manifold=False,
    )
    assert mesh.components() == [{a, b, c}, {d}]


def test_lone_wire_edge_and_lone_self_loop(mesh):
    a, b, c = (mesh.add_vertex() for _ in range(3))
    mesh.add_edge(a, b)
    loop = mesh.add_edge(c, c)
    # a lone edge: its two half-edges are each other's next, one cycle;
    # a lone self-loop: each half-edge is its own next, two cycles
    summarise(mesh, wire_edges=2, loops=1, boundary_loops=3, components=2, genus=None)
    assert [len(x) for x in mesh.boundary_loops()] == [2, 1, 1]
    assert [x[0] for x in mesh.boundary_loops()[1:]] == list(loop.halfedges())


def test_one_gon_on_a_loop(mesh):
    v = mesh.add_vertex()
    p = mesh.add_polygon([v])
    summarise(
        mesh, vertices=1, edges=1, loops=1, polygons=1, polygon_sizes={1: 1}, boundary_edges=1,
        wire_edges=0, boundary_loops=1, components=1, euler_characteristic=1, genus=0,
        pinched_vertices=0, is_closed=False, is_manifold=True,
    )
    # a 1-gon on each side of the loop: a sphere
    mesh.add_polygon([p.halfedge.twin])
    summarise(
        mesh, polygons=2, polygon_sizes={1: 2}, boundary_edges=0, boundary_loops=0,
        euler_characteristic=2, genus=0, is_closed=True, is_manifold=True,
    )


def test_two_gon_on_parallel_edges(mesh):
    a, b = mesh.add_vertex(), mesh.add_vertex()
    e1, e2 = mesh.add_edge(a, b), mesh.add_edge(a, b)
    mesh.add_polygon([e1.halfedges()[0], e2.halfedges()[1]])
    summarise(
        mesh, vertices=2, edges=2, parallel_edges=1, loops=0, polygons=1, polygon_sizes={2: 1},
        boundary_edges=2, wire_edges=0, boundary_loops=1, euler_characteristic=1, genus=0,
        is_manifold=True,
    )
    assert [len(x) for x in mesh.boundary_loops()] == [2]


def test_polygon_adjacent_to_itself(mesh):
    # a quad a→a→b→b: the square with its left and right sides glued, a cylinder
    # whose two boundary circles are the self-loops
    a, b = mesh.add_vertex(), mesh.add_vertex()
    p = mesh.add_polygon([a, a, b, b])
    assert set(p.neighbors()) == {p}
    summarise(
        mesh, vertices=2, edges=3, loops=2, polygons=1, polygon_sizes={4: 1}, boundary_edges=2,
        wire_edges=0, boundary_loops=2, components=1, euler_characteristic=0, genus=0,
        pinched_vertices=0, is_closed=False, is_manifold=True,
    )
    # a→b→c→b: both edges run twice through the one polygon, a closed "pillow"
    other = mesh.store.create_mesh("pillow")
    x, y, z = (other.add_vertex() for _ in range(3))
    other.add_polygon([x, y, z, y])
    summarise(
        other, vertices=3, edges=2, polygons=1, polygon_sizes={4: 1}, boundary_edges=0,
        boundary_loops=0, euler_characteristic=2, genus=0, is_closed=True, is_manifold=True,
    )


def test_two_triangles_sharing_only_a_vertex_are_pinched(mesh):
    c = mesh.add_vertex((0, 0, 0))
    a, b, d, e = (mesh.add_vertex(p) for p in [(1, 0, 0), (1, 1, 0), (-1, 0, 0), (-1, -1, 0)])
    mesh.add_polygon([c, a, b])
    mesh.add_polygon([c, d, e])
    s = summarise(
        mesh, vertices=5, edges=6, polygons=2, boundary_edges=6, wire_edges=0, components=1,
        euler_characteristic=1, pinched_vertices=1, genus=None, is_closed=False, is_manifold=False,
    )
    assert fans(c) == 2
    assert s.boundary_loops == len(free_cycles([h for h in mesh.halfedges() if h.is_boundary]))


def test_wire_edges_at_a_fan_do_not_pinch_but_two_fans_do(mesh):
    c = mesh.add_vertex((0, 0, 0))
    a, b = mesh.add_vertex((1, 0, 0)), mesh.add_vertex((1, 1, 0))
    mesh.add_polygon([c, a, b])
    tail = mesh.add_vertex((-1, 0, 0))
    mesh.add_edge(c, tail)
    summarise(mesh, wire_edges=1, pinched_vertices=0, is_manifold=False, genus=None, components=1)
    d, e = mesh.add_vertex((-1, -1, 0)), mesh.add_vertex((0, -1, 0))
    mesh.add_polygon([c, d, e])
    summarise(mesh, wire_edges=1, pinched_vertices=1, is_manifold=False, genus=None)


def test_several_components(mesh):
    _, triangle = build_faces(mesh, 3, [(0, 1, 2)])
    quad = [mesh.add_vertex() for _ in range(4)]
    mesh.add_polygon(quad)
    lone = mesh.add_vertex()
    x, y = mesh.add_vertex(), mesh.add_vertex()
    mesh.add_edge(x, y)
    s = summarise(
        mesh, vertices=10, isolated_vertices=1, edges=8, polygons=2, polygon_sizes={3: 1, 4: 1},
        boundary_edges=7, wire_edges=1, boundary_loops=3, components=4, genus=None,
    )
    assert s.euler_characteristic == 10 - 8 + 2
    triangle_vertices = set(triangle[0].vertices())
    assert mesh.components() == [triangle_vertices, set(quad), {lone}, {x, y}]


def test_disc(mesh):
    grid(mesh, 3)
    summarise(
        mesh, vertices=16, edges=24, polygons=9, polygon_sizes={4: 9}, boundary_edges=12,
        boundary_loops=1, components=1, euler_characteristic=1, genus=0, pinched_vertices=0,
        is_closed=False, is_manifold=True,
    )
    [loop] = mesh.boundary_loops()
    assert len(loop) == 12 and loop[0].id == min(h.id for h in loop)


@pytest.mark.parametrize(
    "faces, positions, counts",
    [(TETRAHEDRON, None, (4, 6, 4)), (OCTAHEDRON, OCTAHEDRON_POSITIONS, (6, 12, 8))],
    ids=["tetrahedron", "octahedron"],
)
def test_closed_polyhedra_have_genus_zero(mesh, faces, positions, counts):
    build_faces(mesh, counts[0], faces, positions)
    summarise(
        mesh, vertices=counts[0], edges=counts[1], polygons=counts[2], boundary_edges=0,
        boundary_loops=0, components=1, euler_characteristic=2, genus=0, is_closed=True,
        is_manifold=True,
    )
    assert mesh.boundary_loops() == []


def torus(n: int = 4, m: int = 4):
    """An ``n`` × ``m`` quad torus: positions and counter-clockwise quads."""
    positions = [
        ((2 + math.cos(2 * math.pi * j / m)) * math.cos(2 * math.pi * i / n),
         (2 + math.cos(2 * math.pi * j / m)) * math.sin(2 * math.pi * i / n),
         math.sin(2 * math.pi * j / m))
        for i in range(n) for j in range(m)
    ]
    at = lambda i, j: (i % n) * m + (j % m)  # noqa: E731
    quads = [[at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)] for i in range(n) for j in range(m)]
    return positions, quads


def test_torus_has_genus_one(store):
    mesh = store.import_arrays("torus", *torus()).mesh
    summarise(
        mesh, vertices=16, edges=32, polygons=16, polygon_sizes={4: 16}, boundary_loops=0,
        components=1, euler_characteristic=0, genus=1, is_closed=True, is_manifold=True,
    )


def quad_grid(n: int, holes=()):
    """An ``n`` × ``n`` grid of quads as arrays, leaving out the cells in ``holes``."""
    positions = [(i, j, 0) for j in range(n + 1) for i in range(n + 1)]
    at = lambda i, j: j * (n + 1) + i  # noqa: E731
    quads = [
        [at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)]
        for j in range(n) for i in range(n) if (i, j) not in holes
    ]
    return positions, quads


def test_mesh_with_holes(store):
    mesh = store.import_arrays("holes", *quad_grid(5, holes={(1, 1), (3, 3)})).mesh
    summarise(
        mesh, vertices=36, edges=60, polygons=23, boundary_edges=28, boundary_loops=3,
        components=1, euler_characteristic=-1, genus=0, pinched_vertices=0, is_manifold=True,
    )
    loops = mesh.boundary_loops()
    assert sorted(len(x) for x in loops) == [4, 4, 20]


def test_holes_meeting_at_a_corner_pinch_it(store):
    mesh = store.import_arrays("corner", *quad_grid(4, holes={(1, 1), (2, 2)})).mesh
    summarise(mesh, pinched_vertices=1, genus=None, is_manifold=False, components=1)


def test_ids_with_gaps_after_edits(mesh):
    V, Q = grid(mesh, 4)
    mesh.remove_vertex(V[0][0])
    mesh.remove_edge(mesh.find_halfedge(V[2][2], V[2][3]).edge)  # two quads become a hole
    mesh.remove_polygon(Q[3][0])
    extra = mesh.add_vertex()
    mesh.remove_vertex(V[4][4])  # its quad goes too: the hole now meets it at V[3][3]
    summarise(
        mesh, vertices=24, isolated_vertices=1, polygons=11, components=2,
        pinched_vertices=1, genus=None,
    )
    assert fans(V[3][3]) == 2
    assert {extra} in mesh.components()


def test_stats_inside_a_transaction_block_see_its_edits(store, mesh):
    a, b, c = (mesh.add_vertex() for _ in range(3))
    mesh.add_polygon([a, b, c])
    before = mesh.stats()
    with store.transaction():
        d = mesh.add_vertex()
        mesh.add_polygon([a, c, d])
        inside = summarise(mesh, vertices=4, polygons=2, edges=5, boundary_loops=1)
        assert inside != before
        assert len(mesh.boundary_loops()[0]) == 4
    assert mesh.stats() == inside
    with pytest.raises(RuntimeError):
        with store.transaction():
            mesh.add_vertex()
            assert mesh.stats().components == 2
            raise RuntimeError("roll back")
    assert mesh.stats() == inside


def test_deleted_mesh_raises(store, mesh):
    mesh.add_polygon([mesh.add_vertex() for _ in range(3)])
    store.delete_mesh("m")
    for summary in (mesh.stats, mesh.boundary_loops, mesh.components):
        with pytest.raises(MeshNotFoundError):
            summary()


def test_stats_is_exported_frozen_and_hashable(mesh):
    s = mesh.stats()
    assert isinstance(s, hestore.Stats)
    with pytest.raises(AttributeError):
        s.vertices = 1
    mesh.add_polygon([mesh.add_vertex() for _ in range(3)])
    assert len({s, mesh.stats(), mesh.stats()}) == 2


# -- the numpy building blocks, against plain Python -----------------------------------


def test_component_roots_match_networkx():
    rng = np.random.default_rng(7)
    for n, m in [(1, 0), (2, 1), (50, 30), (400, 380), (400, 1200), (2000, 1990)]:
        u, w = rng.integers(0, n, m), rng.integers(0, n, m)
        roots = component_roots(n, u, w)
        graph = nx.Graph()
        graph.add_nodes_from(range(n))
        graph.add_edges_from(zip(u.tolist(), w.tolist()))
        for part in nx.connected_components(graph):
            assert set(roots[list(part)].tolist()) == {min(part)}


def test_component_roots_on_a_path_labelled_in_the_worst_order():
    # a long path whose vertex numbers zigzag: min-label propagation alone
    # would need a round per vertex; hooking and pointer jumping do not
    n = 20001
    order = np.r_[np.arange(0, n, 2), np.arange(1, n, 2)[::-1]]
    roots = component_roots(n, order[:-1], order[1:])
    assert (roots == 0).all()


def test_cycle_positions():
    f = np.array([3, 0, 4, 5, 2, 1])  # cycles 0→3→5→1→0 and 2→4→2
    label = np.array([0, 0, 2, 0, 2, 0])
    assert _cycle_positions(f, label).tolist() == [0, 3, 0, 1, 1, 2]


# -- the shared meshes, against an independent computation ------------------------------

#: Facts about the shared files, from their manifest and their names.
KNOWN = {
    "3torus.off": {"genus": 3, "is_closed": True},
    "torus_quad.off": {"genus": 1, "is_closed": True},
    "knot2.off": {"components": 2, "is_closed": True},
    "blobby_3cc.off": {"components": 3},
    "platonic_shelf.obj": {"components": 5, "genus": 0, "is_closed": True},
}

#: Files the manifest calls closed.
CLOSED = {
    "3torus.off", "bob_small.ply", "cheese.off", "cube1.off", "cube_poly.off", "dodecahedron_poly.obj",
    "eight.off", "igea-subdiv1.ply", "knot2.off", "platonic_shelf.obj", "quadknot.obj", "sphere840.ply",
    "spot.obj", "torus_quad.off",
}

BIG = 1_000_000  # bytes: bigger files only on SQLite, to save time


def reference(arrays) -> dict:
    """The figures, computed from the stored polygons alone, in plain Python and networkx.

    An edge is an unordered pair of vertices that consecutive corners of some
    polygon join (a stored import has no parallel edges, and a self-loop is
    the pair ``(a, a)``); a boundary edge is one that polygons use on one
    side only; its free half-edge runs against the polygon's direction.
    """
    n = len(arrays.vertex_ids)
    polygons = arrays.polygons.tolist() if isinstance(arrays.polygons, np.ndarray) else arrays.polygons
    sides = Counter()
    for loop in polygons:
        for a, b in zip(loop, loop[1:] + loop[:1]):
            sides[a, b] += 1
    used = Counter()
    for (a, b), k in sides.items():
        used[min(a, b), max(a, b)] += k
    boundary = [(a, b) for (a, b) in sides if used[min(a, b), max(a, b)] == 1]
    graph = nx.Graph()
    graph.add_nodes_from(range(n))
    graph.add_edges_from(used)
    isolated = n - len({v for loop in polygons for v in loop})
    # A stored mesh has no wire edges, and no closed fan meets anything else
    # at a vertex (imports refuse that); so a vertex has as many fans as
    # boundary edges leave it, and is pinched when more than one does.
    leaving = Counter(a for a, _ in boundary)
    pinched = sum(1 for k in leaving.values() if k > 1)
    out = {
        "vertices": n,
        "isolated_vertices": isolated,
        "edges": len(used),
        "loops": sum(1 for a, b in used if a == b),
        "polygons": len(polygons),
        "boundary_edges": len(boundary),
        "components": nx.number_connected_components(graph),
        "euler_characteristic": n - len(used) + len(polygons),
        "pinched_vertices": pinched,
        "is_closed": not boundary,
        "parts": {frozenset(arrays.vertex_ids[list(p)].tolist()) for p in nx.connected_components(graph)},
        "boundary": boundary,
    }
    if not pinched:
        # Without pinched vertices one boundary edge leaves each boundary
        # vertex, so following "the boundary edge leaving my target" is
        # unambiguous and its cycles are the boundary loops (run backwards).
        # At a pinched vertex it is the structure that decides which fan's
        # boundary continues which; those files are compared against a walk
        # along the stored `next` instead (`test_shared_meshes`).
        after = dict(boundary)
        seen, loops = set(), 0
        for start in after:
            if start in seen:
                continue
            loops += 1
            v = start
            while v not in seen:
                seen.add(v)
                v = after[v]
        out["boundary_loops"] = loops
        c, chi = out["components"] - isolated, out["euler_characteristic"] - isolated
        out["genus"] = (2 * c - chi - loops) // 2
    else:
        out["genus"] = None
    return out


#: The backends and files of `test_shared_meshes`: every file on SQLite, the files up to `BIG` on PostgreSQL.
SUMMARY_CASES = corpus_files(backend="sqlite") + corpus_files(max_bytes=BIG, backend="postgresql")


@pytest.mark.parametrize("backend, corpus_file", SUMMARY_CASES, indirect=["backend"])
def test_shared_meshes(corpus, backend, corpus_file):
    """The shared file, as the corpus imported it (``on_error="skip"`` where ``"raise"`` refuses), against
    `reference` and `KNOWN`.

    The independent computation is plain Python over the polygons
    `Mesh.to_arrays` gives back, with networkx's ``connected_components`` for
    the components.
    """
    mesh = corpus.mesh(corpus_file)
    s = mesh.stats()
    arrays = mesh.to_arrays()
    ref = reference(arrays)
    for field in (
        "vertices", "isolated_vertices", "edges", "loops", "polygons", "boundary_edges", "components",
        "euler_characteristic", "pinched_vertices", "is_closed", "genus",
    ):
        assert getattr(s, field) == ref[field], (corpus_file, field, getattr(s, field), ref[field])
    assert s.parallel_edges == s.wire_edges == 0, corpus_file
    assert s.halfedges == 2 * s.edges and sum(s.polygon_sizes.values()) == s.polygons
    assert s.is_manifold == (not ref["pinched_vertices"]), corpus_file
    loops = mesh.boundary_loops()
    assert sum(len(x) for x in loops) == s.boundary_edges, corpus_file
    if "boundary_loops" in ref:
        assert s.boundary_loops == ref["boundary_loops"] == len(loops), corpus_file
    if s.boundary_edges <= 2000:
        # the free half-edges, found from the polygon side of each boundary edge
        vertex = lambda row: hestore.Vertex(mesh, arrays.vertex_ids[row])  # noqa: E731
        free = [mesh.find_halfedge(vertex(b), vertex(a)) for a, b in ref["boundary"]]
        assert all(h.is_boundary for h in free)
        assert_loops_well_formed(mesh, loops, free)
        assert s.boundary_loops == len(free_cycles(free)), corpus_file
    else:
        assert "boundary_loops" in ref, f"{corpus_file}: compare its pinched boundary some other way"
    parts = mesh.components()
    assert {frozenset(v.id for v in p) for p in parts} == ref["parts"], corpus_file
    assert [min(v.id for v in p) for p in parts] == sorted(min(p) for p in ref["parts"])
    for field, value in KNOWN.get(corpus_file, {}).items():
        assert getattr(s, field) == value, (corpus_file, field)
    if corpus_file in CLOSED:
        assert s.is_closed and s.boundary_loops == 0 and loops == [], corpus_file
