"""The ``hestore`` command line.

``hestore [--db URL] COMMAND`` — the database is ``--db``, else
``$HESTORE_URL``, else ``./hestore.db`` (a bare path means a SQLite file).
Each command is a subparser with a ``_cmd_*`` function; `main` parses,
dispatches, and turns every error a user can cause (hestore's own, an
unreachable or malformed database URL, an unknown schema revision) into one
line on stderr and exit status 2.

Exit status: 0 success, 1 ``check`` found violations, 2 error.

The ``db`` commands work below the store: `hestore.open` refuses a database
whose schema is behind (that refusal is what tells users to run
``hestore db upgrade``), so they use an engine and `hestore.migrate` directly.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence
from pathlib import Path

import sqlalchemy as sa
from alembic.util.exc import CommandError

import hestore
from hestore import migrate
from hestore.errors import HestoreError, SchemaVersionError

__all__ = ["DEFAULT_URL", "main", "build_parser"]

#: The database used when neither ``--db`` nor ``$HESTORE_URL`` is given.
DEFAULT_URL = "sqlite:///hestore.db"

#: Database drivers hestore documents, and the extra that installs each.
_DRIVER_EXTRAS = {"psycopg": "hestore[postgresql]"}


def _url(args: argparse.Namespace) -> str:
    url = args.db or os.environ.get("HESTORE_URL") or DEFAULT_URL
    # As in hestore.open: a bare path means a SQLite file.
    return url if "://" in url else f"sqlite:///{url}"


def _shown(url: str | sa.URL) -> str:
    # Never echo a password to the terminal (or into a CI log).
    try:
        return sa.make_url(url).render_as_string(hide_password=True)
    except sa.exc.ArgumentError:
        return str(url)


def _open(args: argparse.Namespace) -> hestore.Store:
    return hestore.open(_url(args))


def _engine(url: str) -> sa.Engine:
    # One short command, one connection: nothing to pool.
    return sa.create_engine(url, poolclass=sa.pool.NullPool)


def _sqlite_file_missing(url: str) -> Path | None:
    """The path of a SQLite database file that does not exist yet, else None."""
    parsed = sa.make_url(url)
    if parsed.get_backend_name() != "sqlite":
        return None
    database = parsed.database or ""
    if database in ("", ":memory:") or database.startswith("file:") or parsed.query.get("uri"):
        return None
    path = Path(database)
    return None if path.exists() else path


# -- commands ---------------------------------------------------------------


def _cmd_demo(args: argparse.Namespace) -> int:
    from hestore import demo

    with _open(args) as store:
        demo.run(store)
    return 0


def _cmd_list(args: argparse.Namespace) -> int:
    with _open(args) as store:
        names = store.meshes()
        if not names:
            print(f"no meshes in {_shown(store.url)}", file=sys.stderr)
            return 0
        width = max(len(name) for name in names)
        for name in names:
            mesh = store.mesh(name)
            c = mesh.counts()
            print(
                f"{name:<{width}}  {c.vertices} vertices, {c.edges} edges, "
                f"{c.halfedges} half-edges, {c.polygons} polygons, revision {mesh.revision}"
            )
    return 0


def _cmd_check(args: argparse.Namespace) -> int:
    with _open(args) as store:
        violations = store.mesh(args.name).check()
    if not violations:
        print(f"{args.name}: valid")
        return 0
    print(f"{args.name}: {len(violations)} invariant violation(s)")
    for violation in violations:
        print(violation)
    return 1


def _cmd_db_upgrade(args: argparse.Namespace) -> int:
    url = _url(args)
    head = migrate.head_revision()
    engine = _engine(url)
    try:
        with engine.connect() as conn:
            before = migrate.current_revision(conn)
            if before == head:
                print(f"{_shown(url)}: already at head ({head})")
                return 0
            if before is None and sa.inspect(conn).has_table("meshes"):
                # Creating the tables would collide with these; which revision
                # they match is anyone's guess, so leave them to a human.
                raise SchemaVersionError(
                    f"{_shown(url)} has a 'meshes' table but no hestore schema version, "
                    "so it was not created by hestore; refusing to migrate it"
                )
            if before is not None and before not in migrate.revisions():
                raise SchemaVersionError(
                    f"{_shown(url)} is at schema revision {before}, which hestore "
                    f"{hestore.__version__} does not know (its head is {head}); "
                    "it was written by a newer hestore"
                )
            migrate.upgrade(conn)
    finally:
        engine.dispose()
    origin = "an empty database" if before is None else before
    print(f"{_shown(url)}: upgraded from {origin} to {head} (head)")
    return 0


def _cmd_db_current(args: argparse.Namespace) -> int:
    url = _url(args)
    head = migrate.head_revision()
    missing = _sqlite_file_missing(url)
    if missing is not None:
        # Connecting would create the file; asking must not change anything.
        print(f"none (no database at {missing} yet; head is {head})")
        return 0
    engine = _engine(url)
    try:
        with engine.connect() as conn:
            current = migrate.current_revision(conn)
    finally:
        engine.dispose()
    if current == head:
        print(f"{current} (head)")
    elif current is None:
        print(f"none (empty database; head is {head}: run `hestore db upgrade`)")
    elif current in migrate.revisions():
        print(f"{current} (behind head {head}: run `hestore db upgrade`)")
    else:
        print(
            f"{current} (unknown to hestore {hestore.__version__}, whose head is {head}: "
            "written by a newer hestore)"
        )
    return 0


# -- parser -----------------------------------------------------------------


def build_parser() -> argparse.ArgumentParser:
    """Build the argument parser of the ``hestore`` command.

    Returns
    -------
    argparse.ArgumentParser
        Parsing sets ``func``, the command's function, and its arguments.

    Examples
    --------
    >>> from hestore.cli import build_parser
    >>> args = build_parser().parse_args(["--db", "sqlite:///x.db", "check", "part"])
    >>> args.db, args.name
    ('sqlite:///x.db', 'part')
    """
    parser = argparse.ArgumentParser(
        prog="hestore",
        description="A persistent, transactional half-edge topology store.",
        epilog="The database is --db, else $HESTORE_URL, else ./hestore.db.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {hestore.__version__}")
    parser.add_argument(
        "--db",
        metavar="URL",
        help="SQLAlchemy database URL, e.g. sqlite:///meshes.db or postgresql+psycopg://user@host/db "
        "(a bare path means a SQLite file)",
    )
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)

    demo = commands.add_parser(
        "demo", help="build the demo mesh 'demo' (replacing it) and print what happened"
    )
    demo.set_defaults(func=_cmd_demo)

    listing = commands.add_parser("list", help="list the meshes: counts and revision of each")
    listing.set_defaults(func=_cmd_list)

    check = commands.add_parser(
        "check", help="check a mesh's invariants; exit status 1 and the violations when invalid"
    )
    check.add_argument("name", metavar="NAME", help="the mesh to check")
    check.set_defaults(func=_cmd_check)

    db = commands.add_parser("db", help="database schema: upgrade, current")
    db_commands = db.add_subparsers(dest="db_command", metavar="DB_COMMAND", required=True)
    upgrade = db_commands.add_parser(
        "upgrade", help="migrate the database schema to this hestore's head (creates a new one)"
    )
    upgrade.set_defaults(func=_cmd_db_upgrade)
    current = db_commands.add_parser(
        "current", help="print the database's schema revision and whether it is head"
    )
    current.set_defaults(func=_cmd_db_current)

    return parser


def _error(message: str) -> int:
    # One line, whatever the message: the rest goes to the logs, not the user.
    line = str(message).strip().splitlines()[0] if str(message).strip() else "unknown error"
    print(f"hestore: error: {line}", file=sys.stderr)
    return 2


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``hestore`` command line.

    Parameters
    ----------
    argv : sequence of str, optional
        The arguments, without the program name; default ``sys.argv[1:]``.

    Returns
    -------
    int
        The exit status: 0 success, 1 ``check`` found violations, 2 error
        (reported as one line on stderr, never a traceback).

    Examples
    --------
    >>> import tempfile
    >>> from hestore.cli import main
    >>> url = f"sqlite:///{tempfile.mkdtemp()}/example.db"
    >>> main(["--db", url, "db", "upgrade"])  # doctest: +ELLIPSIS
    sqlite:///.../example.db: upgraded from an empty database to ... (head)
    0
    >>> main(["--db", url, "check", "nonexistent"])  # the error line goes to stderr
    2
    """
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:
        # --help, --version and usage errors; return rather than exit so that
        # main() behaves the same in-process as from the console script.
        return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 2)
    url = _url(args)
    try:
        status = args.func(args)
        sys.stdout.flush()
        return status
    except BrokenPipeError:
        # The reader went away (`hestore list | head`): stop quietly with the
        # status of a process killed by SIGPIPE, as other command-line tools do,
        # and keep Python from complaining when it flushes stdout at exit.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 128 + 13
    except HestoreError as exc:
        return _error(str(exc))
    except CommandError as exc:
        return _error(f"cannot migrate {_shown(url)}: {exc}")
    except sa.exc.OperationalError as exc:
        cause = exc.orig if exc.orig is not None else exc
        return _error(f"cannot use the database {_shown(url)}: {cause}")
    except sa.exc.ArgumentError as exc:
        return _error(f"invalid database URL {_shown(url)!r}: {exc}")
    except ModuleNotFoundError as exc:
        if exc.name not in _DRIVER_EXTRAS:
            raise
        return _error(
            f"the database driver {exc.name!r} for {_shown(url)} is not installed; "
            f"install it with: pip install '{_DRIVER_EXTRAS[exc.name]}'"
        )


if __name__ == "__main__":  # pragma: no cover - `python -m hestore` uses __main__.py
    sys.exit(main())
