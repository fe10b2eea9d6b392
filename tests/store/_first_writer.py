"""A first writer of a new store, run by ``test_store_safety`` in a spawned process of its
own: the child imports this module (the store and the record helper), not the test module
with its bag writers (0.5 CPU s less in each of the six children)."""

from __future__ import annotations

from rv_te_bench.store import open_store
from tests.store.conftest import make_record


def open_and_write(db: str, k: int, barrier: object, errors: object) -> None:
    """A first writer: wait for the others, then open the (new) store and write."""
    try:
        barrier.wait(60)   # type: ignore[attr-defined]
        with open_store(db) as st:
            st.upsert(make_record(k))
    except Exception as exc:  # noqa: BLE001 - reported to the test
        errors.put(f'{type(exc).__name__}: {exc}')   # type: ignore[attr-defined]
