"""The networkx views of a mesh (SPEC §6).

This module owns `to_networkx`: the four graphs a mesh's connectivity is
analysed as — ``"multigraph"`` (vertices and edges, self-loops and parallel
edges kept), ``"graph"`` (parallel edges merged), ``"halfedge"`` (one directed
edge per half-edge) and ``"dual"`` (polygons, joined across the edges between
them). Each is a plain, frozen networkx graph of the mesh's *committed* state,
cached per store, mesh and kind, and rebuilt only when the mesh's committed
revision has changed.

How a graph is made: the columns it needs are read in bulk, in one snapshot
together with the revision (`hestore.columns.read_columns`); the grouping of
edges by end points and the insertion order are worked out with numpy; then
networkx's own adjacency dicts (``G._node``, ``G._adj``, and ``G._pred`` for
the directed kind) are filled directly by comprehensions over ``tolist()``
columns, with the collector paused. The result is an ordinary
`networkx.MultiGraph` (or `~networkx.Graph`, `~networkx.MultiDiGraph`) — the
same dicts, in the same order, as adding the nodes in id order and then the
edges in id order with ``add_edges_from`` would give, so every networkx
algorithm, tie-breaks included, returns what it returns on such a copy.

That is the one place hestore reaches into another library's private members
(networkx's ``_node``, ``_adj``, ``_succ`` and ``_pred``), on purpose and
measured: the result is an ordinary networkx graph, and the test suite
compares its dicts with a copy built through networkx's public API.

Two other designs were measured on the 1 M-triangle grid (1.5 M edges) and
dropped: ``add_nodes_from`` / ``add_edges_from`` with the same attributes
(two to two and a half times as slow: per-edge Python bookkeeping), and a lazy graph whose
adjacency is a mapping over CSR arrays that builds a vertex's dicts when
asked (1.7 times cheaper to make, but components, shortest paths and degrees
each took 1.3 s more, five to eight times as long, so it fell behind after
two such algorithms). The figures are in ``docs/analysis.md``.
"""

from __future__ import annotations

import gc
from contextlib import contextmanager
from itertools import compress, islice
from typing import TYPE_CHECKING, Callable, Iterator

import networkx as nx
import numpy as np
import sqlalchemy as sa

from hestore import schema
from hestore.arrays import Index, run_starts
from hestore.columns import position_request
from hestore.errors import InvalidInputError

if TYPE_CHECKING:  # pragma: no cover
    from hestore.mesh import Mesh

__all__ = ["KINDS", "to_networkx"]

#: The graph kinds `to_networkx` makes, the default first.
KINDS = ("multigraph", "graph", "halfedge", "dual")

#: The key of the graphs in `hestore.session.Session.caches`: ``{(mesh id, kind): (revision, graph)}``.
CACHE = "graphs"


def to_networkx(mesh: "Mesh", kind: str = "multigraph") -> nx.Graph:
    """A frozen networkx graph of the mesh's committed state.

    Parameters
    ----------
    mesh : hestore.Mesh
        The mesh.
    kind : {"multigraph", "graph", "halfedge", "dual"}
        Which graph (SPEC §6):

        ``"multigraph"``
            `networkx.MultiGraph`. Nodes: vertex ids, isolated vertices
            included, with ``pos`` (the ``(x, y, z)`` tuple, or None).
            Edges: one per mesh edge, key = edge id, self-loops kept, with
            ``halfedges`` — ``(h0, h1)``: the edge's `~hestore.Edge.halfedge`
            and its twin — and ``polygons`` — the left polygons of ``h0``
            and ``h1``, None where free.
        ``"graph"``
            `networkx.Graph`. Nodes as above. One edge per pair of joined
            vertices (a self-loop too), with ``multiplicity`` (how many mesh
            edges join them) and ``edges`` (their ids, ascending).
        ``"halfedge"``
            `networkx.MultiDiGraph`. Nodes as above. One edge per half-edge,
            origin → target, key = half-edge id, with ``polygon`` (None
            where free), ``edge`` and ``twin``.
        ``"dual"``
            `networkx.MultiGraph`. Nodes: polygon ids, with ``halfedge``
            (the polygon's `~hestore.Polygon.halfedge` id). Edges: one per
            mesh edge with a polygon on both sides, key = edge id, with
            ``halfedges`` (as above: the polygons of ``h0`` and ``h1`` are
            the two ends) and ``vertices`` (the origins of ``h0`` and
            ``h1``, the mesh edge's end points). A polygon that meets itself
            across an edge has a self-loop.

    Returns
    -------
    networkx.Graph
        Frozen (`networkx.freeze`: adding or removing nodes or edges raises
        `networkx.NetworkXError`); ``G.graph`` holds ``mesh`` (the name),
        ``revision`` and ``kind``. Nodes are in id order and each
        adjacency in the order of the first edge (half-edge) id, as in a
        graph built with ``add_nodes_from`` and ``add_edges_from`` in id
        order, so algorithms give identical results, tie-breaks included.

    Raises
    ------
    InvalidInputError
        ``kind`` is not one of `KINDS`.
    MeshNotFoundError
        The mesh has been deleted.
    InvariantViolationError
        A stored reference points at no element (``REF``); `Mesh.check`
        says more.

    Notes
    -----
    The graph shows committed data only: inside a ``store.transaction()``
    block it is read through a second connection and does not show the
    block's edits — except for an in-memory SQLite store, which has only one
    connection; there it shows the block's state, and such a graph is not
    cached.

    While the committed revision is unchanged, the same graph object is
    returned again (one per kind), so do not modify its attribute dicts.
    To edit a graph, copy it: ``nx.MultiGraph(G)``.

    Examples
    --------
    A triangle with a wire edge hanging off one corner, and an isolated vertex:

    >>> import hestore, networkx as nx
    >>> mesh = hestore.open("sqlite://").create_mesh("m")
    >>> a, b, c, d, lone = (mesh.add_vertex((i, i % 2, 0)) for i in range(5))
    >>> tri = mesh.add_polygon([a, b, c])
    >>> wire = mesh.add_edge(c, d)
    >>> G = mesh.to_networkx()
    >>> G
    <networkx.classes.multigraph.MultiGraph object at ...>
    >>> list(G.edges(keys=True))
    [(0, 1, 0), (0, 2, 2), (1, 2, 1), (2, 3, 3)]
    >>> G.edges[2, 3, 3]
    {'halfedges': (6, 7), 'polygons': (None, None)}
    >>> G.edges[0, 1, 0]
    {'halfedges': (0, 1), 'polygons': (0, None)}
    >>> G.nodes[4], G.degree(2), nx.number_connected_components(G)
    ({'pos': (4.0, 0.0, 0.0)}, 3, 2)
    >>> G.graph
    {'mesh': 'm', 'revision': 7, 'kind': 'multigraph'}
    >>> mesh.to_networkx() is G  # cached while the revision stays
    True

    The other kinds:

    >>> for edge in mesh.to_networkx("halfedge").out_edges(2, keys=True, data=True):
    ...     print(edge)
    (2, 1, 3, {'polygon': None, 'edge': 1, 'twin': 2})
    (2, 0, 4, {'polygon': 0, 'edge': 2, 'twin': 5})
    (2, 3, 6, {'polygon': None, 'edge': 3, 'twin': 7})
    >>> _ = mesh.add_edge(c, d)  # a parallel edge
    >>> mesh.to_networkx("graph").edges[2, 3]
    {'multiplicity': 2, 'edges': [3, 4]}
    >>> D = mesh.to_networkx("dual")
    >>> list(D.nodes(data=True)), D.number_of_edges()
    ([(0, {'halfedge': 0})], 0)
    """
    if kind not in KINDS:
        raise InvalidInputError(f"unknown graph kind {kind!r}; the kinds are {', '.join(map(repr, KINDS))}")
    with mesh.session.snapshot(mesh.ref, committed=True) as snap:
        # Only an in-memory SQLite store inside a block reads its own
        # connection there, and so sees uncommitted edits: a graph of those
        # must not be cached under a revision number a rollback may reuse.
        cache = mesh.session.caches.setdefault(CACHE, {}) if snap.isolated else {}
        revision = snap.revision
        hit = cache.get((mesh.id, kind))
        if hit is not None and hit[0] == revision:
            return hit[1]
        columns = snap.columns(_REQUESTS[kind]())
    with _gc_paused():
        G = _BUILDERS[kind](*columns)
    G.graph.update(mesh=mesh.name, revision=revision, kind=kind)
    nx.freeze(G)
    cache[(mesh.id, kind)] = (revision, G)
    return G


# --------------------------------------------------------------------------
# What each kind reads


def _halfedge_columns(*names: str) -> tuple:
    h = schema.halfedges
    return (h, [h.c.id, *(sa.func.coalesce(h.c.polygon, -1) if k == "polygon" else h.c[k] for k in names)])


def _edge_columns() -> tuple:
    e = schema.edges
    return (e, [e.c.id, e.c.halfedge])


def _polygon_columns() -> tuple:
    p = schema.polygons
    return (p, [p.c.id, p.c.halfedge])


_REQUESTS: dict[str, Callable[[], list]] = {
    "multigraph": lambda: [position_request(), _halfedge_columns("origin", "twin", "polygon"), _edge_columns()],
    "graph": lambda: [position_request(), _halfedge_columns("origin", "twin"), _edge_columns()],
    "halfedge": lambda: [position_request(), _halfedge_columns("origin", "twin", "edge", "polygon")],
    "dual": lambda: [_polygon_columns(), _halfedge_columns("origin", "twin", "polygon"), _edge_columns()],
}


# --------------------------------------------------------------------------
# Array helpers


@contextmanager
def _gc_paused() -> Iterator[None]:
    # Building allocates millions of dicts and tuples and frees none; with the
    # collector on, every generation-2 pass walks all of them again, which
    # made building the 1 M grid's multigraph 3.5 times slower (9.3 s, not 2.6 s).
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


def _rows(ids: np.ndarray, refs: np.ndarray, kind: str, owners: np.ndarray, owner_kind: str, column: str) -> np.ndarray:
    """Row of each of ``refs`` in the sorted ``ids``; one that is not there is a ``REF`` violation."""
    return Index(ids).rows(refs, kind=kind, owners=owners, owner_kind=owner_kind, column=column)


def _or_none(values: np.ndarray) -> list:
    """``values.tolist()`` with the NULL marker ``-1`` as None."""
    out = values.tolist()
    for i in np.flatnonzero(values < 0).tolist():
        out[i] = None
    return out


def _vertex_nodes(v_id, x, y, z, unplaced) -> tuple[list, list]:
    positions = list(zip(x.tolist(), y.tolist(), z.tolist()))
    for i in np.flatnonzero(unplaced).tolist():
        positions[i] = None
    return v_id.tolist(), [{"pos": p} for p in positions]


def _groups(a: np.ndarray, b: np.ndarray, keys: np.ndarray):
    """Sort edges ``a → b`` by ``(a, b, key)``.

    Returns the order, the sorted columns and where each ``(a, b)`` run starts.
    """
    order = np.lexsort((keys, b, a))
    a, b, keys = a[order], b[order], keys[order]
    return order, a, b, keys, run_starts(a, b)


def _keydicts(keys: list, data: list, first: np.ndarray) -> list[dict]:
    """One ``{key: datadict}`` per run of sorted edges, keys ascending."""
    keydicts = [{k: d} for k, d in compress(zip(keys, data), first.tolist())]
    rest = np.flatnonzero(~first)
    if len(rest):
        run = (np.cumsum(first) - 1)[rest].tolist()
        for g, j in zip(run, rest.tolist()):
            keydicts[g][keys[j]] = data[j]
    return keydicts


def _adjacency(
    nodes: list, src: np.ndarray, dst: np.ndarray, rank: np.ndarray, values: list, which: np.ndarray
) -> list[dict]:
    """Per node, ``{nodes[dst[i]]: values[which[i]]}`` over the entries ``i`` with ``src[i]`` its row.

    Each node's entries come in ``rank`` order.

    ``src`` and ``dst`` are rows of ``nodes``; the neighbour keys are the
    node list's own int objects, so an id is stored once, not once per use.
    """
    order = np.lexsort((rank, src))
    counts = np.bincount(src, minlength=len(nodes)).tolist()
    pairs = zip(map(nodes.__getitem__, dst[order].tolist()), map(values.__getitem__, which[order].tolist()))
    # Consecutive runs of one iterator: no per-node slicing of the lists.
    return [dict(islice(pairs, c)) for c in counts]


def _undirected(
    nodes: list, attrs: list, u: np.ndarray, v: np.ndarray, keys: np.ndarray, make_data, multi: bool
) -> nx.Graph:
    """A MultiGraph (or a Graph, parallel edges merged) of edges between node rows ``u`` and ``v``.

    Runs of edges with the same ends become one keydict (Graph: one datadict
    counting them). Each node's neighbours come in the order of their first
    edge key, and each keydict's keys ascending: the dicts ``add_nodes_from``
    and ``add_edges_from`` in key order would make.
    """
    order, a, b, skeys, first = _groups(np.minimum(u, v), np.maximum(u, v), keys)
    key_list = skeys.tolist()
    starts = np.flatnonzero(first)
    if multi:
        values = _keydicts(key_list, make_data(order), first)
    else:
        sizes = np.diff(np.append(starts, len(a))).tolist()
        ids = iter(key_list)
        values = [{"multiplicity": c, "edges": list(islice(ids, c))} for c in sizes]
    ga, gb, gk = a[starts], b[starts], skeys[starts]
    # Both directions share the run's dict, as networkx's add_edge does; a
    # self-loop is a single entry.
    two = np.flatnonzero(ga != gb)
    which = np.concatenate([np.arange(len(ga)), two])
    src, dst = np.concatenate([ga, gb[two]]), np.concatenate([gb, ga[two]])
    adj = _adjacency(nodes, src, dst, gk[which], values, which)
    G = nx.MultiGraph() if multi else nx.Graph()
    G._node = dict(zip(nodes, attrs))
    G._adj = dict(zip(nodes, adj))
    return G


# --------------------------------------------------------------------------
# The four kinds


def _edge_ends(h_id, h_twin, e_id, e_he):
    """Per edge: its half-edge ``h0`` and twin ``h1``, and their rows in the half-edge columns."""
    r0 = _rows(h_id, e_he, "half-edge", e_id, "edge", "halfedge")
    h1 = h_twin[r0]
    r1 = _rows(h_id, h1, "half-edge", e_he, "halfedge", "twin")
    return e_he, h1, r0, r1


def _origin_rows(v_id, h_id, h_origin) -> np.ndarray:
    return _rows(v_id, h_origin, "vertex", h_id, "halfedge", "origin")


def _multigraph(vertices, halfedges, edges) -> nx.MultiGraph:
    nodes, attrs = _vertex_nodes(*vertices)
    h_id, h_origin, h_twin, h_polygon = halfedges
    origin = _origin_rows(vertices[0], h_id, h_origin)
    h0, h1, r0, r1 = _edge_ends(h_id, h_twin, *edges)
    p0, p1 = h_polygon[r0], h_polygon[r1]

    def data(order):
        ends = zip(h0[order].tolist(), h1[order].tolist())
        sides = zip(_or_none(p0[order]), _or_none(p1[order]))
        return [{"halfedges": hs, "polygons": ps} for hs, ps in zip(ends, sides)]

    return _undirected(nodes, attrs, origin[r0], origin[r1], edges[0], data, multi=True)


def _graph(vertices, halfedges, edges) -> nx.Graph:
    nodes, attrs = _vertex_nodes(*vertices)
    h_id, h_origin, h_twin = halfedges
    origin = _origin_rows(vertices[0], h_id, h_origin)
    _h0, _h1, r0, r1 = _edge_ends(h_id, h_twin, *edges)
    return _undirected(nodes, attrs, origin[r0], origin[r1], edges[0], None, multi=False)


def _dual(polygons, halfedges, edges) -> nx.MultiGraph:
    p_id, p_he = polygons
    nodes = p_id.tolist()
    attrs = [{"halfedge": h} for h in p_he.tolist()]
    h_id, h_origin, h_twin, h_polygon = halfedges
    h0, h1, r0, r1 = _edge_ends(h_id, h_twin, *edges)
    inner = np.flatnonzero((h_polygon[r0] >= 0) & (h_polygon[r1] >= 0))
    h0, h1, r0, r1, e_id = h0[inner], h1[inner], r0[inner], r1[inner], edges[0][inner]
    left = _rows(p_id, h_polygon[r0], "polygon", h0, "halfedge", "polygon")
    right = _rows(p_id, h_polygon[r1], "polygon", h1, "halfedge", "polygon")
    o0, o1 = h_origin[r0], h_origin[r1]

    def data(order):
        ends = zip(h0[order].tolist(), h1[order].tolist())
        corners = zip(o0[order].tolist(), o1[order].tolist())
        return [{"halfedges": hs, "vertices": vs} for hs, vs in zip(ends, corners)]

    return _undirected(nodes, attrs, left, right, e_id, data, multi=True)


def _halfedge(vertices, halfedges) -> nx.MultiDiGraph:
    nodes, attrs = _vertex_nodes(*vertices)
    h_id, h_origin, h_twin, h_edge, h_polygon = halfedges
    origin = _origin_rows(vertices[0], h_id, h_origin)
    target = origin[_rows(h_id, h_twin, "half-edge", h_id, "halfedge", "twin")]
    order, a, b, keys, first = _groups(origin, target, h_id)
    data = [
        {"polygon": p, "edge": e, "twin": t}
        for p, e, t in zip(_or_none(h_polygon[order]), h_edge[order].tolist(), h_twin[order].tolist())
    ]
    keydicts = _keydicts(keys.tolist(), data, first)
    starts = np.flatnonzero(first)
    ga, gb, gk = a[starts], b[starts], keys[starts]
    runs = np.arange(len(starts))
    # A (u, v) run's keydict is both succ[u][v] and pred[v][u], as in networkx.
    succ = _adjacency(nodes, ga, gb, gk, keydicts, runs)
    pred = _adjacency(nodes, gb, ga, gk, keydicts, runs)
    G = nx.MultiDiGraph()
    G._node = dict(zip(nodes, attrs))
    G._succ = dict(zip(nodes, succ))  # also sets G._adj
    G._pred = dict(zip(nodes, pred))
    return G


_BUILDERS: dict[str, Callable[..., nx.Graph]] = {
    "multigraph": _multigraph,
    "graph": _graph,
    "halfedge": _halfedge,
    "dual": _dual,
}
