"""Properties: a catalogue and one value table per SQL type; the meshes' property counter.

Revision ID: 0003
Revises: 0002
Create Date: 2026-11-23

Values are plain SQL rows keyed ``(mesh_id, property, id, part)``: up to four
components of one element's value per row (see ``hestore.values``).
Existing meshes get ``next_property = 0`` and no properties.
"""
# Written out explicitly, never imported from hestore.schema: this revision
# must keep describing the schema as it was when it was written.

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0003"
down_revision: str | None = "0002"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

_VALUE_TABLES = (("property_reals", sa.Float(53), 4), ("property_integers", sa.BigInteger(), 4),
                 ("property_texts", sa.Text(), 1))


def upgrade() -> None:
    with op.batch_alter_table("meshes") as batch:
        batch.add_column(sa.Column("next_property", sa.BigInteger(), nullable=False, server_default="0"))
    op.create_table(
        "properties",
        sa.Column("mesh_id", sa.Integer(), primary_key=True),
        sa.Column("id", sa.BigInteger(), primary_key=True),
        sa.Column("kind", sa.String(16), nullable=False),
        sa.Column("name", sa.String(255), nullable=False),
        sa.Column("dtype", sa.String(16), nullable=False),
        sa.Column("size", sa.Integer(), nullable=True),
        sa.Column("default_value", sa.Text(), nullable=True),
        sa.UniqueConstraint("mesh_id", "kind", "name", name="uq_properties_name"),
        sqlite_with_rowid=False,
    )
    for name, type_, width in _VALUE_TABLES:
        op.create_table(
            name,
            sa.Column("mesh_id", sa.Integer(), primary_key=True),
            sa.Column("property", sa.BigInteger(), primary_key=True),
            sa.Column("id", sa.BigInteger(), primary_key=True),
            sa.Column("part", sa.Integer(), primary_key=True),
            *(sa.Column(f"v{k}", type_, nullable=True) for k in range(width)),
            sqlite_with_rowid=False,
        )


def downgrade() -> None:
    for name, _, _ in reversed(_VALUE_TABLES):
        op.drop_table(name)
    op.drop_table("properties")
    with op.batch_alter_table("meshes") as batch:
        batch.drop_column("next_property")
