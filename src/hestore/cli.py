"""The ``hestore`` command line.

``hestore [--db URL] COMMAND`` — the database is ``--db``, else
``$HESTORE_URL``, else ``./hestore.db`` (a bare path means a SQLite file).
Each command is a subparser with a ``_cmd_*`` function; `main` parses,
dispatches, and turns every error a user can cause (hestore's own, an
unreachable or malformed database URL, an unknown schema revision, a file
that cannot be read or written) into one line on stderr and exit status 2.

Commands: ``demo``, ``import FILE``, ``export NAME FILE``, ``list``,
``info NAME`` (`hestore.Mesh.stats`), ``check NAME``, ``graph NAME
components|path A B|degree-histogram|export FILE`` (networkx, through
`hestore.Mesh.to_networkx`), ``db upgrade``, ``db current``.

Exit status: 0 success, 1 ``check`` found violations or ``graph … path``
found no path, 2 error.

``import`` and ``export`` report progress through `ProgressBar`, on stderr:
a redrawn bar on a terminal, and only a plain final line elsewhere, so that
logs carry no control characters. Results go to stdout.

The ``db`` commands work below the store: `hestore.open` refuses a database
whose schema is behind (that refusal is what tells users to run
``hestore db upgrade``), so they use an engine and `hestore.migrate` directly.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TextIO

import sqlalchemy as sa
from alembic.util.exc import CommandError

import hestore
from hestore import migrate
from hestore.errors import HestoreError, MeshExistsError, SchemaVersionError

__all__ = ["DEFAULT_URL", "ProgressBar", "main", "build_parser"]

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


# -- progress ---------------------------------------------------------------


def _isatty(stream: TextIO) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):  # no isatty, or a closed stream
        return False


def _columns(stream: TextIO) -> int:
    """The width of the terminal behind ``stream`` (80 when it cannot be told)."""
    try:
        return os.get_terminal_size(stream.fileno()).columns or 80
    except (AttributeError, ValueError, OSError):  # no file descriptor, or not a terminal
        return 80


def _amount(n: int, unit: str | None) -> str:
    """``n`` in ``unit``, for people: bytes in B/KiB/MiB/GiB, anything else counted."""
    if unit == "bytes":
        if n < 1024:
            return f"{n} B"
        value = float(n)
        for prefix in "KMGT":
            value /= 1024
            if value < 1024 or prefix == "T":
                return f"{value:.1f} {prefix}iB"
    return f"{n:,} {unit}" if unit else ""


def _progress_amount(done: int, total: int, unit: str) -> str:
    """``done`` of ``total``, e.g. ``1.2 MiB of 4.9 MiB`` or ``1,000 of 20,000 rows``."""
    if unit == "bytes":
        return f"{_amount(done, unit)} of {_amount(total, unit)}"
    return f"{done:,} of {_amount(total, unit)}"


class ProgressBar:
    """A one-line progress display, called as ``progress(stage, done, total)``.

    On a terminal it redraws one line in place (with ``\\r``), at most once
    per ``interval`` seconds: the stage, a bar, the percentage and the amount
    done (``units`` names each stage's unit; ``"bytes"`` is shown in
    KiB/MiB/GiB, a stage without a unit shows only the percentage). Anywhere
    else (a pipe, a log file) it draws nothing while running, so the output
    holds no control characters. Either way, `close` after success writes one
    plain line: each stage with its amount and time. After a failure it
    erases the bar and writes nothing, so that the error stays one line.

    Use it as a context manager: leaving the block closes it, successfully
    unless an exception is leaving too.

    Parameters
    ----------
    stream : text stream, optional
        Where to draw; default ``sys.stderr``.
    units : dict, optional
        Stage name to unit (``{"read": "bytes", "write": "rows"}``).
    interval : float
        Least time between two redraws, in seconds.
    width : int
        Characters in the bar itself.
    clock : callable
        Returns the time in seconds (`time.monotonic`; tests pass a fake).

    Examples
    --------
    >>> import io
    >>> out = io.StringIO()  # not a terminal: one plain line at the end
    >>> with ProgressBar(out, units={"read": "bytes", "write": "rows"}, clock=lambda: 0.0) as bar:
    ...     bar("read", 2048, 4096)
    ...     bar("read", 4096, 4096)
    ...     bar("write", 12000, 12000)
    >>> out.getvalue()
    'read 4.0 KiB in 0.0 s, write 12,000 rows in 0.0 s\\n'
    """

    def __init__(
        self,
        stream: TextIO | None = None,
        *,
        units: dict[str, str] | None = None,
        interval: float = 0.1,
        width: int = 24,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.stream = sys.stderr if stream is None else stream
        self.tty = _isatty(self.stream)
        self._columns = _columns(self.stream) if self.tty else 80
        self.units = dict(units or {})
        self.interval = interval
        self.width = width
        self.clock = clock
        self._started = clock()
        # stage -> [done, total, time of its last call], in the order the stages began
        self._stages: dict[str, list] = {}
        self._stage: str | None = None
        self._drawn_at: float | None = None
        self._shown = 0  # characters of the line now on screen
        self._closed = False

    def __call__(self, stage: str, done: int, total: int) -> None:
        now = self.clock()
        new_stage = stage != self._stage
        if new_stage:
            self._stage = stage
            self._stages.pop(stage, None)  # a stage that comes back starts over, at the end
        self._stages[stage] = [int(done), int(total), now]
        # A new stage is always shown (there are a few); within one, at most every `interval`.
        if self.tty and (new_stage or self._drawn_at is None or now - self._drawn_at >= self.interval):
            # Never wider than the terminal: a wrapped line cannot be redrawn in place.
            self._draw(self.line(stage, int(done), int(total))[: max(self._columns - 1, 1)])
            self._drawn_at = now

    def line(self, stage: str, done: int, total: int) -> str:
        """The bar as drawn on a terminal, e.g. ``read  [######..................]  25%  1.0 MiB of 4.0 MiB``."""
        done = min(max(done, 0), total) if total > 0 else done
        fraction = done / total if total > 0 else 1.0
        filled = int(fraction * self.width)
        text = f"{stage:<5} [{'#' * filled}{'.' * (self.width - filled)}] {int(fraction * 100):3d}%"
        unit = self.units.get(stage)
        if unit:
            text += "  " + _progress_amount(done, total, unit)
        return text

    def summary(self) -> str:
        """Each stage with its amount and time, e.g. ``read 4.0 KiB in 0.1 s, build in 0.2 s``.

        A stage's time runs from the previous stage's last call (or from the
        bar's creation) to its own last call.
        """
        parts = []
        since = self._started
        for stage, (done, _total, last) in self._stages.items():
            amount = _amount(done, self.units.get(stage))
            seconds = max(last - since, 0.0)
            parts.append(f"{stage} {amount} in {seconds:.1f} s" if amount else f"{stage} in {seconds:.1f} s")
            since = last
        return ", ".join(parts)

    def _draw(self, text: str) -> None:
        # Pad with spaces over what the previous line left on screen.
        self.stream.write("\r" + text + " " * max(0, self._shown - len(text)))
        self.stream.flush()
        self._shown = len(text)

    def close(self, ok: bool = True) -> None:
        """Finish: the plain final line after success, nothing (the bar erased) after a failure."""
        if self._closed:
            return
        self._closed = True
        if ok and self._stages:
            if self.tty:
                self._draw(self.summary())
                self.stream.write("\n")
            else:
                self.stream.write(self.summary() + "\n")
        elif self.tty and self._shown:
            self._draw("")
            self.stream.write("\r")
        self.stream.flush()

    def __enter__(self) -> "ProgressBar":
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        self.close(ok=exc_type is None)


#: Units of the stages of `hestore.bulk`'s ``progress(stage, done, total)``.
_IMPORT_UNITS = {"read": "bytes", "write": "rows"}
_EXPORT_UNITS = {"write": "rows"}


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


def _cmd_import(args: argparse.Namespace) -> int:
    path = args.file
    with _open(args) as store:
        try:
            with ProgressBar(units=_IMPORT_UNITS) as bar:
                report = store.import_file(path, args.name, on_error=args.on_error, progress=bar)
        except MeshExistsError:
            # As hestore.bulk.import_file: the file name without its extension.
            name = args.name if args.name is not None else os.path.splitext(os.path.basename(path))[0]
            return _error(
                f"a mesh named {name!r} already exists in {_shown(store.url)}; "
                "import under another name with --name NAME"
            )
        except HestoreError as exc:
            skipped = getattr(exc, "skipped", None)
            if skipped is None:
                raise
            where = path if skipped.line is None else f"{path}:{skipped.line}"
            return _error(
                f"{where}: polygon {skipped.index}: {skipped.reason}; nothing was stored "
                "(--on-error skip stores the mesh without such polygons)"
            )
    print(report.summary())
    if report.skipped:
        print(
            f"hestore: warning: {len(report.skipped)} polygon(s) skipped (--on-error skip); "
            f"mesh {report.mesh.name!r} was stored without them",
            file=sys.stderr,
        )
    return 0


def _cmd_export(args: argparse.Namespace) -> int:
    with _open(args) as store:
        mesh = store.mesh(args.name)
        counts = mesh.counts()
        with ProgressBar(units=_EXPORT_UNITS) as bar:
            mesh.export(args.file, binary=not args.ascii, progress=bar)
    size = os.path.getsize(args.file)
    print(
        f"wrote {args.name!r} to {args.file}: {counts.vertices} vertices, "
        f"{counts.polygons} polygons, {size} bytes"
    )
    return 0


def _info(mesh: hestore.Mesh) -> dict:
    """What ``info`` shows, as JSON-ready values; the text form is rendered from it.

    The mesh's name, revision and policy, then every field of `Mesh.stats`
    (`hestore.summary.Stats.as_dict`), in the order of `_INFO_LABELS`. Keys
    are the Python API's names, so a new field of ``Stats`` is one more key
    here without a change, and one more label in `_INFO_LABELS`.
    """
    info = {
        "name": mesh.name,
        "revision": mesh.revision,
        "allow_loops": mesh.allow_loops,
        "allow_multi_edges": mesh.allow_multi_edges,
    }
    for key, value in mesh.stats().as_dict().items():
        info.setdefault(key, _plain(value))
    sizes = info.get("polygon_sizes")
    if isinstance(sizes, dict):  # arity -> count, by arity
        info["polygon_sizes"] = {int(k): sizes[k] for k in sorted(sizes, key=int)}
    # The labelled keys in their order, then any the labels do not know yet.
    order = {key: i for i, key in enumerate(_INFO_LABELS)}
    return dict(sorted(info.items(), key=lambda kv: order.get(kv[0], len(order))))


def _plain(value: object) -> object:
    """``value`` with numpy scalars (and containers of them) as Python ones, for JSON."""
    if isinstance(value, dict):
        return {_plain(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return type(value)(_plain(v) for v in value)
    item = getattr(value, "item", None)
    if item is not None and not isinstance(value, (bool, int, float, str)):
        try:
            return item()
        except (TypeError, ValueError):
            return value
    return value


#: How ``info`` labels each key of `_info` in its text form (unlisted keys show as they are),
#: in the order it shows them.
_INFO_LABELS = {
    "name": "name",
    "revision": "revision",
    "allow_loops": "self-loops allowed",
    "allow_multi_edges": "parallel edges allowed",
    "vertices": "vertices",
    "isolated_vertices": "isolated vertices",
    "edges": "edges",
    "loops": "self-loops",
    "parallel_edges": "parallel edges",
    "halfedges": "half-edges",
    "polygons": "polygons",
    "polygon_sizes": "polygon sizes",
    "boundary_edges": "boundary edges",
    "wire_edges": "wire edges",
    "boundary_loops": "boundary loops",
    "components": "components",
    "euler_characteristic": "Euler characteristic",
    "genus": "genus",
    "pinched_vertices": "pinched vertices",
    "is_closed": "closed",
    "is_manifold": "manifold",
}


def _info_value(key: str, value: object, info: dict) -> str:
    if isinstance(value, bool):
        return "yes" if value else "no"
    if key == "genus" and value is None:
        # The genus is undefined where the surface is not one: say why.
        why = [what for what, field in (("wire edges", "wire_edges"), ("pinched vertices", "pinched_vertices"))
               if info.get(field)]
        return f"- ({' and '.join(why)})" if why else "-"
    if value is None:
        return "-"
    if isinstance(value, dict):
        return ", ".join(f"{k}: {v}" for k, v in value.items()) or "-"
    return str(value)


def _cmd_info(args: argparse.Namespace) -> int:
    with _open(args) as store:
        info = _info(store.mesh(args.name))
    if args.json:
        print(json.dumps(info, indent=2))
        return 0
    labels = {key: _INFO_LABELS.get(key, key) for key in info}
    width = max(len(label) for label in labels.values()) + 1
    for key, value in info.items():
        print(f"{labels[key] + ':':<{width}}  {_info_value(key, value, info)}")
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


# -- graph ------------------------------------------------------------------------

#: How many components ``graph NAME components`` lists, the largest first.
_TOP_COMPONENTS = 10

#: The graph file formats ``graph NAME export`` writes, by extension.
_GRAPH_FORMATS = {".graphml": "GraphML", ".edgelist": "edge list"}

#: The kinds of `hestore.Mesh.to_networkx`, the default first: `hestore.graphs.KINDS`,
#: repeated so that building the parser does not import networkx.
_GRAPH_KINDS = ("multigraph", "graph", "halfedge", "dual")


def _count(n: int, singular: str, plural: str | None = None) -> str:
    """``1 vertex``, ``2 vertices``."""
    return f"{n} {singular if n == 1 else (plural or singular + 's')}"


def _cmd_graph_components(args: argparse.Namespace) -> int:
    # mesh.components() rather than networkx on to_networkx(): it reads two
    # half-edge columns (origin, twin) and the vertex ids into numpy arrays and
    # labels the components there, where the multigraph would build a Python
    # node with its position per vertex and an edge with its half-edges and
    # polygons per edge, only for a traversal in Python that ignores them.
    with _open(args) as store:
        components = store.mesh(args.name).components()
    # (size, lowest vertex id), the largest first; equal sizes by lowest id.
    sizes = sorted(((len(c), min(v.id for v in c)) for c in components), key=lambda s: (-s[0], s[1]))
    vertices = sum(size for size, _ in sizes)
    head = f"{_count(len(sizes), 'component')} of {_count(vertices, 'vertex', 'vertices')}"
    print(head + (", the largest first:" if len(sizes) > 1 else ":" if sizes else ""))
    for size, lowest in sizes[:_TOP_COMPONENTS]:
        print(f"  {_count(size, 'vertex', 'vertices')} (lowest id {lowest})")
    rest = sizes[_TOP_COMPONENTS:]
    if rest:
        print(f"  ... and {len(rest)} more, of {_count(rest[0][0], 'vertex', 'vertices')} or fewer each")
    return 0


def _cmd_graph_path(args: argparse.Namespace) -> int:
    import networkx as nx

    with _open(args) as store:
        mesh = store.mesh(args.name)
        for i in (args.a, args.b):
            mesh.vertex(i)  # an unknown id: ElementNotFoundError, one line, exit 2
        graph = mesh.to_networkx("multigraph")
    try:
        path = nx.shortest_path(graph, args.a, args.b)
    except nx.NetworkXNoPath:
        print(
            f"no path from vertex {args.a} to vertex {args.b} in {args.name!r}: "
            "they are in different components"
        )
        return 1
    print("path: " + " ".join(str(v) for v in path))
    print(f"length: {_count(len(path) - 1, 'edge')}")
    return 0


def _cmd_graph_degree_histogram(args: argparse.Namespace) -> int:
    import networkx as nx

    with _open(args) as store:
        graph = store.mesh(args.name).to_networkx("multigraph")
    histogram = nx.degree_histogram(graph)  # index = degree; a self-loop adds 2
    if not histogram:
        print(f"mesh {args.name!r} has no vertices", file=sys.stderr)
    for degree, count in enumerate(histogram):
        if count:
            print(f"{degree}: {count}")
    return 0


def _graphml_value(value: object) -> object:
    """A GraphML-writable attribute value: scalars as they are, None dropped, the rest as JSON text."""
    value = _plain(value)
    if value is None:
        return _DROP
    if isinstance(value, (bool, int, float, str)):
        return value
    return json.dumps(value)


def _edgelist_value(value: object) -> object:
    """An edge-list attribute value: a Python literal (`ast.literal_eval` reads it back)."""
    return _plain(value)


#: Returned by a converter for an attribute that is left out.
_DROP = object()


def _writable_copy(graph, convert: Callable[[object], object], *, key: str | None = None):
    """A new, unfrozen graph of ``graph``'s type with every attribute value passed through ``convert``.

    The views of `hestore.Mesh.to_networkx` are frozen and cached, so they are
    never changed in place. With ``key``, a multigraph's edge keys are also
    written as that edge attribute (an edge list has no place for keys).
    """
    import networkx as nx

    def attrs(data: dict) -> dict:
        out = {}
        for name, value in data.items():
            value = convert(value)
            if value is not _DROP:
                out[str(name)] = value
        return out

    multi, directed = graph.is_multigraph(), graph.is_directed()
    classes = {
        (False, False): nx.Graph,
        (False, True): nx.DiGraph,
        (True, False): nx.MultiGraph,
        (True, True): nx.MultiDiGraph,
    }
    copy = classes[multi, directed]()
    copy.graph.update(attrs(graph.graph))
    copy.add_nodes_from((n, attrs(d)) for n, d in graph.nodes(data=True))
    if multi:
        copy.add_edges_from(
            (u, v, k, ({key: _plain(k)} if key else {}) | attrs(d))
            for u, v, k, d in graph.edges(keys=True, data=True)
        )
    else:
        copy.add_edges_from((u, v, attrs(d)) for u, v, d in graph.edges(data=True))
    return copy


def _cmd_graph_export(args: argparse.Namespace) -> int:
    suffix = Path(args.file).suffix.lower()
    if suffix not in _GRAPH_FORMATS:
        what = repr(suffix) if suffix else "(no extension)"
        return _error(
            f"{args.file}: unsupported graph file format {what}; "
            "write .graphml (GraphML) or .edgelist (an edge list)"
        )
    import networkx as nx

    with _open(args) as store:
        graph = store.mesh(args.name).to_networkx(args.kind)
    if suffix == ".graphml":
        copy = _writable_copy(graph, _graphml_value)
        nx.write_graphml(copy, args.file)
    else:
        copy = _writable_copy(graph, _edgelist_value, key="key")
        nx.write_edgelist(copy, args.file, data=True)
    size = os.path.getsize(args.file)
    print(
        f"wrote the {args.kind} view of {args.name!r} to {args.file} ({_GRAPH_FORMATS[suffix]}): "
        f"{_count(copy.number_of_nodes(), 'node')}, {_count(copy.number_of_edges(), 'edge')}, {size} bytes"
    )
    return 0


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

    imp = commands.add_parser(
        "import",
        help="import an OFF, OBJ or PLY file as a new mesh and print what was stored",
        description="Import an OFF, OBJ or PLY file (ASCII or binary; the format comes from the "
        "extension) as a new mesh, in one transaction, and print a report: counts, and the "
        "polygons left out, if any. Progress goes to stderr.",
    )
    imp.add_argument("file", metavar="FILE", help="the file to read (.off, .obj or .ply)")
    imp.add_argument(
        "--name", metavar="N", help="the new mesh's name (default: the file name without its extension)"
    )
    imp.add_argument(
        "--on-error",
        choices=("raise", "skip"),
        default="raise",
        help="what to do with a polygon the half-edge structure cannot take: raise (the default) "
        "stops with an error naming it and stores nothing; skip stores the mesh without it "
        "and lists it in the report",
    )
    imp.set_defaults(func=_cmd_import)

    exp = commands.add_parser(
        "export",
        help="write a mesh's vertices and polygons to an OFF, OBJ or PLY file",
        description="Write a mesh's vertices (in id order) and polygons to FILE, in the format "
        "its extension names (.off, .obj or .ply), replacing the file if it exists. Wire edges "
        "are not written. Progress goes to stderr.",
    )
    exp.add_argument("name", metavar="NAME", help="the mesh to export")
    exp.add_argument("file", metavar="FILE", help="the file to write (.off, .obj or .ply)")
    exp.add_argument(
        "--ascii", action="store_true", help="write ASCII PLY instead of binary (OFF and OBJ are always text)"
    )
    exp.set_defaults(func=_cmd_export)

    listing = commands.add_parser("list", help="list the meshes: counts and revision of each")
    listing.set_defaults(func=_cmd_list)

    info = commands.add_parser(
        "info",
        help="a mesh's revision, policy, counts and topology: boundaries, components, genus, ...",
        description="Print a mesh's name, revision and policy, and every field of its "
        "hestore.Mesh.stats(): counts (with self-loops, parallel edges and polygon sizes), "
        "boundary and wire edges, boundary loops, components, Euler characteristic, genus, "
        "pinched vertices, whether it is closed and manifold.",
    )
    info.add_argument("name", metavar="NAME", help="the mesh to describe")
    info.add_argument("--json", action="store_true", help="print a JSON object instead of text")
    info.set_defaults(func=_cmd_info)

    check = commands.add_parser(
        "check", help="check a mesh's invariants; exit status 1 and the violations when invalid"
    )
    check.add_argument("name", metavar="NAME", help="the mesh to check")
    check.set_defaults(func=_cmd_check)

    graph = commands.add_parser(
        "graph",
        help="graph analytics on a mesh's connectivity: components, path, degree-histogram, export",
        description="Graph analytics on a mesh's committed connectivity, through networkx "
        "(hestore.Mesh.to_networkx). components, path and degree-histogram use the multigraph: "
        "one node per vertex, isolated ones included, one edge per edge, self-loops and parallel "
        "edges kept.",
    )
    graph.add_argument("name", metavar="NAME", help="the mesh")
    graph_commands = graph.add_subparsers(dest="graph_command", metavar="GRAPH_COMMAND", required=True)
    components = graph_commands.add_parser(
        "components",
        help=f"the number of connected components and the sizes of the {_TOP_COMPONENTS} largest",
        description="Print the number of connected components of the vertex-edge graph (an "
        f"isolated vertex is one of its own), then the {_TOP_COMPONENTS} largest, one a line: "
        "its number of vertices and its lowest vertex id.",
    )
    components.set_defaults(func=_cmd_graph_components)
    path = graph_commands.add_parser(
        "path",
        help="a shortest path (fewest edges) between vertices A and B",
        description="Print a shortest path, in edges, from vertex A to vertex B: the vertex ids "
        "along it and its length. Exit status 1 when there is none.",
    )
    path.add_argument("a", metavar="A", type=int, help="the id of the first vertex")
    path.add_argument("b", metavar="B", type=int, help="the id of the last vertex")
    path.set_defaults(func=_cmd_graph_path)
    histogram = graph_commands.add_parser(
        "degree-histogram",
        help="how many vertices have each degree (a self-loop counts twice)",
        description="Print 'degree: count' lines for every degree some vertex has, lowest first: "
        "networkx.degree_histogram of the multigraph (a self-loop counts twice, each parallel "
        "edge once).",
    )
    histogram.set_defaults(func=_cmd_graph_degree_histogram)
    gexp = graph_commands.add_parser(
        "export",
        help="write a graph view to a GraphML (.graphml) or edge list (.edgelist) file",
        description="Write one of the graph views of hestore.Mesh.to_networkx to FILE, replacing "
        "it: GraphML for .graphml (nodes, edges with their keys, every attribute; None values "
        "left out, tuples and lists written as JSON text), an edge list for .edgelist (a line "
        "'u v {attributes}' per edge, the key as attribute 'key'; no isolated nodes, no node "
        "attributes).",
    )
    gexp.add_argument("file", metavar="FILE", help="the file to write (.graphml or .edgelist)")
    gexp.add_argument(
        "--kind",
        choices=_GRAPH_KINDS,
        default="multigraph",
        help="the view: multigraph (the default: vertices, one edge per edge), graph (parallel "
        "edges merged), halfedge (directed, one edge per half-edge) or dual (polygons, joined "
        "across their shared edges)",
    )
    gexp.set_defaults(func=_cmd_graph_export)

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
        The exit status: 0 success, 1 ``check`` found violations or ``graph … path``
        found no path, 2 error
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
    except OSError as exc:
        # A file that import cannot read or export cannot write.
        if exc.filename is not None and exc.strerror:
            return _error(f"{os.fsdecode(exc.filename)}: {exc.strerror}")
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
    except Exception as exc:
        # networkx is imported by the graph commands only: look for it, never import it here.
        nx = sys.modules.get("networkx")
        if nx is not None and isinstance(exc, nx.NetworkXException):
            return _error(f"networkx: {exc}")
        raise


if __name__ == "__main__":  # pragma: no cover - `python -m hestore` uses __main__.py
    sys.exit(main())
