"""Database URLs and file paths: which database a store (or the command line) opens, which file a call reads
or writes, and how they are shown.

This module owns turning what a user gives — nothing, ``$HESTORE_URL``, a
SQLAlchemy URL or a bare file path — into the `sqlalchemy.engine.URL` of a
database hestore supports, rendering URLs for messages without their
passwords, and checking every file path a caller gives (`check_path`: a
database file, a mesh file to import or export, a picture, a graph file).
Every mistake is an `~hestore.errors.InvalidInputError` that says what to
write instead:

* a bare path (no ``://``) is exactly that SQLite file — ``?`` and ``#`` in
  it are part of the name, not a query or a fragment;
* ``postgresql://`` means ``postgresql+psycopg://`` (psycopg 3, the driver
  hestore's bulk paths use); ``postgres://`` (Heroku's spelling, which
  SQLAlchemy does not accept) is refused with that hint;
* any other database or driver (``mysql://``, ``postgresql+psycopg2://``,
  ``http://``, a misspelling such as ``postgresq://``, which gets a
  suggestion) is refused in one line, read from the URL's text: no dialect
  or driver is looked up, so none of SQLAlchemy's errors can escape;
* a path is a str, bytes or `os.PathLike` with no NUL character, that the
  file system's encoding can write (no lone surrogates): anything else is
  refused naming it, before a file is touched.

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

__all__ = ["URL", "DEFAULT_URL", "ENVIRONMENT", "resolve", "check_path", "shown", "is_memory", "sqlite_path"]

#: A database URL as SQLAlchemy parses it (what `resolve` returns): the type, for modules that do not import it.
URL = sa.engine.URL

#: Where a store goes when given no URL and ``$HESTORE_URL`` is unset.
DEFAULT_URL = "sqlite:///hestore.db"

#: The environment variable naming the default database.
ENVIRONMENT = "HESTORE_URL"

#: Drivers hestore runs on, per backend; the first is what a bare backend name means.
SUPPORTED = {"sqlite": ("pysqlite",), "postgresql": ("psycopg",)}

#: How to write a URL of each backend, for messages.
_SPELLINGS = {
    "sqlite": "sqlite:///path/to/meshes.db or a bare file path",
    "postgresql": "postgresql+psycopg://user@host/dbname",
}

_EXAMPLES = f"{_SPELLINGS['sqlite']}, or {_SPELLINGS['postgresql']}"


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
    path_object = isinstance(url, os.PathLike)
    if path_object:
        url = check_path(url, "a database path")
    if isinstance(url, str):
        # Not check_path's checks: the drivers take UTF-8 only, and a message must not quote a URL's password.
        if "\x00" in url:
            raise InvalidInputError("a database URL or path cannot contain a NUL character")
        try:
            url.encode("utf-8")
        except UnicodeEncodeError:
            raise InvalidInputError("a database URL or path must be valid Unicode text (no lone surrogates)") from None
        if not url.strip():
            raise InvalidInputError(f"no database given; use {_EXAMPLES}")
        if path_object or "://" not in url:
            # A bare path is exactly that file (a path object too, whatever its name): no query, no fragment.
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
    # From the text, not get_driver_name(): that loads the dialect, and an unknown one raises SQLAlchemy's error.
    backend, plus, driver = parsed.drivername.partition("+")
    if backend not in SUPPORTED:
        raise InvalidInputError(
            f"unsupported database {backend!r} in {shown(parsed)!r}{_suggestion(backend)}: hestore stores meshes in "
            f"SQLite or PostgreSQL; use {_EXAMPLES}"
        )
    drivers = SUPPORTED[backend]
    if not plus:
        # SQLAlchemy's default SQLite driver is the one; its PostgreSQL default is not.
        return parsed if backend == "sqlite" else parsed.set(drivername=f"{backend}+{drivers[0]}")
    if driver not in drivers:
        raise InvalidInputError(
            f"unsupported driver {driver!r} in {shown(parsed)!r}: hestore runs {backend} through "
            f"{' or '.join(drivers)}; use {_SPELLINGS[backend]}"
        )
    return parsed


def _suggestion(backend: str) -> str:
    """``" (did you mean postgresql?)"`` for a near miss of a supported backend's name, else nothing."""
    import difflib  # only on this error path

    close = difflib.get_close_matches(backend.lower(), SUPPORTED, n=1, cutoff=0.6)
    return f" (did you mean {close[0]}?)" if close else ""


def check_path(path: object, what: str = "a file path") -> str:
    """``path`` — a str, bytes or `os.PathLike` — as the str a file call takes, checked.

    Bytes are decoded as `os.fsdecode` does (so every byte string the file
    system can hold comes back the same). ``what`` names the path in the
    message.

    Raises
    ------
    InvalidInputError
        ``path`` is none of those, its ``__fspath__`` raised, it contains a
        NUL character, or it is text no file name can be (a lone surrogate).

    Examples
    --------
    >>> import pathlib
    >>> check_path(pathlib.Path("meshes") / "a.off"), check_path(b"b.ply")
    ('meshes/a.off', 'b.ply')
    >>> check_path("a\\x00b.off")
    Traceback (most recent call last):
    ...
    hestore.errors.InvalidInputError: a file path cannot contain a NUL character: 'a\\x00b.off'
    >>> check_path(42)
    Traceback (most recent call last):
    ...
    hestore.errors.InvalidInputError: a file path is a str, bytes or os.PathLike, not int
    """
    if not isinstance(path, (str, bytes, os.PathLike)):
        raise InvalidInputError(f"{what} is a str, bytes or os.PathLike, not {type(path).__name__}")
    try:
        text = os.fsdecode(os.fspath(path))
    except Exception as exc:  # noqa: BLE001 - a caller's __fspath__ may raise (or return) anything
        raise InvalidInputError(
            f"{what}: os.fspath of the {type(path).__name__} given raised {type(exc).__name__}: {exc}"
        ) from exc
    if "\x00" in text:
        raise InvalidInputError(f"{what} cannot contain a NUL character: {text!r}")
    try:
        os.fsencode(text)
    except UnicodeEncodeError:
        raise InvalidInputError(
            f"{what} must be a name the file system can hold (no lone surrogates): {text!r}"
        ) from None
    return text


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
