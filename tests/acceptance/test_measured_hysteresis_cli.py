"""Issue 34: a hysteresis test measured on another bench, as its DAQ writes it (a CSV written
here with pandas from a closed-form unit: free play, Coulomb friction, two-slope flank;
0.4 N m transducer noise, RON 886 angle errors, loader ramps and ripple, a preload and
several cycles), judged with ``rv-te test PLAN --from``, judged again with ``rv-te
unit-report`` and read without a plan by ``rv-te analyze``: lost motion, backlash and
rigidity K within 2 % of the closed form's truth (tests/core/hysteresis_records.py works it
out from the formulas, not from the suite's code) on every route.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from rv_te_bench.cli.main import main
from tests.core.hysteresis_records import (
    Unit,
    constant_speed_record,
    step_torques,
    torque_step_record,
)

UNIT = Unit()
TRUTH = UNIT.truth()          # backlash, lost motion at +-3 % T_R, rigidity K (0.5-1.0 T_R)
RATIO = 121.0
ARGS = ['--time', 't_s', '--theta-in', 'theta_in_rad', '--theta-out', 'theta_out_rad',
        '--torque', 'torque_nm', '--start-utc', '2026-11-20T08:00:00Z']
PLAN = {'plan': 'daq-hysteresis', 'tolerance': 'limits.yaml', 'steps': [
    {'kind': 'hysteresis', 'name': 'hysteresis', 'rated_torque_nm': UNIT.rated_nm,
     'step_fraction': 0.1, 'dwell_s': 0.5}]}
LIMITS = {'profile': 'rv-20e-like', 'limits': {
    'lost_motion_arcmin': {'max': 1.0, 'source': 'catalogue'},
    'backlash_arcmin': {'max': 1.0, 'source': 'catalogue'},
    'torsional_rigidity_nm_per_arcmin': {'min': 45, 'region': 'K', 'source': 'catalogue'}}}


def write_daq(folder: Path, rec: Any) -> None:
    """What the other bench's DAQ writes: time, both encoders, the load cell's reading (its
    sign: the applied torque; the bench description's scale turns it into the suite's
    convention), and the bench description."""
    import pandas as pd

    folder.mkdir(parents=True, exist_ok=True)
    pd.DataFrame({'t_s': rec.time_s, 'theta_in_rad': np.full(rec.time_s.size, 2.5),
                  'theta_out_rad': rec.angle_rad, 'torque_nm': rec.torque_nm}).to_csv(
        folder / 'run.csv', index=False, float_format='%.17g')
    (folder / 'bench.yaml').write_text(yaml.safe_dump({
        'bench_id': 'other-bench', 'preset': 'li2023-rv', 'sample_rate_hz': 1000.0,
        'block_size': 100,
        'encoders': {'input': {'model': 'heidenhain-ron886'},
                     'output': {'model': 'heidenhain-ron886'}},
        'torque_sensor': {'present': True, 'scale_nm_per_unit': -1.0}}), encoding='utf-8')
    (folder / 'plan.yaml').write_text(yaml.safe_dump(PLAN), encoding='utf-8')
    (folder / 'limits.yaml').write_text(yaml.safe_dump(LIMITS), encoding='utf-8')


def _json(capsys: pytest.CaptureFixture[str]) -> tuple[dict[str, Any], str]:
    cap = capsys.readouterr()
    return json.loads(cap.out[:cap.out.rindex('}') + 1]), cap.err


def _rel(value: float | None, name: str) -> float:
    assert value is not None and math.isfinite(value), name
    return value / TRUTH[name] - 1.0


@pytest.fixture(scope='module')
def steps_daq(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp('daq')
    write_daq(d, torque_step_record(UNIT, step_torques(UNIT, cycles=3),
                                    np.random.default_rng(7)))
    return d


def test_truth_is_the_closed_form() -> None:
    b, tf, k1, t = UNIT.b_rad, UNIT.tf_nm, UNIT.k1, 0.03 * UNIT.rated_nm
    assert TRUTH['backlash_rad'] == pytest.approx(b + 2 * tf / k1, rel=1e-12)
    assert TRUTH['lost_motion_rad'] == pytest.approx(b + 2 * t / k1, rel=1e-12)
    assert TRUTH['torsional_rigidity_K_nm_per_rad'] == pytest.approx(UNIT.k2, rel=1e-12)


def test_judged_again_and_read_without_a_plan(steps_daq: Path, tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    d = steps_daq
    out = tmp_path / 'tests'
    # 1. the plan judged from the DAQ file
    rc = main(['test', str(d / 'plan.yaml'), '--serial', 'RV20-7', '--operator', 'pytest',
               '--from', str(d / 'run.csv'), '--bench', str(d / 'bench.yaml'), *ARGS,
               '--out-dir', str(out), '--no-db', '--json'])
    judged, err = _json(capsys)
    assert rc == 0, judged['reason']
    assert judged['verdict'] == 'pass'
    got = {m['name']: m['value'] for m in judged['metrics']}
    for name in TRUTH:
        assert abs(_rel(got[name], name)) <= 0.02, (name, got[name], TRUTH[name])
    (h,) = [s for s in judged['steps'] if s['kind'] == 'hysteresis']
    assert h['cycles'] == 3 and h['torque_noise_nm'] == pytest.approx(0.4, rel=0.1)
    assert 'torque_sign' not in h       # the bench description's scale gave the convention
    # 2. rv-te unit-report of that output folder: judged again from the imported bag
    (run,) = [p for p in out.iterdir() if p.is_dir()]
    assert (run / 'judged.json').is_file()
    rc = main(['unit-report', str(run), '--json', '--report', str(tmp_path / 'again')])
    again, err = _json(capsys)
    assert rc == 0 and 'every metric equals the recorded result' in err
    assert [(m['name'], m['value'], m['verdict']) for m in again['metrics']] == \
        [(m['name'], m['value'], m['verdict']) for m in judged['metrics']]
    assert (tmp_path / 'again' / 'report.html').is_file()
    # the imported bag named instead of its folder: the same
    assert main(['unit-report', str(run / 'bag'), '--report', str(tmp_path / 'b')]) == 0
    capsys.readouterr()
    # 3. rv-te analyze of the imported bag, no plan: T_R and the method from the record
    rc = main(['analyze', str(run / 'bag'), '--json', '--no-db', '--quiet'])
    doc, _ = _json(capsys)
    a = doc['bags'][0]['hysteresis']
    assert rc == 0 and a['method'] == 'torque_steps' and a['cycles'] == [3]
    assert a['rated_torque_nm'] == pytest.approx(UNIT.rated_nm, rel=0.002)
    for name in TRUTH:
        assert abs(_rel(a['metrics'][name], name)) <= 0.02, (name, a['metrics'][name])
        assert a['spread'][name] is not None
    # the text report names them, in arcmin and N m/arcmin
    assert main(['analyze', str(run / 'bag'), '--no-db', '--quiet']) == 0
    text = capsys.readouterr().out
    lm = TRUTH['lost_motion_rad'] * 10800 / math.pi
    line = next(ln for ln in text.splitlines() if 'lost motion (+-5.01' in ln)
    assert float(line.split()[5]) == pytest.approx(lm, rel=0.02)
    assert 'torsional rigidity K  ' in text and 'backlash (at 0 N m)' in text


def test_analyze_a_constant_speed_record(tmp_path: Path,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    """The output turned at constant speed by a position-controlled loader, two cycles:
    read from the samples (local fits), T_R given."""
    write_daq(tmp_path, constant_speed_record(UNIT, np.random.default_rng(3), cycles=2))
    assert main(['import', str(tmp_path / 'run.csv'), '--bench', str(tmp_path / 'bench.yaml'),
                 *ARGS, '--out', str(tmp_path / 'bag')]) == 0
    capsys.readouterr()
    rc = main(['analyze', str(tmp_path / 'bag'), '--json', '--no-db', '--quiet',
               '--rated-torque', str(UNIT.rated_nm)])
    doc, _ = _json(capsys)
    a = doc['bags'][0]['hysteresis']
    assert rc == 0 and a['method'] == 'constant_speed' and a['rated_from'] == 'given'
    assert a['cycles'] == [2]
    for name in TRUTH:
        assert abs(_rel(a['metrics'][name], name)) <= 0.02, (name, a['metrics'][name])


def test_no_hysteresis_in_a_te_record(tmp_path: Path,
                                      capsys: pytest.CaptureFixture[str]) -> None:
    """The input turning all along: nothing to read, and asked for, one line says why."""
    t = np.arange(20_000) / 1000.0
    th_in = 2 * np.pi * 10 * t
    rec = type('Rec', (), {'time_s': t, 'angle_rad': th_in / RATIO,
                           'torque_nm': np.full(t.size, 5.0)})
    write_daq(tmp_path, rec)
    import pandas as pd

    df = pd.read_csv(tmp_path / 'run.csv')
    df['theta_in_rad'] = th_in
    df.to_csv(tmp_path / 'run.csv', index=False, float_format='%.17g')
    assert main(['import', str(tmp_path / 'run.csv'), '--bench', str(tmp_path / 'bench.yaml'),
                 *ARGS, '--out', str(tmp_path / 'bag')]) == 0
    capsys.readouterr()
    assert main(['analyze', str(tmp_path / 'bag'), '--json', '--no-db', '--quiet']) == 0
    doc, _ = _json(capsys)
    assert 'hysteresis' not in doc['bags'][0]
    assert main(['analyze', str(tmp_path / 'bag'), '--no-db', '--quiet',
                 '--hysteresis', 'on']) == 0
    assert 'hysteresis: none (no stretch with the input locked and the output loaded both ' \
           'ways' in capsys.readouterr().out
