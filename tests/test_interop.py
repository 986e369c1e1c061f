"""trimesh and meshio interop, and the STL / VTK / VTU files read and written through meshio (issue 11).

Round trips on real files must give back the same vertices and polygons;
what a library cannot hold (trimesh and STL: triangles only) is cut into
fans from each polygon's first corner and said so; refusals store nothing.
"""

from __future__ import annotations

import sys

import meshio
import numpy as np
import pytest

import hestore
from hestore import cli
from hestore.errors import InvalidInputError, MissingDependencyError

from helpers import dump



def rows(arrays) -> list[list[int]]:
    p = arrays.polygons
    return [list(map(int, r)) for r in (p.tolist() if isinstance(p, np.ndarray) else p)]


def same_mesh(a, b) -> None:
    x, y = a.to_arrays(), b.to_arrays()
    assert np.allclose(x.positions, y.positions) and rows(x) == rows(y)
    assert b.check() == []


def test_trimesh_round_trip_of_a_triangle_scan(store, meshes):
    mesh = store.import_file(meshes / "sphere840.ply").mesh
    tm = mesh.to_trimesh()
    assert tm.faces.tolist() == rows(mesh.to_arrays()) and tm.is_watertight == mesh.stats().is_closed
    assert tm.metadata["polygon"].tolist() == list(range(mesh.counts().polygons))
    back = store.import_trimesh("back", tm).mesh
    same_mesh(mesh, back)


def test_trimesh_cuts_quads_into_fans_and_says_which_polygon(store, meshes):
    mesh = store.import_file(meshes / "torus_quad.off").mesh
    tm = mesh.to_trimesh()
    quads = rows(mesh.to_arrays())
    assert len(tm.faces) == 2 * len(quads)
    for k, (a, b, c, d) in enumerate(quads):
        assert tm.faces[2 * k].tolist() == [a, b, c] and tm.faces[2 * k + 1].tolist() == [a, c, d]
    assert tm.metadata["polygon"].tolist() == [k for k in range(len(quads)) for _ in range(2)]
    assert store.import_trimesh("tri", tm).mesh.counts().polygons == 2 * len(quads)


@pytest.mark.parametrize("name", ["torus_quad.off", "dodecahedron_poly.obj", "sphere840.ply"])
def test_meshio_keeps_every_polygon(store, meshes, name):
    mesh = store.import_file(meshes / name).mesh
    m = mesh.to_meshio()
    assert sum(len(c.data) for c in m.cells) == mesh.counts().polygons
    back = store.import_meshio("back", m).mesh
    same_mesh(mesh, back)


@pytest.mark.parametrize("suffix", [".vtk", ".vtu"])
def test_vtk_files_round_trip(store, meshes, tmp_path, suffix):
    mesh = store.import_file(meshes / "dodecahedron_poly.obj").mesh
    path = tmp_path / f"d{suffix}"
    mesh.export(path)
    back = store.import_file(path).mesh
    assert back.name == "d" and back.stats().polygon_sizes == mesh.stats().polygon_sizes
    same_mesh(mesh, back)


def test_stl_is_written_as_triangles_and_read_back(store, meshes, tmp_path):
    mesh = store.import_file(meshes / "torus_quad.off").mesh
    path = tmp_path / "t.stl"
    mesh.export(path)
    back = store.import_file(path, orient=True).mesh
    c = mesh.counts()
    assert back.counts().polygons == 2 * c.polygons and back.stats().polygon_sizes == {3: 2 * c.polygons}
    assert back.counts().vertices == c.vertices and back.stats().is_closed and back.check() == []


def test_refusals_store_nothing(store, tmp_path, monkeypatch):
    store.create_mesh("keep")
    before = dump(store)
    lines = meshio.Mesh([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [("triangle", [[0, 1, 2]]), ("line", [[0, 1]])])
    with pytest.raises(InvalidInputError, match="line"):
        store.import_meshio("lines", lines)
    with pytest.raises(InvalidInputError):
        store.import_meshio("x", "not a mesh")
    with pytest.raises(InvalidInputError):
        store.import_trimesh("x", [[0, 1, 2]])
    bad = tmp_path / "bad.vtk"
    bad.write_text("not a vtk file\n")
    with pytest.raises(InvalidInputError, match="bad.vtk"):
        store.import_file(bad)
    monkeypatch.setitem(sys.modules, "trimesh", None)  # as if it were not installed
    with pytest.raises(MissingDependencyError, match="pip install"):
        store.mesh("keep").to_trimesh()
    assert dump(store) == before


def test_a_vertex_without_position_cannot_leave(store):
    mesh = store.create_mesh("m")
    mesh.add_polygon([mesh.add_vertex(), mesh.add_vertex((1, 0, 0)), mesh.add_vertex((0, 1, 0))])
    with pytest.raises(InvalidInputError, match="no position"):
        mesh.to_meshio()


def test_cli_reads_and_writes_meshio_formats(capsys, db_url, meshes, tmp_path):
    assert cli.main(["--db", db_url, "import", str(meshes / "dodecahedron_poly.obj"), "--name", "d"]) == 0
    out = tmp_path / "d.vtu"
    assert cli.main(["--db", db_url, "export", "d", str(out)]) == 0
    assert cli.main(["--db", db_url, "import", str(out), "--name", "again"]) == 0
    capsys.readouterr()
    with hestore.open(db_url) as store:
        same_mesh(store.mesh("d"), store.mesh("again"))
