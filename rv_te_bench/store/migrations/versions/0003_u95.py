"""the expanded uncertainty U of every metric and line (issue 35)

metrics.u95 (the metric's U, about 95 %, in its SI unit) and metrics.uc (its combined
standard uncertainty u_c: what rv-te spc takes as the measurement's standard deviation),
lines.amplitude_u95_rad, lines.amplitude_uc_rad and lines.phase_u95_rad; NULL where a
record has none (records written before, metrics without a budget). Added columns only:
SQLite and PostgreSQL add them in place.

Revision ID: 0003
Revises: 0002
Create Date: 2026-11-27
"""
from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = '0003'
down_revision = '0002'
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.add_column('metrics', sa.Column('u95', sa.Float(), nullable=True))
    op.add_column('metrics', sa.Column('uc', sa.Float(), nullable=True))
    op.add_column('lines', sa.Column('amplitude_u95_rad', sa.Float(), nullable=True))
    op.add_column('lines', sa.Column('amplitude_uc_rad', sa.Float(), nullable=True))
    op.add_column('lines', sa.Column('phase_u95_rad', sa.Float(), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table('lines') as batch:
        batch.drop_column('phase_u95_rad')
        batch.drop_column('amplitude_uc_rad')
        batch.drop_column('amplitude_u95_rad')
    with op.batch_alter_table('metrics') as batch:
        batch.drop_column('uc')
        batch.drop_column('u95')
