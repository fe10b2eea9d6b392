"""record_key widened to 256 characters (test 32 | plan 128 | sha256 64 = 226; was 200)

Before it, a record of a plan name longer than 102 characters fitted every column but
not its key: PostgreSQL refused it ('value too long'), SQLite (which ignores lengths)
kept it (issue #21). Batch mode: SQLite cannot alter a column, the table is copied.

Revision ID: 0002
Revises: 0001
Create Date: 2026-11-25
"""
from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = '0002'
down_revision = '0001'
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table('results') as batch:
        batch.alter_column('record_key', existing_type=sa.String(200), type_=sa.String(256),
                           existing_nullable=False)


def downgrade() -> None:
    with op.batch_alter_table('results') as batch:
        batch.alter_column('record_key', existing_type=sa.String(256), type_=sa.String(200),
                           existing_nullable=False)
