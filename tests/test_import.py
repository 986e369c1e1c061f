"""Bulk import from arrays: the set-based build equals `add_polygon` one by one.

The reference for every comparison is the kernel itself: the same polygons
added with `Mesh.add_polygon` in input order, each refused one skipped. Two
stored meshes are compared through `signature`, which names every polygon
half-edge by (polygon number, corner) and records what its twin is; that is
the whole topology except the order of free gaps around a vertex where
several fans meet, which the issue leaves free.
"""

from __future__ import annotations

import functools
import itertools

import numpy as np
import pytest
import sqlalchemy as sa
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import hestore
from hestore import schema
from hestore.build import build
from hestore.validation import check_arrays
from hestore.errors import (
    HalfEdgeNotFreeError,
    InvalidInputError,
    MeshExistsError,
    NonManifoldError,
    PolicyError,
    TopologyError,
    VertexNotFreeError,
)

from helpers import dump

_names = itertools.count()


def _rows(store: hestore.Store, mesh: hestore.Mesh, table: sa.Table) -> list[tuple]:
    with store.session.reading() as conn:
        cols = [c for c in table.c if c.name not in ("mesh_id", "rev")]
        return [tuple(r) for r in conn.execute(sa.select(*cols).where(table.c.mesh_id == mesh.id).order_by(table.c.id))]


def signature(mesh: hestore.Mesh) -> dict:
    """The topology of a stored mesh, independent of ids and of free-gap order."""
    store = mesh.store
    he = {r[0]: r[1:] for r in _rows(store, mesh, schema.halfedges)}  # id -> origin, next, prev, twin, edge, polygon
    polys = _rows(store, mesh, schema.polygons)
    label = {}
    loops = []
    for k, (_p, start) in enumerate(polys):
        h, loop = start, []
        while True:
            label[h] = (k, len(loop))
            loop.append(he[h][0])
            h = he[h][1]
            if h == start:
                break
        loops.append(tuple(loop))
    twins = {}
    for h, (_origin, _nxt, _prv, twin, _edge, polygon) in he.items():
        if polygon is not None:
            twins[label[h]] = label.get(twin, "free")
    return {
        "counts": mesh.counts(),
        "loops": loops,
        "twins": twins,
        "isolated": sorted(v for v, h, *_ in _rows(store, mesh, schema.vertices) if h is None),
    }


@functools.cache
def _reference_store() -> hestore.Store:
    """The in-memory store that `sequential` builds in (one per process: opening one migrates its schema)."""
    return hestore.open("sqlite://")


def sequential(positions, polygons) -> tuple[hestore.Mesh, list[int]]:
    """The reference: `add_polygon` one by one in a new mesh of an in-memory store, skipping refusals.

    The caller deletes the mesh when done (``reference.store.delete_mesh(reference.name)``).
    """
    store = _reference_store()
    mesh = store.create_mesh(f"reference{next(_names)}")
    with store.transaction():
        vs = [mesh.add_vertex(tuple(p)) for p in positions]
    skipped = []
    for i, poly in enumerate(polygons):
        try:
            if any(not 0 <= j < len(vs) for j in poly):
                raise InvalidInputError("index out of range")
            mesh.add_polygon([vs[j] for j in poly])
        except (TopologyError, InvalidInputError):
            skipped.append(i)
    return mesh, skipped


def grid_positions(n):
    return [(float(i % 4), float(i // 4), 0.0) for i in range(n)]


def assert_same_as_sequential(store, polygons, n_vertices):
    positions = grid_positions(n_vertices)
    reference, skipped = sequential(positions, polygons)
    name = f"soup{next(_names)}"
    report = store.import_arrays(name, positions, polygons, on_error="skip")
    assert [s.index for s in report.skipped] == skipped
    assert report.mesh.check() == []
    assert signature(report.mesh) == signature(reference)
    assert report.polygons == len(polygons) - len(skipped)
    assert (report.vertices, report.edges) == (n_vertices, reference.counts().edges)
    if skipped:
        before = dump(store)
        with pytest.raises((TopologyError, InvalidInputError)) as info:
            store.import_arrays(name + "r", positions, polygons)
        assert info.value.skipped.index == skipped[0]
        assert f"polygon {skipped[0]}" in str(info.value)
        assert dump(store) == before, "a refused import stored something"
    reference.store.delete_mesh(reference.name)
    return report


# -- random soups -----------------------------------------------------------

# Faces of small closed and open meshes: soups drawn from them share edges
# and vertices the way real meshes do, so fans close, meet and conflict.
OCTAHEDRON = [[0, 1, 2], [0, 2, 3], [0, 3, 4], [0, 4, 1], [5, 2, 1], [5, 3, 2], [5, 4, 3], [5, 1, 4]]
CONES = [[0, 1, 2], [0, 2, 3], [0, 3, 1], [0, 4, 5], [0, 5, 6], [0, 6, 4]]  # two closed fans at 0
QUADS = [[0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [4, 5, 9, 8], [5, 6, 10, 9], [6, 7, 11, 10]]


@st.composite
def soups(draw):
    n = draw(st.integers(1, 12))
    pool = draw(st.sampled_from([OCTAHEDRON, CONES, QUADS, None]))
    if pool is not None:
        n = max(n, 1 + max(max(p) for p in pool))
    face = st.lists(st.integers(0, n - 1), min_size=1, max_size=6)
    polys = []
    for _ in range(draw(st.integers(0, 12))):
        kind = draw(st.integers(0, 9))
        if pool is not None and kind < 6:
            p = list(draw(st.sampled_from(pool)))
            if draw(st.integers(0, 5)) == 0:
                p.reverse()  # an orientation conflict
            shift = draw(st.integers(0, len(p) - 1))
            polys.append(p[shift:] + p[:shift])
        elif kind == 9:
            polys.append(draw(st.lists(st.integers(-1, n), max_size=4)))  # maybe empty or out of range
        else:
            polys.append(draw(face))
    return n, polys


@pytest.mark.slow
@pytest.mark.parametrize("backend", ["sqlite", pytest.param("postgresql", marks=pytest.mark.postgresql)], indirect=True)
def test_import_equals_add_polygon_one_by_one(store, backend):
    @settings(
        max_examples=300 if backend == "sqlite" else 80,
        deadline=None,
        suppress_health_check=[HealthCheck.too_slow],
    )
    @given(soups())
    def check(soup):
        n, polys = soup
        assert_same_as_sequential(store, polys, n)

    check()


# -- the cases by name ------------------------------------------------------


@pytest.mark.parametrize(
    "polygons, n, skipped",
    [
        (OCTAHEDRON, 6, []),
        (QUADS, 12, []),
        (CONES, 7, [3, 4, 5]),  # once a fan closes at 0, nothing more can attach there
        (CONES[3:] + CONES[:3], 7, [3, 4, 5]),
        ([[0, 1, 2], [0, 2, 3], [0, 4, 5], [0, 3, 1]], 6, [3]),  # the fan cannot close beside another
        ([[0, 1, 2], [0, 3, 4], [0, 2, 3]], 5, []),  # two fans joined by a third triangle
        ([[0, 1, 2], [0, 1, 2]], 3, [1]),  # a repeated polygon
        ([[0, 1, 2], [2, 1, 0], [0, 1, 3]], 4, [2]),  # a third polygon on edge 0-1
        ([[0]], 1, []),  # a 1-gon on a self-loop
        ([[0, 0]], 1, [0]),  # both sides of one loop: two closed fans at one vertex
        ([[0], [0]], 1, []),  # two 1-gons, one on each side of the loop
        ([[0, 1]], 2, []),  # a 2-gon on both sides of one edge
        ([[0, 1, 0, 2]], 3, []),  # a slit: one edge with the polygon on both sides
        ([[0, 1, 0, 1]], 2, [0]),  # runs 0→1 twice
        ([[], [0, 1, 2], [0, 5, 1]], 3, [0, 2]),
        ([[0, 1, 2]], 5, []),  # unreferenced vertices stay as isolated vertices
    ],
)
def test_named_soups(store, polygons, n, skipped):
    report = assert_same_as_sequential(store, polygons, n)
    assert [s.index for s in report.skipped] == skipped


def test_pinched_fans_are_all_in_the_rotation(store):
    """Two open fans meeting at a vertex (a pinched scan): every fan is reachable around it."""
    positions = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (-1, 0, 0), (0, -1, 0), (1, 1, 0), (-1, -1, 0)]
    mesh = store.import_arrays("pinch", positions, [[0, 1, 5], [0, 5, 2], [0, 3, 6], [0, 6, 4]]).mesh
    assert mesh.check() == []
    centre = mesh.vertex(0)
    assert centre.degree == 6
    assert sorted(v.id for v in centre.neighbors()) == [1, 2, 3, 4, 5, 6]
    assert len(centre.polygons()) == 4
    assert centre.halfedge.is_boundary


def test_raise_names_the_first_bad_polygon_and_stores_nothing(store):
    before = dump(store)
    positions = grid_positions(5)
    with pytest.raises(HalfEdgeNotFreeError) as info:
        store.import_arrays("m", positions, [[0, 1, 2], [3, 4, 0], [1, 2, 0], [0, 1, 2]])
    assert info.value.skipped.index == 2 and info.value.skipped.line is None
    assert "polygon 2" in str(info.value) and "0→1" in str(info.value) or "1→2" in str(info.value)
    with pytest.raises(InvalidInputError, match="out of range"):
        store.import_arrays("m", positions, [[0, 1, 7]])
    with pytest.raises(VertexNotFreeError, match="vertex 0 is not free"):
        store.import_arrays("m", grid_positions(7), CONES)
    with pytest.raises(NonManifoldError, match="vertex 0"):
        store.import_arrays("m", grid_positions(6), [[0, 1, 2], [0, 2, 3], [0, 4, 5], [0, 3, 1]])
    with pytest.raises(PolicyError, match="self-loop"):
        store.import_arrays("m", positions, [[0, 0, 1]], allow_loops=False)
    assert dump(store) == before
    assert store.meshes() == []


def test_input_errors_store_nothing(store):
    store.import_arrays("taken", grid_positions(3), [[0, 1, 2]])
    before = dump(store)
    with pytest.raises(MeshExistsError):
        store.import_arrays("taken", grid_positions(3), [[0, 1, 2]])
    with pytest.raises(InvalidInputError, match="finite"):
        store.import_arrays("nan", [(0, 0, 0), (np.nan, 0, 0), (0, 1, 0)], [[0, 1, 2]])
    with pytest.raises(InvalidInputError, match="shape"):
        store.import_arrays("shape", np.zeros((3, 4)), [[0, 1, 2]])
    with pytest.raises(InvalidInputError, match="integers"):
        store.import_arrays("float", grid_positions(3), [[0, 1, 2.5]])
    with pytest.raises(InvalidInputError, match="on_error"):
        store.import_arrays("mode", grid_positions(3), [[0, 1, 2]], on_error="ignore")
    assert dump(store) == before


def test_array_forms_and_revision(store):
    report = store.import_arrays("grid", np.zeros((4, 2)), np.array([[0, 1, 2], [0, 2, 3]], dtype=np.int32))
    mesh = report.mesh
    assert mesh.revision == 1
    assert mesh.vertex(3).position == (0.0, 0.0, 0.0)
    # ids continue where the import stopped
    v = mesh.add_vertex((5, 5, 5))
    assert v.id == 4
    p = mesh.add_polygon([mesh.vertex(0), mesh.vertex(3), v])
    assert p.id == 2 and mesh.check() == [] and mesh.revision == 3  # add_vertex, add_polygon
    assert {e.id for e in p.edges()} >= {5, 6}


def test_import_inside_a_block_rolls_back(store):
    before = dump(store)
    with pytest.raises(RuntimeError):
        with store.transaction():
            mesh = store.import_arrays("m", grid_positions(3), [[0, 1, 2]]).mesh
            assert mesh.counts().polygons == 1
            mesh.add_polygon([mesh.vertex(2), mesh.vertex(1), mesh.add_vertex()])
            raise RuntimeError("undo")
    assert dump(store) == before
    with store.transaction():
        mesh = store.import_arrays("m", grid_positions(3), [[0, 1, 2]]).mesh
        mesh.add_polygon([mesh.vertex(2), mesh.vertex(1), mesh.add_vertex()])
    assert mesh.revision == 1 and mesh.counts().polygons == 2


def test_to_arrays_round_trip(store):
    polys = [[0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7], [2, 7, 6]]
    positions = grid_positions(9)
    mesh = store.import_arrays("mixed", positions, polys).mesh
    arrays = mesh.to_arrays()
    assert arrays.polygons == polys
    np.testing.assert_array_equal(arrays.positions, np.array(positions, dtype=float))
    np.testing.assert_array_equal(arrays.vertex_ids, np.arange(9))
    again = store.import_arrays("again", arrays.positions, arrays.polygons).mesh
    assert signature(again) == signature(mesh)
    # after edits, ids have gaps: rows still line up
    mesh.remove_vertex(mesh.vertex(0))
    mesh.remove_polygon(mesh.polygon(2))
    arrays = mesh.to_arrays()
    assert arrays.vertex_ids.tolist() == [1, 2, 3, 4, 5, 6, 7, 8]
    ids = arrays.vertex_ids
    assert [[int(ids[i]) for i in p] for p in arrays.polygons] == [[1, 2, 6, 5], [2, 7, 6]]


def test_to_arrays_of_an_empty_and_of_a_deleted_mesh(store):
    mesh = store.create_mesh("empty")
    arrays = mesh.to_arrays()
    assert arrays.positions.shape == (0, 3) and len(arrays.polygons) == 0
    unplaced = store.create_mesh("unplaced")
    unplaced.add_vertex()
    assert np.isnan(unplaced.to_arrays().positions).all()
    store.delete_mesh("empty")
    with pytest.raises(hestore.MeshNotFoundError):
        mesh.to_arrays()


def test_build_without_a_database():
    b = build(4, np.array([[0, 1, 2], [0, 2, 3]]))
    a = b.arrays
    ids = np.arange(len(a.he_id))
    assert (a.he_id == ids).all() and (a.he_twin == ids ^ 1).all() and (a.he_edge == ids >> 1).all()
    # next and prev are inverse permutations; twins start where the other ends
    assert (a.he_prev[a.he_next] == ids).all()
    assert (a.he_origin[a.he_next] == a.he_origin[ids ^ 1]).all()
    assert (a.he_polygon[a.he_next] == a.he_polygon).all()
    free = a.he_polygon < 0
    assert (free[a.v_halfedge[a.he_origin[free]]]).all()  # V_BOUNDARY
    # The same arrays are what validation checks: no database needed.
    assert check_arrays(a) == []
    assert check_arrays(a._replace(he_next=np.roll(a.he_next, 1))) != []
