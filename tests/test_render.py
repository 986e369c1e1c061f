"""Pictures of meshes: `hestore.render.plot` / `render`, `Mesh.plot` / `Mesh.render`, ``hestore render``."""

from __future__ import annotations

import os
import struct
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
import sqlalchemy as sa

import hestore
from hestore import render as rendering
from hestore._session import identity
from hestore.cli import main

matplotlib = pytest.importorskip("matplotlib")
matplotlib.use("Agg")

from matplotlib.collections import LineCollection, PathCollection  # noqa: E402
from matplotlib.colors import to_rgba  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from matplotlib.image import imread  # noqa: E402

from meshes import corpus_files  # noqa: E402


PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
SVG = "{http://www.w3.org/2000/svg}"


@pytest.fixture
def out(tmp_path):
    """An empty folder for pictures (a SQLite store keeps its files in ``tmp_path``)."""
    folder = tmp_path / "pictures"
    folder.mkdir()
    return folder


def axes():
    return Figure(figsize=(6, 4), dpi=100).add_subplot()


def layers(ax) -> dict:
    """The artists `plot` drew, by gid (collections and images)."""
    found: dict = {}
    for artist in [*ax.collections, *ax.images]:
        found.setdefault(artist.get_gid(), []).append(artist)
    return found


def legend_texts(ax) -> list[str]:
    legend = ax.get_legend()
    return [] if legend is None else [t.get_text() for t in legend.get_texts()]


def png_size(path) -> tuple[int, int]:
    with open(path, "rb") as f:
        head = f.read(24)
    assert head[:8] == PNG_SIGNATURE
    assert head[12:16] == b"IHDR"
    return struct.unpack(">II", head[16:24])


def assert_drawn_png(path, size):
    assert png_size(path) == size
    pixels = imread(path)
    assert pixels.shape[:2] == (size[1], size[0])
    rgb = pixels[..., :3].reshape(-1, 3)
    background = rgb[0]  # a corner: the figure's background
    differs = (np.abs(rgb - background) > 0.05).any(axis=1)
    assert differs.mean() > 0.01, "the picture is (almost) all background"


def pyramid(store, name="pyramid"):
    """An open square pyramid: four triangles, one boundary loop (the square)."""
    xyz = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0.5, 0.5, 0.8)]
    return store.import_arrays(name, xyz, [[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]]).mesh


def problems(store):
    """Two triangles sharing only vertex 0 (pinched), a wire edge, an isolated vertex, one without a position."""
    xyz = [(0, 0, 0), (1, 1, 0.2), (-1, 1, 0), (-1, -1, 0), (1, -1, 0.1)]
    mesh = store.import_arrays("problems", xyz, [[0, 1, 2], [0, 3, 4]]).mesh
    mesh.add_edge(mesh.vertex(1), mesh.add_vertex((2, 2, 0)))
    mesh.add_vertex((3, -1, 0))
    mesh.add_vertex()
    return mesh


# -- files -------------------------------------------------------------------------


def test_png_of_a_small_mesh(store, out):
    mesh = pyramid(store)
    path = out / "pyramid.png"
    mesh.render(path, size=(320, 240))
    assert_drawn_png(path, (320, 240))
    assert os.listdir(out) == ["pyramid.png"]  # no temporary file left beside it


def test_svg_of_a_small_mesh(store, out):
    mesh = pyramid(store)
    path = out / "pyramid.svg"
    rendering.render(identity(mesh), str(path), size=(400, 300))
    root = ET.parse(path).getroot()
    assert root.tag == f"{SVG}svg"
    assert (root.get("width"), root.get("height")) == ("288pt", "216pt")  # 400 x 300 px at 100 dpi, in points
    # The four triangles, their edges and the boundary are vector paths.
    assert len(root.findall(f".//{SVG}path")) >= 4


def test_render_replaces_a_file_whole(store, out):
    mesh = pyramid(store)
    path = out / "p.png"
    path.write_bytes(b"old")
    mesh.render(path, size=(100, 80))
    assert png_size(path) == (100, 80)


@pytest.mark.parametrize("backend", ["sqlite"], indirect=True)
@pytest.mark.parametrize("corpus_file", corpus_files(only=["igea-subdiv1.ply"]))
def test_large_mesh_png_and_svg(corpus, corpus_file, out, backend):
    """One read of the 1.07 M-face igea scan (the read dominates), saved as PNG and as SVG.

    The scan is the corpus's (``conftest.corpus``): imported once for every test that reads it.
    """
    large_mesh = corpus.mesh(corpus_file)
    assert large_mesh.counts().polygons > rendering.MAX_POLYGONS
    stages = []
    figure = Figure(figsize=(6, 4.5), dpi=100)
    ax = rendering.plot(identity(large_mesh), figure.add_axes((0, 0, 1, 1)),
                        progress=lambda stage, done, total: stages.append(stage))
    assert {"read", "draw"} <= set(stages)
    assert "check" not in stages  # above CHECK_POLYGONS the check is skipped by default, and the note says so
    assert any("not checked" in t.get_text() for t in ax.texts if t.get_gid() == "notes")
    drawn = layers(ax)
    assert "polygons" not in drawn and len(drawn["raster"]) == 1
    figure.savefig(out / "igea.png", format="png")
    assert_drawn_png(out / "igea.png", (600, 450))
    figure.savefig(out / "igea.svg", format="svg")
    root = ET.parse(out / "igea.svg").getroot()
    # The polygons are one embedded image, not a million paths.
    assert len(root.findall(f".//{SVG}image")) == 1
    assert os.path.getsize(out / "igea.svg") < 2_000_000


# -- what is drawn -------------------------------------------------------------------


def test_highlights(store):
    mesh = problems(store)
    stats = mesh.stats()
    assert stats.pinched_vertices == 1 and stats.wire_edges == 1 and stats.isolated_vertices == 2
    ax = mesh.plot(axes())
    drawn = layers(ax)
    assert len(drawn["polygons"][0].get_paths()) == 2
    [wire] = drawn["wire_edges"]
    assert len(wire.get_segments()) == 1
    assert tuple(wire.get_colors()[0]) == to_rgba(rendering._WIRE)
    [boundary] = drawn["boundary_loops"]
    assert len(boundary.get_segments()) == 6  # both triangles' outer edges
    [pinched] = drawn["pinched_vertices"]
    np.testing.assert_allclose(pinched.get_offsets(), [[0.0, 0.0]], atol=1e-12)  # vertex 0 at the origin
    [isolated] = drawn["isolated_vertices"]
    assert len(isolated.get_offsets()) == 1  # the one with a position
    assert "violations" not in drawn
    texts = legend_texts(ax)
    assert "wire edges (1)" in texts and "pinched vertices (1)" in texts and "isolated vertices (1)" in texts
    assert not any(t.startswith("check()") for t in texts)
    notes = [t.get_text() for t in ax.texts if t.get_gid() == "notes"]
    assert notes and "1 of 8 vertices have no position" in notes[0]


def test_closed_mesh_has_no_boundary_layer(store):
    xyz = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)]
    mesh = store.import_arrays("tetra", xyz, [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]).mesh
    ax = mesh.plot(axes())
    drawn = layers(ax)
    assert set(drawn) == {"polygons"}
    assert ax.get_legend() is None
    # Shaded: a 3-D mesh's faces do not all get one colour.
    faces = drawn["polygons"][0].get_facecolors()
    assert len({tuple(np.round(c, 6)) for c in faces}) > 1


def test_planar_mesh_has_one_face_colour_and_is_seen_straight_on(store):
    xyz = [(0, 0, 5), (2, 0, 5), (2, 1, 5), (0, 1, 5)]
    mesh = store.import_arrays("flat", xyz, [[0, 1, 2], [0, 2, 3]]).mesh
    ax = mesh.plot(axes())
    polygons = layers(ax)["polygons"][0]
    assert len({tuple(c) for c in polygons.get_facecolors()}) == 1
    # Seen from above: the 2 x 1 rectangle keeps its shape on screen.
    corners = np.concatenate([p.vertices for p in polygons.get_paths()])
    extent = corners.max(axis=0) - corners.min(axis=0)
    np.testing.assert_allclose(extent, [2.0, 1.0], atol=1e-9)


def test_views(store):
    mesh = pyramid(store)
    top = layers(mesh.plot(axes(), view="top"))["polygons"][0]
    front = layers(mesh.plot(axes(), view="front"))["polygons"][0]
    on_top = np.concatenate([p.vertices for p in top.get_paths()])
    on_front = np.concatenate([p.vertices for p in front.get_paths()])
    # From the top: the unit square, the apex inside it; from the front: the apex 0.8 above the base.
    np.testing.assert_allclose([on_top.min(axis=0), on_top.max(axis=0)], [[0, 0], [1, 1]], atol=1e-9)
    np.testing.assert_allclose([on_front.min(axis=0), on_front.max(axis=0)], [[0, 0], [1, 0.8]], atol=1e-9)
    # (azimuth, elevation) as matplotlib's: (-90, 0) is the front view.
    same = layers(mesh.plot(axes(), view=(-90, 0)))["polygons"][0]
    rows = np.concatenate([p.vertices for p in same.get_paths()]).round(9) + 0.0
    np.testing.assert_array_equal(np.unique(rows, axis=0), np.unique(on_front.round(9) + 0.0, axis=0))


def test_painters_order(store):
    """Two squares, the small one above the big one: the nearer is drawn last."""
    xyz = [(0, 0, 0), (4, 0, 0), (4, 4, 0), (0, 4, 0), (1, 1, 1), (2, 1, 1), (2, 2, 1), (1, 2, 1)]
    mesh = store.import_arrays("two", xyz, [[4, 5, 6, 7], [0, 1, 2, 3]]).mesh

    def last_width(view):
        paths = layers(mesh.plot(axes(), view=view))["polygons"][0].get_paths()
        last = paths[-1].vertices
        return float(np.ptp(last[:, 0]))

    assert last_width("top") == pytest.approx(1.0)  # the small square, at z = 1, is nearer from above
    assert last_width("bottom") == pytest.approx(4.0)  # from below, the big one


def test_labels(store):
    mesh = pyramid(store)
    ax = mesh.plot(axes(), labels=True)
    labels = sorted(int(t.get_text()) for t in ax.texts if t.get_gid() == "labels")
    assert labels == [v.id for v in mesh.vertices()]
    assert not [t for t in mesh.plot(axes()).texts if t.get_gid() == "labels"]


@pytest.mark.parametrize("which", ["halfedges", "all"])
def test_halfedge_labels(store, which):
    mesh = store.import_arrays("sq", [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)], [[0, 1, 2], [0, 2, 3]]).mesh
    ax = mesh.plot(axes(), labels=which, view="top")
    texts = [t for t in ax.texts if t.get_gid() == "halfedge_labels"]
    assert sorted(int(t.get_text()) for t in texts) == [h.id for h in mesh.halfedges()]
    assert bool([t for t in ax.texts if t.get_gid() == "labels"]) == (which == "all")
    [arrows] = [c for c in ax.collections if c.get_gid() == "halfedge_labels"]
    assert len(arrows.U) == len(texts)
    for t in texts:  # each id sits on its half-edge's left, where its polygon is (or outside, if free)
        h = mesh.halfedge(int(t.get_text()))
        (ax_, ay), (bx, by) = h.origin.position[:2], h.target.position[:2]
        x, y = t.get_position()
        side = (bx - ax_) * (y - ay) - (by - ay) * (x - ax_)
        assert side > 0, (h.id, side)
    with pytest.raises(hestore.InvalidInputError, match="labels"):
        mesh.plot(axes(), labels="faces")


def test_raster_above_max_polygons(store):
    mesh = pyramid(store)
    ax = mesh.plot(axes(), max_polygons=2)
    drawn = layers(ax)
    assert "polygons" not in drawn
    [image] = drawn["raster"]
    pixels = image.get_array()
    assert (pixels[..., 3] > 0).mean() > 0.3  # the pyramid covers much of its bounding box
    assert "boundary_loops" in drawn  # highlights stay vectors
    assert any("raster" in t.get_text() for t in ax.texts if t.get_gid() == "notes")


def test_check_violations_in_red(db_url, out):
    with hestore.open(db_url) as store:
        mesh = pyramid(store)
        mesh_id, apex = mesh.id, mesh.vertex(4)
        wrong = [h for h in mesh.vertex(0).outgoing()][0].id  # a half-edge that does not leave the apex
        edge, other = mesh.edge(0), mesh.edge(1)
        other_halfedge = other.halfedge.id
    engine = sa.create_engine(db_url)
    with engine.begin() as conn:
        v, e = hestore.schema.vertices, hestore.schema.edges
        conn.execute(v.update().where((v.c.mesh_id == mesh_id) & (v.c.id == apex.id)).values(halfedge=wrong))
        # Edge 0 points at a half-edge of edge 1: an H_EDGE violation naming edge 0.
        conn.execute(e.update().where((e.c.mesh_id == mesh_id) & (e.c.id == edge.id)).values(halfedge=other_halfedge))
    engine.dispose()
    with hestore.open(db_url) as store:
        mesh = store.mesh("pyramid")
        violations = mesh.check()
        assert any(x.kind == "vertex" and x.id == apex.id for x in violations)
        ax = mesh.plot(axes())
        [marks] = [a for a in layers(ax)["violations"] if isinstance(a, PathCollection)]
        np.testing.assert_array_equal(marks.get_facecolors()[:, :3], [[1.0, 0.0, 0.0]])
        assert len(marks.get_offsets()) >= 1
        assert any(x.kind == "edge" and x.id == edge.id for x in violations)
        [lines] = [a for a in layers(ax)["violations"] if isinstance(a, LineCollection)]
        assert len(lines.get_segments()) >= 1
        np.testing.assert_array_equal(lines.get_colors()[:, :3], [[1.0, 0.0, 0.0]])
        texts = legend_texts(ax)
        assert any(t.startswith(f"check(): {len(violations)} violation") and "V_HALFEDGE" in t for t in texts)
        # check=False draws no violations even on a broken mesh.
        assert "violations" not in layers(mesh.plot(axes(), check=False))
        mesh.render(out / "broken.png", size=(200, 150))
        assert_drawn_png(out / "broken.png", (200, 150))


def test_view_of_a_past_revision(store):
    mesh = pyramid(store)
    mesh.remove_polygon(mesh.polygon(0))
    mesh.remove_polygon(mesh.polygon(1))
    old = mesh.at(1)
    now = layers(mesh.plot(axes()))["polygons"][0]
    then = layers(old.plot(axes()))["polygons"][0]
    assert len(now.get_paths()) == mesh.counts().polygons == 2
    assert len(then.get_paths()) == old.counts().polygons == 4


def test_empty_mesh(store):
    ax = store.create_mesh("empty").plot(axes())
    assert not layers(ax)
    assert any("empty" in t.get_text() for t in ax.texts)


# -- bad input ----------------------------------------------------------------------


def test_bad_paths_write_nothing(store, out):
    mesh = pyramid(store)
    with pytest.raises(hestore.InvalidInputError, match=r"\.png or \.svg"):
        mesh.render(out / "p.jpg")
    with pytest.raises(hestore.InvalidInputError, match="does not exist"):
        mesh.render(out / "missing" / "p.png")
    (out / "folder.png").mkdir()
    with pytest.raises(hestore.InvalidInputError, match="is a folder"):
        mesh.render(out / "folder.png")
    with pytest.raises(hestore.InvalidInputError):
        mesh.render(out / "p.png", size=(0, 10))
    assert sorted(os.listdir(out)) == ["folder.png"]


@pytest.mark.parametrize("size", [(10_001, 10), (10, 10_001), (100_000, 100_000), (7_000, 7_000), (40_001, 1_000)])
def test_a_picture_too_large_is_refused_before_anything_is_drawn(store, out, monkeypatch, size):
    mesh = pyramid(store)
    # Refused before the mesh is read or a figure made: nothing of the size is ever allocated.
    monkeypatch.setattr(rendering, "_draw", lambda *a, **k: pytest.fail("the picture was drawn"))
    with pytest.raises(hestore.InvalidInputError, match=r"each side 1 to 10,000 pixels and at most 40,000,000"):
        mesh.render(out / "p.png", size=size)
    assert os.listdir(out) == []
    assert rendering.MAX_SIDE == 10_000 and rendering.MAX_PIXELS == 40_000_000


def test_the_largest_picture_is_in_the_help(capsys):
    assert main(["render", "--help"]) == 0
    assert "each side at most 10,000 and 40,000,000 pixels in all" in " ".join(capsys.readouterr().out.split())


def test_unwritable_folder(store, out):
    mesh = pyramid(store)
    locked = out / "locked"
    locked.mkdir()
    locked.chmod(0o500)
    if os.geteuid() == 0:  # root writes into read-only folders; nobody creates files in sysfs
        locked = Path("/sys")
    before = sorted(os.listdir(locked))
    try:
        with pytest.raises(hestore.InvalidInputError, match="cannot write"):
            mesh.render(locked / "p.png")
        assert sorted(os.listdir(locked)) == before
    finally:
        (out / "locked").chmod(0o700)


def test_bad_arguments(store):
    mesh = pyramid(store)
    with pytest.raises(hestore.InvalidInputError, match="Axes"):
        mesh.plot(ax="not an axes")
    with pytest.raises(hestore.InvalidInputError, match="unknown view"):
        mesh.plot(axes(), view="sideways")
    with pytest.raises(hestore.InvalidInputError, match="view"):
        mesh.plot(axes(), view=(1, 2, 3))
    with pytest.raises(hestore.InvalidInputError, match="max_polygons"):
        mesh.plot(axes(), max_polygons=-1)


def test_view_of_a_pruned_revision(store, out):
    mesh = pyramid(store)
    old = mesh.at(1)
    mesh.remove_polygon(mesh.polygon(0))
    mesh.remove_polygon(mesh.polygon(1))
    mesh.prune_history(keep=1)
    with pytest.raises(hestore.RevisionNotFoundError):
        old.render(out / "old.png")
    with pytest.raises(hestore.RevisionNotFoundError):
        mesh.at(1)
    assert os.listdir(out) == []


def test_without_matplotlib(store, out, monkeypatch):
    mesh = pyramid(store)
    for name in [m for m in sys.modules if m == "matplotlib" or m.startswith("matplotlib.")]:
        monkeypatch.setitem(sys.modules, name, None)
    with pytest.raises(hestore.MissingDependencyError, match=r"hestore\[plot\]"):
        mesh.plot()
    with pytest.raises(hestore.MissingDependencyError, match=r"pip install"):
        mesh.render(out / "p.png")
    assert os.listdir(out) == []


# -- command line ----------------------------------------------------------------


@pytest.fixture
def cli_db(store, db_url):
    mesh = pyramid(store)
    mesh.remove_polygon(mesh.polygon(0))
    store.close()
    return db_url


def test_cli_render(cli_db, out, capsys):
    path = out / "p.png"
    assert main(["--db", cli_db, "render", "pyramid", str(path), "--size", "300x200", "--view", "top"]) == 0
    stdout, err = capsys.readouterr()
    assert stdout.startswith("drew 'pyramid' (3 polygons) to ")
    assert "read" in err and "write" in err  # the progress bar's final line
    assert png_size(path) == (300, 200)
    svg = out / "old.svg"
    assert main(["--db", cli_db, "render", "pyramid", str(svg), "--revision", "1", "--view", "30,20"]) == 0
    assert "at revision 1 (4 polygons)" in capsys.readouterr().out
    assert ET.parse(svg).getroot().tag == f"{SVG}svg"


@pytest.mark.parametrize(
    "argv, message",
    [
        (["render", "pyramid", "{out}/p.gif"], ".png or .svg"),
        (["render", "pyramid", "{out}/missing/p.png"], "does not exist"),
        (["render", "nosuchmesh", "{out}/p.png"], "nosuchmesh"),
        (["render", "pyramid", "{out}/p.png", "--revision", "7"], "no revision 7"),
        (["render", "pyramid", "{out}/p.png", "--view", "sideways"], "unknown view"),
        (["render", "pyramid", "{out}/p.png", "--size", "100000x100000"], "each side 1 to 10,000 pixels"),
        (["render", "pyramid", "{out}/p.png", "--size", "10001x10"], "each side 1 to 10,000 pixels"),
        (["render", "pyramid", "{out}/p.png", "--size", "8000x6000"], "at most 40,000,000 pixels"),
    ],
)
def test_cli_errors_are_one_line(cli_db, out, capsys, argv, message):
    argv = [a.replace("{out}", str(out)) for a in argv]
    assert main(["--db", cli_db, *argv]) == 2
    stdout, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("hestore: error: ") and message in lines[0], err
    assert "Traceback" not in err and stdout == ""
    assert not [n for n in os.listdir(out) if n.endswith((".png", ".gif", ".tmp"))]


def test_failed_write_leaves_nothing(store, out, monkeypatch):
    mesh = pyramid(store)
    (out / "p.png").write_bytes(b"old picture")

    def fail(self, fname, **kwargs):
        fname.write(b"half a picture")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(Figure, "savefig", fail)
    with pytest.raises(hestore.InvalidInputError, match="No space left on device"):
        mesh.render(out / "p.png")
    assert os.listdir(out) == ["p.png"]
    assert (out / "p.png").read_bytes() == b"old picture"
