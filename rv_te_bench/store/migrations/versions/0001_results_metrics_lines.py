"""results, metrics and lines (the first schema of the results store)

Revision ID: 0001
Revises:
Create Date: 2026-11-24
"""
from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = '0001'
down_revision = None
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        'results',
        sa.Column('id', sa.Integer(), primary_key=True, autoincrement=True),
        sa.Column('record_key', sa.String(200), nullable=False, unique=True),
        sa.Column('test', sa.String(32), nullable=False),
        sa.Column('plan', sa.String(128), nullable=False),
        sa.Column('serial', sa.String(128)),
        sa.Column('lot', sa.String(128)),
        sa.Column('operator', sa.String(128)),
        sa.Column('bench_id', sa.String(128)),
        sa.Column('preset', sa.String(128)),
        sa.Column('reducer_type', sa.String(16)),
        sa.Column('tested_at', sa.DateTime(), nullable=False),
        sa.Column('analysed_at', sa.DateTime(), nullable=False),
        sa.Column('status', sa.String(16), nullable=False),
        sa.Column('failure', sa.Text()),
        sa.Column('verdict', sa.String(16), nullable=False),
        sa.Column('command', sa.String(32), nullable=False),
        sa.Column('software_version', sa.String(64), nullable=False),
        sa.Column('bag_path', sa.Text(), nullable=False),
        sa.Column('bag_sha256', sa.String(64), nullable=False),
        sa.Column('bag_size_bytes', sa.BigInteger()),
        sa.Column('bag_mtime_ns', sa.BigInteger()),
        sa.Column('advice', sa.JSON()),
        sa.Column('details', sa.JSON()),
    )
    for name, col in (('serial', 'serial'), ('tested_at', 'tested_at'), ('preset', 'preset'),
                      ('verdict', 'verdict'), ('bag_path', 'bag_path')):
        op.create_index(f'ix_results_{name}', 'results', [col])
    op.create_table(
        'metrics',
        sa.Column('id', sa.Integer(), primary_key=True, autoincrement=True),
        sa.Column('result_id', sa.Integer(), sa.ForeignKey('results.id', ondelete='CASCADE'),
                  nullable=False),
        sa.Column('name', sa.String(64), nullable=False),
        sa.Column('direction', sa.String(8), nullable=False),
        sa.Column('value', sa.Float(), nullable=False),
        sa.Column('limit_low', sa.Float()),
        sa.Column('limit_high', sa.Float()),
        sa.Column('verdict', sa.String(16)),
        sa.UniqueConstraint('result_id', 'name', 'direction', name='uq_metrics_result_name'),
    )
    op.create_index('ix_metrics_name', 'metrics', ['name', 'direction'])
    op.create_table(
        'lines',
        sa.Column('id', sa.Integer(), primary_key=True, autoincrement=True),
        sa.Column('result_id', sa.Integer(), sa.ForeignKey('results.id', ondelete='CASCADE'),
                  nullable=False),
        sa.Column('label', sa.String(64), nullable=False),
        sa.Column('output_order', sa.Float()),
        sa.Column('crank_order', sa.Float()),
        sa.Column('frequency_hz', sa.Float()),
        sa.Column('amplitude_rad', sa.Float(), nullable=False),
        sa.Column('phase_rad', sa.Float()),
        sa.UniqueConstraint('result_id', 'label', name='uq_lines_result_label'),
    )
    op.create_index('ix_lines_label', 'lines', ['label'])


def downgrade() -> None:
    op.drop_table('lines')
    op.drop_table('metrics')
    op.drop_table('results')
