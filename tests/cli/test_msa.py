"""``rv-te msa``: the AIAG worked example through the results store and the command; the
simulated demo path; bad studies named in one line."""

from __future__ import annotations

import json
from datetime import UTC, datetime, timedelta
from pathlib import Path

import pytest

from rv_te_bench.cli.main import main
from rv_te_bench.store import MetricValue, UnitRecord, open_store
from tests.core.test_msa import AIAG

ARCMIN = 1.0 / 3437.7467707849396   # rad per arcmin


@pytest.fixture(scope='module')
def aiag_store(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The AIAG MSA 4th ed. study as 90 records: part k -> serial, appraiser -> operator,
    the value stored as a lost motion in rad (shown in arcmin: the manual's numbers)."""
    db = tmp_path_factory.mktemp('msa') / 'r.sqlite'
    t0 = datetime(2026, 11, 1, tzinfo=UTC)
    n = 0
    with open_store(db) as st:
        for trial in range(3):
            for op in 'ABC':
                for part, v in enumerate(AIAG[op][trial]):
                    st.upsert(UnitRecord(
                        test='test-plan', plan='msa', bag_path=f'/bags/{n}',
                        bag_sha256=f'{n:064x}', tested_at=t0 + timedelta(minutes=n),
                        serial=f'P{part + 1:02d}', operator=op,
                        metrics=(MetricValue('lost_motion_rad', v * ARCMIN),)))
                    n += 1
    return db


def test_grr_of_the_aiag_records_gives_the_manuals_numbers(
        aiag_store: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(['msa', 'grr', 'lost_motion_rad', '--db', str(aiag_store), '--json']) == 0
    doc = json.loads(capsys.readouterr().out)
    assert (doc['parts'], doc['operators'], doc['repeats']) == (10, 3, 3)
    assert doc['operator_names'] == ['A', 'B', 'C']
    assert doc['interaction_pooled'] is True
    assert doc['grr'] == pytest.approx(0.302373, abs=5e-6)     # AIAG Table III-B 6a
    assert doc['pv'] == pytest.approx(1.042327, abs=5e-6)
    assert round(doc['pct_grr_of_process'], 1) == 27.9
    assert doc['ndc'] == 4
    # the human summary says the same
    assert main(['msa', 'grr', 'lost_motion_rad', '--db', str(aiag_store),
                 '--tolerance', '6']) == 0
    out = capsys.readouterr().out
    assert '10 parts x 3 operators (A, B, C) x 3 repeats [arcmin]' in out
    assert '%GRR of the process variation 27.9 %' in out and 'ndc 4' in out
    assert 'of the tolerance 6 arcmin (given) 30.2 %' in out and 'unacceptable' in out


def test_type1_of_one_part_needs_25_repeats(aiag_store: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    assert main(['msa', 'type1', 'lost_motion_rad', '--db', str(aiag_store), '--serial', 'P01',
                 '--tolerance', '2']) == 1
    assert capsys.readouterr().err.strip() == (
        'ERROR: a type 1 study needs at least 25 repeats, got 9')


@pytest.mark.parametrize(('argv', 'says'), [
    (['grr', 'te_pp_rad'], "no values of 'te_pp_rad' (direction all)"),
    (['grr', 'lost_motion_rad', '--repeats', '4'], 'has only 3 records'),
    (['grr', 'lost_motion_rad', '--serial', 'P01'], '>= 2 parts'),
    (['type1', 'lost_motion_rad'], 'give --serial'),
    (['type1', 'lost_motion_rad', '--serial', 'P01', '--lsl', '0.1'], 'a lower limit alone'),
])
def test_bad_studies_are_one_line(aiag_store: Path, capsys: pytest.CaptureFixture[str],
                                  argv: list[str], says: str) -> None:
    assert main(['msa', *argv, '--db', str(aiag_store)]) == 1
    err = capsys.readouterr().err
    assert err.startswith('ERROR: ') and err.count('\n') == 1 and says in err, err


def test_unbalanced_study_names_the_missing_cell(aiag_store: Path, tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    db = tmp_path / 'u.sqlite'
    with open_store(aiag_store) as src, open_store(db) as dst:
        for r in src.query():
            if (r.serial, r.operator) != ('P03', 'B'):
                dst.upsert(UnitRecord(test='test-plan', plan='msa', bag_path=r.bag_path,
                                      bag_sha256=r.bag_sha256, tested_at=r.tested_at,
                                      serial=r.serial, operator=r.operator, metrics=tuple(
                                          MetricValue(n, v, direction=d)
                                          for (n, d), v in r.metrics.items())))
    assert main(['msa', 'grr', 'lost_motion_rad', '--db', str(db)]) == 1
    assert 'P03/B' in capsys.readouterr().err


@pytest.mark.slow
def test_demo_on_the_simulated_bench(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Three parts, two operators, two repeats with re-mounting, 25 type 1 repeats: the
    records land in the store, the R&R sees the parts, the type 1 study its reference."""
    db = tmp_path / 'msa.sqlite'
    assert main(['msa', 'demo', '--db', str(db), '--parts', '3', '--repeats', '2',
                 '--json']) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc['records'] == 3 * 2 * 2 + 25
    grr_te, t1_te, grr_lm, _ = doc['studies']
    assert grr_te['study'] == 'grr' and grr_te['parts'] == 3 and grr_te['repeats'] == 2
    assert grr_te['operator_names'] == ['A', 'B']
    # re-mounting moves the TE p-p (repeatability > 0); the parts differ far more
    assert 0 < grr_te['ev'] < grr_te['pv']
    assert t1_te['study'] == 'type1' and t1_te['n'] == 25
    assert t1_te['reference'] is not None and t1_te['cgk'] is not None
    assert grr_lm['metric'] == 'lost_motion_rad'
    with open_store(db) as st:
        assert len(st.query()) == doc['records']
