"""The session: hestore's one door to the database.

This module owns everything that touches a connection: the engine and its
connections, the transaction and savepoint scopes, the per-mesh writer locks,
the units of work and their flushing, the committed-read connection, the
identity of meshes across rollbacks, the thread a store belongs to, and the
translation of every driver error into a typed `hestore.errors.StoreError`.
Every other module reads and writes through a `Session` (`Store.session`),
through the small interface below, and never through its private members.

A session's connection runs its driver in autocommit mode and hestore issues
``BEGIN``/``COMMIT``/``SAVEPOINT`` itself, which gives exactly SPEC §4 on
both databases:

* outside a block, every read is one autocommitted statement (it sees the
  latest commit and holds no snapshot), and every edit is its own write
  transaction (`editing` opens and commits it);
* a block (`transaction`) is one write transaction — SQLite ``BEGIN
  IMMEDIATE``, so the database's single writer lock is taken up front;
  PostgreSQL ``BEGIN`` — and nested blocks are savepoints. There is one
  scope, written once (``_scope``): the outermost level begins and commits or
  rolls back, a nested level is a savepoint (`transaction`, `scope`) or,
  for a single edit, the unit of work's undo log (`editing`), which costs no
  round trip;
* before its first change to a mesh a write transaction locks that mesh's
  row (PostgreSQL ``SELECT ... FOR UPDATE``, in a savepoint inside a block
  so that a lock timeout leaves the block usable), so writers to one mesh
  are serialized and writers to different meshes are not; a lock not granted
  within ``busy_timeout`` is `StoreBusyError`;
* edits collect in one `hestore.unitofwork.UnitOfWork` per mesh and are
  flushed — handed to `hestore.persistence` as one `ChangeSet` each —
  before any read, before a savepoint and at commit. The mesh's revision
  grows by one in the first flush of a transaction that changes it;
* `dry_run` runs an operation and throws it away without the writer lock:
  outside a block in a read-only transaction (which never waits for a
  writer), inside one in the block itself.

A `MeshRef` is a mesh's identity for this session. A mesh created in a
transaction that is rolled back dies with it: its id may be handed out again
(SQLite reuses it), and every handle of the dead mesh raises
`MeshNotFoundError` instead of reaching the new one.

A session belongs to the thread that opened it. Any use from another thread
raises `WrongThreadError` before the connection is touched.

Private reach: none. `hestore.columns` and `hestore.persistence` are handed
the session's DBAPI cursor; nothing outside this module holds it.
"""

from __future__ import annotations

import weakref
from contextlib import contextmanager
from datetime import datetime, timezone
from threading import get_ident
from typing import Any, Callable, Iterator

import sqlalchemy as sa

from hestore import drivers, migrate, schema, urls
from hestore.columns import read_columns, read_snapshot
from hestore.journal import (
    COUNTERS,
    as_of,
    as_of_kept,
    changed_rows,
    request_as_of,
    restore_statements,
    restored,
    to_history,
)
from hestore.drivers import is_driver_error
from hestore.errors import (
    HestoreError,
    InvalidInputError,
    MeshNotFoundError,
    ReadOnlyError,
    RevisionNotFoundError,
    SchemaVersionError,
    StoreError,
    WrongThreadError,
)
from hestore.persistence import Persistence
from hestore.statements import Prepared, StatementCache
from hestore.unitofwork import UnitOfWork

__all__ = ["Session", "MeshRef", "Snapshot"]

class MeshRef:
    """A mesh's identity for one session: what every algorithm below the facade is handed.

    Its id, its name, its policy, the session it belongs to (the door for
    every read and write of it), and whether it still exists here. All
    handles of one mesh share its `MeshRef`. ``alive`` turns False when the
    transaction that created the mesh is rolled back.
    """

    __slots__ = ("session", "id", "name", "allow_loops", "allow_multi_edges", "alive", "revision", "base",
                 "__weakref__")

    def __init__(
        self,
        session: "Session",
        mesh_id: int,
        name: str,
        allow_loops: bool,
        allow_multi_edges: bool,
        revision: int | None = None,
        base: "MeshRef | None" = None,
    ) -> None:
        self.session = session
        self.id = mesh_id
        self.name = name
        self.allow_loops = allow_loops
        self.allow_multi_edges = allow_multi_edges
        self.alive = True
        #: None for the mesh itself; ``r`` for a read-only view of its revision ``r`` (`Session.view`).
        self.revision = revision
        #: The mesh a view belongs to (None for the mesh itself): the view lives and dies with it.
        self.base = base

    def __repr__(self) -> str:
        at = "" if self.revision is None else f" at {self.revision}"
        return f"MeshRef({self.id}, {self.name!r}{at}{'' if self.alive else ', dead'})"


class Snapshot:
    """Reads of one mesh that see one consistent state: what `Session.snapshot` yields.

    Attributes
    ----------
    revision : int
        The mesh's revision in this state.
    isolated : bool
        Whether the state is committed data only (False: a block's own
        state, seen through an in-memory store's single connection).
    """

    def __init__(
        self, connection: sa.Connection, mesh_id: int, revision: int, isolated: bool, as_of: int | None = None
    ) -> None:
        self._connection = connection
        self._mesh_id = mesh_id
        self._as_of = as_of
        self.revision = revision
        self.isolated = isolated

    def columns(self, requests) -> list:
        """Columns of several tables of the mesh: `hestore.columns.read_columns`."""
        if self._as_of is not None:
            requests = [request_as_of(request, self._as_of) for request in requests]
        return read_columns(self._connection, self._mesh_id, requests)

    def rows(self, stmt) -> list[tuple]:
        """The rows of one Core statement (bound parameters given in it), in this state."""
        if self._as_of is not None:
            stmt = as_of(stmt, sa.literal(self._as_of))
        return [tuple(row) for row in self._connection.execute(stmt)]


class _TracingCursor:
    """A DBAPI cursor that reports every statement (and, if asked, its parameters) before running it."""

    def __init__(self, cursor: Any, callback: Callable[..., object], parameters: bool) -> None:
        self._cursor = cursor
        self._callback = callback
        self._parameters = parameters

    def _report(self, sql, args) -> None:
        if self._parameters:
            self._callback(sql, args[0] if args else None)
        else:
            self._callback(sql)

    def execute(self, sql, *args, **kwargs):
        self._report(sql, args)
        return self._cursor.execute(sql, *args, **kwargs)

    def executemany(self, sql, *args, **kwargs):
        self._report(sql, args)
        return self._cursor.executemany(sql, *args, **kwargs)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._cursor, name)


class Session:
    """The connection(s), transactions, locks and units of work of one `Store`.

    Parameters
    ----------
    url : sqlalchemy.engine.URL
        A URL `hestore.urls.resolve` accepted.
    busy_timeout : float
        Seconds to wait for another writer's lock before `StoreBusyError`.

    Raises
    ------
    StoreError
        The database cannot be opened or used (not a database, unreachable,
        tables of another application in the way, driver not installed).
    SchemaVersionError
        The database needs ``hestore db upgrade`` (or a newer hestore).

    Examples
    --------
    >>> from hestore import urls
    >>> session = Session(urls.resolve("sqlite://"), busy_timeout=1.0)
    >>> with session.reading() as conn:
    ...     conn.execute(sa.text("SELECT count(*) FROM meshes")).scalar()
    0
    >>> session.close()
    """

    def __init__(self, url: sa.engine.URL, *, busy_timeout: float) -> None:
        self.url = url
        self.shown_url = urls.shown(url)
        self.busy_timeout = float(busy_timeout)
        self.is_sqlite = url.get_backend_name() == "sqlite"
        self.is_memory = urls.is_memory(url)
        #: Derived data kept for the session's lifetime (graph views), dropped by `close`.
        self.caches: dict[str, Any] = {}
        self._thread = get_ident()
        self._closed = True
        self._scopes: list[str] = []
        self._uows: dict[int, UnitOfWork] = {}
        self._message: str | None = None
        # The views of each mesh this session made (weakly held), so that a prune can end those it removes.
        self._views: dict[int, list] = {}
        self._locked: set[int] = set()
        self._changed: set[int] = set()
        self._refs: dict[int, MeshRef] = {}
        self._born: list[MeshRef] = []
        # (ref, name before) of every rename in the open transaction, to undo on rollback
        self._renamed: list[tuple[MeshRef, str]] = []
        self._failed = False
        self._engine = drivers.make_engine(url, busy_timeout=self.busy_timeout)
        try:
            with self._guard(f"cannot open {self.shown_url}"):
                self._conn = self._engine.connect()
                self._raw = self._conn.connection.dbapi_connection
                self._cur = self._raw.cursor()
        except BaseException:
            self._engine.dispose()
            raise
        self._closed = False
        self.dialect = self._engine.dialect
        self.statements = StatementCache(self.dialect)
        self._persistence = Persistence(self.statements, lambda: self._cur)
        try:
            self._ensure_schema()
        except BaseException:
            self.close()
            raise

    def __repr__(self) -> str:
        return f"Session({self.shown_url!r})"

    # -- who may use it ------------------------------------------------------

    def check(self) -> None:
        """Raise unless the session is usable: open, in the thread that opened it, its block not failed."""
        if self._thread != get_ident():
            raise WrongThreadError(
                f"the store on {self.shown_url} was opened in thread {self._thread} and is used from thread "
                f"{get_ident()}; a store belongs to one thread: open one per thread"
            )
        if self._closed:
            raise HestoreError(
                f"the store on {self.shown_url} is closed; nothing more can be read or written through it"
            )
        if self._failed:
            raise StoreError(
                "a write in this transaction block failed, so the block can only be left "
                "(its changes are rolled back when it ends)"
            )

    def _alive(self, ref: MeshRef) -> None:
        self.check()
        if not ref.alive or not (ref.base or ref).alive:
            raise self._dead(ref)

    def _writable(self, ref: MeshRef) -> None:
        self._alive(ref)
        if ref.revision is not None:
            raise ReadOnlyError(
                f"mesh {ref.name!r} at revision {ref.revision} is a read-only view of the past; "
                "edit the mesh itself (or revert it to that revision)"
            )

    @staticmethod
    def _dead(ref: MeshRef) -> HestoreError:
        if ref.revision is not None and (ref.base is None or ref.base.alive):
            return RevisionNotFoundError(
                f"revision {ref.revision} of mesh {ref.name!r} is gone: the transaction that made it was rolled "
                "back, or its history was pruned"
            )
        return MeshNotFoundError(
            f"mesh {ref.name!r} no longer exists: the transaction that created it was rolled back"
        )

    def missing(self, ref: MeshRef) -> MeshNotFoundError:
        """The error for a mesh that is not in the database (deleted, or never committed)."""
        return MeshNotFoundError(f"mesh {ref.name!r} has been deleted from {self.shown_url}")

    def require(self, ref: MeshRef) -> None:
        """Raise `MeshNotFoundError` unless the mesh is in the database as the open transaction sees it.

        For a view, `RevisionNotFoundError` too unless its revision is still
        kept. What an empty answer means is told apart with it: no element,
        or no mesh.
        """
        self._alive(ref)
        with self._guard(f"could not read mesh {ref.name!r}"):
            if self._uows:
                self._flush()
            if ref.revision is None:
                self._history_row(ref)
            else:
                self._kept(ref, ref.revision)

    # -- mesh identities -----------------------------------------------------

    def ref(self, mesh_id: int, name: str, allow_loops: bool, allow_multi_edges: bool) -> MeshRef:
        """The identity of a stored mesh, shared by every handle of it in this session."""
        ref = self._refs.get(mesh_id)
        if ref is None or not ref.alive:
            ref = self._refs[mesh_id] = MeshRef(self, mesh_id, name, allow_loops, allow_multi_edges)
        else:
            ref.name = name
        return ref

    def new_ref(self, mesh_id: int, name: str, allow_loops: bool, allow_multi_edges: bool) -> MeshRef:
        """The identity of a mesh created in the open transaction: it dies if that is rolled back."""
        ref = self._refs[mesh_id] = MeshRef(self, mesh_id, name, allow_loops, allow_multi_edges)
        self._born.append(ref)
        return ref

    def _kill_born(self, keep: int) -> None:
        for ref in self._born[keep:]:
            ref.alive = False
            if self._refs.get(ref.id) is ref:
                del self._refs[ref.id]
        del self._born[keep:]

    def renamed(self, ref: MeshRef, name: str) -> None:
        """Record that the open transaction renamed the mesh: its handles show ``name`` unless it rolls back."""
        self._renamed.append((ref, ref.name))
        ref.name = name

    def _unrename(self, keep: int) -> None:
        for ref, old in reversed(self._renamed[keep:]):
            ref.name = old
        del self._renamed[keep:]

    # -- errors ----------------------------------------------------------------

    def _translated(self, exc: BaseException, what: str) -> StoreError:
        return drivers.translate(exc, what, self.shown_url)

    def _guard(self, what: str):
        return drivers.guard(what, self.shown_url)

    # -- raw transaction control ----------------------------------------------

    def _exec(self, sql: str) -> None:
        self._cur.execute(sql)

    def _in_txn(self) -> bool:
        if self.is_sqlite:
            return self._raw.in_transaction
        return self._raw.info.transaction_status != 0  # psycopg: 0 = IDLE

    def _begin(self, sql: str | None = None) -> None:
        with self._guard("could not start a transaction"):
            self._exec(sql or ("BEGIN IMMEDIATE" if self.is_sqlite else "BEGIN"))

    def _commit(self) -> None:
        with self._guard("could not commit"):
            if self._in_txn():
                self._exec("COMMIT")
        self._forget()
        self._born.clear()
        self._renamed.clear()

    def _rollback(self) -> None:
        try:
            if not self._closed and self._in_txn():
                self._exec("ROLLBACK")
        except Exception:  # noqa: BLE001 - the error being handled matters more
            # A connection that cannot roll back (one interrupted mid-statement)
            # is dropped: the server rolls back what it held, nothing stays half-done.
            self._forget()
            self._kill_born(0)
            self._unrename(0)
            self.close()
            return
        self._forget()
        self._kill_born(0)
        self._unrename(0)

    def _forget(self) -> None:
        self._uows.clear()
        self._locked.clear()
        self._changed.clear()
        self._failed = False

    def _ensure_schema(self) -> None:
        with self._guard(f"cannot read the schema of {self.shown_url}"):
            state = migrate.schema_state(self._conn)
        if state.status == "new":
            with self.scope(), self._guard(f"cannot create hestore's tables in {self.shown_url}"):
                migrate.upgrade(self._conn)
        elif state.status == "foreign":
            raise StoreError(
                f"{self.shown_url} holds tables hestore did not create ({', '.join(state.foreign_tables)}); "
                "hestore will not use or change them: open another database"
            )
        elif state.status != "head":
            raise SchemaVersionError(
                f"{self.shown_url} is at schema revision {state.current}, but this hestore needs {state.head}: "
                + (
                    "run `hestore db upgrade` (hestore --db URL db upgrade)"
                    if state.status == "behind"
                    else "it was written by a newer hestore"
                )
            )

    def close(self) -> None:
        """Roll back anything uncommitted, close the connection, drop the caches."""
        if self._closed:
            return
        if self._thread != get_ident():
            self.check()
        self._closed = True
        try:
            if self._in_txn():
                self._exec("ROLLBACK")
        except Exception:  # noqa: BLE001 - closing anyway; the database rolls back on disconnect
            pass
        finally:
            self._forget()
            self._kill_born(0)
            self._unrename(0)
            self.caches.clear()
            try:
                self._conn.close()
            except Exception:  # noqa: BLE001 - a lost connection is closed all the same
                pass
            self._engine.dispose()

    # -- scopes ----------------------------------------------------------------

    @property
    def in_transaction(self) -> bool:
        """Whether a transaction is open (a block, or an operation running)."""
        return bool(self._scopes)

    @contextmanager
    def _scope(self, kind: str, *, savepoint: bool) -> Iterator[sa.Connection]:
        """The one transaction scope.

        Outermost: a write transaction, committed when the body succeeds and
        rolled back when it raises. Nested: a savepoint (``savepoint``) or
        nothing at all (the caller's unit of work undoes its own changes).
        """
        self.check()
        if not self._scopes:
            self._begin()
            self._scopes.append(kind)
            try:
                yield self._conn
                self.check()
                with self._guard("could not write"):
                    self._flush()
                self._commit()
            except BaseException as exc:
                self._rollback()
                if is_driver_error(exc):
                    raise self._translated(exc, "the transaction failed and was rolled back") from exc
                raise
            finally:
                self._scopes.pop()
            return
        if not savepoint:
            self._scopes.append(kind)
            try:
                yield self._conn
            except BaseException as exc:
                if is_driver_error(exc):
                    # The database may have aborted the transaction (PostgreSQL does): end the block.
                    self._failed = True
                    raise self._translated(exc, "the operation failed; the block can only be left") from exc
                raise
            finally:
                self._scopes.pop()
            return
        name = f"hestore_sp{len(self._scopes)}"
        with self._guard("could not start a savepoint"):
            self._flush()
            self._exec(f"SAVEPOINT {name}")
        saved = (set(self._locked), set(self._changed), len(self._born), len(self._renamed))
        self._scopes.append(kind)
        try:
            yield self._conn
            self.check()
            with self._guard("could not write"):
                self._flush()
                self._exec(f"RELEASE SAVEPOINT {name}")
        except BaseException as exc:
            if not self._closed:
                with self._guard("could not roll back to a savepoint"):
                    self._exec(f"ROLLBACK TO SAVEPOINT {name}")
                    self._exec(f"RELEASE SAVEPOINT {name}")
                self._locked, self._changed = saved[0], saved[1]
                self._kill_born(saved[2])
                self._unrename(saved[3])
                # Cached rows may hold edits the database just forgot.
                self._uows.clear()
                self._failed = False
            if is_driver_error(exc):
                raise self._translated(exc, "the step failed and changed nothing") from exc
            raise
        finally:
            self._scopes.pop()

    @contextmanager
    def transaction(self, message: str | None = None) -> Iterator[sa.Connection]:
        """A block: one transaction (nested: a savepoint) that commits or rolls back as a whole.

        `hestore.Store.transaction` is this. ``message`` names the revisions
        the block makes (the outermost block's message that is not None).
        """
        if message is not None and not isinstance(message, str):
            raise InvalidInputError(f"a transaction's message is a str, not {type(message).__name__}")
        if self._message is None:
            self._message = message
        try:
            with self._scope("block", savepoint=True) as conn:
                yield conn
        finally:
            if not self._scopes:
                self._message = None

    def scope(self):
        """One atomic step of several statements: its own transaction outside a block, a savepoint inside.

        Yields the connection to run them on; pending edits are written before
        it starts and when it ends.
        """
        return self._scope("step", savepoint=True)

    @contextmanager
    def editing(self, ref: MeshRef) -> Iterator[UnitOfWork]:
        """One atomic edit of a mesh, through its unit of work.

        Outside a block the edit is its own transaction; inside one, its
        changes are undone by the unit of work if it raises, and the block
        goes on. The mesh is locked for the transaction before its first
        change.
        """
        self._writable(ref)
        with self._scope("edit", savepoint=False):
            uow = self._uow(ref)
            if uow.values.staged:
                # Set-based writes are written before the next edit, which may
                # read the values they set (an operator deriving new values).
                self._flush()
            with uow.operation():
                yield uow

    @contextmanager
    def dry_run(self, ref: MeshRef) -> Iterator[UnitOfWork]:
        """An edit that is always undone, without the writer lock: what ``can_*`` predicates run.

        Outside a block it runs in a read-only transaction (SQLite: a
        deferred one; PostgreSQL: ``REPEATABLE READ READ ONLY``), which never
        waits for a writer and is rolled back. Inside a block it sees the
        block's state; the mesh is not locked for it.
        """
        self._writable(ref)
        if self._scopes:
            with self._guard("could not read"):
                uow = self._uows.get(ref.id) or self._unlocked_uow(ref)
                with uow.operation(keep=False):
                    yield uow
            return
        self._begin("BEGIN" if self.is_sqlite else "BEGIN ISOLATION LEVEL REPEATABLE READ READ ONLY")
        try:
            with self._guard("could not read"):
                uow = self._unlocked_uow(ref)
                with uow.operation(keep=False):
                    yield uow
        finally:
            with self._guard("could not end a read transaction"):
                if self._in_txn():
                    self._exec("ROLLBACK")

    def _unlocked_uow(self, ref: MeshRef) -> UnitOfWork:
        row = self._persistence.mesh_row(ref.id, lock=False)
        if row is None:
            raise self.missing(ref)
        return self._new_uow(ref, row)

    def _uow(self, ref: MeshRef) -> UnitOfWork:
        uow = self._uows.get(ref.id)
        if uow is None:
            row = self._lock(ref)
            uow = self._uows[ref.id] = self._new_uow(ref, row)
        return uow

    def _new_uow(self, ref: MeshRef, row: tuple) -> UnitOfWork:
        p = self._persistence
        return UnitOfWork(
            ref.id, p.load, row[:4], bool(row[4]), bool(row[5]), p.catalogue, bool(row[6]), p.values, p.positions,
            # The stored revision already counts this transaction once it has changed the mesh.
            revision=int(row[7]) + (0 if ref.id in self._changed else 1), history=bool(row[8]),
        )

    def lock(self, ref: MeshRef) -> None:
        """Take the mesh's writer lock for the open transaction (before reads that an edit relies on).

        A set-based edit checks its ids against the mesh before staging its
        write; taking the lock first means nobody can change the mesh in
        between. Outside a transaction this does nothing: use it in `scope`.
        """
        self._writable(ref)
        if self._scopes:
            self._uow(ref)

    def _lock(self, ref: MeshRef) -> tuple:
        """Lock the mesh for this transaction; return its row's counters and policy."""
        # SQLite's BEGIN IMMEDIATE already holds the database's writer lock.
        lock = not self.is_sqlite and ref.id not in self._locked
        what = f"mesh {ref.name!r} is being edited by another transaction"
        if lock and len(self._scopes) > 1:
            # In a savepoint, so that a lock timeout leaves the enclosing transaction usable.
            with self._scope("lock", savepoint=True), self._guard(what):
                row = self._persistence.mesh_row(ref.id, lock=True)
        else:
            with self._guard(what):
                row = self._persistence.mesh_row(ref.id, lock=lock)
        if row is None:
            raise self.missing(ref)
        self._locked.add(ref.id)
        return row

    def _flush(self) -> None:
        """Write every unit of work's changes (reads and commits see them afterwards)."""
        dropped = []
        for mesh_id, uow in self._uows.items():
            if uow.dirty:
                changes = uow.changes(0 if mesh_id in self._changed else 1)
                try:
                    self._persistence.write(changes, self._message)
                except BaseException:
                    # The cache and the database now disagree: only leaving the block repairs that.
                    self._failed = bool(self._scopes)
                    raise
                uow.flushed()
                self._changed.add(mesh_id)
                if changes.drop:
                    dropped.append(mesh_id)
        for mesh_id in dropped:
            del self._uows[mesh_id]

    def analyze(self, tables) -> None:
        """Refresh the planner's statistics of ``tables`` (PostgreSQL, outside a transaction; else nothing)."""
        self.check()
        if self.is_sqlite or self._scopes:
            return
        with self._guard("could not analyze"):
            for table in tables:
                self._exec(f"ANALYZE {table.name}")

    # -- reading -----------------------------------------------------------------

    def fetch(self, ref: MeshRef, key: Any, build: Callable[[], Any], values: dict) -> list[tuple]:
        """Rows of a compiled statement about one mesh, seeing the open transaction's edits.

        Parameters
        ----------
        ref : MeshRef
            The mesh; bound as ``:m``.
        key, build
            The statement's cache key, and a function building it (once) from
            `hestore.schema`'s tables, with named ``bindparam`` placeholders.
        values : dict
            The other parameters (the dict is reused: ``m`` is set in it).
        """
        if self._thread != get_ident() or self._closed or self._failed or not ref.alive:
            self._alive(ref)
        try:
            if self._uows:
                self._flush()
            if ref.revision is None:
                stmt = self.statements.get(key, build)
            else:
                stmt = self.statements.get(
                    ("as_of", key), lambda: as_of_kept(build(), sa.bindparam("asof"), sa.bindparam("m")),
                    prepare=False,
                )
                values["asof"] = ref.revision
            values["m"] = ref.id
            cur = self._cur
            stmt.execute(cur, stmt.bind(values))
            rows = cur.fetchall()
            if not rows and ref.revision is not None:
                # A view's statement reads nothing once its revision is no longer kept: say so, not "empty".
                self._kept(ref, ref.revision)
            return rows
        except HestoreError:
            raise
        except Exception as exc:
            if is_driver_error(exc):
                raise self._translated(exc, f"could not read mesh {ref.name!r}") from exc
            raise

    @contextmanager
    def reading(self) -> Iterator[sa.Connection]:
        """The session's connection after pending edits are flushed (reads see them); errors translated."""
        self.check()
        with self._guard("could not read"):
            if self._uows:
                self._flush()
            yield self._conn

    @contextmanager
    def snapshot(self, ref: MeshRef, *, committed: bool = False) -> Iterator[Snapshot]:
        """Reads of one mesh in one consistent state.

        Parameters
        ----------
        ref : MeshRef
        committed : bool
            Committed data only: inside a block, read through a second
            connection — except for an in-memory SQLite database, which has
            only the one (`Snapshot.isolated` then says False).

        Raises
        ------
        MeshNotFoundError
            The mesh is not in that state.
        """
        self._alive(ref)
        other = committed and self._scopes and not self.is_memory
        with self._guard(f"could not read mesh {ref.name!r}"):
            if other:
                conn = self._engine.connect()
            else:
                if self._uows:
                    self._flush()
                conn = self._conn
            try:
                with read_snapshot(conn):
                    isolated = bool(other) or not self._scopes
                    if ref.revision is None:
                        m = schema.meshes
                        revision = conn.execute(sa.select(m.c.revision).where(m.c.id == ref.id)).scalar()
                        if revision is None:
                            raise self.missing(ref)
                        yield Snapshot(conn, ref.id, revision, isolated)
                    else:
                        # A revision of this block's own is not in the committed data: it is checked where it is
                        # (no one else can prune a mesh the block has changed: the block holds its lock).
                        mine = other and ref.id in self._changed
                        with self._kept_during(ref, [ref.revision], self._conn if mine else conn):
                            yield Snapshot(conn, ref.id, ref.revision, isolated, as_of=ref.revision)
            finally:
                if other:
                    conn.close()

    # -- history (SPEC §4.1) ------------------------------------------------

    def _history_row(self, ref: MeshRef, conn: sa.Connection | None = None) -> tuple:
        m = schema.meshes
        row = (conn or self._conn).execute(
            sa.select(m.c.revision, m.c.kept_from, m.c.history).where(m.c.id == ref.id)
        ).first()
        if row is None:
            raise self.missing(ref)
        return tuple(row)

    def _kept(self, ref: MeshRef, revision: int, conn: sa.Connection | None = None) -> int:
        """Check that ``revision`` of the mesh can be read (on ``conn``); return the current revision."""
        current, kept_from, keep = self._history_row(ref, conn)
        if revision == current:
            return current
        if revision < 0 or revision > current:
            raise RevisionNotFoundError(
                f"mesh {ref.name!r} has no revision {revision}: it is at revision {current}"
            )
        if not keep:
            raise RevisionNotFoundError(
                f"mesh {ref.name!r} keeps no history (created with history=False): only its current "
                f"revision {current} can be read"
            )
        if revision < kept_from:
            raise RevisionNotFoundError(
                f"revision {revision} of mesh {ref.name!r} is no longer kept: its history was pruned, "
                f"and the oldest revision kept is {kept_from}"
            )
        return current

    @contextmanager
    def _kept_during(self, ref: MeshRef, revisions, conn: sa.Connection) -> Iterator[None]:
        """Check that ``revisions`` of the mesh are kept for the reads of the block, made on ``conn``.

        Checked before the reads, in the same snapshot. A PostgreSQL block
        reads at READ COMMITTED, each statement in a snapshot of its own, so
        another process's prune may commit between them: there the check is
        made again after the reads (a revision pruned stays pruned, so kept
        then means kept all along), and a read that failed on rows the prune
        took away is reported as the revision gone.
        """
        def check() -> None:
            for r in revisions:
                self._kept(ref, r, conn)

        check()
        shared = bool(self._scopes) and not self.is_sqlite and conn is self._conn
        try:
            yield
        except HestoreError:
            if shared:
                check()
            raise
        if shared:
            check()

    def view(self, ref: MeshRef, revision: int) -> MeshRef:
        """The identity of a read-only view of the mesh as it was at ``revision``.

        Reads through it (`fetch`, `snapshot`) see that revision; edits raise
        `ReadOnlyError`. It lives as long as the mesh does.

        Raises
        ------
        RevisionNotFoundError
            The revision was never made, or is no longer kept.
        """
        self._alive(ref)
        with self._guard(f"could not read mesh {ref.name!r}"):
            if self._uows:
                self._flush()
            current = self._kept(ref, revision)
        view = MeshRef(self, ref.id, ref.name, ref.allow_loops, ref.allow_multi_edges, revision=revision, base=ref)
        if revision == current and ref.id in self._changed:
            self._born.append(view)  # a revision of the open transaction: a rollback takes it away
        views = [w for w in self._views.get(ref.id, ()) if w() is not None]
        self._views[ref.id] = [*views, weakref.ref(view)]
        return view

    def oldest_kept(self, ref: MeshRef) -> int:
        """The oldest revision of the mesh that can still be read (its current one if it keeps no history)."""
        self._alive(ref)
        with self._guard(f"could not read the history of mesh {ref.name!r}"):
            if self._uows:
                self._flush()
            current, kept_from, keep = self._history_row(ref)
        return kept_from if keep else current

    def revisions(self, ref: MeshRef, limit: int | None = None, *, newest_first: bool = True) -> list[tuple]:
        """The kept revisions ``>= 1``: ``(number, committed_at, message, changes JSON or None, action, target)``.

        ``action`` and ``target`` say what an undo, redo or revert did (None
        for an ordinary revision): what `hestore.history` replays.
        """
        self._alive(ref)
        r = schema.revisions
        with self._guard(f"could not read the history of mesh {ref.name!r}"):
            if self._uows:
                self._flush()
            _, kept_from, keep = self._history_row(ref)
            if not keep:
                return []
            stmt = (
                sa.select(r.c.number, r.c.committed_at, r.c.message, r.c.changes, r.c.action, r.c.target)
                .where(r.c.mesh_id == ref.id, r.c.number >= max(kept_from, 1))
                .order_by(r.c.number.desc() if newest_first else r.c.number)
            )
            if limit is not None:
                stmt = stmt.limit(limit)
            return [tuple(row) for row in self._conn.execute(stmt)]

    def versions(self, ref: MeshRef, a: int, b: int, *, check: bool = True) -> dict[str, tuple[list, list]]:
        """Per versioned table, its rows at revisions ``a`` and ``b`` of every key changed in between.

        The catalogue of properties comes whole at both. From revision 0
        (empty), every row at ``b``. One consistent snapshot; the cost grows
        with the changes between the two, not with the mesh.

        Raises
        ------
        RevisionNotFoundError
            ``a`` or ``b`` is not kept (with ``check``; without, the rows
            that history still has are read: a kept revision's changes).
        """
        self._alive(ref)
        with self._guard(f"could not read the history of mesh {ref.name!r}"):
            if self._uows:
                self._flush()
            with read_snapshot(self._conn), self._kept_during(ref, (a, b) if check else (), self._conn):
                lo, hi = min(a, b), max(a, b)
                values = {"m": ref.id, "lo": lo, "hi": hi}
                values.update({f"s_{n}": v for n, v in self._counters_after(ref, lo).items()})
                values.update({f"e_{n}": v for n, v in self._counters_after(ref, hi).items()})
                out = {}
                for table in schema.VERSIONED:
                    whole = table is schema.properties or lo == 0
                    rows = []
                    for r in (a, b):
                        side = "whole" if whole else "before" if r == lo else "after"
                        stmt = self.statements.get(
                            ("versions", table.name, side), lambda t=table, s=side: changed_rows(t, s), prepare=False
                        )
                        rows.append(stmt.rows(self._cur, {**values, "r": r}) if r else [])
                    out[table.name] = (rows[0], rows[1])
                return out

    def _counters_after(self, ref: MeshRef, revision: int) -> dict:
        """The id counters after ``revision``: when the next one began, or the mesh's own after the last."""
        r, m = schema.revisions, schema.meshes
        names = COUNTERS
        row = self._conn.execute(
            sa.select(*(r.c[n] for n in names)).where(r.c.mesh_id == ref.id, r.c.number == revision + 1)
        ).first()
        if row is None:
            row = self._conn.execute(sa.select(*(m.c[n] for n in names)).where(m.c.id == ref.id)).first()
        return dict(zip(names, row))

    def restorable(self, ref: MeshRef, action: str) -> None:
        """Raise unless the mesh may be restored now: `InvalidInputError` in a block that changed it already."""
        self._writable(ref)
        if ref.id in self._changed or (ref.id in self._uows and self._uows[ref.id].dirty):
            raise InvalidInputError(
                f"{action} makes a revision of its own, but this block has already changed mesh {ref.name!r}: "
                f"call it outside the block, or before the block's other edits of the mesh"
            )

    def restore(self, ref: MeshRef, target: int, message: str, action: str, acted_on: int) -> int:
        """Commit a new revision of the mesh whose rows equal those at ``target``; return its number.

        Set-based (`hestore.journal.restore_statements`), recorded in history
        like any edit: ids, positions and property values come back as they
        were, and the id counters do not move back, so no id is handed out
        twice. Its own transaction, or a savepoint of the open block, which
        must not have changed the mesh already.

        Raises
        ------
        RevisionNotFoundError
            ``target`` is not kept.
        InvalidInputError
            The open block has already changed the mesh.
        """
        self.restorable(ref, action)
        with self._scope("step", savepoint=True) as conn:
            self._flush()
            uow = self._uow(ref)  # the writer lock, and the revision this makes
            current = self._kept(ref, target)
            if not uow.history:
                raise RevisionNotFoundError(
                    f"mesh {ref.name!r} keeps no history (created with history=False): there is nothing to {action}"
                )
            revision = uow.revision
            dialect = self._engine.dialect.name
            since = self._counters_after(ref, target)
            for table in schema.VERSIONED:
                statements = restore_statements(table, target, revision, since)
                if len(statements) > 2:  # rows came back: those that did not exist before get their record
                    statements.append(to_history(table, "new", dialect, restored(table, target, revision)))
                for stmt in statements:
                    # Planned for these revisions each time (see `Prepared`): the best plan depends on them.
                    Prepared(stmt, self.dialect, prepare=False).run(self._cur, {"m": ref.id, "r": revision})
            m = schema.meshes
            conn.execute(m.update().where(m.c.id == ref.id).values(revision=revision))
            # Its id counters are the mesh's (a restore hands out no id): what later revisions create starts there.
            counters = self._counters_after(ref, revision)
            conn.execute(
                schema.revisions.insert().values(
                    mesh_id=ref.id, number=revision, committed_at=datetime.now(timezone.utc), message=message,
                    action=action, target=acted_on, **counters,
                )
            )
            assert current == revision - 1
            self._changed.add(ref.id)
            # Its cached rows are those of before: the next edit reads the restored ones.
            del self._uows[ref.id]
        return revision

    def prune(self, ref: MeshRef, keep: int) -> int:
        """Forget all but the newest ``keep`` revisions (the current one included); return the oldest kept."""
        self._writable(ref)
        with self._scope("step", savepoint=True) as conn:
            self._flush()
            self._uow(ref)
            current, kept_from, _ = self._history_row(ref)
            oldest = max(kept_from, current - keep + 1, 0)
            for history in schema.HISTORY.values():
                # Rows superseded by the oldest kept revision stay: they say what it changed.
                conn.execute(history.delete().where(history.c.mesh_id == ref.id, history.c.rev_to < oldest))
            r = schema.revisions
            conn.execute(r.delete().where(r.c.mesh_id == ref.id, r.c.number < oldest))
            m = schema.meshes
            conn.execute(m.update().where(m.c.id == ref.id).values(kept_from=oldest))
            for view in self._views.get(ref.id, []):
                if view() is not None and view().revision < oldest:
                    view().alive = False
        return oldest

    @contextmanager
    def traced(self, callback: Callable[..., object], *, parameters: bool = False) -> Iterator[None]:
        """Call ``callback(sql)`` for every statement the session sends on its cursor (benchmarks, tests).

        With ``parameters``, ``callback(sql, parameters)``: the driver's
        parameters as sent (a sequence of rows for ``executemany``), so that
        a statement can be run again, under ``EXPLAIN`` say.
        """
        self.check()
        plain = self._cur
        self._cur = _TracingCursor(plain, callback, parameters)
        try:
            yield
        finally:
            self._cur = plain
