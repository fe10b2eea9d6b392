"""One results store per user (issue 33 s.3): what rv-te test and rv-te analyze record, in
whatever folder, rv-te results finds without --db; every command names the store.

The session bag of a plan run on the simulated bench is written by rosbags
(tests.acceptance.recorded_data); the verdicts come from a tolerance the test sets.
"""

from __future__ import annotations

import json
import re
from typing import TYPE_CHECKING

import pytest
import yaml

from rv_te_bench.cli.main import main
from tests import wang2020_reference as ref
from tests.acceptance.recorded_data import run_plan, write_session_bag
from tests.unit_bags import unit_bag

if TYPE_CHECKING:
    from pathlib import Path

TE_ONLY = {'plan': 'te-only', 'steps': [
    {'kind': 'te', 'name': 'te', 'speed_rpm': 3000, 'load_nm': 200, 'settle_s': 0.2}]}
#: A limit no unit meets: both tests fail.
STRICT = {'profile': 'strict', 'limits': {'te_pp_arcmin': {
    'max': 0.001, 'source': 'a limit no unit meets (test)'}}}


def test_two_failing_tests_are_listed_by_rv_te_results(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], default_store: Path) -> None:
    """The README's order: two units tested (both fail), then ``rv-te results --since ...
    --verdict fail`` lists both (before: 'no records match', the tests were in
    out/tests/...sqlite, results read ./bags/)."""
    plan = tmp_path / 'plan.yaml'
    plan.write_text(yaml.safe_dump(TE_ONLY), encoding='utf-8')
    tol = tmp_path / 'strict.yaml'
    tol.write_text(yaml.safe_dump(STRICT), encoding='utf-8')
    for k, serial in enumerate(('RV-A1', 'RV-A2')):
        bag = write_session_bag(tmp_path / f'line{k}' / 'session', run_plan(TE_ONLY, seed=k))
        rc = main(['test', str(plan), '--from', str(bag), '--tolerance', str(tol),
                   '--serial', serial, '--operator', 'kim',
                   '--out-dir', str(tmp_path / f'out{k}')])
        out = capsys.readouterr().out
        assert rc == 3, out
        assert f'results store {default_store}' in out
    assert main(['results', '--since', '2020-01-01', '--verdict', 'fail', '--json']) == 0
    cap = capsys.readouterr()
    assert sorted(r['serial'] for r in json.loads(cap.out)) == ['RV-A1', 'RV-A2']
    assert f'results store {default_store} (2 records): 2 match' in cap.err
    # nothing matches: the store and its record count are named
    assert main(['results', '--serial', 'NOBODY']) == 0
    out = capsys.readouterr().out
    assert out.strip() == f'no records match in the results store {default_store} (2 records)'


def test_analyses_in_two_folders_go_to_one_store(tmp_path: Path, default_store: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    import numpy as np

    rng = np.random.default_rng(5)
    for folder in ('shift1', 'shift2'):
        bag = unit_bag(tmp_path / folder / 'run', ref.table2_unit(), rng, rate_hz=1000.0,
                       custom_data={'unit_serial': f'SN-{folder}'})
        assert main(['analyze', str(bag), '--no-advice', '--quiet']) == 0
        out = capsys.readouterr().out
        assert re.search(rf'recorded in the results store {re.escape(str(default_store))} '
                         r'\(\d records?\)', out), out
    assert main(['results', '--json']) == 0
    assert sorted(r['serial'] for r in json.loads(capsys.readouterr().out)) == [
        'SN-shift1', 'SN-shift2']
    assert not list(tmp_path.rglob('rv-te-results.sqlite'))    # nothing next to the bags


def test_rv_te_db_moves_the_store_and_a_missing_one_is_named(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    other = tmp_path / 'lab.sqlite'
    monkeypatch.setenv('RV_TE_DB', str(other))
    assert main(['results']) == 1
    err = capsys.readouterr().err
    assert err.startswith(f'ERROR: no results store at {other} (from $RV_TE_DB)')
    assert len(err.strip().splitlines()) == 1
