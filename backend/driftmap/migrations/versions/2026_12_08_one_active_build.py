"""jobs: at most one unfinished map build per site (partial unique index on ``site_id``)

Revision ID: 0016
Revises: 0015
Create Date: 2026-12-08 09:00:00.000000
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0016"
down_revision = "0015"
branch_labels = None
depends_on = None

ACTIVE = sa.text("kind = 'map.build' AND parent_id IS NULL AND status IN ('queued', 'running')")


def upgrade() -> None:
    clashes = op.get_bind().execute(
        sa.text(
            "SELECT site_id, count(*) FROM jobs WHERE kind = 'map.build' AND parent_id IS NULL "
            "AND status IN ('queued', 'running') GROUP BY site_id HAVING count(*) > 1"
        )
    )
    found = [f"site {site_id}: {count} builds" for site_id, count in clashes]
    if found:
        raise RuntimeError(
            "more than one unfinished map build per site (" + "; ".join(found) + "): cancel all but one "
            "(`POST /api/jobs/{id}/cancel`, or let them finish) with the previous version of driftmap, then upgrade"
        )
    with op.batch_alter_table("jobs", schema=None) as batch_op:
        batch_op.create_index(
            "uq_jobs_site_id_active_build",
            ["site_id"],
            unique=True,
            sqlite_where=ACTIVE,
            postgresql_where=ACTIVE,
        )


def downgrade() -> None:
    with op.batch_alter_table("jobs", schema=None) as batch_op:
        batch_op.drop_index("uq_jobs_site_id_active_build")
