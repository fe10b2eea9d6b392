"""Fleet analysis on a real local Dask cluster: one record per good bag, failures recorded,
the same metrics as ``rv-te analyze`` of each bag alone, a killed worker loses nothing.

The bags are written by rosbags (tests/unit_bags.py) from units of the independent Wang
2020 model in tests/wang2020_reference.py; two more are damaged.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from rv_te_bench.fleet import FleetOptions, discover_bags, run_fleet
from rv_te_bench.store import open_store, records_from_analysis_json
from tests import wang2020_reference as ref
from tests.unit_bags import unit_bag

pytest.importorskip('distributed')
RV_TE = [sys.executable, '-m', 'rv_te_bench.cli.main']
N_GOOD = 6


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env.pop('_ROS_WHEELS_BOOTSTRAP_COMPLETE', None)
    env.pop('RV_TE_DB', None)
    return env


@pytest.fixture(scope='module')
def fleet_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """6 unit bags (1 kHz, 2 output revolutions) + a bag with broken metadata + a lone
    .mcap of garbage, in nested folders."""
    root = tmp_path_factory.mktemp('fleet')
    rng = np.random.default_rng(21)
    for i in range(N_GOOD):
        unit_bag(root / f'day{i % 2}' / f'unit{i}', ref.random_unit(rng), rng,
                 rate_hz=1000.0, duration_s=32.0)
    bad = root / 'day0' / 'broken'
    bad.mkdir()
    (bad / 'metadata.yaml').write_text('rosbag2_bagfile_information: {version: 9\n')
    (root / 'day1' / 'garbage.mcap').write_bytes(b'\x89MCAP0\r\n' + b'\x00' * 500)
    return root


def test_discover_bags(fleet_dir: Path) -> None:
    bags = discover_bags([str(fleet_dir)])
    assert len(bags) == N_GOOD + 2
    assert discover_bags([str(fleet_dir / 'day0' / 'unit*')]) == sorted(
        (fleet_dir / 'day0').glob('unit*'))
    from rv_te_bench.errors import BagError
    with pytest.raises(BagError, match='no such file'):
        discover_bags([str(fleet_dir / 'nope')])
    with pytest.raises(BagError, match='names no bag'):
        discover_bags([str(fleet_dir / 'x*')])


def test_fleet_command_records_every_bag_like_analyze(fleet_dir: Path, tmp_path: Path) -> None:
    """``rv-te fleet analyze`` with 2 workers: 6 ok records, 2 failed ones with reasons,
    exit 1 naming the failures; each record's metrics and lines equal those of
    ``rv-te analyze BAG --json`` run alone; a rerun skips the 6, tries the 2 again."""
    db = tmp_path / 'r.sqlite'
    cmd = [*RV_TE, 'fleet', 'analyze', str(fleet_dir), '--workers', '2', '--db', str(db),
           '--json', '--quiet']
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=300, env=_env(),
                       check=False)
    assert p.returncode == 1, p.stderr
    assert p.stderr.count('\n') == 1 and p.stderr.startswith('ERROR: 2 of 8 bag(s) failed')
    summary = json.loads(p.stdout)
    assert (summary['ok'], summary['failed'], summary['skipped']) == (N_GOOD, 2, 0)
    with open_store(db) as st:
        rows = st.query()
    assert len(rows) == N_GOOD + 2
    failed = {Path(r.bag_path).name: r.failure for r in rows if r.status == 'failed'}
    assert set(failed) == {'broken', 'garbage.mcap'}
    assert 'metadata.yaml' in failed['broken']
    # the garbage is named as what it is, not as a bag without BenchInfo (issue #21)
    assert 'is not a readable MCAP bag' in failed['garbage.mcap'], failed['garbage.mcap']
    assert '--ratio' not in failed['garbage.mcap']
    good = [r for r in rows if r.status == 'ok']
    assert len(good) == N_GOOD
    for r in good:
        alone = subprocess.run([*RV_TE, 'analyze', r.bag_path, '--json', '--no-db'],
                               capture_output=True, text=True, timeout=120, env=_env(),
                               check=False)
        assert alone.returncode == 0, alone.stderr
        (rec,) = records_from_analysis_json(json.loads(alone.stdout),
                                            bag_paths=[Path(r.bag_path)], command='analyze',
                                            software_version='x')
        assert rec.bag_sha256 == r.bag_sha256
        assert r.metrics == {(m.name, m.direction): m.value for m in rec.metrics}
        assert r.lines == {ln.label: (ln.amplitude_rad, ln.phase_rad) for ln in rec.lines}
        assert r.advice == rec.advice
    p2 = subprocess.run(cmd, capture_output=True, text=True, timeout=300, env=_env(),
                        check=False)
    again = json.loads(p2.stdout)
    assert (again['skipped'], again['failed'], again['ok']) == (N_GOOD, 2, 0)
    with open_store(db) as st:
        assert len(st.query()) == N_GOOD + 2           # updated, not duplicated


def test_killed_worker_loses_no_result(fleet_dir: Path, tmp_path: Path) -> None:
    """SIGKILL of a worker process while it analyses a bag: the scheduler runs the bag
    again elsewhere and every bag still ends with its record."""
    bags = [b for b in discover_bags([str(fleet_dir)]) if b.name.startswith('unit')]
    killed: list[int] = []

    def killer(client) -> None:
        def go() -> None:
            deadline = time.monotonic() + 60
            while time.monotonic() < deadline and not killed:
                busy = {w: ks for w, ks in client.processing().items() if ks}
                if busy:
                    addr = next(iter(busy))
                    pids = client.run(os.getpid, workers=[addr])
                    pid = pids[addr]
                    os.kill(pid, signal.SIGKILL)
                    killed.append(pid)
                    return
                time.sleep(0.02)
        threading.Thread(target=go, daemon=True).start()

    with open_store(tmp_path / 'r.sqlite') as st:
        summary = run_fleet(bags, st, options=FleetOptions(), workers=2, on_client=killer)
        rows = st.query()
    assert killed, 'no worker was busy to be killed'
    assert summary.failed == 0, summary.failures
    assert summary.ok == N_GOOD
    assert sorted(r.bag_path for r in rows) == sorted(str(b) for b in bags)
    assert all(r.status == 'ok' and r.metrics for r in rows)


def test_a_busy_dashboard_port_prints_nothing(tmp_path: Path) -> None:
    """Another Dask cluster holding port 8787 made `rv-te fleet analyze` print a UserWarning
    (its scheduler's HTTP server) before its one result line."""
    import socket
    import warnings

    from rv_te_bench.fleet._run import _client

    with socket.socket() as s:
        try:
            s.bind(('127.0.0.1', 8787))
        except OSError:
            pytest.skip('port 8787 is taken by something else here')
        s.listen()
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter('always')
            client, cluster = _client(1, None)
            client.close()
            cluster.close()
    assert not [w for w in caught if '8787' in str(w.message)]


def test_workers_read_without_the_read_ahead_thread_when_they_fill_the_cores() -> None:
    """With a worker per core, parallel bags use the cores; each analysis's read-ahead
    thread (~0.16 of a core more) would oversubscribe them (benchmarks/README, fleet row)."""
    import os

    from rv_te_bench.fleet._run import _client

    client, cluster = _client(2, None)
    try:
        got = set(client.run(lambda: os.environ.get('RV_TE_READ_AHEAD')).values())
    finally:
        client.close()
        cluster.close()
    assert got == ({'0'} if (os.cpu_count() or 1) <= 2 else {None})


def test_local_workers_come_forked_with_the_analysis_imported() -> None:
    """Issue 41: a local cluster's workers are forked from one fork server that imported the
    analysis (``fleet._warm``) once; no worker imports it itself. Fails before: Dask set
    its own preload list on the fork server (numpy, pandas, ...), replacing ours, and each
    worker imported the analysis at its start (~0.6 CPU s each, per run)."""
    from rv_te_bench.fleet._run import _client

    def where_imported() -> tuple[int, int | None]:
        warm = sys.modules.get('rv_te_bench.fleet._warm')
        return os.getpid(), getattr(warm, 'IMPORTED_IN_PID', None)

    def profiling(dask_worker: Any) -> bool:      # Dask passes its Worker
        return 'profile' in dask_worker.periodic_callbacks

    def tick_ms(dask_worker: Any) -> float:
        return dask_worker.periodic_callbacks['tick'].callback_time

    client, cluster = _client(2, None)
    try:
        got = list(client.run(where_imported).values())
        profiled = set(client.run(profiling).values())
        ticks = {*client.run(tick_ms).values(),
                 cluster.scheduler.periodic_callbacks['tick'].callback_time}
    finally:
        client.close()
        cluster.close()
    assert profiled == {False}          # no stack sampling beside the analysis (issue 41)
    assert ticks == {1000.0}            # loop health checked each second, not every 20 ms
    assert len(got) == 2
    (server,) = {imported for _, imported in got}        # one fork server for both
    assert server is not None and server not in {pid for pid, _ in got}


def test_what_the_workers_import_leaves_out_the_database() -> None:
    """The fork server imports what a worker needs (``fleet._warm``) once per run: the
    analysis and the records, not the store's database side (SQLAlchemy, ~0.3 CPU s),
    which only the client uses. Fails before: ``rv_te_bench.store`` imported it."""
    code = ('import sys, rv_te_bench.fleet._warm; print(sorted(m for m in ("sqlalchemy", '
            '"alembic", "pandas", "matplotlib") if m in sys.modules))')
    p = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                       timeout=120, env=_env(), check=False)
    assert p.returncode == 0, p.stderr
    assert p.stdout.strip() == '[]'


def test_a_bag_at_two_paths_is_one_record_and_reruns_skip_both(fleet_dir: Path,
                                                                tmp_path: Path) -> None:
    """Issue #21: records are keyed by content hash, the rerun skipped by path. A unit's bag
    copied to a second folder is one test of one unit: one record (the first path), the
    summary names both paths; a rerun (and one after the copy's mtime changed) skips
    both and the record's path stays. Fails before: '3 analysed' for 2 records, every
    rerun '1 analysed, 2 skipped' with the record's bag_path flipping between the copies.
    Without the reassembly advice (the phase search, ~2.5 CPU s a bag): which bags are
    analysed, skipped or paired does not depend on it."""
    import shutil
    root = tmp_path / 'bags'
    shutil.copytree(fleet_dir / 'day0' / 'unit0', root / 'a' / 'unit0')
    shutil.copytree(fleet_dir / 'day0' / 'unit0', root / 'b' / 'unit0-copy')
    shutil.copytree(fleet_dir / 'day1' / 'unit1', root / 'a' / 'unit1')
    db = tmp_path / 'r.sqlite'
    cmd = [*RV_TE, 'fleet', 'analyze', str(root), '--workers', '1', '--db', str(db),
           '--quiet', '--no-advice']
    first_path = str(root / 'a' / 'unit0')
    pair = [first_path, str(root / 'b' / 'unit0-copy')]
    runs = []
    for touch in (False, False, True):
        if touch:
            os.utime(root / 'b' / 'unit0-copy' / 'metadata.yaml', (1e9, 1e9))
        p = subprocess.run([*cmd, '--json'], capture_output=True, text=True, timeout=300,
                           env=_env(), check=False)
        assert p.returncode == 0, p.stderr
        s = json.loads(p.stdout)
        runs.append((s['ok'], s['skipped'], s.get('duplicate_paths'), s.get('duplicates')))
        with open_store(db) as st:
            rows = st.query()
        assert len(rows) == 2
        assert sorted(r.bag_path for r in rows) == [first_path, str(root / 'a' / 'unit1')]
    assert runs == [(2, 0, 1, [pair]), (0, 2, 1, [pair]), (0, 2, 1, [pair])]
    text = subprocess.run(cmd, capture_output=True, text=True, timeout=300, env=_env(),
                          check=False)
    assert text.returncode == 0, text.stderr
    assert '0 analysed' in text.stdout and '2 skipped' in text.stdout
    assert f'2 paths hold the same bag (one record, {first_path}): {", ".join(pair)}' \
        in text.stdout


# The scheduler answers every heartbeat of a worker late, as a busy one does (seen at load
# 13): a worker's shutdown then nearly always finds a heartbeat waiting for its reply.
_LATE_HEARTBEATS = """
import asyncio, sys
from distributed.scheduler import Scheduler

_init = Scheduler.__init__

def _late_heartbeats(self, *args, **kwargs):
    _init(self, *args, **kwargs)
    answer = self.handlers['heartbeat_worker']

    async def late(**kw):
        await asyncio.sleep(LATE_S)
        return answer(**kw)

    self.handlers['heartbeat_worker'] = late

Scheduler.__init__ = _late_heartbeats

if __name__ == '__main__':
    from rv_te_bench.cli.main import main
    sys.exit(main(sys.argv[1:]))
"""


def test_a_busy_scheduler_leaves_stderr_clean_at_shutdown(fleet_dir: Path,
                                                          tmp_path: Path) -> None:
    """A worker that closes cuts off its own heartbeat still waiting for the scheduler's
    reply, and Dask logged 'Failed to communicate with scheduler during heartbeat' at ERROR
    with a traceback on the command's stderr (before: in 2 of 2 runs like this one, 3 of 3
    with replies 0.3 s late). With every reply 1 s late, `rv-te fleet analyze --quiet
    --json` prints nothing there."""
    script = tmp_path / 'late_heartbeats.py'
    script.write_text(_LATE_HEARTBEATS.replace('LATE_S', '1.0'), encoding='utf-8')
    p = subprocess.run([sys.executable, str(script), 'fleet', 'analyze',
                        str(fleet_dir / 'day0' / 'unit0'), '--workers', '1', '--no-advice',
                        '--db', str(tmp_path / 'r.sqlite'), '--json', '--quiet'],
                       capture_output=True, text=True, timeout=300, env=_env(), check=False)
    assert p.returncode == 0, p.stderr
    assert json.loads(p.stdout)['ok'] == 1
    assert p.stderr == ''
