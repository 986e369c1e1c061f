"""The array vocabulary: a mesh's topology as numpy columns, and the helpers on them.

This module owns `TopologyArrays` (the four tables as int64 columns, NULL as
-1), the currency of building and checking: `hestore.build` makes them,
`hestore.bulk` writes them as an import, and `hestore.validation` reads a
stored mesh into them and checks them, so a freshly built import can be
validated in memory before anything is written. It owns `Ragged` (polygon
soups), the one integer coercion of index arrays (`as_integers`), and the
numpy building blocks every set-based module shares — mapping ids to rows
(`Index`: every id → row mapping of hestore goes through it), labelling the
cycles of a function (`cycles`, `restricted_cycles` for walks kept within
groups, `cycle_positions`), runs of equal keys (`run_starts`, `run_heads`,
`cyclic_next`, `groups`), dense numbering (`dense`), walking polygon loops
(`polygon_halfedges`, `polygon_loops`) and position columns (`positions`).
`hestore.summary`, `hestore.render`, `hestore.graphs` and the exports of
`hestore.bulk` read only the columns they need into records of their own,
and use these building blocks on them.

Nothing here knows SQL or handles, and nothing builds a Python object per
element.

Examples
--------
A triangle as arrays, its loop walked back from the ``next`` column:

>>> import numpy as np
>>> from hestore.arrays import TopologyArrays, polygon_loops
>>> a = lambda *v: np.array(v, dtype=np.int64)
>>> tri = TopologyArrays(
...     he_id=a(0, 1, 2, 3, 4, 5), he_origin=a(0, 1, 1, 2, 2, 0),
...     he_next=a(2, 5, 4, 1, 0, 3), he_prev=a(4, 3, 0, 5, 2, 1),
...     he_twin=a(1, 0, 3, 2, 5, 4), he_edge=a(0, 0, 1, 1, 2, 2),
...     he_polygon=a(0, -1, 0, -1, 0, -1),
...     v_id=a(0, 1, 2), v_halfedge=a(5, 1, 3),
...     e_id=a(0, 1, 2), e_halfedge=a(0, 2, 4), p_id=a(0), p_halfedge=a(0))
>>> loops = polygon_loops(tri.v_id, tri.he_id, tri.he_origin, tri.he_next, tri.p_halfedge)
>>> loops.indices.tolist()
[0, 1, 2]
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from hestore.errors import InvalidInputError, InvariantViolationError, Violation, shown

__all__ = [
    "TopologyArrays",
    "Ragged",
    "ragged",
    "as_integers",
    "Index",
    "cycles",
    "restricted_cycles",
    "component_roots",
    "cycle_positions",
    "run_starts",
    "run_heads",
    "cyclic_next",
    "groups",
    "first_per_group",
    "dense",
    "polygon_loops",
    "polygon_halfedges",
    "positions",
]

I64 = np.int64


class TopologyArrays(NamedTuple):
    """The topology of one mesh as int64 arrays, one group per table.

    Each table's arrays are sorted by its ``id`` column; ids are the stored
    ids (not dense, not row numbers). NULL references are ``-1``.

    Attributes
    ----------
    he_id, he_origin, he_next, he_prev, he_twin, he_edge, he_polygon : ndarray
        The ``halfedges`` table; ``he_polygon`` is -1 for a free half-edge.
    v_id, v_halfedge : ndarray
        The ``vertices`` table; ``v_halfedge`` is -1 for an isolated vertex.
    e_id, e_halfedge : ndarray
        The ``edges`` table.
    p_id, p_halfedge : ndarray
        The ``polygons`` table.

    Examples
    --------
    >>> arrays = TopologyArrays.empty()
    >>> len(arrays.he_id), arrays.he_id.dtype
    (0, dtype('int64'))
    """

    he_id: np.ndarray
    he_origin: np.ndarray
    he_next: np.ndarray
    he_prev: np.ndarray
    he_twin: np.ndarray
    he_edge: np.ndarray
    he_polygon: np.ndarray
    v_id: np.ndarray
    v_halfedge: np.ndarray
    e_id: np.ndarray
    e_halfedge: np.ndarray
    p_id: np.ndarray
    p_halfedge: np.ndarray

    @classmethod
    def empty(cls) -> "TopologyArrays":
        """The arrays of a mesh without any element."""
        return cls(*(np.empty(0, dtype=I64) for _ in cls._fields))

    #: The tables' columns, grouped by element kind, each group's id first.
    GROUPS = (
        ("halfedge", ("he_id", "he_origin", "he_next", "he_prev", "he_twin", "he_edge", "he_polygon")),
        ("vertex", ("v_id", "v_halfedge")),
        ("edge", ("e_id", "e_halfedge")),
        ("polygon", ("p_id", "p_halfedge")),
    )


class Ragged(NamedTuple):
    """Polygons as one flat index array: polygon ``i`` is ``indices[offsets[i]:offsets[i + 1]]``.

    Examples
    --------
    >>> r = Ragged(np.array([0, 3, 7]), np.array([0, 1, 2, 2, 1, 3, 4]))
    >>> len(r), r.indices[r.offsets[1]:r.offsets[2]].tolist()
    (2, [2, 1, 3, 4])
    """

    offsets: np.ndarray
    indices: np.ndarray

    def __len__(self) -> int:
        return len(self.offsets) - 1


def ragged(polygons) -> Ragged:
    """Normalise polygons given as an ``(F, k)`` array or a sequence of sequences.

    Parameters
    ----------
    polygons : array_like or sequence of sequences of int, or Ragged
        Vertex indices, one row per polygon. A flat sequence of numbers, a
        mapping, a string and rows that are not flat sequences of integers
        are refused.

    Returns
    -------
    Ragged

    Raises
    ------
    InvalidInputError
        When the polygons are not rows of integers.

    Examples
    --------
    >>> r = ragged([[0, 1, 2], [2, 1, 3, 4]])
    >>> r.offsets.tolist(), r.indices.tolist()
    ([0, 3, 7], [0, 1, 2, 2, 1, 3, 4])
    >>> ragged(np.array([[0, 1, 2], [0, 2, 3]])).offsets.tolist()
    [0, 3, 6]
    >>> ragged([0, 1, 2])
    Traceback (most recent call last):
    ...
    hestore.errors.InvalidInputError: polygons must be ...; polygon 0 is 0, not a sequence of vertex indices
    """
    if isinstance(polygons, Ragged):
        return Ragged(np.asarray(polygons.offsets, dtype=I64), _as_indices(polygons.indices))
    what = "polygons must be an (F, k) array or a sequence of index sequences"
    if isinstance(polygons, np.ndarray) and polygons.dtype != object:
        if polygons.ndim != 2:
            raise InvalidInputError(f"{what}, not a {polygons.ndim}-d array")
        f, k = polygons.shape
        return Ragged(np.arange(f + 1, dtype=I64) * k, _as_indices(polygons.reshape(-1)))
    if isinstance(polygons, (str, bytes, dict)) or not hasattr(polygons, "__iter__"):
        raise InvalidInputError(f"{what}, not {type(polygons).__name__}")
    if isinstance(polygons, (list, tuple)) and polygons:
        try:
            # Rows of one length: one conversion instead of one per polygon.
            whole = np.asarray(polygons)
        except Exception:  # noqa: BLE001 - ragged rows, or items whose own conversions raise: taken row by row
            whole = None
        if whole is not None and whole.ndim == 2 and whole.dtype.kind in "iuf":
            return ragged(whole)
    try:
        given = list(polygons)
    except Exception as exc:  # noqa: BLE001 - a 0-d array, or the caller's __iter__, may raise anything
        raise InvalidInputError(f"{what}; iterating over them raised {type(exc).__name__}: {exc}") from exc
    rows = []
    for i, p in enumerate(given):
        if isinstance(p, (str, bytes, dict)) or not hasattr(p, "__len__"):
            raise InvalidInputError(f"{what}; polygon {i} is {shown(p)}, not a sequence of vertex indices")
        try:
            row = np.asarray(p)
        except Exception:  # noqa: BLE001 - ragged, or items whose own conversions raise
            raise InvalidInputError(
                f"{what}; polygon {i} is not a flat sequence of vertex indices: {shown(p)}"
            ) from None
        if row.ndim != 1 or row.dtype == object:
            raise InvalidInputError(f"{what}; polygon {i} is not a flat sequence of vertex indices: {shown(p)}")
        rows.append(row)
    lengths = np.fromiter((len(r) for r in rows), dtype=I64, count=len(rows))
    offsets = np.zeros(len(rows) + 1, dtype=I64)
    np.cumsum(lengths, out=offsets[1:])
    flat = np.concatenate(rows) if rows else np.zeros(0, dtype=I64)
    return Ragged(offsets, _as_indices(flat))


def _as_indices(a) -> np.ndarray:
    a = np.asarray(a)
    if a.size == 0:
        return np.zeros(0, dtype=I64)
    if a.dtype.kind == "b":
        raise InvalidInputError("polygon vertex indices must be integers, not booleans")
    found = as_integers(a)
    if found is not None:
        return found
    if a.dtype.kind == "u":
        raise InvalidInputError("a polygon vertex index is larger than any vertex count")
    raise InvalidInputError(
        f"polygon vertex indices must be integers, got {a.dtype} values such as {shown(a.reshape(-1)[:3].tolist())}"
    )


def as_integers(values: np.ndarray) -> np.ndarray | None:
    """Integer-valued numbers as int64, or None unless every one is an integer that int64 holds.

    The one integer coercion of arrays: integer arrays convert as they are
    (a uint64 beyond int64's range is None); floats must be finite whole
    numbers of magnitude below 2**63. Booleans and other dtypes are None.
    Callers say what was wrong in their own words (`ragged` refuses, the
    file readers of `hestore.io` call the file malformed).

    Examples
    --------
    >>> as_integers(np.array([3.0, -1.0])).tolist(), as_integers(np.array([0.5])), as_integers(np.array([2.0**63]))
    ([3, -1], None, None)
    >>> as_integers(np.array([2**64 - 1], dtype=np.uint64)) is None
    True
    """
    values = np.asarray(values)
    if values.dtype.kind in "iu":
        if values.dtype == np.uint64 and values.size and values.max() > np.iinfo(I64).max:
            return None
        return values.astype(I64, copy=False)
    if values.dtype.kind == "f":
        with np.errstate(invalid="ignore"):
            whole = np.isfinite(values) & (values == np.floor(values)) & (np.abs(values) < 2.0**63)
        return values.astype(I64) if whole.all() else None
    return None


class Index:
    """Maps ids of one table (sorted, distinct) to row numbers.

    Contiguous ids map by subtraction; ids spread over at most ``SPREAD``
    times their count through a lookup table; sparser ones by
    `numpy.searchsorted` on the sorted references (sorted keys keep the binary
    searches cache-friendly).

    Parameters
    ----------
    ids : ndarray of int64
        Sorted, distinct ids.

    Examples
    --------
    >>> index = Index(np.array([2, 5, 9]))
    >>> rows, ok = index.find(np.array([9, 3, 2]))
    >>> rows.tolist(), ok.tolist()
    ([2, 0, 0], [True, False, True])
    """

    #: Ids spread over at most this many times their count use a lookup table.
    SPREAD = 8

    def __init__(self, ids: np.ndarray) -> None:
        self.ids = ids
        self.n = n = len(ids)
        self.first = int(ids[0]) if n else 0
        span = int(ids[-1]) - self.first + 1 if n else 0
        self.contiguous = n > 0 and span == n
        self.table = None
        if n and not self.contiguous and span <= self.SPREAD * n + 1024:
            self.table = np.full(span, -1, dtype=np.int32 if n < 2**31 else I64)
            self.table[ids - self.first] = np.arange(n, dtype=self.table.dtype)

    def find(self, refs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Row of each reference, and whether it exists.

        Rows of missing references are 0 (a valid index when the table is not
        empty); use them only where the returned mask is True.
        """
        n = self.n
        if n == 0:
            return np.zeros(len(refs), dtype=I64), np.zeros(len(refs), dtype=bool)
        if self.contiguous or self.table is not None:
            rows = refs - self.first
            ok = (rows >= 0) & (rows < (n if self.contiguous else len(self.table)))
            rows[~ok] = 0
            if self.table is not None:
                rows = self.table[rows].astype(I64)
                ok &= rows >= 0
                rows[~ok] = 0
            return rows, ok
        order = np.argsort(refs, kind="stable")
        keys = refs[order]
        found = np.searchsorted(self.ids, keys)
        np.minimum(found, n - 1, out=found)
        hit = self.ids[found] == keys
        found[~hit] = 0
        rows = np.empty(len(refs), dtype=I64)
        ok = np.empty(len(refs), dtype=bool)
        rows[order] = found
        ok[order] = hit
        return rows, ok

    def get(self, refs: np.ndarray) -> np.ndarray:
        """Row of each reference, -1 where it names nothing.

        Examples
        --------
        >>> Index(np.array([2, 5, 9])).get(np.array([9, 3, 2])).tolist()
        [2, -1, 0]
        """
        rows, ok = self.find(refs)
        return np.where(ok, rows, -1)

    def rows(self, refs: np.ndarray, *, kind: str, owners: np.ndarray, owner_kind: str, column: str) -> np.ndarray:
        """Row of each reference, all of which must exist.

        Raises
        ------
        InvariantViolationError
            Some reference names no element (``REF``); up to five are listed,
            as ``owner_kind owner: column = ref``.
        """
        rows, ok = self.find(refs)
        if not ok.all():
            bad = ~ok
            raise InvariantViolationError(
                [
                    Violation("REF", owner_kind, (o, r), f"{column} = {r}, but there is no {kind} {r}")
                    for o, r in zip(owners[bad][:5].tolist(), refs[bad][:5].tolist())
                ]
            )
        return rows


def cycles(f: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Label the cycles of the function ``i -> f[i]`` on ``range(len(f))``.

    Pointer jumping: after round k, ``label[i]`` is the least index among
    ``i, f(i), ..., f^(2^k - 1)(i)`` and ``jump = f^(2^k)``; ``ceil(log2 n)``
    rounds cover every orbit. When ``f`` is a permutation the rounds stop as
    soon as no label changes (then every window already holds its cycle's
    minimum).

    Returns
    -------
    label : ndarray
        For an element on a cycle: the least index of its cycle. (For an
        element on a tail leading into a cycle, the least index of its orbit.)
    on_cycle : ndarray of bool
        Whether the element lies on a cycle (``f`` need not be a permutation).
    end : ndarray
        An element of the cycle that the orbit of each element ends in (the
        element itself when it is on a cycle).

    Examples
    --------
    >>> label, on_cycle, end = cycles(np.array([1, 0, 3, 2, 2]))
    >>> label.tolist(), on_cycle.tolist(), end.tolist()
    ([0, 0, 2, 2, 2], [True, True, True, True, False], [0, 1, 2, 3, 3])
    """
    n = len(f)
    label = np.arange(n, dtype=I64)
    if n == 0:
        return label, np.zeros(0, dtype=bool), label
    is_permutation = bool((np.bincount(f, minlength=n) == 1).all())
    jump = f
    reach = 1  # jump == f^reach
    while reach < n:
        new = np.minimum(label, label[jump])
        if is_permutation and np.array_equal(new, label):
            break
        label = new
        jump = jump[jump]
        reach *= 2
    if is_permutation:
        return label, np.ones(n, dtype=bool), np.arange(n, dtype=I64)
    # jump = f^m with m >= n: its image is exactly the set of cyclic elements.
    on_cycle = np.zeros(n, dtype=bool)
    on_cycle[jump] = True
    return label, on_cycle, np.where(on_cycle, np.arange(n, dtype=I64), jump)


def restricted_cycles(step: np.ndarray, group: np.ndarray) -> tuple[np.ndarray, ...]:
    """Label the cycles of ``step`` walked only within a group: `cycles` of the restricted function.

    Element ``i`` steps to ``step[i]`` when both lie in one group
    (``group[step[i]] == group[i] >= 0``) and stays where it is otherwise:
    a walk stops where it would leave its group. An element of no group
    (``group[i] < 0``) is a fixed point nothing steps to, so only the
    elements of groups are walked — the few free half-edges of a mesh with a
    small boundary cost no more than their number. Polygon loops (``next``
    within a polygon), the rotation around a vertex (``next(twin(h))``
    within an origin) and boundary loops (``next`` among free half-edges)
    are such walks.

    Parameters
    ----------
    step : ndarray of int
        A function on ``range(n)``: each element's successor.
    group : ndarray of int
        Each element's group, negative for none.

    Returns
    -------
    rows : ndarray
        The elements of groups, ascending; the other elements are cycles of
        their own.
    f : ndarray
        Per entry of ``rows``, the position in ``rows`` it steps to (its own
        where it stays).
    label, on_cycle, end : ndarray
        What `cycles` returns for ``f``: positions in ``rows``.

    Examples
    --------
    The walk 0 -> 1 -> 2 -> 0 within group 7; 4 would step to 0, in another
    group, and 3 is in none:

    >>> rows, f, label, on_cycle, end = restricted_cycles(np.array([1, 2, 0, 0, 0]), np.array([7, 7, 7, -1, 8]))
    >>> rows.tolist(), f.tolist(), label.tolist(), on_cycle.tolist()
    ([0, 1, 2, 4], [1, 2, 0, 3], [0, 0, 0, 3], [True, True, True, True])
    """
    grouped = group >= 0
    rows = np.flatnonzero(grouped)
    position = np.cumsum(grouped) - 1  # of each element of a group in ``rows``: those before it
    to = step[rows]
    f = np.where(group[to] == group[rows], position[to], np.arange(len(rows), dtype=I64))
    return (rows, f, *cycles(f))


def cycle_positions(f: np.ndarray, label: np.ndarray) -> np.ndarray:
    """Steps from the smallest member of each cycle of ``f`` to each element.

    List ranking by pointer jumping: cut every cycle just before its smallest
    member (``label[i] == i``), count the steps from each element to the cut,
    and subtract from the cycle's length. ``log2`` of the longest cycle rounds.

    Examples
    --------
    >>> f = np.array([2, 0, 1])          # the cycle 0 -> 2 -> 1 -> 0
    >>> cycle_positions(f, cycles(f)[0]).tolist()
    [0, 2, 1]
    """
    n = len(f)
    ids = np.arange(n, dtype=I64)
    succ = np.where(label[f] == f, ids, f)
    to_end = (succ != ids).astype(I64)
    while True:
        jumped = succ[succ]
        if np.array_equal(jumped, succ):
            break
        to_end += to_end[succ]
        succ = jumped
    length = np.bincount(label, minlength=n)[label]
    return length - 1 - to_end


def component_roots(n: int, u: np.ndarray, w: np.ndarray) -> np.ndarray:
    """For each of ``n`` vertices, the smallest vertex of its connected component.

    Vectorised union-find on the edges ``u[i] -- w[i]``. The forest is kept
    flat (every vertex points at its root); each round hooks every root onto
    the smallest root next to its tree, when that is smaller, then flattens
    again by pointer jumping. A root no tree hooks onto in one round is next
    to a tree that has meanwhile hooked onto a smaller root, so it hooks in
    the next round: every tree merges with another within two rounds, and the
    rounds are at most ``2 log2 n``. Hooking only downwards never makes a
    cycle, and the smallest vertex of a component is never hooked, so it ends
    as the root.

    Examples
    --------
    >>> component_roots(5, np.array([4, 1]), np.array([2, 3])).tolist()
    [0, 1, 2, 1, 2]
    """
    parent = np.arange(n, dtype=I64)
    keep = u != w
    u, w = u[keep], w[keep]
    while len(u):
        pu, pw = parent[u], parent[w]
        across = pu != pw
        # An edge inside one tree stays inside it: drop it for good.
        u, w, pu, pw = u[across], w[across], pu[across], pw[across]
        if not len(u):
            break
        np.minimum.at(parent, np.maximum(pu, pw), np.minimum(pu, pw))
        while True:
            grand = parent[parent]
            if np.array_equal(grand, parent):
                break
            parent = grand
    return parent


# --------------------------------------------------------------------------
# The summaries


def run_starts(*sorted_keys: np.ndarray) -> np.ndarray:
    """Where a run of equal key tuples begins, in arrays sorted by those keys.

    Examples
    --------
    >>> run_starts(np.array([1, 1, 2, 2]), np.array([5, 6, 6, 6])).tolist()
    [True, True, True, False]
    """
    n = len(sorted_keys[0])
    start = np.zeros(n, dtype=bool)
    start[:1] = True
    for k in sorted_keys:
        start[1:] |= k[1:] != k[:-1]
    return start


def run_heads(start: np.ndarray) -> np.ndarray:
    """For each position, the position where its run begins (``start`` flags the beginnings).

    Examples
    --------
    >>> run_heads(np.array([True, False, True, False, False])).tolist()
    [0, 0, 2, 2, 2]
    """
    return np.maximum.accumulate(np.where(start, np.arange(len(start)), 0))


def cyclic_next(start: np.ndarray) -> np.ndarray:
    """Each position's successor within its run, the last of a run wrapping to the first.

    Examples
    --------
    >>> cyclic_next(np.array([True, False, False, True])).tolist()
    [1, 2, 0, 3]
    """
    n = len(start)
    last = np.ones(n, dtype=bool)
    last[:-1] = start[1:]
    succ = np.arange(1, n + 1)
    succ[last] = run_heads(start)[last]
    return succ


def groups(labels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Element order grouped by label (labels ascending, elements in order) and the group offsets.

    Examples
    --------
    >>> order, bounds = groups(np.array([7, 3, 7, 3, 3]))
    >>> order.tolist(), bounds.tolist()
    ([1, 3, 4, 0, 2], [0, 3, 5])
    """
    order = np.argsort(labels, kind="stable")
    sorted_labels = labels[order]
    starts = np.flatnonzero(run_starts(sorted_labels)) if len(order) else order
    return order, np.r_[starts, len(order)]


def first_per_group(group: np.ndarray, values: np.ndarray, n: int) -> np.ndarray:
    """For each group ``0 <= g < n``, the first of its ``values`` (in order), else -1.

    Examples
    --------
    >>> first_per_group(np.array([2, 0, 2]), np.array([10, 11, 12]), 3).tolist()
    [11, -1, 10]
    """
    out = np.full(n, -1, dtype=I64)
    if len(group):
        order = np.argsort(group, kind="stable")
        g = group[order]
        first = run_starts(g)
        out[g[first]] = values[order][first]
    return out


def dense(ids: np.ndarray) -> tuple[np.ndarray, int]:
    """Dense numbers ``0..k-1`` for arbitrary ids, and ``k`` (the number of distinct ids).

    Examples
    --------
    >>> numbers, k = dense(np.array([40, 7, 40, 9]))
    >>> numbers.tolist(), k
    ([2, 0, 2, 1], 3)
    """
    if not len(ids):
        return ids, 0
    low, span = int(ids.min()), int(ids.max()) - int(ids.min()) + 1
    if span <= 8 * len(ids) + 1024:
        # Ids are allocated densely, so a table beats sorting.
        seen = np.zeros(span, dtype=bool)
        seen[ids - low] = True
        number = np.cumsum(seen, dtype=I64) - 1
        return number[ids - low], int(number[-1]) + 1
    distinct, inverse = np.unique(ids, return_inverse=True)
    return inverse.astype(I64, copy=False), len(distinct)


def polygon_halfedges(he_id: np.ndarray, he_next: np.ndarray, p_halfedge: np.ndarray) -> Ragged:
    """Each polygon's half-edges, as rows of ``he_id``, walked along ``next`` from its ``halfedge``.

    Parameters
    ----------
    he_id : ndarray
        Sorted half-edge ids.
    he_next : ndarray
        The half-edges' ``next`` ids.
    p_halfedge : ndarray
        Each polygon's ``halfedge`` id, in polygon order.

    Returns
    -------
    Ragged
        Polygon ``i``'s half-edge rows, starting at ``p_halfedge[i]``'s. All
        loops are walked together, one numpy step per corner of the largest
        polygon.

    Examples
    --------
    >>> loops = polygon_halfedges(np.array([0, 1, 2, 3]), np.array([2, 3, 0, 1]), np.array([2, 1]))
    >>> loops.offsets.tolist(), loops.indices.tolist()
    ([0, 2, 4], [2, 0, 1, 3])
    """
    # Rows instead of ids: ids are never reused, so after deletions they have gaps.
    halfedges = Index(he_id)
    next_row = halfedges.find(he_next)[0]
    start = halfedges.find(p_halfedge)[0]
    steps_h, steps_p = [], []
    cur = start.copy()
    active = np.arange(len(p_halfedge))
    for _ in range(len(he_id) + 1):
        if not len(active):
            break
        steps_h.append(cur)
        steps_p.append(active)
        cur = next_row[cur]
        going = cur != start[active]
        active, cur = active[going], cur[going]
    poly = np.concatenate(steps_p) if steps_p else np.zeros(0, dtype=I64)
    rows = np.concatenate(steps_h) if steps_h else np.zeros(0, dtype=I64)
    order = np.argsort(poly, kind="stable")  # steps were appended in loop order
    counts = np.bincount(poly, minlength=len(p_halfedge))
    offsets = np.zeros(len(p_halfedge) + 1, dtype=I64)
    np.cumsum(counts, out=offsets[1:])
    return Ragged(offsets, rows[order].astype(I64, copy=False))


def polygon_loops(
    v_id: np.ndarray, he_id: np.ndarray, he_origin: np.ndarray, he_next: np.ndarray, p_halfedge: np.ndarray
) -> Ragged:
    """Each polygon's corners, as vertex rows, walked along ``next`` from its ``halfedge``.

    Parameters
    ----------
    v_id, he_id : ndarray
        Sorted vertex and half-edge ids.
    he_origin, he_next : ndarray
        The half-edges' origin and ``next`` ids.
    p_halfedge : ndarray
        Each polygon's ``halfedge`` id, in polygon order.

    Returns
    -------
    Ragged
        Polygon ``i``'s corners as rows of ``v_id``, starting at the origin of
        ``p_halfedge[i]`` (see `polygon_halfedges`).
    """
    loops = polygon_halfedges(he_id, he_next, p_halfedge)
    origin_row = Index(v_id).find(he_origin)[0]
    return Ragged(loops.offsets, origin_row[loops.indices])


def positions(x: np.ndarray, y: np.ndarray, z: np.ndarray, missing: np.ndarray) -> np.ndarray:
    """Position columns as one ``(V, 3)`` float64 array, NaN rows where a vertex has none.

    Examples
    --------
    >>> positions(np.array([1.0, 0.0]), np.array([2.0, 0.0]), np.array([3.0, 0.0]), np.array([0, 1])).tolist()
    [[1.0, 2.0, 3.0], [nan, nan, nan]]
    """
    out = np.column_stack([x, y, z]).astype(np.float64, copy=False)
    out[np.asarray(missing).astype(bool)] = np.nan
    return out
