"""History: row versions, their history twins, and the revisions table.

Revision ID: 0004
Revises: 0003
Create Date: 2026-11-24

Every versioned table gains ``rev``, the revision that wrote the row, and a
twin ``<table>_history`` holding superseded row versions with ``rev_to``,
the revision that superseded them (SPEC §4.1). ``revisions`` lists the kept
revisions of each mesh with their time and message; ``meshes`` gains
``history`` (whether it is kept) and ``kept_from`` (the oldest revision that
can still be viewed).

Existing meshes keep their current state as their first kept revision: their
rows get ``rev`` = the mesh's revision, ``kept_from`` is that revision, and a
mesh with a revision above 0 gets its row in ``revisions``.
"""
# Written out explicitly, never imported from hestore.schema: this revision
# must keep describing the schema as it was when it was written.

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0004"
down_revision: str | None = "0003"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


class _NoAffinity(sa.types.UserDefinedType):
    cache_ok = True

    def get_col_spec(self, **kw) -> str:
        return ""


_ID = sa.BigInteger()
_FLOAT = sa.Float(53).with_variant(_NoAffinity(), "sqlite")
_KEY = (("mesh_id", sa.Integer()), ("id", _ID))
_VALUE_KEY = (("mesh_id", sa.Integer()), ("property", _ID), ("id", _ID), ("part", sa.Integer()))


def _values(type_, width):
    return tuple((f"v{k}", type_) for k in range(width))


#: Each versioned table: its key columns, then its other columns, as they are at this revision.
_VERSIONED = (
    ("vertices", _KEY, (("halfedge", _ID), ("x", _FLOAT), ("y", _FLOAT), ("z", _FLOAT))),
    ("halfedges", _KEY, tuple((c, _ID) for c in ("origin", "next", "prev", "twin", "edge", "polygon"))),
    ("edges", _KEY, (("halfedge", _ID),)),
    ("polygons", _KEY, (("halfedge", _ID),)),
    ("properties", _KEY, (("kind", sa.String(16)), ("name", sa.String(255)), ("dtype", sa.String(16)),
                          ("size", sa.Integer()), ("default_value", sa.Text()))),
    ("property_reals", _VALUE_KEY, _values(_FLOAT, 4)),
    ("property_integers", _VALUE_KEY, _values(sa.BigInteger(), 4)),
    ("property_texts", _VALUE_KEY, _values(sa.Text(), 1)),
)


def upgrade() -> None:
    with op.batch_alter_table("meshes") as batch:
        batch.add_column(sa.Column("history", sa.Boolean(), nullable=False, server_default=sa.true()))
        batch.add_column(sa.Column("kept_from", _ID, nullable=False, server_default="0"))
    op.execute("UPDATE meshes SET kept_from = revision")
    for name, key, other in _VERSIONED:
        op.add_column(name, sa.Column("rev", _ID, nullable=False, server_default="0"))
        op.execute(f"UPDATE {name} SET rev = (SELECT m.revision FROM meshes AS m WHERE m.id = {name}.mesh_id)")
        op.create_table(
            f"{name}_history",
            *(sa.Column(c, t, primary_key=True) for c, t in key),
            *(sa.Column(c, t, nullable=True) for c, t in other),
            sa.Column("rev", _ID, nullable=True),
            sa.Column("rev_to", _ID, primary_key=True),
            sqlite_with_rowid=False,
        )
        op.create_index(f"ix_{name}_history_rev_to", f"{name}_history", ["mesh_id", "rev_to"])
    revisions = op.create_table(
        "revisions",
        sa.Column("mesh_id", sa.Integer(), primary_key=True),
        sa.Column("number", _ID, primary_key=True),
        sa.Column("committed_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("message", sa.Text(), nullable=True),
        sa.Column("changes", sa.Text(), nullable=True),
        sa.Column("action", sa.String(8), nullable=True),
        sa.Column("target", _ID, nullable=True),
        sqlite_with_rowid=False,
    )
    meshes = sa.table("meshes", sa.column("id"), sa.column("revision"))
    op.execute(
        revisions.insert().from_select(
            ["mesh_id", "number", "committed_at", "message"],
            sa.select(
                meshes.c.id, meshes.c.revision, sa.func.current_timestamp(),
                sa.literal("the state when history began to be kept"),
            ).where(meshes.c.revision > 0),
        )
    )


def downgrade() -> None:
    op.drop_table("revisions")
    for name, _, other in reversed(_VERSIONED):
        op.drop_index(f"ix_{name}_history_rev_to", table_name=f"{name}_history")
        op.drop_table(f"{name}_history")
        # Float columns are declared without a type on SQLite: reflection cannot tell, so say it.
        floats = [sa.Column(c, t) for c, t in other if t is _FLOAT]
        with op.batch_alter_table(name, table_kwargs={"sqlite_with_rowid": False}, reflect_args=floats) as batch:
            batch.drop_column("rev")
    with op.batch_alter_table("meshes") as batch:
        batch.drop_column("kept_from")
        batch.drop_column("history")
