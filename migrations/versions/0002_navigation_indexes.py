"""Navigation indexes on halfedges: by origin and by polygon.

Revision ID: 0002
Revises: 0001
Create Date: 2025-11-21

Rotating around a vertex and walking a polygon look half-edges up by
``origin`` and by ``polygon``; without these indexes both are table scans.
"""

from __future__ import annotations

from collections.abc import Sequence

from alembic import op

revision: str = "0002"
down_revision: str | None = "0001"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None


def upgrade() -> None:
    op.create_index("ix_halfedges_origin", "halfedges", ["mesh_id", "origin"])
    op.create_index("ix_halfedges_polygon", "halfedges", ["mesh_id", "polygon"])


def downgrade() -> None:
    op.drop_index("ix_halfedges_polygon", table_name="halfedges")
    op.drop_index("ix_halfedges_origin", table_name="halfedges")
