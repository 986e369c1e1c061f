"""Shared fixtures: every storage test runs on SQLite and on PostgreSQL.

``db_url`` gives each test a fresh, empty database: a SQLite file in the
test's temporary folder, or a PostgreSQL schema of its own (created in a
database made for this test session, and dropped afterwards).

PostgreSQL is found at ``$HESTORE_TEST_PG_URL`` (default
``postgresql+psycopg://postgres@127.0.0.1:5432/test``). Where it cannot be
reached the PostgreSQL tests are skipped with the reason, except under
``CI=true``, where they fail: CI must never pass without them.
"""

from __future__ import annotations

import os
import uuid
from urllib.parse import quote

import pytest
import sqlalchemy as sa

PG_URL = os.environ.get("HESTORE_TEST_PG_URL", "postgresql+psycopg://postgres@127.0.0.1:5432/test")
IN_CI = os.environ.get("CI", "").lower() in ("1", "true", "yes")

BACKENDS = ["sqlite", pytest.param("postgresql", marks=pytest.mark.postgresql)]


def _pg_problem() -> str | None:
    try:
        import psycopg  # noqa: F401
    except ImportError as exc:  # pragma: no cover - depends on the install
        return f"psycopg is not installed ({exc})"
    try:
        engine = sa.create_engine(PG_URL, connect_args={"connect_timeout": 5})
        with engine.connect() as conn:
            conn.execute(sa.text("SELECT 1"))
        engine.dispose()
    except Exception as exc:  # any failure to connect means: no server here
        return f"PostgreSQL at {PG_URL} is unreachable: {exc.__class__.__name__}: {str(exc).splitlines()[0]}"
    return None


@pytest.fixture(scope="session")
def pg_database():
    """A PostgreSQL database made for this test session, dropped at its end."""
    problem = _pg_problem()
    if problem:
        if IN_CI:
            pytest.fail(f"CI=true but {problem}", pytrace=False)
        pytest.skip(problem)
    admin = sa.create_engine(PG_URL, isolation_level="AUTOCOMMIT")
    name = f"hestore_test_{uuid.uuid4().hex[:12]}"
    with admin.connect() as conn:
        conn.execute(sa.text(f'CREATE DATABASE "{name}"'))
    url = sa.engine.make_url(PG_URL).set(database=name)
    yield url
    with admin.connect() as conn:
        conn.execute(sa.text(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)'))
    admin.dispose()


def _pg_schema_url(database_url: sa.engine.URL, schema: str) -> str:
    # Unqualified table names resolve into the test's own schema.
    base = database_url.render_as_string(hide_password=False)
    return f"{base}?options={quote(f'-csearch_path={schema}')}"


@pytest.fixture(params=BACKENDS)
def backend(request) -> str:
    """The name of the database backend the test runs on."""
    return request.param


@pytest.fixture
def db_url(backend, tmp_path, request) -> str:
    """The URL of a fresh, empty database on the current backend."""
    if backend == "sqlite":
        yield f"sqlite:///{tmp_path / 'test.db'}"
        return
    database_url = request.getfixturevalue("pg_database")
    schema = f"t_{uuid.uuid4().hex[:12]}"
    engine = sa.create_engine(database_url, isolation_level="AUTOCOMMIT")
    with engine.connect() as conn:
        conn.execute(sa.text(f'CREATE SCHEMA "{schema}"'))
    try:
        yield _pg_schema_url(database_url, schema)
    finally:
        with engine.connect() as conn:
            conn.execute(sa.text(f'DROP SCHEMA "{schema}" CASCADE'))
        engine.dispose()


@pytest.fixture
def store(db_url):
    """A `hestore.Store` opened on a fresh database of the current backend."""
    import hestore

    s = hestore.open(db_url)
    yield s
    s.close()


@pytest.fixture
def mesh(store):
    """An empty mesh that allows loops and parallel edges."""
    return store.create_mesh("m")
