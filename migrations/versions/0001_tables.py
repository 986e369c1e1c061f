"""The five tables: meshes, vertices, halfedges, edges, polygons.

Revision ID: 0001
Revises:
Create Date: 2025-11-21
"""
# Written out explicitly, never imported from hestore.schema: this revision
# must keep describing the schema as it was when it was written.

from __future__ import annotations

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0001"
down_revision: str | None = None
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.create_table(
        "meshes",
        sa.Column("id", sa.Integer(), primary_key=True, autoincrement=True),
        sa.Column("name", sa.String(255), nullable=False, unique=True),
        sa.Column("allow_loops", sa.Boolean(), nullable=False),
        sa.Column("allow_multi_edges", sa.Boolean(), nullable=False),
        sa.Column("revision", sa.BigInteger(), nullable=False),
        sa.Column("next_vertex", sa.BigInteger(), nullable=False),
        sa.Column("next_edge", sa.BigInteger(), nullable=False),
        sa.Column("next_polygon", sa.BigInteger(), nullable=False),
        # Mesh ids are never reused either: a stale Mesh must not reach a newer mesh.
        sqlite_autoincrement=True,
    )
    # Element tables are clustered on (mesh_id, id): on SQLite, WITHOUT ROWID
    # makes the primary key the table itself instead of a second b-tree.
    op.create_table(
        "vertices",
        sa.Column("mesh_id", sa.Integer(), primary_key=True),
        sa.Column("id", sa.BigInteger(), primary_key=True),
        sa.Column("halfedge", sa.BigInteger(), nullable=True),
        sa.Column("x", sa.Float(53), nullable=True),
        sa.Column("y", sa.Float(53), nullable=True),
        sa.Column("z", sa.Float(53), nullable=True),
        sqlite_with_rowid=False,
    )
    op.create_table(
        "halfedges",
        sa.Column("mesh_id", sa.Integer(), primary_key=True),
        sa.Column("id", sa.BigInteger(), primary_key=True),
        sa.Column("origin", sa.BigInteger(), nullable=False),
        sa.Column("next", sa.BigInteger(), nullable=False),
        sa.Column("prev", sa.BigInteger(), nullable=False),
        sa.Column("twin", sa.BigInteger(), nullable=False),
        sa.Column("edge", sa.BigInteger(), nullable=False),
        sa.Column("polygon", sa.BigInteger(), nullable=True),
        sqlite_with_rowid=False,
    )
    op.create_table(
        "edges",
        sa.Column("mesh_id", sa.Integer(), primary_key=True),
        sa.Column("id", sa.BigInteger(), primary_key=True),
        sa.Column("halfedge", sa.BigInteger(), nullable=False),
        sqlite_with_rowid=False,
    )
    op.create_table(
        "polygons",
        sa.Column("mesh_id", sa.Integer(), primary_key=True),
        sa.Column("id", sa.BigInteger(), primary_key=True),
        sa.Column("halfedge", sa.BigInteger(), nullable=False),
        sqlite_with_rowid=False,
    )


def downgrade() -> None:
    for table in ("polygons", "edges", "halfedges", "vertices", "meshes"):
        op.drop_table(table)
