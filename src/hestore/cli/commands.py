"""The handlers of the ``hestore`` commands: each takes its parsed arguments, calls the library, prints.

This module owns what each command does, as one function per command
(``cmd_import``, ``cmd_graph_path``, …) that `hestore.cli.parser`'s table
names and `hestore.cli.main` calls with the parsed arguments. A handler
opens the store, makes the library call the command stands for
(`hestore.Store.import_file`, `hestore.Mesh.shortest_path`, …), and prints
what it returned through `hestore.cli.text`; it returns the exit status.
The work is the library's — no SQL and no graph algorithm here — and so are
the refusals: a handler catches a library error only to add the option that
would avoid it (``--name``, ``--on-error``, ``--weight``).

Progress goes to stderr through `hestore.progress.ProgressBar`, results to
stdout.
"""

from __future__ import annotations

import argparse
import json
import os
import sys

import hestore
from hestore import migrate, urls
from hestore.bulk import name_of
from hestore.cli import text
from hestore.errors import HestoreError, InvalidInputError, MeshExistsError, NoPathError, PolicyError
from hestore.errors import PropertyNotFoundError, StoreNotFoundError
from hestore.progress import ProgressBar

__all__ = ["IMPORT_UNITS", "EXPORT_UNITS", "QUIET_SECONDS"]  # and a cmd_* function per command

#: Units of the stages of `hestore.bulk`'s ``progress(stage, done, total)``.
IMPORT_UNITS = {"read": "bytes", "write": "rows"}
EXPORT_UNITS = {"write": "rows"}

#: ``check``, ``info`` and the whole-graph commands show progress only when they take longer than this, in
#: seconds (on large meshes).
QUIET_SECONDS = 1.0


def _open(args: argparse.Namespace, create: bool = False) -> hestore.Store:
    """The store of ``--db``; a database that does not exist is made only by a command that can start from
    nothing (``create``: ``import``, ``demo``), so that a mistyped name is never a new, empty database."""
    try:
        return hestore.open(args.db, busy_timeout=args.busy_timeout, create=create)
    except StoreNotFoundError as exc:
        raise StoreNotFoundError(
            f"{exc}; only `hestore import FILE`, `hestore demo` and `hestore db upgrade` create a database"
        ) from None


def _print(lines: list[str]) -> None:
    for line in lines:
        print(line)


# -- meshes -------------------------------------------------------------------------


def cmd_demo(args: argparse.Namespace) -> int:
    from hestore.cli import demo

    with _open(args, create=True) as store:
        demo.run(store)
    return 0


def cmd_list(args: argparse.Namespace) -> int:
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


def cmd_import(args: argparse.Namespace) -> int:
    path = args.file
    with _open(args, create=True) as store:
        name = args.name if args.name is not None else name_of(path)
        replacing = args.replace and name in store.meshes()
        try:
            with ProgressBar(units=IMPORT_UNITS) as bar:
                report = store.import_file(
                    path, args.name, on_error=args.on_error, progress=bar, replace=args.replace, orient=args.orient
                )
        except MeshExistsError:
            return text.error(
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
            return text.error(f"{where}: polygon {skipped.index}: {skipped.reason}; nothing was stored ({hint})")
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


def cmd_delete(args: argparse.Namespace) -> int:
    with _open(args) as store:
        counts = store.mesh(args.name).counts()
        store.delete_mesh(args.name)
    print(f"deleted mesh {args.name!r}: {counts.vertices} vertices, {counts.edges} edges, {counts.polygons} polygons")
    return 0


def cmd_rename(args: argparse.Namespace) -> int:
    with _open(args) as store:
        store.rename_mesh(args.name, args.new_name)
    print(f"renamed mesh {args.name!r} to {args.new_name!r}")
    return 0


def cmd_copy(args: argparse.Namespace) -> int:
    with _open(args) as store:
        counts = store.copy_mesh(args.name, args.new_name, revision=args.revision).counts()
    print(
        f"copied mesh {args.name!r} to {args.new_name!r}: {counts.vertices} vertices, {counts.edges} edges, "
        f"{counts.polygons} polygons"
    )
    return 0


def _mesh_at(store: hestore.Store, args: argparse.Namespace) -> hestore.Mesh:
    """The mesh ``NAME``, as it was at ``--revision R`` if given."""
    mesh = store.mesh(args.name)
    return mesh if args.revision is None else mesh.at(args.revision)


def _at(args: argparse.Namespace) -> str:
    return "" if args.revision is None else f" at revision {args.revision}"


def cmd_export(args: argparse.Namespace) -> int:
    with _open(args) as store:
        mesh = _mesh_at(store, args)
        counts = mesh.counts()
        with ProgressBar(units=EXPORT_UNITS) as bar:
            mesh.export(args.file, binary=not args.ascii, progress=bar)
    size = os.path.getsize(args.file)
    print(
        f"wrote {args.name!r}{_at(args)} to {args.file}: {counts.vertices} vertices, "
        f"{counts.polygons} polygons, {size} bytes"
    )
    return 0


def cmd_render(args: argparse.Namespace) -> int:
    with _open(args) as store:
        mesh = _mesh_at(store, args)
        with ProgressBar() as bar:
            mesh.render(args.file, view=args.view, labels=args.labels, check=args.check, size=args.size, progress=bar)
        counts = mesh.counts()
    size = os.path.getsize(args.file)
    print(f"drew {args.name!r}{_at(args)} ({counts.polygons} polygons) to {args.file}: {size} bytes")
    return 0


# -- history ------------------------------------------------------------------------


def cmd_log(args: argparse.Namespace) -> int:
    with _open(args) as store:
        mesh = store.mesh(args.name)
        revisions = mesh.history(limit=args.limit)
        current = mesh.revision
        kept = bool(revisions) or bool(mesh.history(limit=1)) or current == 0
    if not kept:
        print(f"mesh {args.name!r} is at revision {current} and keeps no history")
        return 0
    _print([text.revision_line(r) for r in revisions])
    return 0


def cmd_diff(args: argparse.Namespace) -> int:
    with _open(args) as store:
        diff = store.mesh(args.name).diff(args.a, args.b)
    _print(text.diff_lines(args.name, args.a, args.b, diff))
    return 0


def cmd_undo(args: argparse.Namespace) -> int:
    return _went_back(args, lambda mesh: mesh.undo())


def cmd_redo(args: argparse.Namespace) -> int:
    return _went_back(args, lambda mesh: mesh.redo())


def cmd_revert(args: argparse.Namespace) -> int:
    return _went_back(args, lambda mesh: mesh.revert(args.revision))


def _went_back(args: argparse.Namespace, step) -> int:
    with _open(args) as store:
        mesh = store.mesh(args.name)
        number = step(mesh)
        latest = mesh.history(limit=1)[0]
    print(f"{args.name}: {latest.message}: now revision {number} ({text.changes(latest.changes)})")
    return 0


# -- describing and checking ------------------------------------------------------------


def cmd_info(args: argparse.Namespace) -> int:
    with _open(args) as store:
        mesh = store.mesh(args.name)
        with ProgressBar(min_seconds=QUIET_SECONDS) as bar:
            info = text.info(mesh, mesh.stats(bar))
        properties = text.property_rows(mesh)
    if args.json:
        # Only a mesh with properties has the key, so the figures of one without stay as they were.
        if properties:
            info["properties"] = [{**p, "default": text.json_default(p["default"])} for p in properties]
        print(json.dumps(info, indent=2))
        return 0
    _print(text.info_lines(info, properties))
    return 0


def cmd_check(args: argparse.Namespace) -> int:
    with _open(args) as store:
        mesh = store.mesh(args.name)
        with ProgressBar(min_seconds=QUIET_SECONDS) as bar:
            violations = mesh.check(bar)
    if not violations:
        print(f"{args.name}: valid")
        return 0
    print(f"{args.name}: {len(violations)} invariant violation(s)")
    _print([str(violation) for violation in violations])
    return 1


# -- graph ------------------------------------------------------------------------


def cmd_graph_components(args: argparse.Namespace) -> int:
    # mesh.components() rather than networkx on to_networkx(): it reads two
    # half-edge columns (origin, twin) and the vertex ids into numpy arrays and
    # labels the components there, where the multigraph would build a Python
    # node with its position per vertex and an edge with its half-edges and
    # polygons per edge, only for a traversal in Python that ignores them.
    with _open(args) as store:
        with ProgressBar(min_seconds=QUIET_SECONDS) as bar:
            components = store.mesh(args.name).components(bar)
    _print(text.component_lines(components))
    return 0


def cmd_graph_path(args: argparse.Namespace) -> int:
    # A local search in the store (hestore.Mesh.shortest_path), by edges, length or an edge property: it
    # reads the stars it expands and never builds the whole graph.
    with _open(args) as store:
        mesh = store.mesh(args.name)
        a, b = mesh.vertex(args.a), mesh.vertex(args.b)  # an unknown id: ElementNotFoundError, one line, exit 2
        try:
            path = mesh.shortest_path(a, b, args.weight)
            total = None if args.weight is None else mesh.path_weight(path, args.weight)
        except NoPathError:
            print(f"no path from vertex {args.a} to vertex {args.b} in {args.name!r}: they are in different components")
            return 1
        except (PropertyNotFoundError, InvalidInputError) as exc:
            if exc.weights is None:  # not about the name --weight gave
                raise
            return text.error(f"{exc}; --weight takes: {', '.join(exc.weights)}")
    _print(text.path_lines([v.id for v in path], args.weight, total))
    return 0


def cmd_graph_neighbors(args: argparse.Namespace) -> int:
    with _open(args) as store:
        mesh = store.mesh(args.name)
        ring = mesh.k_ring(mesh.vertex(args.v), args.k)
    print(" ".join(str(i) for i in sorted(v.id for v in ring)))
    return 0


def cmd_graph_degree_histogram(args: argparse.Namespace) -> int:
    import networkx as nx  # only here: the command line starts without it

    with _open(args) as store:
        with ProgressBar(min_seconds=QUIET_SECONDS) as bar:
            graph = store.mesh(args.name).to_networkx("multigraph", progress=bar)
    histogram = nx.degree_histogram(graph)  # index = degree; a self-loop adds 2
    if not histogram:
        print(f"mesh {args.name!r} has no vertices", file=sys.stderr)
    _print([f"{degree}: {n}" for degree, n in enumerate(histogram) if n])
    return 0


def cmd_graph_export(args: argparse.Namespace) -> int:
    from hestore import graphio  # imports networkx

    graphio.format_of(args.file)  # before any work: an unknown extension is one line, exit 2
    with _open(args) as store, ProgressBar(min_seconds=QUIET_SECONDS) as bar:
        graph = store.mesh(args.name).to_networkx(args.kind, progress=bar)
        bar("write", 0, 1)
        nodes, edges = graphio.write_graph(graph, args.file)
        bar("write", 1, 1)
    size = os.path.getsize(args.file)
    kind = graphio.FORMATS[graphio.format_of(args.file)]
    print(
        f"wrote the {args.kind} view of {args.name!r} to {args.file} ({kind}): "
        f"{text.count(nodes, 'node')}, {text.count(edges, 'edge')}, {size} bytes"
    )
    return 0


# -- the database ---------------------------------------------------------------------


def cmd_db_upgrade(args: argparse.Namespace) -> int:
    before, after = migrate.upgrade_database(args.db, busy_timeout=args.busy_timeout)
    shown = urls.shown(urls.resolve(args.db))
    if before.status == "head":
        print(f"{shown}: already at head ({after.head})")
    else:
        origin = "an empty database" if before.current is None else before.current
        print(f"{shown}: upgraded from {origin} to {after.current} (head)")
    return 0


def cmd_db_current(args: argparse.Namespace) -> int:
    print(migrate.database_state(args.db, busy_timeout=args.busy_timeout).describe())
    return 0
