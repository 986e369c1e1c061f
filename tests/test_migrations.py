"""Schema migrations: the Alembic revisions build exactly `hestore.schema`.

Runs on SQLite and PostgreSQL (the ``db_url`` fixture). Where these tests fail
after a schema change, ``docs/migrations.md`` says what is missing.
"""

from __future__ import annotations

from pathlib import Path

import pytest
import sqlalchemy as sa
from alembic import command
from alembic.autogenerate import compare_metadata
from alembic.migration import MigrationContext

import hestore
from hestore import migrate, schema

TABLES = {"meshes", "vertices", "halfedges", "edges", "polygons"}
ELEMENT_TABLES = TABLES - {"meshes"}
INDEXES = {"ix_halfedges_origin", "ix_halfedges_polygon"}


@pytest.fixture
def engine(db_url):
    engine = sa.create_engine(db_url, poolclass=sa.pool.NullPool)
    yield engine
    engine.dispose()


def _differences(conn: sa.Connection) -> list:
    return compare_metadata(MigrationContext.configure(conn), schema.metadata)


def _index_names(conn: sa.Connection) -> set[str]:
    return {ix["name"] for ix in sa.inspect(conn).get_indexes("halfedges")}


def test_head_revision_is_schema_revision():
    assert migrate.head_revision() == schema.SCHEMA_REVISION


def test_history_is_one_line_of_numbered_revisions():
    # Numbered 0001, 0002, ... in order, one file each, named after the id.
    revisions = migrate.revisions()
    assert revisions == [f"{n:04d}" for n in range(1, len(revisions) + 1)]
    assert revisions[-1] == migrate.head_revision()
    location = Path(migrate.script_location())
    assert (location / "env.py").is_file()
    files = sorted(p.name for p in (location / "versions").glob("*.py"))
    assert [name[:4] for name in files] == revisions


def test_upgrade_in_steps_then_open(db_url, engine):
    with engine.connect() as conn:
        assert migrate.current_revision(conn) is None
        migrate.upgrade(conn, "0001")
        assert migrate.current_revision(conn) == "0001"
        assert TABLES <= set(sa.inspect(conn).get_table_names())
        assert _index_names(conn) == set()

        migrate.upgrade(conn)
        assert migrate.current_revision(conn) == migrate.head_revision()
        assert _index_names(conn) == INDEXES

    with hestore.open(db_url) as store:
        mesh = store.create_mesh("m")
        a, b, c = (mesh.add_vertex((x, y, 0.0)) for x, y in [(0, 0), (1, 0), (0, 1)])
        mesh.add_polygon([a, b, c])
        assert mesh.counts().polygons == 1
        assert mesh.check() == []


def test_head_matches_schema(engine, backend):
    with engine.connect() as conn:
        migrate.upgrade(conn)
        assert _differences(conn) == []
        if backend == "sqlite":
            sql = dict(
                conn.execute(sa.text("SELECT name, sql FROM sqlite_master WHERE type = 'table'")).all()
            )
            for table in ELEMENT_TABLES:
                assert "WITHOUT ROWID" in sql[table], table
            assert "WITHOUT ROWID" not in sql["meshes"]


def test_comparison_notices_a_missing_revision(engine):
    # Guards the test above: at 0001 the indexes of 0002 are missing, and
    # compare_metadata must say so.
    with engine.connect() as conn:
        migrate.upgrade(conn, "0001")
        added = {diff[1].name for diff in _differences(conn) if diff[0] == "add_index"}
    assert added == INDEXES


def test_new_database_is_created_at_head(db_url, engine):
    hestore.open(db_url).close()
    with engine.connect() as conn:
        assert migrate.current_revision(conn) == migrate.head_revision()
        assert _differences(conn) == []


def test_open_refuses_an_older_database(db_url, engine):
    with engine.connect() as conn:
        migrate.upgrade(conn, "0001")
    with pytest.raises(hestore.SchemaVersionError, match="hestore db upgrade"):
        hestore.open(db_url)
    with engine.connect() as conn:
        assert migrate.current_revision(conn) == "0001"  # refused, not migrated


def test_downgrade_to_base_and_back(engine):
    with engine.connect() as conn:
        migrate.upgrade(conn)
        migrate.downgrade(conn, "base")
        assert migrate.current_revision(conn) is None
        assert not TABLES & set(sa.inspect(conn).get_table_names())

        migrate.upgrade(conn)
        assert migrate.current_revision(conn) == migrate.head_revision()
        assert _differences(conn) == []


def test_environment_opens_its_own_connection(db_url, engine):
    # The URL path of env.py, as the `alembic` command line uses it; the
    # PostgreSQL URL carries %-escapes that must survive the ini-style config.
    command.upgrade(migrate.alembic_config(url=db_url), "head")
    with engine.connect() as conn:
        assert migrate.current_revision(conn) == migrate.head_revision()


def test_environment_falls_back_to_hestore_url(tmp_path, monkeypatch):
    url = f"sqlite:///{tmp_path / 'env.db'}"
    monkeypatch.setenv("HESTORE_URL", url)
    command.upgrade(migrate.alembic_config(), "0001")
    with sa.create_engine(url).connect() as conn:
        assert migrate.current_revision(conn) == "0001"


def test_current_revision_rejects_a_branched_version_table(engine):
    with engine.connect() as conn:
        migrate.upgrade(conn)
        conn.execute(sa.text("INSERT INTO alembic_version (version_num) VALUES ('0001')"))
        conn.commit()
        with pytest.raises(hestore.SchemaVersionError, match="several schema revisions"):
            migrate.current_revision(conn)
