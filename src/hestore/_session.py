"""The session: hestore's one door to the database.

This module owns everything that touches a connection: the engine and its
connections, the transaction and savepoint scopes, the per-mesh writer locks,
the units of work and their flushing, the committed-read connection, the
identity of meshes across rollbacks (views of the past included, with the
check that their revision is still kept), the thread a store belongs to,
and the translation of every driver error into a typed
`hestore.errors.StoreError`. Every other module reads and writes through a
`Session` (`Store.session`), through the small interface below, and never
through its private members: it hands the session a registered query of
`hestore._queries` and its values, and every statement runs on the
session's one cursor (`hestore._queries.Executor`), which `traced` watches.
What history means and does — its revisions, the rows between two,
restores, prunes — is `hestore._timeline`'s, run inside these scopes.

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
* edits collect in one `hestore._unitofwork.UnitOfWork` per mesh and are
  flushed — handed to `hestore._persistence` as one `ChangeSet` each —
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

Private reach: none. `hestore._columns`, `hestore._persistence` and the
executor are handed the session's DBAPI cursor; nothing outside the
session layer holds it.
"""

from __future__ import annotations

import os
import weakref
from contextlib import contextmanager
from threading import get_ident
from typing import Any, Callable, Iterator

import sqlalchemy as sa

from hestore import migrate, urls
from hestore import _drivers as drivers
from hestore._columns import read_columns, read_snapshot
from hestore._journal import request_as_of
from hestore._drivers import is_driver_error
from hestore.errors import (
    HestoreError,
    InvalidInputError,
    MeshNotFoundError,
    ReadOnlyError,
    RevisionNotFoundError,
    SchemaVersionError,
    StoreError,
    StoreNotFoundError,
    WrongThreadError,
)
from hestore._persistence import Persistence
from hestore._queries import Executor, Query
from hestore._queries import history as history_q
from hestore._unitofwork import UnitOfWork

__all__ = ["Session", "MeshRef", "Snapshot", "identity"]


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


def identity(mesh) -> MeshRef:
    """The identity a `hestore.Mesh` (or a view of its past) carries: what the layers below the facade are handed.

    The facade keeps it private (``Mesh._ref``, with its session): it is no
    part of the public API. This function is the one place that reads it, for
    the modules below the facade that hold a mesh — handles, the store — and
    for examples and tests of the algorithms, which take an identity.

    Examples
    --------
    >>> import hestore
    >>> from hestore._session import identity
    >>> mesh = hestore.open("sqlite://").create_mesh("m")
    >>> identity(mesh)
    MeshRef(1, 'm')
    >>> identity(mesh).session is identity(mesh.at(0)).session
    True
    """
    return mesh._ref


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
        self, db: Executor, connection: sa.Connection, mesh_id: int, revision: int, isolated: bool,
        as_of: int | None = None,
    ) -> None:
        self._db = db
        self._connection = connection
        self._mesh_id = mesh_id
        self._as_of = as_of
        self.revision = revision
        self.isolated = isolated

    def columns(self, requests) -> list:
        """Columns of several tables of the mesh: `hestore._columns.read_columns`."""
        if self._as_of is not None:
            requests = [request_as_of(request, self._as_of) for request in requests]
        return read_columns(self._connection, self._mesh_id, requests, cursor=self._db.cursor())

    def rows(self, q: Query, values: dict | None = None) -> list[tuple]:
        """The rows of a registered query about the mesh (bound as ``:m``), in this state."""
        db = self._db
        values = {**(values or {}), "m": self._mesh_id}
        if self._as_of is None:
            return db.rows(q, values)
        values["asof"] = self._as_of
        return db.as_of(q, kept=False).rows(db.cursor(), values)


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

    def copy(self, sql, *args, **kwargs):
        self._report(sql, args)
        return self._cursor.copy(sql, *args, **kwargs)

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
    create : bool
        Whether a database without hestore's tables gets them (a SQLite file
        that does not exist is created). Without, it is `StoreNotFoundError`.

    Raises
    ------
    StoreError
        The database cannot be opened or used (not a database, unreachable,
        tables of another application in the way, driver not installed).
    StoreNotFoundError
        Without ``create``: the SQLite file does not exist, or the database
        has no hestore tables.
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

    def __init__(self, url: sa.engine.URL, *, busy_timeout: float, create: bool = True) -> None:
        self.url = url
        self.shown_url = urls.shown(url)
        path = urls.sqlite_path(url)
        if not create and path is not None and not os.path.exists(path):
            # Before connecting: SQLite creates a missing file when it opens it.
            raise StoreNotFoundError(
                f"no database at {self.shown_url}: the file {os.path.abspath(path)} does not exist"
            )
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
        # (callback, parameters) of each `traced` block open, innermost last.
        self._traces: list[tuple] = []
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
        self._db = Executor(self.dialect, lambda: self._cur)
        # The compiled statements of `fetch`, the hottest path: looked up without a call.
        self._prepared = self._db.compiled
        self._persistence = Persistence(self._db)
        try:
            self._ensure_schema(create)
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

    def writable(self, ref: MeshRef) -> None:
        """Raise unless the mesh may be edited: alive, and not a view of the past (`ReadOnlyError`)."""
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
                self.history_row(ref)
            else:
                self.kept(ref, ref.revision)

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

    def _ensure_schema(self, create: bool) -> None:
        with self._guard(f"cannot read the schema of {self.shown_url}"):
            state = migrate.schema_state(self._conn)
        if state.status == "new" and not create:
            raise StoreNotFoundError(
                f"{self.shown_url} has no hestore tables: it is an empty database, and nothing was created in it"
            )
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
    def _scope(self, kind: str, *, savepoint: bool) -> Iterator[Executor]:
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
                yield self._db
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
                yield self._db
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
            yield self._db
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
    def transaction(self, message: str | None = None) -> Iterator[Executor]:
        """A block: one transaction (nested: a savepoint) that commits or rolls back as a whole.

        `hestore.Store.transaction` is this. ``message`` names the revisions
        the block makes (the outermost block's message that is not None).
        """
        if message is not None and not isinstance(message, str):
            raise InvalidInputError(f"a transaction's message is a str, not {type(message).__name__}")
        if self._message is None:
            self._message = message
        try:
            with self._scope("block", savepoint=True) as db:
                yield db
        finally:
            if not self._scopes:
                self._message = None

    def scope(self):
        """One atomic step of several statements: its own transaction outside a block, a savepoint inside.

        Yields the executor to run them with (`hestore._queries.Executor`, on
        the session's cursor); pending edits are written before it starts and
        when it ends.
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
        self.writable(ref)
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
        self.writable(ref)
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

    def lock(self, ref: MeshRef) -> UnitOfWork | None:
        """Take the mesh's writer lock for the open transaction (before reads that an edit relies on).

        A set-based edit checks its ids against the mesh before staging its
        write; taking the lock first means nobody can change the mesh in
        between. Outside a transaction this does nothing: use it in `scope`.
        Returns the mesh's unit of work for the transaction (its
        ``revision`` is the one the transaction makes).
        """
        self.writable(ref)
        return self._uow(ref) if self._scopes else None

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

    def fetch(self, ref: MeshRef, query: Query, values: dict) -> list[tuple]:
        """Rows of a registered query about one mesh, seeing the open transaction's edits.

        For a view, the query as of its revision (`hestore._queries.Executor.as_of`),
        reading nothing unless that revision is kept.

        Parameters
        ----------
        ref : MeshRef
            The mesh; bound as ``:m``.
        query : hestore._queries.Query
            The statement (`hestore._queries.elements`, `hestore._queries.stars`, …).
        values : dict
            The other parameters (the dict is reused: ``m`` is set in it).
        """
        if self._thread != get_ident() or self._closed or self._failed or not ref.alive:
            self._alive(ref)
        try:
            if self._uows:
                self._flush()
            if ref.revision is None:
                stmt = self._prepared.get(query) or self._db.prepared(query)
            else:
                stmt = self._db.as_of(query, kept=True)
                values["asof"] = ref.revision
            values["m"] = ref.id
            cur = self._cur
            stmt.execute(cur, stmt.bind(values))
            rows = cur.fetchall()
            if not rows and ref.revision is not None:
                # A view's statement reads nothing once its revision is no longer kept: say so, not "empty".
                self.kept(ref, ref.revision)
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
    def querying(self, ref: MeshRef | None = None, what: str = "could not read") -> Iterator[Executor]:
        """Run registered queries, pending edits flushed first; driver errors are ``what`` (`StoreError`).

        With ``ref``, the mesh's identity must be alive (its rows may be
        gone: that is for the queries to find). Yields the executor, whose
        statements go on the session's cursor.
        """
        if ref is None:
            self.check()
        else:
            self._alive(ref)
        with self._guard(what):
            if self._uows:
                self._flush()
            yield self._db

    @contextmanager
    def snapshot(self, ref: MeshRef, *, committed: bool = False, kept: tuple = ()) -> Iterator[Snapshot]:
        """Reads of one mesh in one consistent state.

        Parameters
        ----------
        ref : MeshRef
        committed : bool
            Committed data only: inside a block, read through a second
            connection — except for an in-memory SQLite database, which has
            only the one (`Snapshot.isolated` then says False).
        kept : tuple of int
            Revisions of the mesh that must be kept for the reads to hold
            (a view's own revision always is): checked in the snapshot.

        Raises
        ------
        MeshNotFoundError
            The mesh is not in that state.
        RevisionNotFoundError
            The view's revision, or one of ``kept``, is not kept.
        """
        self._alive(ref)
        other = committed and self._scopes and not self.is_memory
        with self._guard(f"could not read mesh {ref.name!r}"):
            if other:
                conn = self._engine.connect()
                cursor = self._traced(conn.connection.dbapi_connection.cursor())
                db = self._db.on(lambda: cursor)
            else:
                if self._uows:
                    self._flush()
                conn, db = self._conn, self._db
            try:
                with read_snapshot(conn):
                    isolated = bool(other) or not self._scopes
                    if ref.revision is None:
                        current = self.history_row(ref, db)[0]
                        with self._kept_during(ref, kept, db):
                            yield Snapshot(db, conn, ref.id, current, isolated)
                    else:
                        # A revision of this block's own is not in the committed data: it is checked where it is
                        # (no one else can prune a mesh the block has changed: the block holds its lock).
                        mine = other and ref.id in self._changed
                        with self._kept_during(ref, (ref.revision, *kept), self._db if mine else db):
                            yield Snapshot(db, conn, ref.id, ref.revision, isolated, as_of=ref.revision)
            finally:
                if other:
                    cursor.close()
                    conn.close()

    @contextmanager
    def consistent(self) -> Iterator[None]:
        """Run the block's reads in one read snapshot of the session's connection (an open block's own state).

        Cheaper than `snapshot`, which also reads the revision: a search
        whose queries must see one committed state (`hestore.traversal`).
        """
        with self.querying(), read_snapshot(self._conn):
            yield

    # -- what a view needs ---------------------------------------------------

    def history_row(self, ref: MeshRef, db: Executor | None = None) -> tuple:
        """``(revision, kept_from, history)`` of the mesh (`MeshNotFoundError` if it is gone); run it in a scope."""
        row = (db or self._db).first(history_q.mesh_history, {"m": ref.id})
        if row is None:
            raise self.missing(ref)
        return row

    def kept(self, ref: MeshRef, revision: int, db: Executor | None = None) -> int:
        """Check that ``revision`` of the mesh can be read (`hestore._queries.history.kept`); return the current one.

        Run it in a scope (`querying`, `scope`).
        """
        return history_q.kept(ref.name, revision, self.history_row(ref, db))

    @contextmanager
    def _kept_during(self, ref: MeshRef, revisions, db: Executor) -> Iterator[None]:
        """Check that ``revisions`` of the mesh are kept for the reads of the block, made through ``db``.

        Checked before the reads, in the same snapshot. A PostgreSQL block
        reads at READ COMMITTED, each statement in a snapshot of its own, so
        another process's prune may commit between them: there the check is
        made again after the reads (a revision pruned stays pruned, so kept
        then means kept all along), and a read that failed on rows the prune
        took away is reported as the revision gone.
        """
        def check() -> None:
            for r in revisions:
                self.kept(ref, r, db)

        check()
        shared = bool(revisions) and bool(self._scopes) and not self.is_sqlite and db is self._db
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
        `ReadOnlyError`. It lives as long as the mesh does, until a rollback
        takes its revision away or a prune ends it (`end_views`).

        Raises
        ------
        RevisionNotFoundError
            The revision was never made, or is no longer kept.
        """
        with self.querying(ref, f"could not read mesh {ref.name!r}"):
            current = self.kept(ref, revision)
        view = MeshRef(self, ref.id, ref.name, ref.allow_loops, ref.allow_multi_edges, revision=revision, base=ref)
        if revision == current and ref.id in self._changed:
            self._born.append(view)  # a revision of the open transaction: a rollback takes it away
        views = [w for w in self._views.get(ref.id, ()) if w() is not None]
        self._views[ref.id] = [*views, weakref.ref(view)]
        return view

    def end_views(self, ref: MeshRef, oldest: int) -> None:
        """End the views of the mesh's revisions before ``oldest`` (a prune took them): they raise from now on."""
        for weak in self._views.get(ref.id, []):
            view = weak()
            if view is not None and view.revision < oldest:
                view.alive = False

    def changed(self, ref: MeshRef) -> bool:
        """Whether the open transaction has changed the mesh (flushed or not)."""
        uow = self._uows.get(ref.id)
        return ref.id in self._changed or (uow is not None and uow.dirty)

    def written(self, ref: MeshRef) -> None:
        """Record that the open scope changed the mesh's rows itself (a restore): its revision counts, its cache goes.

        The mesh's cached rows are those of before: the next edit reads them again.
        """
        self._changed.add(ref.id)
        self._uows.pop(ref.id, None)

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
        self._traces.append((callback, parameters))
        try:
            yield
        finally:
            self._cur = plain
            self._traces.pop()

    def _traced(self, cursor: Any) -> Any:
        """``cursor`` (of a second connection) reporting to the traces open now, as the session's own does."""
        for callback, parameters in self._traces:
            cursor = _TracingCursor(cursor, callback, parameters)
        return cursor
