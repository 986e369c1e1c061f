"""Shared helpers for hestore's benchmarks (SPEC §9).

Nothing here is timed by itself. It provides:

* `Backend`: where benchmark databases live — SQLite files in a temporary
  folder, or PostgreSQL schemas in a database made for the run and dropped at
  its end — with a pristine "build" copy per mesh size and working copies
  restored from it;
* `build_grid`: the SPEC §9 workload, a triangulated grid, built through the
  public API in one transaction;
* `Model`: a plain-Python picture of a mesh's triangles and boundary, used to
  choose edits (a boundary half-edge to attach to, an interior edge to remove)
  *before* the timed region, and to check afterwards that the database agrees;
* `CountingCursor`: counts the SQL statements hestore sends on its driver
  cursor;
* statistics and table printing;
* for the one-command benchmarks of the large meshes (``import.py``,
  ``graph.py``): where the shared meshes are and the grid's arrays, plain-driver
  connections to the run's SQLite files and PostgreSQL schemas, a binary
  ``COPY TO`` into numpy columns, a `Runner` that runs each step in a fresh
  process (so each figure has its own peak RSS), and the machine notes.
"""

from __future__ import annotations

import contextlib
import json
import argparse
import math
import os
import platform
import random
import resource
import shutil
import sqlite3
import subprocess
import sys
import time
import uuid
from collections import defaultdict
from dataclasses import dataclass, field
from typing import Any, Iterable
from urllib.parse import quote

import numpy as np
import sqlalchemy as sa

import hestore

DEFAULT_PG_URL = "postgresql+psycopg://postgres@127.0.0.1:5432/test"
MESH = "grid"


# -- statistics and formatting ---------------------------------------------------


def percentile(values: list[float], q: float) -> float:
    """The ``q``-quantile (0..1) with linear interpolation, like numpy's default."""
    if not values:
        return math.nan
    s = sorted(values)
    pos = (len(s) - 1) * q
    lo = math.floor(pos)
    hi = min(lo + 1, len(s) - 1)
    return s[lo] + (s[hi] - s[lo]) * (pos - lo)


def median(values: list[float]) -> float:
    return percentile(values, 0.5)


def fmt_ns(ns: float | None) -> str:
    """A duration in nanoseconds, in the unit that reads best."""
    if ns is None or (isinstance(ns, float) and math.isnan(ns)):
        return "—"
    if ns < 1_000_000:
        return f"{ns / 1000:.0f} µs" if ns >= 100_000 else f"{ns / 1000:.1f} µs"
    if ns < 1_000_000_000:
        return f"{ns / 1e6:.2f} ms"
    return f"{ns / 1e9:.2f} s"


def print_table(headers: list[str], rows: list[list[str]], align: str | None = None, out=sys.stdout) -> None:
    """A plain-text table; ``align`` has one 'l' or 'r' per column."""
    align = align or "l" * len(headers)
    widths = [max(len(str(x)) for x in col) for col in zip(headers, *rows)]

    def line(cells):
        return "  ".join(
            (str(c).ljust(w) if a == "l" else str(c).rjust(w)) for c, w, a in zip(cells, widths, align)
        ).rstrip()

    print(line(headers), file=out)
    print("  ".join("-" * w for w in widths), file=out)
    for r in rows:
        print(line(r), file=out)
    out.flush()


def peak_rss_mb() -> float:
    """Peak resident set size of this process, in MiB (Linux reports KiB)."""
    kb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return kb / 1024 if sys.platform != "darwin" else kb / 1024 / 1024


def log(msg: str) -> None:
    print(f"[{time.strftime('%H:%M:%S')}] {msg}", file=sys.stderr, flush=True)


# -- SQL statement counting ----------------------------------------------------------


class CountingCursor:
    """Wraps a DBAPI cursor and counts what hestore sends through it.

    hestore runs its hot statements on the driver's own cursor
    (``store._cur``), not through ``Connection.execute``, so SQLAlchemy's
    ``before_cursor_execute`` event does not see them. Install with
    ``store._cur = CountingCursor(store._cur)`` and put the original back
    afterwards.
    """

    def __init__(self, cursor: Any) -> None:
        self._inner = cursor
        self.reset()

    def reset(self) -> None:
        self.calls = 0  # execute + executemany calls (driver round trips, roughly)
        self.rows = 0  # parameter sets (an executemany of n rows counts n)
        self.by_kind: dict[str, list[int]] = defaultdict(lambda: [0, 0])  # kind -> [calls, rows]

    @staticmethod
    def _kind(sql: str) -> str:
        word = sql.lstrip().split(None, 1)[0].upper()
        if word in ("SELECT", "INSERT", "UPDATE", "DELETE"):
            return word
        if word in ("WITH", "(SELECT"):
            return "SELECT"
        return "TXN"  # BEGIN, COMMIT, SAVEPOINT, RELEASE, ROLLBACK

    def execute(self, sql, *args, **kwargs):
        self.calls += 1
        self.rows += 1
        k = self.by_kind[self._kind(sql)]
        k[0] += 1
        k[1] += 1
        return self._inner.execute(sql, *args, **kwargs)

    def executemany(self, sql, seq, *args, **kwargs):
        seq = list(seq)
        self.calls += 1
        self.rows += len(seq)
        k = self.by_kind[self._kind(sql)]
        k[0] += 1
        k[1] += len(seq)
        return self._inner.executemany(sql, seq, *args, **kwargs)

    def snapshot(self) -> tuple[int, int, dict[str, tuple[int, int]]]:
        return self.calls, self.rows, {k: tuple(v) for k, v in self.by_kind.items()}

    def __getattr__(self, name):
        return getattr(self._inner, name)


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


# -- where the databases live ---------------------------------------------------------


class Backend:
    """Benchmark databases on one backend: a pristine build per size, working copies.

    ``build_url(n)`` is where the size-``n`` mesh is built once;
    ``restore(n)`` makes (or remakes) the working copy from it and returns its
    URL; ``cleanup()`` removes everything the run made.
    """

    name = "?"

    def build_url(self, n: int) -> str: ...
    def restore(self, n: int) -> str: ...
    def has_build(self, n: int) -> bool: ...
    def cleanup(self) -> None: ...

    def engine(self, url: str) -> sa.Engine:
        """A plain SQLAlchemy engine on ``url``, configured as hestore configures its own."""
        if url.startswith("sqlite"):
            eng = sa.create_engine(url)

            @sa.event.listens_for(eng, "connect")
            def _pragmas(dbapi_conn, _record):
                cur = dbapi_conn.cursor()
                cur.execute("PRAGMA journal_mode=WAL")
                cur.execute("PRAGMA synchronous=NORMAL")
                cur.close()

            return eng
        return sa.create_engine(url)


class SQLiteBackend(Backend):
    name = "sqlite"

    def __init__(self, workdir: str) -> None:
        self.dir = workdir

    def _path(self, kind: str, n: int) -> str:
        return os.path.join(self.dir, f"{kind}-{n}.db")

    def build_url(self, n: int) -> str:
        return f"sqlite:///{self._path('build', n)}"

    def has_build(self, n: int) -> bool:
        return os.path.exists(self._path("build", n))

    @staticmethod
    def _remove(path: str) -> None:
        for suffix in ("", "-wal", "-shm", "-journal"):
            if os.path.exists(path + suffix):
                os.remove(path + suffix)

    def restore(self, n: int) -> str:
        src, dst = self._path("build", n), self._path("work", n)
        if os.path.exists(src + "-wal") and os.path.getsize(src + "-wal") > 0:
            raise RuntimeError(f"{src} still has a WAL: close every store on it before copying")
        self._remove(dst)
        shutil.copyfile(src, dst)
        return f"sqlite:///{dst}"

    def size_bytes(self, n: int) -> int:
        return os.path.getsize(self._path("build", n))

    def cleanup(self) -> None:
        pass  # the caller removes the folder


class PostgresBackend(Backend):
    """One database made for the run (dropped at the end); one schema per size.

    ``b<n>`` holds the pristine build, ``w<n>`` the working copy, remade by
    ``restore`` with hestore's own migration plus ``INSERT … SELECT`` of every
    table, then ``VACUUM (ANALYZE)`` — what autovacuum does soon after a bulk
    load. Without it the first reads of each freshly written page pay for
    setting hint bits, and the planner has no statistics.
    """

    name = "postgresql"

    def __init__(self, admin_url: str) -> None:
        self.admin_url = sa.engine.make_url(admin_url)
        self.dbname = f"hestore_bench_{uuid.uuid4().hex[:10]}"
        admin = sa.create_engine(self.admin_url, isolation_level="AUTOCOMMIT")
        with admin.connect() as conn:
            conn.execute(sa.text(f'CREATE DATABASE "{self.dbname}"'))
        admin.dispose()
        self.db_url = self.admin_url.set(database=self.dbname)
        self._eng = sa.create_engine(self.db_url, isolation_level="AUTOCOMMIT")
        self._built: set[int] = set()

    def _schema_url(self, schema: str) -> str:
        base = self.db_url.render_as_string(hide_password=False)
        return f"{base}?options={quote(f'-csearch_path={schema}')}"

    def _recreate_schema(self, schema: str) -> None:
        with self._eng.connect() as conn:
            conn.execute(sa.text(f'DROP SCHEMA IF EXISTS "{schema}" CASCADE'))
            conn.execute(sa.text(f'CREATE SCHEMA "{schema}"'))

    def build_url(self, n: int) -> str:
        self._recreate_schema(f"b{n}")
        self._built.add(n)
        return self._schema_url(f"b{n}")

    def has_build(self, n: int) -> bool:
        return n in self._built

    def restore(self, n: int) -> str:
        src, dst = f"b{n}", f"w{n}"
        self._recreate_schema(dst)
        url = self._schema_url(dst)
        hestore.open(url).close()  # creates hestore's tables at head, as a user's new database
        with self._eng.connect() as conn:
            for table in ("meshes", "vertices", "halfedges", "edges", "polygons"):
                conn.execute(sa.text(f'INSERT INTO "{dst}".{table} SELECT * FROM "{src}".{table}'))
            conn.execute(
                sa.text(
                    f"SELECT setval(pg_get_serial_sequence('\"{dst}\".meshes', 'id'), "
                    f'(SELECT coalesce(max(id), 0) + 1 FROM "{dst}".meshes), false)'
                )
            )
            for table in ("meshes", "vertices", "halfedges", "edges", "polygons"):
                conn.execute(sa.text(f'VACUUM (ANALYZE) "{dst}".{table}'))
        return url

    def analyze_build(self, n: int) -> None:
        with self._eng.connect() as conn:
            for table in ("meshes", "vertices", "halfedges", "edges", "polygons"):
                conn.execute(sa.text(f'ANALYZE "b{n}".{table}'))

    def size_bytes(self, n: int) -> int:
        with self._eng.connect() as conn:
            return conn.execute(
                sa.text(
                    "SELECT coalesce(sum(pg_total_relation_size(c.oid)), 0) FROM pg_class c "
                    "JOIN pg_namespace s ON s.oid = c.relnamespace WHERE s.nspname = :s AND c.relkind = 'r'"
                ),
                {"s": f"b{n}"},
            ).scalar()

    def cleanup(self) -> None:
        self._eng.dispose()
        admin = sa.create_engine(self.admin_url, isolation_level="AUTOCOMMIT")
        with admin.connect() as conn:
            conn.execute(sa.text(f'DROP DATABASE IF EXISTS "{self.dbname}" WITH (FORCE)'))
        admin.dispose()


def pg_problem(url: str) -> str | None:
    """Why PostgreSQL at ``url`` cannot be used, or None."""
    try:
        import psycopg  # noqa: F401
    except ImportError as exc:
        return f"psycopg is not installed ({exc})"
    try:
        eng = sa.create_engine(url, connect_args={"connect_timeout": 5})
        with eng.connect() as conn:
            conn.execute(sa.text("SELECT 1"))
        eng.dispose()
    except Exception as exc:
        return f"{exc.__class__.__name__}: {str(exc).splitlines()[0]}"
    return None


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


def mesh_id(engine: sa.Engine, name: str = MESH) -> int:
    with engine.connect() as conn:
        return conn.execute(sa.text("SELECT id FROM meshes WHERE name = :n"), {"n": name}).scalar_one()


# -- one-command benchmarks of large meshes (import.py, graph.py) -----------------------
#
# The pieces below are shared by the benchmarks that run each figure in a fresh
# subprocess (`Runner`) on the 1 M-triangle grid and the large shared meshes.

HERE = os.path.dirname(os.path.abspath(__file__))
FILES = {"bunny": "stanford-bunny-subdiv2.obj", "igea": "igea-subdiv1.ply"}
MESHES = ("grid", "bunny", "igea")


def meshes_dir() -> str:
    """``$HESTORE_BENCH_MESHES``, else ``../shared/meshes`` next to the repository."""
    env = os.environ.get("HESTORE_BENCH_MESHES")
    if env:
        return env
    return os.path.normpath(os.path.join(HERE, "..", "..", "shared", "meshes"))

@dataclass
class Figure:
    """One row of a 1 M-mesh benchmark's table: a time beside its floor and target."""

    backend: str
    mesh: str
    name: str
    seconds: float | None
    floor: float | None
    floor_parts: str
    target: str
    rss: int | None
    verdict: str
    cpu: float | None = None

    @property
    def ratio(self) -> float | None:
        if self.seconds is None or not self.floor:
            return None
        return self.seconds / self.floor


def mesh_bench_parser(doc: str, *, workdir_help: str, profile_help: str) -> argparse.ArgumentParser:
    """The options every 1 M-mesh benchmark (``import.py``, ``graph.py``) takes."""
    ap = argparse.ArgumentParser(description=doc.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--backends", default="sqlite,postgresql", help="sqlite and/or postgresql (default both)")
    ap.add_argument("--only", default=",".join(MESHES), help="meshes to run: grid, bunny, igea (default all)")
    ap.add_argument("--n", type=int, default=710, help="grid vertices per side (default 710: 1,005,362 triangles)")
    ap.add_argument("--pg-url", default=os.environ.get("HESTORE_BENCH_PG_URL", DEFAULT_PG_URL),
                    help="PostgreSQL server to use; a database is created there for the run and dropped at the end")
    ap.add_argument("--workdir", help=workdir_help)
    ap.add_argument("--meshes-dir", default=meshes_dir(),
                    help="folder of the shared mesh files (default $HESTORE_BENCH_MESHES, else ../shared/meshes)")
    ap.add_argument("--profile", choices=("over", "all", "off"), default="over", help=profile_help)
    ap.add_argument("--timeout", type=float, default=1800, help="seconds allowed per step (default 1800)")
    ap.add_argument("--child", help=argparse.SUPPRESS)
    return ap


def selected_meshes(ap: argparse.ArgumentParser, args: argparse.Namespace, known_backends) -> tuple[list, list, list]:
    """``(meshes, backends, skipped)`` from ``--only`` and ``--backends``; a missing file skips its mesh."""
    only = [m.strip() for m in args.only.split(",") if m.strip()]
    backends = [b.strip() for b in args.backends.split(",") if b.strip()]
    for m in only:
        if m not in MESHES:
            ap.error(f"unknown mesh {m!r} (choose from {', '.join(MESHES)})")
    for b in backends:
        if b not in known_backends:
            ap.error(f"unknown backend {b!r}")
    if args.n < 2:
        ap.error("--n must be at least 2")
    skipped: list[str] = []
    for m in list(only):
        if m in FILES and not os.path.exists(os.path.join(args.meshes_dir, FILES[m])):
            skipped.append(f"{m}: {os.path.join(args.meshes_dir, FILES[m])} not found")
            only.remove(m)
    return only, backends, skipped



def grid_arrays(n: int) -> tuple[np.ndarray, np.ndarray]:
    """The triangulated n×n vertex grid: positions (n², 3) and triangles (2(n-1)², 3), counter-clockwise."""
    j, i = np.divmod(np.arange(n * n, dtype=np.int64), n)
    positions = np.column_stack([i, j, np.zeros(n * n)]).astype(np.float64)
    v = (np.arange(n - 1)[:, None] * n + np.arange(n - 1)[None, :]).ravel()
    faces = np.empty((2 * len(v), 3), dtype=np.int64)
    faces[0::2] = np.column_stack([v, v + 1, v + n + 1])
    faces[1::2] = np.column_stack([v, v + n + 1, v + n])
    return positions, faces


def mesh_label(mesh: str, n: int) -> str:
    if mesh == "grid":
        return f"grid {n}×{n}"
    return FILES[mesh]


def fmt_s(x: float | None) -> str:
    return "—" if x is None else f"{x:.2f} s"


def fmt_mib(b: int | None) -> str:
    return "—" if b is None else f"{b / 2**20:,.0f} MiB"


def maxrss() -> int:
    """Peak RSS of this process so far, in bytes."""
    kb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return kb * 1024 if sys.platform != "darwin" else kb


def cpu_seconds() -> float:
    """User + system CPU time of this process so far."""
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def best_of(fn, *args, repeat: int = 2):
    times, out = [], None
    for _ in range(repeat):
        out = None
        t0 = time.perf_counter()
        out = fn(*args)
        times.append(time.perf_counter() - t0)
    return min(times), out


# Databases made for a run: SQLite files and PostgreSQL schemas, reached with the plain drivers.


def sqlite_url(path: str) -> str:
    return f"sqlite:///{path}"


def remove_sqlite(path: str) -> None:
    for suffix in ("", "-wal", "-shm", "-journal"):
        with contextlib.suppress(FileNotFoundError):
            os.remove(path + suffix)


def sqlite_connect(path: str) -> sqlite3.Connection:
    """A plain connection configured as hestore configures its own."""
    con = sqlite3.connect(path, isolation_level=None)
    con.execute("PRAGMA journal_mode=WAL")
    con.execute("PRAGMA synchronous=NORMAL")
    con.execute("PRAGMA cache_size=-65536")
    return con


def pg_schema_url(db_url: str, schema_name: str) -> str:
    return f"{db_url}?options={quote(f'-csearch_path={schema_name}')}"


def pg_connect(url: str, *, autocommit: bool = False):
    import psycopg

    u = sa.engine.make_url(url)
    kw = {"host": u.host, "port": u.port, "user": u.username, "dbname": u.database}
    if u.password:
        kw["password"] = u.password
    if "options" in u.query:
        kw["options"] = u.query["options"]
    return psycopg.connect(autocommit=autocommit, **{k: v for k, v in kw.items() if v is not None})


def pg_fresh_schema(db_url: str, name: str) -> str:
    with pg_connect(db_url, autocommit=True) as conn:
        conn.execute(f'DROP SCHEMA IF EXISTS "{name}" CASCADE')
        conn.execute(f'CREATE SCHEMA "{name}"')
    return pg_schema_url(db_url, name)


def pg_drop_schema(db_url: str, name: str) -> None:
    with pg_connect(db_url, autocommit=True) as conn:
        conn.execute(f'DROP SCHEMA IF EXISTS "{name}" CASCADE')


def settle(spec: dict) -> None:
    """Before a timed region: flush dirty pages, and on PostgreSQL run a CHECKPOINT,
    so that work left by the previous step does not land in this one."""
    os.sync()
    if spec.get("backend") == "postgresql":
        with pg_connect(spec["db_url"], autocommit=True) as conn:
            conn.execute("CHECKPOINT")


def pg_copy_columns(cursor, exprs: list[str], rest: str, dtypes: list) -> list[np.ndarray]:
    """``SELECT exprs rest`` as numpy columns, through one binary ``COPY TO`` of one row of ``array_agg``s.

    Each expression is cast to int8 or float8 (after its dtype) and aggregated
    into one array; the single row that comes back is decoded with
    ``np.frombuffer``. (A row-per-row ``COPY TO`` is far slower: the driver
    hands over every row as its own message.) NULL elements are not supported.
    """
    aggs = ", ".join(f"array_agg(({e})::{'float8' if np.dtype(d).kind == 'f' else 'int8'})"
                     for e, d in zip(exprs, dtypes))
    with cursor.copy(f"COPY (SELECT {aggs} {rest}) TO STDOUT (FORMAT BINARY)") as copy:
        buf = b"".join(copy)
    pos = 19 + 2  # signature, flags, header extension; then the row's field count
    columns = []
    for dtype in dtypes:
        value = ">f8" if np.dtype(dtype).kind == "f" else ">i8"
        item = np.dtype([("length", ">i4"), ("value", value)])
        length = int.from_bytes(buf[pos : pos + 4], "big", signed=True)
        if length < 0:  # array_agg of no rows is NULL
            columns.append(np.empty(0, dtype=dtype))
            pos += 4
            continue
        count = int.from_bytes(buf[pos + 16 : pos + 20], "big")  # after ndim, flags, element type
        columns.append(np.frombuffer(buf, dtype=item, count=count, offset=pos + 24)["value"].astype(dtype))
        pos += 4 + length
    return columns


# Running each figure in a fresh process.


class Runner:
    """Runs ``script --child SPEC_JSON`` in a fresh process per step; the child writes its result as JSON."""

    def __init__(self, script: str, workdir: str, timeout: float) -> None:
        self.script = os.path.abspath(script)
        self.workdir = workdir
        self.timeout = timeout
        self.errors: list[str] = []
        self._k = 0

    def run(self, **spec) -> dict | None:
        self._k += 1
        spec["result"] = os.path.join(self.workdir, f"result-{self._k}.json")
        spec["workdir"] = self.workdir
        what = " ".join(str(spec[k]) for k in ("job", "backend", "mesh", "fmt", "kind", "what", "variant") if spec.get(k))
        if spec.get("profile"):
            what += " (under cProfile)"
        t0 = time.perf_counter()
        try:
            proc = subprocess.run([sys.executable, self.script, "--child", json.dumps(spec)],
                                  timeout=self.timeout, stdout=subprocess.DEVNULL)
        except subprocess.TimeoutExpired:
            self.errors.append(f"{what}: timed out after {self.timeout:.0f} s")
            log(self.errors[-1])
            return None
        if proc.returncode != 0 or not os.path.exists(spec["result"]):
            self.errors.append(f"{what}: the child process failed (exit {proc.returncode}; its traceback is above)")
            log(self.errors[-1])
            return None
        with open(spec["result"]) as f:
            result = json.load(f)
        os.remove(spec["result"])
        log(f"{what}: done in {time.perf_counter() - t0:.1f} s")
        return result


def child_main(jobs: dict, spec_json: str) -> int:
    """The child side of `Runner.run`: run ``jobs[spec["job"]](spec)``, write its result, exit.

    The process ends with ``os._exit``: a job may leave gigabytes of Python
    objects (a networkx graph) that the interpreter would otherwise free one
    by one on the way out, for nothing.
    """
    spec = json.loads(spec_json)
    result = jobs[spec["job"]](spec)
    with open(spec["result"], "w") as f:
        json.dump(result, f)
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(0)


class PgRun(PostgresBackend):
    """The run's PostgreSQL database (made at the start, dropped by ``cleanup``)."""

    @property
    def url(self) -> str:
        return self.db_url.render_as_string(hide_password=False)

    def version(self) -> str:
        with self._eng.connect() as conn:
            return conn.execute(sa.text("SHOW server_version")).scalar()


def print_machine(pg_version: str | None, load_start: tuple, meshes: str, elapsed: float, libraries: str = "") -> None:
    """The machine notes that end a benchmark's output."""
    print()
    print("Machine:")
    cpu = ""
    with contextlib.suppress(OSError):
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    mem = ""
    with contextlib.suppress(OSError, ValueError, IndexError):
        with open("/proc/meminfo") as fh:
            mem = f"{int(fh.readline().split()[1]) / 2**20:.1f} GiB RAM"
    load_end = os.getloadavg()
    print(f"  {os.cpu_count()} CPUs ({cpu or platform.machine()}), {mem}, {platform.platform()}")
    print(f"  load average (1/5/15 min) {' '.join(f'{x:.2f}' for x in load_start)} at the start, "
          f"{' '.join(f'{x:.2f}' for x in load_end)} at the end")
    print(f"  SQLite {sqlite3.sqlite_version} (journal_mode=WAL, synchronous=NORMAL, cache_size=64 MiB, as hestore sets)")
    print(f"  PostgreSQL {pg_version or '— (not run)'}, on the same machine")
    try:
        import psycopg

        drivers = f"psycopg {psycopg.__version__}"
    except ImportError:
        drivers = "psycopg not installed"
    print(f"  Python {platform.python_version()}, numpy {np.__version__}, SQLAlchemy {sa.__version__}, {drivers}"
          + (f", {libraries}" if libraries else ""))
    print(f"  meshes from {meshes}; whole run {elapsed / 60:.1f} min")
