"""Database URLs: which database a store (or the command line) opens, and how it is shown.

This module owns turning what a user gives — nothing, ``$HESTORE_URL``, a
SQLAlchemy URL or a bare file path — into the `sqlalchemy.engine.URL` of a
database hestore supports, and rendering URLs for messages without their
passwords. Every mistake is an `~hestore.errors.InvalidInputError` that says
what to write instead:

* a bare path (no ``://``) is exactly that SQLite file — ``?`` and ``#`` in
  it are part of the name, not a query or a fragment;
* ``postgresql://`` means ``postgresql+psycopg://`` (psycopg 3, the driver
  hestore's bulk paths use); ``postgres://`` (Heroku's spelling, which
  SQLAlchemy does not accept) is refused with that hint;
* any other database or driver (``mysql://``, ``postgresql+psycopg2://``) is
  refused in one line, before a driver is imported.

Examples
--------
>>> from hestore.urls import resolve, shown
>>> resolve("meshes?v2#old.db").database
'meshes?v2#old.db'
>>> resolve("postgresql://me:secret@db/meshes").drivername
'postgresql+psycopg'
>>> shown(resolve("postgresql://me:secret@db/meshes"))
'postgresql+psycopg://me:***@db/meshes'
"""

from __future__ import annotations

import os

import sqlalchemy as sa

from hestore.errors import InvalidInputError

__all__ = ["DEFAULT_URL", "ENVIRONMENT", "resolve", "shown", "is_memory", "sqlite_path"]

#: Where a store goes when given no URL and ``$HESTORE_URL`` is unset.
DEFAULT_URL = "sqlite:///hestore.db"

#: The environment variable naming the default database.
ENVIRONMENT = "HESTORE_URL"

#: Drivers hestore runs on, per backend; the first is what a bare backend name means.
SUPPORTED = {"sqlite": ("pysqlite",), "postgresql": ("psycopg",)}

_EXAMPLES = "sqlite:///path/to/meshes.db, a bare file path, or postgresql+psycopg://user@host/dbname"


def resolve(url: str | sa.engine.URL | None = None) -> sa.engine.URL:
    """The URL of the database to open.

    Parameters
    ----------
    url : str or sqlalchemy.engine.URL, optional
        A SQLAlchemy URL (``"sqlite:///path.db"``, ``"sqlite://"`` in memory,
        ``"postgresql+psycopg://user@host/db"``) or a bare path of a SQLite
        file. Default: ``$HESTORE_URL``, else ``./hestore.db``.

    Returns
    -------
    sqlalchemy.engine.URL
        For PostgreSQL, with the driver (``postgresql+psycopg``).

    Raises
    ------
    InvalidInputError
        Not a URL, or a database or driver hestore does not support.

    Examples
    --------
    >>> resolve("sqlite:///x.db").database, resolve("/tmp/a b.db").database
    ('x.db', '/tmp/a b.db')
    >>> resolve("mysql://me@db/meshes")
    Traceback (most recent call last):
    ...
    hestore.errors.InvalidInputError: unsupported database 'mysql' in 'mysql://me@db/meshes': hestore stores ...
    """
    if url is None:
        url = os.environ.get(ENVIRONMENT) or DEFAULT_URL
    if isinstance(url, os.PathLike):
        url = os.fspath(url)
    if isinstance(url, str):
        if "\x00" in url:
            raise InvalidInputError("a database URL or path cannot contain a NUL character")
        if not url.strip():
            raise InvalidInputError(f"no database given; use {_EXAMPLES}")
        if "://" not in url:
            # A bare path is exactly that file: no query string, no fragment.
            return sa.engine.URL.create("sqlite", database=url)
        scheme = url.split("://", 1)[0].lower()
        if scheme == "postgres":
            raise InvalidInputError(
                f"{shown(url)!r}: write postgresql+psycopg:// instead of postgres:// "
                "(SQLAlchemy does not accept the postgres:// spelling)"
            )
        try:
            parsed = sa.engine.make_url(url)
        except (sa.exc.ArgumentError, ValueError) as exc:
            raise InvalidInputError(f"not a database URL: {shown(url)!r} ({exc}); use {_EXAMPLES}") from None
    elif isinstance(url, sa.engine.URL):
        parsed = url
    else:
        raise InvalidInputError(f"a database URL is a string or a sqlalchemy URL, not {type(url).__name__}")
    backend, driver = parsed.get_backend_name(), parsed.get_driver_name()
    if backend not in SUPPORTED:
        raise InvalidInputError(
            f"unsupported database {backend!r} in {shown(parsed)!r}: hestore stores meshes in SQLite or "
            f"PostgreSQL; use {_EXAMPLES}"
        )
    drivers = SUPPORTED[backend]
    if "+" not in parsed.drivername:
        # SQLAlchemy's default SQLite driver is the one; its PostgreSQL default is not.
        return parsed if backend == "sqlite" else parsed.set(drivername=f"{backend}+{drivers[0]}")
    if driver not in drivers:
        raise InvalidInputError(
            f"unsupported driver {driver!r} in {shown(parsed)!r}: hestore runs {backend} through "
            f"{' or '.join(drivers)}; write {backend}+{drivers[0]}://..."
        )
    return parsed


def shown(url: str | sa.engine.URL) -> str:
    """``url`` as text for messages and logs, its password hidden.

    Examples
    --------
    >>> shown("postgresql+psycopg://me:secret@db/meshes")
    'postgresql+psycopg://me:***@db/meshes'
    >>> shown("not a url")
    'not a url'
    """
    try:
        parsed = url if isinstance(url, sa.engine.URL) else sa.engine.make_url(url)
        return parsed.render_as_string(hide_password=True)
    except (sa.exc.ArgumentError, ValueError, TypeError):
        return str(url)


def is_memory(url: sa.engine.URL) -> bool:
    """Whether ``url`` is an in-memory SQLite database.

    Examples
    --------
    >>> is_memory(resolve("sqlite://")), is_memory(resolve("x.db"))
    (True, False)
    """
    return url.get_backend_name() == "sqlite" and url.database in (None, "", ":memory:")


def sqlite_path(url: sa.engine.URL) -> str | None:
    """The file of a SQLite URL (None for other databases, in-memory and ``file:`` URI ones).

    Examples
    --------
    >>> sqlite_path(resolve("sqlite:///data/m.db")), sqlite_path(resolve("sqlite://"))
    ('data/m.db', None)
    """
    if url.get_backend_name() != "sqlite" or is_memory(url):
        return None
    database = url.database or ""
    return None if url.query.get("uri") else database
