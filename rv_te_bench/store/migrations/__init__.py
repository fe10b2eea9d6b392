"""Alembic migrations of the results store (run by ``rv_te_bench.store.open_store``)."""
