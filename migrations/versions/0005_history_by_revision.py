"""History clustered by revision: one B-tree per history table instead of two.

Revision ID: 0005
Revises: 0004
Create Date: 2026-11-24

Each ``<table>_history`` was keyed ``(mesh_id, <key>, rev_to)``, with a
second index on ``(mesh_id, rev_to)``. It is now keyed ``(mesh_id, rev_to,
<key>)`` and has no other index: what one revision superseded is one range,
undo, diff and prune read it as one, and an edit writes its records into one
B-tree per table (one page) instead of two. The rows are kept as they are.

SQLite cannot change a primary key, so there each history table is rebuilt
under its own name; PostgreSQL swaps the constraint.
"""
# Written out explicitly, never imported from hestore.schema: this revision
# must keep describing the schema as it was when it was written.

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0005"
down_revision: str | None = "0004"
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


#: Each versioned table: its key columns, then its other columns, as in revision 0004.
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


def _rekey(name: str, key: tuple, other: tuple, primary_key: list[str]) -> None:
    """Give ``<name>_history`` the primary key ``primary_key``, keeping its rows."""
    table = f"{name}_history"
    if op.get_bind().dialect.name != "sqlite":
        op.drop_constraint(f"{table}_pkey", table, type_="primary")
        op.create_primary_key(f"{table}_pkey", table, primary_key)
        return
    op.rename_table(table, f"{table}_old")
    op.create_table(
        table,
        *(sa.Column(c, t, nullable=False) for c, t in key),
        *(sa.Column(c, t, nullable=True) for c, t in other),
        sa.Column("rev", _ID, nullable=True),
        sa.Column("rev_to", _ID, nullable=False),
        sa.PrimaryKeyConstraint(*primary_key),
        sqlite_with_rowid=False,
    )
    op.execute(f"INSERT INTO {table} SELECT * FROM {table}_old")
    op.drop_table(f"{table}_old")


def upgrade() -> None:
    for name, key, other in _VERSIONED:
        op.drop_index(f"ix_{name}_history_rev_to", table_name=f"{name}_history")
        _rekey(name, key, other, ["mesh_id", "rev_to", *(c for c, _ in key[1:])])


def downgrade() -> None:
    for name, key, other in reversed(_VERSIONED):
        _rekey(name, key, other, [c for c, _ in key] + ["rev_to"])
        op.create_index(f"ix_{name}_history_rev_to", f"{name}_history", ["mesh_id", "rev_to"])
