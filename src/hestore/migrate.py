"""The link between hestore's schema and Alembic.

`hestore.schema` defines the tables; the Alembic revisions in the
``migrations`` folder (shipped inside the wheel as ``hestore/migrations``)
create and change them. This module owns the schema's versioning: it finds
those revisions, builds an Alembic configuration for them without an
``alembic.ini``, runs them on a connection the caller owns (`upgrade`: what
`hestore.open` uses to create a new database at head), and says where a
database stands (`schema_state`, `SchemaState`). `database_state` and
`upgrade_database` do the same for a database URL, below any store (a store
refuses a database that is behind): they are ``hestore db current`` and
``hestore db upgrade``.

>>> import sqlalchemy as sa
>>> from hestore import migrate
>>> engine = sa.create_engine("sqlite://")
>>> with engine.connect() as conn:
...     print(migrate.current_revision(conn))
...     migrate.upgrade(conn)
...     print(migrate.current_revision(conn) == migrate.head_revision())
None
True
"""

from __future__ import annotations

import functools
import importlib.resources
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import sqlalchemy as sa

from hestore import schema, urls
from hestore import _drivers as drivers
from hestore import _values as values
from hestore.errors import SchemaVersionError

if TYPE_CHECKING:  # pragma: no cover - typing only
    import alembic.config
    import alembic.script

__all__ = [
    "compare_type",
    "script_location",
    "alembic_config",
    "upgrade",
    "downgrade",
    "current_revision",
    "head_revision",
    "revisions",
    "SchemaState",
    "schema_state",
    "database_state",
    "upgrade_database",
]

#: The table in which Alembic records the revision a database is at.
VERSION_TABLE = "alembic_version"


def script_location() -> str:
    """Return the folder holding hestore's Alembic environment and revisions.

    An installed hestore carries them inside the package as
    ``hestore/migrations``; an editable install or a source checkout has them
    in the repository's top-level ``migrations/`` folder instead.

    Returns
    -------
    str
        Path of a folder containing ``env.py`` and ``versions/``.

    Examples
    --------
    >>> from pathlib import Path
    >>> from hestore.migrate import script_location
    >>> (Path(script_location()) / "env.py").is_file()
    True
    """
    packaged = importlib.resources.files("hestore") / "migrations"
    if packaged.joinpath("env.py").is_file():
        # Alembic needs a real folder; an installed package is one on disk.
        return str(packaged)
    return str(Path(__file__).resolve().parents[2] / "migrations")


def alembic_config(
    connection: sa.Connection | None = None, url: str | None = None
) -> alembic.config.Config:
    """Build an Alembic configuration for hestore's revisions, without an ini file.

    Parameters
    ----------
    connection : sqlalchemy.Connection, optional
        When given, migrations run on this connection (inside its current
        transaction, if it has one) instead of opening their own.
    url : str, optional
        Database URL for migrations run without a connection. When neither is
        given, ``env.py`` falls back to ``$HESTORE_URL``, then
        ``sqlite:///hestore.db``.

    Returns
    -------
    alembic.config.Config
        Usable with any `alembic.command` function.

    Examples
    --------
    >>> from alembic import command
    >>> from hestore.migrate import alembic_config
    >>> cfg = alembic_config(url="sqlite://")
    >>> cfg.get_main_option("sqlalchemy.url")
    'sqlite://'
    """
    from alembic.config import Config

    config = Config()
    config.set_main_option("script_location", script_location())
    if url is not None:
        # The options go through configparser, which treats % as interpolation
        # (URL-encoded passwords and query options contain it).
        config.set_main_option("sqlalchemy.url", str(url).replace("%", "%%"))
    if connection is not None:
        config.attributes["connection"] = connection
    return config


def compare_type(context, inspected_column, metadata_column, inspected_type, metadata_type) -> bool | None:
    """Alembic's ``compare_type`` hook: hestore's untyped SQLite float columns match untyped columns.

    `hestore.schema` declares float columns without a type on SQLite (so
    that no affinity rewrites ``-0.0``); Alembic's own comparison cannot
    read an empty type. Anything else is left to Alembic (None).
    """
    if isinstance(metadata_type.dialect_impl(context.dialect), schema.NoAffinity):
        return not isinstance(inspected_type, sa.types.NullType)
    return None


def upgrade(connection: sa.Connection, revision: str = "head") -> None:
    """Migrate the database behind `connection` to `revision`, and commit.

    Works on an empty database (every revision runs) as well as on one at
    any older revision; a database already at `revision` is left alone.

    Parameters
    ----------
    connection : sqlalchemy.Connection
        An open connection; whatever it has done in its current transaction
        is committed together with the migration.
    revision : str, default "head"
        The target revision id.

    Examples
    --------
    >>> import sqlalchemy as sa
    >>> from hestore.migrate import current_revision, upgrade
    >>> with sa.create_engine("sqlite://").connect() as conn:
    ...     upgrade(conn, "0001")
    ...     print(current_revision(conn))
    0001
    """
    from alembic import command

    command.upgrade(alembic_config(connection=connection), revision)
    connection.commit()


def downgrade(connection: sa.Connection, revision: str) -> None:
    """Migrate the database behind `connection` back to `revision`, and commit.

    Destructive: going below a revision drops what it created, data included.
    Meant for testing revisions (see ``docs/migrations.md``), not for use on
    stored meshes.

    Parameters
    ----------
    connection : sqlalchemy.Connection
        An open connection.
    revision : str
        The target revision id, or ``"base"`` for an empty database.

    Examples
    --------
    >>> import sqlalchemy as sa
    >>> from hestore.migrate import current_revision, downgrade, upgrade
    >>> with sa.create_engine("sqlite://").connect() as conn:
    ...     upgrade(conn)
    ...     downgrade(conn, "base")
    ...     print(current_revision(conn), sa.inspect(conn).has_table("meshes"))
    None False
    """
    from alembic import command

    command.downgrade(alembic_config(connection=connection), revision)
    connection.commit()


def current_revision(connection: sa.Connection) -> str | None:
    """Return the revision the database is at, or None for an unversioned one.

    Reads Alembic's version table directly (no migration environment is
    loaded), so it is cheap enough to call on every `hestore.open`.

    Parameters
    ----------
    connection : sqlalchemy.Connection
        An open connection.

    Returns
    -------
    str or None
        The revision id; None when the version table is missing or empty
        (a new database, or one emptied by downgrading to base).

    Raises
    ------
    SchemaVersionError
        The version table names several revisions: hestore's history is
        linear, so the database was changed by something else.

    Examples
    --------
    >>> import sqlalchemy as sa
    >>> from hestore.migrate import current_revision
    >>> with sa.create_engine("sqlite://").connect() as conn:
    ...     print(current_revision(conn))
    None
    """
    if not sa.inspect(connection).has_table(VERSION_TABLE):
        return None
    version = sa.table(VERSION_TABLE, sa.column("version_num", sa.String))
    rows = connection.execute(sa.select(version.c.version_num)).scalars().all()
    if not rows:
        return None
    if len(rows) > 1:
        raise SchemaVersionError(
            f"the database records several schema revisions ({', '.join(sorted(rows))}); "
            "hestore's schema history is linear, so it was changed outside hestore"
        )
    return rows[0]


@functools.cache
def _scripts() -> alembic.script.ScriptDirectory:
    # Parsing the revision files is the slow part; they cannot change while
    # this process runs, so do it once.
    from alembic.script import ScriptDirectory

    return ScriptDirectory.from_config(alembic_config())


def head_revision() -> str:
    """Return the newest revision this version of hestore knows.

    A test keeps it equal to `hestore.schema.SCHEMA_REVISION`.

    Returns
    -------
    str
        The head revision id.

    Examples
    --------
    >>> from hestore import migrate, schema
    >>> migrate.head_revision() == schema.SCHEMA_REVISION
    True
    """
    head = _scripts().get_current_head()
    if head is None:  # pragma: no cover - only a broken install has no revisions
        raise SchemaVersionError(f"no schema revisions found in {script_location()}")
    return head


def revisions() -> list[str]:
    """Return every revision this version of hestore knows, oldest first.

    Returns
    -------
    list of str
        Revision ids from the first to `head_revision`.

    Examples
    --------
    >>> from hestore.migrate import head_revision, revisions
    >>> revisions()[0], revisions()[-1] == head_revision()
    ('0001', True)
    """
    return [script.revision for script in reversed(list(_scripts().walk_revisions()))]


@dataclass(frozen=True)
class SchemaState:
    """Where a database stands against this hestore's schema: what `schema_state` returns.

    Attributes
    ----------
    current : str or None
        The revision the database is at; None when it has no hestore schema.
    head : str
        This hestore's newest revision.
    status : str
        ``"new"`` (no hestore tables: `hestore.open` creates them at head),
        ``"head"`` (up to date), ``"behind"`` (``hestore db upgrade`` brings
        it to head), ``"ahead"`` (written by a newer hestore) or
        ``"foreign"`` (tables with hestore's names that hestore did not
        create: nothing will touch them).
    foreign_tables : tuple of str
        For ``"foreign"``: the tables in the way.
    """

    current: str | None
    head: str
    status: str
    foreign_tables: tuple[str, ...] = ()

    def describe(self) -> str:
        """One line for people, e.g. ``0002 (behind head 0003: run `hestore db upgrade`)``.

        Examples
        --------
        >>> SchemaState(None, "0003", "new").describe()
        'none: a new, empty database (hestore creates its tables at head, 0003, when it first opens it)'
        """
        if self.status == "new":
            return (
                f"none: a new, empty database (hestore creates its tables at head, {self.head}, "
                "when it first opens it)"
            )
        if self.status == "foreign":
            return (
                f"none: the database holds tables hestore did not create ({', '.join(self.foreign_tables)}); "
                "hestore will not use or change them"
            )
        if self.status == "head":
            return f"{self.current} (head)"
        if self.status == "behind":
            return f"{self.current} (behind head {self.head}: run `hestore db upgrade`)"
        return f"{self.current} (unknown to hestore, whose head is {self.head}: written by a newer hestore)"


def schema_state(connection: sa.Connection) -> SchemaState:
    """Where the database behind ``connection`` stands against this hestore's schema.

    Parameters
    ----------
    connection : sqlalchemy.Connection
        An open connection; nothing is written.

    Returns
    -------
    SchemaState

    Examples
    --------
    >>> import sqlalchemy as sa
    >>> from hestore.migrate import schema_state, upgrade
    >>> with sa.create_engine("sqlite://").connect() as conn:
    ...     print(schema_state(conn).status, end=" ")
    ...     upgrade(conn)
    ...     print(schema_state(conn).status)
    new head
    """
    head = head_revision()
    current = current_revision(connection)
    if current is None:
        ours = set(schema.metadata.tables)
        clash = tuple(sorted(ours & set(sa.inspect(connection).get_table_names())))
        return SchemaState(None, head, "foreign" if clash else "new", clash)
    if current == head:
        return SchemaState(current, head, "head")
    return SchemaState(current, head, "behind" if current in revisions() else "ahead")


def database_state(
    url: str | sa.engine.URL | None, *, busy_timeout: float = drivers.DEFAULT_BUSY_TIMEOUT
) -> SchemaState:
    """Where the database at ``url`` stands, without changing anything (``hestore db current``).

    A SQLite file that does not exist yet is ``"new"`` and is not created.
    ``busy_timeout`` is as for `hestore.open`.

    Raises
    ------
    InvalidInputError
        ``url`` is not a database hestore supports, or ``busy_timeout`` is not
        a finite number of seconds ≥ 0.
    StoreError
        The database cannot be read.

    Examples
    --------
    >>> import tempfile, os
    >>> path = os.path.join(tempfile.mkdtemp(), "new.db")
    >>> database_state(path).status, os.path.exists(path)
    ('new', False)
    """
    seconds = values.check_seconds(busy_timeout, "busy_timeout")
    url = urls.resolve(url)
    path = urls.sqlite_path(url)
    if path is not None and not Path(path).exists():
        return SchemaState(None, head_revision(), "new")
    engine = drivers.make_engine(url, busy_timeout=seconds, pooled=False, autocommit=False)
    try:
        with drivers.guard(f"cannot read {urls.shown(url)}", urls.shown(url)), engine.connect() as conn:
            return schema_state(conn)
    finally:
        engine.dispose()


def upgrade_database(
    url: str | sa.engine.URL | None, *, busy_timeout: float = drivers.DEFAULT_BUSY_TIMEOUT
) -> tuple[SchemaState, SchemaState]:
    """Bring the database at ``url`` to head, creating it if new (``hestore db upgrade``).

    ``busy_timeout`` is how long to wait for another writer's lock, as for `hestore.open`.

    Returns
    -------
    (SchemaState, SchemaState)
        Where it stood before and where it stands after.

    Raises
    ------
    InvalidInputError
        ``url`` is not a database hestore supports, or ``busy_timeout`` is not
        a finite number of seconds ≥ 0.
    SchemaVersionError
        Tables hestore did not create are in the way, or a newer hestore
        wrote the database: nothing is changed.
    StoreError
        The database cannot be changed (read-only, unreachable).

    Examples
    --------
    >>> import tempfile, os
    >>> before, after = upgrade_database(os.path.join(tempfile.mkdtemp(), "m.db"))
    >>> before.status, after.status
    ('new', 'head')
    """
    seconds = values.check_seconds(busy_timeout, "busy_timeout")
    url = urls.resolve(url)
    shown = urls.shown(url)
    engine = drivers.make_engine(url, busy_timeout=seconds, pooled=False, autocommit=False)
    try:
        with drivers.guard(f"cannot upgrade {shown}", shown), engine.connect() as conn:
            before = schema_state(conn)
            if before.status == "foreign":
                # Creating the tables would collide with these; which revision
                # they match is anyone's guess, so leave them to a human.
                raise SchemaVersionError(
                    f"{shown} holds tables hestore did not create ({', '.join(before.foreign_tables)}); "
                    "refusing to migrate it"
                )
            if before.status == "ahead":
                raise SchemaVersionError(
                    f"{shown} is at schema revision {before.current}, which this hestore does not know "
                    f"(its head is {before.head}); it was written by a newer hestore"
                )
            if before.status != "head":
                upgrade(conn)
            return before, schema_state(conn)
    finally:
        engine.dispose()
