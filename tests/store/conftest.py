"""Fixtures of the results-store tests: records, and a real PostgreSQL server of our own.

The PostgreSQL server is started by the test session itself (initdb into a temporary
folder, pg_ctl on a free port, trust authentication on 127.0.0.1), as the ``postgres``
system user when the tests run as root (the server refuses root), and stopped at the end.
Where the server binaries are missing the PostgreSQL tests are skipped with a loud reason,
unless RV_TE_REQUIRE_POSTGRES=1 (set by .ci/run, which installs the package), which turns
the skip into a failure.
"""

from __future__ import annotations

import glob
import os
import pwd
import shutil
import socket
import subprocess
import tempfile
from datetime import UTC, datetime, timedelta
from pathlib import Path

import pytest

from rv_te_bench.store import LineValue, MetricValue, UnitRecord


def _pg_bin(name: str) -> str | None:
    hits = sorted(glob.glob(f'/usr/lib/postgresql/*/bin/{name}'))
    return hits[-1] if hits else shutil.which(name)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        return int(s.getsockname()[1])


@pytest.fixture(scope='session')
def postgres_url():
    """URL of a fresh PostgreSQL server of this test session (stopped afterwards)."""
    initdb, pg_ctl = _pg_bin('initdb'), _pg_bin('pg_ctl')
    if initdb is None or pg_ctl is None:
        reason = ('PostgreSQL server binaries (initdb, pg_ctl) not found: install the '
                  "Debian package 'postgresql' (.ci/run does) to run the PostgreSQL tests")
        if os.environ.get('RV_TE_REQUIRE_POSTGRES') == '1':
            pytest.fail(reason)
        pytest.skip(reason)
    pytest.importorskip('psycopg', reason="psycopg missing: pip install 'rv-te-bench[postgres]'")
    prefix: list[str] = []
    owner = None
    if os.geteuid() == 0:
        try:
            owner = pwd.getpwnam('postgres')
        except KeyError:
            pytest.fail('running as root and there is no postgres user to run the server as')
        prefix = ['runuser', '-u', 'postgres', '--']
    root = Path(tempfile.mkdtemp(prefix='rv-te-pg-'))
    data = root / 'data'
    if owner is not None:
        os.chown(root, owner.pw_uid, owner.pw_gid)
    port = _free_port()
    env = {**os.environ, 'LC_ALL': 'C.UTF-8'}
    subprocess.run([*prefix, initdb, '-D', str(data), '-A', 'trust', '-U', 'rvte',
                    '-E', 'UTF8'], check=True, capture_output=True, timeout=120, env=env)
    opts = f"-F -p {port} -k {root} -c listen_addresses=127.0.0.1"
    subprocess.run([*prefix, pg_ctl, '-D', str(data), '-o', opts, '-l', str(root / 'log'),
                    '-w', '-t', '60', 'start'], check=True, capture_output=True, timeout=90,
                   env=env)
    try:
        yield f'postgresql://rvte@127.0.0.1:{port}/postgres'
    finally:
        subprocess.run([*prefix, pg_ctl, '-D', str(data), '-m', 'immediate', 'stop'],
                       capture_output=True, timeout=60, check=False)
        shutil.rmtree(root, ignore_errors=True)


@pytest.fixture
def fresh_pg_db(postgres_url: str):
    """A new empty database on the session's server, dropped afterwards."""
    import psycopg
    name = f'rvte_{os.getpid()}_{os.urandom(4).hex()}'
    with psycopg.connect(postgres_url, autocommit=True) as conn:
        conn.execute(f'CREATE DATABASE {name}')
    try:
        yield postgres_url.rsplit('/', 1)[0] + '/' + name
    finally:
        with psycopg.connect(postgres_url, autocommit=True) as conn:
            conn.execute(f'DROP DATABASE IF EXISTS {name} WITH (FORCE)')


def make_record(i: int, *, serial: str | None = None, preset: str = 'wang2020-2kv',
                te_pp_rad: float | None = None, verdict: str = 'not-judged',
                n_extra_metrics: int = 0, lot: str | None = None) -> UnitRecord:
    """A record of unit ``i`` (hash, time and values derived from i)."""
    base = datetime(2026, 11, 1, tzinfo=UTC) + timedelta(hours=i)
    pp = te_pp_rad if te_pp_rad is not None else 5e-4 + 1e-6 * i
    metrics = [MetricValue('te_pp_rad', pp), MetricValue('te_std_rad', pp / 4),
               MetricValue('te_pp_rad', pp * 1.1, direction='cw'),
               MetricValue('te_pp_rad', pp * 0.9, direction='ccw', limit_high=4.6e-4,
                           verdict='fail' if pp * 0.9 > 4.6e-4 else 'pass')]
    metrics += [MetricValue(f'extra_{k}_rad', float(k)) for k in range(n_extra_metrics)]
    return UnitRecord(
        test='te-analysis', bag_path=f'/bags/unit{i:04d}', bag_sha256=f'{i:064x}',
        tested_at=base, serial=serial or f'SN{i:05d}', lot=lot, bench_id='bench-1',
        preset=preset, reducer_type='2kv', verdict=verdict, software_version='test',
        metrics=tuple(metrics),
        lines=(LineValue('1 f_w', 2e-4 + 1e-7 * i, output_order=25.0, crank_order=1.0,
                         phase_rad=0.1 * i),
               LineValue('f_out', 9e-5, output_order=1.0)),
        advice={'method': 'identified-assembly-phases', 'te_after_rad': 1.7e-4},
        details={'speed_rpm': 300})
