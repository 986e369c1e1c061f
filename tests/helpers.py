"""Helpers shared by the test files (the fixtures are in ``conftest.py``).

* `dump` — the full content of every hestore table (the property catalogue,
  value tables and history included), as sorted tuples, so that "a refused
  operation changed nothing" is one equality;
* `assert_refused` — the standard check of a refused operation: the typed
  error, and unchanged tables and revision, both outside a transaction block
  and inside one (which then goes on and commits another edit);
* `assert_read_refused` and `put` — a file that `hestore.io.read` refuses,
  and the file written first;
* `run` — the command line, in the test's process;
* `Rollback`, raised into a transaction block to roll it back, and
  `STORED`, the hypothesis settings of a test that edits a stored mesh;
* small mesh builders with known ids and positions.
"""

from __future__ import annotations

import functools
import math
import pathlib
from typing import Callable, Sequence

import pytest
import sqlalchemy as sa
from hypothesis import HealthCheck

import hestore
from hestore import cli, schema
from hestore import io as formats
from hestore.errors import InvalidInputError

TABLES = (
    schema.meshes, schema.vertices, schema.halfedges, schema.edges, schema.polygons, schema.properties,
    *schema.VALUE_TABLES, *schema.HISTORY.values(),
)


@functools.cache
def _select(table: sa.Table) -> sa.Select:
    # Times as text: what both backends give the same way.
    return sa.select(*(sa.cast(c, sa.String) if isinstance(c.type, sa.DateTime) else c for c in table.c))


def _rows(conn, table: sa.Table) -> list[tuple]:
    return sorted((tuple(r) for r in conn.execute(_select(table))), key=_sortable)


@functools.lru_cache(maxsize=16)
def _engine(url: str) -> sa.Engine:
    """An engine that connects afresh each time (no pool), kept for its cache of compiled statements."""
    return sa.create_engine(url, poolclass=sa.pool.NullPool)


def _sortable(row: tuple) -> tuple:
    """A sort key for rows with NULLs (a history row of a key that did not exist has no values)."""
    return tuple((v is None, 0 if v is None else v) for v in row)


def dump(source, tables: Sequence[sa.Table] = TABLES) -> dict[str, list[tuple]]:
    """Every row of every hestore table (or of ``tables``), sorted.

    ``source`` is a `hestore.Store` (read through its own connection, so inside
    a transaction block the block's own edits are included) or a database URL
    (read through a fresh connection: committed data only).
    """
    if isinstance(source, hestore.Store):
        with source.session.reading() as conn:
            return {t.name: _rows(conn, t) for t in tables}
    with _engine(source).connect() as conn:
        return {t.name: _rows(conn, t) for t in tables}


def committed_url(store: hestore.Store) -> str:
    return store.url.render_as_string(hide_password=False)


def _without(d: dict, vertex_id: int, mesh_id: int) -> dict:
    """``d`` without the meshes row of ``mesh_id`` and without vertex ``vertex_id`` of it."""
    return {
        **d,
        "meshes": [r for r in d["meshes"] if r[0] != mesh_id],
        "vertices": [r for r in d["vertices"] if (r[0], r[1]) != (mesh_id, vertex_id)],
    }


def assert_refused(
    store: hestore.Store,
    mesh: hestore.Mesh,
    op: Callable[[], object],
    exc: type[BaseException],
    match: str | None = None,
):
    """``op()`` raises ``exc`` and changes nothing, outside and inside a block.

    Outside a block: every table and ``mesh.revision`` are as before (through
    the store and through a fresh connection). Inside a block: right after the
    refusal the block sees the tables as before; it then adds a vertex and
    commits, and afterwards exactly that vertex (and the mesh's counters and
    revision) differ. The vertex is removed again at the end, so the caller
    gets the same topology back (with one id consumed).

    Returns the `pytest.ExceptionInfo` of the first refusal.
    """
    url = committed_url(store)
    before = dump(store)
    rev = mesh.revision
    with pytest.raises(exc, match=match) as info:
        op()
    assert dump(store) == before, "a refused operation changed the stored data"
    assert dump(url) == before, "a refused operation changed the committed data"
    assert mesh.revision == rev, "a refused operation bumped the revision"

    with store.transaction():
        with pytest.raises(exc, match=match):
            op()
        assert dump(store) == before, "a refused operation inside a block changed what the block sees"
        extra = mesh.add_vertex((0.5, 0.25, 0.125))
        assert extra.position == (0.5, 0.25, 0.125)
    after = dump(url)
    assert mesh.revision == rev + 1
    assert _without(after, extra.id, mesh.id) == _without(before, extra.id, mesh.id)
    assert (mesh.id, extra.id, None, 0.5, 0.25, 0.125, rev + 1) in after["vertices"]
    assert mesh.check() == []
    mesh.remove_vertex(extra)
    return info


def assert_read_refused(path: pathlib.Path, where, fragment: str) -> None:
    """Reading ``path`` raises InvalidInputError naming the file and ``where`` (a line or "byte N")."""
    with pytest.raises(InvalidInputError) as info:
        formats.read(path)
    message = str(info.value)
    assert message.startswith(f"{path}:{where}: "), message
    assert fragment in message, message


def put(tmp_path: pathlib.Path, name: str, content: str | bytes) -> pathlib.Path:
    """The file ``name`` in ``tmp_path``, holding ``content`` (text is written as UTF-8)."""
    path = tmp_path / name
    path.write_bytes(content.encode() if isinstance(content, str) else content)
    return path


def run(capsys, *argv: str) -> tuple[int, str, str]:
    """``hestore ARGV...`` in this process: the exit status, and what it wrote to stdout and to stderr."""
    code = cli.main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


class Rollback(Exception):
    """Raised into a block to roll it back."""


#: Hypothesis settings of a test that edits a stored mesh: examples take their time, and share the test's store.
STORED = dict(deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])


# -- builders -----------------------------------------------------------------


def grid(mesh: hestore.Mesh, n: int = 2, m: int | None = None, *, positions: bool = True):
    """An ``n`` × ``m`` grid of counter-clockwise quads in the z = 0 plane.

    Returns ``(V, Q)``: ``V[i][j]`` is the vertex at ``(i, j)`` (``i`` along x),
    ``Q[i][j]`` the quad whose lower-left corner is ``(i, j)``. Vertices are
    added row by row (``V[i][j]`` has id ``j * (n + 1) + i`` in a fresh mesh).
    """
    m = n if m is None else m
    V = [[None] * (m + 1) for _ in range(n + 1)]
    for j in range(m + 1):
        for i in range(n + 1):
            V[i][j] = mesh.add_vertex((float(i), float(j), 0.0) if positions else None)
    Q = [[None] * m for _ in range(n)]
    for j in range(m):
        for i in range(n):
            Q[i][j] = mesh.add_polygon([V[i][j], V[i + 1][j], V[i + 1][j + 1], V[i][j + 1]])
    return V, Q


def triangle_grid(n: int) -> tuple[list, list]:
    """An ``n`` × ``n``-cell grid of triangles as arrays: ``(positions, triangles)``.

    Vertex ``v`` is at ``(v % (n + 1), v // (n + 1), 0)``; each cell is cut by
    its diagonal from its lower-left corner ``v`` to ``v + n + 2``.
    """
    w = n + 1
    positions = [(float(i % w), float(i // w), 0.0) for i in range(w * w)]
    triangles = [f for j in range(n) for i in range(n)
                 for v in (j * w + i,) for f in ([v, v + 1, v + w + 1], [v, v + w + 1, v + w])]
    return positions, triangles


#: Outward-oriented faces of a tetrahedron on vertices 0..3.
TETRAHEDRON = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]

#: Octahedron: vertices +x, -x, +y, -y, +z, -z (0..5), outward faces.
OCTAHEDRON_POSITIONS = [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)]
OCTAHEDRON = [
    (0, 2, 4), (2, 1, 4), (1, 3, 4), (3, 0, 4),
    (2, 0, 5), (1, 2, 5), (3, 1, 5), (0, 3, 5),
]


def build_faces(mesh: hestore.Mesh, n_vertices: int, faces: Sequence[Sequence[int]], positions=None):
    """Add ``n_vertices`` vertices, then each face as a vertex loop; returns ``(vertices, polygons)``."""
    vs = [mesh.add_vertex(positions[i] if positions else None) for i in range(n_vertices)]
    ps = [mesh.add_polygon([vs[i] for i in f]) for f in faces]
    return vs, ps


def angle(v: hestore.HalfEdge) -> float:
    """The direction of a half-edge in the xy plane, in [0, 2π)."""
    x, y, _ = v.vector
    return math.atan2(y, x) % (2 * math.pi)


def free_in_out(v: hestore.Vertex) -> tuple[list[hestore.HalfEdge], list[hestore.HalfEdge]]:
    """The free incoming and free outgoing half-edges of ``v``."""
    return [h for h in v.incoming() if h.is_boundary], [h for h in v.outgoing() if h.is_boundary]
