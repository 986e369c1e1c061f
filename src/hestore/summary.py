"""Topological summaries of a stored mesh (SPEC §3, "Checks and summaries").

This module owns what `Mesh.stats`, `Mesh.boundary_loops` and
`Mesh.components` return: the `Stats` record (counts, boundary, components,
Euler characteristic, genus, pinched vertices, closedness, manifoldness) and
the definitions behind each of its fields; `Mesh` only delegates here.

Everything is set-based. The columns a summary needs are read in one
consistent snapshot through the store's session (`Session.snapshot`; inside a
transaction block the block's edits are seen),
references become row numbers, and the rest is numpy:

- cycles of ``next`` among free half-edges are labelled by pointer jumping
  (`hestore.arrays.restricted_cycles`), ``log2`` of the longest boundary loop rounds;
- connected components come from a vectorised union-find: every tree hooks
  its root onto the smallest neighbouring root, then pointer jumping flattens
  the trees again; each tree merges with another within two rounds, so there
  are at most ``2 log2 V`` rounds (a 1000 × 1000 grid needs two);
- fans around vertices are counted from the rotation without walking it (see
  `Stats.pinched_vertices`).

No Python object is built per element, except the handles that
`boundary_loops` and `components` return.

The figures assume a valid mesh (`Mesh.check` returns ``[]``). On corrupted
tables they are unspecified, but every call still terminates.

Examples
--------
>>> import hestore
>>> store = hestore.open("sqlite://")
>>> square = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]
>>> mesh = store.import_arrays("square", square, [[0, 1, 2], [0, 2, 3]]).mesh
>>> s = mesh.stats()
>>> s.vertices, s.edges, s.polygons, s.boundary_edges, s.boundary_loops, s.genus
(4, 5, 2, 4, 1, 0)
>>> [[h.origin.id for h in loop] for loop in mesh.boundary_loops()]
[[1, 0, 3, 2]]
>>> store.close()
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Callable, NamedTuple

import numpy as np

from hestore.arrays import Index, component_roots, cycle_positions, dense, groups, restricted_cycles
from hestore._columns import request, sides_request
from hestore.progress import check_progress
from hestore._session import MeshRef

__all__ = ["Stats", "stats", "boundary_loops", "components", "pinched_vertices", "fan_counts"]

_I64 = np.int64


@dataclass(frozen=True)
class Stats:
    """Counts and topological invariants of a mesh: what `Mesh.stats` returns.

    Attributes
    ----------
    vertices : int
        All vertices, isolated ones included.
    isolated_vertices : int
        Vertices no edge touches.
    edges : int
        All edges.
    loops : int
        Self-loop edges (both ends at one vertex).
    parallel_edges : int
        Edges beyond the first between the same two vertices, the pair taken
        unordered: three edges joining ``a`` and ``b`` give 2, two self-loops
        at one vertex give 1.
    halfedges : int
        All half-edges (twice `edges`).
    polygons : int
        All polygons.
    polygon_sizes : dict of int to int
        Arity (number of half-edges) -> how many polygons have it, by
        increasing arity.
    boundary_edges : int
        Edges with exactly one free half-edge.
    wire_edges : int
        Edges with both half-edges free (no polygon on either side).
    boundary_loops : int
        Cycles of free half-edges under ``next``. Wire edges' half-edges are
        free and belong to these cycles: a lone edge is one cycle (its two
        half-edges), a lone self-loop two (each half-edge is its own ``next``).
    components : int
        Connected components of the vertex–edge graph; an isolated vertex is
        a component of its own (as in networkx).
    euler_characteristic : int
        ``V - E + F``, isolated vertices included.
    genus : int or None
        ``(2c - χ - b) / 2`` over the components that are not isolated
        vertices: ``c`` and ``χ`` leave the isolated vertices out, ``b`` is
        `boundary_loops`. For several components it is the sum of their
        genera; without any edge (an empty mesh, isolated vertices only) it
        is 0, the empty sum. ``None`` where the mesh has wire edges or pinched
        vertices: the formula counts handles of surfaces, and such a mesh is
        not one.
    pinched_vertices : int
        Vertices where more than one fan meets. A fan is a maximal run of
        polygon corners around the vertex, each linked to the next through an
        edge the two polygons share; a vertex whose corners all link up has
        one closed fan. Wire edges are not fans and do not split one: a
        vertex with one fan and wire edges is not pinched (the wire edges
        make the mesh non-manifold already), one with two fans is, wire
        edges or not.
    is_closed : bool
        No free half-edge: no boundary and no wire edge. True for an empty
        mesh and for isolated vertices only, which have no half-edge at all.
    is_manifold : bool
        No pinched vertex and no wire edge. Isolated vertices do not make a
        mesh non-manifold.

    Examples
    --------
    >>> import hestore
    >>> store = hestore.open("sqlite://")
    >>> mesh = store.create_mesh("m")
    >>> a, b = mesh.add_vertex(), mesh.add_vertex()
    >>> _ = mesh.add_edge(a, b), mesh.add_edge(a, b), mesh.add_edge(a, a)
    >>> s = mesh.stats()
    >>> s.edges, s.loops, s.parallel_edges, s.wire_edges, s.is_manifold, s.genus
    (3, 1, 1, 3, False, None)
    >>> s.as_dict()["polygon_sizes"]
    {}
    >>> store.close()
    """

    vertices: int
    isolated_vertices: int
    edges: int
    loops: int
    parallel_edges: int
    halfedges: int
    polygons: int
    # Left out of the hash (a dict has none), still compared: equal Stats hash equal.
    polygon_sizes: dict[int, int] = field(hash=False)
    boundary_edges: int
    wire_edges: int
    boundary_loops: int
    components: int
    euler_characteristic: int
    genus: int | None
    pinched_vertices: int
    is_closed: bool
    is_manifold: bool

    def as_dict(self) -> dict:
        """The fields as a JSON-ready dict (``polygon_sizes`` a new dict with int keys).

        Examples
        --------
        >>> import hestore, json
        >>> store = hestore.open("sqlite://")
        >>> mesh = store.import_arrays("t", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [[0, 1, 2]]).mesh
        >>> d = mesh.stats().as_dict()
        >>> d["polygon_sizes"], d["euler_characteristic"], d["is_closed"]
        ({3: 1}, 1, False)
        >>> json.loads(json.dumps(d))["polygon_sizes"]
        {'3': 1}
        >>> store.close()
        """
        out = {f.name: getattr(self, f.name) for f in fields(self)}
        out["polygon_sizes"] = {int(k): int(v) for k, v in self.polygon_sizes.items()}
        return out


# --------------------------------------------------------------------------
# Reading


class _Tables(NamedTuple):
    """The columns a summary reads, references turned into row numbers.

    ``v_id`` and ``he_id`` are sorted, so row order is id order. ``origin`` is
    a vertex row and ``twin`` a half-edge row; ``polygon`` is the polygon id,
    or -1 for a free half-edge; ``next`` is the half-edge row of ``next``,
    meaningful for free half-edges only. What was not asked for is None.
    """

    v_id: np.ndarray | None
    he_id: np.ndarray
    origin: np.ndarray | None
    twin: np.ndarray | None
    polygon: np.ndarray | None
    next: np.ndarray | None


def _read(ref: MeshRef, *, sides: bool, links: bool) -> _Tables:
    """Read what a summary needs in one snapshot.

    Half-edge ids always; ``sides``: each half-edge's polygon, and ``next``
    where it is free; ``links``: ``origin`` and ``twin``, and the vertex ids.
    """
    names = ("origin", "twin") if links else ()
    requests = [sides_request(*names) if sides else request("halfedges", *names)]
    if links:
        requests.append(request("vertices"))
    with ref.session.snapshot(ref) as snap:
        tables = snap.columns(requests)
    he_id, *more = tables[0]
    he_index = Index(he_id)
    v_id = origin = twin = polygon = nxt = None
    # Rows, not ids: ids are never reused, so after deletions they have gaps.
    if sides:
        side = more.pop(0)
        free = side < 0
        polygon = np.where(free, -1, side)
        nxt = np.zeros(len(he_id), dtype=_I64)
        nxt[free] = he_index.find(-1 - side[free])[0]
    if links:
        v_id = tables[1][0]
        origin = Index(v_id).find(more[0])[0]
        twin = he_index.find(more[1])[0]
    return _Tables(v_id, he_id, origin, twin, polygon, nxt)


# --------------------------------------------------------------------------
# Set-based building blocks


def _free_cycles(free: np.ndarray, nxt: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Label the cycles of ``next`` among the free half-edges (`hestore.arrays.restricted_cycles`).

    Returns ``(rows, f, label, on_cycle)``: the free half-edges' rows (in id
    order) and, per entry of ``rows``, the position in ``rows`` of its
    ``next``, the position of the smallest member of its cycle, and whether
    it lies on a cycle (always, on a valid mesh: there ``next`` of a free
    half-edge is free). A free half-edge whose next has a polygon (a
    corrupted table) ends its walk there.
    """
    return restricted_cycles(nxt, np.where(free, 0, -1))[:4]


def _fans(t: _Tables, free: np.ndarray, out_degree: np.ndarray) -> np.ndarray:
    """The number of polygon fans at each vertex (by row): `fan_counts` on the tables read."""
    return fan_counts(t.origin, t.twin, free, out_degree)


def fan_counts(origin: np.ndarray, twin: np.ndarray, free: np.ndarray, out_degree: np.ndarray) -> np.ndarray:
    """The number of polygon fans at each vertex, from half-edge columns (a vertex with more than one is pinched).

    By V_ROTATION, rotating h -> next(twin(h)) is one cycle through every
    outgoing half-edge of the vertex, and the corner at h is linked to the
    next one exactly when edge(h) has polygons on both sides. The links cut
    the cycle into runs, so a vertex has (corners - links) fans, or one
    closed fan when every outgoing half-edge is linked. No walk is needed.

    Parameters
    ----------
    origin : ndarray
        Each half-edge's origin, as a vertex row.
    twin : ndarray
        Each half-edge's twin, as a half-edge row.
    free : ndarray of bool
        Whether each half-edge is free (has no polygon).
    out_degree : ndarray
        Outgoing half-edges per vertex row (``np.bincount(origin)``, as long as there are vertices).

    Examples
    --------
    One triangle (half-edges 0, 2, 4 inside, 1, 3, 5 free): one fan at each corner.

    >>> origin, twin = np.array([0, 1, 1, 2, 2, 0]), np.array([1, 0, 3, 2, 5, 4])
    >>> free = np.array([False, True, False, True, False, True])
    >>> fan_counts(origin, twin, free, np.bincount(origin)).tolist()
    [1, 1, 1]
    """
    n_v = len(out_degree)
    corner = ~free
    linked = corner & ~free[twin]
    corners = np.bincount(origin[corner], minlength=n_v)
    links = np.bincount(origin[linked], minlength=n_v)
    return np.where((links == out_degree) & (out_degree > 0), 1, corners - links)


def pinched_vertices(ref: MeshRef) -> list[int]:
    """Ids of the vertices where more than one polygon fan meets (`Stats.pinched_vertices` counts them).

    Examples
    --------
    Two triangles meeting only at vertex 0 (a "bowtie"):

    >>> from hestore._session import identity
    >>> import hestore
    >>> store = hestore.open("sqlite://")
    >>> xyz = [(0, 0, 0), (1, 1, 0), (-1, 1, 0), (-1, -1, 0), (1, -1, 0)]
    >>> mesh = store.import_arrays("bowtie", xyz, [[0, 1, 2], [0, 3, 4]]).mesh
    >>> pinched_vertices(identity(mesh))
    [0]
    """
    t = _read(ref, sides=True, links=True)
    out_degree = np.bincount(t.origin, minlength=len(t.v_id))
    return t.v_id[_fans(t, t.polygon < 0, out_degree) > 1].tolist()


def stats(ref: MeshRef, progress: Callable[[str, int, int], object] | None = None) -> Stats:
    """Counts and topological invariants of a mesh, set-based: `Mesh.stats`.

    Reads the vertex ids and four half-edge columns (id, origin, twin, and
    one carrying the polygon or, for a free half-edge, ``next``) in one
    snapshot — the block's own edits included, inside a transaction block —
    and computes every field with numpy; see `Stats` for the definitions.

    Parameters
    ----------
    ref : hestore._session.MeshRef
        The mesh (its identity: the facade passes its own, `hestore._session.identity`).
    progress : callable, optional
        ``progress(stage, done, total)`` at the start and end of each stage,
        ``"read"`` then ``"stats"`` (a `hestore.progress.ProgressBar`, say).

    Returns
    -------
    Stats

    Raises
    ------
    hestore.MeshNotFoundError
        The mesh has been deleted.

    Examples
    --------
    A tetrahedron is closed, of genus 0; an isolated vertex beside it is a
    component of its own and counts in χ, but not in the genus:

    >>> import hestore
    >>> store = hestore.open("sqlite://")
    >>> corners = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1), (5, 5, 5)]
    >>> faces = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]
    >>> s = store.import_arrays("tet", corners, faces).mesh.stats()
    >>> s.components, s.isolated_vertices, s.euler_characteristic, s.genus, s.is_closed
    (2, 1, 3, 0, True)
    >>> s.polygon_sizes, s.pinched_vertices, s.is_manifold
    ({3: 4}, 0, True)
    >>> store.close()
    """
    report = check_progress(progress)
    report("read", 0, 1)
    t = _read(ref, sides=True, links=True)
    report("read", 1, 1)
    report("stats", 0, 1)
    n_v, n_h = len(t.v_id), len(t.he_id)
    rows = np.arange(n_h, dtype=_I64)
    free = t.polygon < 0
    out_degree = np.bincount(t.origin, minlength=n_v)
    isolated = int(np.count_nonzero(out_degree == 0))

    # One half-edge per edge: the one with the lower row of the twin pair.
    rep = np.flatnonzero(rows < t.twin)
    other = t.twin[rep]
    u, w = t.origin[rep], t.origin[other]
    n_e = len(rep)
    loops = int(np.count_nonzero(u == w))
    pair = np.minimum(u, w) * max(n_v, 1) + np.maximum(u, w)
    pair.sort()
    parallel = int(np.count_nonzero(pair[1:] == pair[:-1]))
    free_rep, free_other = free[rep], free[other]
    boundary_edges = int(np.count_nonzero(free_rep != free_other))
    wire_edges = int(np.count_nonzero(free_rep & free_other))

    polygon_of, n_p = dense(t.polygon[~free])
    arity = np.bincount(polygon_of, minlength=n_p)
    by_arity = np.bincount(arity)
    polygon_sizes = {int(k): int(by_arity[k]) for k in np.flatnonzero(by_arity) if k > 0}

    free_rows, _, label, on_cycle = _free_cycles(free, t.next)
    n_loops = int(np.count_nonzero(on_cycle & (label == np.arange(len(free_rows)))))

    roots = component_roots(n_v, u, w)
    n_components = int(np.count_nonzero(roots == np.arange(n_v)))

    pinched = int(np.count_nonzero(_fans(t, free, out_degree) > 1))

    chi = n_v - n_e + n_p
    genus = None
    if not wire_edges and not pinched:
        genus = (2 * (n_components - isolated) - (chi - isolated) - n_loops) // 2
    report("stats", 1, 1)
    return Stats(
        vertices=n_v,
        isolated_vertices=isolated,
        edges=n_e,
        loops=loops,
        parallel_edges=parallel,
        halfedges=n_h,
        polygons=n_p,
        polygon_sizes=polygon_sizes,
        boundary_edges=boundary_edges,
        wire_edges=wire_edges,
        boundary_loops=n_loops,
        components=n_components,
        euler_characteristic=chi,
        genus=genus,
        pinched_vertices=pinched,
        is_closed=not bool(free.any()),
        is_manifold=not pinched and not wire_edges,
    )


def boundary_loops(ref: MeshRef) -> list[list[int]]:
    """The cycles of free half-edges under ``next``, as half-edge ids: `Mesh.boundary_loops`.

    Wire edges' half-edges are free and belong to these cycles (see
    `Stats.boundary_loops`).

    Parameters
    ----------
    ref : hestore._session.MeshRef
        The mesh (its identity: the facade passes its own, `hestore._session.identity`).

    Returns
    -------
    list of list of int
        One list per cycle, in ``next`` order starting at its smallest id;
        the cycles sorted by that id. Empty for a closed mesh.

    Raises
    ------
    hestore.MeshNotFoundError
        The mesh has been deleted.

    Examples
    --------
    A quad with a wire edge hanging off one corner: one cycle runs around
    the quad's outside and out along the wire edge and back.

    >>> import hestore
    >>> store = hestore.open("sqlite://")
    >>> mesh = store.import_arrays("q", [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)], [[0, 1, 2, 3]]).mesh
    >>> _ = mesh.add_edge(mesh.vertex(2), mesh.add_vertex((2, 2, 0)))
    >>> [loop] = mesh.boundary_loops()
    >>> [(h.origin.id, h.target.id) for h in loop]
    [(1, 0), (0, 3), (3, 2), (2, 4), (4, 2), (2, 1)]
    >>> all(h.next == loop[(i + 1) % len(loop)] and h.polygon is None for i, h in enumerate(loop))
    True
    >>> store.close()
    """
    t = _read(ref, sides=True, links=False)
    free_rows, f, label, on_cycle = _free_cycles(t.polygon < 0, t.next)
    # Half-edges on no cycle only occur in corrupted tables; leave them out.
    keep = np.flatnonzero(on_cycle)
    where = np.full(len(free_rows), -1, dtype=_I64)
    where[keep] = np.arange(len(keep), dtype=_I64)
    f = where[f[keep]]
    label = where[label[keep]]
    position = cycle_positions(f, label)
    order = np.lexsort((position, label))
    ids = t.he_id[free_rows[keep][order]].tolist()
    bounds = np.flatnonzero(np.r_[True, label[order][1:] != label[order][:-1], True]).tolist() if len(ids) else [0]
    return [ids[a:b] for a, b in zip(bounds[:-1], bounds[1:])]


def components(ref: MeshRef, progress: Callable[[str, int, int], object] | None = None) -> list[list[int]]:
    """The connected components of the vertex–edge graph, as vertex ids: `Mesh.components`.

    Parameters
    ----------
    ref : hestore._session.MeshRef
        The mesh (its identity: the facade passes its own, `hestore._session.identity`).
    progress : callable, optional
        ``progress(stage, done, total)`` at the start and end of ``"read"`` and ``"label"``.

    Returns
    -------
    list of list of int
        One list of vertex ids per component, an isolated vertex in a list of
        its own; sorted by each component's smallest vertex id.

    Raises
    ------
    hestore.MeshNotFoundError
        The mesh has been deleted.

    Examples
    --------
    >>> import hestore
    >>> store = hestore.open("sqlite://")
    >>> mesh = store.create_mesh("m")
    >>> a, b, c, d = (mesh.add_vertex() for _ in range(4))
    >>> _ = mesh.add_edge(d, a), mesh.add_edge(b, b)
    >>> [sorted(v.id for v in part) for part in mesh.components()]
    [[0, 3], [1], [2]]
    >>> store.close()
    """
    report = check_progress(progress)
    report("read", 0, 1)
    t = _read(ref, sides=False, links=True)
    report("read", 1, 1)
    report("label", 0, 1)
    rep = np.flatnonzero(np.arange(len(t.he_id)) < t.twin)
    roots = component_roots(len(t.v_id), t.origin[rep], t.origin[t.twin[rep]])
    order, bounds = groups(roots)
    ids = t.v_id[order].tolist()
    bounds = bounds.tolist()
    found = [ids[a:b] for a, b in zip(bounds[:-1], bounds[1:])]
    report("label", 1, 1)
    return found
