"""``rv-te results`` and ``rv-te spc`` on a store filled with known records."""

from __future__ import annotations

import csv
import json
import os
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from rv_te_bench.store import MetricValue, open_store
from tests.store.conftest import make_record

RV_TE = [sys.executable, '-m', 'rv_te_bench.cli.main']
STEP_AT = 40
ARCMIN = 1.0 / 3437.7467707849396   # rad per arcmin


def _run(*args: str, ok: int = 0) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ)
    env.pop('_ROS_WHEELS_BOOTSTRAP_COMPLETE', None)
    env.pop('RV_TE_DB', None)
    p = subprocess.run([*RV_TE, *args], capture_output=True, text=True, timeout=120, env=env,
                       check=False)
    assert p.returncode == ok, (p.returncode, p.stdout, p.stderr)
    return p


@pytest.fixture(scope='module')
def store_with_step(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """60 units; TE p-p per revolution ~ N(0.60', 0.03') and from unit 40 on 0.12' more
    (a worn part); units 50-59 in lots of 5."""
    db = tmp_path_factory.mktemp('spc') / 'r.sqlite'
    rng = np.random.default_rng(5)
    pp = rng.normal(0.60, 0.03, 60)
    pp[STEP_AT:] += 0.12
    with open_store(db) as st:
        for i, v in enumerate(pp):
            rec = make_record(i, lot=f'L{i // 5}', verdict='fail' if v > 0.75 else 'pass')
            st.upsert(replace(rec, metrics=(
                *rec.metrics, MetricValue('te_pp_revolution_max_rad', float(v) * ARCMIN))))
    return db


def test_results_filters_and_export(store_with_step: Path, tmp_path: Path) -> None:
    p = _run('results', '--db', str(store_with_step), '--serial', 'SN00007')
    assert 'SN00007' in p.stdout and '1 record(s)' in p.stdout
    p = _run('results', '--db', str(store_with_step), '--since', '2026-11-02',
             '--until', '2026-11-02', '--json')
    got = json.loads(p.stdout)
    assert [r['serial'] for r in got] == [f'SN{i:05d}' for i in range(24, 48)]  # one day
    out = tmp_path / 'all.csv'
    _run('results', '--db', str(store_with_step), '--export', str(out))
    with out.open(newline='') as fh:
        assert len(list(csv.DictReader(fh))) == 60
    p = _run('results', '--db', str(tmp_path / 'none.sqlite'), ok=1)
    assert p.stderr.startswith('ERROR: no results store at') and p.stderr.count('\n') == 1
    p = _run('results', '--db', str(store_with_step), '--since', 'yesterday', ok=2)
    assert 'not an ISO 8601 date' in p.stderr


def test_spc_step_change_fires_at_or_just_after_the_step(store_with_step: Path,
                                                        tmp_path: Path) -> None:
    """Baseline the first 20 units: the first rule violation is at unit 40 or within 5
    after it, none before; capability against TE <= 1 arcmin is reported; the PNG, HTML
    and JSON are written."""
    rep = tmp_path / 'rep'
    p = _run('spc', 'te_pp_revolution_max_rad', '--db', str(store_with_step), '--usl', '1.0',
             '--json', '--report', str(rep))
    doc = json.loads(p.stdout)
    hits = doc['chart']['hits']
    assert hits
    assert STEP_AT <= hits[0]['index'] <= STEP_AT + 5, hits[:3]
    assert doc['unit'] == 'arcmin'
    assert doc['chart']['centre'] == pytest.approx(0.60, abs=0.02)
    cap = doc['capability']
    assert cap['usl'] == pytest.approx(1.0)
    assert cap['cp'] is None and cap['cpk'] > 2.0
    assert (rep / 'spc.png').read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    assert 'rule violation' in (rep / 'spc.html').read_text()
    assert json.loads((rep / 'spc.json').read_text())['chart']['hits'] == hits


def test_spc_by_lot_and_line(store_with_step: Path) -> None:
    p = _run('spc', 'te_pp_revolution_max_rad', '--db', str(store_with_step), '--by-lot',
             '--baseline', '6', '--json')
    doc = json.loads(p.stdout)
    assert doc['chart']['kind'] == 'xbar-r'
    assert doc['chart']['sizes'] == [5] * 12
    assert doc['chart']['hits'][0]['index'] >= STEP_AT // 5
    p = _run('spc', 'line:1 f_w', '--db', str(store_with_step))
    assert 'line:1 f_w across 60 units [arcmin]' in p.stdout


def test_spc_bad_metric_one_line(store_with_step: Path) -> None:
    p = _run('spc', 'te_pp', '--db', str(store_with_step), ok=1)
    assert p.stderr.startswith("ERROR: no values of 'te_pp'") and 'te_pp_rad' in p.stderr
    assert p.stderr.count('\n') == 1
