"""The ``hestore`` command line: commands, exit status, one-line errors.

Mostly in-process through `hestore.cli.main` on a SQLite file; once as a real
process (``python -m hestore`` and the installed console script) to prove that
errors reach the user as one line, not a traceback; ``db upgrade`` from an
older schema, ``import``, ``export``, ``info`` and ``graph`` also on PostgreSQL
(``info`` and ``graph`` on small meshes built with the API: a wireframe with
a self-loop and parallel edges, a disc, two components, a torus, a bowtie).
The progress bar is tested on its own with a fake terminal and a fake clock.
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
from hestore import cli, migrate, progress, traversal
from hestore.cli import commands, parser, text

from helpers import run

IN_CI = os.environ.get("CI", "").lower() in ("1", "true", "yes")

#: Seconds after which a child process is taken for hung: a guard against hangs, far beyond any honest
#: run however busy the machine, never a measure of speed.
HUNG = 600


@pytest.fixture
def url(tmp_path) -> str:
    return f"sqlite:///{tmp_path / 'cli.db'}"


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
    assert run(capsys, "--db", url, "db", "upgrade")[0] == 0
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
    # New, not behind: hestore.open would create it at head, no upgrade needed.
    assert out.startswith("none: a new, empty database") and "db upgrade" not in out
    assert not path.exists()  # asking does not create it

    code, out, _ = run(capsys, "--db", url, "db", "upgrade")
    assert (code, out) == (0, f"{url}: upgraded from an empty database to {head} (head)\n")
    assert run(capsys, "--db", url, "db", "current") == (0, f"{head} (head)\n", "")
    assert run(capsys, "--db", url, "db", "upgrade") == (0, f"{url}: already at head ({head})\n", "")
    assert run(capsys, "--db", url, "list")[0] == 0


def _leaf_commands(table=parser.COMMANDS, words: tuple[str, ...] = ()):
    """The words of every command that runs (``("graph", "path")``, not ``("graph",)``)."""
    for command in table:
        if command.commands:
            yield from _leaf_commands(command.commands, (*words, command.name))
        else:
            yield (*words, command.name)


#: Commands that make a database when there is none: they can start from nothing.
CREATING = {("demo",), ("import",), ("db", "upgrade")}
#: Every other command (but ``db current``, which reads below the store), with arguments it takes:
#: each needs a database that exists, and says there is none rather than make one.
NEEDING = {
    ("list",): ["list"],
    ("info",): ["info", "cube1"],
    ("check",): ["check", "cube1"],
    ("log",): ["log", "cube1"],
    ("diff",): ["diff", "cube1", "0", "1"],
    ("export",): ["export", "cube1", "{tmp}/cube1.off"],
    ("render",): ["render", "cube1", "{tmp}/cube1.png"],
    ("graph", "components"): ["graph", "cube1", "components"],
    ("graph", "path"): ["graph", "cube1", "path", "0", "1"],
    ("graph", "neighbors"): ["graph", "cube1", "neighbors", "0"],
    ("graph", "degree-histogram"): ["graph", "cube1", "degree-histogram"],
    ("graph", "export"): ["graph", "cube1", "export", "{tmp}/cube1.graphml"],
    ("delete",): ["delete", "cube1"],
    ("rename",): ["rename", "cube1", "cube2"],
    ("copy",): ["copy", "cube1", "cube2"],
    ("undo",): ["undo", "cube1"],
    ("redo",): ["redo", "cube1"],
    ("revert",): ["revert", "cube1", "0"],
}


def test_every_command_either_creates_a_database_or_needs_one():
    assert set(_leaf_commands()) == CREATING | set(NEEDING) | {("db", "current")}


@pytest.mark.parametrize("words", sorted(NEEDING), ids=" ".join)
def test_a_command_on_a_database_that_does_not_exist_creates_nothing(capsys, tmp_path, monkeypatch, words):
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("HESTORE_URL", raising=False)
    argv = [arg.replace("{tmp}", str(tmp_path)) for arg in NEEDING[words]]
    for db, name in ((["--db", "typo.db"], "typo.db"), (["--db", "sqlite:///typo.db"], "typo.db"), ([], "hestore.db")):
        code, out, err = run(capsys, *db, *argv)
        assert_one_line_error(code, out, err)
        # It says there is none, and names the file.
        assert f"no database at sqlite:///{name}: the file {tmp_path / name} does not exist" in err, err
        assert list(tmp_path.iterdir()) == [], f"{' '.join(db + argv)} created {list(tmp_path.iterdir())}"


def test_a_command_on_an_empty_database_creates_no_tables(capsys, tmp_path):
    path = tmp_path / "empty.db"
    url = f"sqlite:///{path}"
    sa.create_engine(url).connect().close()  # an empty file: a SQLite database without tables
    code, out, err = run(capsys, "--db", url, "info", "cube1")
    assert_one_line_error(code, out, err)
    assert f"{url} has no hestore tables" in err, err
    assert migrate.database_state(url).status == "new"  # still no table
    assert run(capsys, "--db", url, "demo")[0] == 0  # a command that creates still does
    assert run(capsys, "--db", url, "check", "demo")[0] == 0


def test_open_without_create(tmp_path, db_url):
    path = tmp_path / "missing.db"
    with pytest.raises(hestore.StoreNotFoundError, match=f"the file {path} does not exist"):
        hestore.open(path, create=False)
    with pytest.raises(hestore.StoreNotFoundError, match="does not exist"):
        hestore.open(f"sqlite:///{path}", create=False)
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(hestore.StoreNotFoundError, match="no hestore tables"):
        hestore.open("sqlite://", create=False)  # in memory: new every time
    assert issubclass(hestore.StoreNotFoundError, hestore.StoreError)
    with pytest.raises(hestore.StoreNotFoundError):
        hestore.open(db_url, create=False)  # a new database: a missing file, or no tables
    assert migrate.database_state(db_url).status == "new"
    with hestore.open(db_url) as store:
        store.create_mesh("m")
    with hestore.open(db_url, create=False) as store:  # a hestore database: opened as ever
        assert store.meshes() == ["m"]


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
    assert out.startswith("none: a new, empty database") and "db upgrade" not in out


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
    assert "tables hestore did not create (meshes)" in err


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


@pytest.mark.parametrize(
    "db",
    [
        "postgresq://x/y",  # misspellings of a database hestore supports
        "postgre://me@host/meshes",
        "PostgreSQL://me@host/meshes",
        "sqlit:///meshes.db",
        "sqlite3:///meshes.db",
        "http://example.com/db",  # not a database at all
        "https://example.com/meshes.db",
        "file:///tmp/meshes.db",
        "nosuchdialect+nosuchdriver://host/db",
        "postgresql+nodriver://me@host/meshes",  # a database hestore supports, through a driver it does not
        "sqlite+nodriver:///meshes.db",
    ],
)
def test_an_unsupported_database_url_is_one_clear_line(capsys, tmp_path, monkeypatch, db):
    monkeypatch.chdir(tmp_path)
    code, out, err = run(capsys, "--db", db, "list")
    assert_one_line_error(code, out, err)
    assert "unexpected" not in err and "a bug in hestore" not in err, err
    # The same kind of line as mysql://: what is unsupported, and the spellings that work.
    assert "unsupported" in err and ("postgresql+psycopg://" in err or "sqlite:///" in err), err
    # The library says the same, typed, before any driver is looked for.
    with pytest.raises(hestore.InvalidInputError, match="unsupported") as info:
        hestore.open(db)
    assert info.value.__cause__ is None and info.value.__context__ is None
    assert str(info.value) in err
    assert list(tmp_path.iterdir()) == []


def test_a_misspelt_database_name_gets_a_suggestion(capsys):
    code, out, err = run(capsys, "--db", "postgresq://me@host/meshes", "list")
    assert_one_line_error(code, out, err)
    assert "did you mean postgresql" in err, err
    assert "did you mean sqlite" in str(pytest.raises(hestore.InvalidInputError, hestore.open, "sqlit:///m.db").value)


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
    return subprocess.run(argv, cwd=cwd, env=env, capture_output=True, text=True, timeout=HUNG)


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
    done = _run_process([script, "list"], tmp_path)  # the default ./hestore.db, which does not exist
    assert done.returncode == 2 and "does not exist" in done.stderr, done.stderr
    assert not (tmp_path / "hestore.db").exists()
    done = _run_process([script, "demo"], tmp_path)
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


def mesh_names(url: str) -> list[str]:
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
    assert mesh_names(url) == ["part"]


def test_import_stops_at_a_bad_polygon_and_stores_nothing(capsys, db_url, tmp_path):
    # Polygon 2 (line 9) runs 0->1 like polygon 0: the half-edge is taken.
    path = off_file(tmp_path, [[0, 1, 2], [0, 2, 3], [0, 1, 2]])
    code, out, err = run(capsys, "--db", db_url, "import", str(path))
    assert_one_line_error(code, out, err)
    assert err.startswith(f"hestore: error: {path}:9: polygon 2: ")
    assert "0→1" in err and "nothing was stored" in err
    assert "--on-error skip" in err
    assert mesh_names(db_url) == []

    code, out, err = run(capsys, "--db", db_url, "import", str(path), "--on-error", "raise")
    assert_one_line_error(code, out, err)
    assert mesh_names(db_url) == []

    path = off_file(tmp_path, [[0, 1, 2], [0, 2, 7]], "range.off")
    code, out, err = run(capsys, "--db", db_url, "import", str(path))
    assert_one_line_error(code, out, err)
    assert err.startswith(f"hestore: error: {path}:8: polygon 1: vertex index 7 is out of range")
    assert mesh_names(db_url) == []

    # Binary PLY has no lines: the error names the file and the polygon.
    path = tmp_path / "range.ply"
    path.write_bytes(binary_ply([[0, 1, 2, 3], [1, 4, 9]]))
    code, out, err = run(capsys, "--db", db_url, "import", str(path))
    assert_one_line_error(code, out, err)
    assert err.startswith(f"hestore: error: {path}: polygon 1: vertex index 9 is out of range")
    assert "--on-error skip" in err
    assert mesh_names(db_url) == []


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
    assert mesh_names(url) == []


@pytest.mark.parametrize("suffix", [".obj", ".off", ".ply"])
def test_import_of_what_is_not_a_mesh_file_is_refused_alike_in_every_format(capsys, url, tmp_path, suffix):
    import base64
    import random

    garbage = random.Random("cli garbage").randbytes(200_000)
    contents = {
        "garbage": garbage,  # random bytes
        "base64": base64.encodebytes(garbage),  # text, but not a mesh
        "empty": b"",
        "blank": b"\n  \n",
    }
    for stem, content in contents.items():
        path = tmp_path / f"{stem}{suffix}"
        path.write_bytes(content)
        code, out, err = run(capsys, "--db", url, "import", str(path))
        assert_one_line_error(code, out, err)
        message = err.removeprefix(f"hestore: error: {path}:").rstrip("\n")
        assert message != err.rstrip("\n"), err  # the file, then where in it
        assert message.isascii() and message.isprintable() and len(message) < 200, err
        if stem in ("empty", "blank"):
            assert "the file is empty" in message, err
    assert mesh_names(url) == []


@pytest.mark.parametrize(
    "name, content",
    [("nothing.off", "OFF\n0 0 0\n"), ("nothing.obj", "o nothing\n"), ("nothing.ply", "ply\nformat ascii 1.0\n"
     "element vertex 0\nproperty float x\nproperty float y\nelement face 0\nproperty list uchar int vertex_indices\n"
     "end_header\n")],
)
def test_a_file_that_declares_no_vertices_imports_as_an_empty_mesh_that_info_calls_empty(capsys, url, tmp_path,
                                                                                      name, content):
    path = tmp_path / name
    path.write_text(content)
    code, out, err = run(capsys, "--db", url, "import", str(path))
    assert code == 0 and "nothing: 0 vertices, 0 edges, 0 polygons" in out, (out, err)
    code, out, err = run(capsys, "--db", url, "info", "nothing")
    assert (code, err) == (0, "")
    shown = info_lines(out)
    assert shown["empty"] == "yes (no vertices: closed, manifold and genus do not apply)"
    assert "closed" not in shown and "manifold" not in shown and "genus" not in shown
    assert (shown["vertices"], shown["edges"], shown["polygons"], shown["components"]) == ("0", "0", "0", "0")
    assert out.splitlines()[-1].startswith("empty:")


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
        pytest.param("mesh.xyz", "1 2 3\n", "unsupported file format '.xyz'", id="unknown-extension"),
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
        (["export", "sq", str(tmp_path / "x.xyz")], "unsupported file format"),
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
        "name:                    sq",
        f"revision:                {revision}",
        "self-loops allowed:      yes",
        "parallel edges allowed:  yes",
        "vertices:                5",
        "isolated vertices:       0",
        "edges:                   6",
        "self-loops:              0",
        "parallel edges:          0",
        "half-edges:              12",
        "polygons:                2",
        "polygon sizes:           3: 1, 4: 1",
        "boundary edges:          5",
        "wire edges:              0",
        "boundary loops:          1",
        "components:              1",
        "Euler characteristic:    1",
        "genus:                   0",
        "pinched vertices:        0",
        "closed:                  no",
        "manifold:                yes",
    ]

    code, out, err = run(capsys, "--db", db_url, "info", "sq", "--json")
    assert (code, err) == (0, "")
    info = json.loads(out)
    assert info == {
        "name": "sq",
        "revision": revision,
        "allow_loops": True,
        "allow_multi_edges": True,
        "vertices": 5,
        "isolated_vertices": 0,
        "edges": 6,
        "loops": 0,
        "parallel_edges": 0,
        "halfedges": 12,
        "polygons": 2,
        "polygon_sizes": {"3": 1, "4": 1},  # JSON object keys are strings
        "boundary_edges": 5,
        "wire_edges": 0,
        "boundary_loops": 1,
        "components": 1,
        "euler_characteristic": 1,
        "genus": 0,
        "pinched_vertices": 0,
        "is_closed": False,
        "is_manifold": True,
    }
    assert list(info) == list(text.INFO_LABELS)  # every field has a label, in the order shown

    code, out, _ = run(capsys, "--db", db_url, "info", "strict")
    assert code == 0
    assert "self-loops allowed:      no" in out and "parallel edges allowed:  no" in out
    assert "polygon sizes:           -\n" in out
    code, out, _ = run(capsys, "--db", db_url, "info", "--json", "strict")
    info = json.loads(out)
    assert (info["allow_loops"], info["allow_multi_edges"], info["vertices"], info["edges"]) == (False, False, 1, 0)
    assert (info["isolated_vertices"], info["components"], info["polygon_sizes"]) == (1, 1, {})

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
    code, out, _ = run(capsys, "graph", "--help")
    assert code == 0 and all(word in out for word in ("components", "path", "degree-histogram", "export"))
    code, out, _ = run(capsys, "graph", "NAME", "export", "--help")
    assert code == 0 and "--kind" in out and "GraphML" in out
    from hestore import graphs

    assert traversal.KINDS == graphs.KINDS  # --kind offers every kind, the default first


# -- info on other shapes, and graph ---------------------------------------------------


def build_meshes(url: str) -> dict[str, dict[str, int]]:
    """Small meshes built with the API; returns each one's vertex ids by name.

    - ``wire``: a wireframe a-b twice (parallel edges), b-c, a self-loop at c,
      and d, isolated and without a position;
    - ``disc``: a 3×2 grid of vertices 0..5 covered by the quad 0 1 4 3 and
      the triangles 1 2 5, 1 5 4 — one boundary loop, mixed arities;
    - ``two``: two triangles that share nothing — two components;
    - ``dust``: twelve isolated vertices, the first two joined by an edge;
    - ``torus``: the 3×3 quad grid with opposite sides glued (import_arrays);
    - ``bowtie``: two triangles meeting at one vertex, which is pinched;
    - ``empty``: nothing at all.
    """
    ids: dict[str, dict[str, int]] = {}
    with hestore.open(url) as store:
        wire = store.create_mesh("wire")
        a, b, c = (wire.add_vertex(p) for p in [(0, 0, 0), (1, 0, 0), (2, 0, 0)])
        d = wire.add_vertex()
        for u, v in [(a, b), (a, b), (b, c), (c, c)]:
            wire.add_edge(u, v)
        ids["wire"] = {"a": a.id, "b": b.id, "c": c.id, "d": d.id}

        disc = store.create_mesh("disc")
        vs = [disc.add_vertex((x, y, 0)) for y in range(2) for x in range(3)]
        with store.transaction():
            for loop in ([0, 1, 4, 3], [1, 2, 5], [1, 5, 4]):
                disc.add_polygon([vs[i] for i in loop])
        ids["disc"] = {str(i): v.id for i, v in enumerate(vs)}

        two = store.create_mesh("two")
        vs = [two.add_vertex((x + 5 * k, y, 0)) for k in range(2) for x, y in [(0, 0), (1, 0), (0, 1)]]
        two.add_polygon(vs[:3])
        two.add_polygon(vs[3:])

        dust = store.create_mesh("dust")
        vs = [dust.add_vertex((i, 0, 0)) for i in range(12)]
        dust.add_edge(vs[0], vs[1])
        ids["dust"] = {str(i): v.id for i, v in enumerate(vs)}

        n = 3
        positions = [(i, j, 0) for j in range(n) for i in range(n)]
        quads = [
            [j * n + i, j * n + (i + 1) % n, ((j + 1) % n) * n + (i + 1) % n, ((j + 1) % n) * n + i]
            for j in range(n)
            for i in range(n)
        ]
        store.import_arrays("torus", positions, quads)

        bowtie = store.create_mesh("bowtie")
        vs = [bowtie.add_vertex(p) for p in [(0, 0, 0), (-1, -1, 0), (-1, 1, 0), (1, 1, 0), (1, -1, 0)]]
        bowtie.add_polygon([vs[0], vs[1], vs[2]])
        bowtie.add_polygon([vs[0], vs[3], vs[4]])

        store.create_mesh("empty")
    return ids


def stats_of(url: str, name: str) -> dict:
    with hestore.open(url) as store:
        mesh = store.mesh(name)
        return {"revision": mesh.revision, **mesh.stats().as_dict()}


def info_lines(out: str) -> dict[str, str]:
    """The text form of ``info`` as label -> value."""
    return {label: value.strip() for label, value in (line.split(":  ", 1) for line in out.splitlines())}


def test_info_of_other_shapes(capsys, db_url):
    build_meshes(db_url)
    expected = {
        # name: (vertices, isolated, edges, loops, parallel, polygons, wire, components, χ, genus, closed, manifold)
        "wire": (4, 1, 4, 1, 1, 0, 4, 2, 0, None, False, False),
        "disc": (6, 0, 8, 0, 0, 3, 0, 1, 1, 0, False, True),
        "two": (6, 0, 6, 0, 0, 2, 0, 2, 2, 0, False, True),
        "torus": (9, 0, 18, 0, 0, 9, 0, 1, 0, 1, True, True),
        "bowtie": (5, 0, 6, 0, 0, 2, 0, 1, 1, None, False, False),
        "empty": (0, 0, 0, 0, 0, 0, 0, 0, 0, 0, True, True),
    }
    fields = (
        "vertices", "isolated_vertices", "edges", "loops", "parallel_edges", "polygons", "wire_edges",
        "components", "euler_characteristic", "genus", "is_closed", "is_manifold",
    )  # fmt: skip
    for name, values in expected.items():
        code, out, err = run(capsys, "--db", db_url, "info", name, "--json")
        assert (code, err) == (0, ""), name
        info = json.loads(out)
        assert tuple(info[f] for f in fields) == values, name
        # Everything else as the API says, JSON turning the arities into strings.
        api = stats_of(db_url, name)
        api["polygon_sizes"] = {str(k): v for k, v in api["polygon_sizes"].items()}
        assert {k: v for k, v in info.items() if k in api} == api, name
        assert info["name"] == name and info["halfedges"] == 2 * info["edges"]

        code, text, err = run(capsys, "--db", db_url, "info", name)
        assert (code, err) == (0, ""), name
        lines = text.splitlines()
        shown = info_lines(text)
        assert shown["Euler characteristic"] == str(info["euler_characteristic"])
        if name == "empty":
            # Closed, manifold and of genus 0 only vacuously: the text says what the mesh is instead.
            assert len(lines) == len(info) - 2, name
            assert shown["empty"].startswith("yes (no vertices") and "closed" not in shown and "genus" not in shown
            continue
        assert len(lines) == len(info) <= 24, name  # one screen
        assert shown["closed"] == ("yes" if info["is_closed"] else "no")
        assert shown["manifold"] == ("yes" if info["is_manifold"] else "no")

    code, out, _ = run(capsys, "--db", db_url, "info", "wire")
    shown = info_lines(out)
    assert shown["genus"].startswith("- (wire edges")
    assert (shown["self-loops"], shown["parallel edges"], shown["polygon sizes"]) == ("1", "1", "-")
    code, out, _ = run(capsys, "--db", db_url, "info", "bowtie")
    assert "genus:                   - (pinched vertices)\n" in out and "pinched vertices:        1\n" in out
    code, out, _ = run(capsys, "--db", db_url, "info", "torus")
    assert "genus:                   1\n" in out and "polygon sizes:           4: 9\n" in out
    assert "boundary loops:          0\n" in out
    code, out, _ = run(capsys, "--db", db_url, "info", "disc")
    assert "polygon sizes:           3: 2, 4: 1\n" in out and "boundary loops:          1\n" in out


def test_graph_components(capsys, db_url):
    ids = build_meshes(db_url)
    w = ids["wire"]
    code, out, err = run(capsys, "--db", db_url, "graph", "wire", "components")
    assert (code, err) == (0, "")
    assert out.splitlines() == [
        "2 components of 4 vertices, the largest first:",
        f"  3 vertices (lowest id {min(w['a'], w['b'], w['c'])})",
        f"  1 vertex (lowest id {w['d']})",
    ]

    # Eleven components, ten listed: one of two vertices, then single vertices by id.
    code, out, err = run(capsys, "--db", db_url, "graph", "dust", "components")
    assert (code, err) == (0, "")
    d = ids["dust"]
    assert out.splitlines() == [
        "11 components of 12 vertices, the largest first:",
        f"  2 vertices (lowest id {d['0']})",
        *(f"  1 vertex (lowest id {d[str(i)]})" for i in range(2, 11)),
        "  ... and 1 more, of 1 vertex or fewer each",
    ]

    assert run(capsys, "--db", db_url, "graph", "two", "components")[1].splitlines()[0] == (
        "2 components of 6 vertices, the largest first:"
    )
    assert run(capsys, "--db", db_url, "graph", "disc", "components") == (
        0, f"1 component of 6 vertices:\n  6 vertices (lowest id {ids['disc']['0']})\n", "",
    )  # fmt: skip
    assert run(capsys, "--db", db_url, "graph", "empty", "components") == (0, "0 components of 0 vertices\n", "")
    assert_one_line_error(*run(capsys, "--db", db_url, "graph", "missing", "components"))


def test_graph_path(capsys, db_url):
    ids = build_meshes(db_url)
    w, g = ids["wire"], ids["disc"]
    code, out, err = run(capsys, "--db", db_url, "graph", "wire", "path", str(w["a"]), str(w["c"]))
    assert (code, err) == (0, "")
    assert out == f"path: {w['a']} {w['b']} {w['c']}\nlength: 2 edges\n"
    # Across the disc: through the quad's corner 1, not around the boundary.
    code, out, err = run(capsys, "--db", db_url, "graph", "disc", "path", str(g["0"]), str(g["5"]))
    assert (code, out) == (0, f"path: {g['0']} {g['1']} {g['5']}\nlength: 2 edges\n")
    code, out, _ = run(capsys, "--db", db_url, "graph", "disc", "path", str(g["4"]), str(g["3"]))
    assert (code, out) == (0, f"path: {g['4']} {g['3']}\nlength: 1 edge\n")
    assert run(capsys, "--db", db_url, "graph", "wire", "path", str(w["c"]), str(w["c"])) == (
        0, f"path: {w['c']}\nlength: 0 edges\n", "",
    )  # fmt: skip

    # No path: said on stdout, exit status 1.
    code, out, err = run(capsys, "--db", db_url, "graph", "wire", "path", str(w["a"]), str(w["d"]))
    assert (code, err) == (1, "")
    assert out == f"no path from vertex {w['a']} to vertex {w['d']} in 'wire': they are in different components\n"

    for a, b in [(w["a"], 99), (99, w["a"]), (-1, w["a"])]:
        code, out, err = run(capsys, "--db", db_url, "graph", "wire", "path", str(a), str(b))
        assert_one_line_error(code, out, err)
        bad = a if a != w["a"] else b
        assert f"vertex {bad} does not exist" in err, err
    code, out, err = run(capsys, "--db", db_url, "graph", "wire", "path", "a", "1")
    assert code == 2 and "invalid int value" in err
    assert_one_line_error(*run(capsys, "--db", db_url, "graph", "missing", "path", "0", "1"))


def test_graph_degree_histogram(capsys, db_url):
    build_meshes(db_url)
    # a: the two parallel edges; b: those and b-c; c: b-c and the loop, twice; d: nothing.
    assert run(capsys, "--db", db_url, "graph", "wire", "degree-histogram") == (0, "0: 1\n2: 1\n3: 2\n", "")
    assert run(capsys, "--db", db_url, "graph", "disc", "degree-histogram") == (0, "2: 3\n3: 2\n4: 1\n", "")
    assert run(capsys, "--db", db_url, "graph", "torus", "degree-histogram") == (0, "4: 9\n", "")
    code, out, err = run(capsys, "--db", db_url, "graph", "empty", "degree-histogram")
    assert (code, out) == (0, "") and "no vertices" in err
    assert_one_line_error(*run(capsys, "--db", db_url, "graph", "missing", "degree-histogram"))


def views(url: str, name: str, kind: str):
    with hestore.open(url) as store:
        return store.mesh(name).to_networkx(kind)


@pytest.mark.parametrize("kind", ["multigraph", "graph", "halfedge", "dual", None])
@pytest.mark.parametrize("name", ["wire", "disc"])
def test_graph_export_graphml(capsys, db_url, tmp_path, name, kind):
    import networkx as nx

    ids = build_meshes(db_url)
    view = views(db_url, name, kind or "multigraph")
    target = tmp_path / f"{name}.graphml"
    argv = ["--db", db_url, "graph", name, "export", str(target)] + (["--kind", kind] if kind else [])
    code, out, err = run(capsys, *argv)
    assert (code, err) == (0, ""), err
    n, m = view.number_of_nodes(), view.number_of_edges()
    assert out == (
        f"wrote the {kind or 'multigraph'} view of {name!r} to {target} (GraphML): "
        f"{n} node{'s' * (n != 1)}, {m} edge{'s' * (m != 1)}, {target.stat().st_size} bytes\n"
    )

    back = nx.read_graphml(target, node_type=int, force_multigraph=view.is_multigraph())
    assert (back.is_directed(), back.is_multigraph()) == (view.is_directed(), view.is_multigraph())
    assert sorted(back.nodes) == sorted(view.nodes)
    assert back.number_of_edges() == m
    if view.is_multigraph():  # the keys (edge or half-edge ids) survive as GraphML edge ids
        assert sorted(back.edges(keys=True)) == sorted(view.edges(keys=True))
    else:
        assert sorted(map(sorted, back.edges)) == sorted(map(sorted, view.edges))
    # Scalars are kept, None left out, tuples and lists written as JSON text.
    for node, data in view.nodes(data=True):
        for attr, value in data.items():
            if value is None:
                assert attr not in back.nodes[node]
            elif isinstance(value, (tuple, list)):
                assert json.loads(back.nodes[node][attr]) == json.loads(json.dumps(list(value)))
            else:
                assert back.nodes[node][attr] == value
    if (kind or "multigraph") == "multigraph" and name == "wire":
        w = ids["wire"]
        assert "pos" not in back.nodes[w["d"]]  # no position
        assert json.loads(back.nodes[w["b"]]["pos"]) == [1.0, 0.0, 0.0]
    for edge in view.edges(keys=True) if view.is_multigraph() else view.edges:
        data = view.edges[edge]
        got = back.edges[edge]
        assert set(got) == {attr for attr, value in data.items() if value is not None}
        for attr, value in got.items():
            if isinstance(data[attr], (tuple, list)):  # e.g. polygons (3, None) -> "[3, null]"
                assert json.loads(value) == [*data[attr]]
            else:
                assert value == data[attr]
    # The graph's own attributes: mesh, revision, kind (read_graphml adds empty defaults).
    assert {k: v for k, v in back.graph.items() if not k.endswith("_default")} == view.graph


@pytest.mark.parametrize("kind", ["multigraph", "graph", "halfedge", "dual"])
def test_graph_export_edgelist(capsys, db_url, tmp_path, kind):
    import networkx as nx

    build_meshes(db_url)
    for name in ("wire", "disc"):
        view = views(db_url, name, kind)
        target = tmp_path / f"{name}-{kind}.edgelist"
        code, out, err = run(capsys, "--db", db_url, "graph", name, "export", str(target), "--kind", kind)
        assert (code, err) == (0, ""), err
        assert out.startswith(f"wrote the {kind} view of {name!r} to {target} (edge list): ")
        cls = {(False, False): nx.Graph, (True, False): nx.MultiGraph, (True, True): nx.MultiDiGraph}[
            (view.is_multigraph(), view.is_directed())
        ]
        back = nx.read_edgelist(target, create_using=cls, nodetype=int)
        assert back.number_of_edges() == view.number_of_edges()
        # An edge list has no isolated nodes.
        assert sorted(back.nodes) == sorted(v for v in view.nodes if view.degree(v) > 0)
        # Each line is `u v {attributes}`, a multigraph's key among them as "key",
        # which read_edgelist hands to add_edge: the keys come back as keys.
        if view.is_multigraph():
            edges, expected = back.edges(keys=True, data=True), view.edges(keys=True, data=True)
        else:
            edges, expected = back.edges(data=True), view.edges(data=True)
        if not view.is_directed():  # as unordered pairs
            edges = [(min(e[:2]), max(e[:2]), *e[2:]) for e in edges]
            expected = [(min(e[:2]), max(e[:2]), *e[2:]) for e in expected]
        # The attributes too: literals, None and tuples included.
        assert sorted(edges, key=repr) == sorted(expected, key=repr)


def test_graph_export_errors(capsys, db_url, tmp_path):
    build_meshes(db_url)
    for argv, message in [
        (["graph", "wire", "export", str(tmp_path / "g.txt")], "unsupported graph file format '.txt'"),
        (["graph", "wire", "export", str(tmp_path / "g")], "unsupported graph file format (no extension)"),
        (["graph", "wire", "export", str(tmp_path / "no" / "such" / "g.graphml")], "No such file or directory"),
        (["graph", "wire", "export", str(tmp_path / "no" / "such" / "g.edgelist")], "No such file or directory"),
        (["graph", "missing", "export", str(tmp_path / "g.graphml")], "missing"),
    ]:
        code, out, err = run(capsys, "--db", db_url, *argv)
        assert_one_line_error(code, out, err)
        assert message in err, err
    assert list(tmp_path.glob("g*")) == []
    target = str(tmp_path / "g.graphml")
    code, out, err = run(capsys, "--db", db_url, "graph", "wire", "export", target, "--kind", "x")
    assert code == 2 and "invalid choice" in err
    code, out, err = run(capsys, "--db", db_url, "graph", "wire")
    assert code == 2 and "GRAPH_COMMAND" in err


def test_graph_as_a_process(tmp_path):
    # The console entry point, end to end: import a file, then ask about its graph.
    url = f"sqlite:///{tmp_path / 'proc.db'}"
    path = write_tiny(tmp_path, "off")
    command = [sys.executable, "-m", "hestore", "--db", url]
    done = _run_process([*command, "import", str(path)], tmp_path)
    assert done.returncode == 0, done.stderr
    done = _run_process([*command, "graph", "sq", "path", "0", "4"], tmp_path)
    assert (done.returncode, done.stdout, done.stderr) == (0, "path: 0 1 4\nlength: 2 edges\n", "")
    done = _run_process([*command, "graph", "sq", "path", "0", "9"], tmp_path)
    assert done.returncode == 2 and done.stdout == ""
    assert done.stderr.startswith("hestore: error: ") and done.stderr.count("\n") == 1


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
    bar = progress.ProgressBar(out, units={"read": "bytes", "write": "rows"}, clock=clock)
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
    with progress.ProgressBar(out, units=commands.IMPORT_UNITS, clock=clock) as bar:
        assert not bar.tty
        bar("read", 10, 20)
        clock.now += 0.25
        bar("read", 20, 20)
        bar("write", 3, 3)
        assert out.getvalue() == ""  # nothing while it runs
    assert out.getvalue() == "read 20 B in 0.2 s, write 3 rows in 0.0 s\n"


@pytest.mark.parametrize("terminal", [False, True])
def test_progress_bar_with_min_seconds_shows_only_long_operations(terminal):
    for seconds, shown in ((0.4, False), (1.5, True)):
        out, clock = (FakeTerminal() if terminal else io.StringIO()), FakeClock()
        with progress.ProgressBar(out, clock=clock, min_seconds=1.0) as bar:
            bar("read", 0, 1)
            clock.now += seconds
            bar("read", 1, 1)
            bar("check", 3, 3)
        assert bool(out.getvalue()) == shown, (seconds, out.getvalue())
        if shown:  # the final line (on a terminal over the bar, padded to its width)
            assert out.getvalue().rstrip(" \n").endswith(f"read in {seconds:.1f} s, check in 0.0 s")


def test_check_and_stats_report_their_stages(store):
    mesh = store.import_arrays("t", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [[0, 1, 2]]).mesh
    calls = []
    assert mesh.check(lambda *a: calls.append(a)) == []
    assert calls == [("read", 0, 1), ("read", 1, 1), ("check", 0, 3), ("check", 1, 3), ("check", 2, 3),
                     ("check", 3, 3)]
    calls.clear()
    assert mesh.stats(lambda *a: calls.append(a)).polygons == 1
    assert calls == [("read", 0, 1), ("read", 1, 1), ("stats", 0, 1), ("stats", 1, 1)]


def test_long_commands_show_progress_when_slow(db_url, capsys, monkeypatch, tmp_path):
    assert run(capsys, "--db", db_url, "demo")[0] == 0
    for argv in (["check", "demo"], ["info", "demo"], ["graph", "demo", "components"]):
        assert run(capsys, "--db", db_url, *argv)[2] == ""  # never slow enough (conftest): nothing on stderr
    monkeypatch.setattr(commands, "QUIET_SECONDS", 0.0)  # always slow enough, as if the mesh were large
    code, out, err = run(capsys, "--db", db_url, "check", "demo")
    assert (code, out) == (0, "demo: valid\n") and err.startswith("read in ") and ", check in " in err
    code, out, err = run(capsys, "--db", db_url, "info", "demo")
    assert code == 0 and "vertices" in out and err.startswith("read in ") and ", stats in " in err
    code, out, err = run(capsys, "--db", db_url, "graph", "demo", "components")
    assert code == 0 and err.startswith("read in ") and ", label in " in err
    code, out, err = run(capsys, "--db", db_url, "graph", "demo", "degree-histogram")
    assert code == 0 and err.startswith("read in ") and ", build in " in err
    code, out, err = run(capsys, "--db", db_url, "graph", "demo", "export", str(tmp_path / "g.graphml"))
    assert code == 0 and out.startswith("wrote") and ", write in " in err


def test_progress_bar_after_a_failure():
    out = FakeTerminal()
    with pytest.raises(RuntimeError):
        with progress.ProgressBar(out, clock=FakeClock()) as bar:
            bar("build", 0, 1)
            raise RuntimeError
    drawn = len("build [........................]   0%")
    assert out.getvalue().endswith("\r" + " " * drawn + "\r")  # erased, the cursor at the line's start
    assert "\n" not in out.getvalue()

    plain = io.StringIO()
    with pytest.raises(RuntimeError):
        with progress.ProgressBar(plain) as bar:
            bar("build", 0, 1)
            raise RuntimeError
    assert plain.getvalue() == ""

    quiet = io.StringIO()
    progress.ProgressBar(quiet).close()  # never called: nothing to say
    assert quiet.getvalue() == ""


# -- Ctrl-C ------------------------------------------------------------------------


def _import_is_writing(db_url: str, backend: str, application: str) -> bool:
    """Whether the import has reached its write stage (rows are flowing into the database)."""
    if backend == "sqlite":
        wal = Path(sa.make_url(db_url).database + "-wal")
        return wal.exists() and wal.stat().st_size > (1 << 20)
    engine = sa.create_engine(db_url, poolclass=sa.pool.NullPool)
    try:
        with engine.connect() as conn:
            copying = "SELECT count(*) FROM pg_stat_activity WHERE query LIKE 'COPY %' AND application_name = :a"
            return bool(conn.execute(sa.text(copying), {"a": application}).scalar())
    finally:
        engine.dispose()


@pytest.mark.slow
def test_ctrl_c_during_an_import_is_one_line_exit_130_and_stores_nothing(db_url, backend, tmp_path):
    import signal
    import time

    from meshes import require_shared_meshes

    source = require_shared_meshes() / "igea-subdiv1.ply"  # about 7 s of writing: time to interrupt it
    hestore.open(db_url).close()  # the schema exists before the import starts
    env = {k: v for k, v in os.environ.items() if k != "HESTORE_URL"}
    # The import's own connection, told apart from anything else the server runs.
    application = f"hestore-ctrl-c-{os.getpid()}-{time.monotonic_ns()}"
    cli_url = db_url if backend == "sqlite" else f"{db_url}&application_name={application}"
    proc = subprocess.Popen(
        [sys.executable, "-m", "hestore", "--db", cli_url, "import", str(source)],
        cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        # A shell without job control starts background jobs with Ctrl-C ignored, and children inherit
        # that: give the import the terminal's default, as a user's shell does.
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    try:
        deadline = time.monotonic() + HUNG
        while not _import_is_writing(db_url, backend, application):
            assert proc.poll() is None, f"the import ended before it could be interrupted: {proc.communicate()}"
            assert time.monotonic() < deadline, "the import never started writing"
            time.sleep(0.05)
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=HUNG)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, (out, err)
    assert err.startswith("hestore: interrupted") and err.count("\n") == 1, err
    assert "Traceback" not in err and out == ""
    with hestore.open(db_url) as store:  # the database opens at once, and holds nothing half-stored
        assert store.meshes() == []
        with store.session.reading() as conn:
            for table in ("vertices", "halfedges", "edges", "polygons"):
                assert conn.execute(sa.text(f"SELECT count(*) FROM {table}")).scalar() == 0
        assert store.import_arrays("after", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [[0, 1, 2]]).mesh.check() == []


#: The shared libraries a process maps while ``hestore`` imports its modules (numpy, SQLAlchemy): seen in
#: /proc/PID/maps, they say the command line's own code runs and the import is under way.
IMPORTING = ("numpy/_core/_multiarray_umath", "sqlalchemy/util/_collections_cy", "sqlalchemy/engine/_row_cy")


def _maps(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/maps").read_text()
    except OSError:  # the process is gone
        return ""


@pytest.mark.skipif(not Path("/proc/self/maps").exists(), reason="reads /proc/PID/maps (Linux)")
@pytest.mark.parametrize("entry", ["python -m hestore", "console script"])
def test_ctrl_c_while_the_command_line_starts_is_one_line_exit_130(tmp_path, entry):
    import signal
    import time

    if entry == "console script":
        script = shutil.which("hestore", path=str(Path(sys.executable).parent))
        if script is None:
            pytest.skip(f"no `hestore` console script next to {sys.executable}")
        command = [script]
    else:
        command = [sys.executable, "-m", "hestore"]
    # A named pipe nobody writes to: opening it waits for ever, so the command can only end by the interrupt,
    # whenever that comes, and the process is always there to receive it.
    fifo = tmp_path / "never.off"
    os.mkfifo(fifo)
    env = {k: v for k, v in os.environ.items() if k != "HESTORE_URL"}
    for marker in IMPORTING:
        proc = subprocess.Popen(
            [*command, "--db", str(tmp_path / "m.db"), "import", str(fifo)],
            cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),  # as a user's shell starts it
        )
        try:
            deadline = time.monotonic() + HUNG
            # Right after the import of hestore's modules starts: Python's own start-up (before any code of
            # hestore runs) is past, and most of the import is still to come.
            while marker not in _maps(proc.pid):
                assert proc.poll() is None, f"the command ended before it was interrupted: {proc.communicate()}"
                assert time.monotonic() < deadline, f"{marker} was never loaded"
                time.sleep(0.001)
            proc.send_signal(signal.SIGINT)
            out, err = proc.communicate(timeout=HUNG)
        finally:
            if proc.poll() is None:
                proc.kill()
        assert "Traceback" not in err, (marker, err)
        assert proc.returncode == 130, (marker, proc.returncode, err)
        assert err == "hestore: interrupted; the unfinished command changed nothing\n" and out == "", (marker, err)


def test_busy_timeout_reaches_the_store(capsys, db_url, tmp_path):
    import threading

    with hestore.open(db_url) as store:
        mesh = store.create_mesh("m")
        mesh.add_vertex()
        mesh.add_vertex()
    held, release, done = threading.Event(), threading.Event(), []

    def hold() -> None:
        # Another writer: a transaction on mesh m, open until released.
        with hestore.open(db_url) as other:
            with other.transaction():
                other.mesh("m").add_vertex()
                held.set()
                release.wait(HUNG)
            done.append(other.mesh("m").revision)

    holder = threading.Thread(target=hold)
    holder.start()
    try:
        assert held.wait(HUNG)
        # No wait at all: the lock is held, so the undo gives up at once and changes nothing.
        code, out, err = run(capsys, "--db", db_url, "--busy-timeout", "0", "undo", "m")
        assert_one_line_error(code, out, err)
        assert "another writer holds the lock" in err, err
        # A wait far longer than the holder takes: the undo waits for it, then goes through.
        threading.Timer(0.2, release.set).start()
        code, out, err = run(capsys, "--db", db_url, "--busy-timeout", str(HUNG), "undo", "m")
        assert code == 0, err
    finally:
        release.set()
        holder.join(HUNG)
    assert done == [3]
    assert out.startswith("m: undo of revision 3: now revision 4"), out
    with hestore.open(db_url) as store:
        assert store.mesh("m").counts().vertices == 2


@pytest.mark.parametrize("seconds", ["-1", "nan", "inf"])
def test_busy_timeout_must_be_seconds(capsys, url, seconds):
    assert run(capsys, "--db", url, "demo")[0] == 0
    code, out, err = run(capsys, "--db", url, "--busy-timeout", seconds, "list")
    assert_one_line_error(code, out, err)
    assert "busy_timeout" in err or "--busy-timeout" in err, err


def test_busy_timeout_is_in_the_help(capsys):
    code, out, _ = run(capsys, "--help")
    out = " ".join(out.split())  # argparse wraps the help to the terminal's width
    assert code == 0 and "--busy-timeout SECONDS" in out and "(default 5)" in out


def test_an_unexpected_error_is_one_line_too(capsys, url, monkeypatch):
    def broken(args):
        raise RuntimeError("something nobody expected")

    monkeypatch.setattr(commands, "cmd_list", broken)
    monkeypatch.delenv(cli.DEBUG_ENVIRONMENT, raising=False)
    code, out, err = run(capsys, "--db", url, "list")
    assert_one_line_error(code, out, err)
    assert "unexpected RuntimeError: something nobody expected" in err and cli.DEBUG_ENVIRONMENT in err


# -- properties: info, and weighted paths ---------------------------------------------


def build_weighted(url: str) -> dict[str, int]:
    """``w``: from ``a`` to ``c`` along the legs of a right triangle (9 + 12, two edges) or its
    hypotenuse (15) cut into three edges of 5, with properties of every kind; ``u`` hangs off
    ``c`` by a wire edge of length 1."""
    with hestore.open(url) as store:
        mesh = store.create_mesh("w")
        xyz = {"a": (0, 0, 0), "b": (9, 0, 0), "c": (9, 12, 0), "q": (6, 8, 0), "p": (3, 4, 0)}
        v = {name: mesh.add_vertex(position) for name, position in xyz.items()}
        mesh.add_polygon([v[n] for n in "abcqp"])
        v["u"] = mesh.add_vertex((9, 13, 0))
        wire = mesh.add_edge(v["c"], v["u"])
        mesh.add_property("vertex", "temperature", "float64", default=0.0)
        mesh.add_property("halfedge", "uv", "float64", shape=(2,))
        mesh.add_property("edge", "cost", "int64", default=1)
        mesh.add_property("edge", "tag", "str")
        mesh.add_property("edge", "toll", "float64")  # no default
        mesh.add_property("polygon", "label", "str", default="")
        with store.transaction():
            mesh.find_halfedge(v["b"], v["c"]).edge["cost"] = 5  # the legs: 1 + 5, the hypotenuse: 3
        ids = {name: vertex.id for name, vertex in v.items()}
        ids["wire"] = wire.id
        return ids


def test_info_lists_properties(capsys, db_url):
    build_weighted(db_url)
    code, out, err = run(capsys, "--db", db_url, "info", "w")
    assert (code, err) == (0, "")
    lines = out.splitlines()
    assert lines[0] == "name:                    w" and lines[20] == "manifold:                no"
    assert lines[21:] == [
        "properties:              6",
        "  vertex    temperature  float64  ()    default 0.0",
        "  halfedge  uv           float64  (2,)  no default",
        "  edge      cost         int64    ()    default 1",
        "  edge      tag          str      ()    no default",
        "  edge      toll         float64  ()    no default",
        "  polygon   label        str      ()    default ''",
    ]
    code, out, err = run(capsys, "--db", db_url, "info", "w", "--json")
    assert (code, err) == (0, "")
    info = json.loads(out)
    assert list(info) == [*text.INFO_LABELS, "properties"]
    assert info["properties"] == [
        {"kind": "vertex", "name": "temperature", "dtype": "float64", "shape": [], "default": 0.0},
        {"kind": "halfedge", "name": "uv", "dtype": "float64", "shape": [2], "default": None},
        {"kind": "edge", "name": "cost", "dtype": "int64", "shape": [], "default": 1},
        {"kind": "edge", "name": "tag", "dtype": "str", "shape": [], "default": None},
        {"kind": "edge", "name": "toll", "dtype": "float64", "shape": [], "default": None},
        {"kind": "polygon", "name": "label", "dtype": "str", "shape": [], "default": ""},
    ]
    with hestore.open(db_url) as store:
        store.mesh("w").add_property("vertex", "rgb", "int64", shape=(3,), default=(0, 0, 255))
    code, out, _ = run(capsys, "--db", db_url, "info", "w")
    assert "properties:              7\n" in out
    assert "  vertex    rgb          int64    (3,)  default (0, 0, 255)\n" in out
    assert json.loads(run(capsys, "--db", db_url, "info", "w", "--json")[1])["properties"][1] == {
        "kind": "vertex", "name": "rgb", "dtype": "int64", "shape": [3], "default": [0, 0, 255],
    }  # fmt: skip


def test_graph_path_weight(capsys, db_url):
    v = build_weighted(db_url)
    a, b, c, q, p = (v[n] for n in "abcqp")
    argv = ("--db", db_url, "graph", "w", "path", str(a), str(c))
    assert run(capsys, *argv) == (0, f"path: {a} {b} {c}\nlength: 2 edges\n", "")
    assert run(capsys, *argv, "--weight", "length") == (
        0, f"path: {a} {p} {q} {c}\nlength: 3 edges\ntotal length: 15\n", "",
    )  # fmt: skip
    assert run(capsys, *argv, "--weight", "cost") == (
        0, f"path: {a} {p} {q} {c}\nlength: 3 edges\ntotal cost: 3\n", "",
    )  # fmt: skip
    assert run(capsys, "--db", db_url, "graph", "w", "path", str(b), str(q), "--weight", "length") == (
        0, f"path: {b} {c} {q}\nlength: 2 edges\ntotal length: 17\n", "",
    )  # fmt: skip
    u = v["u"]
    assert run(capsys, "--db", db_url, "graph", "w", "path", str(u), str(p), "--weight", "length") == (
        0, f"path: {u} {c} {q} {p}\nlength: 3 edges\ntotal length: 11\n", "",
    )  # fmt: skip
    code, out, err = run(capsys, "--db", db_url, "graph", "w", "path", "--weight", "length", str(a), str(a))
    assert (code, out, err) == (0, f"path: {a}\nlength: 0 edges\ntotal length: 0\n", "")
    code, out, _ = run(capsys, "graph", "NAME", "path", "--help")
    assert code == 0 and "--weight" in out and "length" in out


def test_graph_path_bad_weight(capsys, db_url):
    v = build_weighted(db_url)
    argv = ("--db", db_url, "graph", "w", "path", str(v["a"]), str(v["c"]), "--weight")
    for weight, message in [
        ("nope", "mesh 'w' has no edge property named 'nope'; --weight takes: length, cost, toll"),
        ("tag", "edge property 'tag' of mesh 'w' is str, not a number"),
        ("uv", "has no edge property named 'uv'"),  # a half-edge property
        ("temperature", "has no edge property named 'temperature'"),
        ("toll", "cannot weigh the paths of 'w' by toll: edge 0 has no value of property 'toll', which has no default"),
    ]:
        code, out, err = run(capsys, *argv, weight)
        assert_one_line_error(code, out, err)
        assert message in err, err

    # Edges the search meets must have a weight of 0 or more.
    with hestore.open(db_url) as store:
        mesh = store.mesh("w")
        mesh.set_position(mesh.vertex(v["u"]), None)
        mesh.edge(v["wire"])["cost"] = -2
    back = ("--db", db_url, "graph", "w", "path", str(v["c"]), str(v["a"]), "--weight")  # meets the wire first
    code, out, err = run(capsys, *back, "length")
    assert_one_line_error(code, out, err)
    assert f"edge {v['wire']} has no length: vertex {v['u']} has no position" in err, err
    code, out, err = run(capsys, *back, "cost")
    assert_one_line_error(code, out, err)
    assert f"edge {v['wire']} has a negative cost (-2)" in err, err


# -- history: log, diff, undo, redo, revert, copy --revision, export --revision ------------

SQUARE = ([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)], [[0, 1, 2], [0, 2, 3]])


def build_history(url: str) -> None:
    """Mesh "sq": revision 1 its import, 2 a corner lifted (with a message), 3 a vertex added."""
    with hestore.open(url) as store:
        mesh = store.import_arrays("sq", *SQUARE).mesh
        with store.transaction(message="lift a corner"):
            mesh.set_position(mesh.vertex(2), (1.0, 1.0, 1.0))
        mesh.add_vertex((5.0, 5.0, 5.0))


def log_lines(out: str) -> list[tuple[int, str, str]]:
    """``(number, time, rest)`` of each line of ``log``."""
    rows = []
    for line in out.splitlines():
        number, date, clock, utc, rest = line.split(maxsplit=4)
        assert utc == "UTC" and len(date) == 10 and len(clock) == 8, line
        rows.append((int(number), f"{date} {clock}", rest))
    return rows


def test_log(capsys, db_url):
    build_history(db_url)
    code, out, err = run(capsys, "--db", db_url, "log", "sq")
    assert code == 0 and err == "", err
    rows = log_lines(out)
    assert [n for n, _, _ in rows] == [3, 2, 1]
    assert [rest for _, _, rest in rows] == [
        "+1 vertex",
        "~1 vertex  lift a corner",
        "+4 vertex, +10 halfedge, +5 edge, +2 polygon",
    ]
    times = [t for _, t, _ in rows]
    assert times == sorted(times, reverse=True)
    code, out, err = run(capsys, "--db", db_url, "log", "sq", "--limit", "2")
    assert code == 0 and [n for n, _, _ in log_lines(out)] == [3, 2]
    # a mesh without history says so
    with hestore.open(db_url) as store:
        bare = store.create_mesh("bare", history=False)
        bare.add_vertex()
    code, out, err = run(capsys, "--db", db_url, "log", "bare")
    assert (code, out) == (0, "mesh 'bare' is at revision 1 and keeps no history\n")


def test_log_limit_zero_prints_nothing(capsys, url):
    build_history(url)
    code, out, err = run(capsys, "--db", url, "log", "sq", "--limit", "0")
    assert code == 0 and "keeps no history" not in out


def test_diff(capsys, db_url):
    build_history(db_url)
    code, out, err = run(capsys, "--db", db_url, "diff", "sq", "1", "3")
    assert code == 0, err
    assert out.splitlines() == [
        "sq: revision 1 → 3: +1 ~1 vertex",
        "  created vertex 4",
        "  changed vertex 2",
    ]
    code, out, err = run(capsys, "--db", db_url, "diff", "sq", "3", "1")
    assert code == 0 and out.splitlines() == [
        "sq: revision 3 → 1: −1 ~1 vertex",
        "  removed vertex 4",
        "  changed vertex 2",
    ]
    code, out, err = run(capsys, "--db", db_url, "diff", "sq", "2", "2")
    assert (code, out) == (0, "sq: revision 2 → 2: no change\n")
    code, out, err = run(capsys, "--db", db_url, "diff", "sq", "0", "1")
    assert code == 0 and out.splitlines()[0] == "sq: revision 0 → 1: +4 vertex, +10 halfedge, +5 edge, +2 polygon"
    assert out.splitlines()[2] == "  created halfedge 0, 1, 2, 3, 4, 5, 6, 7, 8, 9"


def test_diff_lists_at_most_twenty_ids(capsys, url):
    with hestore.open(url) as store:
        mesh = store.create_mesh("many")
        with store.transaction():
            for _ in range(25):
                mesh.add_vertex()
    code, out, err = run(capsys, "--db", url, "diff", "many", "0", "1")
    assert code == 0
    assert out.splitlines()[1] == "  created vertex " + ", ".join(map(str, range(20))) + ", ..."


def test_undo_redo_revert(capsys, db_url):
    build_history(db_url)
    code, out, err = run(capsys, "--db", db_url, "undo", "sq")
    assert (code, err) == (0, "")
    assert out == "sq: undo of revision 3: now revision 4 (−1 vertex)\n"
    code, out, err = run(capsys, "--db", db_url, "undo", "sq")
    assert out == "sq: undo of revision 2: now revision 5 (~1 vertex)\n"
    with hestore.open(db_url) as store:
        mesh = store.mesh("sq")
        assert mesh.counts().vertices == 4 and mesh.vertex(2).position == (1.0, 1.0, 0.0)
    code, out, err = run(capsys, "--db", db_url, "redo", "sq")
    assert out == "sq: redo of revision 2: now revision 6 (~1 vertex)\n"
    code, out, err = run(capsys, "--db", db_url, "revert", "sq", "3")
    assert out == "sq: revert to revision 3: now revision 7 (+1 vertex)\n"
    with hestore.open(db_url) as store:
        mesh = store.mesh("sq")
        assert mesh.revision == 7 and mesh.vertex(4).position == (5.0, 5.0, 5.0)
        assert mesh.vertex(2).position == (1.0, 1.0, 1.0) and mesh.check() == []
    code, out, err = run(capsys, "--db", db_url, "revert", "sq", "0")
    assert out == "sq: revert to revision 0: now revision 8 (−5 vertex, −10 halfedge, −5 edge, −2 polygon)\n"
    code, out, err = run(capsys, "--db", db_url, "log", "sq", "--limit", "3")
    assert [rest.split("  ")[-1] for _, _, rest in log_lines(out)] == [
        "revert to revision 0", "revert to revision 3", "redo of revision 2",
    ]


def test_copy_and_export_at_a_revision(capsys, db_url, tmp_path):
    build_history(db_url)
    code, out, err = run(capsys, "--db", db_url, "copy", "sq", "flat", "--revision", "1")
    assert code == 0, err
    assert out == "copied mesh 'sq' to 'flat': 4 vertices, 5 edges, 2 polygons\n"
    target = tmp_path / "at2.off"
    code, out, err = run(capsys, "--db", db_url, "export", "sq", str(target), "--revision", "2")
    assert code == 0, err
    assert out == f"wrote 'sq' at revision 2 to {target}: 4 vertices, 2 polygons, {target.stat().st_size} bytes\n"
    now = tmp_path / "now.off"
    assert run(capsys, "--db", db_url, "export", "sq", str(now))[0] == 0
    assert target.read_bytes() != now.read_bytes()  # revision 3 has one more vertex
    with hestore.open(db_url) as store:
        flat = store.mesh("flat")
        assert flat.revision == 1 and flat.vertex(2).position == (1.0, 1.0, 0.0)
        assert flat.history()[0].message == "copy of 'sq' at revision 1"
        again = store.import_file(target, "again").mesh
        assert again.to_arrays().positions.tolist() == store.mesh("sq").at(2).to_arrays().positions.tolist()


def test_history_command_errors_are_one_line(capsys, url, tmp_path):
    build_history(url)
    with hestore.open(url) as store:
        store.create_mesh("bare", history=False).add_vertex()
        store.create_mesh("new")
    for argv, message in [
        (["log", "missing"], "missing"),
        (["log", "sq", "--limit", "-1"], "limit"),
        (["diff", "sq", "1", "9"], "no revision 9"),
        (["diff", "sq", "-1", "2"], "no revision -1"),
        (["diff", "missing", "1", "2"], "missing"),
        (["diff", "bare", "0", "1"], "no history"),
        (["undo", "new"], "nothing to undo"),
        (["undo", "bare"], "nothing to undo"),
        (["redo", "sq"], "nothing to redo"),
        (["revert", "sq", "4"], "no revision 4"),
        (["revert", "bare", "0"], "no history"),
        (["copy", "sq", "x", "--revision", "7"], "no revision 7"),
        (["export", "sq", str(tmp_path / "x.off"), "--revision", "9"], "no revision 9"),
        (["export", "bare", str(tmp_path / "x.off"), "--revision", "0"], "no history"),
    ]:
        code, out, err = run(capsys, "--db", url, *argv)
        assert_one_line_error(code, out, err)
        assert message in err, (argv, err)
    assert not (tmp_path / "x.off").exists()
    with hestore.open(url) as store:
        assert store.meshes() == ["bare", "new", "sq"] and store.mesh("sq").revision == 3
    # argparse refuses what is not a number: a usage error, status 2
    for argv in (["diff", "sq", "one", "2"], ["revert", "sq", "1.5"], ["log", "sq", "--limit", "x"]):
        code, out, err = run(capsys, "--db", url, *argv)
        assert code == 2 and out == "" and "invalid int value" in err


def test_help_names_the_history_commands(capsys):
    code, out, _ = run(capsys, "--help")
    assert code == 0 and all(word in out for word in ("log", "diff", "undo", "redo", "revert"))
    code, out, _ = run(capsys, "export", "--help")
    assert code == 0 and "--revision" in out
