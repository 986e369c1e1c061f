"""Benchmark: what mesh history (SPEC §4.1) costs — journaling, reading the past, undo (SPEC §9).

    python bench/history.py [--backends sqlite,postgresql] [--n 710] [--small 50x100] [--edits 1000]

SPEC §9: "journaling adds ≤ 25 % to a one-polygon transaction and ≤ 10 % to
a 1 M import; at(r) costs in proportion to the changes since r, not to the
mesh". Every figure with history is printed beside the same work on a mesh
created with ``history=False`` (or on the current mesh), measured in the
same run, on the same database server.

Workloads: the triangulated N×N vertex grid (``--n``, default 710: 1,005,362
triangles) and a small grid of ``--small`` cells (default 50×100: 10,000
triangles), both with 2 triangles per cell. Each is stored twice per
backend with ``store.import_arrays``: once with history (``history=True``,
the default) and once with ``history=False``, each mesh in a database of its
own, so that the two differ in nothing but their history (side by side in one
database, the mesh stored second appends at the right edge of every table and
index, where SQLite splits pages more cheaply: about 8 % of a one-polygon
transaction), untimed, on PostgreSQL followed by ``VACUUM (ANALYZE)``. Every step runs in a
fresh process on a freshly opened store; before each timed region it runs
``os.sync()`` and, on PostgreSQL, a ``CHECKPOINT``. On PostgreSQL each mesh's
store has a backend of its own; where the server is local and this process
may, the steps that time the two meshes side by side run on one CPU with both
backends (``share_one_cpu``: a round trip to a backend on the client's CPU
took 24 µs here, to one on the other CPU 62 µs, and which backend is where is
chance — up to 30 % of a one-polygon transaction, to either mesh); the notes
say whether they could. In order:

edits          ``--edits`` committed transactions on each mesh, each one
               ``flip_edge`` of the diagonal of a random cell (distinct
               cells) and ``set_position`` of the cell's lower-left corner:
               a small transaction that updates rows (figure: its median with
               history vs without), and the revisions the views read.
views          on the meshes with history, the view ``mesh.at(r)`` at
               ``r = R − --recent`` and ``r = R − --edits`` (R: the revision
               after the edits; ``R − --edits`` is the import): ``at(r)``
               itself (floor: ``store.mesh(name)``), ``at(r).counts()`` with
               the view made in the call (floor: ``counts()`` of the current
               mesh; the median of ``--view-runs``), and for ``--reads``
               vertices ``vertex(i)``, its ``position`` and ``neighbors()``
               through the view (floor: the same reads of the current mesh;
               median per vertex, after an untimed pass of both). Half the
               vertices are corners of the cells edited after r (the view must
               give back their old rows), the rest random. A read through the
               view so slow that the loop would take over ``--view-budget``
               seconds is timed on fewer vertices (at least 3).
1-polygon txn  ``with store.transaction(): mesh.add_polygon([a, b, c])`` with
               a, b, c free (isolated) vertices added in an earlier, untimed
               transaction; and, as ``bench/edits.py`` times it, ``add_vertex``
               + ``add_polygon`` of a triangle on a free boundary half-edge
               (bottom row, each site extended round-robin). Commit included;
               the history and history=False meshes alternate call by call;
               median of ``--repeat`` (after ``--warmup``). Target (SPEC §9):
               ≤ 1.25× the history=False floor.
undo           one transaction of ``--edits`` edits (``set_position`` of a
               random vertex, ``flip_edge`` of a random cell's diagonal, a
               triangle with a new vertex on a free boundary half-edge of the
               top row, in turn), commit included, on each mesh (the
               history=False one first: the journaling floor, ≤ 1.25×
               applied), after an untimed run of the same transaction on
               each, rolled back; then ``mesh.undo()`` of it on the mesh with
               history (floor: the transaction itself; no target).
check          ``mesh.check()`` of the meshes with history after the undo.
import         ``store.import_arrays`` of the large grid with history and with
               ``history=False``, each run in a fresh process and a fresh
               database (``--import-runs`` runs of each, alternating; the
               faster run of each is the figure). Target (SPEC §9): ≤ 1.10×
               the history=False floor.

Two more tables put the view figures side by side: after ``--recent`` and
after ``--edits`` edits (proportional to the changes: the second should
cost more only where the reads scan history), and on the small and the large
grid (independent of the mesh: ≈ 1×). SPEC gives no number for them: the
ratios are printed without a verdict. The undo of both grids is compared the
same way.

Correctness gates (the exit status is non-zero only when one fails or a step
crashes, never on a slow figure): the stored counts are the grid's; each
edit makes exactly one revision on the mesh with history and none is kept
on the other (``history()`` empty, ``at(1)`` refused); every position and
neighbour set read through a view equals that of a plain-Python model of
the grid with the edits up to r, and every read of the current mesh that of
the model with all of them; ``at(r).counts()`` equals ``counts()``; after
the 1-polygon transactions the counts grew by their known change and
``at(r)`` of the revision before them gives the old counts; after ``undo()``
the counts, the positions and neighbour sets of every vertex the transaction
touched (and of random others) equal those before it, ``diff`` of the two
revisions is empty, and ``undo()`` on the history=False mesh is refused;
``check()`` is empty; each import stores the grid's counts and keeps one
revision (none with ``history=False``).

With ``--profile over`` (the default) a figure over its target is run once
more under cProfile (the profiler on during the timed calls only): the top
functions of the mesh with history are printed, and the functions whose time
grows most from the history=False mesh's profile; ``--profile all``
profiles every 1-polygon variant, the undo and the import.

Run alone or by ``bench/all.py`` (``tests/test_bench.py`` runs it with
``--quick``). This file keeps the workloads, the floors and the targets; the
harness (``bench/harness/``) parses the options, runs each step in a fresh
process on each backend and prints the report.
"""

from __future__ import annotations

import contextlib
import cProfile
import os
import pstats
import random
import time
from functools import partial

import hestore
from hestore import schema

from harness.bench import Bench
from harness.cli import Parser, at_least, cells, wants_profile
from harness.databases import open_store, pg_connect, settle, share_one_cpu, vacuum
from harness.profiling import Statements, profile_report
from harness.runner import one_shot
from harness.stats import fastest, median, percentile
from harness.tables import Figure, fmt_time, verdict
from harness.timing import gc_paused, maxrss, pc, time_each, timed
from workloads import Rollback, counts_text, grid_arrays, grid_counts, timed_check, triangles_label

QUICK = {"n": 30, "small": "12x12", "edits": 40, "recent": 5, "repeat": 10, "warmup": 3, "reads": 10,
         "view_runs": 2, "import_runs": 1, "profile": "off"}
TARGET_TXN = 1.25  # with history ÷ history=False, a one-polygon transaction (SPEC §9)
TARGET_IMPORT = 1.10  # with history ÷ history=False, a 1 M import (SPEC §9)
COUNTED = 20  # transactions of the untimed pass that counts hestore's statements
GRIDS = ("small", "large")
VARIANTS = {
    "free": "1-polygon txn: add_polygon of 3 free vertices",
    "boundary": "1-polygon txn: add_vertex + add_polygon on the boundary",
}
#: Change of (vertices, edges, polygons) per transaction of each variant.
DELTA = {"free": (0, 3, 1), "boundary": (1, 2, 1)}
ABOUT = """\
Gates: stored counts are the grid's; one revision per edit transaction with history, none kept without
(history() empty, at(1) and undo() refused); every read through a view equals the model of the grid with
the edits up to r, every read of the current mesh the model with all of them; at(r).counts() equals
counts(); the 1-polygon transactions change the counts by their known amount and at(r) before them gives
the old counts; after undo() the counts and every touched vertex's position and neighbours are as before,
diff() of the two revisions is empty; check() is empty; each import keeps one revision (none without)."""


def mesh_name(grid: str, history: bool) -> str:
    return f"{grid}_{'h' if history else 'n'}"


# ==========================================================================
# The grid and a plain-Python model of its edits


def cell_of(nx: int, c: int) -> tuple[int, int, int]:
    """Cell number ``c`` of a grid of ``nx`` vertices per row: (i, j, its lower-left vertex)."""
    i, j = c % (nx - 1), c // (nx - 1)
    return i, j, j * nx + i


def corners(nx: int, c: int) -> tuple[int, int, int, int]:
    _, _, v = cell_of(nx, c)
    return v, v + 1, v + nx, v + nx + 1


def diagonal(mesh, nx: int, c: int):
    """The diagonal edge of cell ``c``, either way round (a flip turns it)."""
    V = hestore.Vertex
    _, _, v = cell_of(nx, c)
    for a, b in ((v, v + nx + 1), (v + 1, v + nx)):
        h = mesh.find_halfedge(V(mesh, a), V(mesh, b))
        if h is not None and h.polygon is not None and h.twin.polygon is not None:
            return h.edge
    raise RuntimeError(f"cell {c} of mesh {mesh.name!r} has no diagonal")


def expected(nx: int, ny: int, cells: list[int], applied: int, u: int) -> tuple[tuple, list[int]]:
    """Vertex ``u``'s position and sorted neighbours once the first ``applied`` edits of the edits step are in.

    The grid's neighbours (row, column, and the diagonal ``v``–``v+nx+1`` of
    each cell), then each edited cell's diagonal turned to ``v+1``–``v+nx``;
    edit k moves the cell's lower-left corner to ``(i, j, 1 + k)``.
    """
    i, j = u % nx, u // nx
    nbrs = set()
    for di, dj in ((1, 0), (-1, 0), (0, 1), (0, -1), (1, 1), (-1, -1)):
        if 0 <= i + di < nx and 0 <= j + dj < ny:
            nbrs.add(u + di + dj * nx)
    pos = (float(i), float(j), 0.0)
    for k, c in enumerate(cells[:applied]):
        v = cell_of(nx, c)[2]
        a, b, x, y = v, v + nx + 1, v + 1, v + nx
        if u in (a, b):
            nbrs.discard(b if u == a else a)
        if u in (x, y):
            nbrs.add(y if u == x else x)
        if u == v:
            pos = (float(i), float(j), 1.0 + k)
    return pos, sorted(nbrs)


def read_position(mesh, i: int):
    """``vertex(i).position``: a point read of the view figures."""
    return mesh.vertex(i).position


def read_ring(mesh, i: int) -> list[int]:
    """The ids of vertex ``i``'s neighbours (``neighbors()`` of a handle made without a read): a one-ring."""
    return sorted(x.id for x in hestore.Vertex(mesh, i).neighbors())


#: The reads timed through a view: the function, and which part of `expected` it gives.
READS = {"position": (read_position, 0), "one-ring": (read_ring, 1)}


def read_vertex(mesh):
    """``vertex(i)``, its position and its neighbours' ids: one read of the view figures."""
    def read(i: int):
        v = mesh.vertex(i)
        return v.position, sorted(x.id for x in v.neighbors())
    return read


class Chains:
    """Free boundary half-edges to attach triangles to, round-robin: after ``[a, b, c]`` on ``a→b``, the
    site goes on from the new free half-edge ``a→c``."""

    def __init__(self, mesh, sites: list[tuple[int, int]]) -> None:
        V = hestore.Vertex
        self.sites = [(V(mesh, a), V(mesh, b)) for a, b in sites]
        self.k = 0

    def next(self):
        return self.sites[self.k % len(self.sites)]

    def advance(self, c) -> None:
        i = self.k % len(self.sites)
        self.sites[i] = (self.sites[i][0], c)
        self.k += 1


def bottom_sites(nx: int) -> list[tuple[int, int]]:
    """The bottom row's free half-edges ``(i+1) → i`` (the lower triangles hold ``i → i+1``)."""
    return [(i + 1, i) for i in range(nx - 1)]


def left_sites(nx: int, ny: int) -> list[tuple[int, int]]:
    """The left column's free half-edges ``j·nx → (j+1)·nx`` (the upper triangles hold the other way), the
    corners left out: where a profiled rerun attaches its triangles (the bottom row's sites are used up)."""
    return [(j * nx, (j + 1) * nx) for j in range(1, ny - 2)]


def top_sites(nx: int, ny: int) -> list[tuple[int, int]]:
    """The top row's free half-edges ``top+i → top+i+1`` (the upper triangles hold the other way)."""
    top = (ny - 1) * nx
    return [(top + i, top + i + 1) for i in range(nx - 1)]


def analyze_history(spec: dict) -> None:
    """On PostgreSQL, ``ANALYZE`` of the history tables and the revisions, as autovacuum soon does after the
    edits filled them; nothing on SQLite."""
    if spec["backend"] == "postgresql":
        with pg_connect(spec["url"], autocommit=True) as conn:
            for table in (*schema.HISTORY.values(), schema.revisions):
                conn.execute(f"ANALYZE {table.name}")


# ==========================================================================
# Child jobs (each runs in its own process)


@contextlib.contextmanager
def open_grid(spec: dict, grid: str, out: dict | None = None):
    """The stores of one grid's two meshes, ``{history: store}``, each on its own database, closed at the end.

    Side by side in one database, the mesh stored second would append at the right edge of every table and
    index, where SQLite splits pages more cheaply, and the first mesh's edits would pay for the splits in the
    middle: about 8 % of a one-polygon transaction that has nothing to do with history. Apart, the two meshes
    differ only in their history. On PostgreSQL each store has its own backend: for a step that times the two
    meshes side by side (``out`` given), `share_one_cpu` puts both on this process's CPU, and
    ``out["placement"]`` says whether it could.
    """
    with contextlib.ExitStack() as stack:
        stores = {flag: stack.enter_context(open_store(spec["dbs"][mesh_name(grid, flag)])) for flag in (True, False)}
        placement = share_one_cpu(spec) if out is not None else None
        if placement:
            out["placement"] = placement
        yield stores


def job_setup(spec: dict) -> dict:
    """Store each grid twice, with and without history (untimed); VACUUM (ANALYZE) on PostgreSQL."""
    problems, seconds = [], {}
    for grid in GRIDS:
        with open_grid(spec, grid) as stores:
            nx, ny = spec["dims"][grid]
            positions, faces = grid_arrays(nx, ny)
            want = grid_counts(nx, ny)
            for flag in (True, False):
                t0 = time.perf_counter()
                mesh = stores[flag].import_arrays(mesh_name(grid, flag), positions, faces, history=flag).mesh
                seconds[mesh_name(grid, flag)] = time.perf_counter() - t0
                c = mesh.counts()
                if (c.vertices, c.edges, c.polygons) != want:
                    problems.append(f"{mesh.name}: stored counts {c}, not V, E, F = {want}")
                if mesh.revision != 1:
                    problems.append(f"{mesh.name}: at revision {mesh.revision} after its import, not 1")
        for flag in (True, False):
            vacuum(spec["dbs"][mesh_name(grid, flag)])
    return {"seconds": seconds, "problems": problems, "rss": maxrss()}


def job_edits(spec: dict) -> dict:
    """``--edits`` committed flip_edge + set_position transactions on each mesh, the two alternating."""
    rng = random.Random(spec["seed"])
    out: dict = {"problems": []}
    problems = out["problems"]
    for grid in GRIDS:
        with open_grid(spec, grid, out) as stores:
            nx, ny = spec["dims"][grid]
            cells = rng.sample(range((nx - 1) * (ny - 1)), spec["edits"])
            meshes = {flag: stores[flag].mesh(mesh_name(grid, flag)) for flag in (True, False)}
            # Handles read before the timed region (a read inside a block writes its pending changes first).
            plans = {flag: [(diagonal(m, nx, c), hestore.Vertex(m, cell_of(nx, c)[2])) for c in cells]
                     for flag, m in meshes.items()}
            r0 = meshes[True].revision
            samples: dict = {True: [], False: []}
            settle(spec)
            with gc_paused():  # for the whole loop: a collection per transaction would dominate
                for k, c in enumerate(cells):
                    i, j, _ = cell_of(nx, c)
                    pos = (float(i), float(j), 1.0 + k)
                    for flag in (True, False) if k % 2 == 0 else (False, True):
                        mesh, (e, v) = meshes[flag], plans[flag][k]
                        t0 = pc()
                        with stores[flag].transaction():
                            mesh.flip_edge(e)
                            mesh.set_position(v, pos)
                        samples[flag].append(pc() - t0)
            r1 = meshes[True].revision
            if r1 - r0 != len(cells):
                problems.append(f"{grid}: {len(cells)} edit transactions made {r1 - r0} revisions, not one each")
            newest = [x.number for x in meshes[True].history(limit=2)]  # the whole list would diff every revision
            if newest != [r1, r1 - 1]:
                problems.append(f"{grid}: the newest revisions kept are {newest}, not {[r1, r1 - 1]}")
            if meshes[False].history():
                problems.append(f"{grid}: the history=False mesh kept revisions")
            out[grid] = {"cells": cells, "r0": r0, "revision": r1, "h": samples[True], "n": samples[False]}
    out["rss"] = maxrss()
    return out


def job_views(spec: dict) -> dict:
    """``at(r)`` after ``--recent`` and after ``--edits`` edits: the view, counts(), positions, one-rings."""
    rng = random.Random(spec["seed"] + 1)
    out: dict = {"problems": []}
    problems = out["problems"]
    for grid in GRIDS:
        nx, ny = spec["dims"][grid]
        cells, rend = spec["cells"][grid], spec["revision"][grid]
        analyze_history(spec["dbs"][mesh_name(grid, True)])
        with open_grid(spec, grid) as stores:
            store = stores[True]
            name = mesh_name(grid, True)
            mesh = store.mesh(name)
            if mesh.revision != rend:
                problems.append(f"{grid}: at revision {mesh.revision}, not {rend} as after the edits")
            try:
                stores[False].mesh(mesh_name(grid, False)).at(1)
                problems.append(f"{grid}: at(1) of the history=False mesh did not raise")
            except hestore.RevisionNotFoundError:
                pass
            for since in spec["since"]:
                r = rend - since
                applied = len(cells) - since
                touched = {u for c in cells[applied:] for u in corners(nx, c)}
                ids = rng.sample(sorted(touched), min(len(touched), spec["reads"] // 2))
                chosen = set(ids)
                while len(ids) < spec["reads"]:
                    u = rng.randrange(nx * ny)
                    if u not in chosen:
                        chosen.add(u)
                        ids.append(u)
                rng.shuffle(ids)
                view = mesh.at(r)
                res: dict = {"revision": r, "touched": sum(1 for i in ids if i in touched)}
                # The view itself, and its floor: a handle on the current mesh.
                settle(spec)
                res["make"] = time_each(lambda _, r=r, m=mesh: m.at(r), range(spec["repeat"])).samples
                res["make_floor"] = time_each(lambda _, n=name, s=store: s.mesh(n), range(spec["repeat"])).samples
                # counts(), the view made in the call; the current mesh's in turn.
                now_s, past_s, now_c, past_c = [], [], [], []
                with gc_paused():
                    for _ in range(spec["view_runs"]):
                        t0 = pc()
                        now_c.append(mesh.counts())
                        t1 = pc()
                        past_c.append(mesh.at(r).counts())
                        t2 = pc()
                        now_s.append(t1 - t0)
                        past_s.append(t2 - t1)
                res["counts"], res["counts_floor"] = past_s, now_s
                if any(p != now_c[0] for p in past_c + now_c):
                    problems.append(f"{grid}, r = R − {since}: at(r).counts() {past_c[0]} differs from counts() "
                                    f"{now_c[0]} (flips and moves keep the counts)")
                # Positions and one-rings: each loop timed call by call, the current mesh first.
                want_past = {i: expected(nx, ny, cells, applied, i) for i in ids}
                want_now = {i: expected(nx, ny, cells, len(cells), i) for i in ids}
                bad = []
                for kind, (read, part) in READS.items():
                    past_read, now_read = partial(read, view), partial(read, mesh)
                    # An untimed call of each first; a slow view read is timed on fewer vertices (--view-budget).
                    t0 = pc()
                    past_read(ids[0])
                    probe = (pc() - t0) / 1e9
                    now_read(ids[0])
                    n = len(ids) if probe * len(ids) <= spec["budget"] else max(3, int(spec["budget"] / probe))
                    some = ids[:n]
                    if n == len(ids):
                        for i in some:
                            now_read(i)
                            past_read(i)
                    floor = time_each(now_read, some)
                    past = time_each(past_read, some)
                    for i, got in zip(some, past.results):
                        if got != want_past[i][part]:
                            bad.append(f"{kind} of vertex {i} through at({r}): {got}, expected {want_past[i][part]}")
                    for i, got in zip(some, floor.results):
                        if got != want_now[i][part]:
                            bad.append(f"{kind} of vertex {i} now: {got}, expected {want_now[i][part]}")
                    res[kind] = {"samples": past.samples, "cpu": past.cpu, "floor": floor.samples,
                                 "probe": probe, "cut": n < len(ids)}
                if bad:
                    problems.append(f"{grid}, r = R − {since}: {len(bad)} read(s) differ from the model, "
                                    f"e.g. {bad[:2]}")
                out[f"{grid}/{since}"] = res
    out["rss"] = maxrss()
    return out


def job_txn1(spec: dict) -> dict:
    """One-polygon transactions, the mesh with history and the one without alternating call by call."""
    out: dict = {"problems": []}
    problems = out["problems"]
    warmup, repeat = spec["warmup"], spec["repeat"]
    counted = min(COUNTED, repeat)
    calls = warmup + repeat + counted  # the last ones: the untimed pass that counts statements
    # Under --profile: one profiler for each mesh, so that the difference can be shown function by function.
    profilers = {True: cProfile.Profile(), False: cProfile.Profile()} if spec.get("profile") else None
    for grid in spec.get("grids", GRIDS):
        with open_grid(spec, grid, out) as stores:
            nx, ny = spec["dims"][grid]
            meshes = {flag: stores[flag].mesh(mesh_name(grid, flag)) for flag in (True, False)}
            for variant in spec.get("variants", VARIANTS):
                if variant == "free":
                    # Isolated vertices, committed before (untimed): each call joins three of them.
                    triples = {}
                    for flag, m in meshes.items():
                        with stores[flag].transaction():
                            vs = [m.add_vertex((float(k // 3), -2.0 - k % 3, 0.0)) for k in range(3 * calls)]
                        triples[flag] = [vs[3 * k:3 * k + 3] for k in range(calls)]

                    def call(flag: bool, k: int, meshes=meshes, triples=triples) -> None:
                        with stores[flag].transaction():
                            meshes[flag].add_polygon(triples[flag][k])
                else:
                    sites = left_sites(nx, ny) if spec.get("profile") else bottom_sites(nx)
                    chains = {flag: Chains(m, sites) for flag, m in meshes.items()}

                    def call(flag: bool, k: int, meshes=meshes, chains=chains) -> None:
                        m, chain = meshes[flag], chains[flag]
                        a, b = chain.next()
                        with stores[flag].transaction():
                            c = m.add_vertex((float(k), -1.0, 0.5))
                            m.add_polygon([a, b, c])
                        chain.advance(c)

                before = {flag: m.counts() for flag, m in meshes.items()}
                r0 = meshes[True].revision
                samples: dict = {True: [], False: []}
                counters = {True: Statements(), False: Statements()}
                settle(spec)
                with gc_paused():
                    for k in range(calls):
                        for flag in (True, False) if k % 2 == 0 else (False, True):
                            if k >= warmup + repeat:
                                with stores[flag].session.traced(counters[flag]):
                                    call(flag, k)
                                continue
                            prof = profilers[flag] if profilers and k >= warmup else None
                            t0 = pc()
                            if prof:
                                prof.enable()
                            call(flag, k)
                            if prof:
                                prof.disable()
                            samples[flag].append(pc() - t0)
                dv, de, dp = DELTA[variant]
                for flag, m in meshes.items():
                    b, got = before[flag], m.counts()
                    want = (b.vertices + calls * dv, b.edges + calls * de, b.polygons + calls * dp)
                    if (got.vertices, got.edges, got.polygons) != want:
                        problems.append(f"{m.name} {variant}: counts {got} after {calls} transactions, not "
                                        f"V, E, F = {want}")
                if meshes[True].revision != r0 + calls:
                    problems.append(f"{grid} {variant}: {calls} transactions made {meshes[True].revision - r0} "
                                    "revisions")
                if meshes[True].at(r0).counts() != before[True]:
                    problems.append(f"{grid} {variant}: at({r0}).counts() is not the counts before the transactions")
                if meshes[False].history():
                    problems.append(f"{grid} {variant}: the history=False mesh kept revisions")
                out[f"{grid}/{variant}"] = {
                    "h": samples[True][warmup:], "n": samples[False][warmup:],
                    "statements": {("h" if flag else "n"): {k: v / counted for k, v in c.by_kind.items()}
                                   for flag, c in counters.items()},
                }
    out["rss"] = maxrss()
    if profilers:
        out["profile"] = profile_report(profilers[True])
        out["difference"] = profile_difference(profilers[True], profilers[False], repeat)
    return out


def job_undo(spec: dict) -> dict:
    """A ``--edits``-edit transaction on each mesh of each grid, then ``undo()`` of it on the one with history."""
    rng = random.Random(spec["seed"] + 2)
    out: dict = {"problems": []}
    problems = out["problems"]
    for grid in spec.get("grids", GRIDS):
        with open_grid(spec, grid, out) as stores:
            nx, ny = spec["dims"][grid]
            n_edits = spec["edits"]
            kinds = ["position", "flip", "add"]
            plan = [kinds[k % 3] for k in range(n_edits)]
            cells = rng.sample(range((nx - 1) * (ny - 1)), plan.count("flip"))
            moved = [rng.randrange(nx * ny) for _ in range(plan.count("position"))]
            meshes = {flag: stores[flag].mesh(mesh_name(grid, flag)) for flag in (True, False)}
            edges = {flag: [diagonal(m, nx, c) for c in cells] for flag, m in meshes.items()}
            # What the gate compares: every vertex the transaction touches, and as many random ones.
            sample = set(moved) | {u for c in cells for u in corners(nx, c)}
            sample |= {u for site in top_sites(nx, ny)[: plan.count("add")] for u in site}
            sample |= {rng.randrange(nx * ny) for _ in range(len(sample))}
            sample = sorted(sample)
            h = meshes[True]
            before = [read_vertex(h)(i) for i in sample]
            counts0 = h.counts()
            r0 = h.revision

            result = {}
            sites = top_sites(nx, ny)
            for flag in (False, True):  # warm-up: the same transaction on each mesh, rolled back
                many_edits(stores[flag], meshes[flag], plan, edges[flag], moved, sites, ny, commit=False)
            for flag in (False, True):
                settle(spec)
                with gc_paused():
                    t = timed(partial(many_edits, stores[flag], meshes[flag], plan, edges[flag], moved, sites, ny))
                result["h" if flag else "n"] = {"seconds": t.seconds, "cpu": t.cpu}
            if h.revision != r0 + 1:
                problems.append(f"{grid}: the {n_edits}-edit transaction made {h.revision - r0} revisions, not 1")
            counts1 = h.counts()
            settle(spec)
            with gc_paused():
                t = timed(h.undo)
            result["undo"] = {"seconds": t.seconds, "cpu": t.cpu, "rss": maxrss(), "revision": t.result}
            # The gates.
            after = [read_vertex(h)(i) for i in sample]
            bad = [f"vertex {i}: {a} after undo, {b} before" for i, a, b in zip(sample, after, before) if a != b]
            if bad:
                problems.append(f"{grid}: {len(bad)} of {len(sample)} vertices differ after undo(), e.g. {bad[:2]}")
            if h.counts() != counts0:
                problems.append(f"{grid}: counts {h.counts()} after undo(), {counts0} before the transaction")
            if t.result != r0 + 2 or h.revision != r0 + 2:
                problems.append(f"{grid}: undo() made revision {t.result}, the mesh is at {h.revision}; "
                                f"expected {r0 + 2}")
            top = h.history(limit=1)
            if not top or top[0].message != f"undo of revision {r0 + 1}":
                problems.append(f"{grid}: the newest revision is {top[:1]}, not the undo of revision {r0 + 1}")
            if h.diff(r0, r0 + 2):
                problems.append(f"{grid}: diff({r0}, {r0 + 2}) is not empty after the undo: "
                                f"{h.diff(r0, r0 + 2).counts()}")
            try:
                meshes[False].undo()
                problems.append(f"{grid}: undo() on the history=False mesh did not raise")
            except hestore.RevisionNotFoundError:
                pass
            if spec.get("profile"):
                # The same transaction once more (it applies again: the undo freed its sites), and its undo under
                # cProfile: the figure above ran without the profiler.
                many_edits(stores[True], h, plan, edges[True], moved, sites, ny)
                settle(spec)
                p = timed(h.undo, profile=True)
                result["profile"] = (p.profile, p.dominant, p.seconds)
                if h.counts() != counts0:
                    problems.append(f"{grid}: counts {h.counts()} after the profiled undo(), {counts0} before")
            result.update(sampled=len(sample), changed=[counts1.vertices - counts0.vertices,
                                                        counts1.edges - counts0.edges,
                                                        counts1.polygons - counts0.polygons])
            out[grid] = result
    out["rss"] = maxrss()
    return out


def many_edits(store, mesh, plan: list[str], flips: list, moved: list[int], sites: list, ny: int,
               commit: bool = True) -> None:
    """One transaction of the undo step's edits, in turn: set_position, flip_edge, a triangle on the top row
    (rolled back at its end unless ``commit``)."""
    V = hestore.Vertex
    flips, moves, chain = iter(flips), iter(moved), Chains(mesh, sites)
    try:
        with store.transaction(message=f"{len(plan)} edits"):
            for k, kind in enumerate(plan):
                if kind == "position":
                    mesh.set_position(V(mesh, next(moves)), (0.5, 0.5, float(k)))
                elif kind == "flip":
                    mesh.flip_edge(next(flips))
                else:
                    a, b = chain.next()
                    c = mesh.add_vertex((float(k), float(ny), 0.5))
                    mesh.add_polygon([a, b, c])
                    chain.advance(c)
            if not commit:
                raise Rollback
    except Rollback:
        pass


def job_check(spec: dict) -> dict:
    out = {}
    for grid in GRIDS:
        with open_grid(spec, grid) as stores:
            out[grid] = timed_check(stores[True], mesh_name(grid, True))
    return out


def job_import(spec: dict) -> dict:
    """``import_arrays`` of the large grid into a fresh database, with or without history."""
    nx, ny = spec["dims"]["large"]
    positions, faces = grid_arrays(nx, ny)  # the arrays a user already has
    with open_store(spec) as store:
        report, out = one_shot(spec, lambda: store.import_arrays("grid", positions, faces, history=spec["history"]),
                               profile=spec.get("profile", False))
        c = report.mesh.counts()
        kept = len(report.mesh.history())
    problems = []
    want = grid_counts(nx, ny)
    if (c.vertices, c.edges, c.polygons) != want:
        problems.append(f"import: counts {c}, not V, E, F = {want}")
    if kept != (1 if spec["history"] else 0):
        problems.append(f"import with history={spec['history']}: {kept} revision(s) kept")
    return dict(out, problems=problems)


def profile_difference(with_history: cProfile.Profile, without: cProfile.Profile, calls: int, top: int = 8) -> str:
    """Where the extra time goes: the functions whose own time grows most from the history=False profile to the
    history one (the driver's ``execute`` and ``executemany`` are where the SQL runs), per call of each."""

    def own(profiler: cProfile.Profile) -> dict:
        return {(f"{func} ({os.path.basename(file)}:{line})" if line else func): row[2]
                for (file, line, func), row in pstats.Stats(profiler).stats.items()}

    h, n = own(with_history), own(without)
    grown = sorted(((t - n.get(k, 0.0), k) for k, t in h.items()), reverse=True)[:top]
    rows = ", ".join(f"{k} +{fmt_time(d / calls)}" for d, k in grown if d > 0)
    return (f"with the profiler on, {fmt_time(sum(h.values()) / calls)} per transaction with history, "
            f"{fmt_time(sum(n.values()) / calls)} without; own time that grew most, per transaction: {rows}")


JOBS = {"setup": job_setup, "edits": job_edits, "views": job_views, "txn1": job_txn1, "undo": job_undo,
        "check": job_check, "import": job_import}


# ==========================================================================
# The parent


def main(argv=None) -> int:
    ap = Parser(__doc__, quick=QUICK, grid=710, jobs=JOBS, profile=True, seed=20240601)
    ap.add_argument("--small", type=cells, default="50x100",
                    help="cells of the small grid, WxH (default 50x100: 10,000 triangles)")
    ap.add_argument("--edits", type=int, default=1000,
                    help="edit transactions before the views, and edits in the transaction undone (default 1000)")
    ap.add_argument("--recent", type=at_least(1), default=10, help="the other view: this many edits back (default 10)")
    ap.add_argument("--repeat", type=at_least(1), default=200,
                    help="timed 1-polygon transactions per variant (default 200)")
    ap.add_argument("--warmup", type=at_least(0), default=20, help="untimed ones before them (default 20)")
    ap.add_argument("--reads", type=at_least(1), default=100, help="vertices read through each view (default 100)")
    ap.add_argument("--view-runs", type=at_least(1), default=5,
                    help="counts() of each view and of the mesh (default 5)")
    ap.add_argument("--view-budget", type=float, default=30,
                    help="seconds a timed loop of reads through a view may take: a slower read is timed on fewer "
                         "vertices, at least 3 (default 30)")
    ap.add_argument("--import-runs", type=at_least(1), default=2,
                    help="imports with and without history, each a fresh process (default 2 of each)")
    args = ap.parse_args(argv)
    sw, sh = args.small
    dims = {"small": (sw + 1, sh + 1), "large": (args.n, args.n)}
    if not args.recent < args.edits <= min((nx - 1) * (ny - 1) for nx, ny in dims.values()):
        ap.error(f"--edits must be above --recent and at most the number of cells of the smaller grid ({sw * sh})")

    runs: dict = {}  # (backend, step) -> result
    imports: dict = {}  # (backend, history) -> [results]
    with Bench(args, "history", __file__) as bench:
        for place in bench.for_each_backend():
            run_steps(bench, place, dims, runs)
            run_imports(bench, place, dims, imports)
    report(bench, dims, runs, imports)
    return bench.finish()


def run_steps(bench: Bench, place, dims: dict, runs: dict) -> None:
    """Every step on the four meshes of one backend, in order: setup, edits, views, 1-polygon transactions, the
    big transaction and its undo, check()."""
    args, run, bname = bench.args, bench.runner.run, place.backend
    # Each mesh in a database of its own (see open_grid).
    dbs = {mesh_name(grid, flag): place.fresh(f"history_{mesh_name(grid, flag)}")
           for grid in GRIDS for flag in (True, False)}
    spec = dict(backend=bname, db_url=place.db_url, dbs=dbs, dims=dims, seed=args.seed)
    setup = runs[(bname, "setup")] = run(job="setup", what="store both grids twice", **spec)
    if setup is not None:
        edits = runs[(bname, "edits")] = run(job="edits", edits=args.edits,
                                             what=f"{args.edits} edit transactions per mesh", **spec)
        if edits is not None:
            runs[(bname, "views")] = run(job="views", since=[args.recent, args.edits], reads=args.reads,
                                         repeat=args.repeat, budget=args.view_budget, view_runs=args.view_runs,
                                         cells={g: edits[g]["cells"] for g in GRIDS},
                                         revision={g: edits[g]["revision"] for g in GRIDS}, what="views at(r)",
                                         **spec)
        common = dict(spec, repeat=args.repeat, warmup=args.warmup)
        txn = runs[(bname, "txn1")] = run(job="txn1", what="1-polygon transactions", **common)
        profile_txn1(bench, common, bname, txn)
        undo = runs[(bname, "undo")] = run(job="undo", edits=args.edits, profile=args.profile == "all",
                                           what=f"{args.edits}-edit transaction and undo()", **spec)
        for grid in GRIDS if undo is not None else ():
            if undo[grid].get("profile"):
                text, dominant, seconds = undo[grid]["profile"]
                bench.report.profiles.append((f"{bname}, {triangles_label(*dims[grid])} triangles: undo() of the "
                                              f"{args.edits}-edit transaction, made again, under cProfile "
                                              f"({seconds:.2f} s with the profiler on; --profile all)", dominant, text))
        runs[(bname, "check")] = run(job="check", what="check() after undo()", **spec)
    for db in dbs.values():
        place.drop(db)


def run_imports(bench: Bench, place, dims: dict, imports: dict) -> None:
    """The imports of the large grid with and without history, alternating, each into a fresh database; the one
    with history under cProfile when it is over its target."""
    args, bname = bench.args, place.backend
    for k in range(args.import_runs):
        for flag in (False, True) if k % 2 == 0 else (True, False):
            imp = place.fresh(f"import_{k}_{'h' if flag else 'n'}")
            imports.setdefault((bname, flag), []).append(bench.runner.run(
                job="import", history=flag, dims=dims, what=f"import, history={flag}", **imp))
            place.drop(imp)
    if args.profile == "off":
        return
    h, n = (fastest(imports.get((bname, flag))) for flag in (True, False))
    if not h or not n:
        return
    ratio = h["seconds"] / n["seconds"]
    if wants_profile(args, ratio > TARGET_IMPORT):
        imp = place.fresh("import_profile")
        prof = bench.runner.run(job="import", history=True, dims=dims, profile=True, what="import under cProfile",
                                **imp)
        place.drop(imp)
        if prof and prof.get("profile"):
            bench.report.profiles.append((f"{bname}, {triangles_label(*dims['large'])} triangles: import_arrays with "
                                          f"history under cProfile ({prof['seconds']:.2f} s with the profiler on; "
                                          f"{ratio:.2f}× the history=False floor without it)", prof["dominant"],
                                          prof["profile"]))


def profile_txn1(bench: Bench, common: dict, bname: str, txn: dict | None) -> None:
    """A 1-polygon variant over its target (or every one, with ``--profile all``): once more under cProfile."""
    args = bench.args
    if args.profile == "off" or not txn:
        return
    for grid in GRIDS:
        for variant in VARIANTS:
            r = txn.get(f"{grid}/{variant}")
            if not r or not r["h"]:
                continue
            ratio = median(r["h"]) / median(r["n"])
            if wants_profile(args, ratio > TARGET_TXN):
                prof = bench.runner.run(job="txn1", grids=[grid], variants=[variant], profile=True,
                                        what=f"{variant} 1-polygon transactions on the {grid} grid", **common)
                if prof and prof.get("profile"):
                    text, dominant = prof["profile"]
                    label = triangles_label(*common["dims"][grid])
                    bench.report.profiles.append((
                        f"{bname}, {label} triangles: {VARIANTS[variant]} with history under cProfile ({ratio:.2f}× "
                        f"the history=False floor without the profiler; {args.repeat} transactions of each mesh "
                        f"profiled, after {args.warmup}). Difference from history=False: {prof['difference']}",
                        dominant, text))


# ==========================================================================
# Figures


def _journal(name: str, bname: str, samples: dict, target: str, label: str, rss: int | None) -> Figure:
    """A figure timed on both meshes call by call: the mesh with history beside the history=False floor."""
    t, f = median(samples["h"]) / 1e9, median(samples["n"]) / 1e9
    return Figure.of_calls(name, bname, samples["h"], floor=f, target=target, verdict=verdict(t <= TARGET_TXN * f),
                           mesh=label, rss=rss, floor_parts=f"the same, history=False: median {fmt_time(f)}, "
                                                            f"p90 {fmt_time(percentile(samples['n'], 0.9) / 1e9)}")


def journal_figures(args, dims, runs, imports, process: str) -> list[Figure]:
    """History vs history=False: the 1-polygon transactions, the edit transactions, the big one, the import."""
    out = []
    for bname in args.backends:
        txn = runs.get((bname, "txn1")) or {}
        edits = runs.get((bname, "edits")) or {}
        undo = runs.get((bname, "undo")) or {}
        for grid in ("large", "small"):
            label = triangles_label(*dims[grid])
            for variant, name in VARIANTS.items():
                r = txn.get(f"{grid}/{variant}")
                if r and r["h"]:
                    out.append(_journal(name, bname, r, f"≤ {TARGET_TXN:.2f}× floor", label, txn.get("rss")))
            r = edits.get(grid)
            if r and r["h"]:
                out.append(_journal("edit txn: flip_edge + set_position", bname, r,
                                    f"≤ {TARGET_TXN:.2f}× floor (applied)", label, edits.get("rss")))
            r = undo.get(grid)
            if r:
                t, f = r["h"]["seconds"], r["n"]["seconds"]
                out.append(Figure(f"{args.edits:,}-edit txn, commit included", bname, t, f,
                                  f"≤ {TARGET_TXN:.2f}× floor (applied)", verdict(t <= TARGET_TXN * f), label,
                                  cpu=r["h"]["cpu"],
                                  floor_parts=f"the same, history=False: {f:.3f} (its CPU {r['n']['cpu']:.3f})"))
        h, n = fastest(imports.get((bname, True))), fastest(imports.get((bname, False)))
        if h:
            f = n["seconds"] if n else None
            parts = "missing"
            if n:
                runs_n = ", ".join(f"{x['seconds']:.2f}" for x in imports[(bname, False)] if x)
                parts = f"import_arrays, history=False, {process} and fresh database: fastest of {runs_n}"
            out.append(Figure("import_arrays of the grid", bname, h["seconds"], f, f"≤ {TARGET_IMPORT:.2f}× floor",
                              verdict(None if f is None else h["seconds"] <= TARGET_IMPORT * f),
                              triangles_label(*dims["large"]), n=len([x for x in imports[(bname, True)] if x]),
                              cpu=h["cpu"], rss=h["rss"], floor_parts=parts))
    return out


VIEW_KINDS = {
    "make": ("mesh.at(r)", "store.mesh(name)"),
    "counts": ("at(r).counts(), view made in the call", "counts() of the current mesh"),
    "position": ("vertex(i).position via at(r)", "the same read of the current mesh"),
    "one-ring": ("vertex(i).neighbors() via at(r)", "the same read of the current mesh"),
}


def view_figures(args, dims, runs) -> list[Figure]:
    out = []
    for bname in args.backends:
        views = runs.get((bname, "views")) or {}
        for grid in ("large", "small"):
            label = triangles_label(*dims[grid])
            for since in (args.recent, args.edits):
                r = views.get(f"{grid}/{since}")
                if not r:
                    continue
                for kind, (name, what) in VIEW_KINDS.items():
                    if kind in ("make", "counts"):
                        s, fs, cpu = r[kind], r[f"{kind}_floor"], None
                    else:
                        s, fs, cpu = r[kind]["samples"], r[kind]["floor"], r[kind]["cpu"] / len(r[kind]["samples"])
                    f = median(fs) / 1e9
                    out.append(Figure.of_calls(f"{name}, r = R − {since:,}", bname, s, p90=len(s) >= 10, floor=f,
                                               mesh=label, cpu=cpu, rss=views.get("rss"),
                                               floor_parts=f"{what}: median {fmt_time(f)} of {len(fs)}"))
    return out


def undo_figures(args, dims, runs) -> list[Figure]:
    out = []
    for bname in args.backends:
        undo = runs.get((bname, "undo")) or {}
        for grid in ("large", "small"):
            r = undo.get(grid)
            if not r:
                continue
            u = r["undo"]
            out.append(Figure(f"undo() of the {args.edits:,}-edit txn", bname, u["seconds"], r["h"]["seconds"], "—",
                              verdict(None), triangles_label(*dims[grid]), cpu=u["cpu"], rss=u["rss"],
                              floor_parts=f"the {args.edits:,}-edit transaction itself, with history, commit included"))
    return out


def gates(bench: Bench, dims: dict, runs: dict, imports: dict) -> None:
    """The steps' problems (their gates failed), and the notes on what each step did."""
    args, rep = bench.args, bench.report
    placements: dict = {}  # backend -> {what share_one_cpu said: [steps]}
    for (bname, step), r in runs.items():
        if r is None:
            continue
        if step == "check":
            for grid, c in r.items():
                rep.notes.append(f"{bname} {triangles_label(*dims[grid])}: check() after undo() {c['seconds']:.2f} s, "
                                 f"{c['violations']} violation(s); counts {counts_text(c['counts'])}")
                if c["violations"]:
                    rep.problems.append(f"{bname} {grid}: check() found {c['violations']} violations, "
                                        f"e.g. {c['examples']}")
            continue
        rep.problems.extend(f"{bname} {step}: {p}" for p in r.get("problems", []))
        if step == "setup":
            rep.notes.append(f"{bname}: stored " + ", ".join(f"{name} in {s:.1f} s" for name, s in r["seconds"].items())
                             + " (import_arrays, untimed setup)")
        if r.get("placement"):
            placements.setdefault(bname, {}).setdefault(r["placement"], []).append(step)
        if step == "edits":
            for grid in GRIDS:
                e = r[grid]
                rep.notes.append(f"{bname} {triangles_label(*dims[grid])}: {len(e['cells']):,} edit transactions took "
                                 f"the mesh with history from revision {e['r0']} to {e['revision']}")
        if step == "views":
            for grid in GRIDS:
                for since in (args.recent, args.edits):
                    v = r.get(f"{grid}/{since}")
                    if not v:
                        continue
                    cut = "".join(f"; {kind} through the view timed on {len(v[kind]['samples'])} of them (the first "
                                  f"call took {v[kind]['probe']:.2f} s; --view-budget {args.view_budget:g} s)"
                                  for kind in ("position", "one-ring") if v[kind]["cut"])
                    rep.notes.append(f"{bname} {triangles_label(*dims[grid])}: at({v['revision']}) (R − {since:,}): "
                                     f"{args.reads} vertices chosen, {v['touched']} of them corners of cells edited "
                                     f"since{cut}")
        if step == "undo":
            for grid in GRIDS:
                u = r.get(grid)
                if u:
                    dv, de, dp = u["changed"]
                    rep.notes.append(f"{bname} {triangles_label(*dims[grid])}: the {args.edits:,}-edit transaction "
                                     f"changed V/E/F by {dv:+,}/{de:+,}/{dp:+,}; undo() made revision "
                                     f"{u['undo']['revision']}; {u['sampled']:,} vertices compared before and after")
    for bname, steps in placements.items():
        for placement, names in steps.items():
            rep.notes.append(f"{bname}: {', '.join(names)}: {placement}")
    for (bname, flag), results in imports.items():
        for r in results:
            if r:
                rep.problems.extend(f"{bname} import: {p}" for p in r["problems"])
        secs = ", ".join(f"{r['seconds']:.2f} s" for r in results if r)
        rep.notes.append(f"{bname}: import_arrays of the large grid, history={flag}: {secs} ({bench.runner.process} "
                         "and fresh database each; peak RSS "
                         + ", ".join(f"{r['rss'] / 2**20:,.0f} MiB" for r in results if r) + ")")


def proportional_rows(args, dims, views: list[Figure]) -> list[list[str]]:
    """Each view figure --recent and --edits edits back, side by side."""
    rows = []
    for bname in args.backends:
        for grid in ("large", "small"):
            label = triangles_label(*dims[grid])
            for kind, _ in VIEW_KINDS.values():
                pair = [next((f for f in views if f.backend == bname and f.mesh == label
                              and f.name == f"{kind}, r = R − {s:,}"), None) for s in (args.recent, args.edits)]
                if None in pair:
                    continue
                a, b = pair
                rows.append([bname, label, kind, fmt_time(a.time), f"{a.ratio:.2f}×",
                             fmt_time(b.time), f"{b.ratio:.2f}×", f"{b.time / a.time:.2f}×"])
    return rows


def mesh_size_rows(args, small: str, large: str, figures: list[Figure]) -> list[list[str]]:
    """Each figure on the small grid beside the large one."""
    rows = []
    for bname in args.backends:
        names = dict.fromkeys(f.name for f in figures if f.backend == bname)
        for name in names:
            pair = [next((f for f in figures if f.backend == bname and f.name == name and f.mesh == m), None)
                    for m in (small, large)]
            if None in pair:
                continue
            a, b = pair
            rows.append([bname, name, fmt_time(a.time), fmt_time(b.time), f"{b.time / a.time:.2f}×",
                         "—" if a.ratio is None else f"{a.ratio:.2f}×", "—" if b.ratio is None else f"{b.ratio:.2f}×"])
    return rows


def statement_rows(args, runs) -> list[list[str]]:
    """The statements per 1-polygon transaction on the large grid, with and without history."""
    rows = []
    for bname in args.backends:
        txn = runs.get((bname, "txn1")) or {}
        for variant, name in VARIANTS.items():
            r = txn.get(f"large/{variant}")
            if not r:
                continue
            for who, label in (("h", "history"), ("n", "history=False")):
                rows.append([bname, name, label, Statements.per(r["statements"][who], unit="")])
    return rows


def report(bench: Bench, dims: dict, runs: dict, imports: dict) -> None:
    args, rep = bench.args, bench.report
    gates(bench, dims, runs, imports)
    views = view_figures(args, dims, runs)
    undos = undo_figures(args, dims, runs)
    rep.title(f"hestore history benchmark — seed {args.seed}; {args.repeat} timed 1-polygon transactions per variant "
              f"(after {args.warmup} untimed), {args.edits:,} edits, views {args.recent} and {args.edits:,} edits back")
    rep.figures(journal_figures(args, dims, runs, imports, bench.runner.process), caption=f"""\
Journaling: each figure on the mesh with history, its floor the same work on the mesh created with
history=False, each in a database of its own (time: the median of the n transactions, with and without
history alternating call by call; the big transaction one run each; the import the fastest of n runs,
each in a {bench.runner.process} and fresh database; mesh: triangles; target = SPEC §9, applied where
marked):""")
    rep.figures(views, caption="""\
Reading the past: mesh.at(r) of the mesh with history, R its revision after the edits (time: the median
of the n calls — per vertex for the reads, after an untimed pass of both; its CPU: the reads' mean CPU
per vertex in the measuring process; floor: the same read of the current mesh, same run; no SPEC number):""")
    rep.figures(undos, caption=f"""\
Undo: one run of mesh.undo() of the {args.edits:,}-edit transaction just committed (floor: that
transaction, one run; no SPEC number):""")
    if views:
        rep.table(f"Proportional to the changes since r: each view figure {args.recent} and {args.edits:,} edits back "
                  "(ratio = the second ÷ the first; view ÷ current beside each):",
                  ["backend", "mesh", "figure", f"R − {args.recent}", "÷ current", f"R − {args.edits:,}", "÷ current",
                   "ratio"], proportional_rows(args, dims, views), "lrlrrrrr")
        small, large = triangles_label(*dims["small"]), triangles_label(*dims["large"])
        rep.table(f"Independent of the mesh: each figure on the {small}- and the {large}-triangle grid "
                  f"(ratio = {large} ÷ {small}):",
                  ["backend", "figure", small, large, "ratio", f"÷ floor, {small}", f"÷ floor, {large}"],
                  mesh_size_rows(args, small, large, views + undos), "llrrrrr")
    rep.table(f"SQL statements hestore sent on its driver cursor per 1-polygon transaction on the large grid "
              f"({min(COUNTED, args.repeat)} transactions counted in an untimed pass through store.session.traced; "
              "an executemany counts once; TXN = BEGIN/COMMIT/SAVEPOINT/RELEASE):",
              ["backend", "figure", "mesh", "statements per transaction"], statement_rows(args, runs), "llll")
    rep.close(ABOUT, profiles="Profiles (cProfile on during the timed calls only; the top functions are those of the "
                              "mesh with history):", rss="Peak RSS of the parent")


if __name__ == "__main__":
    raise SystemExit(main())
