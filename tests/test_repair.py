"""Repairs on import: ``orient=True`` (SPEC §5's repair paragraph, issue 11), on SQLite and PostgreSQL.

Orientation is decided set-based on the soup before the builder runs: the
lowest polygon of each component keeps its orientation, the others follow
it, every reversal is reported, and a component that cannot be oriented
raises `NonOrientableError` with nothing stored. A soup that is already
consistent imports identically with and without it.
"""

from __future__ import annotations


import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import hestore
from hestore import cli
from hestore.build import orient
from hestore.errors import InvalidInputError, NonOrientableError, TopologyError

from helpers import STORED, dump



def cycles_of(mesh) -> set[tuple[int, ...]]:
    """Each polygon's vertex cycle, rotated to start at its smallest vertex."""
    out = set()
    for p in mesh.polygons():
        vs = [v.id for v in p.vertices()]
        i = vs.index(min(vs))
        out.add(tuple(vs[i:] + vs[:i]))
    return out


def canon(cycle, reverse=False) -> tuple[int, ...]:
    vs = list(cycle)[::-1] if reverse else list(cycle)
    i = vs.index(min(vs))
    return tuple(vs[i:] + vs[:i])


def test_cube_shuffled_becomes_a_closed_cube(store, meshes):
    path = meshes / "cube-shuffled.off"
    with pytest.raises(TopologyError):
        store.import_file(path)  # mis-wound: refused without the repair
    report = store.import_file(path, orient=True)
    mesh = report.mesh
    s = mesh.stats()
    assert (report.polygons, s.is_closed, s.euler_characteristic, s.components) == (12, True, 2, 1)
    assert mesh.check() == [] and report.flipped and 0 not in report.flipped
    assert f"reversed {len(report.flipped)} polygon(s)" in report.summary()
    soup = hestore.io.read(str(path))
    rows = [soup.indices[a:b].tolist() for a, b in zip(soup.offsets[:-1], soup.offsets[1:])]
    expected = {canon(r, reverse=i in report.flipped) for i, r in enumerate(rows)}
    assert cycles_of(mesh) == expected


def test_a_moebius_strip_cannot_be_oriented_and_nothing_is_stored(store, meshes):
    store.create_mesh("keep")
    before = dump(store)
    for on_error in ("raise", "skip"):
        with pytest.raises(NonOrientableError) as info:
            store.import_file(meshes / "moebius.obj", orient=True, on_error=on_error)
        assert isinstance(info.value, TopologyError) and "polygon 0" in str(info.value)
        assert "moebius.obj" in str(info.value) and "nothing was stored" in str(info.value)
    assert dump(store) == before


@pytest.mark.parametrize("name", ["cube1.off", "sphere840.ply", "quadknot.obj"])
def test_a_consistent_file_imports_identically_with_orient(store, name, meshes):
    plain = store.import_file(meshes / name, name="plain")
    oriented = store.import_file(meshes / name, name="oriented", orient=True)
    assert oriented.flipped == [] and "reversed" not in oriented.summary()
    a, b = plain.mesh.to_arrays(), oriented.mesh.to_arrays()
    assert np.array_equal(np.asarray(a.polygons), np.asarray(b.polygons))
    assert plain.mesh.counts() == oriented.mesh.counts()
    for prop in plain.properties:
        ids_a, va = plain.mesh.property_array(prop.kind, prop.name)
        ids_b, vb = oriented.mesh.property_array(prop.kind, prop.name)
        assert np.array_equal(ids_a, ids_b) and np.array_equal(np.asarray(va), np.asarray(vb), equal_nan=True)


def test_corner_data_is_reversed_with_its_polygon(store, tmp_path):
    # Two triangles sharing edge 1-2, the second wound the same way as the first: it must turn, uvs with it.
    obj = tmp_path / "two.obj"
    obj.write_text(
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\n"
        "vt 0.0 0.0\nvt 0.1 0.0\nvt 0.2 0.0\nvt 0.3 0.0\nvt 0.4 0.0\nvt 0.5 0.0\n"
        "f 1/1 2/2 3/3\nf 2/4 3/5 4/6\n"
    )
    report = store.import_file(obj, orient=True)
    mesh = report.mesh
    assert report.flipped == [1] and mesh.check() == []
    uv = {(h.polygon.id, h.origin.id): h["uv"] for p in mesh.polygons() for h in p.halfedges()}
    assert uv == {(0, 0): (0.0, 0.0), (0, 1): (0.1, 0.0), (0, 2): (0.2, 0.0),
                  (1, 1): (0.3, 0.0), (1, 2): (0.4, 0.0), (1, 3): (0.5, 0.0)}
    assert [v.id for v in mesh.polygon(1).vertices()] == [1, 3, 2]


def test_orient_flag_is_checked(store):
    with pytest.raises(InvalidInputError):
        store.import_arrays("x", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [[0, 1, 2]], orient="yes")
    assert store.meshes() == []


def _octahedron_faces():
    return [[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]]


@settings(max_examples=60, **STORED)
@given(flips=st.lists(st.booleans(), min_size=8, max_size=8), shift=st.integers(0, 2))
def test_random_flips_of_an_orientable_soup_are_undone(flips, shift):
    """orient() alone, on random reversals of a closed octahedron (set-based, no database needed)."""
    faces = [f[shift:] + f[:shift] for f in _octahedron_faces()]
    soup = [list(reversed(f)) if flip else f for f, flip in zip(faces, flips)]
    o = orient(soup)
    assert o.conflict is None
    flat = np.concatenate([np.asarray(f) for f in soup])
    fixed = flat[o.order].reshape(8, 3)
    # The lowest polygon keeps its winding; the rest agree with it.
    reference = {canon(f, reverse=flips[0]) for f in faces}
    assert {canon(f) for f in fixed.tolist()} == reference
    assert not o.flip[0]


def test_random_soup_imports_closed_on_both_databases(store):
    rng = np.random.default_rng(7)
    xyz = [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)]
    for k in range(4):
        flips = rng.random(8) < 0.5
        soup = [list(reversed(f)) if flip else f for f, flip in zip(_octahedron_faces(), flips)]
        report = store.import_arrays(f"octa{k}", xyz, soup, orient=True)
        s = report.mesh.stats()
        assert s.is_closed and s.euler_characteristic == 2 and report.mesh.check() == []
        assert report.flipped == [i for i in range(8) if flips[i] != flips[0]]


def test_cli_import_orient(capsys, db_url, meshes):
    code = cli.main(["--db", db_url, "import", str(meshes / "cube-shuffled.off"), "--orient"])
    out, err = capsys.readouterr()
    assert code == 0 and "reversed" in out and "polygon(s) to orient" in out
    code = cli.main(["--db", db_url, "import", str(meshes / "moebius.obj"), "--orient"])
    out, err = capsys.readouterr()
    assert code == 2 and out == "" and "cannot be oriented" in err and err.count("\n") == 1
    with hestore.open(db_url) as store:
        assert store.meshes() == ["cube-shuffled"]
