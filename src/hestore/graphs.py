"""The networkx views of a mesh (SPEC §6).

This module owns `to_networkx`: the four graphs a mesh's connectivity is
analysed as — ``"multigraph"`` (vertices and edges, self-loops and parallel
edges kept), ``"graph"`` (parallel edges merged), ``"halfedge"`` (one directed
edge per half-edge) and ``"dual"`` (polygons, joined across the edges between
them). Each is a plain, frozen networkx graph of the mesh's *committed* state,
cached per store, mesh and kind, and rebuilt only when the mesh's committed
revision has changed. ``attrs`` adds properties (and the derived edge
``length``) as node and edge attributes: each property's values are read as
one column, in the same snapshot as the connectivity, and set on the
attribute dicts the builders make. ``vertices`` makes the view induced by
some vertices with the same builders, fed the rows of those vertices and of
the half-edges between them (`hestore.traversal`) instead of whole columns.

How a graph is made: the columns it needs are read in bulk, in one snapshot
together with the revision (`hestore._columns.read_columns`); the grouping of
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
from dataclasses import dataclass
from itertools import compress, islice
from typing import Callable, Iterable, Iterator

import networkx as nx
import numpy as np

from hestore import properties as props
from hestore import schema
from hestore import traversal
from hestore.arrays import Index, run_starts
from hestore._columns import position_request, request
from hestore.errors import InvalidInputError, PropertyNotFoundError, shown
from hestore.progress import check_progress
from hestore.traversal import KINDS, LENGTH, NUMERIC
from hestore._values import Property, check_choice, check_items
from hestore._session import MeshRef

# KINDS (the graph kinds `to_networkx` makes, the default first) and LENGTH (the derived edge attribute of
# ``attrs``) are `hestore.traversal`'s, below networkx, so that the command line offers them without it.
__all__ = ["KINDS", "LENGTH", "to_networkx"]

#: The key of the graphs in `hestore._session.Session.caches`: ``{(mesh id, kind): (revision, graph)}``,
#: and ``{(mesh id, kind, attrs): (revision, graph)}`` for graphs with property attributes.
CACHE = "graphs"


def to_networkx(
    ref: MeshRef,
    kind: str = "multigraph",
    attrs: Iterable[str] | None = None,
    vertices: Iterable[int] | None = None,
    progress: Callable[[str, int, int], object] | None = None,
) -> nx.Graph:
    """A frozen networkx graph of the mesh's committed state, or the view induced by some of its vertices.

    Parameters
    ----------
    ref : hestore._session.MeshRef
        The mesh (its identity: the facade passes its own, `hestore._session.identity`).
    kind : {"multigraph", "graph", "halfedge", "dual"}
        Which graph:

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
    attrs : list of str, optional
        Names of properties to put on the graph as attributes,
        and the derived `LENGTH`, ``"length"`` (a single string is one
        name). Each name goes where its property lives:

        - nodes take the properties of the node kind: vertex properties
          (``"multigraph"``, ``"graph"``, ``"halfedge"``), polygon
          properties (``"dual"``);
        - edges take the edge properties; the ``"halfedge"`` kind's edges
          take the half-edge properties and the edge properties (each
          half-edge gets its edge's value; where a half-edge and an edge
          property share the name, the half-edge property);
        - a name that is both a node and an edge property goes on both;
        - ``"length"``, unless an edge (or, for ``"halfedge"``, half-edge)
          property has that name, puts on every edge the Euclidean distance
          between the positions of its two end points: a float, 0.0 for a
          self-loop, None where an end has no position (networkx's weighted
          algorithms take a weight of None as "no such edge"). The dual's
          edges get the length of their primal edge (the boundary the two
          polygons share), not a distance between the polygons.

        Values are Python scalars (``float``, ``int``, ``bool``, ``str``),
        tuples for shaped properties. An element without a value, of a
        property without a default, has no such attribute at all (not
        None), so ``d.get(name)`` and networkx's default weight of 1 apply.
        In the ``"graph"`` kind an edge stands for all the parallel edges
        it merges: a scalar ``int64`` or ``float64`` property gives the
        smallest of their values (as networkx's shortest paths on the
        multigraph use the lightest parallel edge), any other property the
        value of the lowest edge id that has one, and ``"length"`` their
        common length (they join the same two vertices).
    vertices : iterable of int, optional
        For the vertex kinds (``"multigraph"``, ``"graph"``, ``"halfedge"``):
        the view induced by these vertex ids — equal to the whole view's
        ``G.subgraph(vertices)``, with the same nodes, edges, keys and
        attributes, but read from the rows of those vertices and the
        half-edges between them only (`hestore.traversal.halfedges_among`),
        so it costs with the set, not with the mesh. Like the other local
        queries (`hestore.traversal`) it reads the mesh as every read does,
        an open block's own edits included, and is not cached.
    progress : callable, optional
        ``progress(stage, done, total)`` at the start and end of ``"read"``
        and ``"build"`` (not called for a cached graph or an induced view).

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
        ``kind`` is not one of `KINDS`; ``vertices`` is given for the
        ``"dual"``; ``attrs`` is not a list of names;
        a name in ``attrs`` is one of the view's own attributes where it
        would go (``pos``, ``halfedges``, ``edges``, …).
    PropertyNotFoundError
        A name in ``attrs`` is neither a property of a kind that goes on
        this graph nor ``"length"``.
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
    cached. A view induced by ``vertices`` is a local query instead: it
    shows what every read shows, the block's own edits included.

    While the committed revision is unchanged, the same graph object is
    returned again (one per kind and list of ``attrs``), so do not modify
    its attribute dicts. To edit a graph, copy it: ``nx.MultiGraph(G)``.
    Writing a property value is an edit like any other: it commits a new
    revision, and the next call builds a new graph.

    ``attrs`` are read set-based, one statement per property, in the same
    snapshot as the connectivity (so, committed values only); without
    ``attrs`` nothing more is read or built than before.

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

    Properties and the derived ``"length"`` as attributes, for a weighted
    shortest path. From ``a`` to ``c`` along the legs of a right triangle
    (9 + 12) or along its hypotenuse (15), cut into three edges of 5:

    >>> w = hestore.open("sqlite://").create_mesh("w")
    >>> xyz = [(0, 0, 0), (9, 0, 0), (9, 12, 0), (6, 8, 0), (3, 4, 0)]
    >>> a, b, c, q, p = (w.add_vertex(position) for position in xyz)
    >>> pentagon = w.add_polygon([a, b, c, q, p])
    >>> _ = w.add_property("vertex", "label", "str")
    >>> a["label"] = "start"
    >>> G = w.to_networkx(attrs=["length", "label"])
    >>> nx.shortest_path(G, a.id, c.id)  # the fewest edges
    [0, 1, 2]
    >>> nx.shortest_path(G, a.id, c.id, weight="length")  # the shortest
    [0, 4, 3, 2]
    >>> nx.shortest_path_length(G, a.id, c.id, weight="length")
    15.0
    >>> G.nodes[a.id], G.nodes[b.id]  # b has no label (and no default): no attribute
    ({'pos': (0.0, 0.0, 0.0), 'label': 'start'}, {'pos': (9.0, 0.0, 0.0)})
    >>> G.edges[a.id, b.id, 0]
    {'halfedges': (0, 1), 'polygons': (0, None), 'length': 9.0}

    The view induced by a few vertices, read without the rest of the mesh:

    >>> H = w.to_networkx(vertices=[a, b, p], attrs=["length"])
    >>> list(H.edges(keys=True, data="length"))
    [(0, 1, 0, 9.0), (0, 4, 4, 5.0)]
    >>> S = w.to_networkx(attrs=["length"]).subgraph([a.id, b.id, p.id])  # the same, from the whole view
    >>> dict(S.nodes(data=True)) == dict(H.nodes(data=True))
    True
    >>> list(S.edges(keys=True, data=True)) == list(H.edges(keys=True, data=True))
    True
    """
    kind = check_choice(kind, KINDS, "a graph kind")
    names = _names(attrs)
    report = check_progress(progress)
    if vertices is not None:
        if kind == "dual":
            raise InvalidInputError(
                "vertices= takes the vertex kinds ('multigraph', 'graph', 'halfedge'); "
                "the dual's nodes are polygons"
            )
        return _induced(ref, kind, names, vertices)
    key = (ref.id, kind, names) if names else (ref.id, kind)
    with ref.session.snapshot(ref, committed=True) as snap:
        # Only an in-memory SQLite store inside a block reads its own
        # connection there, and so sees uncommitted edits: a graph of those
        # must not be cached under a revision number a rollback may reuse.
        cache = ref.session.caches.setdefault(CACHE, {}) if snap.isolated else {}
        revision = snap.revision
        hit = cache.get(key)
        if hit is not None and hit[0] == revision:
            return hit[1]
        plan = _plan(ref, snap, kind, names) if names else None
        requests = _REQUESTS[kind]()
        used = len(requests)
        if plan is not None and plan.length and kind == "dual":
            requests.append(position_request())  # the dual's nodes are polygons: positions only for lengths
        report("read", 0, 1)
        columns = snap.columns(requests)
        extra = _attributes(snap, ref, kind, plan, columns) if plan is not None else _NO_ATTRIBUTES
        report("read", 1, 1)
    report("build", 0, 1)
    with _gc_paused():
        G = _BUILDERS[kind](*columns[:used], extra=extra)
    report("build", 1, 1)
    G.graph.update(mesh=ref.name, revision=revision, kind=kind)
    nx.freeze(G)
    _remember(cache, key, revision, G)
    return G


def _induced(ref: MeshRef, kind: str, names: tuple[str, ...], vertices: Iterable[int]) -> nx.Graph:
    """The view of ``kind`` induced by the vertex ids ``vertices``: the builders of the whole view, fed their rows.

    The vertices' rows and the half-edges between them are all the
    builders need: with them they make the same dicts, in the same order,
    as the whole view restricted to those nodes.
    """
    ids = sorted(set(vertices))
    with ref.session.snapshot(ref) as snap:
        plan = _plan(ref, snap, kind, names) if names else None
        v_rows = traversal.vertex_rows(ref, ids) if ids else []
        h_rows = traversal.halfedges_among(ref, ids) if ids else []
        columns = _induced_columns(kind, v_rows, h_rows)
        extra = _attributes(snap, ref, kind, plan, columns) if plan is not None else _NO_ATTRIBUTES
        revision = snap.revision
    with _gc_paused():
        G = _BUILDERS[kind](*columns, extra=extra)
    G.graph.update(mesh=ref.name, revision=revision, kind=kind)
    nx.freeze(G)
    return G


def _induced_columns(kind: str, v_rows: list[tuple], h_rows: list[tuple]) -> list:
    """The columns `_REQUESTS` would read, of the rows `hestore.traversal` read (both ascending by id)."""
    unplaced = [r[1] is None or r[2] is None or r[3] is None for r in v_rows]
    coords = [np.array([0.0 if u else r[k] for r, u in zip(v_rows, unplaced)], dtype=np.float64) for k in (1, 2, 3)]
    vertices = [np.array([r[0] for r in v_rows], dtype=np.int64), *coords, np.array(unplaced, dtype=np.int64)]
    names = ("id", "origin", "twin", "edge")
    h = {name: np.array([r[k] for r in h_rows], dtype=np.int64) for k, name in enumerate(names)}
    h["polygon"] = np.array([-1 if r[4] is None else r[4] for r in h_rows], dtype=np.int64)
    edge_rows = sorted({(r[3], r[6]) for r in h_rows})
    edges = [np.array([e for e, _ in edge_rows], dtype=np.int64), np.array([x for _, x in edge_rows], dtype=np.int64)]
    if kind == "multigraph":
        return [vertices, [h["id"], h["origin"], h["twin"], h["polygon"]], edges]
    if kind == "graph":
        return [vertices, [h["id"], h["origin"], h["twin"]], edges]
    return [vertices, [h["id"], h["origin"], h["twin"], h["edge"], h["polygon"]]]


#: How many graphs with ``attrs`` the cache keeps per mesh and kind (the most recently built).
_ATTRS_VARIANTS = 4


def _remember(cache: dict, key: tuple, revision: int, G: nx.Graph) -> None:
    """Cache ``G``; drop the mesh's graphs of other revisions (never hit again) and old ``attrs`` variants."""
    mesh_id, kind = key[0], key[1]
    stale = [k for k, (r, _) in cache.items() if k[0] == mesh_id and r != revision]
    for k in stale:
        del cache[k]
    if len(key) == 3:
        variants = [k for k in cache if len(k) == 3 and k[:2] == (mesh_id, kind) and k != key]
        for k in variants[: max(0, len(variants) - _ATTRS_VARIANTS + 1)]:
            del cache[k]
    cache[key] = (revision, G)


# --------------------------------------------------------------------------
# What each kind reads


# The lists are new on each call: `to_networkx` may append to one. A free half-edge's polygon reads as -1.
_REQUESTS: dict[str, Callable[[], list]] = {
    "multigraph": lambda: [
        position_request(), request("halfedges", "origin", "twin", "polygon"), request("edges", "halfedge")
    ],
    "graph": lambda: [position_request(), request("halfedges", "origin", "twin"), request("edges", "halfedge")],
    "halfedge": lambda: [position_request(), request("halfedges", "origin", "twin", "edge", "polygon")],
    "dual": lambda: [
        request("polygons", "halfedge"), request("halfedges", "origin", "twin", "polygon"), request("edges", "halfedge")
    ],
}


# --------------------------------------------------------------------------
# Attributes from properties (``attrs``)

#: Per kind: the element kind whose properties go on nodes, and those whose
#: properties go on edges (the first that has the name wins).
_TARGETS = {
    "multigraph": ("vertex", ("edge",)),
    "graph": ("vertex", ("edge",)),
    "halfedge": ("vertex", ("halfedge", "edge")),
    "dual": ("polygon", ("edge",)),
}

#: Per kind: the node and edge attributes the view sets itself; a property may not replace them.
_OWN = {
    "multigraph": ({"pos"}, {"halfedges", "polygons"}),
    "graph": ({"pos"}, {"multiplicity", "edges"}),
    "halfedge": ({"pos"}, {"polygon", "edge", "twin"}),
    "dual": ({"halfedge"}, {"halfedges", "vertices"}),
}

#: The value of an element that has none (a property without a default, unset): no attribute.
_ABSENT = object()


@dataclass(frozen=True)
class _Column:
    """One attribute, per row of the elements it is read for.

    ``values`` are Python values (tuples for shaped properties), `_ABSENT`
    where there is none; ``present`` says where there is one; ``numeric``
    holds the raw values of a scalar ``int64`` / ``float64`` property (the
    ``"graph"`` kind takes their minimum over parallel edges), else None.
    """

    name: str
    values: list
    present: np.ndarray
    numeric: np.ndarray | None = None

    def take(self, rows: np.ndarray) -> "_Column":
        """The column of the elements at ``rows``."""
        numeric = None if self.numeric is None else self.numeric[rows]
        return _Column(self.name, list(map(self.values.__getitem__, rows.tolist())), self.present[rows], numeric)


@dataclass(frozen=True)
class _Plan:
    """Which properties go on nodes and edges, and whether ``length`` goes on edges, in ``attrs`` order."""

    nodes: tuple[Property, ...]
    edges: tuple[Property | str, ...]  # a Property, or LENGTH

    @property
    def length(self) -> bool:
        return LENGTH in self.edges


@dataclass(frozen=True)
class _Attributes:
    """The columns a builder puts on nodes (per node row) and on edges (per edge, or half-edge, row)."""

    nodes: tuple[_Column, ...] = ()
    edges: tuple[_Column, ...] = ()


_NO_ATTRIBUTES = _Attributes()


def _names(attrs: object) -> tuple[str, ...]:
    """``attrs`` as a tuple of distinct names, in their order."""
    if attrs is None:
        return ()
    if isinstance(attrs, str):
        attrs = [attrs]
    what = "attrs is a list of property names (or 'length')"
    names = check_items(attrs, what, ordered=False)
    for name in names:
        if not isinstance(name, str):
            raise InvalidInputError(f"{what}; {shown(name)} is not a name")
    return tuple(dict.fromkeys(names))


def _plan(ref: MeshRef, snap, kind: str, names: tuple[str, ...]) -> _Plan:
    """Resolve ``names`` against the properties of the mesh in this snapshot."""
    catalogue = props.catalogue_in(snap)
    node_kind, edge_kinds = _TARGETS[kind]
    own_nodes, own_edges = _OWN[kind]
    nodes: list[Property] = []
    edges: list[Property | str] = []
    for name in names:
        node = catalogue.get((node_kind, name))
        edge = next((catalogue[k, name] for k in edge_kinds if (k, name) in catalogue), None)
        if edge is None and name == LENGTH:
            edge = LENGTH
        if node is None and edge is None:
            *first, last = (node_kind, *edge_kinds)
            kinds = f"{', '.join(first)} or {last}"
            raise PropertyNotFoundError(
                f"mesh {ref.name!r} has no {kinds} property named {name!r} for its {kind} view; "
                f"attrs takes the names of such properties and {LENGTH!r}"
            )
        for found, own, where in ((node, own_nodes, "node"), (edge, own_edges, "edge")):
            if found is not None and name in own:
                raise InvalidInputError(
                    f"property {name!r} cannot be a {where} attribute of the {kind} view: "
                    f"the view sets {name!r} itself"
                )
        if node is not None:
            nodes.append(node)
        if edge is not None:
            edges.append(edge)
    return _Plan(tuple(nodes), tuple(edges))


def _as_column(prop: Property, array: np.ndarray) -> _Column:
    """A `_Column` of a `hestore.Mesh.property_array`-style array (masked where unset without default)."""
    n = len(array)
    if isinstance(array, np.ma.MaskedArray):
        mask = np.ma.getmaskarray(array).reshape(n, -1)
        present = ~mask.any(axis=1) if mask.shape[1] else np.ones(n, dtype=bool)
        raw = array.data
    else:
        present = np.ones(n, dtype=bool)
        raw = array
    out = raw.tolist()
    if prop.shape:
        out = list(map(tuple, out))
    for i in np.flatnonzero(~present).tolist():
        out[i] = _ABSENT
    numeric = raw if not prop.shape and prop.dtype in NUMERIC else None
    return _Column(prop.name, out, present, numeric)


def _length_column(vertices, u: np.ndarray, v: np.ndarray) -> _Column:
    """``length`` of edges between the vertex rows ``u`` and ``v``: None where an end has no position."""
    _ids, x, y, z, unplaced = vertices
    xyz = np.stack([x, y, z], axis=1)
    lengths = np.sqrt(((xyz[u] - xyz[v]) ** 2).sum(axis=1)).tolist()
    for i in np.flatnonzero((unplaced[u] != 0) | (unplaced[v] != 0)).tolist():
        lengths[i] = None
    return _Column(LENGTH, lengths, np.ones(len(lengths), dtype=bool))


def _property_column(snap, ref: MeshRef, prop: Property, ids: np.ndarray) -> _Column:
    """The values of ``prop`` for the elements ``ids``, in the graph's own snapshot (committed data)."""
    return _as_column(prop, props.array_in(snap, ref, prop, ids))


def _attributes(snap, ref: MeshRef, kind: str, plan: _Plan, columns: list) -> _Attributes:
    """The columns of ``plan``, per node row and per edge (half-edge) row of the builder's columns."""
    node_ids = columns[0][0]
    nodes = tuple(_property_column(snap, ref, prop, node_ids) for prop in plan.nodes)
    halfedges = columns[1]
    h_id, h_origin, h_twin = halfedges[0], halfedges[1], halfedges[2]
    edges = []
    for item in plan.edges:
        if item == LENGTH:
            vertices = columns[-1] if kind == "dual" else columns[0]
            origin = _origin_rows(vertices[0], h_id, h_origin)
            if kind == "halfedge":
                edges.append(_length_column(vertices, origin, origin[_twin_rows(h_id, h_twin)]))
            else:
                _h0, _h1, r0, r1 = _edge_ends(h_id, h_twin, *columns[2])
                edges.append(_length_column(vertices, origin[r0], origin[r1]))
        elif kind == "halfedge" and item.kind == "edge":
            # Each half-edge takes its edge's value.
            h_edge = halfedges[3]
            edge_ids = np.unique(h_edge)
            column = _property_column(snap, ref, item, edge_ids)
            edges.append(column.take(Index(edge_ids).find(h_edge)[0]))
        else:
            edges.append(_property_column(snap, ref, item, h_id if kind == "halfedge" else columns[2][0]))
    return _Attributes(nodes, tuple(edges))


def _apply(dicts: list[dict], columns: Iterable[_Column], rows: np.ndarray | None = None) -> None:
    """Set each column's value in ``dicts[i]``, taken from row ``rows[i]`` (row ``i`` without ``rows``)."""
    for column in columns:
        taken = column if rows is None else column.take(rows)
        name = column.name
        if taken.present.all():
            for d, value in zip(dicts, taken.values):
                d[name] = value
        else:
            for d, value in zip(dicts, taken.values):
                if value is not _ABSENT:
                    d[name] = value


def _merged(column: _Column, order: np.ndarray, starts: np.ndarray) -> _Column:
    """One value per run of parallel edges (``order``: the edge rows sorted by run, ``starts``: where runs start).

    A scalar number: the smallest value of the run; anything else: the value
    of its first edge (the lowest id) that has one.
    """
    n = len(starts)
    present = column.present[order]
    if n == 0:
        return _Column(column.name, [], np.zeros(0, dtype=bool))
    if column.numeric is not None:
        raw = column.numeric[order]
        fill = np.inf if raw.dtype.kind == "f" else np.iinfo(np.int64).max
        smallest = np.minimum.reduceat(np.where(present, raw, fill), starts)
        found = np.logical_or.reduceat(present, starts)
        out = smallest.tolist()
    else:
        first_of_run = np.zeros(len(order), dtype=bool)
        first_of_run[starts] = True
        run = np.cumsum(first_of_run) - 1
        have = np.flatnonzero(present)
        runs, first = np.unique(run[have], return_index=True)
        found = np.zeros(n, dtype=bool)
        found[runs] = True
        out = [_ABSENT] * n
        picked = order[have[first]].tolist()
        for r, row in zip(runs.tolist(), picked):
            out[r] = column.values[row]
    for i in np.flatnonzero(~found).tolist():
        out[i] = _ABSENT
    return _Column(column.name, out, found)


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


def _or_none(values: np.ndarray) -> list:
    """``values.tolist()`` with the NULL marker ``-1`` as None."""
    out = values.tolist()
    for i in np.flatnonzero(values < 0).tolist():
        out[i] = None
    return out


def _shared_ids(*columns: np.ndarray) -> list[list]:
    """Each column's ``tolist()``, with the NULL marker ``-1`` as None and one int object per distinct id.

    An id that recurs (a polygon on the sides of several edges, an edge on
    both its half-edges, a vertex at the ends of several) is then one
    object, not one per use: 32 bytes saved per repeat (about 90 MiB on the
    1 M grid's multigraph, 4.5 % of it).
    """
    values = np.concatenate(columns) if columns else np.zeros(0, dtype=np.int64)
    if not len(values):
        return [[] for _ in columns]
    distinct, inverse = np.unique(values, return_inverse=True)
    pool = [None if i < 0 else i for i in distinct.tolist()]
    shared = list(map(pool.__getitem__, inverse.tolist()))
    n = len(columns[0])
    return [shared[k * n : (k + 1) * n] for k in range(len(columns))]


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
    nodes: list,
    attrs: list,
    u: np.ndarray,
    v: np.ndarray,
    keys: np.ndarray,
    make_data,
    multi: bool,
    merge: tuple[_Column, ...] = (),
) -> nx.Graph:
    """A MultiGraph (or a Graph, parallel edges merged) of edges between node rows ``u`` and ``v``.

    Runs of edges with the same ends become one keydict (Graph: one datadict
    counting them). Each node's neighbours come in the order of their first
    edge key, and each keydict's keys ascending: the dicts ``add_nodes_from``
    and ``add_edges_from`` in key order would make. ``merge``: columns (per
    edge row of ``u``, ``v``) that the Graph's merged edges take (`_merged`).
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
        _apply(values, (_merged(column, order, starts) for column in merge))
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

#: How a ``REF`` violation names a missing half-edge.
_HALF_EDGE = schema.KINDS["halfedge"].label


def _edge_ends(h_id, h_twin, e_id, e_he):
    """Per edge: its half-edge ``h0`` and twin ``h1``, and their rows in the half-edge columns."""
    halfedges = Index(h_id)
    r0 = halfedges.rows(e_he, kind=_HALF_EDGE, owners=e_id, owner_kind="edge", column="halfedge")
    h1 = h_twin[r0]
    r1 = halfedges.rows(h1, kind=_HALF_EDGE, owners=e_he, owner_kind="halfedge", column="twin")
    return e_he, h1, r0, r1


def _origin_rows(v_id, h_id, h_origin) -> np.ndarray:
    """Each half-edge's origin as a vertex row; a missing vertex is a ``REF`` violation."""
    return Index(v_id).rows(h_origin, kind="vertex", owners=h_id, owner_kind="halfedge", column="origin")


def _twin_rows(h_id, h_twin) -> np.ndarray:
    """Each half-edge's twin as a half-edge row; a missing one is a ``REF`` violation."""
    return Index(h_id).rows(h_twin, kind=_HALF_EDGE, owners=h_id, owner_kind="halfedge", column="twin")


def _multigraph(vertices, halfedges, edges, extra: _Attributes = _NO_ATTRIBUTES) -> nx.MultiGraph:
    nodes, attrs = _vertex_nodes(*vertices)
    _apply(attrs, extra.nodes)
    h_id, h_origin, h_twin, h_polygon = halfedges
    origin = _origin_rows(vertices[0], h_id, h_origin)
    h0, h1, r0, r1 = _edge_ends(h_id, h_twin, *edges)
    p0, p1 = h_polygon[r0], h_polygon[r1]

    def data(order):
        ends = zip(h0[order].tolist(), h1[order].tolist())
        sides = zip(*_shared_ids(p0[order], p1[order]))
        out = [{"halfedges": hs, "polygons": ps} for hs, ps in zip(ends, sides)]
        _apply(out, extra.edges, order)
        return out

    return _undirected(nodes, attrs, origin[r0], origin[r1], edges[0], data, multi=True)


def _graph(vertices, halfedges, edges, extra: _Attributes = _NO_ATTRIBUTES) -> nx.Graph:
    nodes, attrs = _vertex_nodes(*vertices)
    _apply(attrs, extra.nodes)
    h_id, h_origin, h_twin = halfedges
    origin = _origin_rows(vertices[0], h_id, h_origin)
    _h0, _h1, r0, r1 = _edge_ends(h_id, h_twin, *edges)
    return _undirected(nodes, attrs, origin[r0], origin[r1], edges[0], None, multi=False, merge=extra.edges)


def _dual(polygons, halfedges, edges, extra: _Attributes = _NO_ATTRIBUTES) -> nx.MultiGraph:
    p_id, p_he = polygons
    nodes = p_id.tolist()
    attrs = [{"halfedge": h} for h in p_he.tolist()]
    _apply(attrs, extra.nodes)
    h_id, h_origin, h_twin, h_polygon = halfedges
    h0, h1, r0, r1 = _edge_ends(h_id, h_twin, *edges)
    inner = np.flatnonzero((h_polygon[r0] >= 0) & (h_polygon[r1] >= 0))
    h0, h1, r0, r1, e_id = h0[inner], h1[inner], r0[inner], r1[inner], edges[0][inner]
    polygons = Index(p_id)
    left = polygons.rows(h_polygon[r0], kind="polygon", owners=h0, owner_kind="halfedge", column="polygon")
    right = polygons.rows(h_polygon[r1], kind="polygon", owners=h1, owner_kind="halfedge", column="polygon")
    o0, o1 = h_origin[r0], h_origin[r1]

    def data(order):
        ends = zip(h0[order].tolist(), h1[order].tolist())
        corners = zip(*_shared_ids(o0[order], o1[order]))
        out = [{"halfedges": hs, "vertices": vs} for hs, vs in zip(ends, corners)]
        _apply(out, extra.edges, inner[order])
        return out

    return _undirected(nodes, attrs, left, right, e_id, data, multi=True)


def _halfedge(vertices, halfedges, extra: _Attributes = _NO_ATTRIBUTES) -> nx.MultiDiGraph:
    nodes, attrs = _vertex_nodes(*vertices)
    _apply(attrs, extra.nodes)
    h_id, h_origin, h_twin, h_edge, h_polygon = halfedges
    origin = _origin_rows(vertices[0], h_id, h_origin)
    target = origin[_twin_rows(h_id, h_twin)]
    order, a, b, keys, first = _groups(origin, target, h_id)
    data = [
        {"polygon": p, "edge": e, "twin": t}
        for p, e, t in zip(*_shared_ids(h_polygon[order]), *_shared_ids(h_edge[order]), h_twin[order].tolist())
    ]
    _apply(data, extra.edges, order)
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
