"""Managing meshes: rename, copy, delete and import --replace, from Python and the command line.

Every test runs on SQLite and PostgreSQL. A copy must hold the same rows as
its source (ids, references, positions, the property catalogue and values),
differ only in its mesh id, name and revision, and be independent
afterwards; a refused call changes nothing; a rename or a replace inside a
block that rolls back leaves the catalogue, and the handles, as they were.
"""

from __future__ import annotations

import pytest
import sqlalchemy as sa

import hestore
from hestore import schema
from hestore.errors import (
    HestoreError,
    InvalidInputError,
    MeshExistsError,
    MeshNotFoundError,
    RevisionNotFoundError,
)

from helpers import dump, run

TRI = ([(0, 0, 0), (1, 0, 0), (0, 1, 0), (1, 1, 0)], [[0, 1, 2], [1, 3, 2]])


def _mesh_rows(store: hestore.Store, mesh_id: int) -> dict[str, list[tuple]]:
    """Every row of the current state of one mesh, without the mesh id and the revision that wrote it (sorted)."""
    out = {}
    with store.session.reading() as conn:
        for table in schema.VERSIONED:
            cols = [c for c in table.c if c.name not in ("mesh_id", "rev")]
            rows = conn.execute(sa.select(*cols).where(table.c.mesh_id == mesh_id).order_by(*cols))
            out[table.name] = [tuple(r) for r in rows]
    return out


def _rich(store: hestore.Store, name: str = "src") -> hestore.Mesh:
    """A mesh with positions, properties, a removed element (an id gap) and edits after its import."""
    mesh = store.import_arrays(name, *TRI).mesh
    mesh.add_property("vertex", "t", "float64", default=0.5)
    mesh.add_property("halfedge", "uv", "float64", shape=(2,))
    mesh.add_property("polygon", "label", "str", default="")
    mesh.vertex(1)["t"] = 7.0
    mesh.polygon(0)["label"] = "roof"
    mesh.halfedge(0)["uv"] = (0.25, 0.75)
    mesh.split_edge(mesh.edge(0))
    mesh.remove_vertex(mesh.add_vertex((5, 5, 5)))  # the highest id used is a removed one
    return mesh


# -- copy ---------------------------------------------------------------------


def test_copy_has_the_same_rows_counters_and_policy(store):
    source = _rich(store)
    before = dump(store)
    copy = store.copy_mesh("src", "dst")
    assert copy.name == "dst" and store.meshes() == ["dst", "src"]
    assert _mesh_rows(store, copy.id) == _mesh_rows(store, source.id)
    assert copy.revision == 1 and source.revision == before_revision(before, source.id)
    m = schema.meshes
    with store.session.reading() as conn:
        rows = {r.id: r for r in conn.execute(sa.select(m))}
    for column in ("next_vertex", "next_edge", "next_polygon", "next_property", "allow_loops", "allow_multi_edges"):
        assert getattr(rows[copy.id], column) == getattr(rows[source.id], column), column
    assert copy.check() == [] and copy.vertex(1)["t"] == 7.0 and copy.polygon(0)["label"] == "roof"
    assert copy.to_arrays().positions.tolist() == source.to_arrays().positions.tolist()


def before_revision(before: dict, mesh_id: int) -> int:
    names = [c.name for c in schema.meshes.c]
    row = next(r for r in before["meshes"] if r[names.index("id")] == mesh_id)
    return row[names.index("revision")]


def test_copy_is_independent_and_never_reuses_the_sources_ids(store):
    source = _rich(store)
    copy = store.copy_mesh("src", "dst")
    counters = (source.counts(), _mesh_rows(store, source.id))
    m = schema.meshes
    with store.session.reading() as conn:
        used = conn.execute(sa.select(m.c.next_vertex).where(m.c.id == source.id)).scalar_one()
    assert used > max(v.id for v in source.vertices()) + 1  # the removed vertex is the last one
    v = copy.add_vertex()
    assert v.id == used, "the copy must go on from the source's counter, never handing out an id it used"
    copy.remove_polygon(copy.polygon(0))
    copy.vertex(1)["t"] = -1.0
    assert (source.counts(), _mesh_rows(store, source.id)) == counters
    assert source.vertex(1)["t"] == 7.0 and copy.check() == [] and source.check() == []
    store.delete_mesh("src")
    assert copy.check() == [] and copy.counts().polygons == 1  # its own removal, not the source's deletion


def test_copy_inside_a_block_sees_the_blocks_edits_and_rolls_back(store):
    source = _rich(store)
    with pytest.raises(RuntimeError):
        with store.transaction():
            source.add_vertex((9, 9, 9))
            copy = store.copy_mesh("src", "dst")
            assert copy.counts().vertices == source.counts().vertices
            raise RuntimeError
    assert store.meshes() == ["src"]
    with pytest.raises(MeshNotFoundError):
        copy.counts()


def test_copy_of_the_current_revision_and_refusals(store):
    source = _rich(store)
    copy = store.copy_mesh("src", "now", revision=source.revision)
    assert _mesh_rows(store, copy.id) == _mesh_rows(store, source.id)
    before = dump(store)
    with pytest.raises(RevisionNotFoundError) as info:  # never made (an earlier one is a branch: test_history)
        store.copy_mesh("src", "old", revision=source.revision + 1)
    assert isinstance(info.value, KeyError) and str(source.revision + 1) in str(info.value)
    with pytest.raises(MeshExistsError):
        store.copy_mesh("src", "now")
    with pytest.raises(MeshNotFoundError):
        store.copy_mesh("nope", "x")
    for bad in ("", " ", "a\nb", 7, None):
        with pytest.raises(InvalidInputError):
            store.copy_mesh("src", bad)
    for bad in ("1", 1.0, True):
        with pytest.raises(InvalidInputError):
            store.copy_mesh("src", "x", revision=bad)
    assert dump(store) == before


# -- rename -------------------------------------------------------------------


def test_rename_moves_the_name_and_every_handle_follows(store):
    mesh = _rich(store)
    v = mesh.vertex(0)
    again = store.mesh("src")
    assert store.rename_mesh("src", "part") == mesh
    assert mesh.name == again.name == v.mesh.name == "part"
    assert store.meshes() == ["part"] and store.mesh("part") == mesh
    with pytest.raises(MeshNotFoundError):
        store.mesh("src")
    assert store.rename_mesh("part", "part") == mesh  # to its own name: nothing to do
    assert mesh.check() == [] and v.position == (0.0, 0.0, 0.0)


def test_rename_refused_changes_nothing(store):
    _rich(store, "a")
    store.create_mesh("b")
    before = dump(store)
    with pytest.raises(MeshExistsError):
        store.rename_mesh("a", "b")
    with pytest.raises(MeshNotFoundError):
        store.rename_mesh("c", "d")
    for bad in ("", "x" * 256, "tab\there", 3):
        with pytest.raises(InvalidInputError):
            store.rename_mesh("a", bad)
    assert dump(store) == before and store.mesh("a").name == "a"


def test_rename_rolled_back_restores_the_name_of_the_handles(store):
    mesh = _rich(store)
    with pytest.raises(RuntimeError):
        with store.transaction():
            store.rename_mesh("src", "tmp")
            with store.transaction():
                store.rename_mesh("tmp", "inner")
            assert mesh.name == "inner"
            raise RuntimeError
    assert mesh.name == "src" and store.meshes() == ["src"]
    with store.transaction():
        store.rename_mesh("src", "kept")
        try:
            with store.transaction():  # a savepoint rolled back alone
                store.rename_mesh("kept", "gone")
                raise RuntimeError
        except RuntimeError:
            pass
        assert mesh.name == "kept"
    assert store.meshes() == ["kept"] and mesh.name == "kept"


# -- import --replace -------------------------------------------------------------


def test_import_replace_swaps_the_mesh_in_one_transaction(store):
    old = _rich(store, "m")
    report = store.import_arrays("m", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [[0, 1, 2]], replace=True)
    assert store.meshes() == ["m"] and report.mesh.counts().polygons == 1 and report.mesh.check() == []
    with pytest.raises(MeshNotFoundError):
        old.counts()
    # Nothing of the old mesh is left behind.
    with store.session.reading() as conn:
        for table in schema.MESH_TABLES:
            assert conn.execute(sa.select(sa.func.count()).where(table.c.mesh_id == old.id)).scalar() == 0


def test_import_replace_that_fails_keeps_the_old_mesh(store, tmp_path):
    _rich(store, "m")
    before = dump(store)
    with pytest.raises(InvalidInputError):
        store.import_arrays("m", [(0, 0, 0)], [[0, 1, 2]], replace=True)  # index out of range
    bad = tmp_path / "m.off"
    bad.write_text("OFF\n3 1 0\n0 0 0\n1 0 0\n")  # truncated
    with pytest.raises(InvalidInputError):
        store.import_file(bad, replace=True)
    with pytest.raises(InvalidInputError):
        store.import_arrays("m", *TRI, replace="yes")
    assert dump(store) == before
    with pytest.raises(MeshExistsError):
        store.import_arrays("m", *TRI)
    report = store.import_arrays("new", *TRI, replace=True)  # nothing to replace: a plain import
    assert report.mesh.counts().polygons == 2


# -- the command line -----------------------------------------------------------


def test_cli_delete_rename_copy_and_import_replace(capsys, db_url, tmp_path):
    assert run(capsys, "--db", db_url, "demo")[0] == 0
    code, out, err = run(capsys, "--db", db_url, "copy", "demo", "twin")
    assert code == 0 and out.startswith("copied mesh 'demo' to 'twin': ") and err == ""
    code, out, _ = run(capsys, "--db", db_url, "rename", "twin", "other")
    assert code == 0 and out == "renamed mesh 'twin' to 'other'\n"
    with hestore.open(db_url) as store:
        assert store.meshes() == ["demo", "other"]
        assert _mesh_rows(store, store.mesh("other").id) == _mesh_rows(store, store.mesh("demo").id)
        revision = store.mesh("demo").revision
    assert run(capsys, "--db", db_url, "copy", "demo", "same", "--revision", str(revision))[0] == 0
    code, out, _ = run(capsys, "--db", db_url, "delete", "other")
    assert code == 0 and out.startswith("deleted mesh 'other': ")

    off = tmp_path / "demo.off"
    off.write_text("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
    code, out, err = run(capsys, "--db", db_url, "import", str(off))
    assert code == 2 and "--replace" in err
    code, out, err = run(capsys, "--db", db_url, "import", str(off), "--replace")
    assert code == 0 and "replaced the mesh 'demo'" in out
    with hestore.open(db_url) as store:
        assert store.meshes() == ["demo", "same"] and store.mesh("demo").counts().polygons == 1


@pytest.mark.parametrize(
    "argv, words",
    [
        (("delete", "nope"), "no mesh named 'nope'"),
        (("rename", "nope", "x"), "no mesh named 'nope'"),
        (("rename", "demo", "demo2"), "already exists"),
        (("copy", "demo", "demo2"), "already exists"),
        (("copy", "demo", "x", "--revision", "999"), "no revision 999"),
        (("copy", "demo", ""), "name"),
    ],
)
def test_cli_refusals_are_one_line_and_change_nothing(capsys, db_url, argv, words):
    assert run(capsys, "--db", db_url, "demo")[0] == 0
    assert run(capsys, "--db", db_url, "copy", "demo", "demo2")[0] == 0
    with hestore.open(db_url) as store:
        before = dump(store)
    code, out, err = run(capsys, "--db", db_url, *argv)
    assert code == 2 and out == "" and err.startswith("hestore: error: ") and err.count("\n") == 1
    assert words in err and "Traceback" not in err
    with hestore.open(db_url) as store:
        assert dump(store) == before


# -- the dual -------------------------------------------------------------------



def _octahedron(store, name="octa"):
    xyz = [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)]
    faces = [[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]]
    return store.import_arrays(name, xyz, faces).mesh


def test_dual_of_an_octahedron_is_a_cube_with_centroids_and_orientation(store):
    octa = _octahedron(store)
    cube = octa.dual("cube")
    assert isinstance(cube, hestore.Mesh) and cube.name == "cube"  # the new mesh, as copy_mesh gives it
    assert cube.counts() == hestore.mesh.Counts(8, 24, 12, 6) and cube.check() == []
    assert cube.stats().polygon_sizes == {4: 6} and cube.stats().is_closed
    # Dual vertex i is the centroid of polygon i; dual polygon j goes around vertex j counter-clockwise.
    third = 1 / 3
    assert cube.vertex(0).position == pytest.approx((third, third, third))
    for v in octa.vertices():
        fan = [p.id for p in v.polygons()]
        loop = [u.id for u in cube.polygon(v.id).vertices()]
        i = loop.index(fan[0])
        assert loop[i:] + loop[:i] == fan, "the dual polygon follows the fan counter-clockwise"
    # Outward normals stay outward: the dual polygon around +z has its normal along +z.
    top = [cube.vertex(u.id).position for u in cube.polygon(4).vertices()]
    (ax, ay, _), (bx, by, _), (cx, cy, _) = top[:3]
    assert (bx - ax) * (cy - ay) - (by - ay) * (cx - ax) > 0
    assert octa.counts() == hestore.mesh.Counts(6, 24, 12, 8)  # the source is untouched


def test_dual_of_cube1_matches_the_peers_counts_and_dual_of_dual(store, meshes):
    mesh = store.import_file(meshes / "cube1.off").mesh
    dual = mesh.dual("cube1-dual")
    c = dual.counts()
    assert (c.vertices, c.edges, c.polygons) == (15048, 22572, 7526)
    assert dual.check() == [] and dual.stats().euler_characteristic == mesh.stats().euler_characteristic
    back = dual.dual("cube1-dual-dual")
    assert back.counts() == mesh.counts() and back.check() == []


def test_dual_refusals_store_nothing(store):
    open_tri = store.import_arrays("tri", *TRI).mesh
    _octahedron(store)
    nowhere = store.create_mesh("nowhere")
    a, b, c, d = (nowhere.add_vertex() for _ in range(4))
    for f in [(a, c, b), (a, b, d), (a, d, c), (b, c, d)]:
        nowhere.add_polygon(list(f))
    before = dump(store)
    with pytest.raises(hestore.TopologyError) as info:
        open_tri.dual("x")
    assert "not closed" in str(info.value) and info.value.refs
    with pytest.raises(MeshExistsError):
        store.mesh("octa").dual("tri")
    with pytest.raises(InvalidInputError):
        nowhere.dual("y")  # no positions
    with pytest.raises(InvalidInputError):
        store.mesh("octa").dual("")
    assert dump(store) == before


# -- separating pinched vertices ------------------------------------------------------


def test_separate_a_hole_bounded_at_three_pinched_vertices(store):
    """Three triangles around a triangular hole, each pair meeting only at a corner: three triangles apart."""
    mesh = store.create_mesh("m")
    a, b, c, x, y, z = (mesh.add_vertex(p) for p in [(0, 0, 0), (2, 0, 0), (1, 2, 0), (1, -1, 0), (2, 2, 0), (0, 2, 0)])
    mesh.add_property("vertex", "t", "float64")
    mesh.add_property("vertex", "tag", "str", default="")
    a["t"], a["tag"] = 4.0, "corner a"
    for tri in [(a, x, b), (b, y, c), (c, z, a)]:
        mesh.add_polygon(list(tri))
    s = mesh.stats()
    assert s.pinched_vertices == 3 and s.components == 1
    revision = mesh.revision
    made = mesh.separate_nonmanifold_vertices()
    assert sorted(v.id for v in made) == [a.id, b.id, c.id] and all(len(ws) == 1 for ws in made.values())
    s = mesh.stats()
    assert s.pinched_vertices == 0 and s.components == 3 and s.euler_characteristic == 3
    assert mesh.check() == [] and mesh.revision == revision + 1 and mesh.counts().vertices == 9
    (w,) = made[a]
    assert w.position == a.position and w["t"] == 4.0 and w["tag"] == "corner a"
    assert sorted(p.degree for p in mesh.polygons()) == [3, 3, 3]
    assert mesh.separate_nonmanifold_vertices() == {} and mesh.revision == revision + 1


def test_separate_keeps_wire_edges_and_the_first_fan(store):
    mesh = store.create_mesh("m")
    v = mesh.add_vertex((0, 0, 0))
    ring = [mesh.add_vertex((float(i), 1.0, 0.0)) for i in range(6)]
    f1 = mesh.add_polygon([v, ring[0], ring[1]])
    f2 = mesh.add_polygon([v, ring[2], ring[3]])
    f3 = mesh.add_polygon([v, ring[4], ring[5]])
    wire = mesh.add_edge(v, mesh.add_vertex((0, -1, 0)))
    made = mesh.separate_nonmanifold_vertices()
    assert list(made) == [v] and len(made[v]) == 2
    assert v in wire.vertices(), "wire edges stay at the vertex"
    corners = {p: p.vertices()[0] for p in (f1, f2, f3)}
    assert len(set(corners.values())) == 3 and v in corners.values()
    assert mesh.stats().pinched_vertices == 0 and mesh.check() == []


def test_separate_rolled_back_with_its_block(store):
    xyz = [(0, 0, 0), (1, 1, 0), (-1, 1, 0), (-1, -1, 0), (1, -1, 0)]
    mesh = store.import_arrays("bowtie", xyz, [[0, 1, 2], [0, 3, 4]]).mesh
    before = dump(store)
    with pytest.raises(RuntimeError):
        with store.transaction():
            assert len(mesh.separate_nonmanifold_vertices()) == 1
            assert mesh.stats().pinched_vertices == 0
            raise RuntimeError
    assert dump(store) == before and mesh.stats().pinched_vertices == 1


# -- the store as a mapping of names to meshes ---------------------------------------------------


def test_the_store_reads_like_a_mapping_of_names_to_meshes(store):
    assert len(store) == 0 and list(store) == [] and "a" not in store
    for name in ("b", "a", "c"):
        store.create_mesh(name)
    assert len(store) == 3 and list(store) == ["a", "b", "c"] == sorted(store)
    assert "a" in store and "z" not in store
    assert store["b"] == store.mesh("b") and store["b"].name == "b"
    with pytest.raises(KeyError):  # a MeshNotFoundError, as a dict's missing key
        store["z"]
    with pytest.raises(MeshNotFoundError, match="no mesh named 'z'"):
        store["z"]
    # Anything that cannot be a mesh name is simply not in the store, as with a dict's keys.
    for other in (None, 3, b"a", ("a",), "", "a\x00"):
        assert other not in store
    with pytest.raises(InvalidInputError):
        store[3]
    with store.transaction():
        store.create_mesh("d")
        assert "d" in store and len(store) == 4  # the block's own, uncommitted mesh
        store.delete_mesh("a")
        assert "a" not in store and list(store) == ["b", "c", "d"]
    store.rename_mesh("b", "e")
    assert "b" not in store and "e" in store and dict.fromkeys(store) == dict.fromkeys(["c", "d", "e"])


def test_the_mapping_of_a_closed_store_refuses_like_its_methods(store):
    store.create_mesh("a")
    store.close()
    with pytest.raises(HestoreError, match="is closed") as method:
        store.meshes()
    for probe in (lambda: "a" in store, lambda: store["a"], lambda: len(store), lambda: list(store)):
        with pytest.raises(HestoreError) as mapping:
            probe()
        assert (type(mapping.value), str(mapping.value)) == (type(method.value), str(method.value))
