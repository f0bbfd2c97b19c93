"""survey layers simplified at upload for the first view's zooms

Revision ID: 0006
Revises: 0005
Create Date: 2026-12-01 17:00:00.000000
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0006"
down_revision = "0005"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "survey_layer_levels",
        sa.Column("id", sa.Integer(), nullable=False),
        sa.Column("survey_map_id", sa.Integer(), nullable=False),
        sa.Column("zoom", sa.Integer(), nullable=False),
        sa.Column("tolerance_m", sa.Float(), nullable=False),
        sa.Column("vertices", sa.JSON(), nullable=False),
        sa.Column("layers", sa.JSON(none_as_null=True), nullable=True),
        sa.Column("same_as_zoom", sa.Integer(), nullable=True),
        sa.ForeignKeyConstraint(
            ["survey_map_id"],
            ["survey_maps.id"],
            name=op.f("fk_survey_layer_levels_survey_map_id_survey_maps"),
            ondelete="CASCADE",
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_survey_layer_levels")),
        sa.UniqueConstraint(
            "survey_map_id", "tolerance_m", name="uq_survey_layer_levels_survey_map_id_tolerance_m"
        ),
    )
    with op.batch_alter_table("survey_layer_levels", schema=None) as batch_op:
        batch_op.create_index(
            batch_op.f("ix_survey_layer_levels_survey_map_id"), ["survey_map_id"], unique=False
        )


def downgrade() -> None:
    with op.batch_alter_table("survey_layer_levels", schema=None) as batch_op:
        batch_op.drop_index(batch_op.f("ix_survey_layer_levels_survey_map_id"))

    op.drop_table("survey_layer_levels")
