"""Set-based construction of a half-edge structure from a polygon soup.

This module owns the numpy side of bulk import: given vertex count and
polygons (as a ragged array), it decides which polygons the structure can
take and builds every column of the ``halfedges``, ``edges``, ``polygons``
and ``vertices`` tables at once, without a Python object per element.

The result is exactly what `hestore.mesh.Mesh.add_polygon` would build when
called on the polygons one by one in input order, skipping each one it
refuses — up to the order of the free gaps around a vertex where several
fans meet. Ids follow the kernel's conventions too: vertex ``i`` is input row
``i``, polygons are numbered in input order, edges in order of first use,
edge ``e`` owns half-edges ``2e`` (its first use) and ``2e + 1``.

The steps (seed 003's twin matching, generalised):

1. **Polygon checks** that need no neighbours: an empty polygon, an index out
   of range, a self-loop where the policy forbids it, a polygon that runs the
   same directed edge twice.
2. **Edge uses.** A directed vertex pair ``a→b`` takes at most one polygon
   (a self-loop's two half-edges both run ``a→a``, so it takes two). Sorting
   the uses by pair and input order, the first claim wins; rounds settle the
   chains where a refused polygon releases a pair for a later one.
3. **Fans.** Around each vertex the polygons form fans: paths of corners
   linked through shared edges, found by pointer doubling over
   ``twin(prev(h))``. A vertex may hold any number of open fans, or one
   closed fan and nothing else (seed 000's restriction). Where the survivors
   of step 2 break that, the polygons around the offending vertices are
   replayed in input order (in Python, but only there) to find exactly which
   ones `add_polygon` would have refused.
4. **Boundary links.** Each fan's free incoming half-edge is linked to the
   free outgoing half-edge of the next fan around the vertex, so every fan is
   reachable in the vertex's rotation; ``V_BOUNDARY`` picks a free outgoing
   half-edge wherever there is one.

The repairs run before those steps, on the soup: `orient` decides which
polygons to reverse (and, asked to, where to cut a component that cannot be
oriented), and `separate` renumbers corners onto copies of vertices so that
every well-formed polygon fits (``build(..., split=True)``).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import NamedTuple

import numpy as np

from hestore.arrays import Ragged, TopologyArrays, component_roots, cyclic_next, ragged, run_heads, run_starts
from hestore.errors import HalfEdgeNotFreeError, InvalidInputError, NonManifoldError, PolicyError, VertexNotFreeError

__all__ = ["Refusal", "Built", "build", "well_formed", "separate", "Orientation", "orient"]

_I64 = np.int64


class Refusal(NamedTuple):
    """Why a polygon was refused: its input index, the error class and the reason."""

    index: int
    error: type
    reason: str


@dataclass(frozen=True)
class Built:
    """What `build` decided and made.

    Attributes
    ----------
    arrays : TopologyArrays
        Every table of the new mesh, with the ids it will be stored under:
        vertex ``i`` is input row ``i``, edge ``e`` owns half-edges ``2e``
        (its first use) and ``2e + 1``, polygon ``i`` is input polygon
        ``accepted[i]``. `hestore.validation.check_arrays` checks them
        before anything is written.
    accepted : ndarray
        Input indices of the stored polygons, ascending.
    refused : list of Refusal
        Every refused polygon, in input order.
    copied : ndarray of int
        With ``split=True``: vertex ``n_vertices + i`` is a copy of input
        vertex ``copied[i]``.
    """

    arrays: TopologyArrays
    accepted: np.ndarray
    refused: list[Refusal]
    copied: np.ndarray = field(default_factory=lambda: np.empty(0, dtype=_I64))


class _Corners(NamedTuple):
    poly: np.ndarray  # input polygon index of each corner
    a: np.ndarray  # corner vertex (origin of the half-edge leaving it)
    b: np.ndarray  # next corner vertex (target)
    slot: np.ndarray  # directed pair key: 2 * pair + direction (self-loops: direction 0)
    loop: np.ndarray  # bool, a == b


def _corners(n_vertices: int, soup: Ragged, keep: np.ndarray | None = None) -> _Corners:
    offsets, indices = soup.offsets, soup.indices
    counts = np.diff(offsets)
    poly = np.repeat(np.arange(len(counts), dtype=_I64), counts)
    succ = np.arange(1, len(indices) + 1, dtype=_I64)
    nonempty = counts > 0
    succ[offsets[1:][nonempty] - 1] = offsets[:-1][nonempty]
    a = indices
    b = indices[succ]
    if keep is not None:
        mask = keep[poly]
        poly, a, b = poly[mask], a[mask], b[mask]
    lo = np.minimum(a, b)
    hi = np.maximum(a, b)
    loop = a == b
    slot = (lo * max(n_vertices, 1) + hi) * 2 + (a > b)
    return _Corners(poly, a, b, slot, loop)


class Orientation(NamedTuple):
    """How `orient` turns a soup's polygons.

    Attributes
    ----------
    flip : ndarray of bool
        Per polygon: reversed.
    order : ndarray of int
        Per corner of the oriented soup, the corner of the input it comes
        from (a reversed polygon keeps its first corner and runs the others
        backwards), for corner data to follow.
    conflict : int or None
        A polygon of a component that cannot be oriented, or None (always
        None with ``cut=True``).
    cut : ndarray of int, shape (k, 2)
        With ``cut=True``: the edges, as vertex pairs, along which the
        components that cannot be oriented were cut; their two polygons now
        run them the same way (`build` with ``split=True`` then gives one of
        them its own copy of a vertex).
    """

    flip: np.ndarray
    order: np.ndarray
    conflict: int | None
    cut: np.ndarray


def orient(polygons, *, cut: bool = False, ok: np.ndarray | None = None) -> Orientation:
    """Decide which polygons to reverse so that each component is consistently oriented.

    Two polygons sharing an edge used by exactly two polygons agree when they
    run it in opposite directions. The choices form a signed graph; its
    double cover (polygon ``p`` unreversed is node ``2p``, reversed
    ``2p + 1``) is split into components set-based (`component_roots`). A
    component is non-orientable exactly when some ``2p`` and ``2p + 1`` fall
    together; otherwise the lowest polygon of each component keeps its
    orientation and the others follow it. Edges with more than two uses and
    self-loops decide nothing (the builder refuses what it cannot take).

    With ``cut=True`` a component that cannot be oriented is oriented along
    a breadth-first spanning tree of its polygons, from its lowest polygon;
    the edges where its neighbours then disagree are returned in ``cut``.
    Only the polygons in ``ok`` (default: all) take part (`well_formed`'s:
    a polygon the import leaves out anyway must not decide anything).

    Examples
    --------
    >>> o = orient([[0, 1, 2], [1, 2, 3], [3, 2, 4]])   # the second runs 1→2 like the first
    >>> o.flip.tolist(), o.order.tolist(), o.conflict
    ([False, True, True], [0, 1, 2, 3, 5, 4, 6, 8, 7], None)

    A Möbius band of three quads cannot be oriented; cut, one rung is opened:

    >>> band = [[0, 1, 4, 3], [1, 2, 5, 4], [2, 3, 0, 5]]
    >>> orient(band).conflict
    0
    >>> o = orient(band, cut=True)
    >>> o.flip.tolist(), o.cut.tolist()
    ([False, False, True], [[2, 5]])
    """
    soup = ragged(polygons)
    offsets, idx = soup.offsets, soup.indices
    n_p = len(offsets) - 1
    degree = np.diff(offsets)
    poly = np.repeat(np.arange(n_p, dtype=_I64), degree)
    start = np.zeros(len(idx), dtype=bool)
    start[offsets[:-1][degree > 0]] = True
    a, b = idx, idx[cyclic_next(start)] if len(idx) else idx
    use = np.flatnonzero((a != b) if ok is None else (a != b) & ok[poly])
    lo, hi, forward, owner = np.minimum(a, b)[use], np.maximum(a, b)[use], (a < b)[use], poly[use]
    order = np.lexsort((owner, hi, lo))
    lo, hi, forward, owner = lo[order], hi[order], forward[order], owner[order]
    first = np.flatnonzero(run_starts(lo, hi))
    count = np.diff(np.r_[first, len(lo)])
    pair = first[(count == 2)]
    pair = pair[owner[pair] != owner[pair + 1]]
    p, q = owner[pair], owner[pair + 1]
    same = (forward[pair] == forward[pair + 1]).astype(_I64)  # same direction: one of the two must turn
    u = np.r_[2 * p, 2 * p + 1]
    w = np.r_[2 * q + same, 2 * q + 1 - same]
    roots = component_roots(2 * n_p, u, w)
    stuck = np.flatnonzero(roots[0::2] == roots[1::2])
    flip = roots[0::2] > roots[1::2]
    cut_edges = np.empty((0, 2), dtype=_I64)
    if cut and len(stuck):
        inside = roots[2 * p] == roots[2 * p + 1]  # dual edges of the components that cannot be oriented
        tree = _tree_flips(n_p, p[inside], q[inside], same[inside].astype(bool), np.unique(roots[2 * stuck] // 2))
        ours = np.zeros(n_p, dtype=bool)
        ours[stuck] = True
        flip = np.where(ours, tree, flip)
        torn = inside.copy()
        torn[inside] = (flip[p[inside]] ^ flip[q[inside]]) != same[inside].astype(bool)
        cut_edges = np.column_stack([lo[pair][torn], hi[pair][torn]])
        stuck = stuck[:0]
    local = np.arange(len(idx), dtype=_I64) - offsets[:-1][poly]
    turned = flip[poly] & (local > 0)
    src = offsets[:-1][poly] + np.where(turned, degree[poly] - local, local)
    return Orientation(flip, src, int(stuck[0]) if len(stuck) else None, cut_edges)


def _tree_flips(n_p: int, p: np.ndarray, q: np.ndarray, differ: np.ndarray, roots: np.ndarray) -> np.ndarray:
    """Reversals along a breadth-first spanning forest of the dual edges ``p -- q``.

    ``differ`` says that the edge's two polygons must end up reversed
    differently. The search is level-synchronous, so it costs a few numpy
    gathers per level (the dual graph's diameter), not a Python step per
    polygon; each polygon follows the first neighbour that reaches it.
    """
    src, dst, par = np.r_[p, q], np.r_[q, p], np.r_[differ, differ]
    order = np.argsort(src, kind="stable")
    src, dst, par = src[order], dst[order], par[order]
    first = np.searchsorted(src, np.arange(n_p + 1))
    flip = np.zeros(n_p, dtype=bool)
    seen = np.zeros(n_p, dtype=bool)
    seen[roots] = True
    frontier = roots
    while len(frontier):
        count = first[frontier + 1] - first[frontier]
        at = np.repeat(first[frontier] - np.cumsum(count) + count, count) + np.arange(int(count.sum()))
        reach = ~seen[dst[at]]
        at = at[reach]
        frontier, pick = np.unique(dst[at], return_index=True)
        flip[frontier] = flip[src[at[pick]]] ^ par[at[pick]]
        seen[frontier] = True
    return flip


def build(n_vertices: int, polygons, *, allow_loops: bool = True, index_base: int = 0, split: bool = False) -> Built:
    """Decide which polygons the structure takes and build the half-edge arrays.

    Parameters
    ----------
    n_vertices : int
        Number of vertices; polygon indices must lie in ``range(n_vertices)``.
    polygons : Ragged or array_like or sequence of sequences
        Corners of each polygon, counter-clockwise.
    allow_loops : bool
        Whether a polygon may run along a self-loop (consecutive repeated
        corners).
    index_base : int
        Added to vertex numbers in refusal reasons (1 for OBJ files, whose
        indices count from 1).
    split : bool
        Keep every polygon that is well formed in itself (refuse only an
        empty one, an index out of range, or a self-loop the policy
        forbids), giving it its own copies of the vertices where it does not
        fit; see `separate`.

    Returns
    -------
    Built
        The arrays, the input indices of the polygons kept, every refusal and
        the copied vertices.

    Examples
    --------
    A square with both diagonal triangles, and a third triangle that tries to
    use the diagonal the same way as the first:

    >>> b = build(4, [[0, 1, 2], [0, 2, 3], [0, 1, 2]])
    >>> b.accepted.tolist(), len(b.arrays.e_id), len(b.arrays.he_id)
    ([0, 1], 5, 10)
    >>> from hestore.validation import check_arrays
    >>> check_arrays(b.arrays)
    []
    >>> b.refused[0].index, b.refused[0].error.__name__
    (2, 'HalfEdgeNotFreeError')

    With ``split=True`` the third triangle is kept too, as a triangle of its
    own on copies of vertices 0, 1 and 2 (vertices 4, 5 and 6), since each of
    its edges is taken:

    >>> b = build(4, [[0, 1, 2], [0, 2, 3], [0, 1, 2]], split=True)
    >>> b.accepted.tolist(), b.copied.tolist(), b.refused
    ([0, 1, 2], [0, 1, 2], [])
    """
    soup = ragged(polygons)
    refused: dict[int, Refusal] = {}
    ok = _polygon_checks(n_vertices, soup, allow_loops, refused, index_base)
    if not split:
        return _build(n_vertices, soup, ok, refused, index_base)
    plain = _build(n_vertices, soup, ok.copy(), dict(refused), index_base)
    if len(plain.accepted) == int(ok.sum()):
        return plain  # every well-formed polygon fits as it is: nothing to copy (a clean file costs one build)
    soup, copied = separate(n_vertices, soup, ok)
    while True:
        built = _build(n_vertices + len(copied), soup, ok.copy(), dict(refused), index_base)
        stuck = np.setdiff1d(np.flatnonzero(ok), built.accepted)
        if not len(stuck):
            return replace(built, copied=copied)
        soup, copied = _isolate(n_vertices, soup, copied, stuck)


def well_formed(n_vertices: int, polygons, *, allow_loops: bool = True) -> np.ndarray:
    """Which polygons are well formed in themselves: not empty, indices in range, no forbidden self-loop.

    The polygons ``build(..., split=True)`` keeps, and the ones `orient`
    should look at.

    Examples
    --------
    >>> well_formed(3, [[0, 1, 2], [], [0, 5, 1], [0, 0, 1]], allow_loops=False).tolist()
    [True, False, False, False]
    """
    return _polygon_checks(n_vertices, ragged(polygons), allow_loops, {}, 0)


def _build(n_vertices: int, soup: Ragged, ok: np.ndarray, refused: dict, index_base: int) -> Built:
    corners = _corners(n_vertices, soup, ok)
    order = np.argsort(corners.slot, kind="stable")
    _refuse_overused(corners, order, ok, refused, index_base)
    accepted = _settle_edge_uses(ok, corners, order)
    losers = ok & ~accepted
    built = _assemble(n_vertices, corners, order, accepted)
    fans = _fan_ends(n_vertices, built)
    crowded = _crowded_vertices(n_vertices, built, fans)
    if len(crowded):
        accepted = _replay(n_vertices, corners, ok, losers, crowded, refused, index_base)
        built = _assemble(n_vertices, corners, order, accepted)
        fans = _fan_ends(n_vertices, built)
        assert not len(_crowded_vertices(n_vertices, built, fans)), "replay left a crowded vertex"
    for p in np.flatnonzero(ok & ~accepted).tolist():
        if p not in refused:
            refused[p] = _edge_refusal(p, corners, order, accepted, index_base)
    arrays = _link_boundaries(n_vertices, built, fans)
    return Built(arrays, np.flatnonzero(accepted), [refused[p] for p in sorted(refused)])


def separate(n_vertices: int, soup: Ragged, ok: np.ndarray) -> tuple[Ragged, np.ndarray]:
    """Renumber corners so that every polygon in ``ok`` fits, copying vertices where they must part.

    Every directed vertex pair keeps its first use in input order (a
    self-loop its first two); the first uses of ``a→b`` and ``b→a`` are
    glued into one edge. A later use is *cut*: it has to become an edge of
    its own. Around each vertex, the corners linked through glued edges form
    fans: paths (open) or cycles (closed). A vertex keeps its open fans
    together, as the structure allows; each closed fan that is not alone
    there, and each fan where a cut use starts or ends, goes to a vertex of
    its own, so a cut opens the edge at both ends and leaves no pinch.
    The group holding the vertex's earliest corner keeps the vertex; the
    others get copies, numbered from ``n_vertices`` in order of their
    earliest corner. A clean soup comes back unchanged.

    All of it is set-based: one sort of the corners by vertex pair, and a
    union-find over corners (`component_roots`) for the fans.

    Returns
    -------
    (Ragged, ndarray)
        The renumbered soup, and for each copy the input vertex it copies.

    Examples
    --------
    Two triangles meeting only at vertex 0, each of them a closed fan there
    (two cones' tips): one cone moves to a copy, vertex 6.

    >>> cone = lambda t, r: [[t, r[0], r[1]], [t, r[1], r[2]], [t, r[2], r[0]], [r[2], r[1], r[0]]]
    >>> soup, copied = separate(7, ragged(cone(0, [1, 2, 3]) + cone(0, [4, 5, 6])), np.ones(8, dtype=bool))
    >>> soup.indices.reshape(-1, 3)[4:7].tolist(), copied.tolist()
    ([[7, 4, 5], [7, 5, 6], [7, 6, 4]], [0])
    """
    offsets, idx = soup.offsets, soup.indices
    counts = np.diff(offsets)
    poly = np.repeat(np.arange(len(counts), dtype=_I64), counts)
    first = np.zeros(len(idx), dtype=bool)
    first[offsets[:-1][counts > 0]] = True
    succ = cyclic_next(first)
    live = np.flatnonzero(ok[poly])
    a, b = idx[live], idx[succ[live]]
    loop = a == b
    slot = (np.minimum(a, b) * max(n_vertices, 1) + np.maximum(a, b)) * 2 + (a > b)
    order = np.argsort(slot, kind="stable")
    s_slot, s_loop = slot[order], loop[order]
    heads = run_starts(s_slot)
    rank = np.arange(len(order)) - run_heads(heads)
    cut = np.zeros(len(idx), dtype=bool)
    starts = live[order[rank >= np.where(s_loop, 2, 1)]]
    cut[starts] = True
    cut[succ[starts]] = True  # the corners where a cut use starts or ends
    # Glued: the first a→b with the first b→a (adjacent runs), a self-loop's first two uses.
    h = np.flatnonzero(heads)
    hs = s_slot[h]
    twin_run = (hs[:-1] % 2 == 0) & (hs[1:] == hs[:-1] + 1)
    second = np.flatnonzero(~heads & (rank == 1) & s_loop)
    x = live[order[np.r_[h[:-1][twin_run], second - 1]]]
    y = live[order[np.r_[h[1:][twin_run], second]]]
    # A glued edge links, at each of its ends, the corner it leaves from with the corner the twin reaches.
    u, w = np.r_[x, succ[x]], np.r_[succ[y], y]
    roots = component_roots(len(idx), u, w)
    fans = np.unique(roots[live])
    size = np.bincount(roots[live], minlength=len(idx))[fans]
    links = np.bincount(roots[u], minlength=len(idx))[fans]
    holds_cut = np.bincount(roots[cut], minlength=len(idx))[fans] > 0
    alone = (links == size) | holds_cut  # a closed fan, or one with a cut use
    v = idx[fans]
    shared = np.full(n_vertices, len(idx), dtype=_I64)
    np.minimum.at(shared, v[~alone], fans[~alone])
    label = np.where(alone, fans, shared[v])  # each group is named by its earliest corner
    groups_, at = np.unique(label, return_inverse=True)
    gv = idx[groups_]
    keeper = np.full(n_vertices, len(idx), dtype=_I64)
    np.minimum.at(keeper, gv, groups_)
    moves = groups_ != keeper[gv]
    vertex_of_group = np.where(moves, n_vertices + np.cumsum(moves) - 1, gv)
    fan_vertex = np.zeros(len(idx), dtype=_I64)
    fan_vertex[fans] = vertex_of_group[at]
    renumbered = idx.copy()
    renumbered[live] = fan_vertex[roots[live]]
    return Ragged(offsets, renumbered), gv[moves]


def _isolate(n_vertices: int, soup: Ragged, copied: np.ndarray, stuck: np.ndarray) -> tuple[Ragged, np.ndarray]:
    """Give each corner of the ``stuck`` polygons a new vertex of its own (OpenMesh's importer's remedy).

    `separate` leaves nothing stuck on the inputs we know of; this is the
    guarantee that ``split`` keeps every well-formed polygon whatever the
    input.
    """
    offsets, idx = soup.offsets, soup.indices
    counts = np.diff(offsets)
    mask = np.zeros(len(counts), dtype=bool)
    mask[stuck] = True
    where = np.flatnonzero(np.repeat(mask, counts))
    original = idx[where].copy()
    copy = original >= n_vertices
    original[copy] = copied[original[copy] - n_vertices]
    renumbered = idx.copy()
    renumbered[where] = n_vertices + len(copied) + np.arange(len(where), dtype=_I64)
    copied = np.r_[copied, original].astype(_I64)
    # Copies the stuck polygons held before are used by nobody now: drop them, keeping the order of the rest.
    used = np.zeros(len(copied), dtype=bool)
    live = renumbered[(renumbered >= n_vertices)]
    used[live - n_vertices] = True
    new_id = np.full(len(copied), -1, dtype=_I64)
    new_id[used] = n_vertices + np.arange(int(used.sum()), dtype=_I64)
    moved = renumbered >= n_vertices
    renumbered[moved] = new_id[renumbered[moved] - n_vertices]
    return Ragged(offsets, renumbered), copied[used]


def _polygon_checks(n_vertices: int, soup: Ragged, allow_loops: bool, refused: dict, base: int) -> np.ndarray:
    """Refuse the polygons that are bad on their own; return the mask of the rest."""
    offsets, indices = soup.offsets, soup.indices
    n = len(soup)
    counts = np.diff(offsets)
    ok = counts > 0
    for p in np.flatnonzero(~ok).tolist():
        refused[p] = Refusal(p, InvalidInputError, "a polygon needs at least one vertex")
    poly = np.repeat(np.arange(n, dtype=_I64), counts)
    out = (indices < 0) | (indices >= n_vertices)
    if out.any():
        first = {}
        for pos in np.flatnonzero(out).tolist():
            first.setdefault(int(poly[pos]), int(indices[pos]))
        for p, i in first.items():
            reason = f"vertex index {i + base} is out of range (there are {n_vertices} vertices)"
            refused[p] = Refusal(p, InvalidInputError, reason)
            ok[p] = False
    if not allow_loops:
        c = _corners(n_vertices, soup, ok)
        for pos in np.flatnonzero(c.loop).tolist():
            p = int(c.poly[pos])
            if ok[p]:
                refused[p] = Refusal(
                    p, PolicyError,
                    f"it runs along a self-loop at vertex {int(c.a[pos]) + base} (a repeated consecutive vertex) "
                    "and this mesh does not allow self-loop edges",
                )
                ok[p] = False
    return ok


def _refuse_overused(c: _Corners, order: np.ndarray, ok: np.ndarray, refused: dict, base: int) -> None:
    """Refuse a polygon that claims a directed pair more often than it has room.

    That is twice for ``a→b`` or three times for a self-loop: one edge has
    only two sides, so no order of insertion could take it.
    """
    slot, poly = c.slot[order], c.poly[order]
    run = run_heads(run_starts(slot, poly))
    times = np.bincount(run, minlength=len(run))[run]
    cap = np.where(c.loop[order], 2, 1)
    for pos in order[times > cap].tolist():
        p, a, b = int(c.poly[pos]), int(c.a[pos]) + base, int(c.b[pos]) + base
        if ok[p]:
            what = f"runs the self-loop at vertex {a} more than twice" if a == b else f"runs {a}→{b} twice"
            reason = f"it {what}, but an edge has only two sides (a repeated vertex the structure cannot take)"
            refused[p] = Refusal(p, HalfEdgeNotFreeError, reason)
            ok[p] = False


def _settle_edge_uses(ok: np.ndarray, c: _Corners, order: np.ndarray) -> np.ndarray:
    """Which polygons win their directed pairs when added one by one in input order.

    A use loses when the polygons before it already fill its pair. Polygons
    are decided in rounds: one whose every use fits even if all undecided
    earlier polygons were kept is accepted; one whose use does not fit beside
    the accepted ones alone is refused. The lowest undecided polygon is always
    decided, so the rounds end; on real input there are one to three.
    """
    n_polys = len(ok)
    state = np.where(ok, 0, 2).astype(np.int8)  # 0 undecided, 1 accepted, 2 refused
    if not len(order):
        return ok.copy()
    slot, s_poly = c.slot[order], c.poly[order]
    cap = np.where(c.loop[order], 2, 1)
    run = run_heads(run_starts(slot))
    own_run = run_heads(run_starts(slot, s_poly))  # this polygon's uses of this pair
    own = np.bincount(own_run, minlength=len(order))[own_run]
    while True:
        undecided = state[s_poly] == 0
        if not undecided.any():
            break
        alive = state[s_poly] != 2
        c_alive = np.cumsum(alive) - alive  # alive uses strictly before each position
        rank = c_alive - c_alive[run]
        fits = ~undecided | (rank < cap)
        bad = np.zeros(n_polys, dtype=bool)
        bad[s_poly[~fits]] = True
        state[(state == 0) & ~bad] = 1
        acc = state[s_poly] == 1
        c_acc = np.cumsum(acc) - acc
        before = c_acc[own_run] - c_acc[run]  # accepted uses by earlier polygons
        over = (state[s_poly] == 0) & (before + own > cap)
        state[s_poly[over]] = 2
    return state == 1


class _Assembly(NamedTuple):
    origin: np.ndarray
    next: np.ndarray
    prev: np.ndarray
    polygon: np.ndarray
    polygon_halfedge: np.ndarray


def _assemble(n_vertices: int, c: _Corners, order: np.ndarray, accepted: np.ndarray) -> _Assembly:
    """Half-edges of the accepted polygons, with twins matched; free gaps not yet linked."""
    use = order[accepted[c.poly[order]]]  # accepted corners, sorted by (pair, direction, input order)
    pair = c.slot[use] >> 1
    n = len(use)
    first_in_pair = run_starts(pair)
    starts = np.flatnonzero(first_in_pair)
    # Each pair holds one or two uses (capacity); the earlier one in input order owns 2e.
    two = np.zeros(len(starts), dtype=bool)
    two[(np.cumsum(first_in_pair) - 1)[~first_in_pair]] = True
    u0 = use[starts]
    u1 = np.where(two, use[np.minimum(starts + 1, n - 1)], -1)
    swap = two & (u1 < u0)
    first_use = np.where(swap, u1, u0)
    other_use = np.where(swap, u0, u1)
    edge_of_group = np.empty(len(starts), dtype=_I64)
    edge_of_group[np.argsort(first_use, kind="stable")] = np.arange(len(starts), dtype=_I64)
    n_he = 2 * len(starts)
    corner_he = np.empty(len(c.poly), dtype=_I64)
    corner_he[first_use] = 2 * edge_of_group
    corner_he[other_use[two]] = 2 * edge_of_group[two] + 1

    origin = np.empty(n_he, dtype=_I64)
    polygon = np.full(n_he, -1, dtype=_I64)
    nxt = np.full(n_he, -1, dtype=_I64)
    prv = np.full(n_he, -1, dtype=_I64)
    # Free twins: the half-edge opposite a pair's only use starts at its target.
    lone = ~two
    origin[2 * edge_of_group[lone] + 1] = c.b[first_use[lone]]
    acc_pos = np.flatnonzero(accepted[c.poly])  # accepted corners in input order
    he = corner_he[acc_pos]
    origin[he] = c.a[acc_pos]
    kept_poly = c.poly[acc_pos]
    new_id = np.cumsum(accepted) - 1
    polygon[he] = new_id[kept_poly]
    # Within a polygon the corners are consecutive, so next is the following
    # corner except at the polygon's last corner, which wraps to its first.
    starts_p = run_starts(kept_poly)
    succ = cyclic_next(starts_p)
    nxt[he] = he[succ]
    prv[he[succ]] = he
    return _Assembly(origin, nxt, prv, polygon, he[starts_p])


def _fan_ends(n_vertices: int, a: _Assembly) -> tuple[np.ndarray, np.ndarray]:
    """Follow ``twin(prev(h))`` from every half-edge until a free one.

    Returns ``(end, closed)``: for a half-edge on an open fan, ``end`` is the
    fan's free outgoing half-edge; on a closed fan (a cycle), ``closed`` is
    True and ``end`` is the cycle's smallest half-edge. Pointer doubling:
    ``log2`` of the largest vertex degree steps, each a numpy gather.
    """
    n = len(a.origin)
    max_steps = int(np.bincount(a.origin, minlength=n_vertices).max()) if n else 0
    ids = np.arange(n, dtype=_I64)
    free = a.polygon < 0
    ptr = np.where(free, ids, a.prev ^ 1)
    low = ids.copy()
    steps = 1
    while steps < max_steps + 1:
        low = np.minimum(low, low[ptr])
        ptr = ptr[ptr]
        steps *= 2
    closed = ~free[ptr]
    return np.where(closed, low, ptr), closed


def _crowded_vertices(n_vertices: int, a: _Assembly, fans: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """Vertices where a closed fan meets anything else (seed 000's restriction)."""
    end, closed = fans
    ids = np.arange(len(a.origin))
    cycles = np.bincount(a.origin[closed & (end == ids)], minlength=n_vertices)
    opens = np.bincount(a.origin[a.polygon < 0], minlength=n_vertices)
    return np.flatnonzero((cycles > 1) | ((cycles > 0) & (opens > 0)))


def _link_boundaries(n_vertices: int, a: _Assembly, fans: tuple[np.ndarray, np.ndarray]) -> TopologyArrays:
    """Link the free half-edges around each vertex and choose ``vertex.halfedge``."""
    nxt, prv = a.next, a.prev
    free = a.polygon < 0
    vhe = np.full(n_vertices, -1, dtype=_I64)
    if len(a.origin):
        end = fans[0]
        # A fan starts at a polygon half-edge whose twin is free; that twin
        # arrives at the vertex and is the fan's free incoming half-edge.
        start = np.flatnonzero(~free & free[np.arange(len(free)) ^ 1])
        v = a.origin[start]
        f = end[start]
        g = start ^ 1
        order = np.lexsort((f, v))
        v, f, g = v[order], f[order], g[order]
        after = cyclic_next(run_starts(v))
        # Fan i's free incoming half-edge continues with fan i+1's free outgoing one.
        nxt[g] = f[after]
        prv[f[after]] = g
        ids = np.arange(len(a.origin), dtype=_I64)
        vhe[a.origin] = ids
        vhe[a.origin[free]] = ids[free]
    ids = np.arange(len(a.origin), dtype=_I64)
    edges = np.arange(len(a.origin) // 2, dtype=_I64)
    return TopologyArrays(
        he_id=ids, he_origin=a.origin, he_next=nxt, he_prev=prv, he_twin=ids ^ 1, he_edge=ids >> 1,
        he_polygon=a.polygon, v_id=np.arange(n_vertices, dtype=_I64), v_halfedge=vhe,
        e_id=edges, e_halfedge=2 * edges,
        p_id=np.arange(len(a.polygon_halfedge), dtype=_I64), p_halfedge=a.polygon_halfedge,
    )


def _edge_refusal(p: int, c: _Corners, order: np.ndarray, accepted: np.ndarray, base: int) -> Refusal:
    """Explain why polygon ``p`` lost a directed pair to earlier polygons."""
    sorted_slots = c.slot[order]
    for pos in np.flatnonzero(c.poly == p).tolist():
        a, b, slot = int(c.a[pos]) + base, int(c.b[pos]) + base, int(c.slot[pos])
        lo, hi = np.searchsorted(sorted_slots, [slot, slot + 1])
        holders = sorted({int(q) for q in c.poly[order[lo:hi]] if accepted[q] and q < p})
        cap = 2 if a == b else 1
        if len(holders) + sum(1 for q in c.poly[order[lo:hi]] if q == p) <= cap:
            continue
        names = ", ".join(map(str, holders))
        if a == b:
            if len(holders) < cap:
                reason = f"it runs the self-loop at vertex {a} twice, but polygon {names} already has one side of it"
            else:
                reason = f"both sides of the self-loop at vertex {a} already have polygons ({names})"
            return Refusal(p, HalfEdgeNotFreeError, reason)
        rev = slot ^ 1
        lo2, hi2 = np.searchsorted(sorted_slots, [rev, rev + 1])
        back = sorted({int(q) for q in c.poly[order[lo2:hi2]] if accepted[q] and q < p})
        if back:
            return Refusal(
                p, HalfEdgeNotFreeError,
                f"edge {a}–{b} already has a polygon on each side ({names} on {a}→{b}, {back[0]} on {b}→{a}); "
                "a third cannot be added (a complex edge)",
            )
        return Refusal(
            p, HalfEdgeNotFreeError,
            f"polygon {names} already runs {a}→{b}: this one runs the same way, so its orientation "
            "contradicts that neighbour's (or it repeats it)",
        )
    raise AssertionError(f"polygon {p} was refused without a reason")  # pragma: no cover


def _replay(n_vertices, c: _Corners, ok, losers, crowded, refused: dict, base: int) -> np.ndarray:
    """Add the polygons around crowded vertices one by one, as the kernel would.

    Only polygons touching the region ``R`` (crowded vertices and the corners
    of polygons that lost an edge use) can be decided differently from the
    set-based pass: a polygon outside ``R`` shares no contested pair and
    meets only vertices whose fans stay valid whatever happens inside ``R``.
    So those are kept, and the polygons touching ``R`` are replayed in input
    order against a small model of each vertex's fans in ``R``.
    """
    region = np.zeros(n_vertices, dtype=bool)
    region[crowded] = True
    region[c.a[losers[c.poly]]] = True
    touching = np.zeros(len(ok), dtype=bool)
    touching[c.poly[region[c.a]]] = True
    touching &= ok
    accepted = ok & ~touching
    inside = touching[c.poly]
    # Uses, by the polygons kept outright, of the directed pairs replayed.
    outside = accepted[c.poly] & np.isin(c.slot, c.slot[inside])
    slots, counts = np.unique(c.slot[outside], return_counts=True)
    used = dict(zip(slots.tolist(), counts.tolist()))
    fans: dict[int, _VertexFans] = {}
    uses: dict[int, list[tuple[int, int, int]]] = {}
    for p, a, b, s in zip(c.poly[inside].tolist(), c.a[inside].tolist(), c.b[inside].tolist(), c.slot[inside].tolist()):
        uses.setdefault(p, []).append((a, b, s))
    for p in sorted(uses):
        loop = uses[p]
        claims: dict[int, int] = {}
        ends = []  # (a, b, k): k tells which of a self-loop's two half-edges the use takes
        for a, b, s in loop:
            ends.append((a, b, used.get(s, 0) + claims.get(s, 0)))
            claims[s] = claims.get(s, 0) + 1
        if any(k >= (2 if a == b else 1) for a, b, k in ends):
            continue  # refused for its edge; explained afterwards
        wedges: dict[int, list] = {}
        for i in range(len(ends)):
            a_in, v, k_in = ends[i - 1]
            _, b_out, k_out = ends[i]
            if region[v]:
                wedges.setdefault(v, []).append((_in_end(a_in, v, k_in), _out_end(v, b_out, k_out)))
        closed = [v for v in wedges if v in fans and fans[v].closed()]
        if closed:
            refused[p] = Refusal(
                p, VertexNotFreeError,
                f"vertex {closed[0] + base} is not free: a closed fan of polygons already surrounds it, "
                "so nothing more can attach there",
            )
            continue
        crowded_at = [v for v, w in wedges.items() if not fans.setdefault(v, _VertexFans()).fits(w)]
        if crowded_at:
            refused[p] = Refusal(
                p, NonManifoldError,
                f"at vertex {crowded_at[0] + base} it would close a fan while other polygons meet there: a vertex "
                "holds either open fans or one closed fan alone (a complex vertex)",
            )
            continue
        for v, w in wedges.items():
            fans[v].add(w)
        for s, k in claims.items():
            used[s] = used.get(s, 0) + k
        accepted[p] = True
    return accepted


def _out_end(v: int, b: int, k: int):
    """The edge end at ``v`` that a use ``v→b`` leaves from (``k``: which use of a self-loop)."""
    return ("loop", k) if b == v else ("to", b)


def _in_end(a: int, v: int, k: int):
    """The edge end at ``v`` that a use ``a→v`` arrives at.

    A self-loop's use ``k`` arrives where use ``1 - k`` leaves.
    """
    return ("loop", 1 - k) if a == v else ("to", a)


class _VertexFans:
    """The corners around one vertex: edge ends linked by the polygons' wedges.

    Every edge end has at most two wedges (one per side of the edge), so the
    ends and wedges form paths (open fans) and cycles (closed fans).
    """

    __slots__ = ("wedges",)

    def __init__(self) -> None:
        self.wedges: list = []

    def add(self, wedges: list) -> None:
        self.wedges.extend(wedges)

    def closed(self) -> bool:
        """Whether a fan already closes around the vertex."""
        return _shape(self.wedges)[0] > 0

    def fits(self, extra: list) -> bool:
        """Whether, with ``extra``, the vertex is still open fans only, or one closed fan alone."""
        cycles, components = _shape(self.wedges + extra)
        return cycles == 0 or (cycles == 1 and components == 1)


def _shape(wedges: list) -> tuple[int, int]:
    """Number of cycles and of components of the graph of edge ends and wedges."""
    parent: dict = {}

    def find(x):
        parent.setdefault(x, x)
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    cycles = 0
    for x, y in wedges:
        rx, ry = find(x), find(y)
        if rx == ry:
            cycles += 1
        else:
            parent[rx] = ry
    return cycles, len({find(x) for x in parent})
