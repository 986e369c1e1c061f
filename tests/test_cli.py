"""The ``hestore`` command line: commands, exit status, one-line errors.

Mostly in-process through `hestore.cli.main` on a SQLite file; once as a real
process (``python -m hestore`` and the installed console script) to prove that
errors reach the user as one line, not a traceback; ``db upgrade`` from an
older schema also on PostgreSQL.
"""

from __future__ import annotations

import os
import shutil
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
