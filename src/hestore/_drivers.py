"""Database drivers: making engines, and what their errors mean in hestore's terms.

This module owns the two places where hestore meets SQLAlchemy's engines and
the DBAPI drivers below them (sqlite3, psycopg 3): `make_engine` (SQLite's
WAL, busy timeout and page cache; PostgreSQL's lock timeout) and the
translation of every driver exception into a typed
`~hestore.errors.StoreError` (`translate`, `guard`), so that no driver
exception leaves a public call. `hestore._session` uses both for the store's
connections, `hestore.migrate` for the ``hestore db`` commands.

Examples
--------
>>> import sqlalchemy as sa
>>> from hestore._drivers import guard
>>> engine = sa.create_engine("sqlite://")
>>> with engine.connect() as conn, guard("could not read", "sqlite://"):
...     conn.execute(sa.text("SELECT * FROM nowhere"))
Traceback (most recent call last):
...
hestore.errors.StoreError: could not read: no such table: nowhere
"""

from __future__ import annotations

import sqlite3
from contextlib import contextmanager
from typing import Any, Iterator

import sqlalchemy as sa
from sqlalchemy import event
from sqlalchemy.pool import NullPool, StaticPool

from hestore import urls
from hestore.errors import HestoreError, StoreBusyError, StoreError

__all__ = ["DEFAULT_BUSY_TIMEOUT", "make_engine", "is_driver_error", "is_integrity_error", "translate", "guard"]

_BUSY_SQLSTATES = {"55P03", "40P01", "40001"}  # lock_not_available, deadlock, serialization
_READ_ONLY_SQLSTATES = {"25006"}  # read_only_sql_transaction
_LOCK_TIMEOUT_MAX_MS = 2**31 - 1  # PostgreSQL's lock_timeout is an int of milliseconds


#: Seconds a connection waits for another writer's lock unless told otherwise (`hestore.open`, the ``db``
#: commands).
DEFAULT_BUSY_TIMEOUT = 5.0


def make_engine(
    url: sa.engine.URL, *, busy_timeout: float, pooled: bool = True, autocommit: bool = True
) -> sa.engine.Engine:
    """An engine for ``url``, set up for hestore.

    With ``autocommit`` (what a store uses) the driver runs in autocommit mode
    and the session issues ``BEGIN``/``COMMIT`` itself; without it, the engine
    uses SQLAlchemy's own transactions (what migrations run in). Without
    ``pooled`` each connection is closed when released (one short command).

    SQLite files get WAL (readers never wait for the writer), ``synchronous =
    NORMAL`` (safe in WAL mode) and a 64 MiB page cache; every SQLite
    connection waits ``busy_timeout`` seconds for the writer lock, every
    PostgreSQL one as long for a row lock (``lock_timeout``, which holds at
    most about 24.8 days: a longer wait is that long). An in-memory
    SQLite database is one connection shared by the engine.

    Raises
    ------
    StoreError
        The driver is not installed.
    """
    kwargs: dict[str, Any] = {"isolation_level": "AUTOCOMMIT"} if autocommit else {}
    sqlite = url.get_backend_name() == "sqlite"
    memory = urls.is_memory(url)
    if sqlite:
        kwargs["connect_args"] = {"timeout": busy_timeout}
        if memory:
            kwargs["poolclass"] = StaticPool
            # One connection for the whole store; the session itself refuses other threads.
            kwargs["connect_args"]["check_same_thread"] = False
    if not pooled and not memory:
        kwargs["poolclass"] = NullPool
    try:
        engine = sa.create_engine(url, **kwargs)
    except ModuleNotFoundError as exc:
        raise StoreError(
            f"cannot open {urls.shown(url)}: its database driver {exc.name!r} is not installed; "
            "install it with: pip install 'hestore[postgresql]'"
        ) from exc

    if sqlite:

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

    else:
        ms = min(max(1, int(busy_timeout * 1000)), _LOCK_TIMEOUT_MAX_MS)

        @event.listens_for(engine, "connect")
        def _lock_timeout(dbapi_conn, _record):
            cur = dbapi_conn.cursor()
            cur.execute(f"SET lock_timeout = {ms}")
            cur.close()

    return engine


def is_driver_error(exc: BaseException) -> bool:
    """Whether ``exc`` comes from SQLAlchemy or a database driver (not from hestore or Python).

    Examples
    --------
    >>> import sqlite3
    >>> is_driver_error(sqlite3.OperationalError("disk I/O error")), is_driver_error(ValueError())
    (True, False)
    """
    if isinstance(exc, (sa.exc.SQLAlchemyError, sqlite3.Error)):
        return True
    return any(k.__module__.partition(".")[0] == "psycopg" for k in type(exc).__mro__)


def is_integrity_error(exc: BaseException) -> bool:
    """Whether ``exc`` is a driver's refusal of a row that breaks a constraint (a name taken, say).

    Examples
    --------
    >>> import sqlite3
    >>> is_integrity_error(sqlite3.IntegrityError("UNIQUE constraint failed")), is_integrity_error(ValueError())
    (True, False)
    """
    if isinstance(exc, (sa.exc.IntegrityError, sqlite3.IntegrityError)):
        return True
    # psycopg's errors by SQLSTATE (UniqueViolation, …) are subclasses of its IntegrityError.
    return any(
        k.__name__ == "IntegrityError" and k.__module__.partition(".")[0] == "psycopg" for k in type(exc).__mro__
    )


def translate(exc: BaseException, what: str, shown_url: str) -> StoreError:
    """The typed error for a driver's exception; raise it ``from exc``.

    A lock not granted in time is `StoreBusyError`; a read-only database, a
    file that is not a database and everything else a `StoreError` whose
    message says what was being done, then the driver's own words.

    Examples
    --------
    >>> import sqlite3
    >>> str(translate(sqlite3.OperationalError("database is locked"), "could not commit", "sqlite:///x.db"))
    'could not commit: another writer holds the lock (database is locked)'
    >>> str(translate(sqlite3.DatabaseError("file is not a database"), "cannot open", "sqlite:///x.db"))
    'cannot open: sqlite:///x.db is not a SQLite database (file is not a database)'
    """
    orig = getattr(exc, "orig", None) or exc
    text = " ".join(str(orig).split()) or type(orig).__name__
    sqlstate = getattr(orig, "sqlstate", None)
    lower = text.lower()
    if sqlstate in _BUSY_SQLSTATES or (
        isinstance(orig, sqlite3.OperationalError) and ("locked" in lower or "busy" in lower)
    ):
        return StoreBusyError(f"{what}: another writer holds the lock ({text})")
    if sqlstate in _READ_ONLY_SQLSTATES or "readonly database" in lower or "read-only" in lower:
        return StoreError(f"{what}: the database {shown_url} is read-only ({text})")
    if "file is not a database" in lower:
        return StoreError(f"{what}: {shown_url} is not a SQLite database ({text})")
    return StoreError(f"{what}: {text}")


@contextmanager
def guard(what: str, shown_url: str) -> Iterator[None]:
    """Let hestore's own errors and Python's through; turn a driver's into `translate`'s."""
    try:
        yield
    except HestoreError:
        raise
    except Exception as exc:
        if is_driver_error(exc):
            raise translate(exc, what, shown_url) from exc
        raise
