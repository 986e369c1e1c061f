"""The ``hestore`` command line: commands, exit status, one-line errors.

Mostly in-process through `hestore.cli.main` on a SQLite file; once as a real
process (``python -m hestore`` and the installed console script) to prove that
errors reach the user as one line, not a traceback; ``db upgrade`` from an
older schema, ``import``, ``export`` and ``info`` also on PostgreSQL. The
progress bar is tested on its own with a fake terminal and a fake clock.
"""

from __future__ import annotations

import io
import json
import os
import shutil
import struct
import subprocess
import sys
from pathlib import Path

import pytest
import sqlalchemy as sa

import hestore
from hestore import cli, migrate

IN_CI = os.environ.get("CI", "").lower() in ("1", "true", "yes")


@pytest.fixture
def url(tmp_path) -> str:
    return f"sqlite:///{tmp_path / 'cli.db'}"


def run(capsys, *argv: str) -> tuple[int, str, str]:
    code = cli.main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def assert_one_line_error(code: int, out: str, err: str) -> None:
    assert code == 2
    assert out == ""
    assert err.startswith("hestore: error: ")
    assert err.count("\n") == 1, err
    assert "Traceback" not in err


def stamp(url: str, revision: str) -> None:
    """Make `url` a database at `revision` (an older or unknown schema)."""
    engine = sa.create_engine(url, poolclass=sa.pool.NullPool)
    with engine.connect() as conn:
        migrate.upgrade(conn, "0001")
        conn.execute(sa.text("UPDATE alembic_version SET version_num = :r"), {"r": revision})
        conn.commit()
    engine.dispose()


def test_demo_twice_then_list_and_check(capsys, url):
    code, out, err = run(capsys, "--db", url, "demo")
    assert code == 0, err
    assert "created mesh 'demo'" in out
    assert "refused:" in out and "nothing changed" in out
    assert "check(): valid" in out

    code, out, err = run(capsys, "--db", url, "demo")
    assert code == 0, err
    assert "replaced mesh 'demo'" in out
    assert "check(): valid" in out

    with hestore.open(url) as store:
        assert store.meshes() == ["demo"]
        mesh = store.mesh("demo")
        counts, revision = mesh.counts(), mesh.revision
    assert counts.polygons == 9  # 5 fan triangles, a 1-gon, a 2-gon, 2 bowtie triangles

    code, out, err = run(capsys, "--db", url, "list")
    assert code == 0, err
    assert out.splitlines() == [
        f"demo  {counts.vertices} vertices, {counts.edges} edges, {counts.halfedges} half-edges, "
        f"{counts.polygons} polygons, revision {revision}"
    ]

    assert run(capsys, "--db", url, "check", "demo") == (0, "demo: valid\n", "")


def test_check_reports_violations(capsys, url):
    assert run(capsys, "--db", url, "demo")[0] == 0
    engine = sa.create_engine(url, poolclass=sa.pool.NullPool)
    with engine.begin() as conn:
        mesh_id = conn.execute(sa.text("SELECT id FROM meshes WHERE name = 'demo'")).scalar_one()
        first = conn.execute(
            sa.text("SELECT halfedge FROM polygons WHERE mesh_id = :m ORDER BY id LIMIT 1"),
            {"m": mesh_id},
        ).scalar_one()
        # A half-edge that is its own `next`: prev(next(h)) is no longer h.
        conn.execute(
            sa.text("UPDATE halfedges SET next = id WHERE mesh_id = :m AND id = :h"),
            {"m": mesh_id, "h": first},
        )
    engine.dispose()

    code, out, err = run(capsys, "--db", url, "check", "demo")
    assert code == 1, err
    lines = out.splitlines()
    assert lines[0] == f"demo: {len(lines) - 1} invariant violation(s)"
    assert any("H_NEXT_PREV" in line for line in lines[1:])


def test_list_of_an_empty_database(capsys, url):
    code, out, err = run(capsys, "--db", url, "list")
    assert (code, out) == (0, "")
    assert "no meshes" in err


def test_database_defaults_to_environment_then_current_folder(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("HESTORE_URL", raising=False)
    assert run(capsys, "db", "upgrade")[0] == 0
    assert (tmp_path / "hestore.db").is_file()

    monkeypatch.setenv("HESTORE_URL", f"sqlite:///{tmp_path / 'env.db'}")
    assert run(capsys, "demo")[0] == 0
    with hestore.open(f"sqlite:///{tmp_path / 'env.db'}") as store:
        assert store.meshes() == ["demo"]
    with hestore.open(f"sqlite:///{tmp_path / 'hestore.db'}") as store:
        assert store.meshes() == []


def test_db_commands_on_a_new_database(capsys, tmp_path):
    path = tmp_path / "new.db"
    url = f"sqlite:///{path}"
    head = migrate.head_revision()

    code, out, _ = run(capsys, "--db", url, "db", "current")
    assert code == 0
    assert out.startswith("none (no database at")
    assert not path.exists()  # asking does not create it

    code, out, _ = run(capsys, "--db", url, "db", "upgrade")
    assert (code, out) == (0, f"{url}: upgraded from an empty database to {head} (head)\n")
    assert run(capsys, "--db", url, "db", "current") == (0, f"{head} (head)\n", "")
    assert run(capsys, "--db", url, "db", "upgrade") == (0, f"{url}: already at head ({head})\n", "")
    assert run(capsys, "--db", url, "list")[0] == 0


def test_a_bare_path_means_a_sqlite_file(capsys, tmp_path):
    path = tmp_path / "bare.db"
    code, out, _ = run(capsys, "--db", str(path), "db", "upgrade")
    assert code == 0 and path.is_file()
    assert out.startswith(f"sqlite:///{path}: upgraded")
    assert run(capsys, "--db", str(path), "demo")[0] == 0
    assert run(capsys, "--db", f"sqlite:///{path}", "check", "demo")[0] == 0


def test_db_current_of_an_empty_database(capsys, url):
    sa.create_engine(url).connect().close()  # an empty file, no tables
    code, out, _ = run(capsys, "--db", url, "db", "current")
    assert code == 0
    assert out.startswith("none (empty database;")


def test_db_upgrade_from_an_older_schema(capsys, db_url):
    stamp(db_url, "0001")
    head = migrate.head_revision()

    code, out, err = run(capsys, "--db", db_url, "list")
    assert_one_line_error(code, out, err)
    assert "hestore db upgrade" in err

    code, out, _ = run(capsys, "--db", db_url, "db", "current")
    assert (code, out) == (0, f"0001 (behind head {head}: run `hestore db upgrade`)\n")

    code, out, _ = run(capsys, "--db", db_url, "db", "upgrade")
    assert code == 0
    assert out.endswith(f": upgraded from 0001 to {head} (head)\n")
    assert run(capsys, "--db", db_url, "db", "current") == (0, f"{head} (head)\n", "")
    assert run(capsys, "--db", db_url, "demo")[0] == 0
    assert run(capsys, "--db", db_url, "check", "demo")[0] == 0


def test_db_commands_on_a_newer_schema(capsys, url):
    stamp(url, "9999")
    code, out, _ = run(capsys, "--db", url, "db", "current")
    assert code == 0
    assert out.startswith("9999 (unknown to hestore")
    code, out, err = run(capsys, "--db", url, "db", "upgrade")
    assert_one_line_error(code, out, err)
    assert "newer hestore" in err


def test_db_upgrade_refuses_unversioned_tables(capsys, db_url):
    engine = sa.create_engine(db_url, poolclass=sa.pool.NullPool)
    with engine.begin() as conn:
        conn.execute(sa.text("CREATE TABLE meshes (id INTEGER PRIMARY KEY)"))
    engine.dispose()
    code, out, err = run(capsys, "--db", db_url, "db", "upgrade")
    assert_one_line_error(code, out, err)
    assert "no hestore schema version" in err


@pytest.mark.parametrize(
    "argv",
    [
        pytest.param(["--db", "nosuchdialect://host/db", "list"], id="unknown-dialect"),
        pytest.param(["--db", "://no-dialect", "list"], id="not-a-url"),
        pytest.param(["--db", "://no-dialect", "db", "current"], id="not-a-url-current"),
        pytest.param(["--db", "sqlite:///{tmp}/no/such/folder/x.db", "list"], id="unopenable-file"),
        pytest.param(["--db", "sqlite:///{tmp}/no/such/folder/x.db", "db", "upgrade"], id="unopenable-upgrade"),
        pytest.param(["--db", "sqlite:///{tmp}/ok.db", "check", "missing"], id="missing-mesh"),
    ],
)
def test_errors_are_one_line(capsys, tmp_path, argv):
    argv = [arg.replace("{tmp}", str(tmp_path)) for arg in argv]
    assert_one_line_error(*run(capsys, *argv))


def test_usage_and_version(capsys):
    assert run(capsys, "--version") == (0, f"hestore {hestore.__version__}\n", "")
    code, out, err = run(capsys)
    assert code == 2 and "COMMAND" in err
    code, out, err = run(capsys, "frobnicate")
    assert code == 2 and "invalid choice" in err
    code, out, err = run(capsys, "--help")
    assert code == 0 and "db" in out and "check" in out


def _run_process(argv: list[str], cwd: Path) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k != "HESTORE_URL"}
    return subprocess.run(argv, cwd=cwd, env=env, capture_output=True, text=True, timeout=120)


def test_python_dash_m_hestore(tmp_path):
    url = f"sqlite:///{tmp_path / 'proc.db'}"
    done = _run_process([sys.executable, "-m", "hestore", "--db", url, "demo"], tmp_path)
    assert done.returncode == 0, done.stderr
    assert "check(): valid" in done.stdout

    done = _run_process([sys.executable, "-m", "hestore", "--db", url, "check", "missing"], tmp_path)
    assert done.returncode == 2
    assert done.stdout == ""
    assert done.stderr.startswith("hestore: error: ") and done.stderr.count("\n") == 1
    assert "Traceback" not in done.stderr


def test_console_script(tmp_path):
    script = shutil.which("hestore", path=str(Path(sys.executable).parent))
    if script is None:
        message = f"no `hestore` console script next to {sys.executable}: is hestore installed?"
        if IN_CI:
            pytest.fail(message, pytrace=False)
        pytest.skip(message)
    done = _run_process([script, "--version"], tmp_path)
    assert (done.returncode, done.stdout) == (0, f"hestore {hestore.__version__}\n")
    done = _run_process([script, "list"], tmp_path)  # the default ./hestore.db
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "hestore.db").is_file()


# -- import, export, info ---------------------------------------------------------

# A unit square and a triangle glued to its right side: a quad and a triangle
# sharing the edge 1-2, so arities are mixed and one edge has two polygons.
POSITIONS = [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (1.0, 1.0, 0.0), (0.0, 1.0, 0.0), (2.0, 0.5, 0.0)]
POLYGONS = [[0, 1, 2, 3], [1, 4, 2]]

TINY_FILES = {
    "off": "OFF\n5 2 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n2 0.5 0\n4 0 1 2 3\n3 1 4 2\n",
    "obj": "# a square and a triangle\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0.5 0\nf 1 2 3 4\nf 2 5 3\n",
    "ply": (
        "ply\nformat ascii 1.0\ncomment a square and a triangle\nelement vertex 5\n"
        "property float x\nproperty float y\nproperty float z\nelement face 2\n"
        "property list uchar int vertex_indices\nend_header\n"
        "0 0 0\n1 0 0\n1 1 0\n0 1 0\n2 0.5 0\n4 0 1 2 3\n3 1 4 2\n"
    ),
}


def binary_ply(polygons: list[list[int]] = POLYGONS) -> bytes:
    header = (
        "ply\nformat binary_little_endian 1.0\nelement vertex 5\n"
        f"property float x\nproperty float y\nproperty float z\nelement face {len(polygons)}\n"
        "property list uchar int vertex_indices\nend_header\n"
    ).encode("ascii")
    body = b"".join(struct.pack("<3f", *p) for p in POSITIONS)
    body += b"".join(struct.pack(f"<B{len(p)}i", len(p), *p) for p in polygons)
    return header + body


def write_tiny(tmp_path: Path, kind: str) -> Path:
    """The square-and-triangle as a small file of the given kind."""
    if kind == "ply-binary":
        path = tmp_path / "sq.ply"
        path.write_bytes(binary_ply())
    else:
        path = tmp_path / f"sq.{kind}"
        path.write_text(TINY_FILES[kind])
    return path


def off_file(tmp_path: Path, polygons: list[list[int]], name: str = "t.off") -> Path:
    """An OFF file of the unit square's four corners and the given polygons, one per line from line 7."""
    corners = "0 0 0\n1 0 0\n1 1 0\n0 1 0\n"
    faces = "".join(f"{len(p)} {' '.join(map(str, p))}\n" for p in polygons)
    path = tmp_path / name
    path.write_text(f"OFF\n4 {len(polygons)} 0\n{corners}{faces}")
    return path


def assert_plain(err: str) -> None:
    """Progress written to a non-terminal: no carriage returns or escape sequences."""
    assert "\r" not in err and "\x1b" not in err, repr(err)


def meshes(url: str) -> list[str]:
    with hestore.open(url) as store:
        return store.meshes()


def arrays(url: str, name: str):
    with hestore.open(url) as store:
        mesh = store.mesh(name)
        return mesh.to_arrays(), mesh.counts(), mesh.check()


@pytest.mark.parametrize("kind", ["off", "obj", "ply", "ply-binary"])
def test_import_a_small_file(capsys, db_url, tmp_path, kind):
    path = write_tiny(tmp_path, kind)
    code, out, err = run(capsys, "--db", db_url, "import", str(path))
    assert code == 0, err
    assert out == f"sq: 5 vertices, 6 edges, 2 polygons from {path}\n"
    assert_plain(err)
    # The final progress line: every stage with its amount.
    assert err.startswith(f"read {path.stat().st_size} B in ") and ", build in " in err
    assert err.endswith(" s\n") and err.count("\n") == 1
    assert ", write " in err and " rows in " in err

    (positions, polygons, vertex_ids), counts, violations = arrays(db_url, "sq")
    assert violations == []
    assert (counts.vertices, counts.halfedges, counts.edges, counts.polygons) == (5, 12, 6, 2)
    assert polygons == POLYGONS
    assert positions.tolist() == [list(p) for p in POSITIONS]
    assert vertex_ids.tolist() == [0, 1, 2, 3, 4]


def test_import_under_a_name(capsys, url, tmp_path):
    path = write_tiny(tmp_path, "obj")
    code, out, err = run(capsys, "--db", url, "import", str(path), "--name", "part")
    assert code == 0, err
    assert out.startswith("part: 5 vertices")
    assert meshes(url) == ["part"]


def test_import_stops_at_a_bad_polygon_and_stores_nothing(capsys, db_url, tmp_path):
    # Polygon 2 (line 9) runs 0->1 like polygon 0: the half-edge is taken.
    path = off_file(tmp_path, [[0, 1, 2], [0, 2, 3], [0, 1, 2]])
    code, out, err = run(capsys, "--db", db_url, "import", str(path))
    assert_one_line_error(code, out, err)
    assert err.startswith(f"hestore: error: {path}:9: polygon 2: ")
    assert "0→1" in err and "nothing was stored" in err
    assert "--on-error skip" in err
    assert meshes(db_url) == []

    code, out, err = run(capsys, "--db", db_url, "import", str(path), "--on-error", "raise")
    assert_one_line_error(code, out, err)
    assert meshes(db_url) == []

    path = off_file(tmp_path, [[0, 1, 2], [0, 2, 7]], "range.off")
    code, out, err = run(capsys, "--db", db_url, "import", str(path))
    assert_one_line_error(code, out, err)
    assert err.startswith(f"hestore: error: {path}:8: polygon 1: vertex index 7 is out of range")
    assert meshes(db_url) == []

    # Binary PLY has no lines: the error names the file and the polygon.
    path = tmp_path / "range.ply"
    path.write_bytes(binary_ply([[0, 1, 2, 3], [1, 4, 9]]))
    code, out, err = run(capsys, "--db", db_url, "import", str(path))
    assert_one_line_error(code, out, err)
    assert err.startswith(f"hestore: error: {path}: polygon 1: vertex index 9 is out of range")
    assert "--on-error skip" in err
    assert meshes(db_url) == []


def test_import_can_skip_bad_polygons(capsys, db_url, tmp_path):
    path = off_file(tmp_path, [[0, 1, 2], [0, 2, 3], [0, 1, 2], [], [0, 9, 1]])
    code, out, err = run(capsys, "--db", db_url, "import", str(path), "--on-error", "skip")
    assert code == 0, err
    lines = out.splitlines()
    assert lines[0] == f"t: 4 vertices, 5 edges, 2 polygons from {path}"
    assert lines[1].startswith("skipped 3 polygon(s)")
    assert lines[2].startswith("  polygon 2 (line 9): polygon 0 already runs 0→1")
    assert lines[3].startswith("  polygon 3 (line 10): ")
    assert lines[4].startswith("  polygon 4 (line 11): vertex index 9 is out of range")
    assert len(lines) == 5
    assert_plain(err)
    assert "hestore: warning: 3 polygon(s) skipped (--on-error skip)" in err

    (_, polygons, _), counts, violations = arrays(db_url, "t")
    assert violations == [] and counts.polygons == 2
    assert polygons.tolist() == [[0, 1, 2], [0, 2, 3]]


def test_import_report_fits_on_one_screen(capsys, url, tmp_path):
    # 25 copies of one triangle: the first is kept, 24 are skipped, 20 listed.
    path = off_file(tmp_path, [[0, 1, 2]] * 25)
    code, out, err = run(capsys, "--db", url, "import", str(path), "--on-error", "skip")
    assert code == 0, err
    lines = out.splitlines()
    assert lines[1].startswith("skipped 24 polygon(s)")
    assert [line.split(":")[0] for line in lines[2:22]] == [f"  polygon {i} (line {i + 7})" for i in range(1, 21)]
    assert lines[22:] == ["  ... and 4 more"]


@pytest.mark.parametrize(
    "text, where, what",
    [
        pytest.param("OFF\n3 1 0\n0 0 0\n1 0 zz\n0 1 0\n3 0 1 2\n", "4", "'zz'", id="not-a-number"),
        pytest.param("OFF\n3 1 0\n0 0 0\n1 0 nan\n0 1 0\n3 0 1 2\n", "4", "'nan'", id="nan"),
        pytest.param("OFF\n3 1 0\n0 0 0\n1 0 0\n", "4", "ends", id="truncated"),
        pytest.param("OFF\n", "1", "", id="no-counts"),
    ],
)
def test_import_of_a_malformed_file(capsys, url, tmp_path, text, where, what):
    path = tmp_path / "bad.off"
    path.write_text(text)
    code, out, err = run(capsys, "--db", url, "import", str(path))
    assert_one_line_error(code, out, err)
    assert err.startswith(f"hestore: error: {path}:{where}: "), err
    assert what in err
    assert meshes(url) == []


def test_import_under_an_existing_name(capsys, db_url, tmp_path):
    path = write_tiny(tmp_path, "off")
    assert run(capsys, "--db", db_url, "import", str(path))[0] == 0
    with hestore.open(db_url) as store:
        revision = store.mesh("sq").revision
    code, out, err = run(capsys, "--db", db_url, "import", str(path))
    assert_one_line_error(code, out, err)
    assert "'sq' already exists" in err and "--name" in err
    code, out, err = run(capsys, "--db", db_url, "import", str(path), "--name", "sq")
    assert_one_line_error(code, out, err)
    with hestore.open(db_url) as store:
        assert store.meshes() == ["sq"]
        assert store.mesh("sq").revision == revision


@pytest.mark.parametrize(
    "name, content, message",
    [
        pytest.param("missing.off", None, "No such file or directory", id="missing"),
        pytest.param("mesh.stl", "solid x\n", "unsupported file format '.stl'", id="unknown-extension"),
        pytest.param("folder.off", "folder", "Is a directory", id="a-directory"),
    ],
)
def test_import_of_a_file_it_cannot_read(capsys, url, tmp_path, name, content, message):
    path = tmp_path / name
    if content == "folder":
        path.mkdir()
    elif content is not None:
        path.write_text(content)
    code, out, err = run(capsys, "--db", url, "import", str(path))
    assert_one_line_error(code, out, err)
    assert str(path) in err and message in err


def test_import_refuses_an_unknown_on_error(capsys, url, tmp_path):
    code, out, err = run(capsys, "--db", url, "import", str(write_tiny(tmp_path, "off")), "--on-error", "fix")
    assert code == 2 and "invalid choice" in err


@pytest.mark.parametrize(
    "filename, options",
    [
        pytest.param("out.off", [], id="off"),
        pytest.param("out.obj", [], id="obj"),
        pytest.param("out.ply", [], id="ply-binary"),
        pytest.param("out.ply", ["--ascii"], id="ply-ascii"),
    ],
)
def test_export_round_trip(capsys, db_url, tmp_path, filename, options):
    assert run(capsys, "--db", db_url, "import", str(write_tiny(tmp_path, "obj")))[0] == 0
    target = tmp_path / filename
    code, out, err = run(capsys, "--db", db_url, "export", "sq", str(target), *options)
    assert code == 0, err
    size = target.stat().st_size
    assert out == f"wrote 'sq' to {target}: 5 vertices, 2 polygons, {size} bytes\n"
    assert_plain(err)
    assert err.startswith("read in ") and ", write 7 rows in " in err  # the mesh, then 5 vertices and 2 polygons
    if filename.endswith(".ply"):
        fmt = "ascii" if options else "binary_little_endian"
        assert target.read_bytes().startswith(f"ply\nformat {fmt} 1.0\n".encode())

    code, out, err = run(capsys, "--db", db_url, "import", str(target), "--name", "again")
    assert code == 0, err
    before, counts_before, _ = arrays(db_url, "sq")
    after, counts_after, violations = arrays(db_url, "again")
    assert violations == [] and counts_after == counts_before
    assert after.polygons == before.polygons
    assert after.positions.tolist() == before.positions.tolist()
    assert after.vertex_ids.tolist() == before.vertex_ids.tolist()


def test_export_errors_are_one_line(capsys, url, tmp_path):
    assert run(capsys, "--db", url, "import", str(write_tiny(tmp_path, "off")))[0] == 0
    with hestore.open(url) as store:
        mesh = store.create_mesh("unplaced")
        mesh.add_vertex()  # no position: cannot be written to a file

    for argv, message in [
        (["export", "missing", str(tmp_path / "x.off")], "missing"),
        (["export", "sq", str(tmp_path / "x.stl")], "unsupported file format"),
        (["export", "sq", str(tmp_path / "no" / "such" / "x.off")], "No such file or directory"),
        (["export", "unplaced", str(tmp_path / "x.off")], "no position"),
    ]:
        code, out, err = run(capsys, "--db", url, *argv)
        assert_one_line_error(code, out, err)
        assert message in err, err
    assert not (tmp_path / "x.off").exists()


def test_info(capsys, db_url, tmp_path):
    assert run(capsys, "--db", db_url, "import", str(write_tiny(tmp_path, "ply")))[0] == 0
    with hestore.open(db_url) as store:
        revision = store.mesh("sq").revision
        strict = store.create_mesh("strict", allow_loops=False, allow_multi_edges=False)
        strict.add_vertex((0, 0, 0))

    code, out, err = run(capsys, "--db", db_url, "info", "sq")
    assert (code, err) == (0, "")
    assert out.splitlines() == [
        "name:            sq",
        f"revision:        {revision}",
        "self-loops:      allowed",
        "parallel edges:  allowed",
        "vertices:        5",
        "half-edges:      12",
        "edges:           6",
        "polygons:        2",
    ]

    code, out, err = run(capsys, "--db", db_url, "info", "sq", "--json")
    assert (code, err) == (0, "")
    assert json.loads(out) == {
        "name": "sq",
        "revision": revision,
        "allow_loops": True,
        "allow_multi_edges": True,
        "vertices": 5,
        "halfedges": 12,
        "edges": 6,
        "polygons": 2,
    }

    code, out, _ = run(capsys, "--db", db_url, "info", "strict")
    assert code == 0
    assert "self-loops:      forbidden" in out and "parallel edges:  forbidden" in out
    code, out, _ = run(capsys, "--db", db_url, "info", "--json", "strict")
    info = json.loads(out)
    assert (info["allow_loops"], info["allow_multi_edges"], info["vertices"], info["edges"]) == (False, False, 1, 0)

    assert_one_line_error(*run(capsys, "--db", db_url, "info", "missing"))
    assert_one_line_error(*run(capsys, "--db", db_url, "info", "missing", "--json"))


def test_help_names_the_new_commands(capsys):
    code, out, _ = run(capsys, "--help")
    assert code == 0
    assert all(word in out for word in ("import", "export", "info"))
    code, out, _ = run(capsys, "import", "--help")
    assert code == 0 and "--on-error" in out and "--name" in out
    code, out, _ = run(capsys, "export", "--help")
    assert code == 0 and "--ascii" in out
    code, out, _ = run(capsys, "info", "--help")
    assert code == 0 and "--json" in out


# -- the progress bar ---------------------------------------------------------------


class FakeTerminal(io.StringIO):
    def isatty(self) -> bool:
        return True


class FakeClock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def test_progress_bar_on_a_terminal_redraws_one_line_and_throttles():
    out, clock = FakeTerminal(), FakeClock()
    bar = cli.ProgressBar(out, units={"read": "bytes", "write": "rows"}, clock=clock)
    assert bar.tty
    for done in range(0, 1001):  # a thousand calls at one instant: one redraw
        bar("read", done * 1024, 1000 * 1024)
    assert out.getvalue().count("\r") == 1
    assert out.getvalue() == "\r" + bar.line("read", 0, 1000 * 1024)
    assert out.getvalue() == "\rread  [........................]   0%  0 B of 1000.0 KiB"

    clock.now += 0.0625
    bar("read", 512 * 1024, 1000 * 1024)
    assert out.getvalue().count("\r") == 1  # too soon
    clock.now += 0.0625
    bar("read", 512 * 1024, 1000 * 1024)
    assert out.getvalue().count("\r") == 2
    assert out.getvalue().endswith("\rread  [############............]  51%  512.0 KiB of 1000.0 KiB")

    bar("build", 0, 1)  # a new stage is shown at once, padded over the longer line before
    assert out.getvalue().count("\r") == 3
    last = out.getvalue().rsplit("\r", 1)[1]
    assert last.rstrip(" ") == "build [........................]   0%"
    assert len(last) == len("read  [############............]  51%  512.0 KiB of 1000.0 KiB")
    clock.now += 0.5
    bar("build", 1, 1)
    clock.now += 1.0
    bar("write", 2500, 10000)
    assert out.getvalue().endswith("\rwrite [######..................]  25%  2,500 of 10,000 rows")
    clock.now += 1.0
    bar("write", 10000, 10000)

    bar.close()
    text = out.getvalue()
    final = text.rsplit("\r", 1)[1]  # drawn over the bar, ended with a newline
    assert final.endswith("\n")
    assert final[:-1].rstrip(" ") == "read 512.0 KiB in 0.1 s, build in 0.5 s, write 10,000 rows in 2.0 s"
    assert text.count("\n") == 1
    bar.close()  # closing twice writes nothing more
    assert out.getvalue() == text


def test_progress_bar_elsewhere_writes_one_plain_line():
    out, clock = io.StringIO(), FakeClock()
    with cli.ProgressBar(out, units=cli._IMPORT_UNITS, clock=clock) as bar:
        assert not bar.tty
        bar("read", 10, 20)
        clock.now += 0.25
        bar("read", 20, 20)
        bar("write", 3, 3)
        assert out.getvalue() == ""  # nothing while it runs
    assert out.getvalue() == "read 20 B in 0.2 s, write 3 rows in 0.0 s\n"


def test_progress_bar_after_a_failure():
    out = FakeTerminal()
    with pytest.raises(RuntimeError):
        with cli.ProgressBar(out, clock=FakeClock()) as bar:
            bar("build", 0, 1)
            raise RuntimeError
    drawn = len("build [........................]   0%")
    assert out.getvalue().endswith("\r" + " " * drawn + "\r")  # erased, the cursor at the line's start
    assert "\n" not in out.getvalue()

    plain = io.StringIO()
    with pytest.raises(RuntimeError):
        with cli.ProgressBar(plain) as bar:
            bar("build", 0, 1)
            raise RuntimeError
    assert plain.getvalue() == ""

    quiet = io.StringIO()
    cli.ProgressBar(quiet).close()  # never called: nothing to say
    assert quiet.getvalue() == ""
