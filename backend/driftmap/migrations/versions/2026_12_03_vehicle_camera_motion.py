"""vehicle cameras; heading, speed, motion and odometry flags on vehicle positions

Revision ID: 0008
Revises: 0007
Create Date: 2026-12-03 10:00:00.000000
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0008"
down_revision = "0007"
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table("vehicles", schema=None) as batch_op:
        batch_op.add_column(sa.Column("camera", sa.JSON(none_as_null=True), nullable=True))
    with op.batch_alter_table("vehicle_positions", schema=None) as batch_op:
        batch_op.add_column(sa.Column("speed_mps", sa.Float(), nullable=True))
        batch_op.add_column(sa.Column("moving", sa.Boolean(), nullable=True))
        batch_op.add_column(sa.Column("odometry", sa.Boolean(), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table("vehicle_positions", schema=None) as batch_op:
        batch_op.drop_column("odometry")
        batch_op.drop_column("moving")
        batch_op.drop_column("speed_mps")
    with op.batch_alter_table("vehicles", schema=None) as batch_op:
        batch_op.drop_column("camera")
