"""map_pieces: each drive segment's stage-1 piece kept between map builds (incremental builds)

Revision ID: 0017
Revises: 0016
Create Date: 2026-12-09 09:00:00.000000
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0017"
down_revision = "0016"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "map_pieces",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("drive_id", sa.Integer(), nullable=False),
        sa.Column("piece_key", sa.String(length=64), nullable=False),
        sa.Column("frame_first", sa.Integer(), nullable=False),
        sa.Column("frame_stop", sa.Integer(), nullable=False),
        sa.Column("blob_sha256", sa.String(length=64), nullable=False),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.ForeignKeyConstraint(
            ["drive_id"], ["drives.id"], name=op.f("fk_map_pieces_drive_id_drives"), ondelete="CASCADE"
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_map_pieces")),
        sa.UniqueConstraint("piece_key", name="uq_map_pieces_piece_key"),
    )
    with op.batch_alter_table("map_pieces", schema=None) as batch_op:
        batch_op.create_index(batch_op.f("ix_map_pieces_drive_id"), ["drive_id"], unique=False)
        batch_op.create_index(batch_op.f("ix_map_pieces_blob_sha256"), ["blob_sha256"], unique=False)


def downgrade() -> None:
    with op.batch_alter_table("map_pieces", schema=None) as batch_op:
        batch_op.drop_index(batch_op.f("ix_map_pieces_blob_sha256"))
        batch_op.drop_index(batch_op.f("ix_map_pieces_drive_id"))
    op.drop_table("map_pieces")
