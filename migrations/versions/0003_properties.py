"""Properties: a catalogue and one value table per SQL type; the meshes' property counter.

Revision ID: 0003
Revises: 0002
Create Date: 2026-11-23

Values are plain SQL rows keyed ``(mesh_id, property, id, part)``: up to four
components of one element's value per row (see ``hestore._values``).
Existing meshes get ``next_property = 0`` and no properties.

On SQLite, float columns (the new ``property_reals`` values, and the
vertices' x, y, z, whose table is rebuilt with its rows) are declared without
a type: a ``REAL`` column stores ``-0.0`` as the integer 0, a column without
type affinity keeps every float bit for bit.
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

class _NoAffinity(sa.types.UserDefinedType):
    cache_ok = True

    def get_col_spec(self, **kw) -> str:
        return ""


_FLOAT = sa.Float(53).with_variant(_NoAffinity(), "sqlite")
_VALUE_TABLES = (("property_reals", _FLOAT, 4), ("property_integers", sa.BigInteger(), 4),
                 ("property_texts", sa.Text(), 1))


def _vertex_coordinates(type_) -> None:
    """Rebuild SQLite's vertices table with coordinates of ``type_`` (PostgreSQL's stay double precision)."""
    if op.get_bind().dialect.name != "sqlite":
        return
    with op.batch_alter_table("vertices", recreate="always", table_kwargs={"sqlite_with_rowid": False}) as batch:
        for name in "xyz":
            batch.alter_column(name, type_=type_, existing_nullable=True)


def upgrade() -> None:
    _vertex_coordinates(_FLOAT)
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
    _vertex_coordinates(sa.Float(53))
