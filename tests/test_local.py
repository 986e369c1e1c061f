"""Local graph queries (SPEC §6): `Mesh.k_ring`, `Mesh.shortest_path`, `Mesh.to_networkx(kind, vertices=...)`.

Every answer is checked against networkx on the whole multigraph of the same
state, on both backends: shared meshes, hand-built wireframes with self-loops,
parallel edges, isolated vertices and several components, random small meshes
(hypothesis), an open block's uncommitted edits and views of the past. Then the
typed errors, and the ``graph … path`` / ``graph … neighbors`` commands.
"""

from __future__ import annotations

import math
import pathlib
import random
import re

import networkx as nx
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import hestore
from hestore import graphs
from helpers import STORED, dump, grid, run
from meshes import require_shared_meshes

#: Small and medium shared meshes: components, boundaries, pinched vertices, mixed arities, handles.
SHARED = ("blobby_3cc.off", "knot2.off", "hole_capsule.off", "teapot.obj", "platonic_shelf.obj", "sphere840.ply")

VERTEX_KINDS = ("multigraph", "graph", "halfedge")


# -- networkx, the reference ----------------------------------------------------------


def lightest(u, v, keydict) -> float:
    """The weight function of ``hestore graph … path --weight length``: the lightest parallel edge."""
    return min(d["length"] for d in keydict.values())


def lightest_by(weight: str):
    """The weight function of ``mesh.shortest_path(a, b, weight)`` (``"length"`` or an edge property)."""
    return lightest if weight == "length" else lambda u, v, keydict: min(d[weight] for d in keydict.values())


def reference(mesh: hestore.Mesh) -> nx.MultiGraph:
    """The whole multigraph with lengths, of the state the queries read (a copy: it may be edited)."""
    return nx.MultiGraph(mesh.to_networkx("multigraph", attrs=["length"]))


def path_length(G: nx.MultiGraph, path: list[int], weight: str | None) -> float:
    if weight is None:
        return len(path) - 1
    return sum(lightest_by(weight)(u, v, G[u][v]) for u, v in zip(path, path[1:]))


def check_path(mesh, G, a: int, b: int, weight: str | None) -> list[int] | None:
    """Compare ``mesh.shortest_path`` with networkx for one pair; returns the path's ids (None: no path)."""
    try:
        expected = nx.shortest_path_length(G, a, b, weight=None if weight is None else lightest_by(weight))
    except nx.NetworkXNoPath:
        with pytest.raises(hestore.NoPathError) as info:
            mesh.shortest_path(mesh.vertex(a), mesh.vertex(b), weight=weight)
        message = str(info.value)
        assert f"vertex {a}" in message and f"vertex {b}" in message and repr(mesh.name) in message
        return None
    path = mesh.shortest_path(mesh.vertex(a), mesh.vertex(b), weight=weight)
    assert all(isinstance(v, hestore.Vertex) and v.mesh == mesh for v in path)
    ids = [v.id for v in path]
    assert ids[0] == a and ids[-1] == b
    for u, v in zip(ids, ids[1:]):
        assert G.has_edge(u, v), (ids, u, v)
    got = path_length(G, ids, weight)
    if weight is None:
        assert got == expected
    else:
        assert math.isclose(got, expected, rel_tol=1e-9, abs_tol=1e-12), (got, expected)
    return ids


def check_ring(mesh, G, v: int, k: int) -> set[int]:
    ring = mesh.k_ring(mesh.vertex(v), k)
    assert all(isinstance(x, hestore.Vertex) and x.mesh == mesh for x in ring)
    ids = {x.id for x in ring}
    assert ids == set(nx.single_source_shortest_path_length(G, v, cutoff=k))
    return ids


def edge_items(G: nx.Graph) -> dict:
    """Edges as ``{(u, v[, key]): data}``, undirected pairs ordered."""
    if G.is_multigraph():
        edges = G.edges(keys=True, data=True)
        return {((min(u, v), max(u, v)) if not G.is_directed() else (u, v)) + (k,): d for u, v, k, d in edges}
    return {(min(u, v), max(u, v)): d for u, v, d in G.edges(data=True)}


def check_induced(mesh, kind: str, S: list[int], attrs=None, whole: nx.Graph | None = None) -> nx.Graph:
    H = mesh.to_networkx(kind, attrs=attrs, vertices=[mesh.vertex(i) for i in S])
    W = (whole if whole is not None else mesh.to_networkx(kind, attrs=attrs)).subgraph(S)
    assert type(H) is type(W)
    assert nx.is_frozen(H)
    assert dict(H.nodes(data=True)) == dict(W.nodes(data=True))
    assert edge_items(H) == edge_items(W)
    assert H.number_of_edges() == W.number_of_edges()
    # The same adjacency order as the whole view (networkx's tie-breaks depend on it).
    for n in H:
        assert list(H.adj[n]) == [m for m in W.adj[n]]
    return H


def sample_pairs(ids: list[int], n: int, seed: int) -> list[tuple[int, int]]:
    rng = random.Random(seed)
    return [(rng.choice(ids), rng.choice(ids)) for _ in range(n)]


# -- meshes -----------------------------------------------------------------------------


def wireframe(store: hestore.Store, name: str = "wire") -> hestore.Mesh:
    """Three components and two isolated vertices: a square with a diagonal, a parallel edge and a loop;
    a path with a loop at its end and a doubled edge; a lone edge; two isolated vertices."""
    mesh = store.create_mesh(name)
    xyz = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0),  # the square 0-3
           (5, 0, 0), (6, 0, 1), (7, 2, 1), (9, 2, 0),  # the path 4-7
           (0, 5, 0), (0, 7, 0),  # the lone edge
           (3, 3, 3), (4, 4, 4)]  # isolated
    vs = [mesh.add_vertex(p) for p in xyz]
    edges = [(0, 1), (1, 2), (2, 3), (3, 0), (0, 2), (0, 1), (2, 2),
             (4, 5), (5, 6), (6, 7), (6, 7), (7, 7), (4, 4),
             (8, 9)]  # fmt: skip
    with store.transaction():
        for a, b in edges:
            mesh.add_edge(vs[a], vs[b])
    return mesh


def all_vertex_ids(mesh) -> list[int]:
    return [v.id for v in mesh.vertices()]


def check_everything(mesh, seed: int, pairs: int = 25) -> None:
    G = reference(mesh)
    ids = all_vertex_ids(mesh)
    rng = random.Random(seed)
    for a, b in sample_pairs(ids, pairs, seed):
        check_path(mesh, G, a, b, None)
        check_path(mesh, G, a, b, "length")
    for v in rng.sample(ids, min(len(ids), 10)):
        for k in (0, 1, 2, 3):
            check_ring(mesh, G, v, k)
    for kind in VERTEX_KINDS:
        for size in (0, 1, 5, len(ids) // 3):
            check_induced(mesh, kind, rng.sample(ids, min(size, len(ids))))
    # A k-ring is a typical induced set.
    S = [x.id for x in mesh.k_ring(mesh.vertex(ids[0]), 2)]
    check_induced(mesh, "multigraph", S, attrs=["length"])


# -- agreement with networkx ---------------------------------------------------------------


def test_wireframe_agrees_with_networkx(store):
    mesh = wireframe(store)
    check_everything(mesh, seed=1, pairs=60)
    ids = all_vertex_ids(mesh)
    G = reference(mesh)
    for a in ids:  # every pair, every k: the wireframe is small
        for b in ids:
            check_path(mesh, G, a, b, None)
            check_path(mesh, G, a, b, "length")
        for k in range(5):
            check_ring(mesh, G, a, k)
    # The diagonal (length √2) beats going round the square (2); the parallel edge changes nothing.
    assert [v.id for v in mesh.shortest_path(mesh.vertex(1), mesh.vertex(3), "length")] in ([1, 0, 3], [1, 2, 3])
    assert [v.id for v in mesh.shortest_path(mesh.vertex(4), mesh.vertex(7))] == [4, 5, 6, 7]
    assert {v.id for v in mesh.k_ring(mesh.vertex(10), 3)} == {10}


@pytest.mark.parametrize("name", SHARED)
def test_shared_meshes_agree_with_networkx(store, name):
    folder = require_shared_meshes()
    mesh = store.import_file(folder / name, name="m", on_error="skip").mesh
    check_everything(mesh, seed=len(name), pairs=20)


def test_grid_with_long_paths(store):
    mesh = store.create_mesh("grid")
    grid(mesh, 12, 9)
    G = reference(mesh)
    ids = all_vertex_ids(mesh)
    for a, b in sample_pairs(ids, 30, 7):
        check_path(mesh, G, a, b, None)
        check_path(mesh, G, a, b, "length")
    corner, far = ids[0], ids[-1]
    assert len(check_path(mesh, G, corner, far, None)) == nx.shortest_path_length(G, corner, far) + 1
    check_ring(mesh, G, ids[len(ids) // 2], 4)


def test_induced_views_keep_attrs(store):
    mesh = wireframe(store)
    mesh.add_property("vertex", "heat", "float64", default=0.5)
    mesh.add_property("edge", "cost", "int64")  # no default: only set edges have it
    mesh.add_property("halfedge", "side", "int64", default=3)
    mesh.vertex(2)["heat"] = 7.0
    mesh.edge(4)["cost"] = 9
    mesh.edge(5)["cost"] = 2
    for kind, attrs in [("multigraph", ["heat", "cost", "length"]), ("graph", ["cost", "length", "heat"]),
                        ("halfedge", ["side", "cost", "length"])]:  # fmt: skip
        H = check_induced(mesh, kind, [0, 1, 2, 4, 5, 10], attrs=attrs)
        assert H.nodes[2].get("heat", 7.0) == 7.0
    H = mesh.to_networkx("graph", attrs=["cost"], vertices=[mesh.vertex(0), mesh.vertex(1)])
    assert H.edges[0, 1] == {"multiplicity": 2, "edges": [0, 5], "cost": 2}  # the lightest of the parallel edges


def test_induced_view_reads_only_its_rows(store):
    mesh = store.create_mesh("grid")
    grid(mesh, 30, 30)
    statements: list[str] = []
    S = [mesh.vertex(i) for i in (0, 1, 31, 32)]
    with store.session.traced(statements.append):
        H = mesh.to_networkx(vertices=S)
    assert sorted(H) == [0, 1, 31, 32]
    # The revision the view is of, then one statement for the vertices' rows and one for the half-edges they
    # start: nothing read by the mesh.
    assert len(statements) == 3, statements
    assert "meshes.revision" in statements[0], statements
    assert all(" IN (" in sql for sql in statements[1:]), statements


def test_k_ring_is_one_query_per_level(store):
    mesh = store.create_mesh("grid")
    grid(mesh, 20, 20)
    statements: list[str] = []
    centre = mesh.vertex(220)
    with store.session.traced(statements.append):
        ring = mesh.k_ring(centre, 3)
    assert {x.id for x in ring} == set(nx.single_source_shortest_path_length(mesh.to_networkx(), 220, cutoff=3))
    assert len(ring) > 20
    assert len(statements) == 3, statements  # a level a statement (the first one shows the vertex is there)


# -- hypothesis: random small meshes -----------------------------------------------------

small_xyz = st.tuples(*(st.integers(-3, 3),) * 3)


@st.composite
def wireframes(draw):
    n = draw(st.integers(1, 9))
    positions = draw(st.lists(small_xyz, min_size=n, max_size=n))
    edges = draw(st.lists(st.tuples(st.integers(0, n - 1), st.integers(0, n - 1)), max_size=14))
    return positions, edges


@settings(max_examples=25, **STORED)
@given(wire=wireframes(), data=st.data())
def test_random_wireframes_agree_with_networkx(store, wire, data):
    positions, edges = wire
    mesh = store.create_mesh(f"w{len(store.meshes())}")
    with store.transaction():
        vs = [mesh.add_vertex(p) for p in positions]
        for a, b in edges:
            mesh.add_edge(vs[a], vs[b])
    check_drawn(mesh, [v.id for v in vs], data, k_max=4)


def check_drawn(mesh, ids, data, k_max):
    """Both kinds of path between two drawn vertices, a drawn k-ring and a drawn induced view agree with networkx."""
    G = reference(mesh)
    a, b = data.draw(st.sampled_from(ids)), data.draw(st.sampled_from(ids))
    check_path(mesh, G, a, b, None)
    check_path(mesh, G, a, b, "length")
    check_ring(mesh, G, a, data.draw(st.integers(0, k_max)))
    S = data.draw(st.lists(st.sampled_from(ids), unique=True))
    check_induced(mesh, data.draw(st.sampled_from(VERTEX_KINDS)), S)


@settings(max_examples=15, **STORED)
@given(n=st.integers(2, 5), m=st.integers(2, 5), cut=st.lists(st.integers(0, 60), max_size=6), data=st.data())
def test_random_grids_agree_with_networkx(store, n, m, cut, data):
    mesh = store.create_mesh(f"g{len(store.meshes())}")
    grid(mesh, n, m)
    edges = [e for e in mesh.edges()]
    with store.transaction():
        for i in sorted(set(c % len(edges) for c in cut)):
            mesh.remove_edge(edges[i])  # holes, wire edges, maybe several components
    check_drawn(mesh, all_vertex_ids(mesh), data, k_max=3)


# -- inside a block, and views of the past ---------------------------------------------------


def test_queries_see_the_blocks_own_edits(store):
    mesh = wireframe(store)
    v = mesh.vertex
    before = {v.id for v in mesh.k_ring(v(3), 2)}
    with store.transaction():
        mesh.add_edge(v(3), v(4))  # joins the square to the path
        mesh.remove_edge(mesh.find_halfedge(v(5), v(6)).edge)  # and cuts the path
        w = mesh.add_vertex((1, 2, 0))
        mesh.add_edge(v(2), w)
        mesh.set_position(v(7), (9, 2, 5))
        inside = {
            "ring": {x.id for x in mesh.k_ring(v(3), 2)},
            "path": [x.id for x in mesh.shortest_path(v(0), v(4))],
            "length": [x.id for x in mesh.shortest_path(v(6), v(7), "length")],
            "induced": {kind: mesh.to_networkx(kind, attrs=["length"], vertices=[v(0), v(3), v(4), w, v(6), v(7)])
                        for kind in VERTEX_KINDS},
        }
        with pytest.raises(hestore.NoPathError):
            mesh.shortest_path(v(4), v(6))
        assert [x.id for x in mesh.shortest_path(w, v(5))] == [w.id, 2, 3, 4, 5]
    assert inside["ring"] != before and 4 in inside["ring"]
    # Committed now: networkx on the whole graph must agree with what the block saw.
    G = reference(mesh)
    assert inside["ring"] == set(nx.single_source_shortest_path_length(G, 3, cutoff=2))
    assert len(inside["path"]) - 1 == nx.shortest_path_length(G, 0, 4) == 2
    assert math.isclose(path_length(G, inside["length"], "length"),
                        nx.shortest_path_length(G, 6, 7, weight=lightest), rel_tol=1e-9)
    for kind, H in inside["induced"].items():
        W = mesh.to_networkx(kind, attrs=["length"]).subgraph(H.nodes)
        assert edge_items(H) == edge_items(W) and dict(H.nodes(data=True)) == dict(W.nodes(data=True))


def test_views_of_the_past_answer_as_then(store):
    mesh = wireframe(store)
    r = mesh.revision
    G_then = reference(mesh)
    whole_then = {kind: mesh.to_networkx(kind) for kind in VERTEX_KINDS}
    v = mesh.vertex
    with store.transaction():
        mesh.add_edge(v(3), v(8))
        mesh.remove_edge(mesh.find_halfedge(v(0), v(2)).edge)
        mesh.set_position(v(1), (0.5, 0.1, 0))
    mesh.remove_vertex(v(6))
    mesh.add_edge(v(10), v(11))
    past = mesh.at(r)
    assert past.vertex(6).id == 6
    ids = list(G_then.nodes)
    for a, b in sample_pairs(ids, 40, 3):
        check_path(past, G_then, a, b, None)
        check_path(past, G_then, a, b, "length")
    for x in ids:
        check_ring(past, G_then, x, 2)
    for kind in VERTEX_KINDS:
        check_induced(past, kind, [0, 1, 2, 3, 6, 8, 10, 11], whole=whole_then[kind])
    # And the present differs: the queries of the view did not read today's rows.
    assert {x.id for x in mesh.k_ring(v(3), 1)} != {x.id for x in past.k_ring(past.vertex(3), 1)}
    with pytest.raises(hestore.ElementNotFoundError):
        mesh.k_ring(v(6), 1)


def test_views_read_the_star_by_its_index(store, backend):
    mesh = store.create_mesh("grid")
    grid(mesh, 6, 6)
    r = mesh.revision
    mesh.remove_edge(mesh.edge(3))
    past = mesh.at(r)
    centre = past.vertex(24)
    statements: list[str] = []
    with store.session.traced(statements.append):
        ring = past.k_ring(centre, 2)
    assert {x.id for x in ring} == set(nx.single_source_shortest_path_length(past.to_networkx(), 24, cutoff=2))
    assert statements and all("halfedges_history" in sql for sql in statements)
    if backend == "sqlite":
        # Without statistics SQLite would scan the mesh's half-edges by primary key for an IN list: the view's
        # current half names the origin index, as the hot reads do.
        assert all("INDEXED BY ix_halfedges_origin" in sql for sql in statements), statements[0]


# -- errors ------------------------------------------------------------------------------


def test_no_path_and_trivial_paths(store):
    mesh = wireframe(store)
    v = mesh.vertex
    for weight in (None, "length"):
        with pytest.raises(hestore.NoPathError) as info:
            mesh.shortest_path(v(0), v(4), weight)
        assert str(info.value) == "no path from vertex 0 to vertex 4 in mesh 'wire': they are in different components"
        assert isinstance(info.value, hestore.HestoreError)
        assert mesh.shortest_path(v(10), v(10), weight) == [v(10)]
        assert mesh.shortest_path(v(2), v(2), weight) == [v(2)]  # with a self-loop
        with pytest.raises(hestore.NoPathError):
            mesh.shortest_path(v(10), v(11), weight)
    assert mesh.k_ring(v(10), 0) == {v(10)} and mesh.k_ring(v(0), 0) == {v(0)}


def test_length_needs_positions_the_search_meets(store):
    mesh = store.create_mesh("m")
    a, b, c = mesh.add_vertex((0, 0, 0)), mesh.add_vertex((1, 0, 0)), mesh.add_vertex()
    mesh.add_edge(a, b)
    bc = mesh.add_edge(b, c)
    assert mesh.shortest_path(a, c) == [a, b, c]
    with pytest.raises(hestore.InvalidInputError) as info:
        mesh.shortest_path(a, c, "length")
    assert f"edge {bc.id} has no length: vertex {c.id} has no position" in str(info.value)
    assert mesh.shortest_path(a, b, "length") == [a, b]


def test_bad_input_is_typed_and_changes_nothing(store):
    mesh = wireframe(store)
    other = wireframe(store, "other")
    v = mesh.vertex
    gone = mesh.add_vertex()
    mesh.remove_vertex(gone)
    before = dump(store)
    cases = [
        (hestore.ElementNotFoundError, lambda: mesh.k_ring(other.vertex(0), 1)),
        (hestore.ElementNotFoundError, lambda: mesh.k_ring(gone, 1)),
        (hestore.ElementNotFoundError, lambda: mesh.shortest_path(v(0), gone)),
        (hestore.ElementNotFoundError, lambda: mesh.shortest_path(gone, v(0), "length")),
        (hestore.ElementNotFoundError, lambda: mesh.shortest_path(other.vertex(1), v(0))),
        (hestore.ElementNotFoundError, lambda: mesh.to_networkx(vertices=[v(0), gone])),
        (hestore.ElementNotFoundError, lambda: mesh.to_networkx("graph", vertices=[other.vertex(0)])),
        (hestore.InvalidInputError, lambda: mesh.k_ring(0, 1)),
        (hestore.InvalidInputError, lambda: mesh.k_ring(mesh.edge(0), 1)),
        (hestore.InvalidInputError, lambda: mesh.k_ring(v(0), -1)),
        (hestore.InvalidInputError, lambda: mesh.k_ring(v(0), 1.5)),
        (hestore.InvalidInputError, lambda: mesh.k_ring(v(0), True)),
        (hestore.InvalidInputError, lambda: mesh.k_ring(v(0), "2")),
        (hestore.InvalidInputError, lambda: mesh.k_ring(v(0), None)),
        (hestore.InvalidInputError, lambda: mesh.shortest_path(0, 1)),
        (hestore.PropertyNotFoundError, lambda: mesh.shortest_path(v(0), v(1), "cost")),  # no such edge property
        (hestore.InvalidInputError, lambda: mesh.shortest_path(v(0), v(1), 1)),
        (hestore.InvalidInputError, lambda: mesh.shortest_path(v(0), v(1), weight=["length"])),
        (hestore.InvalidInputError, lambda: mesh.to_networkx(vertices=[0, 1])),
        (hestore.InvalidInputError, lambda: mesh.to_networkx(vertices=v(0))),
        (hestore.InvalidInputError, lambda: mesh.to_networkx(vertices=5)),
        (hestore.InvalidInputError, lambda: mesh.to_networkx("dual", vertices=[v(0)])),
        (hestore.InvalidInputError, lambda: mesh.to_networkx("nope", vertices=[v(0)])),
        (hestore.PropertyNotFoundError, lambda: mesh.to_networkx(attrs=["nope"], vertices=[v(0)])),
    ]
    for error, call in cases:
        with pytest.raises(error):
            call()
    assert dump(store) == before
    assert mesh.k_ring(v(0), 1) == {v(0), v(1), v(2), v(3)}  # still usable
    import numpy as np

    assert mesh.k_ring(v(0), np.int64(1)) == {v(0), v(1), v(2), v(3)}  # a numpy integer is an integer
    assert mesh.to_networkx(vertices=[]).number_of_nodes() == 0
    assert sorted(mesh.to_networkx(vertices=(v(0), v(0), v(1)))) == [0, 1]


def test_a_deleted_mesh_says_so(store):
    mesh = wireframe(store)
    a = mesh.vertex(0)
    store.delete_mesh("wire")
    for call in (lambda: mesh.k_ring(a, 1), lambda: mesh.shortest_path(a, a), lambda: mesh.to_networkx(vertices=[a])):
        with pytest.raises(hestore.MeshNotFoundError):
            call()


# -- weighed by an edge property ------------------------------------------------------------


def weigh_edges(mesh, name: str, dtype: str, values: dict, default=None) -> nx.MultiGraph:
    """Declare the edge property ``name``, set ``values`` ({edge id: value}), and return the reference graph."""
    mesh.add_property("edge", name, dtype, default=default)
    if values:
        mesh.set_property_array("edge", name, list(values), list(values.values()))
    return nx.MultiGraph(mesh.to_networkx("multigraph", attrs=[name]))


def check_weighed(mesh, G, a: int, b: int, name: str) -> list[int] | None:
    """`check_path` by the property ``name``, and `Mesh.path_weight` of the path: networkx's length."""
    ids = check_path(mesh, G, a, b, name)
    if ids is not None:
        path = [mesh.vertex(i) for i in ids]
        total = mesh.path_weight(path, name)
        assert total == path_length(G, ids, name)
        assert isinstance(total, float if mesh.properties("edge")[name].dtype == "float64" else int)
    return ids


def test_property_weights_agree_with_networkx(store):
    mesh = wireframe(store)
    rng = random.Random(4)
    edges = [e.id for e in mesh.edges()]
    # Integers with a default on the unset edges; floats of every size, some 0, one inf, set on every edge.
    G = weigh_edges(mesh, "cost", "int64", {e: rng.choice([0, 1, 2, 7]) for e in edges if rng.random() < 0.7}, 3)
    toll = {e: rng.choice([0.0, 0.5, 1e-9, 2.75, 1e6]) for e in edges}
    toll[edges[-1]] = math.inf  # the lone edge 8-9: a path across it weighs inf
    H = weigh_edges(mesh, "toll", "float64", toll)
    ids = all_vertex_ids(mesh)
    for a in ids:
        for b in ids:
            check_weighed(mesh, G, a, b, "cost")
            check_weighed(mesh, H, a, b, "toll")
    assert mesh.path_weight([mesh.vertex(8), mesh.vertex(9)], "toll") == math.inf
    # The parallel edges 0-1 (edges 0 and 5): the lightest counts, in the search and in the path's weight.
    v = mesh.vertex
    with store.transaction():
        for e, cost in [(0, 9), (5, 0), (1, 4), (4, 9), (2, 9), (3, 1)]:
            mesh.edge(e)["cost"] = cost
    assert mesh.shortest_path(v(1), v(2), "cost") == [v(1), v(2)]
    assert mesh.shortest_path(v(1), v(3), "cost") == [v(1), v(0), v(3)]
    assert mesh.path_weight([v(1), v(0)], "cost") == 0 and mesh.path_weight([v(1), v(0), v(2)], "cost") == 9


def test_a_property_named_length_is_that_property(store):
    mesh = wireframe(store)
    by_position = [v.id for v in mesh.shortest_path(mesh.vertex(1), mesh.vertex(3), "length")]
    G = weigh_edges(mesh, "length", "int64", {4: 10}, default=1)  # the diagonal 0-2, the shortest way, costs 10
    for a in all_vertex_ids(mesh):
        for b in (1, 3, 5):
            check_weighed(mesh, G, a, b, "length")
    assert by_position in ([1, 0, 3], [1, 2, 3])
    assert mesh.path_weight([mesh.vertex(0), mesh.vertex(2)], "length") == 10  # not √2


small_weight = st.one_of(st.none(), st.integers(0, 5), st.sampled_from([0.5, 1e-6, 1e9]))


@settings(max_examples=25, **STORED)
@given(wire=wireframes(), data=st.data())
def test_random_weighted_wireframes_agree_with_networkx(store, wire, data):
    positions, edges = wire
    mesh = store.create_mesh(f"w{len(store.meshes())}")
    with store.transaction():
        vs = [mesh.add_vertex(p) for p in positions]
        es = [mesh.add_edge(vs[a], vs[b]).id for a, b in edges]
    dtype = data.draw(st.sampled_from(["int64", "float64"]))
    number = int if dtype == "int64" else float
    drawn = data.draw(st.lists(small_weight, min_size=len(es), max_size=len(es)))
    values = {e: number(w) for e, w in zip(es, drawn) if w is not None}
    G = weigh_edges(mesh, "w", dtype, values, default=number(data.draw(st.integers(0, 3))))
    ids = [v.id for v in vs]
    for _ in range(4):
        check_weighed(mesh, G, data.draw(st.sampled_from(ids)), data.draw(st.sampled_from(ids)), "w")


def test_grid_weighed_by_a_property_reads_around_its_vertices(store):
    mesh = store.create_mesh("grid")
    grid(mesh, 30, 30)
    rng = random.Random(11)
    G = weigh_edges(mesh, "time", "float64", {e.id: rng.uniform(0.5, 2.0) for e in mesh.edges()})
    for a, b in sample_pairs(all_vertex_ids(mesh), 15, 2):
        check_weighed(mesh, G, a, b, "time")
    mesh.add_property("edge", "unit", "float64", default=1.0)
    a, b = mesh.vertex(480), mesh.vertex(482)  # two edges apart, mid-grid
    statements: list[str] = []
    with store.session.traced(statements.append):
        path = mesh.shortest_path(a, b, "unit")
    assert [x.id for x in path] == [480, 481, 482]
    # The two vertices, the catalogue, then for each of the two levels a batch of stars and their edges' values:
    # never a whole column.
    assert len(statements) == 2 + 2 * 2, statements
    assert all(" IN (" in sql for sql in statements[2:]), statements
    assert ["property_reals" in sql for sql in statements[2:]] == [False, True, False, True], statements


def test_property_weights_in_a_block_and_in_the_past(store):
    mesh = wireframe(store)
    mesh.add_property("edge", "cost", "int64", default=1)
    v = mesh.vertex
    r = mesh.revision
    G_then = nx.MultiGraph(mesh.to_networkx("multigraph", attrs=["cost"]))
    with store.transaction():
        mesh.find_halfedge(v(4), v(5)).edge["cost"] = 50  # the only way from 4 onwards
        mesh.add_edge(v(4), v(7))
        inside = [x.id for x in mesh.shortest_path(v(4), v(6), "cost")]
        assert mesh.path_weight([v(4), v(5)], "cost") == 50  # the block's own edit
    assert inside == [4, 7, 6]
    past = mesh.at(r)
    for a, b in sample_pairs(list(G_then.nodes), 30, 5):
        check_weighed(past, G_then, a, b, "cost")
    assert [x.id for x in past.shortest_path(past.vertex(4), past.vertex(6), "cost")] == [4, 5, 6]
    assert past.path_weight([past.vertex(4), past.vertex(5)], "cost") == 1


def test_property_weights_refuse_what_cannot_weigh(store):
    mesh = store.create_mesh("m", allow_loops=True)
    a, b, c, d = (mesh.add_vertex((x, 0, 0)) for x in range(4))
    ab, bc, cd = mesh.add_edge(a, b), mesh.add_edge(b, c), mesh.add_edge(c, d)
    mesh.add_property("edge", "cost", "int64", default=1)
    mesh.add_property("edge", "toll", "float64")  # no default
    mesh.add_property("edge", "tag", "str", default="")
    mesh.add_property("edge", "uv", "float64", shape=(2,))
    mesh.add_property("vertex", "heat", "float64", default=0.0)
    for weight, error, message in [
        ("nope", hestore.PropertyNotFoundError, "mesh 'm' has no edge property named 'nope'"),
        ("heat", hestore.PropertyNotFoundError, "mesh 'm' has no edge property named 'heat'"),  # a vertex's
        ("tag", hestore.InvalidInputError, "edge property 'tag' of mesh 'm' is str, not a number"),
        ("uv", hestore.InvalidInputError, "edge property 'uv' of mesh 'm' is float64 of shape (2,), not a number"),
    ]:
        for call in (lambda: mesh.shortest_path(a, a, weight), lambda: mesh.path_weight([a], weight)):
            with pytest.raises(error) as info:
                call()
            assert str(info.value) == message and info.value.weights == ("length", "cost", "toll")
    for weight in (1, ["cost"], b"cost", True):
        with pytest.raises(hestore.InvalidInputError) as info:
            mesh.shortest_path(a, d, weight)
        assert info.value.weights is None
    # An edge the search meets without a weight, or with one below 0 or NaN: refused, named.
    for value, reason in [
        (None, f"edge {bc.id} has no value of property 'toll', which has no default"),
        (-1.5, f"edge {bc.id} has a negative toll (-1.5); a shortest path needs weights of 0 or more"),
        (math.nan, f"edge {bc.id} has toll NaN"),
    ]:
        with store.transaction():
            ab["toll"], bc["toll"], cd["toll"] = 1.0, value, 1.0
        for call in (lambda: mesh.shortest_path(a, d, "toll"), lambda: mesh.path_weight([b, c], "toll")):
            with pytest.raises(hestore.InvalidInputError) as info:
                call()
            assert str(info.value) == f"cannot weigh the paths of 'm' by toll: {reason}"
        assert mesh.shortest_path(a, b, "toll") == [a, b]  # edge bc: at b, which the search never expands
    # A self-loop at a vertex the search expands is weighed too (as networkx does), though it never shortens.
    loop = mesh.add_edge(a, a)
    loop["cost"] = -1
    with pytest.raises(hestore.InvalidInputError, match=f"edge {loop.id} has a negative cost"):
        mesh.shortest_path(a, b, "cost")
    assert mesh.shortest_path(b, c, "cost") == [b, c] and mesh.shortest_path(a, a, "cost") == [a]
    mesh.remove_edge(loop)
    # path_weight: a path is consecutive vertices joined by an edge, of this mesh.
    other = store.create_mesh("other").add_vertex()
    before = dump(store)
    cases = [
        (hestore.InvalidInputError, lambda: mesh.path_weight([], "cost")),
        (hestore.InvalidInputError, lambda: mesh.path_weight([a, c], "cost")),
        (hestore.InvalidInputError, lambda: mesh.path_weight([a, b, a, d])),
        (hestore.InvalidInputError, lambda: mesh.path_weight(a)),
        (hestore.InvalidInputError, lambda: mesh.path_weight([a.id, b.id])),
        (hestore.ElementNotFoundError, lambda: mesh.path_weight([a, other])),
    ]
    for error, call in cases:
        with pytest.raises(error):
            call()
    assert dump(store) == before
    assert mesh.path_weight([a]) == 0 and mesh.path_weight([a], "length") == 0.0
    assert mesh.path_weight([a, b, c, d]) == 3 and mesh.path_weight([d, c, b], "length") == 2.0


# -- the command line -----------------------------------------------------------------------


def one_line_error(code: int, out: str, err: str) -> str:
    assert (code, out) == (2, "") and err.startswith("hestore: error: ") and err.count("\n") == 1, err
    return err


def test_cli_graph_neighbors(capsys, db_url):
    with hestore.open(db_url) as store:
        wireframe(store)
    graph = ("--db", db_url, "graph", "wire")
    assert run(capsys, *graph, "neighbors", "1") == (0, "0 1 2\n", "")  # --k 1 by default
    assert run(capsys, *graph, "neighbors", "1", "--k", "0") == (0, "1\n", "")
    assert run(capsys, *graph, "neighbors", "4", "--k", "2") == (0, "4 5 6\n", "")
    assert run(capsys, *graph, "neighbors", "4", "--k", "9") == (0, "4 5 6 7\n", "")
    assert run(capsys, *graph, "neighbors", "11", "--k", "3") == (0, "11\n", "")
    assert "vertex 99 does not exist" in one_line_error(*run(capsys, *graph, "neighbors", "99"))
    assert "k is a number of edges" in one_line_error(*run(capsys, *graph, "neighbors", "1", "--k", "-1"))
    one_line_error(*run(capsys, "--db", db_url, "graph", "missing", "neighbors", "1"))
    code, out, err = run(capsys, *graph, "neighbors", "1", "--k", "two")
    assert code == 2 and "invalid int value" in err
    code, out, _ = run(capsys, "graph", "NAME", "neighbors", "--help")
    assert code == 0 and "--k" in out and "within K edges" in out


def test_cli_graph_path_builds_no_graph(capsys, db_url, monkeypatch):
    with hestore.open(db_url) as store:
        wireframe(store)

    def refused(*args, **kwargs):
        raise AssertionError("graph … path built the whole graph")

    monkeypatch.setattr(graphs, "to_networkx", refused)
    graph = ("--db", db_url, "graph", "wire")
    assert run(capsys, *graph, "path", "4", "7") == (0, "path: 4 5 6 7\nlength: 3 edges\n", "")
    code, out, err = run(capsys, *graph, "path", "1", "3", "--weight", "length")
    assert code == 0 and err == ""
    assert out in ("path: 1 0 3\nlength: 2 edges\ntotal length: 2\n", "path: 1 2 3\nlength: 2 edges\ntotal length: 2\n")
    assert run(capsys, *graph, "path", "0", "2", "--weight", "length") == (
        0, f"path: 0 2\nlength: 1 edge\ntotal length: {math.sqrt(2):.12g}\n", "",
    )  # fmt: skip
    assert run(capsys, *graph, "path", "0", "9") == (
        1, "no path from vertex 0 to vertex 9 in 'wire': they are in different components\n", "",
    )  # fmt: skip
    assert run(capsys, *graph, "path", "0", "9", "--weight", "length")[0] == 1
    assert "vertex 42 does not exist" in one_line_error(*run(capsys, *graph, "path", "0", "42"))


def test_cli_graph_path_by_a_property_builds_no_graph(capsys, db_url, monkeypatch):
    with hestore.open(db_url) as store:
        weigh_edges(wireframe(store), "cost", "int64", {4: 5}, default=1)  # the diagonal 0-2 costs 5

    def refused(*args, **kwargs):
        raise AssertionError("graph … path --weight built the whole graph")

    monkeypatch.setattr(graphs, "to_networkx", refused)
    graph = ("--db", db_url, "graph", "wire", "path")
    code, out, err = run(capsys, *graph, "0", "2", "--weight", "cost")
    assert (code, err) == (0, "")
    assert out in ("path: 0 1 2\nlength: 2 edges\ntotal cost: 2\n", "path: 0 3 2\nlength: 2 edges\ntotal cost: 2\n")
    assert run(capsys, *graph, "4", "8", "--weight", "cost")[0] == 1
    assert one_line_error(*run(capsys, *graph, "0", "2", "--weight", "nope")) == (
        "hestore: error: mesh 'wire' has no edge property named 'nope'; --weight takes: length, cost\n"
    )


# -- the documentation's example --------------------------------------------------------------


def test_the_local_queries_example_in_the_docs_runs(capsys):
    page = (pathlib.Path(__file__).resolve().parents[1] / "docs" / "analysis.md").read_text(encoding="utf-8")
    section = page[page.index("## Local queries") :]
    blocks = re.findall(r"^```python\n(.*?)^```", section, re.M | re.S)
    assert blocks
    for block in blocks:
        exec(compile(block, "docs/analysis.md, Local queries", "exec"), {})
    announced = [m.group(1) for b in blocks for m in re.finditer(r"print\(.*\)\s+# (.*)$", b, re.M)]
    assert capsys.readouterr().out.splitlines() == announced
