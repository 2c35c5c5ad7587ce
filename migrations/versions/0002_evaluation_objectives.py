"""evaluations.objectives: every objective of an evaluation as JSON

Revision ID: 0002
Revises: 0001
Create Date: 2026-12-04
"""

from collections.abc import Sequence

import sqlalchemy as sa
from alembic import op

revision: str = "0002"
down_revision: str | None = "0001"
branch_labels: str | Sequence[str] | None = None
depends_on: str | Sequence[str] | None = None

# JSON object builders by dialect: the stored evaluations get their paper objectives
_BUILD = {"sqlite": "json_object", "postgresql": "json_build_object"}


def upgrade() -> None:
    """Add ``evaluations.objectives`` and fill it from the distance, active_share and
    voxel_count columns of the evaluations already stored."""
    with op.batch_alter_table("evaluations", schema=None) as batch_op:
        batch_op.add_column(sa.Column("objectives", sa.JSON(), nullable=True))
    build = _BUILD.get(op.get_bind().dialect.name, "json_object")
    op.execute(
        f"UPDATE evaluations SET objectives = {build}("
        "'distance', distance, 'active_share', active_share, 'voxel_count', voxel_count)"
    )


def downgrade() -> None:
    """Drop ``evaluations.objectives`` (objectives beyond the paper's three are lost)."""
    with op.batch_alter_table("evaluations", schema=None) as batch_op:
        batch_op.drop_column("objectives")
