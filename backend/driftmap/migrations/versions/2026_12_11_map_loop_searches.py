"""map_loop_searches: each site's latest loop-closure search, kept for the next build to resume

Revision ID: 0019
Revises: 0018
Create Date: 2026-12-11 09:00:00.000000
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0019"
down_revision = "0018"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "map_loop_searches",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("site_id", sa.Integer(), nullable=False),
        sa.Column("search_key", sa.String(length=64), nullable=False),
        sa.Column("chains", sa.JSON(), nullable=False),
        sa.Column("basis_sha256", sa.String(length=64), nullable=False),
        sa.Column("blocks", sa.JSON(), nullable=False),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.ForeignKeyConstraint(
            ["site_id"], ["sites.id"], name=op.f("fk_map_loop_searches_site_id_sites"), ondelete="CASCADE"
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_map_loop_searches")),
        sa.UniqueConstraint("site_id", name="uq_map_loop_searches_site_id"),
    )


def downgrade() -> None:
    op.drop_table("map_loop_searches")
