"""Import with ``on_error="split"`` (issue 11): keep every well-formed polygon, on SQLite and PostgreSQL.

``split`` keeps each polygon that is well formed in itself, on copies of the
vertices where it does not fit (`hestore.build.separate`), and still skips,
with a reason, a polygon that is empty, has an index out of range or runs a
self-loop the policy forbids. Covered here:

* the shared meshes' known outcomes (non-manifold vertices and edges, a
  duplicated face, a Möbius strip cut with ``orient=True``), and that a clean
  file gives the very same tables as with ``on_error="raise"``;
* copies take their original's position and vertex properties, corner data
  (OBJ ``vt``) follows its polygon, through ``orient=True`` too;
* malformed polygons are still skipped and reported;
* properties over random soups: at the array level (`build` with
  ``split=True`` and `check_arrays`), and stored (pinches, flips, duplicates,
  extra polygons on an edge; ``orient=True`` on orientable soups): every
  well-formed polygon is stored, and its corners map back to its input loop
  through ``report.split``;
* export and re-import with ``on_error="raise"``, atomicity and argument
  checks, the ``hestore import --on-error split`` command line;
* the fallback of `build` (a fresh vertex per corner of a polygon `separate`
  could not fit): when `separate` made no copy, without leaving unused
  copies behind, and for a polygon that runs an edge twice; and that a
  polygon left out anyway does not decide the orientation of the others.
"""

from __future__ import annotations

import itertools
import pathlib

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hestore.arrays import polygon_halfedges, ragged
from hestore.build import build, separate
from hestore.errors import InvalidInputError, MeshExistsError
from hestore.io import read
from hestore.validation import check_arrays

from helpers import OCTAHEDRON, OCTAHEDRON_POSITIONS, STORED, dump, run
from test_import import soups

_names = itertools.count()


# -- helpers ------------------------------------------------------------------


def fresh(prefix: str = "soup") -> str:
    """A mesh name not used before in this test session (one per hypothesis example)."""
    return f"{prefix}{next(_names)}"


def tables(store, mesh) -> dict[str, list[tuple]]:
    """Every row the mesh has in every table, without its mesh id and name: equal for meshes stored alike."""
    rows = dump(store)
    out = {t: [r[1:] for r in rs if r[0] == mesh.id] for t, rs in rows.items() if t != "meshes"}
    out["meshes"] = [r[2:] for r in rows["meshes"] if r[0] == mesh.id]
    return out


def loops(mesh) -> list[list[int]]:
    """The stored polygons as vertex id loops, in polygon id order, each from its first corner."""
    arrays = mesh.to_arrays()
    ids = arrays.vertex_ids.tolist()
    return [[ids[i] for i in p] for p in np.asarray(arrays.polygons, dtype=object).tolist()]


def originals(split: dict[int, list[int]]) -> dict[int, int]:
    """Copy id -> the input vertex it copies: the inverse of ``report.split``."""
    return {c: v for v, copies in split.items() for c in copies}


def loops_back(report) -> list[list[int]]:
    """The stored loops, each corner renamed to the input vertex it stands for."""
    back = originals(report.split)
    return [[back.get(v, v) for v in loop] for loop in loops(report.mesh)]


def built_loops_back(built, n: int) -> list[list[int]]:
    """`loops_back` for arrays from `build`: vertex ``n + i`` stands for ``built.copied[i]``."""
    a = built.arrays
    corners = polygon_halfedges(a.he_id, a.he_next, a.p_halfedge)
    original = np.r_[np.arange(n), built.copied].astype(np.int64)[a.he_origin[corners.indices]]
    return [original[s:e].tolist() for s, e in zip(corners.offsets[:-1], corners.offsets[1:])]


def oriented(loop, flip: bool) -> list[int]:
    """A loop reversed as ``orient=True`` reverses it: it keeps its first corner."""
    return [loop[0], *loop[:0:-1]] if flip else list(loop)


def well_formed(loop, n: int, allow_loops: bool) -> bool:
    """What ``split`` keeps: not empty, every index in range, no self-loop where the policy forbids them."""
    if not loop or not all(0 <= v < n for v in loop):
        return False
    return allow_loops or all(loop[k] != loop[k - 1] for k in range(len(loop)))


def assert_copies_are_like_their_originals(report):
    arrays = report.mesh.to_arrays()
    row = {v: i for i, v in enumerate(arrays.vertex_ids.tolist())}
    for v, copies in report.split.items():
        for c in copies:
            np.testing.assert_array_equal(arrays.positions[row[c]], arrays.positions[row[v]])


# -- the shared meshes --------------------------------------------------------

# file, import options, what the report and `stats()` say, report.split (None: checked elsewhere)
SHARED = [
    pytest.param(
        "hourglass_ico.obj", {},
        dict(vertices=24, edges=60, polygons=40, euler_characteristic=4, components=2, is_closed=True,
             is_manifold=True),
        {22: [23]}, id="hourglass",
    ),
    pytest.param(
        "fan3.obj", {},
        dict(vertices=9, polygons=3, components=3, is_manifold=True, pinched_vertices=0),
        {2: [5, 7], 4: [6, 8]}, id="fan3",
    ),
    pytest.param(
        "cow.obj", {},
        dict(vertices=2904, polygons=5804, euler_characteristic=2, is_closed=True, is_manifold=True),
        {253: [2903]}, id="cow",
    ),
    pytest.param(
        "moebius.obj", {},
        dict(polygons=224, euler_characteristic=1, is_manifold=True, boundary_loops=1),
        None, id="moebius",
    ),
    pytest.param(
        "moebius.obj", {"orient": True},
        dict(polygons=224, euler_characteristic=1, pinched_vertices=0, boundary_loops=1),
        None, id="moebius-orient",
    ),
    pytest.param(
        "cube-shuffled.off", {"orient": True},
        dict(vertices=8, polygons=12, euler_characteristic=2, is_closed=True, components=1),
        {}, id="cube-shuffled-orient",
    ),
    pytest.param("joined_tetrahedra.obj", {}, dict(polygons=8, is_manifold=True), None, id="joined_tetrahedra"),
]


@pytest.mark.parametrize("name, options, expected, split", SHARED)
def test_shared_meshes_keep_every_polygon(store, meshes, name, options, expected, split):
    report = store.import_file(meshes / name, on_error="split", **options)
    mesh, stats = report.mesh, report.mesh.stats()
    seen = {k: getattr(report, k) if k in ("vertices", "edges", "polygons") else getattr(stats, k) for k in expected}
    assert seen == expected
    assert report.skipped == [] and mesh.check() == []
    assert (report.vertices, report.edges, report.polygons) == (stats.vertices, stats.edges, stats.polygons)
    if split is not None:
        assert report.split == split
    assert list(report.split) == sorted(report.split)
    copies = sorted(c for cs in report.split.values() for c in cs)
    soup = read(str(meshes / name))
    n = len(soup.positions)
    assert copies == list(range(n, report.vertices))  # every copy is new, numbered on from the input's vertices
    assert_copies_are_like_their_originals(report)
    if report.split:
        line = f"copied {len(report.split)} vertex(es) into {len(copies)} new one(s)"
        assert any(s.startswith(line) for s in report.summary().splitlines())
    else:
        assert "copied" not in report.summary()
    rows = [soup.indices[a:b].tolist() for a, b in zip(soup.offsets[:-1], soup.offsets[1:])]
    flipped = set(report.flipped)
    assert loops_back(report) == [oriented(r, i in flipped) for i, r in enumerate(rows)]


@pytest.mark.parametrize("name, kept", [("cow.obj", 5800), ("moebius.obj", 220), ("joined_tetrahedra.obj", None)])
def test_split_keeps_what_skip_leaves_out(store, meshes, name, kept):
    skip = store.import_file(meshes / name, name="skip", on_error="skip")
    split = store.import_file(meshes / name, name="split", on_error="split")
    if kept is not None:
        assert skip.polygons == kept
    assert skip.skipped and split.skipped == []
    assert split.polygons == skip.polygons + len(skip.skipped)


def test_fan3_copies_take_the_numbers_of_their_earliest_corners(store, meshes):
    # Triangles 1 and 2 run 3→5 (1-based) after triangle 0: each moves to copies of 3 and 5, in corner order.
    report = store.import_file(meshes / "fan3.obj", on_error="split")
    assert loops(report.mesh) == [[0, 2, 4], [3, 5, 6], [7, 8, 1]]
    assert report.split == {2: [5, 7], 4: [6, 8]}
    assert report.mesh.vertex(7).position == report.mesh.vertex(2).position


def test_a_moebius_strip_is_cut_to_be_oriented(store, meshes):
    report = store.import_file(meshes / "moebius.obj", on_error="split", orient=True)
    assert len(report.cut) == 7 and report.flipped and 0 not in report.flipped
    assert all(len(e) == 2 and e[0] < e[1] for e in report.cut)
    lines = report.summary().splitlines()
    assert any(s.startswith("cut 7 edge(s)") for s in lines)
    assert any(s.startswith(f"reversed {len(report.flipped)} polygon(s)") for s in lines)
    # Only the ends of cut edges are copied, and each cut edge is opened: two stored edges stand for it.
    assert set(report.split) <= {v for e in report.cut for v in e}
    back = originals(report.split)
    edges = {frozenset(pair) for loop in loops(report.mesh) for pair in zip(loop, loop[1:] + loop[:1])}
    assert report.edges == len(edges)  # no two edges join the same two vertices
    stand_for = [frozenset(back.get(v, v) for v in e) for e in edges]
    assert [stand_for.count(frozenset(e)) for e in report.cut] == [2] * len(report.cut)


@pytest.mark.parametrize("name", ["cube1.off", "sphere840.ply", "teapot.obj", "quadknot.obj"])
def test_a_clean_file_is_stored_identically_with_split(store, meshes, name):
    plain = store.import_file(meshes / name, name="plain")
    split = store.import_file(meshes / name, name="split", on_error="split")
    assert split.split == {} and split.cut == [] and split.skipped == []
    assert "copied" not in split.summary()
    assert (split.vertices, split.edges, split.polygons) == (plain.vertices, plain.edges, plain.polygons)
    assert split.properties == plain.properties
    assert tables(store, split.mesh) == tables(store, plain.mesh)


# -- copies carry their original's data; corner data follows its polygon ------

QUALITY_PLY = (
    "ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float y\nproperty float z\n"
    "property float quality\nelement face 3\nproperty list uchar int vertex_indices\nend_header\n"
    "0 0 0 0.5\n1 0 0 1.5\n0 1 0 2.5\n0 -1 0 3.5\n1 1 1 4.5\n"
    "3 0 1 2\n3 0 1 3\n3 1 0 4\n"  # the second runs 0→1 like the first: a third polygon on edge 0–1
)


def test_copies_take_position_and_vertex_properties(store, tmp_path):
    path = tmp_path / "quality.ply"
    path.write_text(QUALITY_PLY)
    report = store.import_file(path, on_error="split")
    mesh = report.mesh
    assert [(p.kind, p.name, p.dtype) for p in report.properties] == [("vertex", "quality", "float64")]
    assert report.split == {0: [5], 1: [6]} and report.vertices == 7 and report.polygons == 3
    assert loops(mesh) == [[0, 1, 2], [5, 6, 3], [1, 0, 4]]
    ids, quality = mesh.property_array("vertex", "quality")
    assert ids.tolist() == list(range(7))
    assert np.ma.getdata(quality).tolist() == [0.5, 1.5, 2.5, 3.5, 4.5, 0.5, 1.5]
    assert not np.ma.is_masked(quality)
    for v, (c,) in report.split.items():
        assert mesh.vertex(c)["quality"] == mesh.vertex(v)["quality"]
        assert mesh.vertex(c).position == mesh.vertex(v).position
    assert mesh.check() == []
    # Exported as PLY, the copies keep their values.
    again = tmp_path / "again.ply"
    mesh.export(again, binary=False)
    reread = read(str(again))
    assert reread.vertex_properties["quality"].tolist() == [0.5, 1.5, 2.5, 3.5, 4.5, 0.5, 1.5]


def _uvs(mesh) -> list[list[tuple]]:
    """Each stored polygon's corner uvs, from its first corner."""
    return [[h["uv"] for h in mesh.polygon(p).halfedges()] for p in range(mesh.counts().polygons)]


def _obj_with_uvs(path: pathlib.Path, n: int, faces: list[list[int]]) -> list[list[tuple]]:
    """An OBJ of ``n`` vertices and ``faces`` (0-based), each corner its own ``vt``; returns the uvs by face."""
    lines = [f"v {i} {i % 3} {i // 3}" for i in range(n)]
    uvs, refs, corner = [], [], 0
    for face in faces:
        ks = range(corner, corner + len(face))
        uvs.append([(k / 64, 1 - k / 64) for k in ks])
        refs.append(" ".join(f"{v + 1}/{k + 1}" for v, k in zip(face, ks)))
        corner += len(face)
    lines += [f"vt {u} {w}" for face in uvs for u, w in face]
    lines += [f"f {r}" for r in refs]
    path.write_text("\n".join(lines) + "\n")
    return uvs


def test_corner_data_follows_its_polygon_onto_copies(store, tmp_path):
    faces = [[0, 1, 2], [0, 1, 3], [2, 1, 0], [0, 2, 3]]  # a repeat of 0→1, a reversed copy of the first
    uvs = _obj_with_uvs(tmp_path / "uv.obj", 4, faces)
    report = store.import_file(tmp_path / "uv.obj", on_error="split")
    assert report.polygons == 4 and report.split and report.mesh.check() == []
    assert loops_back(report) == faces
    assert _uvs(report.mesh) == uvs


def test_corner_data_follows_a_cut_and_reversed_band(store, tmp_path):
    # A Möbius band of three quads (hestore.build.orient's example): the third turns, rung 2–5 is cut.
    band = [[0, 1, 4, 3], [1, 2, 5, 4], [2, 3, 0, 5]]
    uvs = _obj_with_uvs(tmp_path / "band.obj", 6, band)
    report = store.import_file(tmp_path / "band.obj", on_error="split", orient=True)
    assert report.flipped == [2] and report.cut == [[2, 5]]
    assert report.polygons == 3 and report.mesh.check() == []
    assert report.split == {2: [6], 5: [7]}  # the cut rung is opened at both ends
    assert loops_back(report) == [oriented(f, i == 2) for i, f in enumerate(band)]
    assert _uvs(report.mesh) == [oriented(u, i == 2) for i, u in enumerate(uvs)]
    stats = report.mesh.stats()
    assert (stats.boundary_loops, stats.pinched_vertices, stats.euler_characteristic) == (1, 0, 1)  # a disc


# -- malformed polygons are still skipped -------------------------------------


def test_malformed_polygons_are_still_skipped(store):
    positions = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, -1, 0)]
    polygons = [[0, 1, 2], [0, 1, 3], [], [0, 1, 9], [2, 2, 3], [0, 1, 2], [-1, 2, 3]]
    report = store.import_arrays("m", positions, polygons, on_error="split", allow_loops=False)
    assert [s.index for s in report.skipped] == [2, 3, 4, 6]
    reasons = [s.reason for s in report.skipped]
    assert "at least one vertex" in reasons[0]
    assert "vertex index 9 is out of range" in reasons[1]
    assert "self-loop" in reasons[2] and "does not allow" in reasons[2]
    assert "vertex index -1 is out of range" in reasons[3]
    assert all(s.line is None for s in report.skipped)
    assert report.polygons == 3 and report.mesh.check() == []
    assert loops_back(report) == [[0, 1, 2], [0, 1, 3], [0, 1, 2]]
    assert report.split and "skipped 4 polygon(s)" in report.summary()
    # Allowing self-loops, the third one is kept too.
    loose = store.import_arrays("loose", positions, polygons, on_error="split")
    assert [s.index for s in loose.skipped] == [2, 3, 6]
    assert loops_back(loose) == [[0, 1, 2], [0, 1, 3], [2, 2, 3], [0, 1, 2]]
    assert loose.mesh.check() == [] and store.meshes() == ["loose", "m"]


def test_malformed_polygons_in_a_file_are_skipped_with_their_line(store, tmp_path):
    path = tmp_path / "bad.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nv 1 1 0\nf 1 2 3\nf 1 2 4\nf 1 2 9\nf 3 2 5\n")
    report = store.import_file(path, on_error="split")
    assert [(s.index, s.line) for s in report.skipped] == [(2, 8)]
    assert "vertex index 9 is out of range" in report.skipped[0].reason  # OBJ numbers vertices from 1
    assert report.polygons == 3 and report.mesh.check() == []
    assert loops_back(report) == [[0, 1, 2], [0, 1, 3], [2, 1, 4]]
    assert report.split == {0: [5], 1: [6]}


def test_a_polygon_running_an_edge_twice_is_kept_on_copies(store):
    # A slit: 0→1 twice, 1→0 twice. `separate` copies 1 for the second pass.
    report = store.import_arrays("slit", [(0, 0, 0), (1, 0, 0)], [[0, 1, 0, 1]], on_error="split")
    assert report.skipped == [] and report.split == {1: [2]} and report.mesh.check() == []
    assert loops(report.mesh) == [[0, 1, 0, 2]]


# -- random soups, array level ------------------------------------------------


@settings(max_examples=250, deadline=None)
@given(soup=soups(), allow_loops=st.booleans())
def test_build_split_keeps_every_well_formed_polygon(soup, allow_loops):
    n, polygons = soup
    built = build(n, polygons, allow_loops=allow_loops, split=True)
    kept = [i for i, p in enumerate(polygons) if well_formed(p, n, allow_loops)]
    assert built.accepted.tolist() == kept
    assert [r.index for r in built.refused] == [i for i in range(len(polygons)) if i not in kept]
    assert check_arrays(built.arrays) == []
    assert built_loops_back(built, n) == [polygons[i] for i in kept]
    assert len(built.arrays.v_id) == n + len(built.copied)
    assert ((0 <= built.copied) & (built.copied < n)).all()
    ok = np.zeros(len(polygons), dtype=bool)
    ok[kept] = True
    renamed, copied = separate(n, ragged(polygons), ok)
    rows = [renamed.indices[renamed.offsets[i]:renamed.offsets[i + 1]].tolist() for i in kept]
    if not build(n + len(copied), rows, allow_loops=allow_loops).refused:
        # No fallback: the copies are `separate`'s, and each is a corner of a kept polygon (see
        # test_the_fallback_leaves_no_unused_copy for what the fallback does).
        assert built.copied.tolist() == copied.tolist()
        corners = built.arrays.he_origin[built.arrays.he_polygon >= 0]
        assert set(range(n, n + len(copied))) <= set(corners.tolist())
    plain = build(n, polygons, allow_loops=allow_loops)
    if [r.index for r in plain.refused] == [r.index for r in built.refused]:  # clean but for malformed ones
        assert len(built.copied) == 0
        assert all(np.array_equal(x, y) for x, y in zip(plain.arrays, built.arrays))


@settings(max_examples=250, deadline=None)
@given(soup=soups())
def test_separate_keeps_earliest_corners_on_the_original(soup):
    n, polygons = soup
    polygons = [p for p in polygons if well_formed(p, n, True)]
    renamed, copied = separate(n, ragged(polygons), np.ones(len(polygons), dtype=bool))
    idx = renamed.indices
    original = np.r_[np.arange(n), copied].astype(np.int64)[idx]
    assert original.tolist() == ragged(polygons).indices.tolist()
    firsts = [int(np.flatnonzero(idx == n + i)[0]) for i in range(len(copied))]  # each copy is used ...
    assert firsts == sorted(firsts)  # ... and numbered in order of its earliest corner
    for v in set(copied.tolist()):
        assert idx[np.flatnonzero(original == v)[0]] == v  # the earliest corner keeps the original


# -- random soups, stored -----------------------------------------------------

GRID_POSITIONS = [(float(i % 3), float(i // 3), 0.0) for i in range(9)]
GRID = [f for v in (0, 1, 3, 4) for f in ([v, v + 1, v + 4], [v, v + 4, v + 3])]  # 2 × 2 squares, 8 triangles
SHAPES = {"octahedron": (OCTAHEDRON_POSITIONS, OCTAHEDRON), "grid": (GRID_POSITIONS, GRID)}


@st.composite
def shape_soups(draw):
    """A real shape's polygons, then pinched, given extra polygons on an edge, repeated, flipped, shuffled."""
    xyz, faces = SHAPES[draw(st.sampled_from(sorted(SHAPES)))]
    positions = [tuple(map(float, p)) for p in xyz]
    polygons = [list(f) for f in faces]
    n = len(positions)
    if draw(st.booleans()):  # a second copy, glued to the first at one vertex (its own stays isolated)
        here, there = draw(st.integers(0, n - 1)), draw(st.integers(0, n - 1))
        rename = {v: v + n for v in range(n)} | {there: here}
        polygons += [[rename[v] for v in f] for f in faces]
        positions += [(x + 3.0, y, z) for x, y, z in positions]
    for k in range(draw(st.integers(0, 2))):  # a third polygon on an existing edge, either way round
        f = draw(st.sampled_from(polygons))
        i = draw(st.integers(0, len(f) - 1))
        a, b = f[i], f[(i + 1) % len(f)]
        positions.append((0.5, 0.5, 2.0 + k))
        polygons.append([a, b, len(positions) - 1] if draw(st.booleans()) else [b, a, len(positions) - 1])
    for _ in range(draw(st.integers(0, 2))):  # a repeated polygon, maybe reversed
        f = draw(st.sampled_from(polygons))
        polygons.append(f[::-1] if draw(st.booleans()) else list(f))
    flips = draw(st.lists(st.booleans(), min_size=len(polygons), max_size=len(polygons)))
    polygons = [f[::-1] if flip else f for f, flip in zip(polygons, flips)]
    order = draw(st.permutations(range(len(polygons))))
    return positions, [polygons[i] for i in order]


@settings(max_examples=25, **STORED)
@given(soup=shape_soups())
def test_split_stores_every_polygon_of_a_damaged_shape(store, soup):
    positions, polygons = soup
    report = store.import_arrays(fresh(), positions, polygons, on_error="split")
    mesh = report.mesh
    assert report.polygons == len(polygons) and report.skipped == []
    assert mesh.check() == []
    assert loops_back(report) == polygons
    copies = sorted(c for cs in report.split.values() for c in cs)
    assert copies == list(range(len(positions), report.vertices))
    assert list(report.split) == sorted(report.split) and all(v < len(positions) for v in report.split)
    assert_copies_are_like_their_originals(report)
    assert mesh.counts().vertices == report.vertices


@st.composite
def orientable_soups(draw):
    """One or two consistently oriented shapes, each polygon maybe reversed and rotated."""
    names = draw(st.sampled_from([("octahedron",), ("grid",), ("octahedron", "grid")]))
    positions, polygons = [], []
    for name in names:
        xyz, faces = SHAPES[name]
        base = len(positions)
        positions += [tuple(map(float, p)) for p in xyz]
        polygons += [[base + v for v in f] for f in faces]
    flips = draw(st.lists(st.booleans(), min_size=len(polygons), max_size=len(polygons)))
    shifts = draw(st.lists(st.integers(0, 2), min_size=len(polygons), max_size=len(polygons)))
    polygons = [(f[::-1] if flip else f) for f, flip in zip(polygons, flips)]
    return positions, [f[s:] + f[:s] for f, s in zip(polygons, shifts)], names


@settings(max_examples=15, **STORED)
@given(soup=orientable_soups())
def test_orient_with_split_is_orient_alone_on_orientable_soups(store, soup):
    positions, polygons, names = soup
    name = fresh("oriented")
    split = store.import_arrays(name + "s", positions, polygons, on_error="split", orient=True)
    plain = store.import_arrays(name + "r", positions, polygons, orient=True)
    assert split.split == {} and split.cut == [] and split.skipped == []
    assert split.flipped == plain.flipped and 0 not in split.flipped
    assert tables(store, split.mesh) == tables(store, plain.mesh)
    flipped = set(split.flipped)
    stored = loops(split.mesh)
    assert stored == [oriented(f, i in flipped) for i, f in enumerate(polygons)]
    # Consistently oriented: no directed edge twice, and each shared edge run both ways.
    directed = [pair for loop in stored for pair in zip(loop, loop[1:] + loop[:1])]
    assert len(set(directed)) == len(directed)
    undirected = {frozenset(p) for p in directed}
    assert split.edges == len(undirected)
    stats = split.mesh.stats()
    assert split.mesh.check() == [] and stats.components == len(names) and stats.is_manifold
    assert stats.is_closed == (names == ("octahedron",))


# -- round trip, atomicity, arguments -----------------------------------------


@pytest.mark.parametrize(
    "name, options, fmt",
    [
        ("hourglass_ico.obj", {}, "ply"),
        ("fan3.obj", {}, "off"),
        ("moebius.obj", {"orient": True}, "obj"),
        ("joined_tetrahedra.obj", {}, "obj"),
    ],
)
def test_an_exported_split_mesh_imports_again_without_errors(store, meshes, tmp_path, name, options, fmt):
    first = store.import_file(meshes / name, name="first", on_error="split", **options)
    path = tmp_path / f"again.{fmt}"
    first.mesh.export(path)
    again = store.import_file(path, name="again")  # on_error="raise": nothing to repair any more
    assert again.split == {} and again.skipped == []
    assert (again.vertices, again.edges, again.polygons) == (first.vertices, first.edges, first.polygons)
    assert again.mesh.counts() == first.mesh.counts()
    assert loops(again.mesh) == loops(first.mesh)
    np.testing.assert_array_equal(again.mesh.to_arrays().positions, first.mesh.to_arrays().positions)


def test_split_into_a_taken_name_stores_nothing(store, meshes):
    positions = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, -1, 0)]
    polygons = [[0, 1, 2], [0, 1, 3]]
    store.import_arrays("taken", positions, [[0, 1, 2]])
    before = dump(store)
    with pytest.raises(MeshExistsError):
        store.import_arrays("taken", positions, polygons, on_error="split")
    with pytest.raises(MeshExistsError):
        store.import_file(meshes / "fan3.obj", name="taken", on_error="split", orient=True)
    assert dump(store) == before
    report = store.import_arrays("taken", positions, polygons, on_error="split", replace=True)
    assert store.meshes() == ["taken"] and report.split == {0: [4], 1: [5]}
    assert store.mesh("taken").counts().polygons == 2 and report.mesh.check() == []


@pytest.mark.parametrize("value", ["splitt", "SPLIT", None])
def test_an_unknown_on_error_names_split(store, meshes, value):
    before = dump(store)
    with pytest.raises(InvalidInputError, match="'split'"):
        store.import_arrays("x", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [[0, 1, 2]], on_error=value)
    with pytest.raises(InvalidInputError, match="'split'"):
        store.import_file(meshes / "fan3.obj", on_error=value)
    assert dump(store) == before and store.meshes() == []


# -- the command line ---------------------------------------------------------


def test_cli_split_and_orient_a_moebius_strip(capsys, db_url, meshes):
    code, out, err = run(capsys, "--db", db_url, "import", str(meshes / "moebius.obj"), "--on-error", "split",
                         "--orient")
    assert code == 0, err
    assert "Traceback" not in err and "warning" not in err
    lines = out.splitlines()
    assert lines[0].startswith("moebius: ") and lines[0].endswith(f"224 polygons from {meshes / 'moebius.obj'}")
    assert any(s.startswith("cut 7 edge(s)") for s in lines)
    assert any(s.startswith("copied ") and " vertex(es) into " in s for s in lines)
    assert any(s.startswith("reversed ") for s in lines)


def test_cli_split_a_fan_of_three(capsys, db_url, meshes):
    code, out, err = run(capsys, "--db", db_url, "import", str(meshes / "fan3.obj"), "--on-error", "split")
    assert code == 0, err
    assert out.splitlines()[0].startswith("fan3: 9 vertices, 9 edges, 3 polygons")
    assert "copied 2 vertex(es) into 4 new one(s) so that every polygon fits: 2 → 5, 7; 4 → 6, 8" in out
    assert "Traceback" not in err and "warning" not in err
    assert run(capsys, "--db", db_url, "check", "fan3") == (0, "fan3: valid\n", "")


def test_cli_split_still_skips_a_malformed_polygon(capsys, db_url, tmp_path):
    path = tmp_path / "bad.off"
    path.write_text("OFF\n4 3 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n3 0 1 2\n3 0 1 3\n3 0 2 7\n")
    code, out, err = run(capsys, "--db", db_url, "import", str(path), "--on-error", "split")
    assert code == 0, err
    assert "hestore: warning: 1 polygon(s) skipped (--on-error split)" in err and "Traceback" not in err
    assert "skipped 1 polygon(s)" in out and "polygon 2 (line 9): vertex index 7 is out of range" in out
    assert "copied 2 vertex(es) into 2 new one(s)" in out


# -- the fallback -----------------------------------------------------------------

# Soups where `separate` copies nothing, yet a polygon does not fit: a cut use whose
# corners stay in the fan that keeps the original vertex (it is glued there through
# its other edge), so the cut edge still repeats a taken directed pair; the fallback
# gives that polygon a vertex per corner.
NO_COPY_STUCK = [
    pytest.param(3, [[0, 1, 2], [2, 1]], id="triangle-and-2gon"),
    pytest.param(5, [[0, 1, 4], [1, 2, 4], [4, 1, 0]], id="reversed-repeat-after-a-neighbour"),
    pytest.param(4, [[0, 2, 1], [3, 1, 0], [3, 0, 1]], id="reversed-neighbour"),
    pytest.param(4, [[0, 1, 2], [0, 1, 3], [1, 0, 3]], id="repeat-then-its-reverse"),
]


@pytest.mark.parametrize("n, polygons", NO_COPY_STUCK)
def test_the_fallback_works_when_separate_made_no_copy(n, polygons):
    assert len(separate(n, ragged(polygons), np.ones(len(polygons), dtype=bool))[1]) == 0
    built = build(n, polygons, split=True)
    assert built.accepted.tolist() == list(range(len(polygons))) and built.refused == []
    assert check_arrays(built.arrays) == []
    assert built_loops_back(built, n) == polygons


def test_split_import_of_a_triangle_and_a_reversed_repeat(store):
    positions = [(0, 0, 0), (1, 0, 0), (2, 0, 0), (0, 1, 0), (1, 1, 0)]
    polygons = [[0, 1, 4], [1, 2, 4], [4, 1, 0]]
    report = store.import_arrays("m", positions, polygons, on_error="split")
    assert report.polygons == 3 and report.mesh.check() == []
    assert loops_back(report) == polygons


def test_a_skipped_polygon_does_not_decide_orientation(store):
    positions = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, -1, 0)]
    clean = store.import_arrays("clean", positions, [[0, 1, 2], [0, 1, 3]], on_error="split", orient=True)
    assert clean.flipped == [1] and clean.split == {}
    report = store.import_arrays("m", positions, [[0, 1, 2], [0, 1, 3], [1, 0, 9]], on_error="split", orient=True)
    assert [s.index for s in report.skipped] == [2]
    assert report.flipped == [1] and report.split == {}
    assert tables(store, report.mesh) == tables(store, clean.mesh)


def test_the_fallback_leaves_no_unused_copy(store):
    # A triangle, then a quad running the self-loop at 0 twice and 0→1 again: separate() copies 0 once (vertex 3),
    # the quad still does not fit, and the fallback moves it onto vertices 4–7.
    positions = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]
    polygons = [[0, 1, 2], [0, 0, 0, 1]]
    report = store.import_arrays("m", positions, polygons, on_error="split")
    assert report.polygons == 2 and report.mesh.check() == []
    assert loops_back(report) == polygons
    assert report.mesh.stats().isolated_vertices == 0
    used = {v for loop in loops(report.mesh) for v in loop}
    assert {c for cs in report.split.values() for c in cs} <= used


@pytest.mark.parametrize("polygon", [[0, 1, 1, 0, 1, 1], [0, 1, 2, 0, 1, 0, 2]], ids=["with-self-loops", "loop-free"])
def test_a_polygon_running_an_edge_twice_is_kept(store, polygon):
    positions = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]
    report = store.import_arrays("m", positions, [polygon], on_error="split")
    assert report.skipped == [] and report.polygons == 1
    assert report.mesh.check() == []
    assert loops_back(report) == [polygon]
