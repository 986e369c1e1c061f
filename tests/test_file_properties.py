"""File data as properties: PLY vertex and face properties, OBJ ``vt``/``vn`` corners (SPEC §3.2, §5).

Imports put a file's per-element data on the new mesh as properties of the
same name, set-based and in the import's one transaction; exports write back
what the format can hold, so a round trip keeps it exactly. Runs on SQLite and
PostgreSQL, on shared meshes where they carry such data and on synthetic
files otherwise.
"""

from __future__ import annotations

import numpy as np
import pytest
import sqlalchemy as sa

import hestore
from hestore import io as mesh_io

from meshes import require_shared_meshes


def shared_mesh(name: str):
    return require_shared_meshes() / name


@pytest.fixture
def store(db_url):
    with hestore.open(db_url) as store:
        yield store


def _square_pair():
    positions = np.array([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (2, 0.5, 0)], dtype=float)
    offsets = np.array([0, 4, 7])
    indices = np.array([0, 1, 2, 3, 1, 4, 2])
    return positions, offsets, indices


def test_ply_vertex_and_face_properties_import_and_round_trip(store, tmp_path):
    positions, offsets, indices = _square_pair()
    rng = np.random.default_rng(7)
    temperature = rng.standard_normal(5) * 1e-300  # subnormal-ish values must survive bit for bit
    label = np.array([3, -70000], dtype=np.int64)
    path = tmp_path / "two.ply"
    mesh_io.write(path, positions, offsets, indices, vertex_properties={"temperature": temperature},
                  polygon_properties={"label": label})
    mesh = store.import_file(path).mesh
    assert mesh.properties("vertex")["temperature"] == hestore.Property("vertex", "temperature", "float64", (), None)
    assert mesh.properties("polygon")["label"].dtype == "int64"
    ids, t = mesh.property_array("vertex", "temperature")
    assert ids.tolist() == [0, 1, 2, 3, 4]
    assert t.view(np.int64).tolist() == temperature.view(np.int64).tolist()
    assert [mesh.polygon(i)["label"] for i in (0, 1)] == [3, -70000]

    again = tmp_path / "again.ply"
    mesh.export(again, binary=False)
    soup = mesh_io.read(again)
    assert soup.vertex_properties["temperature"].view(np.int64).tolist() == temperature.view(np.int64).tolist()
    assert soup.polygon_properties["label"].tolist() == [3, -70000]
    copy = store.import_file(again, "copy").mesh
    assert copy.property_array("polygon", "label")[1].tolist() == [3, -70000]


def test_meshlab_colours_become_int64_vertex_properties(store):
    mesh = store.import_file(shared_mesh("meshlab.ply")).mesh
    found = mesh.properties("vertex")
    assert list(found) == ["red", "green", "blue", "alpha"]
    assert {p.dtype for p in found.values()} == {"int64"}
    ids, blue = mesh.property_array("vertex", "blue")
    assert len(ids) == 8 and not np.ma.is_masked(blue)
    assert blue.tolist() == [255] * 8
    assert mesh.vertex(0)["alpha"] == 255
    assert mesh.check() == []


def test_spot_uv_corners_import_on_the_halfedge_leaving_each_corner(store):
    path = shared_mesh("spot.obj")
    soup = mesh_io.read(path)
    mesh = store.import_file(path).mesh
    assert mesh.properties("halfedge")["uv"].shape == (2,)
    # Corner k of polygon i is the half-edge of polygon i whose origin is that corner.
    for p in (0, 1, 100, len(soup.offsets) - 2):
        start = soup.offsets[p]
        for k, h in enumerate(mesh.polygon(p).halfedges()):
            assert h.origin.id == soup.indices[start + k]
            assert h["uv"] == tuple(soup.corner_properties["uv"][start + k])
    ids, uv = mesh.property_array("halfedge", "uv")
    polygon_side = np.array([mesh.halfedge(int(i)).polygon is not None for i in ids[:200]])
    assert (~np.ma.getmaskarray(uv)[:200].any(axis=1) == polygon_side).all()  # free half-edges have none


def test_obj_round_trip_keeps_uv_and_normals_exactly(store, tmp_path):
    positions, offsets, indices = _square_pair()
    rng = np.random.default_rng(3)
    uv = rng.random((len(indices), 2))
    normal = rng.standard_normal((len(indices), 3))
    normal[5] = np.nan  # a corner without a vn reference
    path = tmp_path / "corners.obj"
    mesh_io.write(path, positions, offsets, indices, corner_properties={"uv": uv, "normal": normal})
    mesh = store.import_file(path).mesh
    h = mesh.polygon(1).halfedges()[1]
    assert h["normal"] is None and h["uv"] == tuple(uv[5])
    out = tmp_path / "out.obj"
    mesh.export(out)
    soup = mesh_io.read(out)
    assert np.array_equal(soup.corner_properties["uv"], uv)
    assert np.array_equal(soup.corner_properties["normal"], normal, equal_nan=True)


def test_skipped_polygons_leave_their_data_out(store, tmp_path):
    positions, offsets, indices = _square_pair()
    # A third polygon repeating the first square's orientation cannot be stored.
    offsets = np.array([0, 4, 7, 11])
    indices = np.array([0, 1, 2, 3, 1, 4, 2, 0, 1, 2, 3])
    uv = np.arange(2 * len(indices), dtype=float).reshape(-1, 2)
    path = tmp_path / "skip.obj"
    mesh_io.write(path, positions, offsets, indices, corner_properties={"uv": uv})
    report = store.import_file(path, on_error="skip")
    assert [s.index for s in report.skipped] == [2]
    mesh = report.mesh
    ids, got = mesh.property_array("halfedge", "uv")
    assert int((~np.ma.getmaskarray(got).any(axis=1)).sum()) == 7
    assert mesh.polygon(1).halfedges()[2]["uv"] == tuple(uv[6])


def test_a_refused_import_stores_no_properties(store, tmp_path):
    positions, offsets, indices = _square_pair()
    offsets = np.array([0, 4, 7, 11])
    indices = np.array([0, 1, 2, 3, 1, 4, 2, 0, 1, 2, 3])
    path = tmp_path / "bad.ply"
    mesh_io.write(path, positions, offsets, indices, polygon_properties={"label": np.arange(3)})
    with pytest.raises(hestore.HalfEdgeNotFreeError):
        store.import_file(path)
    assert store.meshes() == []
    with store.session.reading() as conn:
        assert conn.execute(sa.text("SELECT count(*) FROM properties")).scalar() == 0
        assert conn.execute(sa.text("SELECT count(*) FROM property_integers")).scalar() == 0


def test_files_without_data_declare_nothing(store):
    mesh = store.import_file(shared_mesh("cube1.off")).mesh
    assert all(mesh.properties(kind) == {} for kind in ("vertex", "halfedge", "edge", "polygon"))


def test_str_properties_are_not_written_to_ply(store, tmp_path):
    mesh = store.import_arrays("t", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [[0, 1, 2]]).mesh
    mesh.add_property("vertex", "name", "str", default="")
    mesh.add_property("vertex", "w", "float64")  # no default, unset: written as NaN
    mesh.vertex(1)["w"] = 2.5
    path = tmp_path / "t.ply"
    mesh.export(path)
    soup = mesh_io.read(path)
    assert list(soup.vertex_properties) == ["w"]
    assert np.array_equal(soup.vertex_properties["w"], [np.nan, 2.5, np.nan], equal_nan=True)


def test_the_import_report_names_the_properties_it_declared(store):
    report = store.import_file(shared_mesh("spot.obj"))
    assert report.properties == [hestore.Property("halfedge", "uv", "float64", (2,), None)]
    assert "properties: halfedge 'uv' (float64, shape (2,))" in report.summary()
    plain = store.import_file(shared_mesh("cube1.off"))
    assert plain.properties == [] and "properties" not in plain.summary()
