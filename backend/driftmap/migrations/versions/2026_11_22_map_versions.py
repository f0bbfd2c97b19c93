"""map versions

Revision ID: 0002
Revises: 0001
Create Date: 2026-11-22 04:17:04.943822
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0002"
down_revision = "0001"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "map_versions",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("site_id", sa.Integer(), nullable=False),
        sa.Column("version", sa.Integer(), nullable=False),
        sa.Column("params", sa.JSON(), nullable=False),
        sa.Column("stats", sa.JSON(), nullable=False),
        sa.Column("topomap_sha256", sa.String(length=64), nullable=False),
        sa.Column("created_by", sa.String(length=200), nullable=False),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.ForeignKeyConstraint(
            ["site_id"], ["sites.id"], name=op.f("fk_map_versions_site_id_sites"), ondelete="CASCADE"
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_map_versions")),
        sa.UniqueConstraint("site_id", "version", name="uq_map_versions_site_id_version"),
    )
    with op.batch_alter_table("map_versions", schema=None) as batch_op:
        batch_op.create_index(batch_op.f("ix_map_versions_site_id"), ["site_id"], unique=False)

    op.create_table(
        "map_nodes",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("map_version_id", sa.Integer(), nullable=False),
        sa.Column("node", sa.Integer(), nullable=False),
        sa.Column("x_m", sa.Float(), nullable=False),
        sa.Column("y_m", sa.Float(), nullable=False),
        sa.ForeignKeyConstraint(
            ["map_version_id"],
            ["map_versions.id"],
            name=op.f("fk_map_nodes_map_version_id_map_versions"),
            ondelete="CASCADE",
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_map_nodes")),
        sa.UniqueConstraint("map_version_id", "node", name="uq_map_nodes_map_version_id_node"),
    )
    with op.batch_alter_table("map_nodes", schema=None) as batch_op:
        batch_op.create_index(batch_op.f("ix_map_nodes_map_version_id"), ["map_version_id"], unique=False)

    op.create_table(
        "map_loop_closures",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("map_version_id", sa.Integer(), nullable=False),
        sa.Column("frame_a_id", sa.Integer(), nullable=False),
        sa.Column("frame_b_id", sa.Integer(), nullable=False),
        sa.Column("d_score", sa.Float(), nullable=False),
        sa.Column("accepted", sa.Boolean(), nullable=False),
        sa.Column("chi2", sa.Float(), nullable=False),
        sa.ForeignKeyConstraint(
            ["frame_a_id"],
            ["frames.id"],
            name=op.f("fk_map_loop_closures_frame_a_id_frames"),
            ondelete="CASCADE",
        ),
        sa.ForeignKeyConstraint(
            ["frame_b_id"],
            ["frames.id"],
            name=op.f("fk_map_loop_closures_frame_b_id_frames"),
            ondelete="CASCADE",
        ),
        sa.ForeignKeyConstraint(
            ["map_version_id"],
            ["map_versions.id"],
            name=op.f("fk_map_loop_closures_map_version_id_map_versions"),
            ondelete="CASCADE",
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_map_loop_closures")),
    )
    with op.batch_alter_table("map_loop_closures", schema=None) as batch_op:
        batch_op.create_index(
            batch_op.f("ix_map_loop_closures_map_version_id"), ["map_version_id"], unique=False
        )

    op.create_table(
        "map_node_frames",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("map_version_id", sa.Integer(), nullable=False),
        sa.Column("node", sa.Integer(), nullable=False),
        sa.Column("frame_id", sa.Integer(), nullable=False),
        sa.Column("rank", sa.Integer(), nullable=False),
        sa.ForeignKeyConstraint(
            ["frame_id"], ["frames.id"], name=op.f("fk_map_node_frames_frame_id_frames"), ondelete="CASCADE"
        ),
        sa.ForeignKeyConstraint(
            ["map_version_id"],
            ["map_versions.id"],
            name=op.f("fk_map_node_frames_map_version_id_map_versions"),
            ondelete="CASCADE",
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_map_node_frames")),
    )
    with op.batch_alter_table("map_node_frames", schema=None) as batch_op:
        batch_op.create_index(
            batch_op.f("ix_map_node_frames_map_version_id"), ["map_version_id"], unique=False
        )

    op.create_table(
        "map_poses",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("map_version_id", sa.Integer(), nullable=False),
        sa.Column("frame_id", sa.Integer(), nullable=False),
        sa.Column("x_m", sa.Float(), nullable=False),
        sa.Column("y_m", sa.Float(), nullable=False),
        sa.Column("yaw_rad", sa.Float(), nullable=False),
        sa.ForeignKeyConstraint(
            ["frame_id"], ["frames.id"], name=op.f("fk_map_poses_frame_id_frames"), ondelete="CASCADE"
        ),
        sa.ForeignKeyConstraint(
            ["map_version_id"],
            ["map_versions.id"],
            name=op.f("fk_map_poses_map_version_id_map_versions"),
            ondelete="CASCADE",
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_map_poses")),
        sa.UniqueConstraint("map_version_id", "frame_id", name="uq_map_poses_map_version_id_frame_id"),
    )
    with op.batch_alter_table("map_poses", schema=None) as batch_op:
        batch_op.create_index(batch_op.f("ix_map_poses_map_version_id"), ["map_version_id"], unique=False)

    op.create_table(
        "map_grounding_residuals",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("map_version_id", sa.Integer(), nullable=False),
        sa.Column("grounding_id", sa.Integer(), nullable=True),
        sa.Column("frame_id", sa.Integer(), nullable=False),
        sa.Column("surveyed_x_m", sa.Float(), nullable=False),
        sa.Column("surveyed_y_m", sa.Float(), nullable=False),
        sa.Column("dx_m", sa.Float(), nullable=False),
        sa.Column("dy_m", sa.Float(), nullable=False),
        sa.Column("distance_m", sa.Float(), nullable=False),
        sa.ForeignKeyConstraint(
            ["frame_id"],
            ["frames.id"],
            name=op.f("fk_map_grounding_residuals_frame_id_frames"),
            ondelete="CASCADE",
        ),
        sa.ForeignKeyConstraint(
            ["grounding_id"],
            ["groundings.id"],
            name=op.f("fk_map_grounding_residuals_grounding_id_groundings"),
            ondelete="SET NULL",
        ),
        sa.ForeignKeyConstraint(
            ["map_version_id"],
            ["map_versions.id"],
            name=op.f("fk_map_grounding_residuals_map_version_id_map_versions"),
            ondelete="CASCADE",
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_map_grounding_residuals")),
    )
    with op.batch_alter_table("map_grounding_residuals", schema=None) as batch_op:
        batch_op.create_index(
            batch_op.f("ix_map_grounding_residuals_map_version_id"), ["map_version_id"], unique=False
        )


def downgrade() -> None:
    with op.batch_alter_table("map_grounding_residuals", schema=None) as batch_op:
        batch_op.drop_index(batch_op.f("ix_map_grounding_residuals_map_version_id"))

    op.drop_table("map_grounding_residuals")
    with op.batch_alter_table("map_poses", schema=None) as batch_op:
        batch_op.drop_index(batch_op.f("ix_map_poses_map_version_id"))

    op.drop_table("map_poses")
    with op.batch_alter_table("map_node_frames", schema=None) as batch_op:
        batch_op.drop_index(batch_op.f("ix_map_node_frames_map_version_id"))

    op.drop_table("map_node_frames")
    with op.batch_alter_table("map_loop_closures", schema=None) as batch_op:
        batch_op.drop_index(batch_op.f("ix_map_loop_closures_map_version_id"))

    op.drop_table("map_loop_closures")
    with op.batch_alter_table("map_nodes", schema=None) as batch_op:
        batch_op.drop_index(batch_op.f("ix_map_nodes_map_version_id"))

    op.drop_table("map_nodes")
    with op.batch_alter_table("map_versions", schema=None) as batch_op:
        batch_op.drop_index(batch_op.f("ix_map_versions_site_id"))

    op.drop_table("map_versions")
