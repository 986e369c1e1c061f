"""Shared fixtures: every storage test runs on SQLite and on PostgreSQL.

``db_url`` gives each test a fresh, empty database: a SQLite file in the
test's temporary folder, or a PostgreSQL schema of its own (created in a
database made for this test session, and dropped afterwards). A test that
uses ``store`` (or ``mesh``) gets that database already at the schema's head,
as the store's first `hestore.open` would leave it, made once per session
and copied (see `_AtHead`): the migrations themselves are tested in
``test_migrations`` on truly empty databases.

``corpus`` hands out the shared meshes (``meshes.Corpus``), each imported
once per backend and test session; ``meshes`` is their folder. ``reader``
runs a file-reading test with each way the readers take text.

PostgreSQL is found at ``$HESTORE_TEST_PG_URL`` (default
``postgresql+psycopg://postgres@127.0.0.1:5432/test``). Where it cannot be
reached the PostgreSQL tests are skipped with the reason, except under
``CI=true``, where they fail: CI must never pass without them. The tests'
connections commit without waiting for the server's disk
(``synchronous_commit=off``: what a crash of the server would lose, which no
test provokes); what other connections see, and when, is unchanged.

Parallel runs (pytest-xdist): a run of the whole suite (or of folders) uses
one worker process per CPU (`pytest_cmdline_main`); a run that names test
files or tests, selects with ``-k``, shows output (``-s``) or debugs
(``--pdb``, ``--trace``) stays in one process. ``-n N`` chooses, ``-n 0`` or
``-p no:xdist`` turns it off. Each worker has its own session: its own
PostgreSQL database, corpus and temporary folders; the tests of one corpus
file run on one worker (`pytest_xdist_make_scheduler`). Tests marked
``slow`` are run first, so that the workers finish together.

Nothing a test asserts may depend on the machine's speed: hypothesis has no
deadlines and no health check of slow data generation (each test's number
of examples is its own, the same under CI and elsewhere), and commands run
in the test's process show progress only where a test turns it on
(`_progress_never_by_time`).
"""

from __future__ import annotations

import math
import os
import pathlib
import shutil
import uuid
import warnings
from urllib.parse import quote

import hypothesis
import pytest
import sqlalchemy as sa

PG_URL = os.environ.get("HESTORE_TEST_PG_URL", "postgresql+psycopg://postgres@127.0.0.1:5432/test")
IN_CI = os.environ.get("CI", "").lower() in ("1", "true", "yes")

BACKENDS = ["sqlite", pytest.param("postgresql", marks=pytest.mark.postgresql)]

#: Server settings of every test connection to PostgreSQL (``-c`` options of libpq's ``options``).
PG_SETTINGS = ("synchronous_commit=off",)

#: At most this many workers, however many CPUs there are (each holds a PostgreSQL database and connections).
MAX_WORKERS = 8


# -- parallel runs ---------------------------------------------------------------------------


def _cpus() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def _one_process_reason(config: pytest.Config) -> str | None:
    """Why this run is better in one process (None: it is not)."""
    if config.getoption("usepdb", False) or config.getoption("trace", False):
        return "a debugger"
    if config.getoption("capture", "fd") == "no":
        return "-s shows output"
    if config.getoption("keyword", ""):
        return "a -k selection"
    if config.args_source == pytest.Config.ArgsSource.ARGS:
        named = [arg for arg in config.args if not pathlib.Path(arg.split("::", 1)[0]).is_dir()]
        if named:
            return "named test files or tests"
    return None


@pytest.hookimpl(tryfirst=True)
def pytest_cmdline_main(config: pytest.Config) -> None:
    """Distribute a whole-suite run over the CPUs (before pytest-xdist reads ``-n``)."""
    if not config.pluginmanager.hasplugin("xdist") or "PYTEST_XDIST_WORKER" in os.environ:
        return
    if config.getoption("numprocesses", None) is not None or config.getoption("dist", "no") != "no":
        return  # the caller chose
    if config.getoption("tx", None) or config.getoption("collectonly", False):
        return
    if _one_process_reason(config) is not None:
        return
    workers = min(_cpus(), MAX_WORKERS)
    if workers > 1:
        config.option.numprocesses = workers
        config.option.dist = "load"  # with the corpus's files kept together: `pytest_xdist_make_scheduler`


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers", "slow: runs for many seconds; started first, so that parallel workers finish together"
    )


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """In a parallel run, the slow tests first (a stable sort: otherwise the collection order).

    The workers are handed tests in this order. A run in one process keeps the collection's order.
    """
    if hasattr(config, "workerinput"):  # a pytest-xdist worker
        items.sort(key=lambda item: item.get_closest_marker("slow") is None)


@pytest.hookimpl(optionalhook=True)  # a hook of pytest-xdist, which may not be there
def pytest_xdist_make_scheduler(config: pytest.Config, log):
    """Load balancing (``--dist load``), with a corpus file's tests kept together on one worker.

    A test parametrized by a corpus file has the file in its id
    (`meshes.corpus_id`); all the tests of one file go to the worker that
    runs the first of them, so that the file is imported once per backend
    and its reference made once, not on every worker. The files spread over
    the workers; every other test is sent on its own, as it comes. Any other
    ``--dist`` is pytest-xdist's own.
    """
    if config.getvalue("dist") != "load":
        return None
    from xdist.scheduler import LoadScopeScheduling

    from meshes import corpus_group

    class CorpusScheduling(LoadScopeScheduling):
        # A scope is what goes to one worker at once: a corpus file's tests, or one test.
        def _split_scope(self, nodeid: str) -> str:
            group = corpus_group(nodeid)
            return nodeid if group is None else f"corpus:{group}"

    config.option.loadscopereorder = False  # in the collection's order, which puts the slow tests first
    return CorpusScheduling(config, log)


# -- what may not depend on the machine's speed -----------------------------------------------

# Hypothesis: no example has a deadline, and slow data generation is no failure; how many
# examples each test draws stays its own (the same on every run, CI or not).
hypothesis.settings.register_profile(
    "hestore", deadline=None, suppress_health_check=[hypothesis.HealthCheck.too_slow]
)
hypothesis.settings.load_profile("hestore")


@pytest.fixture(autouse=True)
def _progress_never_by_time(monkeypatch):
    """Commands run in the test's process never show progress because they took long.

    ``check``, ``info`` and the graph commands show progress once they take
    longer than `hestore.cli.commands.QUIET_SECONDS`: on a busy machine, any
    of them may. A test of that output sets ``QUIET_SECONDS`` to 0 itself.
    """
    from hestore.cli import commands

    monkeypatch.setattr(commands, "QUIET_SECONDS", math.inf)


# -- PostgreSQL --------------------------------------------------------------------------------


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
    """A PostgreSQL database made for this test session (for each worker of a parallel run), dropped at its end."""
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


@pytest.fixture(scope="session")
def pg_admin(pg_database):
    """An engine on this session's PostgreSQL database that makes and drops the tests' schemas (autocommit)."""
    engine = sa.create_engine(
        pg_database, isolation_level="AUTOCOMMIT", connect_args={"options": " ".join(f"-c{s}" for s in PG_SETTINGS)}
    )
    yield engine
    engine.dispose()


def _pg_schema_url(database_url: sa.engine.URL, schema: str) -> str:
    # Unqualified table names resolve into the test's own schema.
    base = database_url.render_as_string(hide_password=False)
    options = " ".join(f"-c{setting}" for setting in (f"search_path={schema}", *PG_SETTINGS))
    return f"{base}?options={quote(options)}"


# -- databases at the schema's head ----------------------------------------------------------


class _AtHead:
    """Makes fresh databases that are what `hestore.open` leaves in an empty one, without migrating each.

    SQLite: one database file is opened (so migrated) once, and copied.
    PostgreSQL: the tables of `hestore.schema` and Alembic's version row at
    the head revision are made directly, by statements recorded once and
    sent again, in one transaction, to each new schema (with the search path
    set to it): a fifth of the work of running every migration. The
    recording is checked before it is used: a replay must give the catalogue
    that `hestore.open` gives by migrating (tables, columns, defaults,
    constraints, indexes, sequences, rows), and no statement may name the
    recorded schema; otherwise every store migrates its own database, as
    without this class, and a warning says why. ``test_migrations`` runs the
    migrations themselves, on empty databases.
    """

    def __init__(self, folder: pathlib.Path):
        self.folder = folder
        self._sqlite: pathlib.Path | None = None
        self._pg: list[tuple[str, object, bool]] | None = None
        self._pg_recorded = False

    def sqlite(self, path: pathlib.Path) -> None:
        import hestore

        if self._sqlite is None:
            template = self.folder / "head.db"
            hestore.open(f"sqlite:///{template}").close()
            self._sqlite = template
        for suffix in ("", "-wal", "-shm"):
            source = self._sqlite.with_name(self._sqlite.name + suffix)
            if source.exists():
                shutil.copyfile(source, path.with_name(path.name + suffix))

    def postgresql(self, engine: sa.engine.Engine, database_url: sa.engine.URL, schema: str) -> None:
        """Make ``schema``, at the head."""
        if not self._pg_recorded:
            self._pg, self._pg_recorded = self._record(engine, database_url), True
        self._replay(engine, schema, self._pg or [])

    @staticmethod
    def _replay(engine: sa.engine.Engine, schema: str, statements: list[tuple[str, object, bool]]) -> None:
        """Make ``schema`` and send it ``statements``, in one transaction."""
        with engine.connect() as conn:
            conn = conn.execution_options(isolation_level="READ COMMITTED")  # one transaction, not autocommit
            with conn.begin():
                cursor = conn.connection.cursor()
                cursor.execute(f'CREATE SCHEMA "{schema}"')
                cursor.execute(f'SET LOCAL search_path TO "{schema}"')
                for statement, parameters, many in statements:
                    (cursor.executemany if many else cursor.execute)(statement, parameters)

    @classmethod
    def _record(cls, engine: sa.engine.Engine, database_url: sa.engine.URL) -> list[tuple[str, object, bool]] | None:
        """The statements to replay (None, with a warning, where a replay would not give the migrated schema)."""
        import hestore
        from alembic import command

        from hestore import migrate
        from hestore import schema as tables

        migrated, recorded, replayed = (f"{kind}_{uuid.uuid4().hex[:12]}" for kind in ("head", "record", "replay"))
        sent: list[tuple[str, object, bool]] = []

        def record(conn, cursor, statement, parameters, context, executemany):
            # Without parameters the driver must not look for placeholders (a literal % stays one).
            no_parameters = context is not None and context.no_parameters
            sent.append((statement, list(parameters) if executemany else None if no_parameters else parameters,
                         executemany))

        with engine.connect() as conn:
            for schema in (migrated, recorded):
                conn.exec_driver_sql(f'CREATE SCHEMA "{schema}"')
        try:
            hestore.open(_pg_schema_url(database_url, migrated)).close()
            direct = sa.create_engine(_pg_schema_url(database_url, recorded), poolclass=sa.pool.NullPool)
            sa.event.listen(direct, "before_cursor_execute", record)
            try:
                with direct.connect() as conn:
                    tables.metadata.create_all(conn, checkfirst=False)
                    command.stamp(migrate.alembic_config(connection=conn), "head")
                    conn.commit()
            finally:
                direct.dispose()
            named = [s for s, p, _ in sent if recorded in s or recorded in repr(p)]
            problem = None
            if not sent or named:
                problem = f"{len(sent)} statement(s) made the tables, these name their schema: {named}"
            else:
                cls._replay(engine, replayed, sent)
                with engine.connect() as conn:
                    want, got = _catalogue(conn, migrated), _catalogue(conn, replayed)
                if want != got:
                    problem = f"they differ from the migrated schema: {sorted(set(want) ^ set(got))}"
            if problem:
                warnings.warn(f"every PostgreSQL test database is migrated, not made directly: {problem}",
                              stacklevel=1)
                return None
        finally:
            with engine.connect() as conn:
                for schema in (migrated, recorded, replayed):
                    conn.exec_driver_sql(f'DROP SCHEMA IF EXISTS "{schema}" CASCADE')
        return sent


def _catalogue(conn: sa.Connection, schema: str) -> list[tuple]:
    """What a PostgreSQL schema holds, with its own name left out: comparable between two schemas."""
    queries = {
        "column": "SELECT table_name, column_name, ordinal_position, data_type, is_nullable, column_default"
                  " FROM information_schema.columns WHERE table_schema = :s",
        "constraint": "SELECT c.conrelid::regclass::text, c.conname, pg_get_constraintdef(c.oid) FROM pg_constraint c"
                      " JOIN pg_namespace n ON n.oid = c.connamespace WHERE n.nspname = :s",
        "index": "SELECT tablename, indexname, indexdef FROM pg_indexes WHERE schemaname = :s",
        "sequence": "SELECT sequence_name, data_type, start_value, increment FROM information_schema.sequences"
                    " WHERE sequence_schema = :s",
    }
    rows = [(kind, *row) for kind, sql in queries.items() for row in conn.execute(sa.text(sql), {"s": schema})]
    names = conn.execute(sa.text("SELECT tablename FROM pg_tables WHERE schemaname = :s"), {"s": schema}).scalars()
    for name in names.all():
        rows += [("row", name, *row) for row in conn.exec_driver_sql(f'SELECT * FROM "{schema}"."{name}"')]
    return sorted(tuple(str(x).replace(schema, "<schema>") for x in row) for row in rows)


@pytest.fixture(scope="session")
def _at_head(tmp_path_factory) -> _AtHead:
    return _AtHead(tmp_path_factory.mktemp("at-head"))


# -- the fixtures ------------------------------------------------------------------------------


@pytest.fixture(params=BACKENDS)
def backend(request) -> str:
    """The name of the database backend the test runs on."""
    return request.param


@pytest.fixture
def db_url(backend, tmp_path, request) -> str:
    """The URL of a fresh, empty database on the current backend.

    For a test that uses ``store``, the database is at the schema's head
    already (what the store's `hestore.open` would do first).
    """
    at_head = "store" in request.fixturenames
    if backend == "sqlite":
        path = tmp_path / "test.db"
        if at_head:
            request.getfixturevalue("_at_head").sqlite(path)
        yield f"sqlite:///{path}"
        return
    database_url = request.getfixturevalue("pg_database")
    engine = request.getfixturevalue("pg_admin")
    schema = f"t_{uuid.uuid4().hex[:12]}"
    if at_head:
        request.getfixturevalue("_at_head").postgresql(engine, database_url, schema)
    else:
        with engine.connect() as conn:
            conn.exec_driver_sql(f'CREATE SCHEMA "{schema}"')
    try:
        yield _pg_schema_url(database_url, schema)
    finally:
        with engine.connect() as conn:
            conn.exec_driver_sql(f'DROP SCHEMA "{schema}" CASCADE')


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


# -- the shared meshes, imported once per backend ------------------------------------------------


@pytest.fixture(scope="session")
def corpus_sqlite(tmp_path_factory):
    """The shared meshes in a SQLite file of this test session (see `meshes.Corpus`)."""
    from meshes import Corpus

    corpus = Corpus(f"sqlite:///{tmp_path_factory.mktemp('corpus') / 'corpus.db'}")
    yield corpus
    corpus.close()


@pytest.fixture(scope="session")
def corpus_postgresql(pg_database, pg_admin):
    """The shared meshes in a PostgreSQL schema of this test session's database (see `meshes.Corpus`)."""
    from meshes import Corpus

    with pg_admin.connect() as conn:
        conn.exec_driver_sql('CREATE SCHEMA "corpus"')
    corpus = Corpus(_pg_schema_url(pg_database, "corpus"))
    yield corpus
    corpus.close()


@pytest.fixture
def corpus(backend, request):
    """The shared meshes on the current backend, imported once per test session (see `meshes.Corpus`).

    The test reads the corpus's meshes, or edits copies of them
    (`meshes.Corpus.copy`), which are deleted afterwards; a test that changed
    a corpus mesh fails.
    """
    shared = request.getfixturevalue(f"corpus_{backend}")
    yield shared
    changed = shared.release()
    assert not changed, f"the test changed corpus meshes, which other tests read: {changed}"


@pytest.fixture
def meshes():
    """The shared meshes folder (the test skips where there is none, or fails under CI: `meshes.shared_meshes`)."""
    from meshes import require_shared_meshes

    return require_shared_meshes()


@pytest.fixture(params=["whole", "tiny-chunks", "per-line"])
def reader(request, monkeypatch):
    """How the file readers take text: normally, in 37-byte chunks, or line by line only."""
    from hestore.io import common

    if request.param == "tiny-chunks":
        monkeypatch.setattr(common, "CHUNK_BYTES", 37)
    elif request.param == "per-line":
        monkeypatch.setattr(common, "parse", lambda text, total, dtype: None)
    return request.param
