"""Alembic environment: runs on the connection ``open_store`` hands over (online only).

Developers create a revision with the ``alembic`` command pointing at this folder, e.g.
``alembic -x url=sqlite:///dev.sqlite -c /dev/null revision --autogenerate`` after changing
``rv_te_bench/store/_schema.py`` (see docs/ARCHITECTURE.md).
"""

from __future__ import annotations

from alembic import context
from sqlalchemy import create_engine

from rv_te_bench.store._schema import Base

config = context.config
connection = config.attributes.get('connection')
if connection is None:  # the alembic command line: a URL given with -x url=...
    url = context.get_x_argument(as_dictionary=True).get('url')
    if not url:
        msg = 'give the database with -x url=...'
        raise SystemExit(msg)
    with create_engine(url).connect() as conn:
        context.configure(connection=conn, target_metadata=Base.metadata,
                          render_as_batch=True)
        with context.begin_transaction():
            context.run_migrations()
else:
    context.configure(connection=connection, target_metadata=Base.metadata,
                      render_as_batch=True)
    with context.begin_transaction():
        context.run_migrations()
