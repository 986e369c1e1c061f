"""Graph views (SPEC §6): `hestore.graphs.to_networkx`, on SQLite and PostgreSQL.

The oracle is a graph built the plain networkx way — ``add_nodes_from`` in
vertex (polygon) id order, then ``add_edge`` in edge (half-edge) id order —
from what the navigation API says about each element (`from_handles`) or from
a model kept by hand (`GraphMachine`). `to_networkx` must give the same
nodes, edges, keys and attributes, in the same order (so that algorithms
break ties the same way), for every kind:

* literal expectations on small hand-made meshes: a wireframe with self-loops,
  parallel edges and isolated vertices; a 1-gon on a loop; 2-gons on
  parallel edges; a polygon meeting itself across edges (dual self-loops);
  polygons meeting at a vertex; several components; a hole;
* the demo mesh and a mixed mesh against `from_handles`;
* networkx algorithms on the view against the same algorithms on the plain
  copy;
* frozen, cached per committed revision, committed state only (a second
  connection inside a block; an in-memory SQLite store shows the block's own
  state and caches nothing then), errors;
* a hypothesis state machine of random edits, checking all four kinds after
  every step against a hand-maintained `networkx.MultiGraph` and the model.
"""

from __future__ import annotations

import itertools
import os

import networkx as nx
import pytest
from hypothesis import HealthCheck, Phase, settings
from hypothesis import strategies as st
from hypothesis.stateful import (
    RuleBasedStateMachine,
    initialize,
    invariant,
    precondition,
    rule,
    run_state_machine_as_test,
)

import hestore
from hestore import graphs, schema
from hestore._session import identity
from hestore.cli import demo
from hestore.errors import HestoreError, InvalidInputError, InvariantViolationError, MeshNotFoundError, TopologyError

from helpers import grid

KINDS = graphs.KINDS


# -- the oracle ---------------------------------------------------------------------


def expected(kind: str, vertices: dict, edges: dict, face: dict, polygon_halfedge: dict) -> nx.Graph:
    """The graph of ``kind`` built with networkx's own API, elements in id order.

    ``vertices``: id -> position or None; ``edges``: id -> (a, b, h0, h1) with
    h0 the edge's half-edge (a -> b) and h1 its twin; ``face``: half-edge ->
    polygon or None; ``polygon_halfedge``: polygon -> its half-edge.
    """
    if kind == "dual":
        G = nx.MultiGraph()
        G.add_nodes_from((p, {"halfedge": polygon_halfedge[p]}) for p in sorted(polygon_halfedge))
        for e in sorted(edges):
            a, b, h0, h1 = edges[e]
            if face[h0] is not None and face[h1] is not None:
                G.add_edge(face[h0], face[h1], key=e, halfedges=(h0, h1), vertices=(a, b))
        return G
    G = {"multigraph": nx.MultiGraph, "graph": nx.Graph, "halfedge": nx.MultiDiGraph}[kind]()
    G.add_nodes_from((v, {"pos": vertices[v]}) for v in sorted(vertices))
    if kind == "halfedge":
        halves = {}
        for e, (a, b, h0, h1) in edges.items():
            halves[h0] = (a, b, e, h1)
            halves[h1] = (b, a, e, h0)
        for h in sorted(halves):
            a, b, e, t = halves[h]
            G.add_edge(a, b, key=h, polygon=face[h], edge=e, twin=t)
        return G
    for e in sorted(edges):
        a, b, h0, h1 = edges[e]
        if kind == "multigraph":
            G.add_edge(a, b, key=e, halfedges=(h0, h1), polygons=(face[h0], face[h1]))
        elif G.has_edge(a, b):
            G[a][b]["multiplicity"] += 1
            G[a][b]["edges"].append(e)
        else:
            G.add_edge(a, b, multiplicity=1, edges=[e])
    return G


def pid(p):
    return None if p is None else p.id


def handle_model(mesh: hestore.Mesh) -> tuple[dict, dict, dict, dict]:
    """``(vertices, edges, face, polygon_halfedge)`` as the navigation API reports them."""
    vertices = {v.id: v.position for v in mesh.vertices()}
    edges, face = {}, {}
    for e in mesh.edges():
        h0, h1 = e.halfedges()
        edges[e.id] = (h0.origin.id, h1.origin.id, h0.id, h1.id)
        face[h0.id], face[h1.id] = pid(h0.polygon), pid(h1.polygon)
    polygon_halfedge = {p.id: p.halfedge.id for p in mesh.polygons()}
    return vertices, edges, face, polygon_halfedge


def from_handles(mesh: hestore.Mesh, kind: str = "multigraph") -> nx.Graph:
    """A plain networkx copy of the mesh, built from its handles (``mesh.edges()`` etc.)."""
    return expected(kind, *handle_model(mesh))


def nested(d, depth: int):
    """Dicts of dicts as lists of pairs: equality then includes the order."""
    if depth == 0 or not isinstance(d, dict):
        return d
    return [(k, nested(v, depth - 1)) for k, v in d.items()]


def assert_identical(G: nx.Graph, H: nx.Graph) -> None:
    """Same class, nodes, adjacency (and predecessors), attributes — and the same order throughout."""
    assert type(G) is type(H)
    assert list(G.nodes(data=True)) == list(H.nodes(data=True))
    depth = 4 if G.is_multigraph() else 3
    assert nested(G._adj, depth) == nested(H._adj, depth)
    if G.is_directed():
        assert nested(G._pred, depth) == nested(H._pred, depth)
    assert list(G.edges(data=True, **({"keys": True} if G.is_multigraph() else {}))) == list(
        H.edges(data=True, **({"keys": True} if H.is_multigraph() else {}))
    )


def assert_all_kinds(mesh: hestore.Mesh) -> None:
    model = handle_model(mesh)
    for kind in KINDS:
        G = mesh.to_networkx(kind)
        assert_identical(G, expected(kind, *model))
        assert G.graph == {"mesh": mesh.name, "revision": mesh.revision, "kind": kind}


def edge_table(G: nx.Graph) -> dict:
    """key -> (sorted ends, data) for a multigraph; (sorted ends) -> data for a graph."""
    if G.is_multigraph():
        return {k: (tuple(sorted((u, v))), d) for u, v, k, d in G.edges(keys=True, data=True)}
    return {tuple(sorted((u, v))): d for u, v, d in G.edges(data=True)}


# -- small meshes, literal expectations ----------------------------------------------------


def test_empty_mesh(mesh):
    for kind, cls in zip(KINDS, (nx.MultiGraph, nx.Graph, nx.MultiDiGraph, nx.MultiGraph)):
        G = mesh.to_networkx(kind)
        assert type(G) is cls and G.number_of_nodes() == 0 and G.number_of_edges() == 0
        assert G.graph == {"mesh": "m", "revision": 0, "kind": kind}


def test_wireframe_loops_parallels_isolated(mesh):
    v = [mesh.add_vertex((float(i), 0.0, 0.0)) for i in range(4)] + [mesh.add_vertex()]
    e = [mesh.add_edge(v[0], v[1]), mesh.add_edge(v[0], v[1]), mesh.add_edge(v[1], v[1]), mesh.add_edge(v[2], v[0])]
    assert [x.id for x in e] == [0, 1, 2, 3]

    G = mesh.to_networkx()
    assert type(G) is nx.MultiGraph and G is mesh.to_networkx("multigraph")
    assert dict(G.nodes(data=True)) == {
        0: {"pos": (0.0, 0.0, 0.0)},
        1: {"pos": (1.0, 0.0, 0.0)},
        2: {"pos": (2.0, 0.0, 0.0)},
        3: {"pos": (3.0, 0.0, 0.0)},
        4: {"pos": None},
    }
    free = (None, None)
    assert edge_table(G) == {
        0: ((0, 1), {"halfedges": (0, 1), "polygons": free}),
        1: ((0, 1), {"halfedges": (2, 3), "polygons": free}),
        2: ((1, 1), {"halfedges": (4, 5), "polygons": free}),
        3: ((0, 2), {"halfedges": (6, 7), "polygons": free}),
    }
    # A self-loop counts twice, as for Vertex.degree.
    assert dict(G.degree()) == {0: 3, 1: 4, 2: 1, 3: 0, 4: 0} == {x.id: x.degree for x in v}
    assert list(nx.selfloop_edges(G, keys=True)) == [(1, 1, 2)]
    assert nx.number_connected_components(G) == 3

    S = mesh.to_networkx("graph")
    assert type(S) is nx.Graph and list(S.nodes) == [0, 1, 2, 3, 4]
    assert edge_table(S) == {
        (0, 1): {"multiplicity": 2, "edges": [0, 1]},
        (1, 1): {"multiplicity": 1, "edges": [2]},
        (0, 2): {"multiplicity": 1, "edges": [3]},
    }

    H = mesh.to_networkx("halfedge")
    assert type(H) is nx.MultiDiGraph and dict(H.nodes(data=True)) == dict(G.nodes(data=True))
    assert {k: (u, w, d) for u, w, k, d in H.edges(keys=True, data=True)} == {
        0: (0, 1, {"polygon": None, "edge": 0, "twin": 1}),
        1: (1, 0, {"polygon": None, "edge": 0, "twin": 0}),
        2: (0, 1, {"polygon": None, "edge": 1, "twin": 3}),
        3: (1, 0, {"polygon": None, "edge": 1, "twin": 2}),
        4: (1, 1, {"polygon": None, "edge": 2, "twin": 5}),
        5: (1, 1, {"polygon": None, "edge": 2, "twin": 4}),
        6: (2, 0, {"polygon": None, "edge": 3, "twin": 7}),
        7: (0, 2, {"polygon": None, "edge": 3, "twin": 6}),
    }
    assert dict(H.out_degree()) == {x.id: x.degree for x in v}

    D = mesh.to_networkx("dual")
    assert type(D) is nx.MultiGraph and D.number_of_nodes() == 0
    assert_all_kinds(mesh)


def test_one_gons_on_a_loop(mesh):
    v = mesh.add_vertex((0.0, 0.0, 0.0))
    loop = mesh.add_edge(v, v)
    h0, h1 = loop.halfedges()
    inner = mesh.add_polygon([h0])
    G = mesh.to_networkx()
    assert edge_table(G) == {0: ((0, 0), {"halfedges": (0, 1), "polygons": (inner.id, None)})}
    assert G.degree(0) == v.degree == 2
    D = mesh.to_networkx("dual")
    assert dict(D.nodes(data=True)) == {0: {"halfedge": 0}} and D.number_of_edges() == 0

    outer = mesh.add_polygon([h1])  # a sphere of two 1-gons
    assert edge_table(mesh.to_networkx()) == {0: ((0, 0), {"halfedges": (0, 1), "polygons": (0, 1)})}
    D = mesh.to_networkx("dual")
    assert dict(D.nodes(data=True)) == {0: {"halfedge": 0}, 1: {"halfedge": 1}}
    assert edge_table(D) == {0: ((inner.id, outer.id), {"halfedges": (0, 1), "vertices": (0, 0)})}
    H = mesh.to_networkx("halfedge")
    assert list(H.edges(keys=True, data=True)) == [
        (0, 0, 0, {"polygon": 0, "edge": 0, "twin": 1}),
        (0, 0, 1, {"polygon": 1, "edge": 0, "twin": 0}),
    ]
    assert edge_table(mesh.to_networkx("graph")) == {(0, 0): {"multiplicity": 1, "edges": [0]}}
    assert_all_kinds(mesh)


def test_two_gons_on_parallel_edges(mesh):
    a, b = mesh.add_vertex((0.0, 0.0, 0.0)), mesh.add_vertex((1.0, 0.0, 0.0))
    e0, e1 = mesh.add_edge(a, b), mesh.add_edge(a, b)
    p0 = mesh.add_polygon([e0.halfedges()[0], e1.halfedges()[1]])
    p1 = mesh.add_polygon([e1.halfedges()[0], e0.halfedges()[1]])
    assert (p0.id, p1.id) == (0, 1)
    assert edge_table(mesh.to_networkx()) == {
        0: ((0, 1), {"halfedges": (0, 1), "polygons": (0, 1)}),
        1: ((0, 1), {"halfedges": (2, 3), "polygons": (1, 0)}),
    }
    assert edge_table(mesh.to_networkx("graph")) == {(0, 1): {"multiplicity": 2, "edges": [0, 1]}}
    D = mesh.to_networkx("dual")
    assert edge_table(D) == {
        0: ((0, 1), {"halfedges": (0, 1), "vertices": (0, 1)}),
        1: ((0, 1), {"halfedges": (2, 3), "vertices": (0, 1)}),
    }
    assert D.number_of_edges(0, 1) == 2
    assert_all_kinds(mesh)


def test_dual_self_loops_polygon_meeting_itself(mesh):
    a, b, c = (mesh.add_vertex((float(i), 0.0, 0.0)) for i in range(3))
    e0 = mesh.add_edge(a, b)
    mesh.add_edge(b, c)
    start = e0.halfedges()[0]
    loop, h = [start], start.next
    while h != start:
        loop.append(h)
        h = h.next
    assert [x.id for x in loop] == [0, 2, 3, 1]  # around the path a-b-c
    p = mesh.add_polygon(loop)
    D = mesh.to_networkx("dual")
    assert dict(D.nodes(data=True)) == {p.id: {"halfedge": p.halfedge.id}}
    assert edge_table(D) == {
        0: ((0, 0), {"halfedges": (0, 1), "vertices": (0, 1)}),
        1: ((0, 0), {"halfedges": (2, 3), "vertices": (1, 2)}),
    }
    assert D.degree(p.id) == 4 and nx.number_of_selfloops(D) == 2
    assert edge_table(mesh.to_networkx()) == {
        0: ((0, 1), {"halfedges": (0, 1), "polygons": (0, 0)}),
        1: ((1, 2), {"halfedges": (2, 3), "polygons": (0, 0)}),
    }
    assert_all_kinds(mesh)


def test_polygons_meeting_at_a_vertex(mesh):
    pinch = mesh.add_vertex((0.0, 0.0, 0.0))
    left = [mesh.add_vertex((-1.0, 0.5, 0.0)), mesh.add_vertex((-1.0, -0.5, 0.0))]
    right = [mesh.add_vertex((1.0, -0.5, 0.0)), mesh.add_vertex((1.0, 0.5, 0.0))]
    p, q = mesh.add_polygon([pinch, *left]), mesh.add_polygon([pinch, *right])
    G, D = mesh.to_networkx(), mesh.to_networkx("dual")
    assert G.degree(pinch.id) == pinch.degree == 4 and nx.is_connected(G)
    assert list(D.nodes) == [p.id, q.id] and D.number_of_edges() == 0
    assert nx.number_connected_components(D) == 2
    assert set(nx.articulation_points(G)) == {pinch.id}
    assert_all_kinds(mesh)


def test_components_and_a_hole(mesh):
    V, Q = grid(mesh, 3)
    mesh.remove_polygon(Q[1][1])  # the centre quad: a hole
    corners = [mesh.add_vertex(xyz) for xyz in ((5.0, 0.0, 0.0), (6.0, 0.0, 0.0), (5.0, 1.0, 0.0))]
    tri = mesh.add_polygon(corners)
    mesh.add_vertex((9.0, 9.0, 9.0))  # isolated
    G, D = mesh.to_networkx(), mesh.to_networkx("dual")
    assert nx.number_connected_components(G) == 3
    assert G.number_of_nodes() == 16 + 3 + 1 and G.number_of_edges() == 24 + 3
    # The ring of eight quads around the hole, and the triangle apart.
    assert D.number_of_nodes() == 9 and D.number_of_edges() == 8
    assert sorted(len(c) for c in nx.connected_components(D)) == [1, 8]
    assert [len(c) for c in nx.cycle_basis(nx.Graph(D))] == [8]
    assert Q[1][1].id not in D and tri.id in D
    hole_edges = {e.id for e in mesh.edges() if any(h.polygon is None for h in e.halfedges())}
    assert all(k not in hole_edges for _, _, k in D.edges(keys=True))
    assert_all_kinds(mesh)


def test_demo_mesh(store):
    mesh = demo.run(store, out=lambda line: None)
    assert_all_kinds(mesh)
    G = mesh.to_networkx()
    assert G.number_of_edges() == mesh.counts().edges and G.number_of_nodes() == mesh.counts().vertices
    assert dict(G.degree()) == {v.id: v.degree for v in mesh.vertices()}
    D = mesh.to_networkx("dual")
    assert D.number_of_nodes() == mesh.counts().polygons
    assert nx.number_of_selfloops(mesh.to_networkx()) == 1


def test_ids_with_gaps(mesh):
    V, Q = grid(mesh, 3)
    mesh.remove_vertex(V[0][0])
    mesh.remove_edge(mesh.find_halfedge(V[2][1], V[2][2]).edge)
    mesh.remove_polygon(Q[0][2])
    loop = mesh.add_edge(V[3][3], V[3][3])
    mesh.add_edge(V[3][3], V[0][3])
    mesh.add_polygon([loop.halfedges()[0]])
    assert_all_kinds(mesh)


# -- networkx algorithms: the view against a plain copy ---------------------------------------


def mixed(mesh: hestore.Mesh) -> None:
    """Four components: a grid with a hole, a notch, a wire tail and a loop; parallel edges
    with a 2-gon and a 1-gon (every degree even: Eulerian); a wire edge; an isolated vertex."""
    V, Q = grid(mesh, 4, 3)
    mesh.remove_polygon(Q[1][1])
    mesh.remove_edge(mesh.find_halfedge(V[3][0], V[3][1]).edge)
    mesh.add_edge(V[4][0], mesh.add_vertex((5.0, -1.0, 0.0)))
    a, b, c = (mesh.add_vertex((7.0 + i, 0.0, 0.0)) for i in range(3))
    mesh.add_edge(a, b)
    mesh.add_edge(a, b)
    e1, e2 = mesh.add_edge(b, c), mesh.add_edge(b, c)
    mesh.add_polygon([e1.halfedges()[0], e2.halfedges()[1]])
    loop = mesh.add_edge(c, c)
    mesh.add_polygon([loop.halfedges()[0]])
    mesh.add_edge(V[0][3], V[0][3])
    d, f = mesh.add_vertex((0.0, 9.0, 0.0)), mesh.add_vertex((1.0, 9.0, 0.0))
    mesh.add_edge(d, f)
    mesh.add_vertex()


def test_algorithms_equal_on_a_plain_copy(mesh):
    mixed(mesh)
    G = mesh.to_networkx()
    P = nx.MultiGraph()  # the plain copy, from the edge handles
    P.add_nodes_from((v.id, {"pos": v.position}) for v in mesh.vertices())
    for e in mesh.edges():
        h0, h1 = e.halfedges()
        P.add_edge(
            h0.origin.id, h1.origin.id, key=e.id, halfedges=(h0.id, h1.id), polygons=(pid(h0.polygon), pid(h1.polygon))
        )
    assert_identical(G, P)
    assert nx.number_connected_components(G) == nx.number_connected_components(P) == 4
    assert [sorted(c) for c in nx.connected_components(G)] == [sorted(c) for c in nx.connected_components(P)]
    assert dict(nx.all_pairs_shortest_path_length(G)) == dict(nx.all_pairs_shortest_path_length(P))
    nodes = list(P)
    for s, t in itertools.product(nodes[::3], nodes[::5]):
        if nx.has_path(P, s, t):
            assert nx.shortest_path(G, s, t) == nx.shortest_path(P, s, t)  # tie-breaks too
    def weight(u, v, d):
        return 1 + min(d)

    assert nx.shortest_path(G, 0, 5, weight=weight) == nx.shortest_path(P, 0, 5, weight=weight)
    assert sorted(map(len, nx.cycle_basis(nx.Graph(G)))) == sorted(map(len, nx.cycle_basis(nx.Graph(P))))
    assert nx.cycle_basis(nx.Graph(G)) == nx.cycle_basis(nx.Graph(P))
    assert list(G.degree()) == list(P.degree())
    assert dict(G.degree()) == {v.id: v.degree for v in mesh.vertices()}
    assert nx.is_eulerian(G) == nx.is_eulerian(P)
    LG, LP = nx.line_graph(G), nx.line_graph(P)
    assert (LG.number_of_nodes(), LG.number_of_edges()) == (LP.number_of_nodes(), LP.number_of_edges())
    assert LG.number_of_nodes() == mesh.counts().edges
    big = max(nx.connected_components(P), key=len)
    assert nx.betweenness_centrality(G.subgraph(big)) == nx.betweenness_centrality(P.subgraph(big))
    assert nx.to_dict_of_dicts(G) == nx.to_dict_of_dicts(P)
    assert nx.MultiGraph(G).adj == P.adj and nx.MultiGraph(G).nodes == P.nodes  # an editable copy
    assert not nx.is_eulerian(G)
    knot = nx.node_connected_component(P, nodes[-4])  # the parallel edges, the 2-gon and the 1-gon
    assert len(knot) == 3 and nx.is_eulerian(G.subgraph(knot)) and nx.is_eulerian(P.subgraph(knot))
    circuit = list(nx.eulerian_circuit(G.subgraph(knot), keys=True))
    assert circuit == list(nx.eulerian_circuit(P.subgraph(knot), keys=True))


# -- frozen, cached, committed ----------------------------------------------------------------


def test_frozen(mesh):
    mixed(mesh)
    for kind in KINDS:
        G = mesh.to_networkx(kind)
        assert nx.is_frozen(G)
        u = next(iter(G))
        for mutate in (
            lambda: G.add_node(-1),
            lambda: G.add_edge(u, u),
            lambda: G.remove_node(u),
            lambda: G.add_edges_from([(u, u)]),
            lambda: G.remove_edges_from(list(G.edges())[:1]),
            lambda: G.clear(),
        ):
            with pytest.raises(nx.NetworkXError, match="Frozen"):
                mutate()
        copy = type(G)(G)  # the way to an editable graph
        copy.add_node(-1)
        assert -1 not in G


def test_cached_per_revision(mesh, store):
    a, b = mesh.add_vertex(), mesh.add_vertex()
    mesh.add_edge(a, b)
    graphs_before = {kind: mesh.to_networkx(kind) for kind in KINDS}
    assert len({id(G) for G in graphs_before.values()}) == 4
    for kind, G in graphs_before.items():
        assert mesh.to_networkx(kind) is G
    rev = mesh.revision
    with pytest.raises(InvalidInputError):  # refused: the revision stays, and so does the graph
        mesh.add_polygon([a.halfedge, a.halfedge])
    assert mesh.revision == rev and mesh.to_networkx() is graphs_before["multigraph"]

    mesh.add_edge(b, b)
    G = mesh.to_networkx()
    assert G is not graphs_before["multigraph"] and G.graph["revision"] == rev + 1
    assert G.number_of_edges() == 2 and graphs_before["multigraph"].number_of_edges() == 1  # the old one is untouched
    assert mesh.to_networkx() is G
    assert mesh.to_networkx("dual") is not graphs_before["dual"]

    # Another mesh at the same revision has its own graphs.
    other = store.create_mesh("other")
    for _ in range(mesh.revision):
        other.add_vertex()
    assert other.revision == mesh.revision
    assert other.to_networkx().number_of_edges() == 0 and mesh.to_networkx() is G
    # So does another store on the same database.
    with hestore.open(store.url) as again:
        H = again.mesh("m").to_networkx()
        assert H is not G
        assert_identical(H, G)


def test_committed_state_inside_a_block(mesh, store):
    a, b = mesh.add_vertex((0.0, 0.0, 0.0)), mesh.add_vertex((1.0, 0.0, 0.0))
    mesh.add_edge(a, b)
    before = {kind: mesh.to_networkx(kind) for kind in KINDS}
    with store.transaction():
        c = mesh.add_vertex((2.0, 0.0, 0.0))
        mesh.add_polygon([a, b, c])
        assert mesh.revision == before["multigraph"].graph["revision"] + 1  # the block's own view
        for kind in KINDS:
            assert mesh.to_networkx(kind) is before[kind]  # committed revision unchanged
        assert list(mesh.to_networkx()) == [0, 1]
    G = mesh.to_networkx()
    assert G is not before["multigraph"] and list(G) == [0, 1, 2]
    assert_all_kinds(mesh)

    # Not cached when the block starts: built through a second connection.
    store.session.caches.clear()
    with store.transaction():
        mesh.add_vertex()
        mesh.remove_vertex(c)
        for kind in KINDS:
            G = mesh.to_networkx(kind)
            assert_identical(G, committed_oracle(store, kind))
            assert G.number_of_nodes() == (1 if kind == "dual" else 3)
            assert mesh.to_networkx(kind) is G
        committed = mesh.to_networkx()
    assert list(mesh.to_networkx()) == [0, 1, 3] and mesh.to_networkx("dual").number_of_nodes() == 0
    assert list(committed) == [0, 1, 2]

    # A rolled-back block leaves the committed graph as it was.
    G = mesh.to_networkx()
    with pytest.raises(RuntimeError):
        with store.transaction():
            mesh.remove_vertex(a)
            assert mesh.to_networkx() is G
            raise RuntimeError
    assert mesh.to_networkx() is G


def committed_oracle(store: hestore.Store, kind: str) -> nx.Graph:
    """The oracle of the committed state, read through a store of its own."""
    with hestore.open(store.url) as other:
        return from_handles(other.mesh("m"), kind)


def test_in_memory_store_shows_the_block():
    store = hestore.open("sqlite://")
    mesh = store.create_mesh("m")
    a, b = mesh.add_vertex(), mesh.add_vertex()
    mesh.add_edge(a, b)
    G = mesh.to_networkx()
    with pytest.raises(RuntimeError):
        with store.transaction():
            mesh.add_edge(b, b)
            # One connection only: the block's own state, and not cached.
            inside = mesh.to_networkx()
            assert inside.number_of_edges() == 2 and inside.graph["revision"] == G.graph["revision"] + 1
            assert mesh.to_networkx() is not inside
            raise RuntimeError
    assert mesh.to_networkx() is G and G.number_of_edges() == 1
    # The rolled-back revision number comes again for another state: no stale graph.
    mesh.add_vertex()
    assert mesh.to_networkx().graph["revision"] == inside.graph["revision"]
    assert mesh.to_networkx().number_of_edges() == 1 and mesh.to_networkx().number_of_nodes() == 3
    store.close()


def test_errors(mesh, store):
    mesh.add_vertex()
    with pytest.raises(InvalidInputError, match="'multigraph', 'graph', 'halfedge', 'dual'"):
        mesh.to_networkx("digraph")
    with pytest.raises(InvalidInputError):
        graphs.to_networkx(identity(mesh), kind=None)
    G = mesh.to_networkx()
    store.delete_mesh("m")
    with pytest.raises(MeshNotFoundError, match="deleted"):
        mesh.to_networkx()
    with pytest.raises(MeshNotFoundError):
        graphs.to_networkx(identity(mesh), "dual")
    assert G.number_of_nodes() == 1
    store.close()
    with pytest.raises(HestoreError, match="closed"):
        mesh.to_networkx()


def test_dangling_reference_is_reported(mesh, store):
    a, b = mesh.add_vertex(), mesh.add_vertex()
    mesh.add_edge(a, b)
    h = schema.halfedges
    with store.session.reading() as conn:
        conn.execute(h.update().where(h.c.mesh_id == mesh.id, h.c.id == 1).values(origin=77))
        conn.execute(schema.meshes.update().values(revision=schema.meshes.c.revision + 1))
    for kind in ("multigraph", "graph", "halfedge"):
        with pytest.raises(InvariantViolationError, match="REF halfedge 1: origin = 77, but there is no vertex 77"):
            mesh.to_networkx(kind)
    assert mesh.to_networkx("dual").number_of_nodes() == 0


# -- random edits: a hand-kept MultiGraph alongside -----------------------------------------


class GraphMachine(RuleBasedStateMachine):
    """Random edits on a stored mesh; ``self.G`` is an ``nx.MultiGraph`` edited by hand to match.

    The model beside it: ``ends`` (edge -> (a, b, h0, h1)), ``face``
    (half-edge -> polygon or None), ``loops`` (polygon -> its half-edges),
    ``anchor`` (polygon -> its stored half-edge, recorded when made).
    """

    url = ""
    counter = itertools.count()

    @initialize(n=st.integers(1, 4))
    def open_mesh(self, n):
        self.store = hestore.open(self.url)
        self.mesh = self.store.create_mesh(f"g{next(self.counter)}")
        self.G = nx.MultiGraph()
        self.ends: dict[int, tuple[int, int, int, int]] = {}
        self.face: dict[int, int | None] = {}
        self.loops: dict[int, list[int]] = {}
        self.anchor: dict[int, int] = {}
        self.edge_of: dict[int, int] = {}
        self.last = None
        for i in range(n):
            self.add_vertex(placed=i % 2 == 0)

    def teardown(self):
        if getattr(self, "store", None) is not None:
            self.store.close()

    # -- model effects ----------------------------------------------------------

    def _sides(self, e: int) -> None:
        a, b, h0, h1 = self.ends[e]
        self.G.edges[a, b, e]["polygons"] = (self.face[h0], self.face[h1])

    def _new_edge(self, e) -> None:
        h0, h1 = e.halfedges()
        a, b = h0.origin.id, h1.origin.id
        self.ends[e.id] = (a, b, h0.id, h1.id)
        self.face[h0.id] = self.face[h1.id] = None
        self.edge_of[h0.id] = self.edge_of[h1.id] = e.id
        self.G.add_edge(a, b, key=e.id, halfedges=(h0.id, h1.id), polygons=(None, None))

    def _drop_polygon(self, p: int) -> None:
        for h in self.loops.pop(p):
            self.face[h] = None
            self._sides(self.edge_of[h])
        del self.anchor[p]

    def _drop_edge(self, e: int) -> None:
        a, b, h0, h1 = self.ends[e]
        for p in {self.face[h0], self.face[h1]} - {None}:
            self._drop_polygon(p)
        del self.ends[e], self.face[h0], self.face[h1], self.edge_of[h0], self.edge_of[h1]
        self.G.remove_edge(a, b, key=e)

    # -- rules ------------------------------------------------------------------

    @precondition(lambda self: len(self.G) < 6)  # few vertices: more edges between them
    @rule(placed=st.booleans())
    def add_vertex(self, placed):
        pos = (float(len(self.G)), 0.5, 0.0) if placed else None
        v = self.mesh.add_vertex(pos)
        self.G.add_node(v.id, pos=pos)

    @precondition(lambda self: len(self.G) > 0)
    @rule(i=st.integers(0, 100), j=st.integers(0, 100))
    def add_edge(self, i, j):
        nodes = sorted(self.G)
        a, b = nodes[i % len(nodes)], nodes[j % len(nodes)]
        if (j // len(nodes)) % 3 == 0 and len(self.G[a]):
            b = next(iter(self.G[a]))  # now and then a parallel edge (or a second loop)
        try:
            e = self.mesh.add_edge(self.mesh.vertex(a), self.mesh.vertex(b))
        except TopologyError:
            return
        self._new_edge(e)
        assert self.ends[e.id][:2] == (a, b)  # the edge's half-edge runs a -> b

    @precondition(lambda self: any(p is None for p in self.face.values()))
    @rule(i=st.integers(0, 100), cut=st.booleans())
    def add_polygon(self, i, cut):
        free = sorted(h for h, p in self.face.items() if p is None)
        start = self.mesh.halfedge(free[i % len(free)])
        loop, h = [start], start.next
        while h != start and len(loop) <= 12:
            loop.append(h)
            h = h.next
        if cut or h != start:
            # A triangle on the free chain's first three corners instead (by vertices).
            loop = [x.origin for x in (loop * 3)[:3]]
        try:
            p = self.mesh.add_polygon(loop)
        except (TopologyError, InvalidInputError):  # e.g. a corner twice
            return
        hs = [x.id for x in p.halfedges()]
        for x in hs:
            if x not in self.face:  # an edge the polygon made between two corners
                self._new_edge(self.mesh.halfedge(x).edge)
        for x in hs:
            assert self.face[x] is None
            self.face[x] = p.id
        for x in hs:
            self._sides(self.edge_of[x])
        self.loops[p.id] = hs
        self.anchor[p.id] = p.halfedge.id
        assert self.anchor[p.id] in hs

    @precondition(lambda self: self.loops)
    @rule(i=st.integers(0, 100))
    def remove_polygon(self, i):
        p = sorted(self.loops)[i % len(self.loops)]
        self.mesh.remove_polygon(self.mesh.polygon(p))
        self._drop_polygon(p)

    @precondition(lambda self: self.ends)
    @rule(i=st.integers(0, 100))
    def remove_edge(self, i):
        e = sorted(self.ends)[i % len(self.ends)]
        self.mesh.remove_edge(self.mesh.edge(e))
        self._drop_edge(e)

    @precondition(lambda self: len(self.G) > 0)
    @rule(i=st.integers(0, 100), now=st.integers(0, 2))
    def remove_vertex(self, i, now):
        if now:  # only one time in three: it empties the mesh fast
            return
        v = sorted(self.G)[i % len(self.G)]
        self.mesh.remove_vertex(self.mesh.vertex(v))
        for e in sorted(e for e, (a, b, _h0, _h1) in self.ends.items() if v in (a, b)):
            self._drop_edge(e)
        self.G.remove_node(v)

    # -- the check ----------------------------------------------------------------

    @invariant()
    def graphs_match(self):
        if getattr(self, "mesh", None) is None:
            return
        G = self.mesh.to_networkx()
        revision = self.mesh.revision
        assert G.graph == {"mesh": self.mesh.name, "revision": revision, "kind": "multigraph"}
        if self.last is not None:
            assert (G is self.last[1]) == (revision == self.last[0])
        self.last = (revision, G)
        # The hand-kept graph: same nodes, edges, keys and attributes.
        assert dict(G.nodes(data=True)) == dict(self.G.nodes(data=True))
        assert edge_table(G) == edge_table(self.G)
        assert G.adj == self.G.adj
        assert dict(G.degree()) == dict(self.G.degree())
        # And every kind, in id order, from the model.
        model = (dict(self.G.nodes(data="pos")), self.ends, self.face, self.anchor)
        for kind in KINDS:
            assert_identical(self.mesh.to_networkx(kind), expected(kind, *model))


#: Shrinking replays against the database many times; set HESTORE_SHRINK=1 for it.
SHRINK = os.environ.get("HESTORE_SHRINK", "") not in ("", "0")


@pytest.mark.slow
def test_graph_state_machine(db_url, backend):
    machine = type("Machine", (GraphMachine,), {"url": db_url})
    run_state_machine_as_test(
        machine,
        settings=settings(
            max_examples=30 if backend == "sqlite" else 10,
            stateful_step_count=25,
            deadline=None,
            suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much],
            phases=[Phase.explicit, Phase.reuse, Phase.generate] + ([Phase.shrink] if SHRINK else []),
            database=None,
        ),
    )


# -- attrs: properties and "length" on nodes and edges ------------------------------------


def right_triangle(mesh: hestore.Mesh) -> dict:
    """From ``a`` to ``c``: the legs of a right triangle (9 + 12, two edges) or its hypotenuse
    (15), cut at ``p`` and ``q`` into three edges of 5 (each a 3-4-5 triangle's hypotenuse).

    The pentagon a b c q p; a second polygon a p x below the hypotenuse's first third (for the
    dual), and ``u``, a vertex without a position, joined to ``c`` by a wire edge.
    """
    xyz = {"a": (0, 0, 0), "b": (9, 0, 0), "c": (9, 12, 0), "q": (6, 8, 0), "p": (3, 4, 0), "x": (0, 4, 0)}
    v = {name: mesh.add_vertex(position) for name, position in xyz.items()}
    v["u"] = mesh.add_vertex()
    pentagon = mesh.add_polygon([v[n] for n in "abcqp"])
    corner = mesh.add_polygon([v["a"], v["p"], v["x"]])
    wire = mesh.add_edge(v["c"], v["u"])
    return {**v, "pentagon": pentagon, "corner": corner, "wire": wire}


def edge_between(a: hestore.Vertex, b: hestore.Vertex) -> hestore.Edge:
    return a.mesh.find_halfedge(a, b).edge


def test_attrs_length_by_hand_and_weighted_path(mesh):
    t = right_triangle(mesh)
    a, b, c, p, q, x, u = (t[n].id for n in "abcpqxu")
    by_hand = {
        (a, b): 9.0, (b, c): 12.0, (c, q): 5.0, (q, p): 5.0, (p, a): 5.0,  # sqrt(3² + 4²) = 5
        (p, x): 3.0, (x, a): 4.0, (c, u): None,  # u has no position
    }  # fmt: skip
    G = mesh.to_networkx(attrs=["length"])
    assert {k: d["length"] for u_, v_, k, d in G.edges(keys=True, data=True)} == {
        edge_between(mesh.vertex(e0), mesh.vertex(e1)).id: length for (e0, e1), length in by_hand.items()
    }
    assert all(type(d["length"]) is float for *_, d in G.edges(data=True) if d["length"] is not None)
    assert G.edges[c, u, t["wire"].id]["length"] is None
    # The view's own attributes stay, and come first.
    assert list(G.edges[a, b, edge_between(t["a"], t["b"]).id]) == ["halfedges", "polygons", "length"]

    assert nx.shortest_path(G, a, c) == [a, b, c]  # fewest edges: the legs
    assert nx.shortest_path(G, a, c, weight="length") == [a, p, q, c]  # shortest: the hypotenuse
    assert nx.shortest_path_length(G, a, c, weight="length") == pytest.approx(15.0)
    assert nx.shortest_path_length(G, b, x, weight="length") == pytest.approx(13.0)  # b a x: 9 + 4
    for kind in ("graph", "halfedge"):
        H = mesh.to_networkx(kind, attrs=["length"])
        assert nx.shortest_path(H, a, c, weight="length") == [a, p, q, c], kind
        assert nx.shortest_path(H, c, a, weight="length") == [c, q, p, a], kind
    H = mesh.to_networkx("halfedge", attrs="length")  # one name as a string
    assert {h: d["length"] for _, _, h, d in H.edges(keys=True, data=True)} == {
        h.id: G.edges[h.origin.id, h.target.id, h.edge.id]["length"] for h in mesh.halfedges()
    }

    # The dual's edges: the length of the primal edge the two polygons share (p-a).
    D = mesh.to_networkx("dual", attrs=["length"])
    assert list(D.edges(keys=True, data="length")) == [
        (t["pentagon"].id, t["corner"].id, edge_between(t["p"], t["a"]).id, 5.0)
    ]
    assert D.nodes[t["pentagon"].id] == {"halfedge": t["pentagon"].halfedge.id}

    # A self-loop has length 0; a moved vertex changes the lengths at the next revision.
    loop = mesh.add_edge(t["b"], t["b"])
    mesh.set_position(t["b"], (9, 40, 0))
    G2 = mesh.to_networkx(attrs=["length"])
    assert G2.edges[b, b, loop.id]["length"] == 0.0
    assert G2.edges[a, b, edge_between(t["a"], t["b"]).id]["length"] == pytest.approx(41.0)  # 9-40-41
    assert G.edges[a, b, edge_between(t["a"], t["b"]).id]["length"] == 9.0  # the old graph is untouched


def declare_everything(mesh: hestore.Mesh, t: dict) -> None:
    """Properties of every kind on `right_triangle`, some set, some not."""
    mesh.add_property("vertex", "t", "float64", default=0.0)
    mesh.add_property("vertex", "rgb", "int64", shape=(3,))  # no default: set on a only
    mesh.add_property("vertex", "both", "str", default="v")
    mesh.add_property("edge", "both", "bool", default=False)
    mesh.add_property("edge", "w", "int64", default=10)
    mesh.add_property("edge", "tag", "str")  # no default
    mesh.add_property("halfedge", "uv", "float64", shape=(2,))  # no default
    mesh.add_property("polygon", "label", "str", default="")
    mesh.add_property("polygon", "n", "float64", shape=(3,), default=(0.0, 0.0, 1.0))
    with mesh.store.transaction():
        t["a"]["t"] = 21.5
        t["a"]["rgb"] = (255, 0, 7)
        t["c"]["both"] = "ç"
        edge_between(t["a"], t["b"])["w"] = 3
        edge_between(t["a"], t["b"])["both"] = True
        edge_between(t["b"], t["c"])["tag"] = "leg"
        mesh.find_halfedge(t["a"], t["b"])["uv"] = (0.25, 0.5)
        t["pentagon"]["label"] = "big"
        t["corner"]["n"] = (0.0, 1.0, 0.0)


def with_props(data: dict, handle, names: list[str]) -> dict:
    """``data`` and each property's value as ``handle[name]`` says; None (unset, no default): absent."""
    out = dict(data)
    for name in names:
        value = handle[name]
        if value is not None:
            out[name] = value
    return out


def test_attrs_on_every_kind(mesh):
    t = right_triangle(mesh)
    declare_everything(mesh, t)
    plain = {kind: mesh.to_networkx(kind) for kind in KINDS}

    for kind in ("multigraph", "graph", "halfedge"):
        names = ["t", "rgb", "both", "w", "tag"] + (["uv"] if kind == "halfedge" else [])
        G = mesh.to_networkx(kind, attrs=names)
        assert G.graph == plain[kind].graph
        for v in mesh.vertices():
            assert G.nodes[v.id] == with_props(plain[kind].nodes[v.id], v, ["t", "rgb", "both"]), (kind, v)
        if kind == "multigraph":
            for e in mesh.edges():
                u, w = (h.origin.id for h in e.halfedges())
                assert G.edges[u, w, e.id] == with_props(plain[kind].edges[u, w, e.id], e, ["both", "w", "tag"])
        elif kind == "halfedge":
            for h in mesh.halfedges():
                want = with_props(plain[kind].edges[h.origin.id, h.target.id, h.id], h.edge, ["both", "w", "tag"])
                want = with_props(want, h, ["uv"])
                assert G.edges[h.origin.id, h.target.id, h.id] == want, h
        else:
            for u, w, d in plain[kind].edges(data=True):
                [e] = d["edges"]  # no parallel edges here
                assert G.edges[u, w] == with_props(d, mesh.edge(e), ["both", "w", "tag"])
        # Same adjacency order as the plain view: only attributes were added.
        assert list(G.edges) == list(plain[kind].edges)

    D = mesh.to_networkx("dual", attrs=["label", "n", "w", "tag", "both"])
    for p in mesh.polygons():
        assert D.nodes[p.id] == with_props(plain["dual"].nodes[p.id], p, ["label", "n"])
    for u, w, k, d in plain["dual"].edges(keys=True, data=True):
        assert D.edges[u, w, k] == with_props(d, mesh.edge(k), ["w", "tag", "both"])

    # Python values: scalars of the dtype, tuples for shaped properties, str as stored.
    a = t["a"].id
    G = mesh.to_networkx(attrs=["t", "rgb", "both"])
    assert G.nodes[a] == {"pos": (0.0, 0.0, 0.0), "t": 21.5, "rgb": (255, 0, 7), "both": "v"}
    assert type(G.nodes[a]["rgb"][0]) is int and type(G.nodes[a]["t"]) is float
    assert G.nodes[t["c"].id]["both"] == "ç"
    assert "rgb" not in G.nodes[t["b"].id]  # unset, no default: absent, not None
    assert G.edges[a, t["b"].id, edge_between(t["a"], t["b"]).id]["both"] is True
    assert D.nodes[t["corner"].id]["n"] == (0.0, 1.0, 0.0) and D.nodes[t["pentagon"].id]["n"] == (0.0, 0.0, 1.0)
    assert D.nodes[t["pentagon"].id]["label"] == "big" and D.nodes[t["corner"].id]["label"] == ""
    H = mesh.to_networkx("halfedge", attrs=["uv"])
    assert [d for *_, d in H.edges(data="uv") if d is not None] == [(0.25, 0.5)]
    assert sum("uv" in d for *_, d in H.edges(data=True)) == 1


def test_attrs_on_merged_parallel_edges(mesh):
    a, b, c = (mesh.add_vertex((float(i), 0.0, 0.0)) for i in range(3))
    e = [mesh.add_edge(a, b), mesh.add_edge(a, b), mesh.add_edge(b, a), mesh.add_edge(b, c)]
    mesh.add_property("edge", "w", "float64")
    mesh.add_property("edge", "k", "int64", default=7)
    mesh.add_property("edge", "tag", "str")
    mesh.add_property("edge", "v", "int64", shape=(2,))
    with mesh.store.transaction():
        e[1]["w"], e[2]["w"] = 4.5, 2.5  # e[0] unset: the smallest set value
        e[2]["k"] = 3
        e[2]["tag"], e[1]["tag"] = "two", "one"  # the lowest edge id that has one
        e[2]["v"] = (1, 2)
    G = mesh.to_networkx("graph", attrs=["w", "k", "tag", "v", "length"])
    assert G.edges[a.id, b.id] == {
        "multiplicity": 3, "edges": [e[0].id, e[1].id, e[2].id],
        "w": 2.5, "k": 3, "tag": "one", "v": (1, 2), "length": 1.0,
    }  # fmt: skip
    assert G.edges[b.id, c.id] == {"multiplicity": 1, "edges": [e[3].id], "k": 7, "length": 1.0}
    # The multigraph and the graph agree on weighted paths: networkx takes the lightest parallel edge.
    M = mesh.to_networkx(attrs=["w", "k"])
    assert nx.shortest_path_length(M, a.id, c.id, weight="k") == nx.shortest_path_length(G, a.id, c.id, weight="k")


def test_attrs_unknown_and_refused_names(mesh, store):
    t = right_triangle(mesh)
    declare_everything(mesh, t)
    for kind, name in [
        ("multigraph", "nope"), ("graph", "nope"), ("halfedge", "nope"), ("dual", "nope"),
        ("multigraph", "uv"), ("graph", "label"),  # kinds that do not go on these views
        ("dual", "t"), ("dual", "rgb"), ("dual", "uv"), ("multigraph", "Length"),
    ]:  # fmt: skip
        with pytest.raises(hestore.PropertyNotFoundError, match=repr(name)) as caught:
            mesh.to_networkx(kind, attrs=["t", name] if kind != "dual" else [name])
        assert isinstance(caught.value, KeyError) and isinstance(caught.value, HestoreError)
    # A name the view sets itself cannot be replaced.
    mesh.add_property("vertex", "pos", "float64")
    mesh.add_property("edge", "multiplicity", "int64")
    with pytest.raises(InvalidInputError, match="'pos'"):
        mesh.to_networkx(attrs=["pos"])
    with pytest.raises(InvalidInputError, match="'multiplicity'"):
        mesh.to_networkx("graph", attrs=["multiplicity"])
    assert mesh.to_networkx(attrs=["multiplicity"]).number_of_edges() == 8  # fine on the multigraph
    for bad in (7, [1], {"t": 1}, b"t"):
        with pytest.raises(InvalidInputError, match="attrs"):
            mesh.to_networkx(attrs=bad)
    # An edge property named "length" is that property, not the derived length.
    mesh.add_property("edge", "length", "int64", default=1)
    G = mesh.to_networkx(attrs=["length"])
    assert {d for *_, d in G.edges(data="length")} == {1}
    store.delete_mesh("m")
    with pytest.raises(hestore.MeshNotFoundError):
        mesh.to_networkx(attrs=["t"])


def test_attrs_cached_per_revision_and_committed_only(mesh, store):
    t = right_triangle(mesh)
    declare_everything(mesh, t)
    a = t["a"].id
    plain = mesh.to_networkx()
    G = mesh.to_networkx(attrs=["t", "length"])
    assert mesh.to_networkx(attrs=["t", "length"]) is G
    assert mesh.to_networkx(attrs=("t", "length", "t")) is G  # the same names
    assert mesh.to_networkx() is plain and "t" not in plain.nodes[a]  # the plain view is its own
    L = mesh.to_networkx(attrs=["length", "t"])
    assert L is not G and list(L.nodes[a]) == ["pos", "t"]  # "length" goes on edges only

    revision = mesh.revision
    t["a"]["t"] = -1.0  # a property write is an edit: a new revision, a new graph
    assert mesh.revision == revision + 1
    G2 = mesh.to_networkx(attrs=["t", "length"])
    assert G2 is not G and G2.nodes[a]["t"] == -1.0 and G2.graph["revision"] == revision + 1
    assert G.nodes[a]["t"] == 21.5  # handed out before: the old state
    assert mesh.to_networkx() is not plain

    # Inside a block, the committed values (as for the connectivity).
    with store.transaction():
        t["a"]["t"] = 99.0
        mesh.add_property("vertex", "fresh", "int64", default=0)
        inside = mesh.to_networkx(attrs=["t", "length"])
        assert inside is G2 and inside.nodes[a]["t"] == -1.0
        with pytest.raises(hestore.PropertyNotFoundError):
            mesh.to_networkx(attrs=["fresh"])
        store.session.caches.clear()
        assert mesh.to_networkx(attrs=["t"]).nodes[a]["t"] == -1.0
    assert mesh.to_networkx(attrs=["t", "fresh"]).nodes[a] == {"pos": (0.0, 0.0, 0.0), "t": 99.0, "fresh": 0}

    # Removing a property: the next graph cannot have it.
    mesh.remove_property("vertex", "t")
    with pytest.raises(hestore.PropertyNotFoundError):
        mesh.to_networkx(attrs=["t"])


def test_attrs_cache_keeps_few_graphs(mesh, store):
    right_triangle(mesh)
    mesh.add_property("vertex", "t", "float64", default=0.0)
    cache = store.session.caches.setdefault(graphs.CACHE, {})
    for names in (["t"], ["length"], ["t", "length"], ["length", "t"], ["t", "length", "length"]):
        mesh.to_networkx(attrs=names)
    mesh.to_networkx()
    mine = [k for k in cache if k[0] == mesh.id]
    assert len(mine) == 1 + 4  # the plain graph and four lists of attrs
    mesh.add_vertex()  # a new revision: the next graph drops those of the old one
    mesh.to_networkx(attrs=["t"])
    assert [k for k in cache if k[0] == mesh.id] == [(mesh.id, "multigraph", ("t",))]


def test_attrs_halfedge_property_before_edge_property(mesh):
    a, b = mesh.add_vertex((0, 0, 0)), mesh.add_vertex((0, 3, 4))
    e = mesh.add_edge(a, b)
    mesh.add_property("edge", "side", "str", default="edge")
    mesh.add_property("halfedge", "side", "str")
    h0, h1 = e.halfedges()
    h0["side"] = "half"
    H = mesh.to_networkx("halfedge", attrs=["side", "length"])
    # The half-edge property wins where both are declared; unset without default: absent.
    assert H.edges[h0.origin.id, h0.target.id, h0.id] == {
        "polygon": None, "edge": e.id, "twin": h1.id, "side": "half", "length": 5.0,
    }  # fmt: skip
    assert "side" not in H.edges[h1.origin.id, h1.target.id, h1.id]
    assert mesh.to_networkx(attrs=["side"]).edges[a.id, b.id, e.id]["side"] == "edge"
