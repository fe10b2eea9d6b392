"""Tests of the results store on a real SQLite file and a real PostgreSQL server."""

from __future__ import annotations

import csv
import os
import signal
import sqlite3
import subprocess
import sys
import textwrap
import time
from dataclasses import replace
from datetime import UTC, datetime, timedelta
from pathlib import Path

import pytest
from sqlalchemy import create_engine

from rv_te_bench.errors import StoreError
from rv_te_bench.store import (
    MetricValue,
    ResultFilter,
    export_records,
    open_store,
)
from rv_te_bench.store._store import SCHEMA_HEAD
from tests.store.conftest import make_record

ROOT = Path(__file__).resolve().parents[2]


def _comparable(rows: list) -> list[tuple]:
    """What a query returns, minus the database-assigned id and write time."""
    return [(r.serial, r.preset, r.verdict, r.tested_at, r.status, r.bag_sha256,
             sorted(r.metrics.items()), sorted(r.lines.items()), r.advice) for r in rows]


def test_round_trip_sqlite(tmp_path: Path) -> None:
    rec = make_record(3)
    with open_store(tmp_path / 'r.sqlite') as st:
        rid = st.upsert(rec)
        (row,) = st.query()
    assert row.id == rid
    assert row.serial == 'SN00003'
    assert row.tested_at == rec.tested_at          # timezone-aware UTC back
    assert row.metrics[('te_pp_rad', 'cw')] == pytest.approx(rec.metrics[2].value)
    assert row.limits[('te_pp_rad', 'ccw')][1:] == (4.6e-4, 'pass')
    assert row.lines['1 f_w'] == (rec.lines[0].amplitude_rad, rec.lines[0].phase_rad)
    assert row.advice == rec.advice


def test_same_bag_twice_updates_not_duplicates(tmp_path: Path) -> None:
    """A bag analysed again (same content hash and test) replaces its record: one row,
    the new values, the metric that disappeared gone."""
    db = tmp_path / 'r.sqlite'
    first = make_record(1)
    second = replace(first, metrics=(MetricValue('te_pp_rad', 7e-4),), verdict='fail')
    with open_store(db) as st:
        a = st.upsert(first)
        b = st.upsert(second)
        rows = st.query()
    assert a == b
    assert len(rows) == 1
    assert rows[0].metrics == {('te_pp_rad', 'all'): 7e-4}
    assert rows[0].verdict == 'fail'
    con = sqlite3.connect(db)
    assert con.execute('select count(*) from metrics').fetchone() == (1,)
    con.close()
    # another test of the same bag is another record
    with open_store(db) as st:
        st.upsert(replace(first, test='test-plan', plan='acceptance'))
        assert len(st.query()) == 2


def test_filters(tmp_path: Path) -> None:
    with open_store(tmp_path / 'r.sqlite') as st:
        for i in range(10):
            st.upsert(make_record(i, preset='hu2020-rv' if i % 3 == 0 else 'wang2020-2kv',
                                  verdict='fail' if i == 4 else 'pass'))
        t0 = datetime(2026, 11, 1, tzinfo=UTC)
        assert [r.serial for r in st.query(ResultFilter(serial='SN00007'))] == ['SN00007']
        assert [r.serial for r in st.query(ResultFilter(verdict='fail'))] == ['SN00004']
        assert len(st.query(ResultFilter(preset='hu2020-rv'))) == 4
        got = st.query(ResultFilter(since=t0 + timedelta(hours=2),
                                    until=t0 + timedelta(hours=5)))
        assert [r.serial for r in got] == ['SN00002', 'SN00003', 'SN00004']
        s = st.series('te_pp_rad', direction='ccw', flt=ResultFilter(preset='wang2020-2kv'))
        assert len(s.values) == 6
        assert s.tested_at == sorted(s.tested_at)
        assert st.series('line:1 f_w').values[0] == pytest.approx(2e-4)


def test_naive_filter_dates_rejected() -> None:
    with pytest.raises(StoreError, match='timezone-aware'):
        ResultFilter(since=datetime(2026, 1, 1))


def _kill_a_writer_mid_write(db: str) -> None:
    """Start a process that upserts records of 300 metrics each into ``db`` in a loop and
    SIGKILL it 1.5 s after its third record (in most runs mid-transaction)."""
    code = textwrap.dedent(f"""
        import sys
        sys.path.insert(0, {str(ROOT)!r})
        from rv_te_bench.store import open_store
        from tests.store.conftest import make_record
        st = open_store({db!r})
        i = 0
        while True:
            st.upsert(make_record(i % 50, n_extra_metrics=300))
            i += 1
            if i == 3:
                print('writing', flush=True)
        """)
    proc = subprocess.Popen([sys.executable, '-c', code], stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        assert proc.stdout.readline().strip() == 'writing'
        time.sleep(1.5)
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()


def test_crash_mid_write_leaves_a_consistent_store(tmp_path: Path) -> None:
    """A writer killed with SIGKILL while it writes records of 300 metrics each: every
    record in the store afterwards has all its 300 + 4 metrics and 2 lines, and SQLite's
    integrity check passes (measured: the kill lands mid-transaction in most runs; the
    test checks consistency whatever the moment)."""
    db = tmp_path / 'r.sqlite'
    open_store(db).close()
    _kill_a_writer_mid_write(str(db))
    con = sqlite3.connect(db)
    try:
        assert con.execute('pragma integrity_check').fetchone() == ('ok',)
        counts = con.execute('select r.id, count(m.id) from results r left join metrics m '
                             'on m.result_id = r.id group by r.id').fetchall()
        lines = con.execute('select count(*) from lines').fetchone()[0]
    finally:
        con.close()
    assert counts, 'the writer wrote nothing before it was killed'
    assert {c for _, c in counts} == {304}
    assert lines == 2 * len(counts)
    with open_store(db) as st:              # and it still takes writes
        st.upsert(make_record(99))


def test_postgresql_crash_mid_write_leaves_a_consistent_store(fresh_pg_db: str) -> None:
    """The same on a real PostgreSQL server: after the SIGKILL the server has rolled the
    killed connection's transaction back (no session of it is left, no lock held), every
    stored record has all its metrics and lines, and the store takes writes at once."""
    import psycopg

    open_store(fresh_pg_db).close()
    _kill_a_writer_mid_write(fresh_pg_db)
    dbname = fresh_pg_db.rsplit('/', 1)[1]
    with psycopg.connect(fresh_pg_db) as con:
        end = time.monotonic() + 10.0   # the server notices the closed socket at once
        while True:
            left = con.execute('select count(*) from pg_stat_activity where datname = %s '
                               'and pid <> pg_backend_pid()', (dbname,)).fetchone()[0]
            if left == 0 or time.monotonic() > end:
                break
            time.sleep(0.1)
        assert left == 0, 'a session of the killed writer is still open'
        counts = con.execute('select r.id, count(m.id) from results r left join metrics m '
                             'on m.result_id = r.id group by r.id').fetchall()
        lines = con.execute('select count(*) from lines').fetchone()[0]
    assert counts, 'the writer wrote nothing before it was killed'
    assert {c for _, c in counts} == {304}
    assert lines == 2 * len(counts)
    with open_store(fresh_pg_db) as st:     # no lock left behind: this write goes through
        st.upsert(make_record(99))      # (the writer used units 0..49: a new record)
        assert len(st.query()) == len(counts) + 1


def test_migrations_match_the_orm(tmp_path: Path) -> None:
    """The schema the Alembic migrations build is the one the ORM declares."""
    from alembic.autogenerate import compare_metadata
    from alembic.runtime.migration import MigrationContext

    from rv_te_bench.store._schema import Base
    open_store(tmp_path / 'r.sqlite').close()
    engine = create_engine(f'sqlite:///{tmp_path / "r.sqlite"}')
    with engine.connect() as conn:
        diff = compare_metadata(MigrationContext.configure(conn), Base.metadata)
    engine.dispose()
    assert diff == []


def test_store_newer_than_the_software_is_refused(tmp_path: Path) -> None:
    db = tmp_path / 'r.sqlite'
    open_store(db).close()
    con = sqlite3.connect(db)
    con.execute("update alembic_version set version_num = '9999'")
    con.commit()
    con.close()
    with pytest.raises(StoreError, match="schema revision '9999', newer than"):
        open_store(db)


@pytest.mark.parametrize(('db', 'match'), [
    ('/no/such/folder/r.sqlite', 'does not exist'),
    ('postgresql://nobody@127.0.0.1:1/x', 'cannot open results store'),
    ('mysql+nodriver://x', 'cannot open results store|needs the Python module'),
])
def test_unreachable_store_one_line(db: str, match: str) -> None:
    with pytest.raises(StoreError, match=match) as exc:
        open_store(db)
    assert '\n' not in str(exc.value)


def test_export_csv_and_parquet(tmp_path: Path) -> None:
    with open_store(tmp_path / 'r.sqlite') as st:
        for i in range(4):
            st.upsert(make_record(i))
        rows = st.query()
    assert export_records(rows, tmp_path / 'r.csv') == 4
    with (tmp_path / 'r.csv').open(newline='') as fh:
        table = list(csv.DictReader(fh))
    assert [t['serial'] for t in table] == ['SN00000', 'SN00001', 'SN00002', 'SN00003']
    assert float(table[2]['te_pp_rad_cw']) == pytest.approx((5e-4 + 2e-6) * 1.1)
    assert float(table[1]['line_1_f_w_amplitude_rad']) == pytest.approx(2e-4 + 1e-7)
    import pyarrow.parquet as pq
    assert export_records(rows, tmp_path / 'r.parquet') == 4
    pt = pq.read_table(tmp_path / 'r.parquet').to_pydict()
    assert pt['serial'] == [t['serial'] for t in table]
    assert pt['te_pp_rad_ccw'] == pytest.approx([float(t['te_pp_rad_ccw']) for t in table])
    with pytest.raises(StoreError, match=r'use a \.csv or \.parquet'):
        export_records(rows, tmp_path / 'r.xlsx')


def test_postgresql_and_sqlite_give_the_same_results(tmp_path: Path, fresh_pg_db: str) -> None:
    """The same records written to SQLite and to a real PostgreSQL server; every query
    (all, each filter, a series) returns the same values in the same order."""
    recs = [make_record(i, preset='hu2020-rv' if i % 4 == 0 else 'wang2020-2kv',
                        verdict='fail' if i in (3, 7) else 'pass') for i in range(12)]
    t0 = datetime(2026, 11, 1, tzinfo=UTC)
    filters = [None, ResultFilter(serial='SN00005'), ResultFilter(verdict='fail'),
               ResultFilter(preset='hu2020-rv'),
               ResultFilter(since=t0 + timedelta(hours=3), until=t0 + timedelta(hours=9))]
    out = []
    for db in (tmp_path / 'r.sqlite', fresh_pg_db):
        with open_store(db) as st:
            for r in recs:
                st.upsert(r)
            st.upsert(recs[2])                    # again: an update, not a new row
            res = [_comparable(st.query(f)) for f in filters]
            ser = st.series('te_pp_rad', direction='cw')
            out.append((res, ser.values, ser.serials))
    assert out[0] == out[1]
    assert len(out[0][0][0]) == 12


def test_postgresql_concurrent_upsert_of_one_key(fresh_pg_db: str) -> None:
    """Two stores writing the same key one after the other end with one record."""
    with open_store(fresh_pg_db) as a, open_store(fresh_pg_db) as b:
        a.upsert(make_record(1))
        b.upsert(replace(make_record(1), verdict='fail'))
        rows = a.query()
    assert len(rows) == 1
    assert rows[0].verdict == 'fail'


def _long_text_outcome(db: str | Path) -> tuple[list[tuple], str]:
    """Store a 128-character serial and a 128-character plan (key 226 characters), try a
    129-character serial: what the store holds and the refusal's message."""
    ok = replace(make_record(1), serial='S' * 128)
    plan = replace(make_record(2), test='test-plan', plan='P' * 128)
    with open_store(db) as st:
        st.upsert(ok)
        st.upsert(plan)
        with pytest.raises(StoreError) as exc:
            st.upsert(replace(make_record(3), serial='S' * 129))
        rows = st.query()
    return [(r.serial, r.test, r.plan) for r in rows], str(exc.value)


def test_long_text_same_on_sqlite_and_postgresql(tmp_path: Path, fresh_pg_db: str) -> None:
    """Issue #21: SQLite ignores column lengths, PostgreSQL refuses ('value too long'): a
    record is checked against the widths before either sees it. A 128-character serial and
    plan are kept identically on both, a 129-character serial is refused with the same
    one-line message naming the field and the limit. Fails before: PostgreSQL raised
    'value too long for type character varying(200)' for the 226-character record key and
    accepted nothing the check did not know, SQLite kept the 129-character serial."""
    out_sqlite = _long_text_outcome(tmp_path / 'r.sqlite')
    out_pg = _long_text_outcome(fresh_pg_db)
    assert out_sqlite == out_pg
    rows, message = out_sqlite
    assert rows == [('S' * 128, 'te-analysis', ''), ('SN00002', 'test-plan', 'P' * 128)]
    assert message.startswith('serial is 129 characters, the results store keeps at most 128')
    assert '\n' not in message
    assert len(message) < 200


@pytest.mark.parametrize('field', ['serial', 'lot', 'operator', 'bench_id', 'preset', 'plan'])
def test_each_limited_field_refused_by_name(field: str) -> None:
    """Every String(128) column's field is checked, by name (issue #21)."""
    replace(make_record(1), **{field: 'x' * 128})
    with pytest.raises(StoreError, match=f'^{field} is 129 characters, .* at most 128'):
        replace(make_record(1), **{field: 'x' * 129})


def test_store_at_revision_0001_is_upgraded_keeping_its_records(tmp_path: Path) -> None:
    """A store made by the first schema (record_key 200 wide) is migrated to 0002 (256, batch
    mode on SQLite) when opened, and keeps its records."""
    from alembic import command
    from alembic.config import Config

    from rv_te_bench.store._store import _MIGRATIONS
    db = tmp_path / 'old.sqlite'
    engine = create_engine(f'sqlite:///{db}')
    cfg = Config()
    cfg.set_main_option('script_location', os.fspath(_MIGRATIONS))
    with engine.begin() as conn:
        cfg.attributes['connection'] = conn
        command.upgrade(cfg, '0001')
    engine.dispose()
    con = sqlite3.connect(db)
    assert 'VARCHAR(200)' in con.execute(
        "select sql from sqlite_master where name = 'results'").fetchone()[0]
    con.execute("insert into results (record_key, test, plan, serial, tested_at, analysed_at, "
                "status, verdict, command, software_version, bag_path, bag_sha256) values "
                "('k', 'te-analysis', '', 'OLD1', '2026-11-01 00:00:00', "
                "'2026-11-01 00:00:00', 'ok', 'pass', 'analyze', 'v', '/b', ?)", ('0' * 64,))
    con.commit()
    con.close()
    with open_store(db) as st:
        st.upsert(make_record(5))
    with open_store(db) as st:
        assert [r.serial for r in st.query()] == ['OLD1', 'SN00005']
    con = sqlite3.connect(db)
    assert con.execute('select version_num from alembic_version').fetchone()[0] == SCHEMA_HEAD
    assert 'VARCHAR(256)' in con.execute(
        "select sql from sqlite_master where name = 'results'").fetchone()[0]
    con.close()


def test_schema_head_is_alembics_head() -> None:
    """SCHEMA_HEAD (the store's no-alembic check) names the newest migration."""
    from alembic.config import Config
    from alembic.script import ScriptDirectory

    from rv_te_bench.store._store import _MIGRATIONS, SCHEMA_HEAD
    cfg = Config()
    cfg.set_main_option('script_location', os.fspath(_MIGRATIONS))
    assert ScriptDirectory.from_config(cfg).get_current_head() == SCHEMA_HEAD


def test_a_store_at_the_head_opens_without_alembic(tmp_path: Path) -> None:
    """Opening an up-to-date store (every rv-te analyze) does not import alembic; a new or
    old store does (it is migrated)."""
    db = tmp_path / 'r.sqlite'
    code = ('import sys; from rv_te_bench.store import open_store; '
            f'open_store({str(db)!r}).close(); print("alembic" in sys.modules)')
    runs = [subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                           check=True, timeout=120).stdout.split()[-1] for _ in range(2)]
    assert runs == ['True', 'False']   # created (migrated), then opened as it is


def test_store_at_0002_gains_the_u95_columns_and_keeps_its_metrics(tmp_path: Path) -> None:
    """Issue 35: revision 0003 adds metrics.u95 and the lines' U columns; a store written
    at 0002 keeps its metrics (U NULL, read back as none) and takes records with U."""
    from alembic import command
    from alembic.config import Config

    from rv_te_bench.store import LineValue, MetricValue
    from rv_te_bench.store._store import _MIGRATIONS
    db = tmp_path / 'v2.sqlite'
    engine = create_engine(f'sqlite:///{db}')
    cfg = Config()
    cfg.set_main_option('script_location', os.fspath(_MIGRATIONS))
    with engine.begin() as conn:
        cfg.attributes['connection'] = conn
        command.upgrade(cfg, '0002')
    engine.dispose()
    con = sqlite3.connect(db)
    con.execute("insert into results (id, record_key, test, plan, serial, tested_at, "
                "analysed_at, status, verdict, command, software_version, bag_path, "
                "bag_sha256) values (1, 'k', 'te-analysis', '', 'OLD2', '2026-11-01 00:00:00', "
                "'2026-11-01 00:00:00', 'ok', 'pass', 'analyze', 'v', '/b', ?)", ('0' * 64,))
    con.execute("insert into metrics (result_id, name, direction, value) values "
                "(1, 'te_pp_rad', 'all', 5e-4)")
    con.commit()
    con.close()
    rec = replace(make_record(7), verdict='indeterminate',
                  metrics=(MetricValue('te_pp_rad', 6e-4, u95=4e-6, limit_high=6.1e-4,
                                       verdict='indeterminate'),),
                  lines=(LineValue('1 f_w', 2e-4, amplitude_u95_rad=1e-8,
                                   phase_u95_rad=3e-3),))
    with open_store(db) as st:
        st.upsert(rec)
        old, new = st.query()
    assert old.metrics[('te_pp_rad', 'all')] == 5e-4 and old.u95 == {}
    assert new.u95 == {('te_pp_rad', 'all'): 4e-6} and new.verdict == 'indeterminate'
    assert new.line_u95 == {'1 f_w': (1e-8, 3e-3)}
    with open_store(db) as st:
        series = st.series('te_pp_rad')
    assert series.values == [5e-4, 6e-4] and series.u95 == [None, 4e-6]
    with pytest.raises(StoreError, match='u95 must be finite and >= 0'):
        MetricValue('te_pp_rad', 1.0, u95=-1.0)
