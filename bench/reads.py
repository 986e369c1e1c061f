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
"""

from __future__ import annotations

import contextlib
import os
import random
import shutil
import sys
import tempfile
import time
from collections import Counter

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import hestore  # noqa: E402
from _common import (  # noqa: E402
    Figure,
    Parser,
    Runner,
    child_main,
    fmt_time,
    import_mesh,
    maxrss,
    mesh_label,
    open_backend,
    pc,
    percentile,
    plain_connection,
    print_figures,
    print_machine,
    print_markdown,
    print_table,
    selected_backends,
    settle,
    time_each,
    url_of,
    vacuum_analyze,
    verdict,
)

QUICK = {"n": 100, "vertices": 1000, "runs": 1}
TARGET_FRESH = 2.0  # × the floor
TARGET_HELD = 50e-6  # seconds per vertex
COUNTED = 100  # vertices of the untimed pass that counts hestore's statements
STAR = ("SELECT h.id, t.origin FROM halfedges h{hint} JOIN halfedges t ON t.mesh_id = h.mesh_id AND t.id = h.twin "
        "WHERE h.mesh_id = {p} AND h.origin = {p}")
#: SQLite plans the plain query as a scan of the mesh's primary-key range when the file has no statistics
#: (hestore runs no ANALYZE on SQLite), so the floor names its index, as hestore's own star query does.
HINT = {"sqlite": " INDEXED BY ix_halfedges_origin", "postgresql": ""}


def star_sql(backend: str, mark: str, hint: bool = True) -> str:
    return STAR.format(p=mark, hint=HINT[backend] if hint else "")
JOBS_ORDER = ("floor", "fresh", "held")
FIGURES = {
    "fresh": "mesh.vertex(i).neighbors(), fresh store",
    "held": "v.neighbors(), handles held",
    "floor": "floor: one indexed SELECT of the star",
}


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
    with contextlib.closing(hestore.open(url_of(spec))) as store:
        report = import_mesh(store, "grid", spec["n"], "")
        counts = report.mesh.counts()
        mesh_id = report.mesh.id
    seconds = time.perf_counter() - t0
    vacuum_analyze(spec)
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
    """How many statements of each kind hestore sends for ``calls()`` (an untimed pass)."""
    kinds: Counter = Counter()
    with store.session.traced(lambda sql: kinds.update([sql.lstrip().split(None, 1)[0].upper()])):
        calls()
    return dict(kinds)


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
    ap = Parser(__doc__, quick=QUICK, grid=710, children=True, seed=20240601,
                workdir_help="where SQLite files go (default: a temporary folder, removed at the end)")
    ap.add_argument("--vertices", type=int, default=10000, help="random vertices per run (default 10000)")
    ap.add_argument("--runs", type=int, default=5, help="runs of each figure (default 5), each in a fresh process")
    args = ap.parse_args(argv)
    if args.child:
        return child_main(JOBS, args.child)
    backends = selected_backends(ap, args)
    if args.vertices < 1 or args.runs < 1:
        ap.error("--vertices and --runs must be at least 1")

    own_workdir = args.workdir is None
    workdir = args.workdir or tempfile.mkdtemp(prefix="hestore_bench_reads_")
    os.makedirs(workdir, exist_ok=True)
    runner = Runner(__file__, workdir, args.timeout)
    ids, others = sample_ids(args.n, args.vertices, args.seed)
    load_start = os.getloadavg()
    t_start = time.perf_counter()

    setups: dict = {}  # backend -> result
    runs: dict = {}  # (backend, job) -> [result per run]
    skipped: list[str] = []
    pg_version = None
    try:
        for bname in backends:
            with open_backend(bname, workdir, args.pg_url, skipped) as place:
                if place is None:
                    continue
                pg_version = place.version or pg_version
                spec = dict(place.fresh("reads_grid"), n=args.n)
                setups[bname] = setup = runner.run(job="setup", **spec)
                if setup is None:
                    continue
                spec.update(mesh="grid", mesh_id=setup["mesh_id"], ids=ids, others=others)
                for r in range(args.runs):
                    for k in range(len(JOBS_ORDER)):  # rotated each run, so that drift spreads over all three
                        job = JOBS_ORDER[(k + r) % len(JOBS_ORDER)]
                        runs.setdefault((bname, job), []).append(runner.run(job=job, **spec))
                place.drop(spec)
    finally:
        if own_workdir:
            shutil.rmtree(workdir, ignore_errors=True)

    problems = report(args, backends, ids, setups, runs, skipped, runner.errors)
    print_machine(pg_version, load_start, time.perf_counter() - t_start)
    return 1 if problems else 0


def per_vertex(results: list[dict]) -> tuple[float, float, float, float]:
    """(median over runs of the per-vertex mean, p90 of all single calls, CPU per vertex, peak RSS) in seconds/bytes."""
    means = sorted(sum(r["samples"]) / len(r["samples"]) / 1e9 for r in results)
    calls = [s for r in results for s in r["samples"]]
    cpu = sorted(r["cpu"] / len(r["samples"]) for r in results)
    return (percentile(means, 0.5), percentile(calls, 0.9) / 1e9, percentile(cpu, 0.5),
            max(r["rss"] for r in results))


def report(args, backends, ids, setups, runs, skipped, errors) -> list[str]:
    problems = list(errors)
    figures: list[Figure] = []
    notes: list[str] = []
    plans: list[list[str]] = []
    label = mesh_label("grid", args.n)
    want = [grid_neighbors(v, args.n) for v in ids]
    for bname in backends:
        setup = setups.get(bname)
        if not setup:
            continue
        V, H, E, P = setup["counts"]
        notes.append(f"{bname}: stored in {setup['seconds']:.1f} s (setup, not a figure): "
                     f"V/H/E/P {V:,}/{H:,}/{E:,}/{P:,}")
        for line in setup["plan"]:
            plans.append([bname, "the floor's query", line])
        for line in setup["plain_plan"] or []:
            plans.append([bname, "without INDEXED BY", line])
        if not setup["uses_index"]:
            problems.append(f"{bname}: the floor's query plan does not use ix_halfedges_origin: "
                            + "; ".join(setup["plan"]))
        done = {job: [r for r in runs.get((bname, job), []) if r] for job in JOBS_ORDER}
        floor = per_vertex(done["floor"]) if done["floor"] else None
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
                    problems.append(f"{bname}: {job} run {k + 1} not verified: no floor run")
                    continue
                bad = [i for i, (a, b) in enumerate(zip(r["stars"], ref)) if a != b]
                if bad or len(r["stars"]) != len(ref):
                    i = bad[0] if bad else min(len(r["stars"]), len(ref))
                    what = "the grid's neighbours" if job == "floor" else "the floor's targets"
                    problems.append(f"{bname}: {job} run {k + 1}: {len(bad)} of {len(ref):,} vertices differ from "
                                    f"{what}, e.g. vertex {ids[i] if i < len(ids) else '?'}")
            firsts = sorted(r["samples"][0] / 1e9 for r in results)
            extra = ""
            if job == "fresh":
                extra = f"; hestore.open + store.mesh {fmt_time(percentile([r['opened'] for r in results], 0.5))}"
            if job == "held":
                extra = (f"; taking the handles (mesh.vertex(i) each, untimed) "
                         f"{fmt_time(percentile([r['taking'] for r in results], 0.5))}")
            single = percentile([s for r in results for s in r["samples"]], 0.5) / 1e9
            notes.append(f"{bname}: {FIGURES[job]}: per vertex in each run "
                         + ", ".join(fmt_time(sum(r["samples"]) / len(r["samples"]) / 1e9) for r in results)
                         + f"; median single call {fmt_time(single)}"
                         + f"; first call {fmt_time(percentile(firsts, 0.5))} (median of runs){extra}")
            if "statements" in results[0]:
                kinds = results[0]["statements"]
                per = ", ".join(f"{k} {c / COUNTED:g}" for k, c in sorted(kinds.items()))
                notes.append(f"{bname}: {FIGURES[job]}: statements hestore sent per vertex (untimed pass over "
                             f"{COUNTED} other vertices, store.session.traced): {per or 'none'}")
        stars = sum(len(s) for s in want)
        notes.append(f"{bname}: {len(ids):,} vertices, {stars:,} neighbours in all ({stars / len(ids):.2f} per vertex)")

    print()
    print(f"hestore one-ring read benchmark — {len(ids):,} random vertices (seed {args.seed}) of the stored "
          f"{label} grid, {args.runs} run(s) of each figure, each in a fresh process")
    print()
    if figures:
        print_figures(figures)
    print("(time: the loop's total ÷ the vertices, a mean per vertex with the first call included, median of the runs;")
    print(" p90: of the single calls of all runs; its CPU: the measuring process's user + system time per vertex,")
    print(" without the database server's)")
    if plans:
        print()
        print("The floor's query plan (SQLite: EXPLAIN QUERY PLAN, also of the query without its INDEXED BY;")
        print("PostgreSQL: EXPLAIN):")
        print_table(["backend", "query", "plan"], plans, "lll")
    print()
    print("Correctness and notes:")
    for n in notes:
        print(f"  {n}")
    print("  The floor runs on a fresh plain-driver connection per run: stdlib sqlite3 with hestore's pragmas (WAL,")
    print("  synchronous=NORMAL, 64 MiB cache), psycopg in autocommit; every star is compared with the grid's known")
    print("  neighbours, and hestore's neighbours with the floor's targets, as multisets, outside the timed loops.")
    for s in skipped:
        print(f"  SKIPPED {s}")
    for p in problems:
        print(f"  PROBLEM {p}")
    if figures:
        print_markdown(figures)
    return problems


if __name__ == "__main__":
    sys.exit(main())
