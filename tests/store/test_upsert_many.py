"""``ResultStore.upsert_many``: a batch of records in one transaction (the fleet writes each
batch of bags that way, issue 41), each record written as ``upsert`` writes it."""

from __future__ import annotations

import sqlite3
from dataclasses import replace
from pathlib import Path

import pytest

from rv_te_bench.errors import StoreError
from rv_te_bench.store import MetricValue, open_store
from tests.store.conftest import make_record


def _rows(db: Path) -> list[tuple]:
    with open_store(db) as st:
        return sorted((r.bag_sha256, r.serial, r.verdict, sorted(r.metrics.items()),
                       sorted(r.lines.items())) for r in st.query())


def test_a_batch_is_what_one_upsert_after_another_writes(tmp_path: Path) -> None:
    """New records, an update of a stored one (its serial kept when the new one has none),
    and two records of one key in the same batch (the later wins): the same rows as the
    same records upserted one by one, and the ids of the records in order."""
    first = [make_record(i) for i in range(3)]
    batch = [make_record(3), replace(first[1], serial=None, verdict='fail',
                                     metrics=(MetricValue('te_pp_rad', 7e-4),)),
             make_record(4), replace(make_record(4), serial='SN-B', verdict='pass')]
    one, many = tmp_path / 'one.sqlite', tmp_path / 'many.sqlite'
    with open_store(one) as st:
        for r in first + batch:
            st.upsert(r)
    with open_store(many) as st:
        st.upsert_many(first)
        ids = st.upsert_many(batch)
        by_key = {r.bag_sha256: r.id for r in st.query()}
    assert _rows(many) == _rows(one)
    assert len(_rows(many)) == 5
    assert ids == [by_key[r.bag_sha256] for r in batch]
    row = {r[0]: r for r in _rows(many)}
    assert row[first[1].bag_sha256][1:3] == ('SN00001', 'fail')   # serial kept, verdict new
    assert row[make_record(4).bag_sha256][1] == 'SN-B'
    con = sqlite3.connect(many)     # the replaced metrics are gone, not left behind
    assert con.execute('select count(*) from metrics').fetchone() == (4 * 4 + 1,)
    con.close()


def test_a_batch_is_written_whole_or_not_at_all(tmp_path: Path) -> None:
    """A record the database refuses (two values of one metric and direction) fails the
    batch with one clear error; none of its records is written, the earlier ones stay."""
    db = tmp_path / 'r.sqlite'
    bad = make_record(1)     # past the record's own check: what only the database sees
    object.__setattr__(bad, 'metrics', (MetricValue('te_pp_rad', 1e-4),
                                        MetricValue('te_pp_rad', 2e-4)))
    with open_store(db) as st:
        st.upsert(make_record(9))
        with pytest.raises(StoreError, match='cannot write to results store'):
            st.upsert_many([make_record(0), bad, make_record(2)])
        assert [r.bag_sha256 for r in st.query()] == [make_record(9).bag_sha256]
        assert st.upsert_many([]) == []
