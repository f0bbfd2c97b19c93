"""initial schema

Revision ID: 0001
Revises:
Create Date: 2026-11-22 04:02:41.764684
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0001"
down_revision = None
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "sites",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("name", sa.String(length=200), nullable=False),
        sa.Column("description", sa.Text(), nullable=False),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_sites")),
        sa.UniqueConstraint("name", name=op.f("uq_sites_name")),
    )
    op.create_table(
        "drives",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("site_id", sa.Integer(), nullable=False),
        sa.Column("name", sa.String(length=200), nullable=False),
        sa.Column("kind", sa.String(length=20), nullable=False),
        sa.Column("fps", sa.Float(), nullable=False),
        sa.Column("camera", sa.JSON(), nullable=False),
        sa.Column("frame_count", sa.Integer(), nullable=False),
        sa.Column("source", sa.String(length=1000), nullable=False),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.ForeignKeyConstraint(
            ["site_id"], ["sites.id"], name=op.f("fk_drives_site_id_sites"), ondelete="CASCADE"
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_drives")),
        sa.UniqueConstraint("site_id", "name", name="uq_drives_site_id_name"),
    )
    with op.batch_alter_table("drives", schema=None) as batch_op:
        batch_op.create_index(batch_op.f("ix_drives_site_id"), ["site_id"], unique=False)

    op.create_table(
        "survey_maps",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("site_id", sa.Integer(), nullable=False),
        sa.Column("filename", sa.String(length=500), nullable=False),
        sa.Column("dxf_sha256", sa.String(length=64), nullable=False),
        sa.Column("units", sa.String(length=20), nullable=False),
        sa.Column("min_x_m", sa.Float(), nullable=False),
        sa.Column("min_y_m", sa.Float(), nullable=False),
        sa.Column("max_x_m", sa.Float(), nullable=False),
        sa.Column("max_y_m", sa.Float(), nullable=False),
        sa.Column("layers", sa.JSON(), nullable=False),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.ForeignKeyConstraint(
            ["site_id"], ["sites.id"], name=op.f("fk_survey_maps_site_id_sites"), ondelete="CASCADE"
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_survey_maps")),
    )
    with op.batch_alter_table("survey_maps", schema=None) as batch_op:
        batch_op.create_index(batch_op.f("ix_survey_maps_site_id"), ["site_id"], unique=False)

    op.create_table(
        "frames",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("drive_id", sa.Integer(), nullable=False),
        sa.Column("index", sa.Integer(), nullable=False),
        sa.Column("t_s", sa.Float(), nullable=False),
        sa.Column("blob_sha256", sa.String(length=64), nullable=False),
        sa.Column("image_ext", sa.String(length=8), nullable=False),
        sa.Column("true_x_m", sa.Float(), nullable=True),
        sa.Column("true_y_m", sa.Float(), nullable=True),
        sa.Column("true_yaw_rad", sa.Float(), nullable=True),
        sa.ForeignKeyConstraint(
            ["drive_id"], ["drives.id"], name=op.f("fk_frames_drive_id_drives"), ondelete="CASCADE"
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_frames")),
        sa.UniqueConstraint("drive_id", "index", name="uq_frames_drive_id_index"),
    )
    with op.batch_alter_table("frames", schema=None) as batch_op:
        batch_op.create_index(batch_op.f("ix_frames_blob_sha256"), ["blob_sha256"], unique=False)
        batch_op.create_index(batch_op.f("ix_frames_drive_id"), ["drive_id"], unique=False)

    op.create_table(
        "groundings",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("drive_id", sa.Integer(), nullable=False),
        sa.Column("frame_id", sa.Integer(), nullable=False),
        sa.Column("x_m", sa.Float(), nullable=False),
        sa.Column("y_m", sa.Float(), nullable=False),
        sa.Column("created_by", sa.String(length=200), nullable=False),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("updated_at", sa.DateTime(timezone=True), nullable=False),
        sa.ForeignKeyConstraint(
            ["drive_id"], ["drives.id"], name=op.f("fk_groundings_drive_id_drives"), ondelete="CASCADE"
        ),
        sa.ForeignKeyConstraint(
            ["frame_id"], ["frames.id"], name=op.f("fk_groundings_frame_id_frames"), ondelete="CASCADE"
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_groundings")),
        sa.UniqueConstraint("frame_id", name="uq_groundings_frame_id"),
    )
    with op.batch_alter_table("groundings", schema=None) as batch_op:
        batch_op.create_index(batch_op.f("ix_groundings_drive_id"), ["drive_id"], unique=False)


def downgrade() -> None:
    with op.batch_alter_table("groundings", schema=None) as batch_op:
        batch_op.drop_index(batch_op.f("ix_groundings_drive_id"))

    op.drop_table("groundings")
    with op.batch_alter_table("frames", schema=None) as batch_op:
        batch_op.drop_index(batch_op.f("ix_frames_drive_id"))
        batch_op.drop_index(batch_op.f("ix_frames_blob_sha256"))

    op.drop_table("frames")
    with op.batch_alter_table("survey_maps", schema=None) as batch_op:
        batch_op.drop_index(batch_op.f("ix_survey_maps_site_id"))

    op.drop_table("survey_maps")
    with op.batch_alter_table("drives", schema=None) as batch_op:
        batch_op.drop_index(batch_op.f("ix_drives_site_id"))

    op.drop_table("drives")
    op.drop_table("sites")
