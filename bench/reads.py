"""Benchmark: one-rings read from a stored 1 M-triangle mesh (SPEC §9).

    python bench/reads.py [--backends sqlite,postgresql] [--n 710] [--vertices 10000] [--runs 5]

Workload: the triangulated N×N vertex grid (``--n``, default 710: 2·709² =
1,005,362 triangles), stored once per backend with ``store.import_arrays``
(untimed setup; on PostgreSQL followed by ``VACUUM (ANALYZE)``, as autovacuum
soon would), and ``--vertices`` distinct random vertex ids drawn with a fixed
seed. Every run below is a fresh process on a freshly opened store or
connection, so nothing cached in Python carries over from one to the next
(the operating system's page cache and PostgreSQL's shared buffers do).

Figures, each on SQLite and on PostgreSQL:

fresh store      ``mesh.vertex(i).neighbors()`` for each id, timed call by
                 call, on a store opened just before (``hestore.open`` and
                 ``store.mesh`` are not timed; the first call is).
                 Target (SPEC §9): ≤ 2× the floor.
handles held     ``v.neighbors()`` for each id, on handles taken with
                 ``mesh.vertex(i)`` before the timed loop (same fresh
                 process and store). Target (SPEC §9): ≤ 50 µs per vertex;
                 the floor is printed beside it.
floor            one indexed SELECT of the vertex's star per vertex, on a
                 fresh plain-driver connection to the same database (stdlib
                 ``sqlite3`` configured as hestore configures its own;
                 psycopg in autocommit on PostgreSQL)::

                   SELECT h.id, t.origin FROM halfedges h [INDEXED BY ix_halfedges_origin]
                   JOIN halfedges t ON t.mesh_id = h.mesh_id AND t.id = h.twin
                   WHERE h.mesh_id = ? AND h.origin = ?

                 (the outgoing half-edges and their targets). On SQLite its
                 EXPLAIN QUERY PLAN must use the index ``ix_halfedges_origin``:
                 without ``INDEXED BY`` (which hestore's own star query
                 carries too) SQLite scans the mesh's whole primary-key range
                 on a file without statistics, as hestore leaves it; both
                 plans are printed.

Each figure is the loop's total time ÷ the number of vertices (a mean per
vertex, so the first call counts), the median over ``--runs`` runs; p90 is
that of the single calls of every run. Floor and hestore runs alternate.

Correctness gates, outside the timed loops (the exit status is non-zero only
when one fails or a step crashes): for every vertex the neighbours hestore
returns equal the floor's targets as multisets, and the floor's equal the
grid's known neighbours.

Run alone or by ``bench/all.py`` (``tests/test_bench.py`` runs it with
``--quick``). This file keeps the workloads, the floors and the targets; the
harness (``bench/harness/``) parses the options, runs each step in a fresh
process on each backend and prints the report.
"""

from __future__ import annotations

import random
import time

import hestore

from harness.bench import Bench
from harness.cli import Parser, at_least
from harness.databases import open_store, plain_connection, settle, url_of, vacuum
from harness.profiling import Statements
from harness.stats import finished, percentile
from harness.tables import Figure, fmt_time, verdict
from harness.timing import maxrss, pc, time_each
from workloads import counts_text, import_mesh, mesh_label

QUICK = {"n": 100, "vertices": 1000, "runs": 1}
TARGET_FRESH = 2.0  # × the floor
TARGET_HELD = 50e-6  # seconds per vertex
COUNTED = 100  # vertices of the untimed pass that counts hestore's statements
STAR = ("SELECT h.id, t.origin FROM halfedges h{hint} JOIN halfedges t ON t.mesh_id = h.mesh_id AND t.id = h.twin "
        "WHERE h.mesh_id = {p} AND h.origin = {p}")
#: SQLite plans the plain query as a scan of the mesh's primary-key range when the file has no statistics
#: (hestore runs no ANALYZE on SQLite), so the floor names its index, as hestore's own star query does.
HINT = {"sqlite": " INDEXED BY ix_halfedges_origin", "postgresql": ""}
#: Each step's figure, in the order the steps run (rotated each run).
FIGURES = {
    "floor": "floor: one indexed SELECT of the star",
    "fresh": "mesh.vertex(i).neighbors(), fresh store",
    "held": "v.neighbors(), handles held",
}
JOBS_ORDER = tuple(FIGURES)
ABOUT = """\
The floor runs on a fresh plain-driver connection per run: stdlib sqlite3 with hestore's pragmas (WAL,
synchronous=NORMAL, 64 MiB cache), psycopg in autocommit; every star is compared with the grid's known
neighbours, and hestore's neighbours with the floor's targets, as multisets, outside the timed loops."""


def star_sql(backend: str, mark: str, hint: bool = True) -> str:
    """The floor's query of one vertex's star, with the driver's placeholder ``mark``."""
    return STAR.format(p=mark, hint=HINT[backend] if hint else "")


# ==========================================================================
# The workload


def sample_ids(n: int, k: int, seed: int) -> tuple[list[int], list[int]]:
    """``k`` distinct random vertex ids of the n×n grid, and ``COUNTED`` others for the statement count."""
    ids = random.Random(seed).sample(range(n * n), min(k + COUNTED, n * n))
    return ids[:k], ids[k:]


def grid_neighbors(v: int, n: int) -> list[int]:
    """The neighbours of vertex ``v`` of the triangulated n×n grid (cells split along i = j), ascending.

    Vertex (i, j) is ``j·n + i``; its edges go to (i±1, j), (i, j±1), (i+1, j+1)
    and (i−1, j−1), where they exist.
    """
    j, i = divmod(v, n)
    out = [(i + di) + (j + dj) * n for di, dj in ((1, 0), (-1, 0), (0, 1), (0, -1), (1, 1), (-1, -1))
           if 0 <= i + di < n and 0 <= j + dj < n]
    return sorted(out)


# ==========================================================================
# Child jobs


def job_setup(spec: dict) -> dict:
    """Store the grid (untimed), VACUUM (ANALYZE) on PostgreSQL, and read the floor query's plan."""
    t0 = time.perf_counter()
    with open_store(spec) as store:
        report = import_mesh(store, "grid", spec["n"], "")
        counts = report.mesh.counts()
        mesh_id = report.mesh.id
    seconds = time.perf_counter() - t0
    vacuum(spec)
    plain = plain_connection(spec)
    v = (spec["n"] // 2) * (spec["n"] + 1)  # a vertex in the middle
    plans = {}
    for hint in (True, False):
        sql = star_sql(spec["backend"], plain.mark, hint)
        if spec["backend"] == "sqlite":
            plans[hint] = [r[-1] for r in plain.cur.execute("EXPLAIN QUERY PLAN " + sql, (mesh_id, v)).fetchall()]
        else:
            plain.cur.execute("EXPLAIN " + sql, (mesh_id, v))
            plans[hint] = [r[0] for r in plain.cur.fetchall()]
            break  # no hint on PostgreSQL: one query
    plan, plain_plan = plans[True], plans.get(False)
    uses_index = any("ix_halfedges_origin" in line for line in plan)
    plain.con.close()
    return {"seconds": seconds, "mesh_id": mesh_id, "plan": plan, "plain_plan": plain_plan, "uses_index": uses_index,
            "counts": [counts.vertices, counts.halfedges, counts.edges, counts.polygons]}


def _result(samples: list[int], cpu: float, stars: list[list[int]], **extra) -> dict:
    return dict(samples=samples, cpu=cpu, rss=maxrss(), stars=stars, **extra)


def job_floor(spec: dict) -> dict:
    """The floor: one indexed SELECT of the star per vertex on a fresh plain-driver connection."""
    ids, mesh_id = spec["ids"], spec["mesh_id"]
    settle(spec)
    plain = plain_connection(spec)
    cur = plain.cur
    sql = star_sql(spec["backend"], plain.mark)

    def star(v: int) -> list:
        cur.execute(sql, (mesh_id, v))
        return cur.fetchall()

    samples, rows, cpu = time_each(star, ids)
    plain.con.close()
    return _result(samples, cpu, [sorted(t for _, t in r) for r in rows])


def _statements(store: hestore.Store, calls) -> dict:
    """How many statements hestore sends for ``calls()``, by first word (an untimed pass)."""
    counter = Statements()
    with store.session.traced(counter):
        calls()
    return dict(counter.by_word)


def job_fresh(spec: dict) -> dict:
    """``mesh.vertex(i).neighbors()`` on a store opened just before (opening it is not timed)."""
    ids = spec["ids"]
    settle(spec)
    t0 = pc()
    store = hestore.open(url_of(spec))
    mesh = store.mesh("grid")
    opened = (pc() - t0) / 1e9
    samples, result, cpu = time_each(lambda i: mesh.vertex(i).neighbors(), ids)
    stars = [sorted(v.id for v in r) for r in result]
    kinds = _statements(store, lambda: [mesh.vertex(i).neighbors() for i in spec["others"]])
    store.close()
    return _result(samples, cpu, stars, opened=opened, statements=kinds)


def job_held(spec: dict) -> dict:
    """``v.neighbors()`` on handles taken before the timed loop, on a freshly opened store."""
    ids = spec["ids"]
    settle(spec)
    store = hestore.open(url_of(spec))
    mesh = store.mesh("grid")
    t0 = pc()
    handles = [mesh.vertex(i) for i in ids]
    taking = (pc() - t0) / 1e9
    samples, result, cpu = time_each(lambda v: v.neighbors(), handles)
    stars = [sorted(v.id for v in r) for r in result]
    others = [mesh.vertex(i) for i in spec["others"]]
    kinds = _statements(store, lambda: [v.neighbors() for v in others])
    store.close()
    return _result(samples, cpu, stars, taking=taking, statements=kinds)


JOBS = {"setup": job_setup, "floor": job_floor, "fresh": job_fresh, "held": job_held}


# ==========================================================================
# The parent


def main(argv=None) -> int:
    ap = Parser(__doc__, quick=QUICK, grid=710, jobs=JOBS, seed=20240601)
    ap.add_argument("--vertices", type=at_least(1), default=10000, help="random vertices per run (default 10000)")
    ap.add_argument("--runs", type=at_least(1), default=5,
                    help="runs of each figure (default 5), each in a fresh process")
    args = ap.parse_args(argv)

    ids, others = sample_ids(args.n, args.vertices, args.seed)
    setups: dict = {}  # backend -> result
    runs: dict = {}  # (backend, job) -> [result per run]
    with Bench(args, "reads", __file__) as bench:
        for place in bench.for_each_backend():
            spec = dict(place.fresh("reads_grid"), n=args.n)
            setups[place.backend] = setup = bench.runner.run(job="setup", **spec)
            if setup is None:
                continue
            spec.update(mesh="grid", mesh_id=setup["mesh_id"], ids=ids, others=others)
            for r in range(args.runs):
                for k in range(len(JOBS_ORDER)):  # rotated each run, so that drift spreads over all three
                    job = JOBS_ORDER[(k + r) % len(JOBS_ORDER)]
                    runs.setdefault((place.backend, job), []).append(bench.runner.run(job=job, **spec))
            place.drop(spec)
    report(bench, ids, setups, runs)
    return bench.finish()


def per_vertex(results: list[dict]) -> tuple[float, float, float, float]:
    """(median over runs of the per-vertex mean, p90 of all single calls, CPU per vertex, peak RSS) in seconds/bytes."""
    means = sorted(sum(r["samples"]) / len(r["samples"]) / 1e9 for r in results)
    calls = [s for r in results for s in r["samples"]]
    cpu = sorted(r["cpu"] / len(r["samples"]) for r in results)
    return (percentile(means, 0.5), percentile(calls, 0.9) / 1e9, percentile(cpu, 0.5),
            max(r["rss"] for r in results))


def backend_figures(bench: Bench, bname: str, ids: list[int], want: list, done: dict) -> list[Figure]:
    """The three figures of one backend (floor, fresh store, handles held), their notes and their gates."""
    args, rep = bench.args, bench.report
    label = mesh_label("grid", args.n)
    floor = per_vertex(done["floor"]) if done["floor"] else None
    figures = []
    for job in ("floor", "fresh", "held"):
        results = done[job]
        if not results:
            continue
        t, p90, cpu, rss = per_vertex(results)
        if job == "floor":
            target, ok, fl = "—", None, None
        elif job == "fresh":
            target = f"≤ {TARGET_FRESH:g}× floor"
            ok = None if floor is None else t <= TARGET_FRESH * floor[0]
            fl = floor[0] if floor else None
        else:
            target, ok, fl = f"≤ {fmt_time(TARGET_HELD)}", t <= TARGET_HELD, floor[0] if floor else None
        figures.append(Figure(FIGURES[job], bname, t, fl, target, verdict(ok), label, n=len(ids), p90=p90, cpu=cpu,
                              rss=rss))
        # Correctness: every run's stars against the grid's known neighbours (the floor) or the floor (hestore).
        for k, r in enumerate(results):
            ref = want if job == "floor" else (done["floor"][0]["stars"] if done["floor"] else None)
            if ref is None:
                rep.problems.append(f"{bname}: {job} run {k + 1} not verified: no floor run")
                continue
            bad = [i for i, (a, b) in enumerate(zip(r["stars"], ref)) if a != b]
            if bad or len(r["stars"]) != len(ref):
                i = bad[0] if bad else min(len(r["stars"]), len(ref))
                what = "the grid's neighbours" if job == "floor" else "the floor's targets"
                rep.problems.append(f"{bname}: {job} run {k + 1}: {len(bad)} of {len(ref):,} vertices differ from "
                                    f"{what}, e.g. vertex {ids[i] if i < len(ids) else '?'}")
        firsts = sorted(r["samples"][0] / 1e9 for r in results)
        extra = ""
        if job == "fresh":
            extra = f"; hestore.open + store.mesh {fmt_time(percentile([r['opened'] for r in results], 0.5))}"
        if job == "held":
            extra = (f"; taking the handles (mesh.vertex(i) each, untimed) "
                     f"{fmt_time(percentile([r['taking'] for r in results], 0.5))}")
        single = percentile([s for r in results for s in r["samples"]], 0.5) / 1e9
        rep.notes.append(f"{bname}: {FIGURES[job]}: per vertex in each run "
                         + ", ".join(fmt_time(sum(r["samples"]) / len(r["samples"]) / 1e9) for r in results)
                         + f"; median single call {fmt_time(single)}"
                         + f"; first call {fmt_time(percentile(firsts, 0.5))} (median of runs){extra}")
        if "statements" in results[0]:
            rep.notes.append(f"{bname}: {FIGURES[job]}: statements hestore sent per vertex (untimed pass over "
                             f"{COUNTED} other vertices, store.session.traced): "
                             f"{Statements.per_word(results[0]['statements'], COUNTED)}")
    return figures


def report(bench: Bench, ids: list[int], setups: dict, runs: dict) -> None:
    args, rep = bench.args, bench.report
    figures: list[Figure] = []
    plans: list[list[str]] = []
    label = mesh_label("grid", args.n)
    want = [grid_neighbors(v, args.n) for v in ids]
    for bname, setup in setups.items():  # in the order the backends ran; a failed setup left None
        if not setup:
            continue
        rep.notes.append(f"{bname}: stored in {setup['seconds']:.1f} s (setup, not a figure): "
                         f"{counts_text(setup['counts'])}")
        for line in setup["plan"]:
            plans.append([bname, "the floor's query", line])
        for line in setup["plain_plan"] or []:
            plans.append([bname, "without INDEXED BY", line])
        if not setup["uses_index"]:
            rep.problems.append(f"{bname}: the floor's query plan does not use ix_halfedges_origin: "
                                + "; ".join(setup["plan"]))
        done = {job: finished(runs, (bname, job)) for job in JOBS_ORDER}
        figures += backend_figures(bench, bname, ids, want, done)
        stars = sum(len(s) for s in want)
        rep.notes.append(f"{bname}: {len(ids):,} vertices, {stars:,} neighbours in all "
                         f"({stars / len(ids):.2f} per vertex)")

    rep.title(f"hestore one-ring read benchmark — {len(ids):,} random vertices (seed {args.seed}) of the stored "
              f"{label} grid, {args.runs} run(s) of each figure, each in a {bench.runner.process}")
    rep.figures(figures, after="""\
(time: the loop's total ÷ the vertices, a mean per vertex with the first call included, median of the runs;
 p90: of the single calls of all runs; its CPU: the measuring process's user + system time per vertex,
 without the database server's)""")
    rep.table("The floor's query plan (SQLite: EXPLAIN QUERY PLAN, also of the query without its INDEXED BY;\n"
              "PostgreSQL: EXPLAIN):", ["backend", "query", "plan"], plans, "lll")
    rep.close(ABOUT)


if __name__ == "__main__":
    raise SystemExit(main())
