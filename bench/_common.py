"""What hestore's benchmarks (SPEC §9) share; each benchmark file keeps only its workloads and floors.

Nothing here is a figure by itself. In order:

* **timing**: `gc_paused` and `time_each` (a loop timed call by call with
  ``perf_counter_ns``, Python's cyclic collector paused), `median` and
  `percentile`, `timed` (one run, wall and CPU time, optionally under
  cProfile), `best_of`, `maxrss`;
* **reporting**: `fmt_time` and friends, `Figure` (one row: figure, backend,
  time, floor, ratio, target, verdict, and peak RSS where measured),
  `print_table`, `print_figures` and `print_markdown` (every benchmark's
  table), `print_machine` (the machine notes ending every output);
* **command line**: `Parser` (the options every benchmark takes, and
  ``--quick``), `selected_backends`, `selected_meshes`;
* **subprocesses**: `run_command`, `Runner` (each step of a benchmark in a
  fresh process, so that each figure has its own peak RSS and nothing cached
  carries over) and `child_main`, its other side;
* **databases**: `Place` / `open_backend` (where a run's databases live: SQLite
  files in the work folder, or schemas of a PostgreSQL database made for the
  run and dropped at its end), plain-driver connections (`sqlite_connect`,
  `pg_connect`, `plain_connection`), `pg_copy_columns` (a binary ``COPY TO``
  into numpy columns), `settle`, `vacuum_analyze`;
* **workloads**: the triangulated grid's arrays (`grid_arrays`), the shared
  large meshes (`FILES`, `meshes_dir`, `mesh_label`) and `import_mesh`.
"""

from __future__ import annotations

import argparse
import contextlib
import cProfile
import gc
import io
import json
import math
import os
import platform
import pstats
import resource
import sqlite3
import subprocess
import sys
import time
import uuid
from collections import Counter
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from typing import Any, NamedTuple
from urllib.parse import quote

import numpy as np
import sqlalchemy as sa

import hestore

DEFAULT_PG_URL = "postgresql+psycopg://postgres@127.0.0.1:5432/test"
BACKENDS = ("sqlite", "postgresql")
#: Every table of hestore's schema (element tables, properties, history).
TABLES = tuple(hestore.schema.metadata.tables)
HERE = os.path.dirname(os.path.abspath(__file__))


def log(msg: str) -> None:
    """A progress line on stderr (the figures go to stdout)."""
    print(f"[{time.strftime('%H:%M:%S')}] {msg}", file=sys.stderr, flush=True)


# ======================================================================================
# Timing

pc = time.perf_counter_ns


@contextlib.contextmanager
def gc_paused() -> Iterator[None]:
    """A timed loop's surroundings: a full collection first, then the cyclic collector off until the end."""
    gc.collect()
    gc.disable()
    try:
        yield
    finally:
        gc.enable()


class Loop(NamedTuple):
    """A loop timed call by call: nanoseconds per call, the calls' results, and the CPU seconds of the loop."""

    samples: list[int]
    results: list
    cpu: float


def time_each(fn: Callable[[Any], Any], items: Iterable) -> Loop:
    """``fn(item)`` for each item, each call timed alone with ``perf_counter_ns``, the collector paused."""
    samples: list[int] = []
    results: list = []
    append, keep = samples.append, results.append
    with gc_paused():
        c0 = cpu_seconds()
        for item in items:
            t0 = pc()
            r = fn(item)
            t1 = pc()
            append(t1 - t0)
            keep(r)
        cpu = cpu_seconds() - c0
    return Loop(samples, results, cpu)


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


def maxrss() -> int:
    """Peak RSS of this process so far, in bytes."""
    kb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return kb * 1024 if sys.platform != "darwin" else kb


def cpu_seconds() -> float:
    """User + system CPU time of this process so far."""
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


class Timed(NamedTuple):
    """One timed run: its result, wall seconds, CPU seconds, and with a profile its text and heaviest function."""

    result: Any
    seconds: float
    cpu: float
    profile: str | None = None
    dominant: str | None = None


def timed(fn: Callable[[], Any], *, profile: bool = False, lines: int = 20) -> Timed:
    """Run ``fn()`` once, timed (wall clock and this process's CPU), under cProfile when ``profile``.

    The profile text has the top ``lines`` functions by own time and by
    cumulative time; ``dominant`` names the function with the most own time
    and hestore's functions by cumulative time.
    """
    profiler = cProfile.Profile() if profile else None
    c0 = cpu_seconds()
    t0 = pc()
    if profiler:
        profiler.enable()
    result = fn()
    if profiler:
        profiler.disable()
    seconds = (pc() - t0) / 1e9
    cpu = cpu_seconds() - c0
    if not profiler:
        return Timed(result, seconds, cpu)
    text, dominant = profile_report(profiler, lines)
    return Timed(result, seconds, cpu, text, dominant)


def profile_report(profiler: cProfile.Profile, lines: int = 20) -> tuple[str, str]:
    """A finished profile as ``(text, dominant)``: the top ``lines`` functions by own time and by cumulative
    time, and a line naming the function with the most own time and hestore's functions by cumulative time."""
    raw = pstats.Stats(profiler)
    ours = f"{os.sep}hestore{os.sep}"
    mine = sorted(((row[3], f"{func} ({os.path.basename(file)}:{line})")
                   for (file, line, func), row in raw.stats.items() if ours in file), reverse=True)
    buf = io.StringIO()
    stats = pstats.Stats(profiler, stream=buf).strip_dirs()
    stats.sort_stats("tottime").print_stats(lines)
    stats.sort_stats("cumulative").print_stats(lines)
    (file, line, func), row = max(stats.stats.items(), key=lambda kv: kv[1][2])
    heaviest = ", ".join(f"{name} {fmt_time(t)}" for t, name in mine[:5])
    dominant = (f"{func} ({file}:{line}): {fmt_time(row[2])} of its own time, {fmt_time(row[3])} with callees; "
                f"hestore's functions by time with callees: {heaviest}")
    return buf.getvalue(), dominant


def best_of(fn, *args, repeat: int = 2):
    """The fastest of ``repeat`` runs of ``fn(*args)`` in seconds, and the last run's result."""
    times, out = [], None
    for _ in range(repeat):
        out = None
        t0 = pc()
        out = fn(*args)
        times.append((pc() - t0) / 1e9)
    return min(times), out


# ======================================================================================
# Reporting


def fmt_time(seconds: float | None) -> str:
    """A duration in the unit that reads best: µs below 1 ms, ms below 0.1 s, else s."""
    if seconds is None or (isinstance(seconds, float) and math.isnan(seconds)):
        return "—"
    if seconds < 1e-3:
        us = seconds * 1e6
        return f"{us:.0f} µs" if us >= 100 else f"{us:.1f} µs"
    if seconds < 0.1:
        return f"{seconds * 1e3:.2f} ms"
    return f"{seconds:.2f} s"


def fmt_mib(b: int | None) -> str:
    return "—" if b is None else f"{b / 2**20:,.0f} MiB"


def fmt_ratio(r: float | None) -> str:
    return "—" if r is None else f"{r:.2f}×"


def verdict(ok: bool | None) -> str:
    """``ok`` / ``over`` beside a target, ``—`` without one."""
    return "—" if ok is None else ("ok" if ok else "over")


@dataclass
class Figure:
    """One row of a benchmark's table: a time beside its floor and target.

    ``time`` and ``floor`` are seconds; what ``time`` is (one run, a median of
    calls, a mean per vertex) each benchmark says in its notes.
    """

    name: str
    backend: str
    time: float | None
    floor: float | None = None
    target: str = "—"
    verdict: str = "—"
    mesh: str = ""
    n: int | None = None  # timed calls behind a median
    p90: float | None = None
    cpu: float | None = None  # user + system time of the measuring process
    rss: int | None = None  # its peak RSS, bytes
    floor_parts: str = ""

    @property
    def ratio(self) -> float | None:
        if self.time is None or not self.floor:
            return None
        return self.time / self.floor


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


# (header, alignment, cell, optional): optional columns are printed only when some figure has a value.
_COLUMNS = [
    ("figure", "l", lambda f: f.name, False),
    ("mesh", "r", lambda f: f.mesh, True),
    ("backend", "l", lambda f: f.backend, False),
    ("n", "r", lambda f: "" if f.n is None else f"{f.n:,}", True),
    ("time", "r", lambda f: fmt_time(f.time), False),
    ("p90", "r", lambda f: "" if f.p90 is None else fmt_time(f.p90), True),
    ("its CPU", "r", lambda f: "" if f.cpu is None else fmt_time(f.cpu), True),
    ("floor", "r", lambda f: fmt_time(f.floor), False),
    ("ratio", "r", lambda f: fmt_ratio(f.ratio), False),
    ("target", "l", lambda f: f.target, False),
    ("peak RSS", "r", lambda f: "" if f.rss is None else fmt_mib(f.rss), True),
    ("verdict", "l", lambda f: f.verdict, False),
]


def _columns(figures: list[Figure]):
    return [c for c in _COLUMNS if not c[3] or any(c[2](f) for f in figures)]


def print_figures(figures: list[Figure]) -> None:
    """The figures table (ratio = time ÷ floor), then each floor's parts where it has some."""
    cols = _columns(figures)
    print_table([c[0] for c in cols], [[c[2](f) or "—" for c in cols] for f in figures], "".join(c[1] for c in cols))
    parts = [[f.name, f.mesh, f.backend, f.floor_parts] for f in figures if f.floor_parts]
    if parts:
        print()
        print("Floor parts (seconds):")
        print_table(["figure", "mesh", "backend", "floor ="], parts, "lrll")


def print_markdown(figures: list[Figure]) -> None:
    """The same figures as a markdown table, the floor's parts beside it."""
    cols = _columns(figures)
    heads = [c[0] for c in cols]
    print()
    print("| " + " | ".join(heads) + " |")
    print("|" + "|".join("---:" if a == "r" else "---" for _, a, _, _ in cols) + "|")
    for f in figures:
        cells = []
        for head, _, cell, _ in cols:
            text = cell(f) or "—"
            if head == "floor" and f.floor_parts:
                text = f"{text} = {f.floor_parts}" if f.floor else f.floor_parts
            cells.append(text)
        print("| " + " | ".join(cells) + " |")


def print_machine(pg_version: str | None, load_start: tuple, elapsed: float, *, meshes: str | None = None,
                  libraries: str = "") -> None:
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
    print(f"  SQLite {sqlite3.sqlite_version} (journal_mode=WAL, synchronous=NORMAL, cache_size=64 MiB, "
          "as hestore sets)")
    print(f"  PostgreSQL {pg_version or '— (not run)'}, on the same machine")
    try:
        import psycopg

        drivers = f"psycopg {psycopg.__version__}"
    except ImportError:
        drivers = "psycopg not installed"
    print(f"  hestore {hestore.__version__}, Python {platform.python_version()}, numpy {np.__version__}, "
          f"SQLAlchemy {sa.__version__}, {drivers}" + (f", {libraries}" if libraries else ""))
    print(f"  {'meshes from ' + meshes + '; ' if meshes else ''}whole run {elapsed / 60:.1f} min")


# ======================================================================================
# Command line


class Parser(argparse.ArgumentParser):
    """The options every benchmark takes; ``--quick`` sets the benchmark's smoke-run defaults.

    Options given explicitly win over ``--quick``'s. The option groups a
    benchmark asks for: ``grid`` (``--n``), ``meshes`` (``--only``,
    ``--meshes-dir``), ``children`` (``--timeout``, and the hidden ``--child``
    that `Runner` passes), ``profile`` (``--profile``, with its help text),
    ``seed``.
    """

    def __init__(self, doc: str, *, quick: dict, workdir_help: str, grid: int | None = None, meshes: bool = False,
                 children: bool = False, profile: str | None = None, seed: int | None = None) -> None:
        super().__init__(description=doc.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
        self.quick = quick
        smoke = " ".join(f"--{k.replace('_', '-')} {v}" for k, v in quick.items()) or "each benchmark's own"
        self.add_argument("--quick", action="store_true", help=f"a smoke run of small sizes: {smoke}")
        self.add_argument("--backends", default=",".join(BACKENDS), help="sqlite and/or postgresql (default both)")
        self.add_argument("--pg-url", default=os.environ.get("HESTORE_BENCH_PG_URL", DEFAULT_PG_URL),
                          help="PostgreSQL server to use; a database is created there for the run and dropped at "
                               "the end (default $HESTORE_BENCH_PG_URL, else %(default)s)")
        self.add_argument("--workdir", help=workdir_help)
        if grid is not None:
            self.add_argument("--n", type=int, default=grid,
                              help=f"grid vertices per side (default {grid}: {2 * (grid - 1) ** 2:,} triangles)")
        if meshes:
            self.add_argument("--only", default=",".join(MESHES), help="meshes to run: grid, bunny, igea (default all)")
            self.add_argument("--meshes-dir", default=meshes_dir(),
                              help="folder of the shared mesh files (default $HESTORE_BENCH_MESHES, else "
                                   "../shared/meshes)")
        if profile:
            self.add_argument("--profile", choices=("over", "all", "off"), default="over", help=profile)
        if seed is not None:
            self.add_argument("--seed", type=int, default=seed, help="random seed (default %(default)s)")
        if children:
            self.add_argument("--timeout", type=float, default=1800, help="seconds allowed per step (default 1800)")
            self.add_argument("--child", help=argparse.SUPPRESS)

    def parse_args(self, args=None, namespace=None):
        argv = sys.argv[1:] if args is None else list(args)
        if "--quick" in argv:
            self.set_defaults(**self.quick)
        parsed = super().parse_args(argv, namespace)
        if getattr(parsed, "n", 2) < 2:
            self.error("--n must be at least 2")
        return parsed


def selected_backends(ap: argparse.ArgumentParser, args: argparse.Namespace) -> list[str]:
    backends = [b.strip() for b in args.backends.split(",") if b.strip()]
    for b in backends:
        if b not in BACKENDS:
            ap.error(f"unknown backend {b!r} (choose from {', '.join(BACKENDS)})")
    return backends


def selected_meshes(ap: argparse.ArgumentParser, args: argparse.Namespace,
                    files: dict[str, str] | None = None) -> tuple[list[str], list[str]]:
    """``(meshes, skipped)`` from ``--only``; a missing file skips its mesh. ``files``: the file of each mesh
    (default `FILES`; a benchmark's smaller stand-ins)."""
    files = FILES if files is None else files
    only = [m.strip() for m in args.only.split(",") if m.strip()]
    for m in only:
        if m not in MESHES:
            ap.error(f"unknown mesh {m!r} (choose from {', '.join(MESHES)})")
    skipped: list[str] = []
    for m in list(only):
        if m in files and not os.path.exists(os.path.join(args.meshes_dir, files[m])):
            skipped.append(f"{m}: {os.path.join(args.meshes_dir, files[m])} not found")
            only.remove(m)
    return only, skipped


# ======================================================================================
# Subprocesses


def run_command(argv: list[str], timeout: float | None, *, quiet: bool = False) -> tuple[int | None, float]:
    """Run ``argv`` (its stderr passed through, its stdout too unless ``quiet``): (exit status or None on timeout,
    seconds)."""
    t0 = pc()
    try:
        proc = subprocess.run(argv, timeout=timeout, stdout=subprocess.DEVNULL if quiet else None)
    except subprocess.TimeoutExpired:
        return None, (pc() - t0) / 1e9
    return proc.returncode, (pc() - t0) / 1e9


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
        keys = ("job", "backend", "mesh", "fmt", "kind", "what", "variant")
        what = " ".join(str(spec[k]) for k in keys if spec.get(k))
        if spec.get("profile"):
            what += " (under cProfile)"
        status, seconds = run_command([sys.executable, self.script, "--child", json.dumps(spec)], self.timeout,
                                      quiet=True)
        if status is None:
            self.errors.append(f"{what}: timed out after {self.timeout:.0f} s")
            log(self.errors[-1])
            return None
        if status != 0 or not os.path.exists(spec["result"]):
            self.errors.append(f"{what}: the child process failed (exit {status}; its traceback is above)")
            log(self.errors[-1])
            return None
        with open(spec["result"]) as f:
            result = json.load(f)
        os.remove(spec["result"])
        log(f"{what}: done in {seconds:.1f} s")
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


# ======================================================================================
# Databases


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


def pg_connect(url: str, *, autocommit: bool = False):
    """A plain psycopg connection on a SQLAlchemy-style URL (``options`` such as a search_path kept)."""
    import psycopg

    u = sa.engine.make_url(url)
    kw = {"host": u.host, "port": u.port, "user": u.username, "dbname": u.database}
    if u.password:
        kw["password"] = u.password
    if "options" in u.query:
        kw["options"] = u.query["options"]
    return psycopg.connect(autocommit=autocommit, **{k: v for k, v in kw.items() if v is not None})


def sqlite_url(path: str) -> str:
    return f"sqlite:///{path}"


def remove_sqlite(path: str) -> None:
    for suffix in ("", "-wal", "-shm", "-journal"):
        with contextlib.suppress(FileNotFoundError):
            os.remove(path + suffix)


def sqlite_connect(path: str) -> sqlite3.Connection:
    """A plain stdlib connection configured as hestore configures its own (autocommit: no implicit BEGIN)."""
    con = sqlite3.connect(path, isolation_level=None)
    con.execute("PRAGMA journal_mode=WAL")
    con.execute("PRAGMA synchronous=NORMAL")
    con.execute("PRAGMA cache_size=-65536")
    return con


def pg_schema_url(db_url: str, schema: str) -> str:
    """The URL of one schema of a PostgreSQL database: unqualified table names resolve into it."""
    return f"{db_url}?options={quote(f'-csearch_path={schema}')}"


def pg_fresh_schema(db_url: str, schema: str) -> str:
    """A new, empty schema (an existing one is dropped first); returns its URL."""
    with pg_connect(db_url, autocommit=True) as conn:
        conn.execute(f'DROP SCHEMA IF EXISTS "{schema}" CASCADE')
        conn.execute(f'CREATE SCHEMA "{schema}"')
    return pg_schema_url(db_url, schema)


def pg_drop_schema(db_url: str, schema: str) -> None:
    with pg_connect(db_url, autocommit=True) as conn:
        conn.execute(f'DROP SCHEMA IF EXISTS "{schema}" CASCADE')


class Place:
    """Where a run's databases live on one backend.

    SQLite: files in the work folder. PostgreSQL: a database
    ``hestore_bench_<random>`` made on the server for the run (dropped by
    `close`), one schema per database the benchmark asks for. `fresh` gives a
    step's spec: ``backend``, and ``path`` (SQLite) or ``url`` (the schema),
    ``schema`` and ``db_url`` (the run's database); `url_of` turns it into the
    URL hestore opens; `drop` removes it.
    """

    def __init__(self, backend: str, workdir: str, pg_url: str | None = None) -> None:
        self.backend = backend
        self.workdir = workdir
        self.db_url: str | None = None
        self.version: str | None = None
        if backend == "postgresql":
            self._admin = pg_url
            self._name = f"hestore_bench_{uuid.uuid4().hex[:10]}"
            with pg_connect(pg_url, autocommit=True) as conn:
                conn.execute(f'CREATE DATABASE "{self._name}"')
                self.version = conn.execute("SHOW server_version").fetchone()[0]
            self.db_url = sa.engine.make_url(pg_url).set(database=self._name).render_as_string(hide_password=False)

    def fresh(self, name: str) -> dict:
        """A new, empty database called ``name`` (an existing one is dropped first)."""
        if self.backend == "sqlite":
            path = os.path.join(self.workdir, f"{name}.db")
            remove_sqlite(path)
            return {"backend": "sqlite", "path": path}
        return {"backend": "postgresql", "url": pg_fresh_schema(self.db_url, name), "schema": name,
                "db_url": self.db_url}

    def drop(self, spec: dict) -> None:
        if self.backend == "sqlite":
            remove_sqlite(spec["path"])
        else:
            pg_drop_schema(self.db_url, spec["schema"])

    def close(self) -> None:
        if self.backend == "postgresql":
            with pg_connect(self._admin, autocommit=True) as conn:
                conn.execute(f'DROP DATABASE IF EXISTS "{self._name}" WITH (FORCE)')


@contextlib.contextmanager
def open_backend(backend: str, workdir: str, pg_url: str, skipped: list[str]) -> Iterator[Place | None]:
    """The `Place` of one backend for the run, closed at the end; None (and a line in ``skipped``) when
    PostgreSQL cannot be reached."""
    if backend == "postgresql":
        problem = pg_problem(pg_url)
        if problem:
            skipped.append(f"postgresql: not reachable at {pg_url}: {problem}")
            yield None
            return
    place = Place(backend, workdir, pg_url)
    try:
        yield place
    finally:
        place.close()


def url_of(spec: dict) -> str:
    """The URL hestore opens for a step's database."""
    return sqlite_url(spec["path"]) if spec["backend"] == "sqlite" else spec["url"]


class Plain(NamedTuple):
    """A plain-driver connection on a step's database, its cursor, how to begin one read snapshot, and the
    driver's placeholder."""

    con: Any
    cur: Any
    begin: str
    mark: str


def plain_connection(spec: dict) -> Plain:
    """A plain-driver connection on the step's database: `sqlite_connect`, or psycopg in autocommit."""
    if spec["backend"] == "sqlite":
        con = sqlite_connect(spec["path"])
        return Plain(con, con.cursor(), "BEGIN", "?")
    con = pg_connect(spec["url"], autocommit=True)
    return Plain(con, con.cursor(), "BEGIN ISOLATION LEVEL REPEATABLE READ READ ONLY", "%s")


def plain_mesh_id(plain: Plain, name: str) -> int:
    plain.cur.execute(f"SELECT id FROM meshes WHERE name = {plain.mark}", (name,))
    return plain.cur.fetchone()[0]


def settle(spec: dict) -> None:
    """Before a timed region: flush dirty pages, and on PostgreSQL run a CHECKPOINT,
    so that work left by the previous step does not land in this one."""
    os.sync()
    if spec.get("backend") == "postgresql":
        with pg_connect(spec["db_url"], autocommit=True) as conn:
            conn.execute("CHECKPOINT")


def share_one_cpu(spec: dict) -> str | None:
    """Run this process and every PostgreSQL backend on the step's database on one CPU; say what was done.

    For figures that time two meshes side by side through two connections
    (each its own backend). On a machine with more than one CPU the scheduler
    keeps some backends on the client's CPU and others on another, and which
    is chance: here a round trip to a backend on the client's CPU took 24 µs,
    to one on the other CPU 62 µs, worth 10–30 % of a one-polygon transaction
    of a dozen statements, to either mesh, whatever it stores. On one CPU each
    round trip is a switch between two processes, the same for both meshes.

    Needs Linux, a server on this machine and the right to set its processes'
    affinity (root or the server's user); otherwise nothing changes and the
    answer says why. None on SQLite (no server).
    """
    if spec.get("backend") != "postgresql":
        return None
    if not hasattr(os, "sched_setaffinity"):
        return "backends not placed: this system cannot set CPU affinity; round trips may differ by connection"
    host = sa.engine.make_url(spec["db_url"]).host
    if host not in (None, "", "localhost", "127.0.0.1", "::1") and not str(host).startswith("/"):
        return f"backends not placed: the server at {host} may be another machine; round trips may differ by connection"
    cpu = min(os.sched_getaffinity(0))
    with pg_connect(spec["db_url"], autocommit=True) as conn:
        pids = [row[0] for row in conn.execute(
            "SELECT pid FROM pg_stat_activity WHERE datname = current_database() AND pid <> pg_backend_pid()")]
    try:
        for pid in pids:
            with open(f"/proc/{pid}/comm") as f:
                if f.read().strip() != "postgres":
                    return f"backends not placed: process {pid} here is not the server's"
            os.sched_setaffinity(pid, {cpu})
    except OSError as exc:
        return f"backends not placed ({exc.__class__.__name__}: {exc}); round trips may differ by connection"
    os.sched_setaffinity(0, {cpu})
    return f"the timing process and its {len(pids)} server backends on CPU {cpu}, so that no connection is luckier"


def vacuum_analyze(spec: dict) -> None:
    """On PostgreSQL, ``VACUUM (ANALYZE)`` of hestore's tables, as autovacuum soon does after a bulk load
    (without it the first reads of each fresh page pay for setting hint bits); nothing on SQLite."""
    if spec["backend"] == "postgresql":
        with pg_connect(spec["url"], autocommit=True) as conn:
            for table in TABLES:
                conn.execute(f"VACUUM (ANALYZE) {table}")


def timed_check(store: hestore.Store, name: str) -> dict:
    """``mesh.check()`` of one stored mesh, timed (a correctness gate): seconds, violations, the first five,
    and ``counts`` V/H/E/P."""
    mesh = store.mesh(name)
    t0 = time.perf_counter()
    violations = mesh.check()
    seconds = time.perf_counter() - t0
    c = mesh.counts()
    return {"seconds": seconds, "violations": len(violations), "examples": [str(v) for v in violations[:5]],
            "counts": [c.vertices, c.halfedges, c.edges, c.polygons]}


def parse_cells(text: str) -> tuple[int, int]:
    """``"50x100"`` → (50, 100) cells."""
    try:
        w, h = (int(x) for x in text.lower().replace("×", "x").split("x"))
    except ValueError:
        raise ValueError(f"--small takes WxH cells, such as 50x100, not {text!r}") from None
    if w < 2 or h < 2:
        raise ValueError("--small needs at least 2x2 cells")
    return w, h


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


# ======================================================================================
# Workloads: the triangulated grid and the shared large meshes

FILES = {"bunny": "stanford-bunny-subdiv2.obj", "igea": "igea-subdiv1.ply"}
MESHES = ("grid", "bunny", "igea")


def meshes_dir() -> str:
    """``$HESTORE_BENCH_MESHES``, else ``../shared/meshes`` next to the repository."""
    env = os.environ.get("HESTORE_BENCH_MESHES")
    if env:
        return env
    return os.path.normpath(os.path.join(HERE, "..", "..", "shared", "meshes"))


def grid_arrays(n: int, m: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The triangulated n×n vertex grid (n×m: ``m`` rows of ``n``): positions (nm, 3) and triangles
    (2(n-1)(m-1), 3), counter-clockwise.

    Vertex ``j·n + i`` is at ``(i, j, 0)``; cell ``(i, j)``, ``c = j·(n-1) + i``, holds triangles ``2c``
    ``(v, v+1, v+n+1)`` and ``2c+1`` ``(v, v+n+1, v+n)`` with ``v = j·n + i``.
    """
    m = n if m is None else m
    j, i = np.divmod(np.arange(n * m, dtype=np.int64), n)
    positions = np.column_stack([i, j, np.zeros(n * m)]).astype(np.float64)
    v = (np.arange(m - 1)[:, None] * n + np.arange(n - 1)[None, :]).ravel()
    faces = np.empty((2 * len(v), 3), dtype=np.int64)
    faces[0::2] = np.column_stack([v, v + 1, v + n + 1])
    faces[1::2] = np.column_stack([v, v + n + 1, v + n])
    return positions, faces


def mesh_label(mesh: str, n: int, files: dict[str, str] = FILES) -> str:
    if mesh == "grid":
        return f"grid {n}×{n}"
    return files[mesh]


def import_mesh(store: hestore.Store, mesh: str, n: int, folder: str, grid: tuple | None = None, *,
                files: dict[str, str] = FILES, **options):
    """Store one workload mesh under its own name: the grid through ``store.import_arrays`` (``grid``: its
    arrays, when the caller made them before a timed region), a shared file through ``store.import_file``
    (``files``: the file of each mesh). ``options`` (``on_error``, ``orient``, ...) go to the import.
    Returns hestore's import report."""
    if mesh == "grid":
        positions, faces = grid if grid is not None else grid_arrays(n)
        return store.import_arrays("grid", positions, faces, **options)
    return store.import_file(os.path.join(folder, files[mesh]), mesh, **options)


class Statements:
    """Counts the statements hestore sends on its driver cursor, by kind: install with
    ``store.session.traced(counter)``.

    The callback sees the SQL text only: an ``executemany`` counts as one
    statement, and how many parameter sets (rows) it carried is not known.
    """

    KINDS = ("SELECT", "INSERT", "UPDATE", "DELETE", "TXN")

    def __init__(self) -> None:
        self.by_kind: Counter = Counter()

    def __call__(self, sql: str) -> None:
        word = sql.lstrip().split(None, 1)[0].upper()
        if word in ("WITH", "(SELECT"):
            word = "SELECT"
        self.by_kind[word if word in self.KINDS else "TXN"] += 1  # TXN: BEGIN, COMMIT, SAVEPOINT, RELEASE, ...

    def snapshot(self) -> Counter:
        return Counter(self.by_kind)

    @classmethod
    def per(cls, counts: Counter, n: int) -> str:
        """Statements per operation, by kind."""
        parts = [f"{k} {counts[k] / n:.3g}" for k in cls.KINDS if counts[k]]
        return f"{sum(counts.values()) / n:.3g} statements: " + ", ".join(parts)


def print_profiles(heading: str, profiles: list[tuple[str, str, str]]) -> None:
    """Print ``(title, heaviest function, cProfile text)`` profiles under ``heading`` (nothing if there are none)."""
    if not profiles:
        return
    print()
    print(heading)
    for title, dominant, text in profiles:
        print(f"  {title}")
        print(f"    heaviest: {dominant}")
        for line in text.splitlines():
            print(f"    {line}")
