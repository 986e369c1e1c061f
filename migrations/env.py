"""Alembic environment for hestore's schema.

Used two ways:

* programmatically, by `hestore.migrate` (``hestore.open`` and
  ``hestore db upgrade``), which hands over an open SQLAlchemy connection in
  ``config.attributes["connection"]``; the migrations run on it, inside
  whatever transaction the caller has;
* from the ``alembic`` command line in a source checkout, where the URL comes
  from ``sqlalchemy.url`` in the Alembic config, else ``$HESTORE_URL``, else
  ``sqlite:///hestore.db`` (the same default as ``hestore.open``).

SQLite cannot ``ALTER`` most things in place, so revisions run in batch mode
there (Alembic copies the table, alters the copy and swaps it in).
"""

from __future__ import annotations

import os

import sqlalchemy as sa
from alembic import context

from hestore.migrate import compare_type
from hestore.schema import metadata as target_metadata

config = context.config

DEFAULT_URL = "sqlite:///hestore.db"


def _url() -> str:
    return config.get_main_option("sqlalchemy.url") or os.environ.get("HESTORE_URL") or DEFAULT_URL


def run_migrations_offline() -> None:
    """Write the migration SQL to stdout (``alembic upgrade head --sql``)."""
    url = _url()
    context.configure(
        url=url,
        target_metadata=target_metadata,
        compare_type=compare_type,
        literal_binds=True,
        dialect_opts={"paramstyle": "named"},
        render_as_batch=sa.engine.make_url(url).get_backend_name() == "sqlite",
    )
    with context.begin_transaction():
        context.run_migrations()


def _run_on(connection: sa.Connection) -> None:
    context.configure(
        connection=connection,
        target_metadata=target_metadata,
        compare_type=compare_type,
        render_as_batch=connection.dialect.name == "sqlite",
    )
    with context.begin_transaction():
        context.run_migrations()


def run_migrations_online() -> None:
    """Run the migrations on the caller's connection, or on a new one."""
    connection = config.attributes.get("connection")
    if connection is not None:
        _run_on(connection)
        return
    # NullPool: this engine lives for one command, nothing to keep warm.
    engine = sa.create_engine(_url(), poolclass=sa.pool.NullPool)
    try:
        with engine.connect() as connection:
            _run_on(connection)
    finally:
        engine.dispose()


if context.is_offline_mode():
    run_migrations_offline()
else:
    run_migrations_online()
