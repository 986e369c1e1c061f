"""The store: a database connection, its transactions, and the mesh catalogue.

A `Store` owns one SQLAlchemy connection whose driver runs in autocommit
mode; hestore issues ``BEGIN``/``COMMIT``/``SAVEPOINT`` itself. That gives
exactly the semantics of SPEC §4 on both databases:

* outside a ``with store.transaction():`` block every read is one
  autocommitted statement (it sees the latest commit and holds no snapshot),
  and every mutating call is its own write transaction;
* a block is one write transaction (SQLite: ``BEGIN IMMEDIATE``, so the
  database's single writer lock is taken up front; PostgreSQL: ``BEGIN``);
  nested blocks are savepoints;
* before its first change to a mesh, a write transaction locks that mesh's
  row in ``meshes`` (``SELECT ... FOR UPDATE`` on PostgreSQL), so writers to
  one mesh are serialized and writers to different meshes are not. A lock
  not granted within ``busy_timeout`` raises `StoreBusyError`.

Edits are collected in one `hestore.unitofwork.UnitOfWork` per mesh and
written (flushed) before any read, before a savepoint, and at commit. The
mesh's revision grows by one in the first flush of a transaction that
changes it.

A store is not thread-safe: open one per thread or process.
"""

from __future__ import annotations

import math
import os
import sys
from contextlib import contextmanager
from typing import Any, Iterator

import sqlalchemy as sa
from sqlalchemy import event
from sqlalchemy.pool import StaticPool

from hestore import schema
from hestore.errors import (
    HestoreError,
    InvalidInputError,
    MeshExistsError,
    MeshNotFoundError,
    SchemaVersionError,
    StoreBusyError,
)
from hestore.statements import StatementCache
from hestore.unitofwork import MeshSQL, UnitOfWork

__all__ = ["open", "Store", "DEFAULT_URL"]

#: Where `open` goes when given no URL and ``$HESTORE_URL`` is unset.
DEFAULT_URL = "sqlite:///hestore.db"

_BUSY_SQLSTATES = {"55P03", "40P01", "40001"}  # lock_not_available, deadlock, serialization


def _resolve_url(url: str | sa.engine.URL | None) -> sa.engine.URL:
    if url is None:
        url = os.environ.get("HESTORE_URL") or DEFAULT_URL
    if isinstance(url, str) and "://" not in url:
        url = f"sqlite:///{url}"  # a bare path means a SQLite file
    try:
        return sa.engine.make_url(url)
    except sa.exc.ArgumentError as exc:
        raise InvalidInputError(f"not a database URL: {url!r} ({exc})") from None


def _is_memory(url: sa.engine.URL) -> bool:
    return url.get_backend_name() == "sqlite" and url.database in (None, "", ":memory:")


def _busy(exc: BaseException) -> bool:
    orig = getattr(exc, "orig", None) or exc
    if getattr(orig, "sqlstate", None) in _BUSY_SQLSTATES:
        return True
    text = str(orig).lower()
    return orig.__class__.__name__ == "OperationalError" and ("locked" in text or "busy" in text)


@contextmanager
def _translate_busy(what: str) -> Iterator[None]:
    try:
        yield
    except HestoreError:
        raise
    except Exception as exc:
        if _busy(exc):
            raise StoreBusyError(f"{what}: another writer holds the lock ({str(getattr(exc, 'orig', exc)).strip()})") from exc
        raise


def open(url: str | sa.engine.URL | None = None, *, busy_timeout: float = 5.0) -> "Store":
    """Open (and if new, create) a hestore database.

    Parameters
    ----------
    url : str or sqlalchemy.engine.URL, optional
        A SQLAlchemy URL: ``"sqlite:///path.db"``, ``"sqlite://"`` (in
        memory), ``"postgresql+psycopg://user@host/db"``; a bare path means a
        SQLite file. Default: ``$HESTORE_URL``, else ``./hestore.db``.
    busy_timeout : float
        Seconds to wait for another writer's lock before `StoreBusyError`.

    Returns
    -------
    Store

    Raises
    ------
    SchemaVersionError
        The database was made by another version of hestore; run
        ``hestore db upgrade``.

    Examples
    --------
    >>> import hestore
    >>> store = hestore.open("sqlite://")
    >>> store.meshes()
    []
    >>> store.close()
    """
    return Store(_resolve_url(url), busy_timeout=busy_timeout)


class Store:
    """A hestore database: named meshes and the transactions that edit them.

    Use `open` to make one. A store is a context manager that closes itself.
    """

    def __init__(self, url: sa.engine.URL, *, busy_timeout: float = 5.0) -> None:
        if not (isinstance(busy_timeout, (int, float)) and math.isfinite(busy_timeout) and busy_timeout >= 0):
            raise InvalidInputError(f"busy_timeout must be a number of seconds ≥ 0, not {busy_timeout!r}")
        self.url = url
        self.busy_timeout = float(busy_timeout)
        self._engine = self._make_engine(url)
        self._conn = self._engine.connect()
        self._raw = self._conn.connection.dbapi_connection
        self._cur = self._raw.cursor()
        self._sqlite = self._engine.dialect.name == "sqlite"
        self.statements = StatementCache(self._engine.dialect)
        self._sql = MeshSQL(self.statements, lambda: self._cur)
        self._depth = 0
        self._uows: dict[int, UnitOfWork] = {}
        self._locked: set[int] = set()
        self._bumped: set[int] = set()
        self._closed = False
        try:
            self._ensure_schema()
        except BaseException:
            self.close()
            raise

    # -- connection ------------------------------------------------------

    def _make_engine(self, url: sa.engine.URL) -> sa.engine.Engine:
        timeout = self.busy_timeout
        if url.get_backend_name() == "sqlite":
            kwargs: dict[str, Any] = {"connect_args": {"timeout": timeout}}
            if _is_memory(url):
                kwargs["poolclass"] = StaticPool
                kwargs["connect_args"]["check_same_thread"] = False
            engine = sa.create_engine(url, isolation_level="AUTOCOMMIT", **kwargs)
            memory = _is_memory(url)

            @event.listens_for(engine, "connect")
            def _pragmas(dbapi_conn, _record):
                cur = dbapi_conn.cursor()
                if not memory:
                    cur.execute("PRAGMA journal_mode=WAL")
                # In WAL mode NORMAL loses no consistency, only the last commits on power loss.
                cur.execute("PRAGMA synchronous=NORMAL")
                # 64 MiB of page cache (default 2 MiB): random edits on a large mesh
                # touch pages all over the half-edge table and its indexes.
                cur.execute("PRAGMA cache_size=-65536")
                cur.close()

            return engine
        engine = sa.create_engine(url, isolation_level="AUTOCOMMIT")
        ms = max(1, int(timeout * 1000))

        @event.listens_for(engine, "connect")
        def _lock_timeout(dbapi_conn, _record):
            cur = dbapi_conn.cursor()
            cur.execute(f"SET lock_timeout = {ms}")
            cur.close()

        return engine

    def _ensure_schema(self) -> None:
        from hestore import migrate

        current = migrate.current_revision(self._conn)
        if current is None:
            if sa.inspect(self._conn).has_table("meshes"):
                raise SchemaVersionError(
                    f"{self._safe_url()} has a 'meshes' table but no hestore schema version; "
                    "if it is a hestore database, run `hestore db upgrade`"
                )
            self._begin()
            try:
                migrate.upgrade(self._conn)
                self._commit()
            except BaseException:
                self._rollback()
                raise
        elif current != schema.SCHEMA_REVISION:
            raise SchemaVersionError(
                f"{self._safe_url()} is at schema revision {current}, but this hestore needs "
                f"{schema.SCHEMA_REVISION}: run `hestore db upgrade` (hestore --db URL db upgrade)"
            )

    def _safe_url(self) -> str:
        return self.url.render_as_string(hide_password=True)

    def __repr__(self) -> str:
        return f"Store({self._safe_url()!r})"

    def close(self) -> None:
        """Roll back anything uncommitted and close the connection."""
        if self._closed:
            return
        self._closed = True
        try:
            if self._in_txn():
                self._raw_exec("ROLLBACK")
        finally:
            self._conn.close()
            self._engine.dispose()
            # Graph views cached for this store can be large: free them now, not at garbage collection.
            graphs = sys.modules.get("hestore.graphs")
            if graphs is not None:
                graphs._cache.pop(self, None)

    def __enter__(self) -> "Store":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # -- raw transaction control ------------------------------------------

    def _raw_exec(self, sql: str) -> None:
        self._cur.execute(sql)

    def _in_txn(self) -> bool:
        if self._sqlite:
            return self._raw.in_transaction
        return self._raw.info.transaction_status != 0  # psycopg: 0 = IDLE

    def _begin(self) -> None:
        with _translate_busy("could not start a write transaction"):
            self._raw_exec("BEGIN IMMEDIATE" if self._sqlite else "BEGIN")

    def _commit(self) -> None:
        with _translate_busy("could not commit"):
            if self._in_txn():
                self._raw_exec("COMMIT")
        self._forget()

    def _rollback(self) -> None:
        if self._closed:  # close() already rolled back
            self._forget()
            return
        try:
            if self._in_txn():
                self._raw_exec("ROLLBACK")
        finally:
            self._forget()

    def _forget(self) -> None:
        self._uows.clear()
        self._locked.clear()
        self._bumped.clear()

    @property
    def in_transaction(self) -> bool:
        """Whether a ``with store.transaction():`` block is open."""
        return self._depth > 0

    @contextmanager
    def transaction(self) -> Iterator["Store"]:
        """A block whose edits commit together or not at all.

        An exception leaving the block rolls everything in it back; nested
        blocks are savepoints. Reads inside see the block's own edits; other
        connections see them only after the outermost block commits.

        Examples
        --------
        >>> import hestore
        >>> store = hestore.open("sqlite://")
        >>> mesh = store.create_mesh("m")
        >>> with store.transaction():
        ...     a, b = mesh.add_vertex(), mesh.add_vertex()
        ...     e = mesh.add_edge(a, b)
        >>> mesh.counts().edges, mesh.revision
        (1, 1)
        >>> try:
        ...     with store.transaction():
        ...         mesh.remove_edge(e)
        ...         raise RuntimeError("changed my mind")
        ... except RuntimeError:
        ...     pass
        >>> mesh.counts().edges, mesh.revision
        (1, 1)
        """
        self._check_open()
        if self._depth == 0:
            self._begin()
            self._depth = 1
            try:
                yield self
                self._check_open()
                self._flush()
                self._commit()
            except BaseException:
                self._rollback()
                raise
            finally:
                self._depth = 0
            return
        self._flush()
        name = f"hestore_sp{self._depth}"
        self._raw_exec(f"SAVEPOINT {name}")
        snapshot = (set(self._locked), set(self._bumped))
        self._depth += 1
        try:
            yield self
            self._check_open()
            self._flush()
            self._raw_exec(f"RELEASE SAVEPOINT {name}")
        except BaseException:
            if self._closed:
                raise
            self._raw_exec(f"ROLLBACK TO SAVEPOINT {name}")
            self._raw_exec(f"RELEASE SAVEPOINT {name}")
            self._locked, self._bumped = snapshot
            # Cached rows may hold edits the database just forgot.
            self._uows.clear()
            raise
        finally:
            self._depth -= 1

    # -- editing -----------------------------------------------------------

    def _flush(self) -> None:
        for mesh_id, uow in self._uows.items():
            if uow.dirty:
                with _translate_busy("could not write"):
                    uow.flush(0 if mesh_id in self._bumped else 1)
                self._bumped.add(mesh_id)

    def _lock(self, mesh_id: int) -> tuple:
        """Lock the mesh for this transaction; return its row's counters and policy."""
        m = schema.meshes
        locking = not self._sqlite and mesh_id not in self._locked
        def build():
            stmt = sa.select(
                m.c.next_vertex, m.c.next_edge, m.c.next_polygon, m.c.allow_loops, m.c.allow_multi_edges
            ).where(m.c.id == sa.bindparam("m"))
            return stmt.with_for_update() if locking else stmt

        stmt = self.statements.get(("mesh_row", locking), build)
        if locking and self._depth > 0:
            # In a savepoint, so that a lock timeout leaves the block usable.
            self._raw_exec("SAVEPOINT hestore_lock")
            try:
                with _translate_busy(f"mesh {mesh_id} is being edited by another transaction"):
                    rows = stmt.rows(self._cur, {"m": mesh_id})
            except BaseException:
                self._raw_exec("ROLLBACK TO SAVEPOINT hestore_lock")
                self._raw_exec("RELEASE SAVEPOINT hestore_lock")
                raise
            self._raw_exec("RELEASE SAVEPOINT hestore_lock")
        else:
            with _translate_busy(f"mesh {mesh_id} is being edited by another transaction"):
                rows = stmt.rows(self._cur, {"m": mesh_id})
        if not rows:
            raise MeshNotFoundError(f"the mesh with id {mesh_id} has been deleted from {self._safe_url()}")
        self._locked.add(mesh_id)
        return rows[0]

    def _uow(self, mesh_id: int) -> UnitOfWork:
        uow = self._uows.get(mesh_id)
        if uow is None:
            nv, ne, np_, loops, multi = self._lock(mesh_id)
            uow = self._uows[mesh_id] = UnitOfWork(mesh_id, self._sql, (nv, ne, np_), bool(loops), bool(multi))
        return uow

    @contextmanager
    def _editing(self, mesh_id: int, *, dry_run: bool = False) -> Iterator[UnitOfWork]:
        """One atomic operation on a mesh: its own transaction outside a block.

        With ``dry_run`` the operation's changes are always undone.
        """
        self._check_open()
        outer = self._depth == 0
        if outer:
            self._begin()
        try:
            uow = self._uow(mesh_id)
            uow.begin_operation()
            try:
                yield uow
            except BaseException:
                uow.abort_operation()
                raise
            if dry_run:
                uow.abort_operation()
            else:
                uow.end_operation()
            if outer:
                if dry_run:
                    self._rollback()
                else:
                    self._flush()
                    self._commit()
        except BaseException:
            if outer:
                self._rollback()
            raise

    # -- reading -----------------------------------------------------------

    def _check_open(self) -> None:
        if self._closed:
            raise HestoreError(f"the store on {self._safe_url()} is closed; nothing more can be read or written through it")

    def _cursor(self):
        """The driver cursor, after writing any pending edits (reads see them)."""
        self._check_open()
        if self._uows:
            self._flush()
        return self._cur

    @contextmanager
    def _read(self) -> Iterator[sa.Connection]:
        """The SQLAlchemy connection, after writing any pending edits."""
        self._cursor()
        yield self._conn

    @contextmanager
    def _committed(self) -> Iterator[sa.Connection]:
        """A connection that sees committed data only.

        Outside a block that is the store's own connection. Inside one, a
        second connection of the same engine, which does not see the block's
        edits — except for an in-memory SQLite database, which has only the
        one connection: there the block's own state is what can be read.
        """
        self._check_open()
        if self._depth == 0 or (self._sqlite and _is_memory(self.url)):
            with self._read() as conn:
                yield conn
            return
        with self._engine.connect() as conn:
            yield conn

    # -- the mesh catalogue ------------------------------------------------

    def create_mesh(self, name: str, *, allow_loops: bool = True, allow_multi_edges: bool = True):
        """Create an empty mesh.

        Parameters
        ----------
        name : str
            Unique within the store.
        allow_loops, allow_multi_edges : bool
            Whether self-loop edges and parallel edges may be added.

        Returns
        -------
        Mesh

        Raises
        ------
        MeshExistsError
            A mesh of that name exists.

        Examples
        --------
        >>> import hestore
        >>> store = hestore.open("sqlite://")
        >>> store.create_mesh("part", allow_loops=False)
        Mesh('part')
        """
        from hestore.mesh import Mesh

        self._check_open()
        if not isinstance(name, str) or not name.strip() or len(name) > 255:
            raise InvalidInputError(f"a mesh name is a non-empty string of at most 255 characters, not {name!r}")
        m = schema.meshes
        outer = self._depth == 0
        if outer:
            self._begin()
        else:
            self._flush()
            self._raw_exec("SAVEPOINT hestore_create")
        try:
            if self._conn.execute(sa.select(m.c.id).where(m.c.name == name)).first() is not None:
                raise MeshExistsError(f"a mesh named {name!r} already exists")
            mesh_id = self._conn.execute(
                m.insert()
                .values(
                    name=name,
                    allow_loops=bool(allow_loops),
                    allow_multi_edges=bool(allow_multi_edges),
                    revision=0,
                    next_vertex=0,
                    next_edge=0,
                    next_polygon=0,
                )
                .returning(m.c.id)
            ).scalar_one()
        except BaseException as exc:
            if outer:
                self._rollback()
            else:
                self._raw_exec("ROLLBACK TO SAVEPOINT hestore_create")
                self._raw_exec("RELEASE SAVEPOINT hestore_create")
            if isinstance(exc, sa.exc.IntegrityError):
                raise MeshExistsError(f"a mesh named {name!r} already exists") from None
            raise
        if outer:
            self._commit()
        else:
            self._raw_exec("RELEASE SAVEPOINT hestore_create")
        return Mesh(self, mesh_id, name, bool(allow_loops), bool(allow_multi_edges))

    def import_arrays(self, name: str, positions, polygons, *, on_error: str = "raise", **options):
        """Store a polygon soup as a new mesh; see `hestore.bulk.import_arrays`.

        Examples
        --------
        >>> import hestore
        >>> store = hestore.open("sqlite://")
        >>> store.import_arrays("tri", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [[0, 1, 2]]).polygons
        1
        """
        from hestore import bulk

        return bulk.import_arrays(self, name, positions, polygons, on_error=on_error, **options)

    def import_file(self, path, name: str | None = None, *, on_error: str = "raise", **options):
        """Import an OFF, OBJ or PLY file as a new mesh; see `hestore.bulk.import_file`."""
        from hestore import bulk

        return bulk.import_file(self, path, name, on_error=on_error, **options)

    def mesh(self, name: str):
        """The mesh called ``name``.

        Raises
        ------
        MeshNotFoundError
            No mesh has that name.

        Examples
        --------
        >>> import hestore
        >>> store = hestore.open("sqlite://")
        >>> _ = store.create_mesh("part")
        >>> store.mesh("part").name
        'part'
        """
        from hestore.mesh import Mesh

        m = schema.meshes
        with self._read() as conn:
            row = conn.execute(
                sa.select(m.c.id, m.c.allow_loops, m.c.allow_multi_edges).where(m.c.name == name)
            ).first()
        if row is None:
            known = self.meshes()
            hint = f"; meshes here: {', '.join(known[:10])}" if known else "; the store has no meshes"
            raise MeshNotFoundError(f"no mesh named {name!r} in {self._safe_url()}{hint}")
        return Mesh(self, row.id, name, bool(row.allow_loops), bool(row.allow_multi_edges))

    def meshes(self) -> list[str]:
        """Names of all meshes, sorted.

        Examples
        --------
        >>> import hestore
        >>> store = hestore.open("sqlite://")
        >>> _ = store.create_mesh("b"); _ = store.create_mesh("a")
        >>> store.meshes()
        ['a', 'b']
        """
        m = schema.meshes
        with self._read() as conn:
            return list(conn.execute(sa.select(m.c.name).order_by(m.c.name)).scalars())

    def delete_mesh(self, name: str) -> None:
        """Delete the mesh called ``name`` and all its elements.

        Examples
        --------
        >>> import hestore
        >>> store = hestore.open("sqlite://")
        >>> _ = store.create_mesh("tmp")
        >>> store.delete_mesh("tmp"); store.meshes()
        []
        """
        mesh = self.mesh(name)
        with self._editing(mesh._id):
            for table in schema.ELEMENT_TABLES:
                self._conn.execute(table.delete().where(table.c.mesh_id == mesh._id))
            self._conn.execute(schema.meshes.delete().where(schema.meshes.c.id == mesh._id))
            del self._uows[mesh._id]
        self._locked.discard(mesh._id)

