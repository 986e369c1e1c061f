"""The ``hestore`` command line.

``hestore [--db URL] [--busy-timeout SECONDS] COMMAND`` — the database is ``--db``, else
``$HESTORE_URL``, else ``./hestore.db`` (a bare path means a SQLite file).
Only ``import``, ``demo`` and ``db upgrade`` create a database that does not
exist; every other command says there is none, naming the file
(`hestore.open` with ``create=False``). ``--busy-timeout`` is how long a
command waits for another writer's lock (`hestore.open`'s ``busy_timeout``).
The console script ``hestore`` and ``python -m hestore`` are
`hestore.__main__`, which calls `main` here. `main` parses (`hestore.cli.parser`: a table of
commands, each with its handler), runs the command's handler
(`hestore.cli.commands`: each calls the library and prints, through
`hestore.cli.text`), and turns every error a user can cause (hestore's own,
an unreachable or malformed database URL, an unknown schema revision, a file
that cannot be read or written) into one line on stderr and exit status 2.
``hestore demo`` is `hestore.cli.demo`.

Commands: ``demo``, ``import FILE [--orient] [--replace]``, ``export NAME FILE [--revision R]``,
``render NAME FILE.png|.svg [--revision R] [--view V] [--labels [WHAT]] [--check|--no-check] [--size WxH]``
(`hestore.Mesh.render`), ``list``,
``delete NAME``, ``rename NAME NEW``, ``copy NAME NEW [--revision R]``, ``log NAME [--limit N]``,
``diff NAME A B``, ``undo NAME``, ``redo NAME``, ``revert NAME R``,
``info NAME`` (`hestore.Mesh.stats` and `hestore.Mesh.properties`), ``check NAME``, ``graph NAME
components|path A B [--weight W]|neighbors V [--k K]|degree-histogram|export FILE``, ``db upgrade``,
``db current``.

``graph NAME path A B`` (fewest edges, or ``--weight length`` or an edge property) and
``graph NAME neighbors V --k K`` (the ids of the vertices within K edges of V, V included, ascending,
on one line) are local queries (`hestore.Mesh.shortest_path` and `hestore.Mesh.path_weight`,
`hestore.Mesh.k_ring`): they read the store around their vertices and never build the whole graph.
``degree-histogram`` and ``export`` go through networkx (`hestore.Mesh.to_networkx`).

Exit status: 0 success, 1 ``check`` found violations or ``graph … path``
found no path, 2 error, 130 interrupted (`hestore.__main__`).

``import``, ``export``, ``render``, and ``check``, ``info`` and the whole-graph ``graph`` commands when
they take over a second (large meshes), report progress through `hestore.progress.ProgressBar`, on
stderr: a redrawn bar on a terminal, and only a plain final line elsewhere, so that logs carry no
control characters. Results go to stdout.

The command line is thin: URLs are `hestore.urls`'s, schema states
`hestore.migrate`'s, graph files `hestore.graphio`'s, the progress bar
`hestore.progress`'s and every answer the library's. The ``db`` commands work
below the store (`hestore.open` refuses a database whose schema is behind;
that refusal is what tells users to run ``hestore db upgrade``): they call
`hestore.migrate.database_state` and `hestore.migrate.upgrade_database`.

Ctrl-C raises `KeyboardInterrupt` in `main`, which lets it through: the
command's writes, one transaction, roll back on the way out, and the entry
point (`hestore.__main__`, which also covers the imports before `main` runs)
turns it into one line and exit status 130. An unexpected error is one line
(``HESTORE_DEBUG=1`` shows its traceback).
"""

from __future__ import annotations

import os
import sys
from collections.abc import Sequence

from hestore import urls
from hestore.cli.parser import build_parser
from hestore.cli.text import error
from hestore.errors import HestoreError

__all__ = ["DEFAULT_URL", "main", "build_parser"]

#: The database used when neither ``--db`` nor ``$HESTORE_URL`` is given.
DEFAULT_URL = urls.DEFAULT_URL

#: Set it (to anything) to see the traceback of an unexpected error instead of one line.
DEBUG_ENVIRONMENT = "HESTORE_DEBUG"


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``hestore`` command line.

    Parameters
    ----------
    argv : sequence of str, optional
        The arguments, without the program name; default ``sys.argv[1:]``.

    Returns
    -------
    int
        The exit status: 0 success, 1 ``check`` found violations or ``graph … path``
        found no path, 2 error
        (reported as one line on stderr, never a traceback).

    Raises
    ------
    KeyboardInterrupt
        Ctrl-C, after the command's transaction rolled back: `hestore.__main__`
        makes it one line and exit status 130.

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
        return error(str(exc))
    except OSError as exc:
        # Not a file the library reads or writes (those are InvalidInputError): the standard streams themselves.
        if exc.filename is not None and exc.strerror:
            return error(f"{os.fsdecode(exc.filename)}: {exc.strerror}")
        return error(str(exc))
    except Exception as exc:
        if os.environ.get(DEBUG_ENVIRONMENT):
            raise
        # networkx is imported by the graph commands only: look for it, never import it here.
        nx = sys.modules.get("networkx")
        if nx is not None and isinstance(exc, nx.NetworkXException):
            return error(f"networkx: {exc}")
        return error(
            f"unexpected {type(exc).__name__}: {exc} (a bug in hestore; set {DEBUG_ENVIRONMENT}=1 for the traceback)"
        )
