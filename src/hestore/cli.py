"""The ``hestore`` command line.

``hestore [--db URL] COMMAND`` — the database is ``--db``, else
``$HESTORE_URL``, else ``./hestore.db`` (a bare path means a SQLite file).
Each command is a subparser with a ``_cmd_*`` function; `main` parses,
dispatches, and turns every error a user can cause (hestore's own, an
unreachable or malformed database URL, an unknown schema revision, a file
that cannot be read or written) into one line on stderr and exit status 2.

Commands: ``demo``, ``import FILE [--orient] [--replace]``, ``export NAME FILE [--revision R]``,
``render NAME FILE.png|.svg [--revision R] [--view V] [--labels [WHAT]] [--check|--no-check] [--size WxH]``
(`hestore.Mesh.render`), ``list``,
``delete NAME``, ``rename NAME NEW``, ``copy NAME NEW [--revision R]``, ``log NAME [--limit N]``,
``diff NAME A B``, ``undo NAME``, ``redo NAME``, ``revert NAME R``,
``info NAME`` (`hestore.Mesh.stats` and `hestore.Mesh.properties`), ``check NAME``, ``graph NAME
components|path A B [--weight W]|neighbors V [--k K]|degree-histogram|export FILE``, ``db upgrade``,
``db current``.

``graph NAME path A B`` (fewest edges, or ``--weight length``) and ``graph NAME neighbors V --k K``
(the ids of the vertices within K edges of V, V included, ascending, on one line) are local
queries (`hestore.Mesh.shortest_path`, `hestore.Mesh.k_ring`): they read the store around their
vertices and never build the whole graph. ``path --weight`` by an edge property, ``degree-histogram``
and ``export`` go through networkx (`hestore.Mesh.to_networkx`).

Exit status: 0 success, 1 ``check`` found violations or ``graph … path``
found no path, 2 error, 130 interrupted.

``import``, ``export``, ``render``, and ``check``, ``info`` and the whole-graph ``graph`` commands when
they take over a second (large meshes), report progress through `ProgressBar`, on stderr:
a redrawn bar on a terminal, and only a plain final line elsewhere, so that
logs carry no control characters. Results go to stdout.

The command line is thin: URLs are `hestore.urls`'s, schema states
`hestore.migrate`'s, graph files `hestore.graphio`'s and the progress bar
`hestore.progress`'s. The ``db`` commands work below the store (`hestore.open`
refuses a database whose schema is behind; that refusal is what tells users
to run ``hestore db upgrade``): they call `hestore.migrate.database_state`
and `hestore.migrate.upgrade_database`.

Ctrl-C stops any command with one line and exit status 130; its writes,
one transaction, are rolled back. An unexpected error is one line too
(``HESTORE_DEBUG=1`` shows its traceback).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from collections.abc import Sequence

import hestore
from hestore import migrate, urls
from hestore.bulk import name_of
from hestore.errors import HestoreError, InvalidInputError, MeshExistsError, PolicyError
from hestore.history import KINDS as ELEMENT_KINDS
from hestore.progress import ProgressBar
from hestore.render import CHECK_POLYGONS, LABEL_VERTICES, MAX_POLYGONS, VIEWS
from hestore.values import KINDS as PROPERTY_KINDS

__all__ = ["DEFAULT_URL", "main", "build_parser"]

#: The database used when neither ``--db`` nor ``$HESTORE_URL`` is given.
DEFAULT_URL = urls.DEFAULT_URL

#: Set it (to anything) to see the traceback of an unexpected error instead of one line.
DEBUG_ENVIRONMENT = "HESTORE_DEBUG"


def _open(args: argparse.Namespace) -> hestore.Store:
    return hestore.open(args.db)


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
            print(f"no meshes in {urls.shown(store.url)}", file=sys.stderr)
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
        name = args.name if args.name is not None else name_of(path)
        replacing = args.replace and name in store.meshes()
        try:
            with ProgressBar(units=_IMPORT_UNITS) as bar:
                report = store.import_file(
                    path, args.name, on_error=args.on_error, progress=bar, replace=args.replace, orient=args.orient
                )
        except MeshExistsError:
            return _error(
                f"a mesh named {name!r} already exists in {urls.shown(store.url)}; "
                "import under another name with --name NAME, or replace it with --replace"
            )
        except HestoreError as exc:
            skipped = getattr(exc, "skipped", None)
            if skipped is None:
                raise
            where = path if skipped.line is None else f"{path}:{skipped.line}"
            hint = "--on-error skip stores the mesh without such polygons"
            if not isinstance(exc, (InvalidInputError, PolicyError)):
                hint += ", --on-error split keeps them on copies of their vertices"
            return _error(f"{where}: polygon {skipped.index}: {skipped.reason}; nothing was stored ({hint})")
    print(report.summary())
    if replacing:
        print(f"replaced the mesh {name!r} that was there (in the same transaction)")
    if report.skipped:
        print(
            f"hestore: warning: {len(report.skipped)} polygon(s) skipped (--on-error {args.on_error}); "
            f"mesh {report.mesh.name!r} was stored without them",
            file=sys.stderr,
        )
    return 0


def _cmd_delete(args: argparse.Namespace) -> int:
    with _open(args) as store:
        mesh = store.mesh(args.name)
        counts = mesh.counts()
        store.delete_mesh(args.name)
    print(f"deleted mesh {args.name!r}: {counts.vertices} vertices, {counts.edges} edges, {counts.polygons} polygons")
    return 0


def _cmd_rename(args: argparse.Namespace) -> int:
    with _open(args) as store:
        store.rename_mesh(args.name, args.new_name)
    print(f"renamed mesh {args.name!r} to {args.new_name!r}")
    return 0


def _cmd_copy(args: argparse.Namespace) -> int:
    with _open(args) as store:
        copy = store.copy_mesh(args.name, args.new_name, revision=args.revision)
        counts = copy.counts()
    print(
        f"copied mesh {args.name!r} to {args.new_name!r}: {counts.vertices} vertices, {counts.edges} edges, "
        f"{counts.polygons} polygons"
    )
    return 0


def _cmd_export(args: argparse.Namespace) -> int:
    with _open(args) as store:
        mesh = store.mesh(args.name)
        if args.revision is not None:
            mesh = mesh.at(args.revision)
        counts = mesh.counts()
        with ProgressBar(units=_EXPORT_UNITS) as bar:
            mesh.export(args.file, binary=not args.ascii, progress=bar)
    size = os.path.getsize(args.file)
    at = "" if args.revision is None else f" at revision {args.revision}"
    print(
        f"wrote {args.name!r}{at} to {args.file}: {counts.vertices} vertices, "
        f"{counts.polygons} polygons, {size} bytes"
    )
    return 0


def _view(text: str | None) -> object:
    """``--view``: a named view, or ``AZIMUTH,ELEVATION`` in degrees (anything else: the library refuses it)."""
    if text is None or text in VIEWS:
        return text
    parts = text.split(",")
    try:
        return tuple(float(p) for p in parts) if len(parts) == 2 else text
    except ValueError:
        return text


def _cmd_render(args: argparse.Namespace) -> int:
    view = _view(args.view)
    with _open(args) as store:
        mesh = store.mesh(args.name)
        if args.revision is not None:
            mesh = mesh.at(args.revision)
        with ProgressBar() as bar:
            mesh.render(args.file, view=view, labels=args.labels, check=args.check, size=args.size, progress=bar)
        counts = mesh.counts()
    size = os.path.getsize(args.file)
    at = "" if args.revision is None else f" at revision {args.revision}"
    print(f"drew {args.name!r}{at} ({counts.polygons} polygons) to {args.file}: {size} bytes")
    return 0


def _pixels(text: str) -> tuple[int, int]:
    """``--size WIDTHxHEIGHT``."""
    try:
        width, height = (int(p) for p in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT in pixels, such as 1200x900, not {text!r}") from None
    if width < 1 or height < 1:
        raise argparse.ArgumentTypeError(f"width and height must be at least 1, not {text!r}")
    return width, height


def _changes(changes: dict) -> str:
    """``+3 −1 ~2 vertex, …``: how many of each kind were created (+), removed (−) and changed (~)."""
    parts = []
    for kind in ELEMENT_KINDS:
        c = changes[kind]
        marks = [f"{sign}{c[key]}" for sign, key in (("+", "created"), ("−", "removed"), ("~", "changed")) if c[key]]
        if marks:
            parts.append(f"{' '.join(marks)} {kind}")
    return ", ".join(parts) or "no change"


def _cmd_log(args: argparse.Namespace) -> int:
    with _open(args) as store:
        mesh = store.mesh(args.name)
        revisions = mesh.history(limit=args.limit)
        current = mesh.revision
        kept = bool(revisions) or bool(mesh.history(limit=1)) or current == 0
    if not kept:
        print(f"mesh {args.name!r} is at revision {current} and keeps no history")
        return 0
    for r in revisions:
        when = r.committed_at.strftime("%Y-%m-%d %H:%M:%S UTC")
        message = f"  {r.message}" if r.message else ""
        print(f"{r.number:>6}  {when}  {_changes(r.changes)}{message}")
    return 0


def _cmd_diff(args: argparse.Namespace) -> int:
    with _open(args) as store:
        d = store.mesh(args.name).diff(args.a, args.b)
    print(f"{args.name}: revision {args.a} → {args.b}: {_changes(d.counts())}")
    for what, ids in (("created", d.created), ("removed", d.removed), ("changed", d.changed)):
        for kind in ELEMENT_KINDS:
            if ids[kind]:
                shown = ", ".join(map(str, ids[kind][:20])) + (", ..." if len(ids[kind]) > 20 else "")
                print(f"  {what} {kind} {shown}")
    return 0


def _cmd_undo(args: argparse.Namespace) -> int:
    return _went_back(args, lambda mesh: mesh.undo())


def _cmd_redo(args: argparse.Namespace) -> int:
    return _went_back(args, lambda mesh: mesh.redo())


def _cmd_revert(args: argparse.Namespace) -> int:
    return _went_back(args, lambda mesh: mesh.revert(args.revision))


def _went_back(args: argparse.Namespace, step) -> int:
    with _open(args) as store:
        mesh = store.mesh(args.name)
        number = step(mesh)
        latest = mesh.history(limit=1)[0]
    print(f"{args.name}: {latest.message}: now revision {number} ({_changes(latest.changes)})")
    return 0


def _info(mesh: hestore.Mesh, progress=None) -> dict:
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
    for key, value in mesh.stats(progress).as_dict().items():
        info.setdefault(key, value)
    # The labelled keys in their order, then any the labels do not know yet.
    order = {key: i for i, key in enumerate(_INFO_LABELS)}
    return dict(sorted(info.items(), key=lambda kv: order.get(kv[0], len(order))))


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


def _properties(mesh: hestore.Mesh) -> list[dict]:
    """The mesh's properties (`hestore.Mesh.properties`), kind by kind, each in the order declared.

    Each as ``kind``, ``name``, ``dtype``, ``shape`` (a list: ``[]`` or
    ``[k]``) and ``default`` (None: no default; a list for shaped ones).
    """
    return [
        {"kind": p.kind, "name": p.name, "dtype": p.dtype, "shape": list(p.shape), "default": p.default}
        for kind in PROPERTY_KINDS
        for p in mesh.properties(kind).values()
    ]


def _property_lines(properties: list[dict]) -> list[str]:
    """One aligned line per property: kind, name, dtype, shape, default."""
    rows = [
        (
            p["kind"],
            p["name"],
            p["dtype"],
            str(tuple(p["shape"])),
            "no default" if p["default"] is None else f"default {p['default']!r}",
        )
        for p in properties
    ]
    widths = [max(len(row[c]) for row in rows) for c in range(4)]
    return ["  " + "  ".join([*(f"{cell:<{w}}" for cell, w in zip(row, widths)), row[4]]) for row in rows]


def _cmd_info(args: argparse.Namespace) -> int:
    with _open(args) as store:
        mesh = store.mesh(args.name)
        with ProgressBar(min_seconds=_QUIET_SECONDS) as bar:
            info = _info(mesh, bar)
        properties = _properties(mesh)
    if args.json:
        # Only a mesh with properties has the key, so the figures of one without stay as they were.
        if properties:
            info["properties"] = [{**p, "default": _json_default(p["default"])} for p in properties]
        print(json.dumps(info, indent=2))
        return 0
    labels = {key: _INFO_LABELS.get(key, key) for key in info}
    width = max(len(label) for label in labels.values()) + 1
    for key, value in info.items():
        print(f"{labels[key] + ':':<{width}}  {_info_value(key, value, info)}")
    if properties:
        print(f"{'properties:':<{width}}  {len(properties)}")
        for line in _property_lines(properties):
            print(line)
    return 0


def _json_default(value: object) -> object:
    """A property's default as JSON holds it: tuples as lists, NaN as null."""
    if isinstance(value, tuple):
        return [_json_default(v) for v in value]
    if isinstance(value, float) and value != value:
        return None
    return value


#: ``check`` and ``info`` show progress only when they take longer than this (on large meshes), in seconds.
_QUIET_SECONDS = 1.0


def _cmd_check(args: argparse.Namespace) -> int:
    with _open(args) as store:
        mesh = store.mesh(args.name)
        with ProgressBar(min_seconds=_QUIET_SECONDS) as bar:
            violations = mesh.check(bar)
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
        with ProgressBar(min_seconds=_QUIET_SECONDS) as bar:
            components = store.mesh(args.name).components(bar)
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


#: The derived weight of ``graph … path --weight``: `hestore.graphs.LENGTH`, repeated so
#: that building the parser does not import networkx.
_LENGTH = "length"


def _weight_problem(mesh: hestore.Mesh, weight: str) -> str | None:
    """Why ``--weight`` cannot be ``weight`` for this mesh, or None when it can.

    It can be ``length`` or a scalar ``int64`` / ``float64`` edge property
    (an edge property named ``length`` is that property, as in
    `hestore.Mesh.to_networkx`).
    """
    edge = mesh.properties("edge")
    numeric = [name for name, p in edge.items() if p.dtype in ("int64", "float64") and not p.shape]
    takes = ", ".join([_LENGTH] + [n for n in numeric if n != _LENGTH])
    prop = edge.get(weight)
    if prop is None:
        if weight == _LENGTH:
            return None
        return f"mesh {mesh.name!r} has no edge property named {weight!r}; --weight takes: {takes}"
    if prop.dtype not in ("int64", "float64") or prop.shape:
        shaped = f" of shape {prop.shape}" if prop.shape else ""
        return (
            f"edge property {weight!r} of mesh {mesh.name!r} is {prop.dtype}{shaped}, not a number; "
            f"--weight takes: {takes}"
        )
    return None


class _Unweighed(Exception):
    """An edge the weighted path search needs has no usable weight."""


def _weigher(graph, weight: str):
    """networkx's weight function for a multigraph: the lightest of the parallel edges ``u``-``v``.

    An edge without a weight (``length`` None: an end without a position; a
    property without a default, unset), with NaN or with a negative weight
    raises `_Unweighed` with the reason — only when the search needs it.
    """

    def weigh(u, v, keydict: dict):
        best = None
        for key, data in keydict.items():
            w = data.get(weight)
            if w is None:
                if weight in data:  # the derived length, None: an end without a position
                    unplaced = u if graph.nodes[u]["pos"] is None else v
                    raise _Unweighed(f"edge {key} has no length: vertex {unplaced} has no position")
                raise _Unweighed(f"edge {key} has no value of property {weight!r}, which has no default")
            if w != w:
                raise _Unweighed(f"edge {key} has {weight} NaN")
            if w < 0:
                raise _Unweighed(
                    f"edge {key} has a negative {weight} ({w}); a shortest path needs weights of 0 or more"
                )
            best = w if best is None else min(best, w)
        return best

    return weigh


def _number(x: float | int) -> str:
    return str(x) if isinstance(x, int) else f"{x:.12g}"


def _cmd_graph_path(args: argparse.Namespace) -> int:
    weight = args.weight
    with _open(args) as store:
        mesh = store.mesh(args.name)
        a, b = mesh.vertex(args.a), mesh.vertex(args.b)  # an unknown id: ElementNotFoundError, one line, exit 2
        if weight is not None:
            problem = _weight_problem(mesh, weight)
            if problem:
                return _error(problem)
        if weight is None or (weight == _LENGTH and _LENGTH not in mesh.properties("edge")):
            # Fewest edges or least length: a local search in the store (hestore.Mesh.shortest_path),
            # which reads the stars it expands and never builds the whole graph.
            try:
                path = mesh.shortest_path(a, b, weight)
            except hestore.NoPathError:
                return _no_path(args)
            total = None if weight is None else sum(_distance(u.position, v.position) for u, v in zip(path, path[1:]))
            return _print_path([v.id for v in path], weight, total)
        with ProgressBar(min_seconds=_QUIET_SECONDS) as bar:
            graph = mesh.to_networkx("multigraph", attrs=[weight], progress=bar)
    # An edge property as the weight: networkx on the multigraph with that attribute.
    import networkx as nx

    weigh = _weigher(graph, weight)
    try:
        ids = nx.shortest_path(graph, args.a, args.b, weight=weigh)
    except _Unweighed as exc:
        return _error(f"cannot weigh the paths of {args.name!r} by {weight}: {exc}")
    except nx.NetworkXNoPath:
        return _no_path(args)
    return _print_path(ids, weight, sum(weigh(u, v, graph[u][v]) for u, v in zip(ids, ids[1:])))


def _distance(p: tuple, q: tuple) -> float:
    return sum((x - y) ** 2 for x, y in zip(p, q)) ** 0.5


def _no_path(args: argparse.Namespace) -> int:
    print(f"no path from vertex {args.a} to vertex {args.b} in {args.name!r}: they are in different components")
    return 1


def _print_path(ids: list[int], weight: str | None, total: float | None) -> int:
    print("path: " + " ".join(map(str, ids)))
    print(f"length: {_count(len(ids) - 1, 'edge')}")
    if weight is not None:
        print(f"total {weight}: {_number(total)}")
    return 0


def _cmd_graph_neighbors(args: argparse.Namespace) -> int:
    with _open(args) as store:
        mesh = store.mesh(args.name)
        ring = mesh.k_ring(mesh.vertex(args.v), args.k)
    print(" ".join(str(i) for i in sorted(v.id for v in ring)))
    return 0


def _cmd_graph_degree_histogram(args: argparse.Namespace) -> int:
    import networkx as nx

    with _open(args) as store:
        with ProgressBar(min_seconds=_QUIET_SECONDS) as bar:
            graph = store.mesh(args.name).to_networkx("multigraph", progress=bar)
    histogram = nx.degree_histogram(graph)  # index = degree; a self-loop adds 2
    if not histogram:
        print(f"mesh {args.name!r} has no vertices", file=sys.stderr)
    for degree, count in enumerate(histogram):
        if count:
            print(f"{degree}: {count}")
    return 0


def _cmd_graph_export(args: argparse.Namespace) -> int:
    from hestore import graphio

    graphio.format_of(args.file)  # before any work: an unknown extension is one line, exit 2
    with _open(args) as store, ProgressBar(min_seconds=_QUIET_SECONDS) as bar:
        graph = store.mesh(args.name).to_networkx(args.kind, progress=bar)
        bar("write", 0, 1)
        nodes, edges = graphio.write_graph(graph, args.file)
        bar("write", 1, 1)
    size = os.path.getsize(args.file)
    kind = graphio.FORMATS[graphio.format_of(args.file)]
    print(
        f"wrote the {args.kind} view of {args.name!r} to {args.file} ({kind}): "
        f"{_count(nodes, 'node')}, {_count(edges, 'edge')}, {size} bytes"
    )
    return 0


def _cmd_db_upgrade(args: argparse.Namespace) -> int:
    before, after = migrate.upgrade_database(args.db)
    shown = urls.shown(urls.resolve(args.db))
    if before.status == "head":
        print(f"{shown}: already at head ({after.head})")
    else:
        origin = "an empty database" if before.current is None else before.current
        print(f"{shown}: upgraded from {origin} to {after.current} (head)")
    return 0


def _cmd_db_current(args: argparse.Namespace) -> int:
    print(migrate.database_state(args.db).describe())
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
        choices=("raise", "skip", "split"),
        default="raise",
        help="what to do with a polygon the half-edge structure cannot take: raise (the default) "
        "stops with an error naming it and stores nothing; skip stores the mesh without it "
        "and lists it in the report; split keeps it on its own copies of the vertices where it does not fit "
        "and lists the copies (a polygon malformed in itself is still skipped)",
    )
    imp.add_argument(
        "--orient",
        action="store_true",
        help="reverse polygons so that each component is consistently oriented (reported); a component that "
        "cannot be oriented (a Moebius strip) is an error and nothing is stored, or, with --on-error split, "
        "is cut along edges until it can be (reported)",
    )
    imp.add_argument(
        "--replace",
        action="store_true",
        help="replace a mesh of the same name, in the same transaction: the old mesh goes only if the "
        "new one is stored",
    )
    imp.set_defaults(func=_cmd_import)

    delete = commands.add_parser("delete", help="delete a mesh and all its elements")
    delete.add_argument("name", metavar="NAME", help="the mesh to delete")
    delete.set_defaults(func=_cmd_delete)

    rename = commands.add_parser("rename", help="give a mesh a new name")
    rename.add_argument("name", metavar="NAME", help="the mesh to rename")
    rename.add_argument("new_name", metavar="NEW", help="its new name (no mesh may have it)")
    rename.set_defaults(func=_cmd_rename)

    copy = commands.add_parser(
        "copy",
        help="copy a mesh: the same ids and content under a new name, independent afterwards",
    )
    copy.add_argument("name", metavar="NAME", help="the mesh to copy")
    copy.add_argument("new_name", metavar="NEW", help="the copy's name (no mesh may have it)")
    copy.add_argument(
        "--revision", metavar="R", type=int, default=None,
        help="the revision to copy (default: the current one): branches the mesh there",
    )
    copy.set_defaults(func=_cmd_copy)

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
    exp.add_argument(
        "--revision", metavar="R", type=int, default=None, help="write the mesh as it was at revision R"
    )
    exp.set_defaults(func=_cmd_export)

    rnd = commands.add_parser(
        "render",
        help="draw a mesh to a PNG or SVG picture: shaded polygons, boundary loops, problems highlighted",
        description="Draw a mesh to FILE, a PNG or SVG picture by its extension, replacing the file if it "
        "exists (written whole or not at all): polygons flat-shaded, edges thin, boundary loops as coloured "
        "lines, wire edges, isolated and pinched vertices marked, and what 'check' finds in red, with a "
        f"legend. Above {MAX_POLYGONS:,} polygons they are drawn as a raster image (without edges). "
        "Progress goes to stderr.",
    )
    rnd.add_argument("name", metavar="NAME", help="the mesh to draw")
    rnd.add_argument("file", metavar="FILE", help="the picture to write (.png or .svg)")
    rnd.add_argument(
        "--revision", metavar="R", type=int, default=None, help="draw the mesh as it was at revision R"
    )
    rnd.add_argument(
        "--view",
        metavar="V",
        default=None,
        help=f"where to look from: {', '.join(VIEWS)}, or AZIMUTH,ELEVATION in degrees (default: straight "
        "on for a planar mesh, else iso)",
    )
    rnd.add_argument(
        "--labels",
        nargs="?",
        const="vertices",
        default=False,
        choices=("vertices", "halfedges", "all"),
        help=f"write ids: of vertices (the default with --labels), of half-edges (an arrow each, on its "
        f"polygon's side), or all (up to {LABEL_VERTICES:,} of each)",
    )
    rnd.add_argument(
        "--check",
        action=argparse.BooleanOptionalAction,
        default=None,
        help=f"run the invariant check and draw what it finds in red (default: for meshes of up to "
        f"{CHECK_POLYGONS:,} polygons)",
    )
    rnd.add_argument(
        "--size", metavar="WxH", type=_pixels, default=(1200, 900), help="picture size in pixels (default 1200x900)"
    )
    rnd.set_defaults(func=_cmd_render)

    log = commands.add_parser(
        "log", help="the mesh's revisions, newest first: when, what changed (+created −removed ~changed), message"
    )
    log.add_argument("name", metavar="NAME", help="the mesh")
    log.add_argument("--limit", metavar="N", type=int, default=None, help="show at most N revisions")
    log.set_defaults(func=_cmd_log)
    diff = commands.add_parser("diff", help="what differs between two revisions of a mesh")
    diff.add_argument("name", metavar="NAME", help="the mesh")
    diff.add_argument("a", metavar="A", type=int, help="the earlier revision")
    diff.add_argument("b", metavar="B", type=int, help="the later revision")
    diff.set_defaults(func=_cmd_diff)
    for name, func, text in (
        ("undo", _cmd_undo, "undo the mesh's most recent change not yet undone (a new revision)"),
        ("redo", _cmd_redo, "re-apply the most recently undone change (a new revision)"),
    ):
        step = commands.add_parser(name, help=text)
        step.add_argument("name", metavar="NAME", help="the mesh")
        step.set_defaults(func=func)
    revert = commands.add_parser("revert", help="make the mesh equal to an earlier revision (a new revision)")
    revert.add_argument("name", metavar="NAME", help="the mesh")
    revert.add_argument("revision", metavar="R", type=int, help="the revision to go back to")
    revert.set_defaults(func=_cmd_revert)

    listing = commands.add_parser("list", help="list the meshes: counts and revision of each")
    listing.set_defaults(func=_cmd_list)

    info = commands.add_parser(
        "info",
        help="a mesh's revision, policy, counts and topology: boundaries, components, genus, ...",
        description="Print a mesh's name, revision and policy, and every field of its "
        "hestore.Mesh.stats(): counts (with self-loops, parallel edges and polygon sizes), "
        "boundary and wire edges, boundary loops, components, Euler characteristic, genus, "
        "pinched vertices, whether it is closed and manifold; then its properties, if it has "
        "any: kind, name, dtype, shape and default of each.",
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
        help="graph analytics on a mesh's connectivity: components, path, neighbors, degree-histogram, export",
        description="Graph analytics on a mesh's committed connectivity, on its multigraph: "
        "one node per vertex, isolated ones included, one edge per edge, self-loops and parallel "
        "edges kept. path (by edges or length) and neighbors are local queries that read the "
        "store around their vertices (hestore.Mesh.shortest_path, hestore.Mesh.k_ring); "
        "degree-histogram, export and path by an edge property build the networkx graph "
        "(hestore.Mesh.to_networkx).",
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
        help="a shortest path (fewest edges, or least total --weight) between vertices A and B",
        description="Print a shortest path from vertex A to vertex B: the vertex ids along it "
        "and its length in edges; with --weight, the path of least total weight and that total. "
        "Exit status 1 when there is none.",
    )
    path.add_argument("a", metavar="A", type=int, help="the id of the first vertex")
    path.add_argument("b", metavar="B", type=int, help="the id of the last vertex")
    path.add_argument(
        "--weight",
        metavar="W",
        help="weigh each edge by W: 'length' (the Euclidean length, from the positions of its "
        "ends) or the name of a numeric (int64 or float64, unshaped) edge property; an edge the "
        "search meets without a weight (an end without a position, a property unset without a "
        "default) or with a negative one is an error (default: every edge weighs 1)",
    )
    path.set_defaults(func=_cmd_graph_path)
    neighbors = graph_commands.add_parser(
        "neighbors",
        help="the vertices within K edges of vertex V (its k-ring), V included",
        description="Print the ids of the vertices within K edges of vertex V (hestore.Mesh.k_ring: "
        "V itself, the vertices joined to it by an edge, theirs, and so on, K levels deep), "
        "ascending, on one line separated by spaces. Read from the store around V, without "
        "building the whole graph.",
    )
    neighbors.add_argument("v", metavar="V", type=int, help="the id of the vertex at the centre")
    neighbors.add_argument(
        "--k", metavar="K", type=int, default=1,
        help="how many edges away at most, an integer >= 0 (default: 1, the vertex and its neighbours)",
    )  # fmt: skip
    neighbors.set_defaults(func=_cmd_graph_neighbors)
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
    try:
        status = args.func(args)
        sys.stdout.flush()
        return status
    except KeyboardInterrupt:
        # Every command's writes are one transaction, rolled back on the way out.
        print("hestore: interrupted; the unfinished command changed nothing", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # The reader went away (`hestore list | head`): stop quietly with the
        # status of a process killed by SIGPIPE, as other command-line tools do,
        # and keep Python from complaining when it flushes stdout at exit.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 128 + 13
    except HestoreError as exc:
        return _error(str(exc))
    except OSError as exc:
        # Not a file the library reads or writes (those are InvalidInputError): the standard streams themselves.
        if exc.filename is not None and exc.strerror:
            return _error(f"{os.fsdecode(exc.filename)}: {exc.strerror}")
        return _error(str(exc))
    except Exception as exc:
        if os.environ.get(DEBUG_ENVIRONMENT):
            raise
        # networkx is imported by the graph commands only: look for it, never import it here.
        nx = sys.modules.get("networkx")
        if nx is not None and isinstance(exc, nx.NetworkXException):
            return _error(f"networkx: {exc}")
        return _error(
            f"unexpected {type(exc).__name__}: {exc} (a bug in hestore; set {DEBUG_ENVIRONMENT}=1 for the traceback)"
        )


if __name__ == "__main__":  # pragma: no cover - `python -m hestore` uses __main__.py
    sys.exit(main())
