"""The ``hestore`` command's arguments: a table of commands, and the argparse parser built from it.

This module owns `COMMANDS` — each command's name, help, description and
arguments, and the subcommands of ``graph`` and ``db``; its handler is the
``cmd_*`` function of `hestore.cli.commands` named after it — and
`build_parser`, which turns the table into one `argparse.ArgumentParser`
whose parsing sets ``func``, the handler. `hestore.cli.main` builds it for every run; the values
``--view`` and ``--size`` take are converted here, so a handler receives
what the library takes.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass

import hestore
from hestore.cli import commands
from hestore.cli.text import TOP_COMPONENTS
from hestore.render import CHECK_POLYGONS, LABEL_VERTICES, MAX_PIXELS, MAX_POLYGONS, MAX_SIDE, VIEWS
from hestore.store import DEFAULT_BUSY_TIMEOUT
from hestore.traversal import KINDS as GRAPH_KINDS

__all__ = ["Arg", "Command", "COMMANDS", "build_parser"]


@dataclass(frozen=True)
class Arg:
    """One argument: what `argparse.ArgumentParser.add_argument` takes."""

    flags: tuple[str, ...]
    options: dict


def arg(*flags: str, **options) -> Arg:
    return Arg(flags, options)


@dataclass(frozen=True)
class Command:
    """One command: its arguments, or (``graph``, ``db``) its own commands after its arguments.

    Its handler is the function of `hestore.cli.commands` named after it:
    ``cmd_`` and the command's words, dashes as underscores (``cmd_list``,
    ``cmd_graph_degree_histogram``, ``cmd_db_upgrade``), looked up when the
    parser is built — so a command without one fails every run at once, and
    a test can stand in for one.
    """

    name: str
    help: str
    args: tuple[Arg, ...] = ()
    description: str | None = None
    commands: tuple[Command, ...] = ()


def _view(text: str) -> object:
    """``--view``: a named view, or ``AZIMUTH,ELEVATION`` in degrees (anything else: the library refuses it)."""
    if text in VIEWS:
        return text
    parts = text.split(",")
    try:
        return tuple(float(p) for p in parts) if len(parts) == 2 else text
    except ValueError:
        return text


def _pixels(text: str) -> tuple[int, int]:
    """``--size WIDTHxHEIGHT``."""
    try:
        width, height = (int(p) for p in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT in pixels, such as 1200x900, not {text!r}") from None
    if width < 1 or height < 1:
        raise argparse.ArgumentTypeError(f"width and height must be at least 1, not {text!r}")
    return width, height


def _name(help: str = "the mesh") -> Arg:
    return arg("name", metavar="NAME", help=help)


def _revision(help: str) -> Arg:
    return arg("--revision", metavar="R", type=int, default=None, help=help)


_GRAPH = (
    Command(
        "components",
        f"the number of connected components and the sizes of the {TOP_COMPONENTS} largest",
        description="Print the number of connected components of the vertex-edge graph (an "
        f"isolated vertex is one of its own), then the {TOP_COMPONENTS} largest, one a line: "
        "its number of vertices and its lowest vertex id.",
    ),
    Command(
        "path",
        "a shortest path (fewest edges, or least total --weight) between vertices A and B",
        (
            arg("a", metavar="A", type=int, help="the id of the first vertex"),
            arg("b", metavar="B", type=int, help="the id of the last vertex"),
            arg(
                "--weight",
                metavar="W",
                help="weigh each edge by W: 'length' (the Euclidean length, from the positions of its "
                "ends) or the name of a numeric (int64 or float64, unshaped) edge property; an edge the "
                "search meets without a weight (an end without a position, a property unset without a "
                "default) or with a negative one is an error (default: every edge weighs 1)",
            ),
        ),
        "Print a shortest path from vertex A to vertex B: the vertex ids along it "
        "and its length in edges; with --weight, the path of least total weight and that total. "
        "Exit status 1 when there is none.",
    ),
    Command(
        "neighbors",
        "the vertices within K edges of vertex V (its k-ring), V included",
        (
            arg("v", metavar="V", type=int, help="the id of the vertex at the centre"),
            arg("--k", metavar="K", type=int, default=1,
                help="how many edges away at most, an integer >= 0 (default: 1, the vertex and its neighbours)"),
        ),
        "Print the ids of the vertices within K edges of vertex V (hestore.Mesh.k_ring: "
        "V itself, the vertices joined to it by an edge, theirs, and so on, K levels deep), "
        "ascending, on one line separated by spaces. Read from the store around V, without "
        "building the whole graph.",
    ),  # fmt: skip
    Command(
        "degree-histogram",
        "how many vertices have each degree (a self-loop counts twice)",
        description="Print 'degree: count' lines for every degree some vertex has, lowest first: "
        "networkx.degree_histogram of the multigraph (a self-loop counts twice, each parallel "
        "edge once).",
    ),
    Command(
        "export",
        "write a graph view to a GraphML (.graphml) or edge list (.edgelist) file",
        (
            arg("file", metavar="FILE", help="the file to write (.graphml or .edgelist)"),
            arg(
                "--kind",
                choices=GRAPH_KINDS,
                default="multigraph",
                help="the view: multigraph (the default: vertices, one edge per edge), graph (parallel "
                "edges merged), halfedge (directed, one edge per half-edge) or dual (polygons, joined "
                "across their shared edges)",
            ),
        ),
        "Write one of the graph views of hestore.Mesh.to_networkx to FILE, replacing "
        "it: GraphML for .graphml (nodes, edges with their keys, every attribute; None values "
        "left out, tuples and lists written as JSON text), an edge list for .edgelist (a line "
        "'u v {attributes}' per edge, the key as attribute 'key'; no isolated nodes, no node "
        "attributes).",
    ),
)

#: Every command, in the order ``hestore --help`` lists them.
COMMANDS = (
    Command("demo", "build the demo mesh 'demo' (replacing it) and print what happened"),
    Command(
        "import",
        "import an OFF, OBJ or PLY file as a new mesh and print what was stored",
        (
            arg("file", metavar="FILE", help="the file to read (.off, .obj or .ply)"),
            arg("--name", metavar="N", help="the new mesh's name (default: the file name without its extension)"),
            arg(
                "--on-error",
                choices=("raise", "skip", "split"),
                default="raise",
                help="what to do with a polygon the half-edge structure cannot take: raise (the default) "
                "stops with an error naming it and stores nothing; skip stores the mesh without it "
                "and lists it in the report; split keeps it on its own copies of the vertices where it does not "
                "fit and lists the copies (a polygon malformed in itself is still skipped)",
            ),
            arg(
                "--orient",
                action="store_true",
                help="reverse polygons so that each component is consistently oriented (reported); a component "
                "that cannot be oriented (a Moebius strip) is an error and nothing is stored, or, with --on-error "
                "split, is cut along edges until it can be (reported)",
            ),
            arg(
                "--replace",
                action="store_true",
                help="replace a mesh of the same name, in the same transaction: the old mesh goes only if the "
                "new one is stored",
            ),
        ),
        "Import an OFF, OBJ or PLY file (ASCII or binary; the format comes from the "
        "extension) as a new mesh, in one transaction, and print a report: counts, and the "
        "polygons left out, if any. Progress goes to stderr.",
    ),
    Command("delete", "delete a mesh and all its elements", (_name("the mesh to delete"),)),
    Command(
        "rename",
        "give a mesh a new name",
        (_name("the mesh to rename"), arg("new_name", metavar="NEW", help="its new name (no mesh may have it)")),
    ),
    Command(
        "copy",
        "copy a mesh: the same ids and content under a new name, independent afterwards",
        (
            _name("the mesh to copy"),
            arg("new_name", metavar="NEW", help="the copy's name (no mesh may have it)"),
            _revision("the revision to copy (default: the current one): branches the mesh there"),
        ),
    ),
    Command(
        "export",
        "write a mesh's vertices and polygons to an OFF, OBJ or PLY file",
        (
            _name("the mesh to export"),
            arg("file", metavar="FILE", help="the file to write (.off, .obj or .ply)"),
            arg("--ascii", action="store_true",
                help="write ASCII PLY instead of binary (OFF and OBJ are always text)"),
            _revision("write the mesh as it was at revision R"),
        ),
        "Write a mesh's vertices (in id order) and polygons to FILE, in the format "
        "its extension names (.off, .obj or .ply), replacing the file if it exists. Wire edges "
        "are not written. Progress goes to stderr.",
    ),  # fmt: skip
    Command(
        "render",
        "draw a mesh to a PNG or SVG picture: shaded polygons, boundary loops, problems highlighted",
        (
            _name("the mesh to draw"),
            arg("file", metavar="FILE", help="the picture to write (.png or .svg)"),
            _revision("draw the mesh as it was at revision R"),
            arg(
                "--view",
                metavar="V",
                type=_view,
                default=None,
                help=f"where to look from: {', '.join(VIEWS)}, or AZIMUTH,ELEVATION in degrees (default: "
                "straight on for a planar mesh, else iso)",
            ),
            arg(
                "--labels",
                nargs="?",
                const="vertices",
                default=False,
                choices=("vertices", "halfedges", "all"),
                help=f"write ids: of vertices (the default with --labels), of half-edges (an arrow each, on its "
                f"polygon's side), or all (up to {LABEL_VERTICES:,} of each)",
            ),
            arg(
                "--check",
                action=argparse.BooleanOptionalAction,
                default=None,
                help=f"run the invariant check and draw what it finds in red (default: for meshes of up to "
                f"{CHECK_POLYGONS:,} polygons)",
            ),
            arg("--size", metavar="WxH", type=_pixels, default=(1200, 900),
                help=f"picture size in pixels (default 1200x900; each side at most {MAX_SIDE:,} and "
                f"{MAX_PIXELS:,} pixels in all)"),
        ),
        "Draw a mesh to FILE, a PNG or SVG picture by its extension, replacing the file if it "
        "exists (written whole or not at all): polygons flat-shaded, edges thin, boundary loops as coloured "
        "lines, wire edges, isolated and pinched vertices marked, and what 'check' finds in red, with a "
        f"legend. Above {MAX_POLYGONS:,} polygons they are drawn as a raster image (without edges). "
        "Progress goes to stderr.",
    ),  # fmt: skip
    Command(
        "log",
        "the mesh's revisions, newest first: when, what changed (+created −removed ~changed), message",
        (_name(), arg("--limit", metavar="N", type=int, default=None, help="show at most N revisions")),
    ),
    Command(
        "diff",
        "what differs between two revisions of a mesh",
        (
            _name(),
            arg("a", metavar="A", type=int, help="the earlier revision"),
            arg("b", metavar="B", type=int, help="the later revision"),
        ),
    ),
    Command("undo", "undo the mesh's most recent change not yet undone (a new revision)", (_name(),)),
    Command("redo", "re-apply the most recently undone change (a new revision)", (_name(),)),
    Command(
        "revert",
        "make the mesh equal to an earlier revision (a new revision)",
        (_name(), arg("revision", metavar="R", type=int, help="the revision to go back to")),
    ),
    Command("list", "list the meshes: counts and revision of each"),
    Command(
        "info",
        "a mesh's revision, policy, counts and topology: boundaries, components, genus, ...",
        (_name("the mesh to describe"), arg("--json", action="store_true", help="print a JSON object instead of text")),
        "Print a mesh's name, revision and policy, and every field of its "
        "hestore.Mesh.stats(): counts (with self-loops, parallel edges and polygon sizes), "
        "boundary and wire edges, boundary loops, components, Euler characteristic, genus, "
        "pinched vertices, whether it is closed and manifold; then its properties, if it has "
        "any: kind, name, dtype, shape and default of each.",
    ),
    Command(
        "check",
        "check a mesh's invariants; exit status 1 and the violations when invalid",
        (_name("the mesh to check"),),
    ),
    Command(
        "graph",
        "graph analytics on a mesh's connectivity: components, path, neighbors, degree-histogram, export",
        args=(_name(),),
        description="Graph analytics on a mesh's committed connectivity, on its multigraph: "
        "one node per vertex, isolated ones included, one edge per edge, self-loops and parallel "
        "edges kept. path (by edges, length or an edge property) and neighbors are local queries "
        "that read the store around their vertices (hestore.Mesh.shortest_path, hestore.Mesh.k_ring); "
        "degree-histogram and export build the networkx graph (hestore.Mesh.to_networkx).",
        commands=_GRAPH,
    ),
    Command(
        "db",
        "database schema: upgrade, current",
        commands=(
            Command("upgrade", "migrate the database schema to this hestore's head (creates a new one)"),
            Command("current", "print the database's schema revision and whether it is head"),
        ),
    ),
)


def _add(subparsers, command: Command, words: tuple[str, ...] = ()) -> None:
    """Add ``command`` (and its own commands) to ``subparsers``; ``words`` are the commands it is under."""
    options = {"help": command.help}
    if command.description is not None:
        options["description"] = command.description
    parser = subparsers.add_parser(command.name, **options)
    for a in command.args:
        parser.add_argument(*a.flags, **a.options)
    words = (*words, command.name)
    if command.commands:
        inner = parser.add_subparsers(
            dest=f"{command.name}_command", metavar=f"{command.name.upper()}_COMMAND", required=True
        )
        for sub in command.commands:
            _add(inner, sub, words)
    else:
        parser.set_defaults(func=getattr(commands, "cmd_" + "_".join(words).replace("-", "_")))


def build_parser() -> argparse.ArgumentParser:
    """Build the argument parser of the ``hestore`` command from `COMMANDS`.

    Returns
    -------
    argparse.ArgumentParser
        Parsing sets ``func``, the command's handler, and its arguments.

    Examples
    --------
    >>> from hestore.cli import build_parser
    >>> args = build_parser().parse_args(["--db", "sqlite:///x.db", "check", "part"])
    >>> args.db, args.name, args.func.__name__
    ('sqlite:///x.db', 'part', 'cmd_check')
    >>> build_parser().parse_args(["render", "m", "m.png", "--view", "30,20"]).view
    (30.0, 20.0)
    """
    parser = argparse.ArgumentParser(
        prog="hestore",
        description="A persistent, transactional half-edge topology store.",
        epilog="The database is --db, else $HESTORE_URL, else ./hestore.db. Only import, demo and db upgrade "
        "create it when there is none; every other command says so.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {hestore.__version__}")
    parser.add_argument(
        "--db",
        metavar="URL",
        help="SQLAlchemy database URL, e.g. sqlite:///meshes.db or postgresql+psycopg://user@host/db "
        "(a bare path means a SQLite file)",
    )
    parser.add_argument(
        "--busy-timeout",
        metavar="SECONDS",
        type=float,
        default=DEFAULT_BUSY_TIMEOUT,
        help="how long a command waits for another writer's lock (another process importing into or editing "
        f"the same database) before it gives up, changing nothing (default {DEFAULT_BUSY_TIMEOUT:g})",
    )
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for command in COMMANDS:
        _add(commands, command)
    return parser
