"""Every file in the shared meshes folder, imported on SQLite and PostgreSQL.

Each file either imports with ``on_error="raise"`` and passes ``check()``, or
holds what the half-edge structure cannot represent and then

* fails with ``"raise"``, naming the first bad polygon and its file line,
  storing nothing;
* imports with ``"skip"``, reporting exactly the polygons it left out: the
  stored loops are the file's polygons minus the reported ones, in order;
* and, independently, the skipped list equals what `Mesh.add_polygon` one
  polygon at a time (skipping refusals) leaves out.

`REFUSING` names the files of the second kind, with the reason the manifest
gives; a file moving from one kind to the other fails the test. Each file is
a test of its own; the imports checked are the corpus's (``conftest.corpus``:
each file once per backend and test session, which other tests read too),
and the reference built polygon by polygon is made once per file, for both
backends.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest

from hestore import io as formats

from helpers import dump
from meshes import MISSING, corpus_files, corpus_group, corpus_id, require_shared_meshes, shared_files
from test_import import sequential, signature

#: Files that hold polygons the half-edge structure cannot take, and why.
REFUSING = {
    "cow.obj": "a pinch vertex where two closed fans meet",
    "cube-minimal-degenerated.obj": "repeated indices: a face that reuses a directed edge",
    "cube-shuffled.off": "inconsistently oriented triangles",
    "fan3.obj": "three triangles on one edge",
    "hourglass_ico.obj": "two closed sheets joined at one vertex",
    "joined_tetrahedra.obj": "a duplicated face with opposite orientation: edges with three polygons",
    "moebius.obj": "a non-orientable strip",
}

#: Up to this many polygons, a file is also added polygon by polygon as the reference.
SEQUENTIAL_LIMIT = 20_000


def test_the_shared_meshes_are_all_there():
    found = [p.name for p in shared_files()]
    assert len(found) >= 29, f"expected the 29 shared meshes in {require_shared_meshes()}, found {len(found)}"
    assert set(REFUSING) <= set(found), f"refusing files missing: {set(REFUSING) - set(found)}"


def test_a_corpus_file_is_found_in_the_ids_of_its_tests():
    require_shared_meshes()  # which files are big
    for name in ("cow.obj", "cube-minimal.ply", "sphere840.ply", MISSING):
        assert corpus_group(f"tests/t.py::test[sqlite-{corpus_id(name)}]") == name
        assert corpus_group(f"tests/t.py::test[{corpus_id(name)}-postgresql]") == name
    for name in ("stanford-bunny-subdiv2.obj", "igea-subdiv1.ply"):  # big: by backend too
        assert corpus_group(f"tests/t.py::test[sqlite-{corpus_id(name)}]") == f"{name} on sqlite"
        assert corpus_group(f"tests/t.py::test[{corpus_id(name)}-postgresql]") == f"{name} on postgresql"
    assert corpus_group("tests/t.py::test[sqlite]") is corpus_group("tests/t.py::test_cow.obj") is None


def _loops(soup):
    return [soup.indices[a:b].tolist() for a, b in zip(soup.offsets[:-1].tolist(), soup.offsets[1:].tolist())]


def _stored_loops(mesh):
    polygons = mesh.to_arrays().polygons
    return polygons.tolist() if isinstance(polygons, np.ndarray) else polygons


@functools.cache
def _sequential(path) -> tuple[list[int], dict]:
    """The polygons `sequential` skips in the file at ``path``, and the signature of what it builds.

    The same on every backend (it builds in an in-memory SQLite store), so made once per test session.
    """
    soup = formats.read(path)
    reference, skipped = sequential(soup.positions, _loops(soup))
    try:
        return skipped, signature(reference)
    finally:
        reference.store.delete_mesh(reference.name)


@pytest.mark.parametrize("corpus_file", corpus_files())
def test_every_shared_mesh(store, corpus, corpus_file):
    """The file as the corpus imported it: with ``"raise"``, and after a refusal with ``"skip"``.

    A refused import is made again here, into the test's empty store, to see that it stores nothing.
    """
    imported = corpus.imported(corpus_file)
    path, report = imported.path, imported.report
    soup = formats.read(path)
    n_polygons = len(soup.offsets) - 1
    name = path.stem
    if imported.refusal is not None:
        exc = imported.refusal
        assert path.name in REFUSING, f"{path.name} was refused but should import: {exc}"
        first = exc.skipped
        assert f"polygon {first.index}" in str(exc) and f"line {first.line}" in str(exc), str(exc)
        assert str(path) in str(exc)
        assert first.line == int(soup.lines[first.index])
        before = dump(store)
        with pytest.raises(type(exc)) as again:
            store.import_file(path, name)
        assert str(again.value) == str(exc)
        assert dump(store) == before, f"{path.name}: a refused import stored something"
        skipped = [s.index for s in report.skipped]
        assert skipped[0] == first.index
        assert all(s.line == int(soup.lines[s.index]) and s.reason for s in report.skipped)
        kept = [loop for i, loop in enumerate(_loops(soup)) if i not in set(skipped)]
        assert report.polygons == n_polygons - len(skipped) == len(kept)
        stored = _stored_loops(report.mesh)
        assert stored == kept, f"{path.name}: stored polygons differ from the file minus the skipped"
    else:
        assert path.name not in REFUSING, f"{path.name} imported although it cannot be represented"
        skipped = []
        assert report.polygons == n_polygons
        if n_polygons <= SEQUENTIAL_LIMIT:
            assert _stored_loops(report.mesh) == _loops(soup)
    mesh = report.mesh
    assert mesh.name == name
    assert report.vertices == len(soup.positions), "unreferenced vertices must be kept"
    assert mesh.check() == [], path.name
    if n_polygons <= SEQUENTIAL_LIMIT:
        reference_skipped, reference_signature = _sequential(path)
        assert skipped == reference_skipped, path.name
        assert signature(mesh) == reference_signature, path.name


@pytest.mark.parametrize("backend", ["sqlite"], indirect=True)
@pytest.mark.parametrize("corpus_file", corpus_files(max_bytes=1_000_000, exclude=REFUSING))
def test_export_round_trip_of_shared_meshes(store, corpus, corpus_file, tmp_path, backend):
    """Small representable files: export to each format and import again, same topology."""
    mesh = corpus.mesh(corpus_file)
    stem = mesh.name
    expected = signature(mesh)
    for suffix, options in ((".off", {}), (".obj", {}), (".ply", {}), (".ply", {"binary": False})):
        out = tmp_path / f"{stem}{suffix}"
        mesh.export(out, **options)
        again = store.import_file(out, f"{stem}-again")
        assert signature(again.mesh) == expected, (corpus_file, suffix, options)
        np.testing.assert_array_equal(again.mesh.to_arrays().positions, mesh.to_arrays().positions)
        store.delete_mesh(again.mesh.name)
