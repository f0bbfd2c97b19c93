"""map_database_scores: each site's latest SESAME database pair scores, kept for the next build

Revision ID: 0020
Revises: 0019
Create Date: 2026-12-12 09:00:00.000000
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0020"
down_revision = "0019"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "map_database_scores",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("site_id", sa.Integer(), nullable=False),
        sa.Column("scores_key", sa.String(length=64), nullable=False),
        sa.Column("drives", sa.JSON(), nullable=False),
        sa.Column("scores_sha256", sa.String(length=64), nullable=False),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.ForeignKeyConstraint(
            ["site_id"], ["sites.id"], name=op.f("fk_map_database_scores_site_id_sites"), ondelete="CASCADE"
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_map_database_scores")),
        sa.UniqueConstraint("site_id", name="uq_map_database_scores_site_id"),
    )


def downgrade() -> None:
    op.drop_table("map_database_scores")
