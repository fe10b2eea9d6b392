"""``rv-te analyze`` of a locked-input (hysteresis) record: its TE section says it is not a
TE record, in one line, instead of a table of numbers (the TE of a held input is the
output's torsion under load: 8.4' p-p and a 4175' amplitude on this record before), in
the terminal, the JSON, the HTML report and the results store; its lost motion, backlash
and rigidity are still read (within 2 % of the closed form's truth). The bag is written by
rosbags' own writer from a closed-form unit (tests/core/hysteresis_records.py), not by the
suite.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from rv_te_bench.cli.main import main
from sim.program import ProgramSimulator
from tests.acceptance.recorded_data import Run, write_session_bag
from tests.core.hysteresis_records import Unit, step_torques, torque_step_record

UNIT = Unit()
TRUTH = UNIT.truth()
BLOCK = 100


@pytest.fixture(scope='module')
def locked_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Two load cycles with the input held at 2.5 rad, as a session bag (rosbags)."""
    rec = torque_step_record(UNIT, step_torques(UNIT, cycles=2), np.random.default_rng(7))
    info = ProgramSimulator(preset='li2023-rv', te_mode='dte', sample_rate_hz=1000.0,
                            block_size=BLOCK, seed=1).info
    t = np.asarray(rec.time_s, dtype=np.float64)
    n = t.size // BLOCK * BLOCK
    blocks = [SimpleNamespace(
        seq=k, t0_s=float(t[a]), time_offset_s=t[a:a + BLOCK] - t[a],
        theta_in_rad=np.full(BLOCK, 2.5), theta_out_rad=rec.angle_rad[a:a + BLOCK],
        # the load cell reads the applied torque; the suite's torque is the output's
        torque_out_nm=-np.asarray(rec.torque_nm[a:a + BLOCK]))
        for k, a in enumerate(range(0, n, BLOCK))]
    path = tmp_path_factory.mktemp('locked') / 'bag'
    return write_session_bag(path, Run(report={}, info=info, blocks=blocks))  # type: ignore[arg-type]


def _within_truth(metrics: dict[str, float | None]) -> None:
    for name, truth in TRUTH.items():
        v = metrics[name]
        assert v is not None and math.isfinite(v) and abs(v / truth - 1) <= 0.02, (name, v)


def test_text_says_not_a_te_record(locked_bag: Path,
                                   capsys: pytest.CaptureFixture[str]) -> None:
    assert main(['analyze', str(locked_bag), '--no-db', '--quiet']) == 0
    cap = capsys.readouterr()
    lines = cap.out.splitlines()
    te = [ln for ln in lines if ln.strip().startswith('TE')]
    assert len(te) == 1 and te[0].strip().startswith('TE: not a TE record: the input is held'), \
        cap.out
    for absent in ('cumulative', 'TE p-p', 'spectrum:', 'zero:', 'recommendation'):
        assert absent not in cap.out, (absent, cap.out)
    assert 'no complete output revolution' not in cap.out + cap.err
    lm = next(ln for ln in lines if 'lost motion (+-' in ln)
    assert float(lm.split()[5]) == pytest.approx(TRUTH['lost_motion_rad'] * 10800 / math.pi,
                                                 rel=0.02)


def test_json_report_and_store(locked_bag: Path, tmp_path: Path,
                               capsys: pytest.CaptureFixture[str]) -> None:
    from rv_te_bench.store import open_store

    db = tmp_path / 'results.db'
    assert main(['analyze', str(locked_bag), '--json', '--quiet', '--db', str(db),
                 '--report', str(tmp_path / 'rep')]) == 0
    doc = json.loads(capsys.readouterr().out)
    (bag,) = doc['bags']
    assert bag['not_te_record'].startswith('not a TE record: ')
    assert (bag['cumulative'], bag['windows'], bag['spectrum'], bag['dominant']) == \
        (None, [], None, None)
    assert 'uncertainty' not in bag and bag['recommendation'] is None
    _within_truth(bag['hysteresis']['metrics'])
    # the HTML report and its JSON: the one line, no TE table or TE figures
    rep = tmp_path / 'rep'
    assert sorted(p.name for p in rep.iterdir()) == ['report.html', 'report.json']
    page = (rep / 'report.html').read_text(encoding='utf-8')
    assert 'Not a TE record: the input is held' in page
    assert '<h3>Statistics</h3>' not in page and 'TE p-p' not in page
    assert 'Hysteresis (input locked)' in page and 'lost_motion_rad' in page
    saved = json.loads((rep / 'report.json').read_text(encoding='utf-8'))['bags'][0]
    assert saved['not_te_record'] == bag['not_te_record'] and saved['cumulative'] is None
    _within_truth(saved['hysteresis']['metrics'])
    # the results store keeps its hysteresis, and no TE figure
    with open_store(db, create=False) as st:
        names = {n for n, _ in st.metric_names()}
    assert {'lost_motion_rad', 'backlash_rad'} <= names, names
    assert not {n for n in names if n.startswith('te_')}, names


def test_a_te_record_still_has_its_te(tmp_path: Path,
                                      capsys: pytest.CaptureFixture[str]) -> None:
    """The input turning, a torque channel: the TE table as before, no such line."""
    info = ProgramSimulator(preset='li2023-rv', te_mode='dte', sample_rate_hz=1000.0,
                            block_size=BLOCK, seed=1).info
    t = np.arange(4 * 121 * 1000 // 50) / 1000.0         # 4 output revolutions at 50 rpm in
    th_in = 2 * np.pi * (3000 / 60) * t
    th_out = th_in / 121 + 1e-4 * np.sin(39 * th_in / 121)
    n = t.size // BLOCK * BLOCK
    blocks = [SimpleNamespace(seq=k, t0_s=float(t[a]), time_offset_s=t[a:a + BLOCK] - t[a],
                              theta_in_rad=th_in[a:a + BLOCK], theta_out_rad=th_out[a:a + BLOCK],
                              torque_out_nm=np.full(BLOCK, 5.0))
              for k, a in enumerate(range(0, n, BLOCK))]
    bag = write_session_bag(tmp_path / 'bag', Run(report={}, info=info,
                                                  blocks=blocks))  # type: ignore[arg-type]
    assert main(['analyze', str(bag), '--json', '--no-db', '--quiet', '--no-advice']) == 0
    (entry,) = json.loads(capsys.readouterr().out)['bags']
    assert 'not_te_record' not in entry
    assert entry['cumulative']['te_pp_rad'] == pytest.approx(2e-4, rel=0.01)
