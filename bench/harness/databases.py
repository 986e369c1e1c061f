"""Where a benchmark run's databases live, plain-driver connections to them, and what a step does to them
around a timed region.

Called by `harness.bench.Bench` (one `Place` per backend for the run), by the benchmark scripts' parents (a
fresh database per step, ``place.fresh(name)``, handed to the step as its ``spec``) and by their steps, which
open hestore on ``url_of(spec)``, run their floors on `plain_connection` and call `settle` before a timed
region. A step's ``spec`` is a dict: ``backend``, and ``path`` (SQLite) or ``url``, ``schema`` and ``db_url``
(PostgreSQL).
"""

from __future__ import annotations

import contextlib
import os
import sqlite3
import uuid
from collections.abc import Iterator
from typing import Any, NamedTuple
from urllib.parse import quote

import sqlalchemy as sa

import hestore

#: Every table of hestore's schema (element tables, properties, history).
TABLES = tuple(hestore.schema.metadata.tables)


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
    """The URL hestore opens for a SQLite file."""
    return f"sqlite:///{path}"


def remove_sqlite(path: str) -> None:
    """Remove a SQLite file and its WAL, shared-memory and journal files, those that exist."""
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
    """Drop one schema of a PostgreSQL database and everything in it."""
    with pg_connect(db_url, autocommit=True) as conn:
        conn.execute(f'DROP SCHEMA IF EXISTS "{schema}" CASCADE')


class Place:
    """Where a run's databases live on one backend.

    SQLite: files in the work folder. PostgreSQL: a database ``hestore_bench_<random>`` made on the server for
    the run (dropped by `close`), one schema per database the benchmark asks for. `fresh` gives a step's spec;
    `url_of` turns it into the URL hestore opens; `drop` removes it.

    Parameters
    ----------
    backend : str
        ``"sqlite"`` or ``"postgresql"``.
    workdir : str
        The run's work folder.
    pg_url : str, optional
        The PostgreSQL server (any database on it) where the run's database is made.
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
        """A new, empty database called ``name`` (an existing one is dropped first): its spec."""
        if self.backend == "sqlite":
            path = os.path.join(self.workdir, f"{name}.db")
            remove_sqlite(path)
            return {"backend": "sqlite", "path": path}
        return {"backend": "postgresql", "url": pg_fresh_schema(self.db_url, name), "schema": name,
                "db_url": self.db_url}

    def drop(self, spec: dict) -> None:
        """Remove a database `fresh` made."""
        if self.backend == "sqlite":
            remove_sqlite(spec["path"])
        else:
            pg_drop_schema(self.db_url, spec["schema"])

    def close(self) -> None:
        """Drop the run's PostgreSQL database (SQLite files go with the work folder)."""
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


def open_store(spec: dict) -> contextlib.closing:
    """hestore opened on a step's database, closed at the end of the ``with`` block."""
    return contextlib.closing(hestore.open(url_of(spec)))


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
    """The id of the mesh called ``name``, read with the plain driver."""
    plain.cur.execute(f"SELECT id FROM meshes WHERE name = {plain.mark}", (name,))
    return plain.cur.fetchone()[0]


def settle(spec: dict) -> None:
    """Before a timed region: flush dirty pages, and on PostgreSQL run a CHECKPOINT, so that work left by the
    previous step does not land in this one."""
    os.sync()
    if spec.get("backend") == "postgresql":
        with pg_connect(spec["db_url"], autocommit=True) as conn:
            conn.execute("CHECKPOINT")


def vacuum(spec: dict, tables: tuple[str, ...] | list[str] = TABLES) -> None:
    """On PostgreSQL, ``VACUUM (ANALYZE)`` of some tables (by default hestore's), as autovacuum soon does after
    a bulk load (without it the first reads of each fresh page pay for setting hint bits, and the planner has
    no statistics); nothing on SQLite."""
    if spec["backend"] == "postgresql":
        with pg_connect(spec["url"], autocommit=True) as conn:
            for table in tables:
                conn.execute(f"VACUUM (ANALYZE) {table}")


def share_one_cpu(spec: dict) -> str | None:
    """Run this process and every PostgreSQL backend on the step's database on one CPU; say what was done.

    For figures that time two meshes side by side through two connections (each its own backend). On a machine
    with more than one CPU the scheduler keeps some backends on the client's CPU and others on another, and
    which is chance: here a round trip to a backend on the client's CPU took 24 µs, to one on the other CPU
    62 µs, worth 10–30 % of a one-polygon transaction of a dozen statements, to either mesh, whatever it
    stores. On one CPU each round trip is a switch between two processes, the same for both meshes.

    Needs Linux, a server on this machine and the right to set its processes' affinity (root or the server's
    user); otherwise nothing changes and the answer says why. None on SQLite (no server).
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
