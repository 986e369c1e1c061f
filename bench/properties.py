"""Benchmark: property columns, positions and single property values on a stored 1 M-triangle mesh (SPEC §9).

    python bench/properties.py [--backends sqlite,postgresql] [--n 710] [--runs 3] [--repeat 200]

Workload: the triangulated N×N vertex grid (``--n``, default 710: 1,005,362
triangles, 504,100 vertices), stored once per backend with
``store.import_arrays`` (untimed setup; on PostgreSQL followed by ``VACUUM
(ANALYZE)``). Every step below runs in a fresh process; before each timed
region it runs ``os.sync()`` and, on PostgreSQL, a ``CHECKPOINT``. Values are
random float64s drawn with a fixed seed.

Figures, each on SQLite (a file) and on PostgreSQL:

set, first         ``mesh.set_property_array("vertex", name, ids, values)``
                   over every vertex, on a property just declared (no value
                   stored yet): a float64 column ``t`` and a shape-(3,)
                   float64 column ``n3``.
set, overwrite     the same call again with other values: every old row is
                   deleted and the new ones written.
property_array     ``mesh.property_array("vertex", name)`` after it.
set_positions      ``mesh.set_positions(ids, (n, 3))`` of every vertex.
v[name] = value    one ``v["s"] = value`` outside any block (its own
                   transaction), on ``--repeat`` random vertices, handles
                   taken before the loop, every vertex holding a value
                   already (set untimed); median and p90 of the calls.

Floors, in the same database (the same SQLite file, through stdlib
``sqlite3`` configured as hestore configures its own; the same PostgreSQL
schema, through psycopg), on plain tables ``(id INTEGER PRIMARY KEY, v REAL)``
and ``(id, x, y, z)`` (``bigint`` / ``float8`` on PostgreSQL):

set, first         one transaction writing the same (id, value) rows into the
                   empty table: SQLite ``executemany`` of an INSERT;
                   PostgreSQL ``COPY FROM STDIN (FORMAT BINARY)`` of a buffer
                   built with numpy.
set, overwrite     one transaction: ``DELETE FROM`` the table, then the same
                   write (hestore also deletes every old row first).
property_array     ``SELECT id, v FROM f ORDER BY id`` into numpy: SQLite
                   ``fetchall`` + ``np.array`` and ``np.fromiter(cursor)``;
                   PostgreSQL ``fetchall`` + ``np.array`` and a binary
                   ``COPY TO`` of ``array_agg`` columns. The faster is the
                   floor; both are printed.
set_positions      one transaction updating x, y, z by id of every row of a
                   filled ``(id, x, y, z)`` table: SQLite ``executemany`` of
                   ``UPDATE ... WHERE id = ?``; PostgreSQL (where an
                   ``executemany`` of 504,100 UPDATEs is not what anyone
                   would write) one ``UPDATE ... FROM unnest(arrays)`` and
                   ``COPY`` into a temporary table + ``UPDATE ... FROM``; the
                   faster is the floor.
v[name] = value    a one-row UPDATE transaction (``BEGIN``; ``UPDATE s SET v
                   = ? WHERE id = ?``; ``COMMIT``), same vertices.

Targets: ≤ 2× the floor for the column figures (SPEC §9 states it for one
float column over 1 M vertices; applied to the shaped column, the overwrite
and ``set_positions``); ≤ 2 ms for a single value's transaction (the
one-polygon transaction's target, applied).

Each column figure is the median over ``--runs`` runs, each in a fresh
process; floor and hestore runs alternate. With ``--profile over`` (the
default) a figure over its target is run once more under cProfile and the
top functions are printed.

Correctness gates (the exit status is non-zero only when one fails or a step
crashes): every ``property_array`` gives back exactly the ids and values last
written, each floor's SELECT gives back what it wrote, the stored positions
after ``set_positions`` are the ones written (read with ``mesh.to_arrays()``,
untimed), and the single values read back are the ones last set.

Run alone or by ``bench/all.py`` (``tests/test_bench.py`` runs it with
``--quick``). This file keeps the workloads, the floors and the targets; the
harness (``bench/harness/``) parses the options, runs each step in a fresh
process on each backend and prints the report.
"""

from __future__ import annotations

import time

import numpy as np

import hestore

from floors import PGCOPY_HEADER, by_id, pg_copy_columns
from harness.bench import Bench
from harness.cli import Parser, at_least, wants_profile
from harness.databases import open_store, plain_connection, settle, url_of, vacuum
from harness.profiling import Statements
from harness.stats import finished, median, percentile
from harness.tables import Figure, fmt_time, verdict
from harness.timing import maxrss, time_each, timed
from workloads import import_mesh, mesh_label

QUICK = {"n": 60, "runs": 1, "repeat": 20, "profile": "off"}
TARGET_RATIO = 2.0  # × the floor, column figures
TARGET_SINGLE = 2e-3  # seconds, one value's transaction (median)
COUNTED = 20  # single sets of the untimed pass that counts hestore's statements
#: The two property columns: name, shape, the floor table's value columns.
COLUMNS = {"scalar": ("t", (), ("v",)), "vector": ("n3", (3,), ("x", "y", "z"))}
COLUMN_LABEL = {"scalar": "float64", "vector": "float64 (3,)"}
STEPS = ("set", "overwrite", "read")
STEP_LABEL = {
    "set": 'set_property_array("vertex", {name!r}) {what}, first',
    "overwrite": 'set_property_array("vertex", {name!r}) {what}, overwrite',
    "read": 'property_array("vertex", {name!r}) {what}',
}
POSITIONS = "set_positions of every vertex"
SINGLE = 'v["s"] = value, own transaction'
ABOUT = """\
Floors run in the same database (the same SQLite file through stdlib sqlite3 with hestore's pragmas;
the same PostgreSQL schema through psycopg) on plain tables keyed by id; every property_array and floor
SELECT is compared with the values last written, outside the timed regions."""


# ==========================================================================
# The workload


def column_values(what: str, n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Two different random value arrays of one column (the first write and the overwrite)."""
    shape = COLUMNS[what][1]
    rng = np.random.default_rng(seed)
    return rng.standard_normal((n, *shape)), rng.standard_normal((n, *shape))


def new_positions(n: int, seed: int) -> np.ndarray:
    return np.random.default_rng(seed).uniform(-1e3, 1e3, size=(n, 3))


# ==========================================================================
# Floors


def _create(plain, table: str, cols: tuple[str, ...]) -> None:
    """A fresh plain table ``(id primary key, cols...)`` of float columns."""
    real = "REAL" if plain.mark == "?" else "float8"
    key = "INTEGER PRIMARY KEY" if plain.mark == "?" else "bigint PRIMARY KEY"
    plain.cur.execute(f"DROP TABLE IF EXISTS {table}")
    plain.cur.execute(f"CREATE TABLE {table} (id {key}, {', '.join(f'{c} {real}' for c in cols)})")


def _rows(ids: np.ndarray, data: np.ndarray) -> list[tuple]:
    data = data.reshape(len(ids), -1)
    return list(zip(ids.tolist(), *(data[:, c].tolist() for c in range(data.shape[1]))))


def _pg_copy_binary(cur, table: str, cols: tuple[str, ...], ids: np.ndarray, data: np.ndarray) -> None:
    """``COPY table (id, cols) FROM STDIN (FORMAT BINARY)`` of one buffer built with numpy (no NULLs)."""
    data = data.reshape(len(ids), -1)
    fields = [("count", ">i2"), ("l0", ">i4"), ("v0", ">i8")]
    for c in range(len(cols)):
        fields += [(f"l{c + 1}", ">i4"), (f"v{c + 1}", ">f8")]
    block = np.empty(len(ids), dtype=fields)
    block["count"] = 1 + len(cols)
    block["l0"], block["v0"] = 8, ids
    for c in range(len(cols)):
        block[f"l{c + 1}"], block[f"v{c + 1}"] = 8, data[:, c]
    with cur.copy(f"COPY {table} (id, {', '.join(cols)}) FROM STDIN (FORMAT BINARY)") as copy:
        copy.write(PGCOPY_HEADER)
        copy.write(block.tobytes())
        copy.write(b"\xff\xff")


def _write(plain, backend: str, table: str, cols: tuple[str, ...], ids, data, *, delete: bool) -> None:
    """The write floor: one transaction (optionally emptying the table first) writing every row."""
    cur = plain.cur
    if backend == "sqlite":
        cur.execute("BEGIN")
        if delete:
            cur.execute(f"DELETE FROM {table}")
        marks = ", ".join("?" * (1 + len(cols)))
        cur.executemany(f"INSERT INTO {table} (id, {', '.join(cols)}) VALUES ({marks})", _rows(ids, data))
        cur.execute("COMMIT")
        return
    cur.execute("BEGIN")
    if delete:
        cur.execute(f"DELETE FROM {table}")
    _pg_copy_binary(cur, table, cols, ids, data)
    cur.execute("COMMIT")


def _select_fetchall(plain, table, cols):
    plain.cur.execute(f"SELECT id, {', '.join(cols)} FROM {table} ORDER BY id")
    return np.array(plain.cur.fetchall(), dtype=np.float64)


def _select_fromiter(plain, table, cols):
    plain.cur.execute(f"SELECT id, {', '.join(cols)} FROM {table} ORDER BY id")
    return np.fromiter(plain.cur, dtype=np.dtype((np.float64, (1 + len(cols),))))


def _select_copy(plain, table, cols):
    columns = pg_copy_columns(plain.cur, ["id", *cols], f"FROM {table}", [np.int64] + [np.float64] * len(cols))
    return by_id(np.column_stack([c.astype(np.float64) for c in columns]))


SELECTS = {
    "sqlite": {"fetchall + np.array": _select_fetchall, "np.fromiter(cursor)": _select_fromiter},
    "postgresql": {"fetchall + np.array": _select_fetchall, "COPY TO of array_agg + np.frombuffer": _select_copy},
}


def _split(rows: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """(ids, values) of a fetched float array: values of shape (n,) or (n, k)."""
    ids = rows[:, 0].astype(np.int64) if len(rows) else np.zeros(0, np.int64)
    vals = rows[:, 1:] if len(rows) else np.zeros((0, k))
    return ids, vals[:, 0] if k == 1 else vals


def job_floor_column(spec: dict) -> dict:
    """The column floors: first write, overwrite, and the SELECT variants, on a plain table."""
    what, V = spec["what"], spec["vertices"]
    _, _, cols = COLUMNS[what]
    ids = np.arange(V, dtype=np.int64)
    first, second = column_values(what, V, spec["seed"])
    plain = plain_connection(spec)
    table = f"floor_{what}"
    _create(plain, table, cols)
    out: dict = {"reads": {}}
    settle(spec)
    run = timed(lambda: _write(plain, spec["backend"], table, cols, ids, first, delete=False))
    out["set"] = [run.seconds, run.cpu]
    settle(spec)
    run = timed(lambda: _write(plain, spec["backend"], table, cols, ids, second, delete=True))
    out["overwrite"] = [run.seconds, run.cpu]
    problems = []
    for name, select in SELECTS[spec["backend"]].items():
        settle(spec)
        run = timed(lambda select=select: select(plain, table, cols))
        out["reads"][name] = [run.seconds, run.cpu]
        got_ids, got = _split(run.result, len(cols))
        if not (np.array_equal(got_ids, ids) and np.array_equal(got, second)):
            problems.append(f"floor {what}: {name} does not give back the rows written")
    plain.cur.execute(f"DROP TABLE {table}")
    plain.con.close()
    out.update(problems=problems, rss=maxrss())
    return out


def _update_positions(cur, way: str, ids: np.ndarray, xyz: np.ndarray) -> None:
    """One transaction updating x, y, z of every row of ``floor_positions``, the ``way`` named."""
    cur.execute("BEGIN")
    if way == "executemany UPDATE":
        rows = [(x, y, z, i) for i, x, y, z in _rows(ids, xyz)]
        cur.executemany("UPDATE floor_positions SET x = ?, y = ?, z = ? WHERE id = ?", rows)
    elif way.startswith("UPDATE"):
        cur.execute("UPDATE floor_positions f SET x = u.x, y = u.y, z = u.z "
                    "FROM unnest(%s::bigint[], %s::float8[], %s::float8[], %s::float8[]) AS u(id, x, y, z) "
                    "WHERE f.id = u.id", [ids.tolist(), *(xyz[:, c].tolist() for c in range(3))])
    else:
        cur.execute("CREATE TEMPORARY TABLE u (id bigint, x float8, y float8, z float8) ON COMMIT DROP")
        _pg_copy_binary(cur, "u", ("x", "y", "z"), ids, xyz)
        cur.execute("UPDATE floor_positions f SET x = u.x, y = u.y, z = u.z FROM u WHERE f.id = u.id")
    cur.execute("COMMIT")


def job_floor_positions(spec: dict) -> dict:
    """The set_positions floor: every row of a filled (id, x, y, z) table updated in one transaction."""
    V, backend = spec["vertices"], spec["backend"]
    ids = np.arange(V, dtype=np.int64)
    xyz = new_positions(V, spec["seed"] + 1)
    old = new_positions(V, spec["seed"] + 2)
    plain = plain_connection(spec)
    cur = plain.cur
    cols = ("x", "y", "z")
    variants: dict = {}
    problems = []
    if backend == "sqlite":
        ways = ["executemany UPDATE"]
    else:
        ways = ["UPDATE ... FROM unnest(arrays)", "COPY into a temporary table + UPDATE ... FROM"]
    for way in ways:
        _create(plain, "floor_positions", cols)
        _write(plain, backend, "floor_positions", cols, ids, old, delete=False)
        vacuum(spec, ["floor_positions"])
        settle(spec)
        run = timed(lambda way=way: _update_positions(cur, way, ids, xyz))
        variants[way] = [run.seconds, run.cpu]
        got_ids, got = _split(_select_fetchall(plain, "floor_positions", cols), 3)
        if not (np.array_equal(got_ids, ids) and np.array_equal(got, xyz)):
            problems.append(f"floor positions: {way} did not store the positions written")
        cur.execute("DROP TABLE floor_positions")
    plain.con.close()
    return {"variants": variants, "problems": problems, "rss": maxrss()}


def job_floor_single(spec: dict) -> dict:
    """The single-value floor: one-row UPDATE transactions on a filled (id, v) table."""
    V, picks = spec["vertices"], spec["picks"]
    plain = plain_connection(spec)
    cur = plain.cur
    _create(plain, "floor_single", ("v",))
    _write(plain, spec["backend"], "floor_single", ("v",), np.arange(V, dtype=np.int64), np.zeros(V), delete=False)
    vacuum(spec, ["floor_single"])
    vals = np.random.default_rng(spec["seed"] + 3).standard_normal(len(picks)).tolist()
    items = list(zip(vals, picks))
    if spec["backend"] == "sqlite":
        def one(item):
            cur.execute("BEGIN")
            cur.execute("UPDATE floor_single SET v = ? WHERE id = ?", item)
            cur.execute("COMMIT")
    else:
        plain.con.autocommit = False

        def one(item):
            cur.execute("UPDATE floor_single SET v = %s WHERE id = %s", item)
            plain.con.commit()
    settle(spec)
    samples, _, cpu = time_each(one, items)
    if spec["backend"] == "postgresql":
        plain.con.autocommit = True
    cur.execute("SELECT id, v FROM floor_single")
    stored = dict(cur.fetchall())
    problems = [] if all(stored[i] == v for v, i in items) else ["floor single: a value read back differs"]
    cur.execute("DROP TABLE floor_single")
    plain.con.close()
    return {"samples": samples, "cpu": cpu, "problems": problems, "rss": maxrss()}


# ==========================================================================
# hestore


def _open(spec: dict):
    store = hestore.open(url_of(spec))
    return store, store.mesh("grid")


def _declare(spec: dict, mesh, name: str, shape: tuple, default=None) -> None:
    """A fresh property (an earlier run's one removed first, its dead rows vacuumed on PostgreSQL)."""
    if name in mesh.properties("vertex"):
        mesh.remove_property("vertex", name)
        vacuum(spec, ["property_reals"])
    mesh.add_property("vertex", name, "float64", shape=shape, default=default)


def job_column(spec: dict) -> dict:
    """``set_property_array`` twice (first write, overwrite) and ``property_array`` of one column."""
    what, V = spec["what"], spec["vertices"]
    name, shape, _ = COLUMNS[what]
    ids = np.arange(V, dtype=np.int64)
    first, second = column_values(what, V, spec["seed"])
    profile = spec.get("profile", [])
    store, mesh = _open(spec)
    _declare(spec, mesh, name, shape)
    out: dict = {"profiles": {}}
    for step, fn in (("set", lambda: mesh.set_property_array("vertex", name, ids, first)),
                     ("overwrite", lambda: mesh.set_property_array("vertex", name, ids, second)),
                     ("read", lambda: mesh.property_array("vertex", name))):
        settle(spec)
        run = timed(fn, profile=step in profile)
        out[step] = [run.seconds, run.cpu]
        if run.profile:
            out["profiles"][step] = [run.profile, run.dominant]
    got_ids, got = run.result
    problems = []
    if not (np.array_equal(got_ids, ids) and np.array_equal(np.ma.getdata(got), second)
            and not np.ma.is_masked(got)):
        problems.append(f"{what}: property_array does not give back the ids and values last written")
    store.close()
    out.update(problems=problems, rss=maxrss())
    return out


def job_positions(spec: dict) -> dict:
    """``set_positions`` of every vertex."""
    V = spec["vertices"]
    ids = np.arange(V, dtype=np.int64)
    xyz = new_positions(V, spec["seed"] + 1 + spec["run"])
    store, mesh = _open(spec)
    settle(spec)
    run = timed(lambda: mesh.set_positions(ids, xyz), profile=bool(spec.get("profile")))
    arrays = mesh.to_arrays()
    problems = []
    if not (np.array_equal(arrays.vertex_ids, ids) and np.array_equal(arrays.positions, xyz)):
        problems.append("set_positions: the stored positions are not the ones written")
    store.close()
    return {"set": [run.seconds, run.cpu], "profiles": {"set": [run.profile, run.dominant]} if run.profile else {},
            "problems": problems, "rss": maxrss()}


def job_single(spec: dict) -> dict:
    """``v["s"] = value`` on ``--repeat`` random vertices, each its own transaction."""
    picks = spec["picks"]
    store, mesh = _open(spec)
    _declare(spec, mesh, "s", (), 0.0)
    # Every vertex holds a value first (untimed), as every row of the floor's table does.
    mesh.set_property_array("vertex", "s", np.arange(spec["vertices"]), np.zeros(spec["vertices"]))
    vacuum(spec, ["property_reals"])
    handles = [mesh.vertex(i) for i in picks]
    vals = np.random.default_rng(spec["seed"] + 3).standard_normal(len(picks)).tolist()
    items = list(zip(handles, vals))

    def one(item):
        item[0]["s"] = item[1]

    settle(spec)
    if spec.get("profile"):
        run = timed(lambda: time_each(one, items), profile=True)
        samples, _, cpu = run.result
        profiles = {"single": [run.profile, run.dominant]}
    else:
        samples, _, cpu = time_each(one, items)
        profiles = {}
    problems = [] if all(v["s"] == x for v, x in items) else ['v["s"]: a value read back differs from the one set']
    counter = Statements()
    others = [mesh.vertex(int(i)) for i in picks[:COUNTED]]
    with store.session.traced(counter):
        for v in others:
            v["s"] = 1.5
    store.close()
    return {"samples": samples, "cpu": cpu, "statements": dict(counter.by_word), "profiles": profiles,
            "problems": problems, "rss": maxrss()}


def job_setup(spec: dict) -> dict:
    """Store the grid (untimed) and VACUUM (ANALYZE) on PostgreSQL."""
    t0 = time.perf_counter()
    with open_store(spec) as store:
        report = import_mesh(store, "grid", spec["n"], "")
        counts = report.mesh.counts()
        ids = report.mesh.to_arrays().vertex_ids
    seconds = time.perf_counter() - t0
    vacuum(spec)
    return {"seconds": seconds, "vertices": counts.vertices, "polygons": counts.polygons,
            "dense": bool(np.array_equal(ids, np.arange(len(ids))))}


JOBS = {"setup": job_setup, "floor_column": job_floor_column, "floor_positions": job_floor_positions,
        "floor_single": job_floor_single, "column": job_column, "positions": job_positions, "single": job_single}


# ==========================================================================
# The parent


def main(argv=None) -> int:
    ap = Parser(__doc__, quick=QUICK, grid=710, jobs=JOBS, profile=True, seed=20240601)
    ap.add_argument("--runs", type=at_least(1), default=3,
                    help="runs of each column figure (default 3), each in a fresh process")
    ap.add_argument("--repeat", type=at_least(1), default=200,
                    help="single-value transactions per run (default 200)")
    args = ap.parse_args(argv)

    setups: dict = {}  # backend -> result
    runs: dict = {}  # (backend, job, what) -> [result per run]
    with Bench(args, "properties", __file__) as bench:
        for place in bench.for_each_backend():
            bname = place.backend
            spec = dict(place.fresh("properties_grid"), n=args.n, seed=args.seed)
            setups[bname] = setup = bench.runner.run(job="setup", **spec)
            if setup is None:
                continue
            V = setup["vertices"]
            picks = np.random.default_rng(args.seed).choice(V, size=min(args.repeat, V), replace=False).tolist()
            spec.update(mesh="grid", vertices=V, picks=picks)
            pairs = [("floor_column", "column", w) for w in COLUMNS]
            pairs += [("floor_positions", "positions", ""), ("floor_single", "single", "")]
            for r in range(args.runs):
                for floor_job, job, what in pairs:
                    order = (floor_job, job) if r % 2 == 0 else (job, floor_job)
                    for j in order:
                        runs.setdefault((bname, j, what), []).append(bench.runner.run(job=j, what=what, run=r, **spec))
            profile_over(bench, spec, bname, runs)
            place.drop(spec)
    report(bench, setups, runs)
    return bench.finish()


# ==========================================================================
# Figures


def _one_shot(results: list[dict], step: str) -> tuple[float, float] | None:
    """(median seconds, median CPU) of one step over the runs."""
    if not results:
        return None
    return median([r[step][0] for r in results]), median([r[step][1] for r in results])


def _variants(results: list[dict], field: str) -> dict[str, float]:
    """Median seconds of each floor variant over the runs."""
    names = results[0][field] if results else {}
    return {name: median([r[field][name][0] for r in results]) for name in names}


def column_figures(runs: dict, bname: str, label: str) -> list[tuple[str, str, str, Figure]]:
    """(job, what, step, Figure) of every column-like figure of one backend (the columns and set_positions)."""
    out = []
    for what, (name, _, _) in COLUMNS.items():
        mine, floor = finished(runs, (bname, "column", what)), finished(runs, (bname, "floor_column", what))
        for step in STEPS:
            got = _one_shot(mine, step)
            if got is None:
                continue
            parts = ""
            if step == "read":
                variants = _variants(floor, "reads")
                fl = min(variants.values()) if variants else None
                if variants:
                    parts = min(variants, key=variants.get)
            else:
                fl_run = _one_shot(floor, step)
                fl = fl_run[0] if fl_run else None
            ok = None if fl is None else got[0] <= TARGET_RATIO * fl
            fig = Figure(STEP_LABEL[step].format(name=name, what=COLUMN_LABEL[what]), bname, got[0], fl,
                         f"≤ {TARGET_RATIO:g}× floor", verdict(ok), label, n=len(mine), cpu=got[1],
                         rss=max(r["rss"] for r in mine), floor_parts=parts)
            out.append(("column", what, step, fig))
    mine, floor = finished(runs, (bname, "positions", "")), finished(runs, (bname, "floor_positions", ""))
    got = _one_shot(mine, "set")
    if got is not None:
        variants = _variants(floor, "variants")
        fl = min(variants.values()) if variants else None
        ok = None if fl is None else got[0] <= TARGET_RATIO * fl
        fig = Figure(POSITIONS, bname, got[0], fl, f"≤ {TARGET_RATIO:g}× floor (applied)", verdict(ok), label,
                     n=len(mine), cpu=got[1], rss=max(r["rss"] for r in mine),
                     floor_parts=min(variants, key=variants.get) if variants else "")
        out.append(("positions", "", "set", fig))
    return out


def single_figure(runs: dict, bname: str, label: str) -> Figure | None:
    mine, floor = finished(runs, (bname, "single", "")), finished(runs, (bname, "floor_single", ""))
    if not mine:
        return None
    calls = [s / 1e9 for r in mine for s in r["samples"]]
    floor_calls = [s / 1e9 for r in floor for s in r["samples"]]
    t = median(calls)
    cpu = median([r["cpu"] / len(r["samples"]) for r in mine])
    return Figure(SINGLE, bname, t, median(floor_calls) if floor_calls else None, f"≤ {fmt_time(TARGET_SINGLE)}",
                  verdict(t <= TARGET_SINGLE), label, n=len(calls), p90=percentile(calls, 0.9), cpu=cpu,
                  rss=max(r["rss"] for r in mine))


def profile_over(bench: Bench, spec: dict, bname: str, runs: dict) -> None:
    """Run each figure over its target (or every one, with ``--profile all``) once more under cProfile."""
    args = bench.args
    if args.profile == "off":
        return
    label = mesh_label("grid", args.n)
    chosen: dict = {}
    for job, what, step, fig in column_figures(runs, bname, label):
        if wants_profile(args, fig.verdict == "over"):
            chosen.setdefault((job, what), []).append(step)
    fig = single_figure(runs, bname, label)
    if fig is not None and wants_profile(args, fig.verdict == "over"):
        chosen[("single", "")] = ["single"]
    for (job, what), steps in chosen.items():
        prof = bench.runner.run(job=job, what=what, run=args.runs, profile=steps, **spec)
        if not prof:
            continue
        for step, (text, dominant) in prof["profiles"].items():
            if job == "column":
                title = STEP_LABEL[step].format(name=COLUMNS[what][0], what=COLUMN_LABEL[what])
            else:
                title = SINGLE if job == "single" else POSITIONS
            seconds = prof[step][0] if step in prof else sum(prof["samples"]) / 1e9
            bench.report.profiles.append((f"{bname}: {title} under cProfile ({seconds:.2f} s with the profiler on)",
                                          dominant, text))


def variant_rows(runs: dict, bname: str) -> list[list[str]]:
    """Every floor variant of one backend, beside hestore's ratio to it."""
    rows = []
    for what in COLUMNS:
        floor = finished(runs, (bname, "floor_column", what))
        mine = _one_shot(finished(runs, (bname, "column", what)), "read")
        for variant, seconds in _variants(floor, "reads").items():
            ratio = f"{mine[0] / seconds:.2f}×" if mine and seconds else "—"
            rows.append([f"read {COLUMN_LABEL[what]}", bname, variant, fmt_time(seconds), ratio])
        for step in ("set", "overwrite"):
            got, mine_step = _one_shot(floor, step), _one_shot(finished(runs, (bname, "column", what)), step)
            if got:
                way = "executemany INSERT" if bname == "sqlite" else "COPY FROM STDIN (FORMAT BINARY), numpy"
                if step == "overwrite":
                    way = "DELETE FROM + " + way
                ratio = f"{mine_step[0] / got[0]:.2f}×" if mine_step else "—"
                rows.append([f"{step} {COLUMN_LABEL[what]}", bname, way, fmt_time(got[0]), ratio])
    floor = finished(runs, (bname, "floor_positions", ""))
    mine = _one_shot(finished(runs, (bname, "positions", "")), "set")
    for variant, seconds in _variants(floor, "variants").items():
        ratio = f"{mine[0] / seconds:.2f}×" if mine and seconds else "—"
        rows.append(["set_positions", bname, variant, fmt_time(seconds), ratio])
    return rows


def report(bench: Bench, setups: dict, runs: dict) -> None:
    args, rep = bench.args, bench.report
    figures: list[Figure] = []
    variants: list[list[str]] = []
    label = mesh_label("grid", args.n)
    for bname in args.backends:
        setup = setups.get(bname)
        if not setup:
            continue
        rep.notes.append(f"{bname}: grid stored in {setup['seconds']:.1f} s (setup, not a figure): "
                         f"{setup['vertices']:,} vertices, {setup['polygons']:,} triangles")
        if not setup["dense"]:
            rep.problems.append(f"{bname}: the grid's vertex ids are not 0..{setup['vertices'] - 1}")
        for key, results in runs.items():
            if key[0] == bname:
                for r in results:
                    rep.problems.extend(f"{bname}: {p}" for p in (r or {}).get("problems", []))
        figures.extend(fig for *_, fig in column_figures(runs, bname, label))
        fig = single_figure(runs, bname, label)
        if fig is not None:
            figures.append(fig)
            kinds = finished(runs, (bname, "single", ""))[0].get("statements", {})
            rep.notes.append(f"{bname}: {SINGLE}: statements hestore sent per call (untimed pass over {COUNTED} "
                             f"vertices, store.session.traced): {Statements.per_word(kinds, COUNTED)}")
        variants += variant_rows(runs, bname)
        for (b, job, what), results in sorted(runs.items()):
            if b == bname and job in ("column", "positions"):
                done = [r for r in results if r]
                for step in STEPS if job == "column" else ("set",):
                    each = ", ".join(fmt_time(r[step][0]) for r in done)
                    title = (STEP_LABEL[step].format(name=COLUMNS[what][0], what=COLUMN_LABEL[what])
                             if job == "column" else POSITIONS)
                    rep.notes.append(f"{bname}: {title}: each run {each}")

    rep.title(f"hestore property benchmark — the stored {label}, {args.runs} run(s) of each column figure, "
              f"{args.repeat} single-value transactions per run, each run in a {bench.runner.process}")
    rep.figures(figures, after="""\
(time: one call, the median of the runs (n); for the single value the median of all calls (n) of all
 runs, and the floor the median of the floor's calls; its CPU: the measuring process's user + system
 time, without the database server's; peak RSS: of the process that ran the figure's steps)""")
    rep.table("Floor variants, every one measured (median of the runs; ratio = hestore's time ÷ this variant's):",
              ["figure", "backend", "floor variant", "time", "hestore ÷"], variants, "lllrr")
    rep.close(ABOUT, profiles="Profiles of the figures over their target:")


if __name__ == "__main__":
    raise SystemExit(main())
