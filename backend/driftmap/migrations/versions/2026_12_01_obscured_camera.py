"""obscured-camera judgement and its measures on vehicle positions

Revision ID: 0005
Revises: 0004
Create Date: 2026-12-01 16:20:00.000000
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0005"
down_revision = "0004"
branch_labels = None
depends_on = None

_FLOATS = ("salient", "sharpness", "speckle", "flat_area")


def upgrade() -> None:
    with op.batch_alter_table("vehicle_positions", schema=None) as batch_op:
        batch_op.add_column(sa.Column("obscured", sa.Boolean(), nullable=True))
        batch_op.add_column(sa.Column("obscured_reason", sa.String(length=16), nullable=True))
        for name in _FLOATS:
            batch_op.add_column(sa.Column(name, sa.Float(), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table("vehicle_positions", schema=None) as batch_op:
        for name in reversed(_FLOATS):
            batch_op.drop_column(name)
        batch_op.drop_column("obscured_reason")
        batch_op.drop_column("obscured")
