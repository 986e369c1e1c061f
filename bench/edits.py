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
"""

from __future__ import annotations

import argparse
import gc
import os
import random
import shutil
import sys
import tempfile
import time
from dataclasses import dataclass, field

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import sqlalchemy as sa  # noqa: E402

import hestore  # noqa: E402
from _common import (  # noqa: E402
    DEFAULT_PG_URL,
    MESH,
    CountingCursor,
    Model,
    PostgresBackend,
    SQLiteBackend,
    build_grid,
    fmt_ns,
    log,
    median,
    peak_rss_mb,
    percentile,
    pg_problem,
    print_table,
)

pc = time.perf_counter_ns

US, MS = 1_000, 1_000_000
TARGET_EDIT = 1 * MS  # one add_polygon / remove_edge inside a transaction, median
TARGET_AMORTISED = 100 * US  # per edit of a 1,000-edit transaction, commit included
TARGET_COMMIT = 2 * MS  # commit of a 1-polygon transaction, median (SPEC: SQLite WAL)


class _Rollback(Exception):
    """Raised at the end of a measuring block to undo it."""


@dataclass
class Figure:
    name: str
    samples: list[float]  # ns
    target: float | None = None
    floor: float | None = None
    note: str = ""
    p90: bool = True  # whether p90 means anything (false for a handful of runs)

    @property
    def median(self) -> float:
        return median(self.samples)


@dataclass
class SizeResult:
    backend: str
    size: int
    figures: list[Figure] = field(default_factory=list)
    sql: list[tuple[str, str]] = field(default_factory=list)  # (what, counts)
    notes: list[str] = field(default_factory=list)


# -- choosing edits ------------------------------------------------------------------


def _pick(items, rng, ok, tries=64):
    """A random item satisfying ``ok`` (``(item, True)``), else a random one (``(item, False)``)."""
    for _ in range(tries):
        x = items.choice(rng)
        if ok(x):
            return x, True
    return items.choice(rng), False


def plan_cold_adds(model: Model, rng: random.Random, k: int) -> list[tuple[int, int]]:
    """Up to ``k`` boundary half-edges a→b, no two sharing a vertex."""
    touched: set[int] = set()
    out = []
    misses = 0
    while len(out) < k and misses < 400:
        a, b = model.boundary.choice(rng)
        if a in touched or b in touched:
            misses += 1
            continue
        out.append((a, b))
        touched.update((a, b))
    return out


def _clean_interior(model: Model, u: int, v: int) -> bool:
    ps = model.side_polygons(u, v)
    return len(ps) == 2 and not any(model.is_boundary_vertex(x) for x in model.remove_footprint(u, v))


def plan_cold_removes(model: Model, rng: random.Random, k: int) -> list[tuple[int, int]]:
    """Up to ``k`` interior edges away from the boundary, whose triangles share no vertex."""
    touched: set[int] = set()
    out = []
    misses = 0
    while len(out) < k and misses < 400:
        u, v = model.interior.choice(rng)
        fp = model.remove_footprint(u, v)
        if not fp.isdisjoint(touched) or not _clean_interior(model, u, v):
            misses += 1
            continue
        out.append((u, v))
        touched |= fp
    return out


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

    for i in range(n):
        if i % 2 == 1 and len(model.interior):
            (u, v), cold = _pick(model.interior, rng, lambda k: model.remove_footprint(*k).isdisjoint(touched))
            touched |= model.remove_footprint(u, v)
            plan.append((REMOVE, hestore.Edge(mesh, model.eid[(u, v)]), None, None))
            model.remove_edge(u, v)
            stats["removes"] += 1
        else:
            if i % 2 == 1:
                stats["no_interior"] += 1
            (a, b), cold = _pick(model.boundary, rng, lambda k: k[0] not in touched and k[1] not in touched)
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
    gc.collect()
    gc.disable()
    try:
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
                raise _Rollback
        t2 = pc()
    except _Rollback:
        t2 = pc()
    finally:
        gc.enable()
    return t2 - t0, t2 - t1, newv


# -- measurements ----------------------------------------------------------------------


def _fmt_counts(calls: int, rows: int, by_kind: dict, per: int) -> str:
    parts = []
    for kind in ("SELECT", "INSERT", "UPDATE", "DELETE", "TXN"):
        if kind in by_kind:
            c, r = by_kind[kind]
            parts.append(f"{kind} {c / per:.3g}" + (f" ({r / per:.3g} rows)" if r != c else ""))
    return f"{calls / per:.3g} driver calls: " + ", ".join(parts)


def _diff(after, before):
    calls = after[0] - before[0]
    rows = after[1] - before[1]
    kinds = {}
    for k, (c, r) in after[2].items():
        c0, r0 = before[2].get(k, (0, 0))
        if c - c0 or r - r0:
            kinds[k] = (c - c0, r - r0)
    return calls, rows, kinds


def _accumulate(acc, d):
    acc[0] += d[0]
    acc[1] += d[1]
    for k, (c, r) in d[2].items():
        x = acc[2].setdefault(k, [0, 0])
        x[0] += c
        x[1] += r


def measure_single(store, mesh, model, rng, kind: str, n: int, warm: int, block: int, counter=None):
    """Median-able samples of single add_polygon (and add_vertex) or remove_edge calls.

    Runs blocks of up to ``block`` independent edits, each block one
    transaction rolled back at its end (so the mesh stays the base mesh). An
    untimed ``add_vertex`` opens each block's unit of work (the mesh lock), a
    per-transaction cost that belongs to the commit figure.
    With ``counter`` (a CountingCursor installed as store._cur), also counts
    statements per op and at a forced flush.
    """
    samples, vsamples = [], []
    cnt_op = [0, 0, {}]
    cnt_flush = [0, 0, {}]
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
        gc.collect()
        gc.disable()
        try:
            with store.transaction():
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
                            _accumulate(cnt_op, _diff(counter.snapshot(), before))
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
                            _accumulate(cnt_op, _diff(counter.snapshot(), before))
                        samples.append(t1 - t0)
                n_ops += len(plan)
                if counter:
                    before = counter.snapshot()
                    mesh.counts()  # flushes the block's writes
                    _accumulate(cnt_flush, _diff(counter.snapshot(), before))
                raise _Rollback
        except _Rollback:
            pass
        finally:
            gc.enable()
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
    samples = []
    gc.collect()
    gc.disable()
    try:
        for k in range(warm + n):
            t0 = pc()
            with engine.begin() as conn:
                for i in range(12):
                    conn.execute(upd, {"i": i, "v": k})
            samples.append(pc() - t0)
    finally:
        gc.enable()
    md.drop_all(engine)
    return samples[warm:]


def measure_commits(store, mesh, model, rng, n: int, warm: int, counter=None):
    """One-polygon transactions end to end, and their part after the last edit."""
    total, tail = [], []
    acc = [0, 0, {}]
    gc.collect()
    gc.disable()  # for the whole loop: a full collection per transaction would dominate the run
    try:
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
                _accumulate(acc, _diff(counter.snapshot(), before))
            model.add_triangle(a, b, c.id, pos, p.id)
            if k >= warm:
                total.append(t2 - t0)
                tail.append(t2 - t1)
    finally:
        gc.enable()
    return total, tail, acc


# -- one size on one backend -------------------------------------------------------------


def open_work(backend, size):
    url = backend.restore(size)
    engine = backend.engine(url)
    store = hestore.open(url)
    mesh = store.mesh(MESH)
    model = Model.load(engine, mesh._id)
    return url, engine, store, mesh, model


def run_size(backend, size: int, args, rng: random.Random) -> SizeResult:
    res = SizeResult(backend.name, size)
    load0 = os.getloadavg()[0]
    url, engine, store, mesh, model = open_work(backend, size)
    counts = mesh.counts()
    assert counts.polygons == model.n_polygons and counts.edges == model.n_edges, (counts, model.n_polygons)
    log(f"{backend.name} {size}: {counts}; boundary half-edges {len(model.boundary)}, interior edges {len(model.interior)}")

    # add_polygon / remove_edge inside a transaction
    for kind in ("add", "remove"):
        s, vs, _ = measure_single(store, mesh, model, rng, kind, args.repeat, args.warmup, args.block)
        if kind == "add":
            res.figures.append(Figure("add_polygon in txn (triangle on boundary)", s, TARGET_EDIT))
            res.figures.append(Figure("  add_vertex in txn (its new corner)", vs))
        else:
            res.figures.append(Figure("remove_edge in txn (interior, 2 triangles)", s, TARGET_EDIT))
        if args.count:
            orig = store._cur
            store._cur = counter = CountingCursor(orig)
            try:
                _, _, (op, fl, n_ops) = measure_single(store, mesh, model, rng, kind, args.block, 0, args.block, counter)
            finally:
                store._cur = orig
            label = "add_polygon" if kind == "add" else "remove_edge"
            res.sql.append((f"{label}: during the call, per op", _fmt_counts(op[0], op[1], op[2], n_ops)))
            res.sql.append((f"{label}: at flush, per op ({n_ops} ops)", _fmt_counts(fl[0], fl[1], fl[2], n_ops)))
    assert mesh.counts() == counts, "a rolled-back block changed the mesh"

    # floor: a 12-row update transaction through SQLAlchemy, same database
    floor = measure_floor(engine, args.repeat, args.warmup)
    floor_med = median(floor)
    res.figures.append(Figure("floor: 12-row UPDATE txn via SQLAlchemy", floor))

    # one-polygon transactions (these commit: the model follows)
    total, tail, _ = measure_commits(store, mesh, model, rng, args.repeat, args.warmup)
    res.figures.append(Figure("1-polygon txn, end to end", total, TARGET_COMMIT, floor_med))
    res.figures.append(Figure("  of which flush + COMMIT", tail, TARGET_COMMIT, floor_med))
    if args.count:
        orig = store._cur
        store._cur = counter = CountingCursor(orig)
        try:
            _, _, acc = measure_commits(store, mesh, model, rng, 20, 0, counter)
        finally:
            store._cur = orig
        res.sql.append(("1-polygon txn, per txn", _fmt_counts(acc[0], acc[1], acc[2], 20)))
    store.close()
    engine.dispose()

    # 1,000-edit transactions, each on a fresh copy of the base mesh
    per_edit, commit_part, warm_share = [], [], []
    for run in range(args.txn_runs):
        url, engine, store, mesh, model = open_work(backend, size)
        # warm-up (and statement count): the same kind of transaction, rolled back
        plan, _, _ = plan_mixed(model.copy(), mesh, rng, args.edits)
        orig = store._cur
        counter = CountingCursor(orig) if (args.count and run == 0) else None
        if counter:
            store._cur = counter
        try:
            run_mixed(store, mesh, plan, commit=False)
        finally:
            store._cur = orig
        if counter:
            res.sql.append(
                (f"{args.edits}-edit txn, per edit (incl. flush)", _fmt_counts(counter.calls, counter.rows, counter.snapshot()[2], args.edits))
            )
        plan, slots, stats = plan_mixed(model, mesh, rng, args.edits)
        total, tail, newv = run_mixed(store, mesh, plan, commit=True)
        per_edit.append(total / args.edits)
        commit_part.append(tail)
        warm_share.append(stats["warm"] / args.edits)
        # the database must now hold what the plan said
        vmap = {neg: newv[slot].id for neg, slot in slots.items()}
        expected = model.signature(vmap)
        actual = Model.load(engine, mesh._id).signature()
        if expected != actual:
            msg = (f"{backend.name} {size}: after the {args.edits}-edit transaction the database differs from the plan: "
                   f"polygons {actual[0]} vs {expected[0]}, edges {actual[1]} vs {expected[1]}, "
                   f"boundary half-edges {len(actual[2])} vs {len(expected[2])}")
            res.notes.append("MISMATCH: " + msg)
            log(msg)
        res.notes.append(
            f"1000-edit run {run + 1}: {fmt_ns(total)} total, {fmt_ns(tail)} flush+COMMIT, "
            f"{stats['adds']} adds / {stats['removes']} removes"
            + (f" ({stats['no_interior']} removes became adds: no interior edge left)" if stats["no_interior"] else "")
            + f", {100 * stats['warm'] / args.edits:.0f}% of edits on vertices an earlier edit had touched"
        )
        if run < args.txn_runs - 1:
            store.close()
            engine.dispose()
    res.figures.append(
        Figure(
            f"{args.edits}-edit txn, per edit incl. COMMIT",
            per_edit,
            TARGET_AMORTISED,
            p90=False,
            note=f"median of {len(per_edit)} run(s); commit part {fmt_ns(median(commit_part))}",
        )
    )

    res.notes.append(f"load average (1 min) {load0:.1f} at the start of the measurements, "
                     f"{os.getloadavg()[0]:.1f} at the end ({os.cpu_count()} CPUs)")
    if args.check:
        t0 = time.perf_counter()
        violations = mesh.check()
        dt = time.perf_counter() - t0
        res.notes.append(f"mesh.check() after the runs: {len(violations)} violation(s), {dt:.2f} s")
        if violations:
            log(f"{backend.name} {size}: check() found {len(violations)} violations, e.g. {violations[:3]}")
    store.close()
    engine.dispose()
    return res


# -- main ----------------------------------------------------------------------------------


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", default="1000,10000,100000", help="mesh sizes in polygons, comma-separated")
    ap.add_argument("--backends", default="sqlite,postgresql", help="sqlite and/or postgresql")
    ap.add_argument("--repeat", type=int, default=200, help="timed calls per single-operation figure (default 200)")
    ap.add_argument("--warmup", type=int, default=20, help="untimed calls before each figure (default 20)")
    ap.add_argument("--txn-runs", type=int, default=3, help="1,000-edit transactions per size (default 3)")
    ap.add_argument("--edits", type=int, default=1000, help="edits in the amortised transaction (default 1000)")
    ap.add_argument("--block", type=int, default=50, help="edits per rolled-back measuring block (default 50)")
    ap.add_argument("--seed", type=int, default=20240601)
    ap.add_argument("--pg-url", default=os.environ.get("HESTORE_BENCH_PG_URL", DEFAULT_PG_URL),
                    help="PostgreSQL server to use; a database is created there and dropped at the end")
    ap.add_argument("--max-build-seconds", type=float, default=180,
                    help="skip a size whose build is expected to take longer (default 180)")
    ap.add_argument("--workdir", help="where SQLite files go (default: a temporary folder, removed at the end)")
    ap.add_argument("--no-count", dest="count", action="store_false", help="skip the SQL statement counts")
    ap.add_argument("--no-check", dest="check", action="store_false", help="skip mesh.check() at the end")
    args = ap.parse_args(argv)

    sizes = [int(s) for s in args.sizes.split(",") if s.strip()]
    backends = [b.strip() for b in args.backends.split(",") if b.strip()]
    rng = random.Random(args.seed)
    workdir = args.workdir or tempfile.mkdtemp(prefix="hestore_bench_")
    os.makedirs(workdir, exist_ok=True)

    builds, results, skipped = [], [], []
    try:
        for bname in backends:
            if bname == "sqlite":
                backend = SQLiteBackend(workdir)
            elif bname == "postgresql":
                problem = pg_problem(args.pg_url)
                if problem:
                    skipped.append(f"postgresql: not reachable at {args.pg_url}: {problem}")
                    continue
                backend = PostgresBackend(args.pg_url)
            else:
                ap.error(f"unknown backend {bname!r}")
            try:
                rate = None
                for size in sizes:
                    if rate and size / rate > args.max_build_seconds:
                        skipped.append(
                            f"{bname} {size}: skipped, the build would take ~{size / rate:.0f} s at "
                            f"{rate:.0f} polygons/s (limit {args.max_build_seconds:.0f} s)"
                        )
                        continue
                    log(f"{bname} {size}: building")
                    store = hestore.open(backend.build_url(size))
                    b = build_grid(store, size)
                    store.close()
                    rate = b.rate
                    builds.append((bname, b, backend.size_bytes(size), peak_rss_mb()))
                    log(f"{bname} {size}: built {b.polygons} polygons in {b.seconds:.2f} s ({b.rate:.0f}/s)")
                    results.append(run_size(backend, size, args, rng))
                    log(f"{bname} {size}: done; peak RSS {peak_rss_mb():.0f} MiB")
            finally:
                backend.cleanup()
    finally:
        if not args.workdir:
            shutil.rmtree(workdir, ignore_errors=True)

    report(args, builds, results, skipped)
    return 1 if any("MISMATCH" in n for r in results for n in r.notes) else 0


def report(args, builds, results, skipped) -> None:
    import platform

    print()
    print(f"hestore {hestore.__version__} edit benchmark — Python {platform.python_version()}, "
          f"SQLAlchemy {sa.__version__}, {os.cpu_count()} CPUs, seed {args.seed}, "
          f"{args.repeat} timed calls per figure, {args.txn_runs} × {args.edits}-edit transactions per size")
    print()
    print("Build: triangulated grid through the public API, one transaction "
          "(add_vertex ×V, add_polygon ×F, commit). PostGIS Topology: 45–240 triangles/s.")
    rows = []
    for bname, b, nbytes, rss in builds:
        rows.append([
            bname, f"{b.polygons:,}", f"{b.vertices:,}", f"{b.seconds:.2f} s",
            f"{b.seconds_vertices:.2f} / {b.seconds_polygons:.2f} / {b.seconds_commit:.2f} s",
            f"{b.rate:,.0f}", f"{nbytes / 2**20:.1f} MiB", f"{rss:.0f} MiB",
        ])
    print_table(["backend", "polygons", "vertices", "build", "vertices / polygons / commit", "polygons/s", "db size",
                 "peak RSS so far"], rows, "llrrrrrr")
    print()
    print("Edits (medians and p90 over the timed calls; target = SPEC §9; floor measured in the same run):")
    rows = []
    for r in results:
        for f in r.figures:
            verdict = "—"
            if f.target is not None:
                verdict = "ok" if f.median <= f.target else "over"
            rows.append([
                r.backend, f"{r.size:,}", f.name, str(len(f.samples)), fmt_ns(f.median),
                fmt_ns(percentile(f.samples, 0.9)) if f.p90 else "—",
                ("≤ " + fmt_ns(f.target)) if f.target else "—",
                fmt_ns(f.floor) if f.floor else "—",
                f"{f.median / f.floor:.1f}×" if f.floor else "—",
                verdict,
            ])
        rows.append([""] * 10)
    if rows:
        print_table(["backend", "mesh", "figure", "n", "median", "p90", "target", "floor", "÷floor", "verdict"],
                    rows[:-1], "lrlrrrrrrl")
    if results:
        print()
        print("Growth with the mesh (median at each size; ratio = largest size / smallest size):")
        names = [f.name for f in results[0].figures]
        sizes = sorted({r.size for r in results})
        rows = []
        for bname in dict.fromkeys(r.backend for r in results):
            by_size = {r.size: r for r in results if r.backend == bname}
            for i, name in enumerate(names):
                vals = [by_size[s].figures[i].median if s in by_size else None for s in sizes]
                present = [v for v in vals if v is not None]
                ratio = f"{present[-1] / present[0]:.2f}" if len(present) > 1 else "—"
                rows.append([bname, name.strip()] + [fmt_ns(v) for v in vals] + [ratio])
        print_table(["backend", "figure"] + [f"{s:,}" for s in sizes] + ["ratio"], rows, "ll" + "r" * (len(sizes) + 1))
    notes = [(r.backend, r.size, n) for r in results for n in r.notes]
    if notes:
        print()
        print("Notes:")
        for bname, size, n in notes:
            print(f"  {bname} {size:,}: {n}")
    sql = [(r.backend, r.size, w, c) for r in results for w, c in r.sql]
    if sql:
        print()
        print("SQL sent on hestore's driver cursor, per operation (counted in separate, untimed passes; an")
        print("executemany is one call, its parameter sets are 'rows'; TXN = BEGIN/COMMIT/SAVEPOINT/RELEASE/ROLLBACK):")
        print_table(["backend", "mesh", "what", "statements"], [[b, f"{s:,}", w, c] for b, s, w, c in sql], "lrll")
    for s in skipped:
        print(f"SKIPPED {s}")
    print()
    print("In-transaction timings exclude writing: hestore writes a transaction's changes at commit (or before a")
    print("read); the 1,000-edit figure includes them. The commit target (≤ 2 ms) is SPEC's for SQLite WAL; it is")
    print("applied to PostgreSQL as well. The floor is 12 single-row UPDATEs in engine.begin() on the same database.")
    print(f"Peak RSS: {peak_rss_mb():.0f} MiB")


if __name__ == "__main__":
    sys.exit(main())
