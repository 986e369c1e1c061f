"""Benchmark: single topological edits, and commits, against mesh size (SPEC §9).

    python bench/edits.py [--sizes 1000,10000,100000] [--backends sqlite,postgresql] [--repeat N]

For each backend and mesh size it builds the triangulated grid through the
public API (one transaction; the build rate is printed too), then measures on
a working copy of it:

add_polygon        one ``add_polygon([a, b, c])`` inside an open transaction:
                   a triangle on a random boundary half-edge a→b and a new
                   vertex c (its ``add_vertex`` is timed separately). Ops of
                   one block touch disjoint vertices, so every op reads its
                   rows from the database, not from the block's cache.
remove_edge        one ``remove_edge(e)`` inside an open transaction, e a random
                   interior edge away from the boundary (removes 2 triangles).
1-polygon txn      ``with store.transaction(): add_vertex; add_polygon`` end to
                   end (BEGIN, mesh lock, reads, writes, COMMIT), and the part
                   after the last edit (flush + COMMIT) on its own.
floor              12 single-row UPDATEs of a scratch table through SQLAlchemy
                   Core in ``engine.begin()``, same database, same settings.
1000-edit txn      one transaction of 1,000 mixed edits (add a triangle on the
                   boundary / remove an interior edge, alternating, random over
                   the whole mesh), total time including COMMIT / 1000.

Edits are chosen before each timed region from a plain-Python model of the
mesh; after every committed run the model is compared with the database and
at the end ``mesh.check()`` must come back empty.

In-transaction edit timings do not include writing: hestore keeps a
transaction's changes in a unit of work and writes them at commit (or before a
read). The 1,000-edit figure includes those writes.

Run alone or by ``bench/all.py`` (``tests/test_bench.py`` runs it with
``--quick``). This file keeps the workloads, the floor and the targets; the
harness (``bench/harness/``) parses the options, opens each backend and
prints the report.
"""

from __future__ import annotations

import math
import os
import random
import shutil
import time
from collections import Counter, defaultdict
from collections.abc import Iterable
from dataclasses import dataclass, field

import sqlalchemy as sa

import hestore

from harness.bench import Bench
from harness.cli import Parser
from harness.databases import TABLES, Place, pg_connect, url_of
from harness.profiling import Statements, traced
from harness.runner import log
from harness.stats import median
from harness.tables import Figure, fmt_time, verdict
from harness.timing import gc_paused, maxrss, pc, time_each
from workloads import Rollback

MESH = "grid"
US, MS = 1_000, 1_000_000
TARGET_EDIT = 1 * MS  # one add_polygon / remove_edge inside a transaction, median
TARGET_AMORTISED = 100 * US  # per edit of a 1,000-edit transaction, commit included
TARGET_COMMIT = 2 * MS  # commit of a 1-polygon transaction, median (SPEC: SQLite WAL)
QUICK = {"sizes": "1000", "repeat": 20, "warmup": 5, "txn_runs": 1, "edits": 100}
ABOUT = """\
In-transaction timings exclude writing: hestore writes a transaction's changes at commit (or before a
read); the many-edit figure includes them. The commit target (≤ 2 ms) is SPEC's for SQLite WAL; it is
applied to PostgreSQL as well. The floor is 12 single-row UPDATEs in engine.begin() on the same database."""


@dataclass
class Samples:
    """One figure of one size: its timed calls (ns), target and floor (ns)."""

    name: str
    samples: list[float]
    target: float | None = None
    floor: float | None = None
    p90: bool = True  # whether p90 means anything (false for a handful of runs)

    @property
    def median(self) -> float:
        return median(self.samples)


@dataclass
class SizeResult:
    """What one size on one backend gave: its figures, statement counts, notes and failed gates."""

    backend: str
    size: int
    figures: list[Samples] = field(default_factory=list)
    sql: list[tuple[str, str]] = field(default_factory=list)  # (what, counts)
    notes: list[str] = field(default_factory=list)
    problems: list[str] = field(default_factory=list)


# -- the grid -----------------------------------------------------------------------


def grid_shape(n_polygons: int) -> tuple[int, int]:
    """Cells ``(nx, ny)`` of a grid with about ``n_polygons`` triangles (2 per cell).

    Exact when n/2 has a factor pair with aspect ratio ≤ 2.5 (1 k = 20×25,
    10 k = 50×100, 100 k = 200×250, 1 M = 625×800), else nearly square.
    """
    cells = max(1, n_polygons // 2)
    best = None
    for nx in range(int(math.isqrt(cells)), 0, -1):
        if cells % nx == 0:
            ny = cells // nx
            if ny / nx <= 2.5:
                best = (nx, ny)
            break
    if best is None:
        nx = max(1, round(math.sqrt(cells)))
        best = (nx, math.ceil(cells / nx))
    return best


@dataclass
class BuildResult:
    polygons: int
    vertices: int
    seconds: float
    seconds_vertices: float
    seconds_polygons: float
    seconds_commit: float

    @property
    def rate(self) -> float:
        return self.polygons / self.seconds


def build_grid(store: hestore.Store, n_polygons: int) -> BuildResult:
    """Build the triangulated grid through the public API, in one transaction.

    Every grid vertex is added with its position, then the triangles cell by
    cell, row by row, so each one attaches to triangles already there.
    """
    nx, ny = grid_shape(n_polygons)
    mesh = store.create_mesh(MESH, allow_loops=False, allow_multi_edges=False)
    t0 = time.perf_counter()
    with store.transaction():
        rows = [[mesh.add_vertex((float(i), float(j), 0.0)) for i in range(nx + 1)] for j in range(ny + 1)]
        t1 = time.perf_counter()
        add = mesh.add_polygon
        for j in range(ny):
            lo, hi = rows[j], rows[j + 1]
            for i in range(nx):
                a, b, c, d = lo[i], lo[i + 1], hi[i + 1], hi[i]
                add([a, b, c])
                add([a, c, d])
        t2 = time.perf_counter()
    t3 = time.perf_counter()
    return BuildResult(2 * nx * ny, (nx + 1) * (ny + 1), t3 - t0, t1 - t0, t2 - t1, t3 - t2)



# -- a plain-Python picture of the mesh -----------------------------------------------


class IndexedSet:
    """A set with O(1) add, discard and uniform random choice."""

    __slots__ = ("_items", "_index")

    def __init__(self, items: Iterable = ()) -> None:
        self._items: list = []
        self._index: dict = {}
        for x in items:
            self.add(x)

    def add(self, x) -> None:
        if x not in self._index:
            self._index[x] = len(self._items)
            self._items.append(x)

    def discard(self, x) -> None:
        i = self._index.pop(x, None)
        if i is None:
            return
        last = self._items.pop()
        if i < len(self._items):
            self._items[i] = last
            self._index[last] = i

    def choice(self, rng: random.Random):
        return self._items[rng.randrange(len(self._items))]

    def __contains__(self, x) -> bool:
        return x in self._index

    def __len__(self) -> int:
        return len(self._items)

    def __iter__(self):
        return iter(self._items)

    def copy(self) -> "IndexedSet":
        new = IndexedSet()
        new._items = list(self._items)
        new._index = dict(self._index)
        return new


def _ekey(a: int, b: int) -> tuple[int, int]:
    return (a, b) if a < b else (b, a)


@dataclass
class Model:
    """Triangles, half-edges and boundary of a mesh without parallel edges or loops.

    Half-edges are keyed ``(origin, target)``; ``he[(a, b)]`` is the polygon
    on its left or None (free). Vertices not yet in the database (planned
    additions) have negative ids. ``boundary`` holds the free half-edges whose
    twin has a polygon (where a triangle can be attached); ``interior`` the
    edges with polygons on both sides and a known id (which can be removed by
    handle).
    """

    he: dict = field(default_factory=dict)
    out: dict = field(default_factory=lambda: defaultdict(set))
    eid: dict = field(default_factory=dict)
    loops: dict = field(default_factory=dict)
    pos: dict = field(default_factory=dict)
    boundary: IndexedSet = field(default_factory=IndexedSet)
    interior: IndexedSet = field(default_factory=IndexedSet)
    n_vertices: int = 0
    _new: int = 0

    @classmethod
    def load(cls, engine: sa.Engine, mesh_id: int) -> "Model":
        m = cls()
        with engine.connect() as conn:
            rows = conn.execute(
                sa.text(
                    "SELECT h.id, h.origin, t.origin, h.next, h.edge, h.polygon FROM halfedges h "
                    "JOIN halfedges t ON t.mesh_id = h.mesh_id AND t.id = h.twin WHERE h.mesh_id = :m"
                ),
                {"m": mesh_id},
            ).all()
            for vid, x, y, z in conn.execute(
                sa.text("SELECT id, x, y, z FROM vertices WHERE mesh_id = :m"), {"m": mesh_id}
            ):
                m.pos[vid] = (x, y, z)
        m.n_vertices = len(m.pos)
        by_id = {}
        for hid, a, b, nxt, e, p in rows:
            if (a, b) in m.he:
                raise ValueError(f"parallel half-edges {a}→{b}: the benchmark's model does not handle them")
            m.he[(a, b)] = p
            m.out[a].add(b)
            m.eid[_ekey(a, b)] = e
            by_id[hid] = (a, nxt, p)
        seen = set()
        for hid, (a, nxt, p) in by_id.items():
            if p is None or p in seen:
                continue
            seen.add(p)
            loop = [a]
            h = nxt
            while h != hid:
                loop.append(by_id[h][0])
                h = by_id[h][1]
            m.loops[p] = tuple(loop)
        for a, b in m.he:
            if a < b:
                m._refresh(a, b)
        return m

    def copy(self) -> "Model":
        out = defaultdict(set)
        for k, v in self.out.items():
            out[k] = set(v)
        return Model(
            dict(self.he), out, dict(self.eid), dict(self.loops), dict(self.pos),
            self.boundary.copy(), self.interior.copy(), self.n_vertices, self._new,
        )

    def _refresh(self, a: int, b: int) -> None:
        he = self.he
        pab, pba = he.get((a, b), 0), he.get((b, a), 0)  # 0: no such half-edge
        for key, mine, other in (((a, b), pab, pba), ((b, a), pba, pab)):
            if mine is None and other not in (None, 0):
                self.boundary.add(key)
            else:
                self.boundary.discard(key)
        k = _ekey(a, b)
        if pab not in (None, 0) and pba not in (None, 0) and self.eid.get(k) is not None:
            self.interior.add(k)
        else:
            self.interior.discard(k)

    # -- queries

    def is_boundary_vertex(self, v: int) -> bool:
        return any(self.he[(v, t)] is None for t in self.out[v])

    def side_polygons(self, u: int, v: int) -> list:
        return [p for p in (self.he.get((u, v)), self.he.get((v, u))) if p is not None]

    def remove_footprint(self, u: int, v: int) -> set[int]:
        """Vertices a removal of edge u–v reads (its two polygons' corners)."""
        vs = {u, v}
        for p in self.side_polygons(u, v):
            vs.update(self.loops[p])
        return vs

    def new_position(self, a: int, b: int) -> tuple[float, float, float]:
        (xa, ya, _), (xb, yb, _) = self.pos[a], self.pos[b]
        return ((xa + xb) / 2, (ya + yb) / 2, 0.5)

    @property
    def n_polygons(self) -> int:
        return len(self.loops)

    @property
    def n_edges(self) -> int:
        return len(self.eid)

    # -- edits (what hestore is expected to do)

    def new_vertex_id(self) -> int:
        self._new -= 1
        return self._new

    def add_triangle(self, a: int, b: int, c: int, position, poly_key) -> None:
        """Triangle [a, b, c] on the free half-edge a→b; c is a new vertex."""
        assert self.he[(a, b)] is None and c not in self.out
        he = self.he
        he[(a, b)] = poly_key
        he[(b, c)] = poly_key
        he[(c, a)] = poly_key
        he[(c, b)] = None
        he[(a, c)] = None
        self.out[a].add(c)
        self.out[b].add(c)
        self.out[c] = {a, b}
        self.eid[_ekey(b, c)] = None
        self.eid[_ekey(c, a)] = None
        self.loops[poly_key] = (a, b, c)
        self.pos[c] = position
        self.n_vertices += 1
        self._refresh(a, b)
        self._refresh(b, c)
        self._refresh(c, a)

    def remove_edge(self, u: int, v: int) -> None:
        """Edge u–v and the polygons on both of its sides."""
        touched = []
        for p in self.side_polygons(u, v):
            loop = self.loops.pop(p)
            for i, x in enumerate(loop):
                y = loop[(i + 1) % len(loop)]
                self.he[(x, y)] = None
                touched.append((x, y))
        del self.he[(u, v)], self.he[(v, u)]
        self.out[u].discard(v)
        self.out[v].discard(u)
        del self.eid[_ekey(u, v)]
        self.boundary.discard((u, v))
        self.boundary.discard((v, u))
        self.interior.discard(_ekey(u, v))
        for x, y in touched:
            if (x, y) in self.he:
                self._refresh(x, y)

    def signature(self, vertex_map: dict[int, int] | None = None) -> tuple:
        """Comparable summary: polygon count, edge count, sorted boundary half-edges."""
        f = (lambda x: vertex_map.get(x, x)) if vertex_map else (lambda x: x)
        return (
            self.n_polygons,
            self.n_edges,
            sorted((f(a), f(b)) for a, b in self.boundary),
        )




# -- where the meshes live: a pristine build per size, working copies restored from it --------------------


def sa_engine(url: str) -> sa.Engine:
    """A plain SQLAlchemy engine on ``url``, configured as hestore configures its own."""
    eng = sa.create_engine(url)
    if url.startswith("sqlite"):

        @sa.event.listens_for(eng, "connect")
        def _pragmas(dbapi_conn, _record):
            cur = dbapi_conn.cursor()
            cur.execute("PRAGMA journal_mode=WAL")
            cur.execute("PRAGMA synchronous=NORMAL")
            cur.close()

    return eng


class Copies:
    """On one `Place`: the grid of each size built once (``b<n>``), and a working copy (``w<n>``) remade from it.

    On PostgreSQL the copy is made with hestore's own migration plus ``INSERT …
    SELECT`` of every table, then ``VACUUM (ANALYZE)`` — what autovacuum does
    soon after a bulk load. Without it the first reads of each freshly written
    page pay for setting hint bits, and the planner has no statistics.
    """

    def __init__(self, place: Place) -> None:
        self.place = place
        self.builds: dict[int, dict] = {}

    def build_url(self, n: int) -> str:
        self.builds[n] = self.place.fresh(f"b{n}")
        return url_of(self.builds[n])

    def restore(self, n: int) -> str:
        src, dst = self.builds[n], self.place.fresh(f"w{n}")
        if self.place.backend == "sqlite":
            wal = src["path"] + "-wal"
            if os.path.exists(wal) and os.path.getsize(wal) > 0:
                raise RuntimeError(f"{src['path']} still has a WAL: close every store on it before copying")
            shutil.copyfile(src["path"], dst["path"])
            return url_of(dst)
        hestore.open(url_of(dst)).close()  # creates hestore's tables at head, as a user's new database
        a, b = src["schema"], dst["schema"]
        with pg_connect(self.place.db_url, autocommit=True) as conn:
            for table in TABLES:
                conn.execute(f'INSERT INTO "{b}".{table} SELECT * FROM "{a}".{table}')
            conn.execute(f"SELECT setval(pg_get_serial_sequence('\"{b}\".meshes', 'id'), "
                         f'(SELECT coalesce(max(id), 0) + 1 FROM "{b}".meshes), false)')
            for table in TABLES:
                conn.execute(f'VACUUM (ANALYZE) "{b}".{table}')
        return url_of(dst)

    def size_bytes(self, n: int) -> int:
        src = self.builds[n]
        if self.place.backend == "sqlite":
            return os.path.getsize(src["path"])
        with pg_connect(self.place.db_url, autocommit=True) as conn:
            return conn.execute(
                "SELECT coalesce(sum(pg_total_relation_size(c.oid)), 0) FROM pg_class c "
                "JOIN pg_namespace s ON s.oid = c.relnamespace WHERE s.nspname = %s AND c.relkind = 'r'",
                (src["schema"],),
            ).fetchone()[0]


# -- choosing edits ------------------------------------------------------------------


def _pick(items, rng, ok, tries=64):
    """A random item satisfying ``ok`` (``(item, True)``), else a random one (``(item, False)``)."""
    for _ in range(tries):
        x = items.choice(rng)
        if ok(x):
            return x, True
    return items.choice(rng), False


def _plan_cold(items: IndexedSet, rng: random.Random, k: int, footprint, ok=None) -> list[tuple[int, int]]:
    """Up to ``k`` random ``items`` whose ``footprint`` vertices no other one's share (and that pass ``ok``)."""
    touched: set[int] = set()
    out = []
    misses = 0
    while len(out) < k and misses < 400:
        x = items.choice(rng)
        fp = footprint(x)
        if not fp.isdisjoint(touched) or (ok is not None and not ok(x)):
            misses += 1
            continue
        out.append(x)
        touched |= fp
    return out


def plan_cold_adds(model: Model, rng: random.Random, k: int) -> list[tuple[int, int]]:
    """Up to ``k`` boundary half-edges a→b, no two sharing a vertex."""
    return _plan_cold(model.boundary, rng, k, set)


def _clean_interior(model: Model, u: int, v: int) -> bool:
    ps = model.side_polygons(u, v)
    return len(ps) == 2 and not any(model.is_boundary_vertex(x) for x in model.remove_footprint(u, v))


def plan_cold_removes(model: Model, rng: random.Random, k: int) -> list[tuple[int, int]]:
    """Up to ``k`` interior edges away from the boundary, whose triangles share no vertex."""
    return _plan_cold(model.interior, rng, k, lambda e: model.remove_footprint(*e),
                      lambda e: _clean_interior(model, *e))


ADD, REMOVE = 0, 1


def plan_mixed(model: Model, mesh: hestore.Mesh, rng: random.Random, n: int) -> tuple[list, dict, dict]:
    """``n`` alternating edits, applied to ``model`` as planned.

    Each edit prefers a spot whose vertices no earlier edit of the plan
    touched (so it reads from the database); on a small mesh that soon runs
    out and the rest are "warm". Returns the plan, the slot of each planned
    vertex (negative model id → index of its ``add_vertex`` in the run), and
    counters.
    """
    touched: set[int] = set()
    plan: list = []
    slots: dict[int, int] = {}
    stats = {"adds": 0, "removes": 0, "warm": 0, "no_interior": 0}

    def ref(x: int):
        return hestore.Vertex(mesh, x) if x >= 0 else slots[x]

    def untouched_edge(k) -> bool:
        return model.remove_footprint(*k).isdisjoint(touched)

    def untouched_halfedge(k) -> bool:
        return k[0] not in touched and k[1] not in touched

    for i in range(n):
        if i % 2 == 1 and len(model.interior):
            (u, v), cold = _pick(model.interior, rng, untouched_edge)
            touched |= model.remove_footprint(u, v)
            plan.append((REMOVE, hestore.Edge(mesh, model.eid[(u, v)]), None, None))
            model.remove_edge(u, v)
            stats["removes"] += 1
        else:
            if i % 2 == 1:
                stats["no_interior"] += 1
            (a, b), cold = _pick(model.boundary, rng, untouched_halfedge)
            c = model.new_vertex_id()
            pos = model.new_position(a, b)
            plan.append((ADD, ref(a), ref(b), pos))
            slots[c] = len(slots)
            model.add_triangle(a, b, c, pos, ("new", c))
            touched.update((a, b, c))
            stats["adds"] += 1
        if not cold:
            stats["warm"] += 1
    return plan, slots, stats


def run_mixed(store: hestore.Store, mesh: hestore.Mesh, plan: list, *, commit: bool):
    """Run a planned mixed transaction; return (total ns, ns after last edit, new vertices)."""
    newv: list = []
    add_vertex, add_polygon, remove_edge = mesh.add_vertex, mesh.add_polygon, mesh.remove_edge
    try:
        with gc_paused():
            t0 = pc()
            with store.transaction():
                for kind, a, b, pos in plan:
                    if kind == ADD:
                        if type(a) is int:
                            a = newv[a]
                        if type(b) is int:
                            b = newv[b]
                        c = add_vertex(pos)
                        newv.append(c)
                        add_polygon([a, b, c])
                    else:
                        remove_edge(a)
                t1 = pc()
                if not commit:
                    mesh.counts()  # forces the flush, so that its statements can be counted
                    raise Rollback
            t2 = pc()
    except Rollback:
        t2 = pc()
    return t2 - t0, t2 - t1, newv


# -- measurements ----------------------------------------------------------------------


def measure_single(store, mesh, model, rng, kind: str, n: int, warm: int, block: int, counter=None):
    """Median-able samples of single add_polygon (and add_vertex) or remove_edge calls.

    Runs blocks of up to ``block`` independent edits, each block one
    transaction rolled back at its end (so the mesh stays the base mesh). An
    untimed ``add_vertex`` opens each block's unit of work (the mesh lock), a
    per-transaction cost that belongs to the commit figure.
    With ``counter`` (a `Statements`), also counts statements per op and at a
    forced flush; returns ``(samples, add_vertex samples, (per op, at flush,
    ops))``.
    """
    samples, vsamples = [], []
    cnt_op, cnt_flush = Counter(), Counter()
    n_ops = 0
    while len(samples) < warm + n:
        want = min(block, warm + n - len(samples))
        pairs = plan_cold_adds(model, rng, want) if kind == "add" else plan_cold_removes(model, rng, want)
        if not pairs:
            raise RuntimeError(f"no {kind} candidates left in the model")
        if kind == "add":
            plan = [(hestore.Vertex(mesh, a), hestore.Vertex(mesh, b), model.new_position(a, b)) for a, b in pairs]
        else:
            plan = [hestore.Edge(mesh, model.eid[(u, v)]) for u, v in pairs]
        try:
            with gc_paused(), traced(store, counter), store.transaction():
                mesh.add_vertex()
                if kind == "add":
                    for a, b, pos in plan:
                        before = counter.snapshot() if counter else None
                        t0 = pc()
                        c = mesh.add_vertex(pos)
                        t1 = pc()
                        mesh.add_polygon([a, b, c])
                        t2 = pc()
                        if counter:
                            cnt_op += counter.snapshot() - before
                        vsamples.append(t1 - t0)
                        samples.append(t2 - t1)
                else:
                    remove_edge = mesh.remove_edge
                    for e in plan:
                        before = counter.snapshot() if counter else None
                        t0 = pc()
                        remove_edge(e)
                        t1 = pc()
                        if counter:
                            cnt_op += counter.snapshot() - before
                        samples.append(t1 - t0)
                n_ops += len(plan)
                if counter:
                    before = counter.snapshot()
                    mesh.counts()  # flushes the block's writes
                    cnt_flush += counter.snapshot() - before
                raise Rollback
        except Rollback:
            pass
    return samples[warm:], vsamples[warm:], (cnt_op, cnt_flush, n_ops)


def measure_floor(engine: sa.Engine, n: int, warm: int) -> list[float]:
    """A 12-row update transaction through SQLAlchemy Core: the commit floor."""
    md = sa.MetaData()
    t = sa.Table("bench_floor_scratch", md, sa.Column("id", sa.Integer, primary_key=True), sa.Column("val", sa.Integer))
    md.drop_all(engine)
    md.create_all(engine)
    with engine.begin() as conn:
        conn.execute(t.insert(), [{"id": i, "val": 0} for i in range(12)])
    upd = t.update().where(t.c.id == sa.bindparam("i")).values(val=sa.bindparam("v"))

    def one(k: int) -> None:
        with engine.begin() as conn:
            for i in range(12):
                conn.execute(upd, {"i": i, "v": k})

    samples = time_each(one, range(warm + n)).samples
    md.drop_all(engine)
    return samples[warm:]


def measure_commits(store, mesh, model, rng, n: int, warm: int, counter=None):
    """One-polygon transactions end to end, and their part after the last edit."""
    total, tail = [], []
    acc = Counter()
    with gc_paused(), traced(store, counter):  # for the whole loop: a collection per transaction would dominate
        for k in range(warm + n):
            a, b = model.boundary.choice(rng)
            A, B, pos = hestore.Vertex(mesh, a), hestore.Vertex(mesh, b), model.new_position(a, b)
            before = counter.snapshot() if counter else None
            t0 = pc()
            with store.transaction():
                c = mesh.add_vertex(pos)
                p = mesh.add_polygon([A, B, c])
                t1 = pc()
            t2 = pc()
            if counter:
                acc += counter.snapshot() - before
            model.add_triangle(a, b, c.id, pos, p.id)
            if k >= warm:
                total.append(t2 - t0)
                tail.append(t2 - t1)
    return total, tail, acc


# -- one size on one backend -------------------------------------------------------------


def open_work(copies: Copies, size: int):
    url = copies.restore(size)
    engine = sa_engine(url)
    store = hestore.open(url)
    mesh = store.mesh(MESH)
    model = Model.load(engine, mesh.id)
    return engine, store, mesh, model


def run_size(copies: Copies, size: int, args, rng: random.Random) -> SizeResult:
    bname = copies.place.backend
    res = SizeResult(bname, size)
    load0 = os.getloadavg()[0]
    engine, store, mesh, model = open_work(copies, size)
    counts = mesh.counts()
    assert counts.polygons == model.n_polygons and counts.edges == model.n_edges, (counts, model.n_polygons)
    log(f"{bname} {size}: {counts}; boundary half-edges {len(model.boundary)}, interior edges {len(model.interior)}")

    # add_polygon / remove_edge inside a transaction
    for kind in ("add", "remove"):
        s, vs, _ = measure_single(store, mesh, model, rng, kind, args.repeat, args.warmup, args.block)
        if kind == "add":
            res.figures.append(Samples("add_polygon in txn (triangle on boundary)", s, TARGET_EDIT))
            res.figures.append(Samples("  add_vertex in txn (its new corner)", vs))
        else:
            res.figures.append(Samples("remove_edge in txn (interior, 2 triangles)", s, TARGET_EDIT))
        if args.count:
            counter = Statements()
            _, _, (op, fl, n_ops) = measure_single(store, mesh, model, rng, kind, args.block, 0, args.block, counter)
            label = "add_polygon" if kind == "add" else "remove_edge"
            res.sql.append((f"{label}: during the call, per op", Statements.per(op, n_ops)))
            res.sql.append((f"{label}: at flush, per op ({n_ops} ops)", Statements.per(fl, n_ops)))
    assert mesh.counts() == counts, "a rolled-back block changed the mesh"

    # floor: a 12-row update transaction through SQLAlchemy, same database
    floor = measure_floor(engine, args.repeat, args.warmup)
    floor_med = median(floor)
    res.figures.append(Samples("floor: 12-row UPDATE txn via SQLAlchemy", floor))

    # one-polygon transactions (these commit: the model follows)
    total, tail, _ = measure_commits(store, mesh, model, rng, args.repeat, args.warmup)
    res.figures.append(Samples("1-polygon txn, end to end", total, TARGET_COMMIT, floor_med))
    res.figures.append(Samples("  of which flush + COMMIT", tail, TARGET_COMMIT, floor_med))
    if args.count:
        _, _, acc = measure_commits(store, mesh, model, rng, 20, 0, Statements())
        res.sql.append(("1-polygon txn, per txn", Statements.per(acc, 20)))
    store.close()
    engine.dispose()

    # many-edit transactions, each on a fresh copy of the base mesh
    per_edit, commit_part = [], []
    for run in range(args.txn_runs):
        engine, store, mesh, model = open_work(copies, size)
        # warm-up (and statement count): the same kind of transaction, rolled back
        plan, _, _ = plan_mixed(model.copy(), mesh, rng, args.edits)
        counter = Statements() if (args.count and run == 0) else None
        with traced(store, counter):
            run_mixed(store, mesh, plan, commit=False)
        if counter:
            res.sql.append((f"{args.edits}-edit txn, per edit (incl. flush)",
                            Statements.per(counter.by_kind, args.edits)))
        plan, slots, stats = plan_mixed(model, mesh, rng, args.edits)
        total, tail, newv = run_mixed(store, mesh, plan, commit=True)
        per_edit.append(total / args.edits)
        commit_part.append(tail)
        # the database must now hold what the plan said
        vmap = {neg: newv[slot].id for neg, slot in slots.items()}
        expected = model.signature(vmap)
        actual = Model.load(engine, mesh.id).signature()
        if expected != actual:
            res.problems.append(f"after the {args.edits}-edit transaction the database differs from the plan: "
                                f"polygons {actual[0]} vs {expected[0]}, edges {actual[1]} vs {expected[1]}, "
                                f"boundary half-edges {len(actual[2])} vs {len(expected[2])}")
            log(f"{bname} {size}: {res.problems[-1]}")
        res.notes.append(
            f"{args.edits}-edit run {run + 1}: {fmt_time(total / 1e9)} total, {fmt_time(tail / 1e9)} flush+COMMIT, "
            f"{stats['adds']} adds / {stats['removes']} removes"
            + (f" ({stats['no_interior']} removes became adds: no interior edge left)" if stats["no_interior"] else "")
            + f", {100 * stats['warm'] / args.edits:.0f}% of edits on vertices an earlier edit had touched"
        )
        if run < args.txn_runs - 1:
            store.close()
            engine.dispose()
    res.figures.append(Samples(f"{args.edits}-edit txn, per edit incl. COMMIT", per_edit, TARGET_AMORTISED, p90=False))
    res.notes.append(f"{args.edits}-edit txn: the figure is the median of {len(per_edit)} run(s); "
                     f"their flush+COMMIT part {fmt_time(median(commit_part) / 1e9)} (median)")

    res.notes.append(f"load average (1 min) {load0:.1f} at the start of the measurements, "
                     f"{os.getloadavg()[0]:.1f} at the end ({os.cpu_count()} CPUs)")
    if args.check:
        t0 = time.perf_counter()
        violations = mesh.check()
        dt = time.perf_counter() - t0
        res.notes.append(f"mesh.check() after the runs: {len(violations)} violation(s), {dt:.2f} s")
        if violations:
            res.problems.append(f"check() found {len(violations)} violations, e.g. {violations[:3]}")
            log(f"{bname} {size}: {res.problems[-1]}")
    store.close()
    engine.dispose()
    return res


# -- main ----------------------------------------------------------------------------------


def main(argv=None) -> int:
    ap = Parser(__doc__, quick=QUICK, seed=20240601)
    ap.add_argument("--sizes", default="1000,10000,100000", help="mesh sizes in polygons, comma-separated")
    ap.add_argument("--repeat", type=int, default=200, help="timed calls per single-operation figure (default 200)")
    ap.add_argument("--warmup", type=int, default=20, help="untimed calls before each figure (default 20)")
    ap.add_argument("--txn-runs", type=int, default=3, help="many-edit transactions per size (default 3)")
    ap.add_argument("--edits", type=int, default=1000, help="edits in the amortised transaction (default 1000)")
    ap.add_argument("--block", type=int, default=50, help="edits per rolled-back measuring block (default 50)")
    ap.add_argument("--max-build-seconds", type=float, default=180,
                    help="skip a size whose build is expected to take longer (default 180)")
    ap.add_argument("--no-count", dest="count", action="store_false", help="skip the SQL statement counts")
    ap.add_argument("--no-check", dest="check", action="store_false", help="skip mesh.check() at the end")
    args = ap.parse_args(argv)
    sizes = [int(s) for s in args.sizes.split(",") if s.strip()]
    rng = random.Random(args.seed)

    builds, results = [], []
    with Bench(args, "edits") as bench:
        for place in bench.for_each_backend():
            bname, copies, rate = place.backend, Copies(place), None
            for size in sizes:
                if rate and size / rate > args.max_build_seconds:
                    bench.report.skipped.append(
                        f"{bname} {size}: skipped, the build would take ~{size / rate:.0f} s at "
                        f"{rate:.0f} polygons/s (limit {args.max_build_seconds:.0f} s)"
                    )
                    continue
                log(f"{bname} {size}: building")
                store = hestore.open(copies.build_url(size))
                b = build_grid(store, size)
                store.close()
                rate = b.rate
                builds.append((bname, b, copies.size_bytes(size), maxrss()))
                log(f"{bname} {size}: built {b.polygons} polygons in {b.seconds:.2f} s ({b.rate:.0f}/s)")
                results.append(run_size(copies, size, args, rng))
                log(f"{bname} {size}: done; peak RSS {maxrss() / 2**20:.0f} MiB")
    report(bench, builds, results)
    return bench.finish()


def figures_of(results: list[SizeResult]) -> list[Figure]:
    return [Figure.of_calls(f.name, r.backend, f.samples, p90=f.p90,
                            floor=f.floor / 1e9 if f.floor else None,
                            target=("≤ " + fmt_time(f.target / 1e9)) if f.target else "—",
                            verdict=verdict(None if f.target is None else f.median <= f.target), mesh=f"{r.size:,}")
            for r in results for f in r.figures]


def growth_rows(results: list[SizeResult]) -> tuple[list[int], list[list[str]]]:
    """Each figure's median at each size, per backend, and the ratio of the largest size's to the smallest's."""
    names = [f.name for f in results[0].figures]
    sizes = sorted({r.size for r in results})
    rows = []
    for bname in dict.fromkeys(r.backend for r in results):
        by_size = {r.size: r for r in results if r.backend == bname}
        for i, name in enumerate(names):
            vals = [by_size[s].figures[i].median if s in by_size else None for s in sizes]
            present = [v for v in vals if v is not None]
            ratio = f"{present[-1] / present[0]:.2f}" if len(present) > 1 else "—"
            rows.append([bname, name.strip()] + [fmt_time(None if v is None else v / 1e9) for v in vals] + [ratio])
    return sizes, rows


def report(bench: Bench, builds: list, results: list[SizeResult]) -> None:
    args, rep = bench.args, bench.report
    rep.title(f"hestore edit benchmark — seed {args.seed}, {args.repeat} timed calls per figure, "
              f"{args.txn_runs} × {args.edits}-edit transactions per size")
    rows = [[bname, f"{b.polygons:,}", f"{b.vertices:,}", f"{b.seconds:.2f} s",
             f"{b.seconds_vertices:.2f} / {b.seconds_polygons:.2f} / {b.seconds_commit:.2f} s",
             f"{b.rate:,.0f}", f"{nbytes / 2**20:.1f} MiB", f"{rss / 2**20:.0f} MiB"]
            for bname, b, nbytes, rss in builds]
    rep.table("Build: triangulated grid through the public API, one transaction (add_vertex ×V, add_polygon ×F, "
              "commit). PostGIS Topology: 45–240 triangles/s.",
              ["backend", "polygons", "vertices", "build", "vertices / polygons / commit", "polygons/s", "db size",
               "peak RSS so far"], rows, "llrrrrrr")
    rep.figures(figures_of(results), caption="Edits (time: the median of the n timed calls, p90 beside it; mesh: "
                                             "polygons; target = SPEC §9; floor measured in the same run):")
    if results:
        sizes, rows = growth_rows(results)
        rep.table("Growth with the mesh (median at each size; ratio = largest size / smallest size):",
                  ["backend", "figure"] + [f"{s:,}" for s in sizes] + ["ratio"], rows, "ll" + "r" * (len(sizes) + 1))
    rep.table("SQL statements hestore sent on its driver cursor, per operation (counted through\n"
              "store.session.traced in separate, untimed passes; an executemany counts once, its rows are not seen;\n"
              "TXN = BEGIN/COMMIT/SAVEPOINT/RELEASE/ROLLBACK):", ["backend", "mesh", "what", "statements"],
              [[r.backend, f"{r.size:,}", w, c] for r in results for w, c in r.sql], "lrll")
    for r in results:
        rep.notes += [f"{r.backend} {r.size:,}: {n}" for n in r.notes]
        rep.problems += [f"{r.backend} {r.size:,}: {p}" for p in r.problems]
    rep.close(ABOUT, rss="Peak RSS of the whole run")


if __name__ == "__main__":
    raise SystemExit(main())
