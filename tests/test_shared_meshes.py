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
gives; a file moving from one kind to the other fails the test.
"""

from __future__ import annotations

import numpy as np
import pytest

from hestore import io as formats
from hestore.errors import InvalidInputError, TopologyError

from helpers import dump
from meshes import require_shared_meshes
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


def _files():
    folder = require_shared_meshes()
    found = sorted(p for p in folder.iterdir() if p.suffix.lower() in (".off", ".obj", ".ply"))
    assert len(found) >= 29, f"expected the 29 shared meshes in {folder}, found {len(found)}"
    return found


def _loops(soup):
    return [soup.indices[a:b].tolist() for a, b in zip(soup.offsets[:-1].tolist(), soup.offsets[1:].tolist())]


def _stored_loops(mesh):
    polygons = mesh.to_arrays().polygons
    return polygons.tolist() if isinstance(polygons, np.ndarray) else polygons


def test_every_shared_mesh(store):
    seen_refusing = set()
    for path in _files():
        soup = formats.read(path)
        n_polygons = len(soup.offsets) - 1
        name = path.stem
        before = dump(store)
        try:
            report = store.import_file(path, name)
        except (TopologyError, InvalidInputError) as exc:
            assert path.name in REFUSING, f"{path.name} was refused but should import: {exc}"
            seen_refusing.add(path.name)
            first = exc.skipped
            assert f"polygon {first.index}" in str(exc) and f"line {first.line}" in str(exc), str(exc)
            assert str(path) in str(exc)
            assert first.line == int(soup.lines[first.index])
            assert dump(store) == before, f"{path.name}: a refused import stored something"
            report = store.import_file(path, name, on_error="skip")
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
        assert report.vertices == len(soup.positions), "unreferenced vertices must be kept"
        assert mesh.check() == [], path.name
        if n_polygons <= SEQUENTIAL_LIMIT:
            reference, reference_skipped = sequential(soup.positions, _loops(soup))
            assert skipped == reference_skipped, path.name
            assert signature(mesh) == signature(reference), path.name
            reference.store.close()
        store.delete_mesh(name)  # keeps the store small, so the dumps above stay cheap
    assert seen_refusing == set(REFUSING)


@pytest.mark.parametrize("backend", ["sqlite"], indirect=True)
def test_export_round_trip_of_shared_meshes(store, tmp_path, backend):
    """Small representable files: export to each format and import again, same topology."""
    for path in _files():
        if path.name in REFUSING or path.stat().st_size > 1_000_000:
            continue
        mesh = store.import_file(path, path.stem).mesh
        expected = signature(mesh)
        for suffix, options in ((".off", {}), (".obj", {}), (".ply", {}), (".ply", {"binary": False})):
            out = tmp_path / f"{path.stem}{suffix}"
            mesh.export(out, **options)
            again = store.import_file(out, f"{path.stem}-again")
            assert signature(again.mesh) == expected, (path.name, suffix, options)
            np.testing.assert_array_equal(again.mesh.to_arrays().positions, mesh.to_arrays().positions)
            store.delete_mesh(again.mesh.name)
        store.delete_mesh(mesh.name)
