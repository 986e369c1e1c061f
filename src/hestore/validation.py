"""The invariants of the half-edge structure, and their set-based checking.

This module owns the list of invariants a stored mesh must keep (SPEC §2), each
under a stable code, and the code that checks them. `Mesh.check` and
`Mesh.validate` are thin wrappers around `check`; `check_arrays` does the work
on plain numpy arrays, so it can be used (and tested) without a database.

The check is set-based: the tables of one mesh are read with one ``SELECT``
each into int64 arrays (`load_arrays`), references are mapped to row indices
(by subtraction, a lookup table or `numpy.searchsorted`), and the cyclic
structures (polygon and boundary loops, the rotation around a vertex) are
labelled with vectorised pointer jumping. There is no Python loop over
elements: the cost is O(n log n) in the number of half-edges, and a Python
object is built only per reported *violation*.

Checking never repairs anything. Corrupted tables (dangling references, a
``next`` that is not a permutation, ...) are reported; they never crash the
check nor make it loop forever. A reference to a missing element is reported
once, as ``REF``, and the checks that would have to follow it skip it.

Invariant codes, in report order:

==============  ==============================================================
``H_TWIN``      ``twin(twin(h)) == h`` and ``twin(h) != h``
``H_NEXT_PREV`` ``prev(next(h)) == h`` and ``next(prev(h)) == h``
``H_ORIGIN``    ``origin(next(h)) == origin(twin(h))``
``H_EDGE``      ``edge(h) == edge(twin(h))``, ``edge(e.halfedge) == e``, and
                every edge has exactly two half-edges
``H_POLYGON``   ``polygon(next(h)) == polygon(h)`` (NULL included)
``P_LOOP``      the ``next`` loop from ``p.halfedge`` is exactly the
                half-edges whose polygon is ``p``
``V_HALFEDGE``  ``v.halfedge`` is NULL iff nothing starts at ``v``, else
                ``origin(v.halfedge) == v``
``V_ROTATION``  rotating (``h -> next(twin(h))``) from ``v.halfedge`` visits
                every outgoing half-edge of ``v`` exactly once
``V_BOUNDARY``  a vertex with a free outgoing half-edge has a free
                ``v.halfedge``
``REF``         every reference names an existing element of the mesh
``POLICY``      no self-loop / parallel edge where the mesh forbids them
``PROPERTY_REF`` every property value row belongs to a declared property
                and an existing element of its kind (stored meshes only)
==============  ==============================================================

Examples
--------
One edge between two vertices (a wire edge: each half-edge is the other's
``next`` and ``prev``), checked from arrays:

>>> import numpy as np
>>> from hestore.arrays import TopologyArrays
>>> from hestore.validation import check_arrays
>>> def a(*values):
...     return np.array(values, dtype=np.int64)
>>> wire = TopologyArrays(
...     he_id=a(0, 1), he_origin=a(0, 1), he_next=a(1, 0), he_prev=a(1, 0),
...     he_twin=a(1, 0), he_edge=a(0, 0), he_polygon=a(-1, -1),
...     v_id=a(0, 1), v_halfedge=a(0, 1), e_id=a(0), e_halfedge=a(0),
...     p_id=a(), p_halfedge=a())
>>> check_arrays(wire)
[]
>>> for violation in check_arrays(wire._replace(he_twin=a(1, 1))):
...     print(violation)
H_TWIN halfedge 0: twin(twin(0)) = 1 (twin(0) = 1), expected 0
H_TWIN halfedge 1: twin(1) = 1: a half-edge cannot be its own twin
H_ORIGIN halfedge 1: origin(next(1)) = origin(0) = vertex 0, but origin(twin(1)) = origin(1) = vertex 1
V_ROTATION vertex 1: rotating from halfedge 1 leaves the vertex: next(twin(1)) = 0 starts at vertex 0
>>> check_arrays(wire._replace(he_next=a(1, 7)))[0].message
'next = 7, but there is no halfedge 7 in this mesh'
"""

from __future__ import annotations

from typing import Callable, NamedTuple

import numpy as np

from hestore import schema
from hestore.arrays import Index, TopologyArrays, first_per_group, restricted_cycles
from hestore._columns import Connection, read_columns, request
from hestore.errors import InvalidInputError, Violation
from hestore.progress import check_progress
from hestore._queries import catalogue as catalogue_q
from hestore._queries import history as history_q
from hestore._queries import values as value_rows
from hestore._session import MeshRef

__all__ = [
    "CODES",
    "CODE_DESCRIPTIONS",
    "KINDS",
    "load_arrays",
    "check_arrays",
    "check",
]

#: The invariant codes, in the order `check_arrays` reports them.
CODES: tuple[str, ...] = (
    "H_TWIN",
    "H_NEXT_PREV",
    "H_ORIGIN",
    "H_EDGE",
    "H_POLYGON",
    "P_LOOP",
    "V_HALFEDGE",
    "V_ROTATION",
    "V_BOUNDARY",
    "REF",
    "POLICY",
    "PROPERTY_REF",
    "HISTORY",
)

#: One line per invariant code: what it requires.
CODE_DESCRIPTIONS: dict[str, str] = {
    "H_TWIN": "twin(twin(h)) == h and twin(h) != h",
    "H_NEXT_PREV": "prev(next(h)) == h and next(prev(h)) == h",
    "H_ORIGIN": "origin(next(h)) == origin(twin(h)): the destination of h is consistent",
    "H_EDGE": "edge(h) == edge(twin(h)); edge.halfedge is one of the edge's two half-edges; every edge has exactly two",
    "H_POLYGON": "polygon(next(h)) == polygon(h), NULL included",
    "P_LOOP": "walking next from p.halfedge returns to it and visits exactly the half-edges whose polygon is p",
    "V_HALFEDGE": "v.halfedge is NULL iff no half-edge starts at v; else origin(v.halfedge) == v",
    "V_ROTATION": "rotating around v from v.halfedge visits every outgoing half-edge of v exactly once",
    "V_BOUNDARY": "if v has a free outgoing half-edge, v.halfedge is free",
    "REF": "every reference points at an existing element of the same mesh",
    "POLICY": "no loop / parallel edge in a mesh whose policy forbids them",
    "PROPERTY_REF": "every property value row belongs to a declared property and an existing element of its kind",
    "HISTORY": "the kept history agrees with the current state: no row is newer than the mesh's revision, each "
    "superseded row version ended after it began, a current row is newer than the versions it superseded, and "
    "every kept revision has its record",
}

#: The codes `check_arrays` checks: all but those about stored property rows and history.
_ARRAY_CODES = CODES[:-2]

#: Element kinds a `Violation` can be about, in report order for equal ids.
KINDS: tuple[str, ...] = ("halfedge", "vertex", "edge", "polygon", "property", "revision")

_CODE_RANK = {code: i for i, code in enumerate(CODES)}
_KIND_RANK = {kind: i for i, kind in enumerate(KINDS)}


# --------------------------------------------------------------------------
# Loading


#: The `hestore._columns.read_columns` requests of `TopologyArrays`' columns, table by table (NULL -> -1).
_REQUESTS = [
    request(schema.KINDS[kind].table.name, *(name.split("_", 1)[1] for name in names[1:]))
    for kind, names in TopologyArrays.GROUPS
]


def load_arrays(connection: Connection, mesh_id: int, *, use_copy: bool | None = None) -> TopologyArrays:
    """Read the topology of one mesh into int64 arrays, as one consistent state.

    Every table is read with one ``SELECT`` filtered by ``mesh_id``, without
    SQLAlchemy ``Row`` objects:

    - on PostgreSQL with psycopg 3, the four selects are ``array_agg``
      aggregates joined into one statement, streamed by a binary ``COPY (...)
      TO STDOUT`` and decoded with `numpy.frombuffer`; one statement is one
      snapshot;
    - elsewhere each is ``ORDER BY id``, fetched from the DBAPI cursor in
      chunks and flattened with `numpy.fromiter`; on an idle connection (SQLite,
      or autocommit psycopg) they run in a read-only transaction that is
      rolled back after, so they too see one snapshot. A connection already in
      a transaction reads within it (and sees its own writes).

    Parameters
    ----------
    connection : sqlalchemy.Connection
        An open connection to a database holding `hestore.schema`'s tables.
    mesh_id : int
        The ``meshes.id`` of the mesh to read.
    use_copy : bool or None, optional
        Force (True) or forbid (False) the PostgreSQL ``COPY`` path; by
        default it is used on PostgreSQL with psycopg 3.

    Returns
    -------
    TopologyArrays
        Each table's arrays sorted by id; NULL references as -1. A mesh
        without rows (or that does not exist) reads as empty arrays.

    Examples
    --------
    >>> import sqlalchemy as sa
    >>> from hestore import schema
    >>> engine = sa.create_engine("sqlite://")
    >>> schema.metadata.create_all(engine)
    >>> with engine.begin() as conn:
    ...     _ = conn.execute(schema.vertices.insert(), [{"mesh_id": 1, "id": 7, "halfedge": None}])
    ...     arrays = load_arrays(conn, 1)
    >>> arrays.v_id, arrays.v_halfedge
    (array([7]), array([-1]))
    >>> check_arrays(arrays)
    []
    """
    tables = read_columns(connection, mesh_id, _REQUESTS, use_copy=use_copy)
    return _arrays(tables)


def _arrays(tables: list) -> TopologyArrays:
    """`TopologyArrays` from the columns `_REQUESTS` read, table by table."""
    return TopologyArrays(*(col for table in tables for col in table))


# --------------------------------------------------------------------------
# Checking: helpers


def _null(value: int) -> str:
    return "NULL" if value == -1 else str(value)


def _eg(value: int) -> str:
    return f" (e.g. {value})" if value != -1 else ""


def _eg_ids(*values: int) -> tuple[int, ...]:
    return tuple(v for v in values if v != -1)


class _Batch(NamedTuple):
    """Violations of one kind of failure, as columns; formatted lazily."""

    code: str
    kind: str
    sub: int  # tie-break between batches for the same element
    cols: tuple[np.ndarray, ...]  # cols[0] holds the offending elements' ids
    fmt: Callable[..., tuple[tuple[int, ...], str]]  # row values -> (ids, message)


def _normalized(arrays: TopologyArrays) -> TopologyArrays:
    """Int64 arrays, each table sorted by id; raises on malformed input."""
    out = {}
    for kind, names in TopologyArrays.GROUPS:
        cols = [np.asarray(getattr(arrays, name)) for name in names]
        for name, col in zip(names, cols):
            if col.ndim != 1:
                raise InvalidInputError(f"{name} must be one-dimensional, got shape {col.shape}")
            if len(col) and not np.issubdtype(col.dtype, np.integer):
                raise InvalidInputError(f"{name} must hold integers, got {col.dtype}")
        if len({len(c) for c in cols}) != 1:
            raise InvalidInputError(f"the {kind} arrays have different lengths: {[len(c) for c in cols]}")
        cols = [c.astype(np.int64, copy=False) for c in cols]
        ids = cols[0]
        if len(ids) > 1 and not (ids[1:] > ids[:-1]).all():
            order = np.argsort(ids, kind="stable")
            cols = [c[order] for c in cols]
            ids = cols[0]
            dup = np.flatnonzero(ids[1:] == ids[:-1])
            if len(dup):
                raise InvalidInputError(f"duplicate {kind} id {int(ids[dup[0]])}")
        out.update(zip(names, cols))
    return TopologyArrays(**out)


# --------------------------------------------------------------------------
# Checking: the invariants


class _Checker:
    """Shared lookups of one `check_arrays` call; one method per code.

    Each method returns its code's batches. A comparison that would
    have to follow a reference to a missing element is skipped: that
    reference is reported once, by `REF`.
    """

    def __init__(self, a: TopologyArrays, allow_loops: bool, allow_multi_edges: bool) -> None:
        self.a = a
        self.allow_loops = allow_loops
        self.allow_multi_edges = allow_multi_edges
        self.nH, self.nV, self.nE, self.nP = len(a.he_id), len(a.v_id), len(a.e_id), len(a.p_id)
        self.hrow = np.arange(self.nH, dtype=np.int64)
        he, vertex, edge, polygon = Index(a.he_id), Index(a.v_id), Index(a.e_id), Index(a.p_id)
        self.nxt, self.nxt_ok = he.find(a.he_next)
        self.prv, self.prv_ok = he.find(a.he_prev)
        self.tw, self.tw_ok = he.find(a.he_twin)
        self.org, self.org_ok = vertex.find(a.he_origin)
        self.edg, self.edg_ok = edge.find(a.he_edge)
        self.free = a.he_polygon == -1
        self.pol, self.pol_ok = polygon.find(a.he_polygon)
        self.pol_valid = self.pol_ok | self.free  # NULL or an existing polygon
        self.v_null = a.v_halfedge == -1
        self.vh, self.vh_ok = he.find(a.v_halfedge)
        self.vh_ok &= ~self.v_null
        self.eh, self.eh_ok = he.find(a.e_halfedge)
        self.ph, self.ph_ok = he.find(a.p_halfedge)
        del he, vertex, edge, polygon  # the lookup tables
        # Outgoing half-edges per vertex (those whose origin exists).
        self.out_count = np.bincount(self.org[self.org_ok], minlength=self.nV)

    def good_vertices(self) -> tuple[np.ndarray, np.ndarray]:
        """Rows of the vertices whose halfedge exists and starts at them, and its row."""
        i = np.flatnonzero(self.vh_ok)
        h = self.vh[i]
        keep = self.org_ok[h] & (self.org[h] == i)
        return i[keep], h[keep]

    def _walks(
        self, code: str, kind: str, sub: int, ids: np.ndarray, k: np.ndarray, h0: np.ndarray, *,
        step: np.ndarray, valid: np.ndarray, grouped: np.ndarray, group: np.ndarray, lands: np.ndarray,
        leaves: Callable, stuck: Callable, short: Callable,
    ) -> list[_Batch]:
        """The walks of ``step`` within groups: `P_LOOP`'s next-loops, `V_ROTATION`'s rotations.

        Half-edge ``h`` is in the group of row ``group[h]`` where
        ``grouped[h]``; ``step`` is followed where ``valid`` (elsewhere a
        reference is missing: `REF` reports it, and a group holding such a
        half-edge is skipped). The walk of group ``k[i]`` (id ``ids[k[i]]``)
        starts at half-edge row ``h0[i]``. Three batches, numbered from
        ``sub``: the walks that leave their group (``leaves(group, h0, x, y,
        lands[y])``: ``x`` steps to ``y``, outside), those that never return
        to their start (``stuck(group, h0)``), and those whose cycle misses
        half-edges of the group (``short(group, h0, cycle size, group size,
        the first half-edge it misses or -1)``); ids, not rows.
        """
        he, n_groups = self.a.he_id, len(ids)
        g = np.where(grouped, group, -1)
        # rows: the grouped half-edges; label, on_cycle and end speak of positions in them
        rows, _, label, on_cycle, end = restricted_cycles(np.where(valid, step, self.hrow), g)
        q = group[rows]
        exits = valid & grouped & (g[step] != g)
        touched = np.zeros(n_groups, dtype=bool)
        touched[group[grouped & ~valid]] = True
        at = np.cumsum(grouped)[h0] - 1  # h0's positions in rows (each h0 is in a group)
        keep = valid[rows[end[at]]] & ~touched[k]
        k, h0, at = k[keep], h0[keep], at[keep]
        x = rows[end[at]]
        out = exits[x]
        y = step[x[out]]
        leave_batch = _Batch(code, kind, sub, (ids[k[out]], he[h0[out]], he[x[out]], he[y], lands[y]), leaves)
        k, h0, at = k[~out], h0[~out], at[~out]
        never = ~on_cycle[at]
        stuck_batch = _Batch(code, kind, sub + 1, (ids[k[never]], he[h0[never]]), stuck)
        k, h0, at = k[~never], h0[~never], at[~never]
        # the cycle from h0 holds only half-edges of its group: all of them?
        size = np.bincount(label[on_cycle], minlength=len(rows))[label[at]]
        members = np.bincount(q, minlength=n_groups)
        bad = size != members[k]
        k, h0, at, size = k[bad], h0[bad], at[bad], size[bad]
        cycle_of = np.full(n_groups, -1, dtype=np.int64)
        cycle_of[k] = label[at]
        off = (cycle_of[q] >= 0) & ~(on_cycle & (label == cycle_of[q]))
        missed = first_per_group(q[off], he[rows[off]], n_groups)
        short_batch = _Batch(code, kind, sub + 2, (ids[k], he[h0], size, members[k], missed[k]), short)
        return [leave_batch, stuck_batch, short_batch]

    def H_TWIN(self) -> list[_Batch]:
        he = self.a.he_id
        i = np.flatnonzero(self.tw_ok)
        t = self.tw[i]
        own = i[t == i]
        j = i[(t != i) & self.tw_ok[t]]
        tj = self.tw[j]
        ttj = self.tw[tj]
        bad = ttj != j
        j, tj, ttj = j[bad], tj[bad], ttj[bad]
        return [
            _Batch(
                "H_TWIN",
                "halfedge",
                0,
                (he[own],),
                lambda h: ((h,), f"twin({h}) = {h}: a half-edge cannot be its own twin"),
            ),
            _Batch(
                "H_TWIN",
                "halfedge",
                1,
                (he[j], he[tj], he[ttj]),
                lambda h, t, tt: ((h, t, tt), f"twin(twin({h})) = {tt} (twin({h}) = {t}), expected {h}"),
            ),
        ]

    def H_NEXT_PREV(self) -> list[_Batch]:
        he = self.a.he_id
        batches = []
        directions = [
            (self.nxt, self.nxt_ok, self.prv, self.prv_ok, "next", "prev"),
            (self.prv, self.prv_ok, self.nxt, self.nxt_ok, "prev", "next"),
        ]
        for sub, (step, step_ok, back, back_ok, s, b) in enumerate(directions):
            i = np.flatnonzero(step_ok)
            n = step[i]
            keep = back_ok[n]
            i, n = i[keep], n[keep]
            m = back[n]
            bad = m != i
            i, n, m = i[bad], n[bad], m[bad]
            batches.append(
                _Batch(
                    "H_NEXT_PREV",
                    "halfedge",
                    sub,
                    (he[i], he[n], he[m]),
                    lambda h, x, y, s=s, b=b: ((h, x, y), f"{b}({s}({h})) = {y} ({s}({h}) = {x}), expected {h}"),
                )
            )
        return batches

    def H_ORIGIN(self) -> list[_Batch]:
        a, he = self.a, self.a.he_id
        i = np.flatnonzero(self.nxt_ok & self.tw_ok)
        n, t = self.nxt[i], self.tw[i]
        keep = self.org_ok[n] & self.org_ok[t]
        i, n, t = i[keep], n[keep], t[keep]
        on, ot = a.he_origin[n], a.he_origin[t]
        bad = on != ot
        return [
            _Batch(
                "H_ORIGIN",
                "halfedge",
                0,
                (he[i[bad]], he[n[bad]], he[t[bad]], on[bad], ot[bad]),
                lambda h, n, t, on, ot: (
                    (h, n, t),
                    f"origin(next({h})) = origin({n}) = vertex {on}, "
                    f"but origin(twin({h})) = origin({t}) = vertex {ot}",
                ),
            )
        ]

    def H_EDGE(self) -> list[_Batch]:
        a, he = self.a, self.a.he_id
        # edge(h) == edge(twin(h))
        i = np.flatnonzero(self.tw_ok & self.edg_ok)
        t = self.tw[i]
        keep = self.edg_ok[t]
        i, t = i[keep], t[keep]
        bad = self.edg[i] != self.edg[t]
        i, t = i[bad], t[bad]
        twin_batch = _Batch(
            "H_EDGE",
            "halfedge",
            0,
            (he[i], he[t], a.he_edge[i], a.he_edge[t]),
            lambda h, t, e, et: ((h, t), f"edge({h}) = {e}, but edge(twin({h})) = edge({t}) = {et}"),
        )
        # edge(e.halfedge) == e
        k = np.flatnonzero(self.eh_ok)
        h = self.eh[k]
        keep = self.edg_ok[h]
        k, h = k[keep], h[keep]
        bad = self.edg[h] != k
        k, h = k[bad], h[bad]
        back_batch = _Batch(
            "H_EDGE",
            "edge",
            1,
            (a.e_id[k], he[h], a.he_edge[h]),
            lambda e, h, eh: ((e, h), f"halfedge = {h}, but edge({h}) = {eh}, not {e}"),
        )
        # exactly two half-edges per edge; an edge whose half-edge's twin has a
        # missing edge is left out (that twin may have been meant for it)
        count = np.bincount(self.edg[self.edg_ok], minlength=self.nE)
        i = np.flatnonzero(self.edg_ok & self.tw_ok)
        suspect = np.zeros(self.nE, dtype=bool)
        suspect[self.edg[i[~self.edg_ok[self.tw[i]]]]] = True
        k = np.flatnonzero((count != 2) & ~suspect)
        wanted = np.zeros(self.nE, dtype=bool)
        wanted[k] = True
        members = np.flatnonzero(self.edg_ok)
        members = members[wanted[self.edg[members]]]
        members = members[np.argsort(self.edg[members], kind="stable")]
        starts = np.searchsorted(self.edg[members], k)
        member_ids = he[members]

        def count_fmt(e: int, c: int, s: int) -> tuple[tuple[int, ...], str]:
            listed = [int(x) for x in member_ids[s : s + min(c, 6)]]
            shown = ", ".join(map(str, listed)) + (", ..." if c > 6 else "")
            return (e, *listed), f"has {c} half-edge(s){f' ({shown})' if c else ''}, expected 2"

        count_batch = _Batch("H_EDGE", "edge", 2, (a.e_id[k], count[k], starts), count_fmt)
        return [twin_batch, back_batch, count_batch]

    def H_POLYGON(self) -> list[_Batch]:
        a, he = self.a, self.a.he_id
        i = np.flatnonzero(self.nxt_ok & self.pol_valid)
        n = self.nxt[i]
        keep = self.pol_valid[n]
        i, n = i[keep], n[keep]
        bad = a.he_polygon[i] != a.he_polygon[n]
        i, n = i[bad], n[bad]
        return [
            _Batch(
                "H_POLYGON",
                "halfedge",
                0,
                (he[i], he[n], a.he_polygon[i], a.he_polygon[n]),
                lambda h, n, p, q: (
                    (h, n),
                    f"polygon({h}) = {_null(p)}, but polygon(next({h})) = polygon({n}) = {_null(q)}",
                ),
            )
        ]

    def P_LOOP(self) -> list[_Batch]:
        a, he = self.a, self.a.he_id
        # polygon(p.halfedge) == p
        k = np.flatnonzero(self.ph_ok)
        h0 = self.ph[k]
        keep = self.pol_valid[h0]
        k, h0 = k[keep], h0[keep]
        bad = a.he_polygon[h0] != a.p_id[k]
        owner_batch = _Batch(
            "P_LOOP",
            "polygon",
            0,
            (a.p_id[k[bad]], he[h0[bad]], a.he_polygon[h0[bad]]),
            lambda p, h, q: ((p, h), f"halfedge = {h}, but polygon({h}) = {_null(q)}"),
        )
        k, h0 = k[~bad], h0[~bad]
        # Walk next only between half-edges of one polygon; a next that is missing, or whose polygon is,
        # is left to REF. On a valid mesh this needs log2(largest polygon) rounds, not log2(n).
        return [owner_batch, *self._walks(
            "P_LOOP", "polygon", 1, a.p_id, k, h0,
            step=self.nxt, valid=self.nxt_ok & self.pol_valid[self.nxt], grouped=self.pol_ok, group=self.pol,
            lands=a.he_polygon,
            leaves=lambda p, h, x, y, q: (
                (p, h, x, y),
                f"the next-loop from halfedge {h} leaves the polygon: next({x}) = {y} lies in polygon {_null(q)}",
            ),
            stuck=lambda p, h: ((p, h), f"walking next from halfedge {h} never returns to it"),
            short=lambda p, h, size, mine, x: (
                (p, h, *_eg_ids(x)),
                f"the next-loop from halfedge {h} has {size} half-edge(s), but polygon {p} has {mine}; "
                f"{mine - size} not on the loop{_eg(x)}",
            ),
        )]

    def V_HALFEDGE(self) -> list[_Batch]:
        a, he = self.a, self.a.he_id
        k = np.flatnonzero(self.v_null & (self.out_count > 0))
        wanted = np.zeros(self.nV, dtype=bool)
        wanted[k] = True
        j = np.flatnonzero(self.org_ok)
        j = j[wanted[self.org[j]]]
        example = first_per_group(self.org[j], he[j], self.nV)
        null_batch = _Batch(
            "V_HALFEDGE",
            "vertex",
            0,
            (a.v_id[k], self.out_count[k], example[k]),
            lambda v, c, x: ((v, x), f"halfedge is NULL, but {c} half-edge(s) start at vertex {v} (e.g. {x})"),
        )
        k = np.flatnonzero(self.vh_ok)
        h = self.vh[k]
        keep = self.org_ok[h]
        k, h = k[keep], h[keep]
        bad = self.org[h] != k
        k, h = k[bad], h[bad]
        origin_batch = _Batch(
            "V_HALFEDGE",
            "vertex",
            1,
            (a.v_id[k], he[h], a.he_origin[h], self.out_count[k]),
            lambda v, h, o, c: (
                (v, h),
                f"halfedge = {h}, but origin({h}) = vertex {o}" + ("" if c else f"; no half-edge starts at vertex {v}"),
            ),
        )
        return [null_batch, origin_batch]

    def V_ROTATION(self) -> list[_Batch]:
        a = self.a
        # r(h) = next(twin(h)), walked only between half-edges of one origin; one with a missing twin,
        # next(twin) or origin is left to REF. On a valid mesh this needs log2(highest degree) rounds.
        rot = self.nxt[self.tw]
        k, h0 = self.good_vertices()
        return self._walks(
            "V_ROTATION", "vertex", 0, a.v_id, k, h0,
            step=rot, valid=self.tw_ok & self.org_ok & self.nxt_ok[self.tw] & self.org_ok[rot], grouped=self.org_ok,
            group=self.org, lands=a.he_origin,
            leaves=lambda v, h, x, y, w: (
                (v, h, x, y),
                f"rotating from halfedge {h} leaves the vertex: next(twin({x})) = {y} starts at vertex {w}",
            ),
            stuck=lambda v, h: ((v, h), f"rotating (h -> next(twin(h))) from halfedge {h} never returns to it"),
            short=lambda v, h, size, out, x: (
                (v, h, *_eg_ids(x)),
                f"rotating from halfedge {h} visits {size} half-edge(s), but {out} start at vertex {v}; "
                f"{out - size} not visited{_eg(x)}",
            ),
        )

    def V_BOUNDARY(self) -> list[_Batch]:
        a, he = self.a, self.a.he_id
        k, h0 = self.good_vertices()
        free_out = self.org_ok & self.free
        free_count = np.bincount(self.org[free_out], minlength=self.nV)
        bad = (free_count[k] > 0) & ~self.free[h0]
        k, h0 = k[bad], h0[bad]
        wanted = np.zeros(self.nV, dtype=bool)
        wanted[k] = True
        j = np.flatnonzero(free_out)
        j = j[wanted[self.org[j]]]
        example = first_per_group(self.org[j], he[j], self.nV)
        return [
            _Batch(
                "V_BOUNDARY",
                "vertex",
                0,
                (a.v_id[k], he[h0], a.he_polygon[h0], free_count[k], example[k]),
                lambda v, h, p, c, x: (
                    (v, h, x),
                    f"halfedge = {h} lies in polygon {p}, but {c} free half-edge(s) start at vertex {v} (e.g. {x})",
                ),
            )
        ]

    def REF(self) -> list[_Batch]:
        a = self.a
        fields = [
            ("halfedge", a.he_id, "origin", a.he_origin, self.org_ok, "vertex"),
            ("halfedge", a.he_id, "next", a.he_next, self.nxt_ok, "halfedge"),
            ("halfedge", a.he_id, "prev", a.he_prev, self.prv_ok, "halfedge"),
            ("halfedge", a.he_id, "twin", a.he_twin, self.tw_ok, "halfedge"),
            ("halfedge", a.he_id, "edge", a.he_edge, self.edg_ok, "edge"),
            ("halfedge", a.he_id, "polygon", a.he_polygon, self.pol_valid, "polygon"),
            ("vertex", a.v_id, "halfedge", a.v_halfedge, self.vh_ok | self.v_null, "halfedge"),
            ("edge", a.e_id, "halfedge", a.e_halfedge, self.eh_ok, "halfedge"),
            ("polygon", a.p_id, "halfedge", a.p_halfedge, self.ph_ok, "halfedge"),
        ]
        batches = []
        for sub, (kind, ids, field, refs, ok, target) in enumerate(fields):
            bad = np.flatnonzero(~ok)
            batches.append(
                _Batch(
                    "REF",
                    kind,
                    sub,
                    (ids[bad], refs[bad]),
                    lambda x, ref, field=field, target=target: (
                        (x, ref),
                        f"{field} = {ref}, but there is no {target} {ref} in this mesh",
                    ),
                )
            )
        return batches

    def POLICY(self) -> list[_Batch]:
        a = self.a
        if self.allow_loops and self.allow_multi_edges:
            return []
        # the end vertices of each edge: origins of e.halfedge and of its twin
        k = np.flatnonzero(self.eh_ok)
        h = self.eh[k]
        keep = self.tw_ok[h] & self.org_ok[h]
        k, h = k[keep], h[keep]
        t = self.tw[h]
        keep = self.org_ok[t]
        k, h, t = k[keep], h[keep], t[keep]
        u, w = a.he_origin[h], a.he_origin[t]
        batches = []
        if not self.allow_loops:
            loop = u == w
            batches.append(
                _Batch(
                    "POLICY",
                    "edge",
                    0,
                    (a.e_id[k[loop]], u[loop]),
                    lambda e, v: ((e, v), f"is a self-loop at vertex {v}, but the mesh does not allow loops"),
                )
            )
        if not self.allow_multi_edges:
            lo, hi, eid = np.minimum(u, w), np.maximum(u, w), a.e_id[k]
            order = np.lexsort((eid, hi, lo))
            lo, hi, eid = lo[order], hi[order], eid[order]
            starts = np.ones(len(eid), dtype=bool)
            starts[1:] = (lo[1:] != lo[:-1]) | (hi[1:] != hi[:-1])
            first = eid[np.maximum.accumulate(np.where(starts, np.arange(len(eid)), 0))] if len(eid) else eid
            extra = ~starts
            batches.append(
                _Batch(
                    "POLICY",
                    "edge",
                    1,
                    (eid[extra], first[extra], lo[extra], hi[extra]),
                    lambda e, f, x, y: (
                        (e, f),
                        f"joins vertices {x} and {y} like edge {f}, but the mesh does not allow parallel edges",
                    ),
                )
            )
        return batches


def _emit(batches: list[_Batch], room: int | None) -> list[Violation]:
    """The violations of one code, ordered by id, at most ``room`` of them."""
    batches = [b for b in batches if len(b.cols[0])]
    if not batches:
        return []
    ids = np.concatenate([b.cols[0] for b in batches])
    kind = np.concatenate([np.full(len(b.cols[0]), _KIND_RANK[b.kind]) for b in batches])
    sub = np.concatenate([np.full(len(b.cols[0]), b.sub) for b in batches])
    src = np.concatenate([np.full(len(b.cols[0]), i) for i, b in enumerate(batches)])
    row = np.concatenate([np.arange(len(b.cols[0])) for b in batches])
    order = np.lexsort((row, sub, kind, ids))
    if room is not None:
        order = order[:room]
    out = []
    for s, r in zip(src[order].tolist(), row[order].tolist()):
        b = batches[s]
        element_ids, message = b.fmt(*(int(c[r]) for c in b.cols))
        out.append(Violation(b.code, b.kind, tuple(int(x) for x in element_ids), message))
    return out


def check_arrays(
    arrays: TopologyArrays,
    *,
    allow_loops: bool = True,
    allow_multi_edges: bool = True,
    limit: int | None = None,
) -> list[Violation]:
    """Check every invariant on a mesh's topology arrays, set-based.

    Parameters
    ----------
    arrays : TopologyArrays
        The mesh's tables (see `load_arrays`). Tables not sorted by id are
        sorted first.
    allow_loops, allow_multi_edges : bool, optional
        The mesh's policy; ``POLICY`` reports self-loops / parallel edges
        (every edge beyond the lowest-id one between the same two vertices)
        where they are not allowed.
    limit : int or None, optional
        Return at most this many violations (the first ones in report order);
        None returns them all. Checks after the limit is reached are skipped.

    Returns
    -------
    list of Violation
        Empty when the topology is valid. Ordered by the code's position in
        `CODES`, then by the offending element's id (then kind, then reason).

    Raises
    ------
    hestore.InvalidInputError
        If arrays of one table differ in length, are not 1-d integer arrays,
        or a table holds an id twice.

    Examples
    --------
    A triangle (polygon 0) with its boundary loop of free half-edges; half-edges
    ``2e`` and ``2e + 1`` make edge ``e``:

    >>> import numpy as np
    >>> a = lambda *v: np.array(v, dtype=np.int64)
    >>> tri = TopologyArrays(
    ...     he_id=a(0, 1, 2, 3, 4, 5), he_origin=a(0, 1, 1, 2, 2, 0),
    ...     he_next=a(2, 5, 4, 1, 0, 3), he_prev=a(4, 3, 0, 5, 2, 1),
    ...     he_twin=a(1, 0, 3, 2, 5, 4), he_edge=a(0, 0, 1, 1, 2, 2),
    ...     he_polygon=a(0, -1, 0, -1, 0, -1),
    ...     v_id=a(0, 1, 2), v_halfedge=a(5, 1, 3),
    ...     e_id=a(0, 1, 2), e_halfedge=a(0, 2, 4), p_id=a(0), p_halfedge=a(0))
    >>> check_arrays(tri)
    []
    >>> for v in check_arrays(tri._replace(v_halfedge=a(0, 1, 3))):
    ...     print(v)
    V_BOUNDARY vertex 0: halfedge = 0 lies in polygon 0, but 1 free half-edge(s) start at vertex 0 (e.g. 5)
    >>> swapped = tri._replace(he_next=a(2, 3, 4, 1, 0, 5))  # next(1) <-> next(5)
    >>> for v in check_arrays(swapped, limit=2):
    ...     print(v)
    H_NEXT_PREV halfedge 1: prev(next(1)) = 5 (next(1) = 3), expected 1
    H_NEXT_PREV halfedge 3: next(prev(3)) = 5 (prev(3) = 5), expected 3
    >>> sorted({v.code for v in check_arrays(swapped)})
    ['H_NEXT_PREV', 'H_ORIGIN', 'V_ROTATION']
    """
    if limit is not None:
        limit = int(limit)
        if limit < 0:
            raise InvalidInputError(f"limit must be None or >= 0, got {limit}")
    checker = _Checker(_normalized(arrays), bool(allow_loops), bool(allow_multi_edges))
    result: list[Violation] = []
    for code in _ARRAY_CODES:
        room = None if limit is None else limit - len(result)
        if room == 0:
            break
        result.extend(_emit(getattr(checker, code)(), room))
    return result


def check(ref: MeshRef, progress: Callable[[str, int, int], object] | None = None) -> list[Violation]:
    """Check a stored mesh: what `Mesh.check` returns.

    Reads the mesh's tables in one snapshot through its store's session
    (after pending writes are flushed, so a block sees its own edits) and
    checks them with `check_arrays` under the mesh's policy.

    Parameters
    ----------
    ref : hestore._session.MeshRef
        The mesh (its identity: the facade passes its own, `hestore._session.identity`).
    progress : callable, optional
        ``progress(stage, done, total)``: ``"read"`` (0 then 1 of 1), then
        ``"check"`` (topology, properties, history: 0 to 3 of 3).

    Returns
    -------
    list of Violation
        Empty when every invariant holds.

    Raises
    ------
    hestore.MeshNotFoundError
        The mesh has been deleted.

    Examples
    --------
    >>> from hestore._session import identity
    >>> import hestore
    >>> store = hestore.open("sqlite://")
    >>> mesh = store.create_mesh("m")
    >>> check(identity(mesh))
    []
    >>> store.close()
    """
    report = check_progress(progress)
    with ref.session.snapshot(ref) as snap:
        report("read", 0, 1)
        arrays = _arrays(snap.columns(_REQUESTS))
        report("read", 1, 1)
        report("check", 0, 3)
        found = check_arrays(arrays, allow_loops=ref.allow_loops, allow_multi_edges=ref.allow_multi_edges)
        report("check", 1, 3)
        found += _property_violations(snap, arrays)
        report("check", 2, 3)
        if ref.revision is None:  # a view is read from the history this checks
            found += _history_violations(snap)
        report("check", 3, 3)
        return found


def _property_violations(snap, a: TopologyArrays) -> list[Violation]:
    """``PROPERTY_REF``: value rows of undeclared properties or of elements that do not exist."""
    catalogue = {pid: (kind, name) for pid, kind, name, *_ in snap.rows(catalogue_q.properties_of)}
    columns = snap.columns(value_rows.owners())
    out = []
    for ids, props in columns:
        for pid in np.unique(props).tolist():
            rows = ids[props == pid]
            if pid not in catalogue:
                out.extend(
                    Violation("PROPERTY_REF", "property", (pid, i), f"a value row of element {i} belongs to "
                              f"property {pid}, which is not declared")
                    for i in rows[:100].tolist()
                )
                continue
            kind, name = catalogue[pid]
            dangling = rows[~np.isin(rows, getattr(a, schema.KINDS[kind].id_column))]
            out.extend(
                Violation("PROPERTY_REF", kind, (i, pid), f"property {name!r} has a value for {kind} {i}, "
                          "which does not exist")
                for i in dangling[:100].tolist()
            )
    return sorted(out, key=lambda v: (v.kind, v.ids))


def _history_violations(snap) -> list[Violation]:
    """``HISTORY``: the row versions and revision records against the mesh's revision. Set-based, 100 per kind."""
    [(current, kept_from, keep)] = snap.rows(history_q.mesh_history)
    out = []
    for table in schema.VERSIONED:
        kind = schema.KIND_OF_TABLE.get(table.name, "property")
        for row in snap.rows(history_q.newer(table), {"current": current}):
            out.append(Violation("HISTORY", kind, _ids(row), f"{kind} {_ids(row)[0]} was written by revision "
                                 f"{row[-1]}, after the mesh's revision {current}"))
        for row in snap.rows(history_q.bad_versions(table), {"current": current}):
            out.append(Violation("HISTORY", kind, _ids(row), f"a kept version of {kind} {_ids(row)[0]} runs from "
                                 f"revision {row[-2]} to {row[-1]}, which the mesh at revision {current} cannot have"))
        for row in snap.rows(history_q.stale(table)):
            out.append(Violation("HISTORY", kind, _ids(row), f"{kind} {_ids(row)[0]} is a version of revision "
                                 f"{row[-2]}, older than revision {row[-1]}, which superseded an earlier one"))
    if keep and current >= 1:
        first = max(kept_from, 1)
        recorded = {n for (n,) in snap.rows(history_q.recorded, {"first": first, "current": current})}
        missing = [n for n in range(first, current + 1) if n not in recorded]
        out.extend(Violation("HISTORY", "revision", (n,), f"revision {n} is kept but has no record")
                   for n in missing[:100])
    return out


def _ids(row) -> tuple[int, ...]:
    """A history violation's ids: the element (for a value row, the element and the property), then revisions."""
    return tuple(int(x) for x in row if x is not None)
