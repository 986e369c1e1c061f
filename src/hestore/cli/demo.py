"""The demo behind ``hestore demo`` (`hestore.cli.commands.cmd_demo`): one mesh showing what hestore can store.

It builds the mesh ``"demo"`` — a polygon fan, a wire edge, a self-loop
bounding a 1-gon, two parallel edges bounding a 2-gon and two triangles
meeting at a single vertex — in one transaction, edits it in a second one,
shows a failed transaction rolled back and a non-manifold edit refused
without changing anything, applies Euler operators (a split wire edge, a
flipped diagonal, a poked 1-gon) and a refused collapse, and prints a
short summary. It replaces an
existing ``"demo"`` mesh, so it can be run any number of times.

The demo is also a smoke test: where the store does not behave as promised,
it raises instead of printing a misleading summary.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING

from hestore.errors import TopologyError

if TYPE_CHECKING:  # pragma: no cover - typing only
    from hestore.mesh import Mesh
    from hestore.store import Store

__all__ = ["MESH_NAME", "run"]

#: The name of the mesh the demo (re)creates.
MESH_NAME = "demo"


class _Rollback(Exception):
    """Raised on purpose to leave a transaction block."""


def _ids(handles) -> str:
    return ", ".join(str(h.id) for h in handles)


def _unchanged(mesh: Mesh, before: tuple, what: str) -> None:
    after = (mesh.counts(), mesh.revision)
    if after != before:
        raise RuntimeError(
            f"hestore demo: {what} changed the mesh ({before} -> {after}); this is a bug in hestore"
        )


def run(store: Store, out: Callable[[str], object] = print) -> Mesh:
    """Build, edit and summarise the demo mesh in `store`.

    Parameters
    ----------
    store : hestore.Store
        Where to build it. A mesh called ``"demo"`` there is replaced.
    out : callable, default print
        Called with each line of the report.

    Returns
    -------
    hestore.Mesh
        The demo mesh, valid (``mesh.check() == []``).

    Raises
    ------
    RuntimeError
        The store broke one of its promises (an edit that should have been
        refused or rolled back changed the mesh).

    Examples
    --------
    >>> import hestore
    >>> from hestore.cli import demo
    >>> store = hestore.open("sqlite://")
    >>> mesh = demo.run(store, out=lambda line: None)
    >>> mesh.name, mesh.counts().polygons, mesh.check()
    ('demo', 9, [])
    >>> mesh = demo.run(store, out=lambda line: None)  # again: replaces it
    >>> store.meshes()
    ['demo']
    >>> store.close()
    """
    out(f"hestore demo on {store.url}")

    # One transaction for replace-and-build: if anything fails, the previous
    # demo mesh is still there, untouched.
    with store.transaction(message="build the demo mesh"):
        replaced = MESH_NAME in store.meshes()
        if replaced:
            store.delete_mesh(MESH_NAME)
        mesh = store.create_mesh(MESH_NAME, allow_loops=True, allow_multi_edges=True)

        # A fan of four triangles around `centre`, counter-clockwise seen from +z.
        centre = mesh.add_vertex((0.0, 0.0, 0.0))
        rim = [
            mesh.add_vertex((math.cos(i * math.pi / 5), math.sin(i * math.pi / 5), 0.0))
            for i in range(5)
        ]
        fan = [mesh.add_polygon([centre, rim[i], rim[i + 1]]) for i in range(4)]

        # A wire edge: no polygon on either side, attached to nothing.
        w0, w1 = mesh.add_vertex((2.0, 0.0, 0.0)), mesh.add_vertex((3.0, 0.0, 0.0))
        wire = mesh.add_edge(w0, w1)

        # A self-loop bounding a 1-gon.
        knot = mesh.add_vertex((4.5, 0.0, 0.0))
        loop = mesh.add_edge(knot, knot)
        monogon = mesh.add_polygon([loop.halfedges()[0]])

        # Two parallel edges bounding a 2-gon: a->b along one, b->a back along the other.
        a, b = mesh.add_vertex((6.0, 0.0, 0.0)), mesh.add_vertex((7.0, 0.0, 0.0))
        e1, e2 = mesh.add_edge(a, b), mesh.add_edge(a, b)
        digon = mesh.add_polygon([e1.halfedges()[0], e2.halfedges()[1]])

        # Two triangles sharing one vertex and nothing else (a "bowtie").
        pinch = mesh.add_vertex((9.0, 0.0, 0.0))
        left = [mesh.add_vertex((8.0, 0.5, 0.0)), mesh.add_vertex((8.0, -0.5, 0.0))]
        right = [mesh.add_vertex((10.0, -0.5, 0.0)), mesh.add_vertex((10.0, 0.5, 0.0))]
        bowtie = [mesh.add_polygon([pinch, *left]), mesh.add_polygon([pinch, *right])]

    out(f"{'replaced' if replaced else 'created'} mesh {MESH_NAME!r} in one transaction:")
    out(f"  fan of triangles {_ids(fan)} around vertex {centre.id}")
    out(f"  wire edge {wire.id} between vertices {w0.id} and {w1.id}, no polygon on either side")
    out(f"  self-loop edge {loop.id} at vertex {knot.id}, bounding the 1-gon {monogon.id}")
    out(
        f"  parallel edges {e1.id} and {e2.id} between vertices {a.id} and {b.id}, "
        f"bounding the 2-gon {digon.id}"
    )
    out(f"  triangles {_ids(bowtie)} meeting only at vertex {pinch.id}")

    # Several edits, one transaction: the revision goes up by one.
    revision = mesh.revision
    with store.transaction(message="close the fan's half-disc"):
        rim.append(mesh.add_vertex((-1.0, 0.0, 0.0)))
        fan.append(mesh.add_polygon([centre, rim[4], rim[5]]))
    out(
        f"edited in one transaction: new vertex {rim[5].id} and triangle {fan[-1].id} "
        f"close the fan's half-disc (revision {revision} -> {mesh.revision})"
    )

    # A block that fails is rolled back as a whole, however far it got.
    spoke = mesh.find_halfedge(centre, rim[1]).edge
    before = (mesh.counts(), mesh.revision)
    try:
        with store.transaction():
            mesh.remove_edge(spoke)
            raise _Rollback
    except _Rollback:
        pass
    _unchanged(mesh, before, "a rolled-back transaction")
    out(
        f"rolled back: a transaction removed edge {spoke.id} (and both triangles on it), "
        "then failed; nothing changed"
    )

    # An edge bounds at most two polygons: the spoke centre-rim[2] already
    # has a triangle on each side, so a third one must be refused.
    before = (mesh.counts(), mesh.revision)
    try:
        mesh.add_polygon([centre, rim[2], rim[4]])
    except TopologyError as exc:
        refusal = f"{type(exc).__name__}: {exc}"
    else:
        raise RuntimeError(
            "hestore demo: a third polygon on an edge was accepted; this is a bug in hestore"
        )
    _unchanged(mesh, before, "a refused edit")
    out(
        f"refused: triangle ({centre.id}, {rim[2].id}, {rim[4].id}) would be a third polygon "
        f"on the edge between vertices {centre.id} and {rim[2].id}"
    )
    out(f"  {refusal}")
    out("  nothing changed: counts and revision are as before")

    # Euler operators, on the fan and on the shapes manifold-only libraries refuse.
    with store.transaction(message="Euler operators: split, flip, poke"):
        middle = mesh.split_edge(wire)  # a wire edge splits like any other
        diagonal = mesh.flip_edge(mesh.find_halfedge(centre, rim[2]).edge)
        inside = mesh.poke_polygon(monogon)  # the 1-gon becomes a triangle on its self-loop
    ends = sorted(v.id for v in diagonal.vertices())
    out(
        f"Euler operators in one transaction: vertex {middle.id} splits wire edge {wire.id}, "
        f"edge {diagonal.id} flipped to join vertices {ends[0]} and {ends[1]}, "
        f"vertex {inside.id} pokes the 1-gon {monogon.id} (now a triangle on self-loop {loop.id})"
    )
    before = (mesh.counts(), mesh.revision)
    if mesh.can_collapse_edge(e1.halfedges()[0]):
        raise RuntimeError("hestore demo: collapsing an edge of a 2-gon was allowed; this is a bug in hestore")
    try:
        mesh.collapse_edge(e1.halfedges()[0])
    except TopologyError as exc:
        refusal = f"{type(exc).__name__} ({exc.reason}): {exc}"
    _unchanged(mesh, before, "a refused collapse")
    out(f"refused: collapsing edge {e1.id} of the 2-gon {digon.id}")
    out(f"  {refusal}")

    counts = mesh.counts()
    violations = mesh.check()
    out(f"summary of {MESH_NAME!r}:")
    out(
        f"  {counts.vertices} vertices, {counts.edges} edges, "
        f"{counts.halfedges} half-edges, {counts.polygons} polygons"
    )
    out(f"  revision {mesh.revision}")
    out(f"  check(): {'valid' if not violations else f'{len(violations)} violation(s)'}")
    for violation in violations:
        out(f"    {violation}")
    return mesh
