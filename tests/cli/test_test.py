"""``rv-te test``: bad plans and tolerance files give one clear line and exit code 1 before
anything starts; a whole simulated unit run exits 0 when it passes and 3 when it fails."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

from rv_te_bench.acceptance import load_plan, parse_plan, shipped_plans, shipped_tolerances
from rv_te_bench.acceptance.tolerance import load_tolerance
from rv_te_bench.cli.main import main
from tests.procs import alive, children

GOOD_STEP = {'kind': 'te', 'name': 'te', 'speed_rpm': 1500}
GOOD_LIMITS = {'te_pp_arcmin': {'max': 1.0, 'source': 's'}}


def plan(**top: object) -> dict:
    return {'plan': 'p', 'steps': [GOOD_STEP], **top}


def step(**kw: object) -> dict:
    return plan(steps=[{**GOOD_STEP, **kw}])


BAD_PLANS = [
    ('[1, 2', 'not valid YAML'),
    ([1, 2], 'must be a mapping'),
    ({'steps': [GOOD_STEP]}, 'plan is required'),
    (plan(colour='red'), "unknown key(s) ['colour']"),
    (plan(steps=[]), 'steps must be a list of 1..100 steps'),
    (plan(steps=['te']), 'step 0: must be a mapping'),
    (plan(steps=[{'kind': 'fly'}]),
     "kind must be one of ['te', 'hysteresis', 'sweep', 'operator', 'efficiency', "),
    (step(speed_rpm=-5), "step 0 ('te'): speed_rpm must be > 0, got -5"),
    (step(speed_rpm='fast'), "speed_rpm must be a finite number, got 'fast'"),
    (step(speedrpm=5), "unknown key(s) ['speedrpm']"),
    (step(directions=['up']), 'directions must be a list of distinct directions'),
    (step(directions=['cw', 'cw']), 'directions must be a list of distinct directions'),
    (step(revolutions=0), 'revolutions must be an integer in 1..100, got 0'),
    (step(load_nm=-1), 'load_nm must be >= 0, got -1'),
    (plan(steps=[GOOD_STEP, GOOD_STEP]), "name must be unique in the plan, got 'te'"),
    (plan(steps=[{'kind': 'hysteresis', 'name': 'h'}]), 'rated_torque_nm is required'),
    (plan(steps=[{'kind': 'hysteresis', 'rated_torque_nm': 10, 'method': 'hammer'}]),
     "method must be one of ['torque_steps', 'constant_speed'], got 'hammer'"),
    (plan(steps=[{'kind': 'hysteresis', 'rated_torque_nm': 10, 'rigidity': {'K': [0.6, 0.5]}}]),
     "rigidity region 'K': need 0 < lo_fraction < hi_fraction <= 1"),
    (plan(steps=[{'kind': 'hysteresis', 'rated_torque_nm': 10, 'rigidity': {'K': 0.5}}]),
     'rigidity.K must be [lo, hi]'),
    (plan(steps=[{'kind': 'hysteresis', 'rated_torque_nm': 10, 'step_fraction': 0.7}]),
     'step_fraction must be <= 0.5, got 0.7'),
    (plan(steps=[{'kind': 'hysteresis', 'rated_torque_nm': 10, 'preload': 'yes'}]),
     "preload must be true or false, got 'yes'"),
    (plan(steps=[{'kind': 'sweep', 'speeds_rpm': []}]), 'speeds_rpm must be a list of 1..50'),
    (plan(steps=[{'kind': 'sweep', 'speeds_rpm': [100, 0]}]),
     'speeds_rpm[1] must be finite and >= 0 and <= 100000 and non-zero, got 0'),
    (plan(steps=[{'kind': 'sweep', 'speeds_rpm': [100], 'direction': 'left'}]),
     "direction must be one of ['ccw', 'cw'], got 'left'"),
]

BAD_TOLERANCES = [
    ('{a', 'not valid YAML'),
    ([1], 'is not a tolerance profile (a mapping with "profile" and "limits"'),
    ({'limits': GOOD_LIMITS}, 'profile must be a non-empty string'),
    ({'profile': 't', 'limits': {}}, 'limits must map limit keys'),
    ({'profile': 't', 'limits': GOOD_LIMITS, 'x': 1}, "unknown key(s) ['x']"),
    ({'profile': 't', 'limits': {'te_pp_degrees': {'max': 1}}}, "limit 'te_pp_degrees' unknown"),
    ({'profile': 't', 'limits': {'te_pp_arcmin': {'max': -1}}},
     'limit te_pp_arcmin.max must be a number in 0..1e+06, got -1'),
    ({'profile': 't', 'limits': {'te_pp_arcmin': {'source': 'x'}}},
     'limit te_pp_arcmin: needs max'),
    ({'profile': 't', 'limits': {'te_pp_arcmin': {'max': 1, 'colour': 1}}},
     "limit te_pp_arcmin: unknown field(s) ['colour']"),
    ({'profile': 't', 'limits': {'hysteresis_loss_j': {'min': 2, 'max': 1}}},
     'limit hysteresis_loss_j: min 2 > max 1'),
    ({'profile': 't', 'limits': {'backlash_arcmin': {'min': 0.1, 'max': 1}}},
     'limit backlash_arcmin: min is not allowed (only max'),
    ({'profile': 't', 'limits': {'backlash_arcmin': {'max': 1, 'region': 'K'}}},
     "unknown field(s) ['region']"),
    ({'profile': 't', 'limits': {'te_pp_arcmin': {'max': 1}, 'te_pp_arcsec': {'max': 60}}},
     'limit te_pp_arcsec: a second limit on te_pp'),
    ({'profile': 't', 'limits': {'te_pp_arcmin': 1.0}}, 'limit te_pp_arcmin: must be a mapping'),
]


def write(tmp_path: Path, name: str, content: object) -> Path:
    path = tmp_path / name
    path.write_text(content if isinstance(content, str) else yaml.safe_dump(content),
                    encoding='utf-8')
    return path


def one_error_line(capsys: pytest.CaptureFixture[str]) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert err[0].startswith('ERROR: ')
    return err[0]


@pytest.mark.parametrize(('content', 'expect'), BAD_PLANS)
def test_bad_plan(tmp_path: Path, capsys: pytest.CaptureFixture[str], content: object,
                  expect: str) -> None:
    path = write(tmp_path, 'plan.yaml', content)
    assert main(['test', str(path), '--serial', 'S', '--operator', 'o']) == 1
    line = one_error_line(capsys)
    assert expect in line and str(path) in line


@pytest.mark.parametrize(('content', 'expect'), BAD_TOLERANCES)
def test_bad_tolerance(tmp_path: Path, capsys: pytest.CaptureFixture[str], content: object,
                       expect: str) -> None:
    good = write(tmp_path, 'plan.yaml', plan())
    tol = write(tmp_path, 'tol.yaml', content)
    assert main(['test', str(good), '--serial', 'S', '--operator', 'o', '--tolerance',
                 str(tol)]) == 1
    line = one_error_line(capsys)
    assert expect in line and str(tol) in line


@pytest.mark.parametrize(('args', 'expect'), [
    (['no_such_plan.yaml'], "test plan 'no_such_plan.yaml': no such file"),
    (['rv-80e', '--tolerance', 'nope.yaml'], "tolerance profile 'nope.yaml': no such file"),
    (['rv-80e', '--condition', 'temperature'], "--condition 'temperature' is not of the form"),
    (['rv-80e', '--launch', 'rv-99'], "unknown preset 'rv-99'"),
    (['rv-80e', '--launch', 'rv-80e-101', '--set', 'torsion.clearence_rad=1'],
     "preset 'rv-80e-101' has no key 'torsion.clearence_rad'"),
])
def test_bad_arguments(capsys: pytest.CaptureFixture[str], args: list[str], expect: str) -> None:
    assert main(['test', *args, '--serial', 'S', '--operator', 'o']) == 1
    assert expect in one_error_line(capsys)


def test_unit_report_of_a_folder_without_a_test(tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    assert main(['unit-report', str(tmp_path / 'nothing')]) == 1
    assert 'cannot read the bag' in one_error_line(capsys)


def test_plan_names_its_tolerance_relative_to_itself(tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    write(tmp_path, 'limits.yaml', {'profile': 't', 'limits': {'te_pp_arcmin': {'max': -2}}})
    path = write(tmp_path, 'plan.yaml', plan(tolerance='limits.yaml'))
    assert main(['test', str(path), '--serial', 'S', '--operator', 'o']) == 1
    assert 'limits.yaml: limit te_pp_arcmin.max' in one_error_line(capsys)


def test_shipped_plans_and_profiles_are_valid() -> None:
    assert set(shipped_plans()) == {'rv-80e', 'li2023-rv', 'wang2020-2kv', 'full-rv-80e',
                                    'full-li2023-rv'}
    for name in shipped_plans():
        p, _ = load_plan(name)
        assert p.steps
    from sim.presets import available_presets

    assert set(available_presets()) <= set(shipped_tolerances())
    for name in shipped_tolerances():
        prof, _ = load_tolerance(name)
        assert all(lim.source for lim in prof.limits), name
    assert parse_plan(plan()).steps[0].directions == ('ccw', 'cw')


@pytest.mark.ros
@pytest.mark.timeout(300)
@pytest.mark.parametrize(('extra', 'code', 'word'), [
    ([], 0, 'PASS'),
    (['--set', 'torsion.clearance_rad=4e-4'], 3, 'FAIL'),   # 1.37 arcmin of backlash
])
def test_whole_unit_exit_codes(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                               extra: list[str], code: int, word: str,
                               default_store: Path) -> None:
    plan_file = write(tmp_path, 'plan.yaml', {'plan': 'quick', 'steps': [
        {'kind': 'te', 'name': 'te', 'speed_rpm': 3000, 'settle_s': 0.2},
        {'kind': 'hysteresis', 'name': 'hysteresis', 'rated_torque_nm': 450.0,
         'dwell_s': 0.1}]})
    rc = main(['test', str(plan_file), '--serial', 'LI-7', '--operator', 'pytest',
               '--launch', 'li2023-rv', '--out-dir', str(tmp_path / 'out'),
               '--speed-factor', '0', '--condition', 'ambient_temperature_c=21', *extra])
    out = capsys.readouterr().out
    assert rc == code, out
    assert f'VERDICT: {word}  unit LI-7' in out
    (run,) = [p for p in (tmp_path / 'out').iterdir() if p.is_dir()]
    report = json.loads((run / 'report' / 'report.json').read_text())
    assert report['unit']['serial'] == 'LI-7' and report['conditions'] == {
        'ambient_temperature_c': 21}
    html = (run / 'report' / 'report.html').read_text()
    assert '<title>Acceptance test of unit LI-7: ' + word in html
    backlash = next(m for m in report['metrics'] if m['name'] == 'backlash_rad')
    assert backlash['verdict'] == ('pass' if code == 0 else 'fail')
    assert (run / 'bag' / 'metadata.yaml').exists()
    # the user's results store has the test, its verdict and metrics
    from rv_te_bench.store import ResultFilter, open_store

    with open_store(default_store) as store:
        (rec,) = store.query(ResultFilter(test='test-plan'))
    assert (rec.serial, rec.plan, rec.verdict) == ('LI-7', 'quick', word.lower())
    assert rec.metrics[('te_pp_revolution_max_rad', 'ccw')] == pytest.approx(next(
        m['value'] for m in report['metrics'] if m['name'] == 'te_pp_ccw_rad'))
    assert rec.limits[('backlash_rad', 'all')][2] == backlash['verdict']
    # the same test again from the bag alone: same metrics, same verdict, same exit code
    assert main(['unit-report', str(run / 'bag'), '--report', str(tmp_path / 'again')]) == code
    cap = capsys.readouterr()
    assert 'every metric equals the recorded result' in cap.err, cap.err
    again = json.loads((tmp_path / 'again' / 'report.json').read_text())
    assert [m['value'] for m in again['metrics']] == pytest.approx(
        [m['value'] for m in report['metrics']], rel=1e-9)


@pytest.mark.ros
@pytest.mark.timeout(300)
def test_ctrl_c_cancels_the_test_stops_the_bench_and_keeps_the_bag(
        tmp_path: Path, ros_domain_id: int, default_store: Path) -> None:
    """Ctrl-C in the terminal (SIGINT to the command's process group) during a step of
    ``rv-te test --launch``: the test is cancelled, the bench and the other nodes stop, the
    exit code is 1 with one ERROR line, the report says 'cancelled', and the bag of what was
    measured is complete and readable by rosbags."""
    import os
    import signal
    import subprocess
    import sys
    import threading
    import time

    from rosbags.highlevel import AnyReader

    from rv_te_bench.io.msgdefs import rv_te_typestore

    env = {**os.environ, 'ROS_DOMAIN_ID': str(ros_domain_id),
           'PYTHONPATH': str(Path(__file__).resolve().parents[2])}
    env.pop('_ROS_WHEELS_BOOTSTRAP_COMPLETE', None)
    p = subprocess.Popen(
        [sys.executable, '-m', 'rv_te_bench.cli.main', 'test', 'wang2020-2kv', '--serial',
         'SN-C', '--operator', 'pytest', '--launch', 'wang2020-2kv', '--out-dir',
         str(tmp_path / 'out'), '--speed-factor', '1'],
        env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        start_new_session=True,   # its own process group, as a terminal's foreground job
        # a terminal's job takes Ctrl-C; a suite started in the background (nohup ... &)
        # ignores SIGINT, and its children would inherit that
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))  # noqa: PLW1509
    err: list[str] = []
    reader = threading.Thread(target=lambda: err.extend(iter(p.stderr.readline, '')))
    reader.start()
    try:
        def step_pct() -> float:   # the last progress line: '  32.6 % of the step, ...'
            pcts = [float(ln.split('%')[0]) for ln in err if '% of the step' in ln]
            return pcts[-1] if pcts else -1.0

        end = time.monotonic() + 120
        while step_pct() < 10.0 and time.monotonic() < end and p.poll() is None:
            time.sleep(0.1)
        assert step_pct() >= 10.0, ''.join(err)   # well into the first step
        nodes = children(p.pid)
        assert len(nodes) >= 3, nodes   # bench, test_sequencer, recorder
        os.killpg(p.pid, signal.SIGINT)
        p.wait(timeout=90)
        out = p.stdout.read()   # (short: the verdict table)
    finally:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait()
        reader.join(timeout=10)
    assert p.returncode == 1, ''.join(err)
    text = ''.join(err)
    assert 'cancelling the test (the bench stops)' in text
    errors = [ln for ln in err if ln.startswith('ERROR')]
    assert errors == ['ERROR: test of unit SN-C cancelled: cancelled after 0 of 3 steps: '
                      "cancelled by the operator (step 'te')\n"], text
    assert not any(alive(pid) for pid in nodes), 'a node outlived the test'
    (run,) = [d for d in (tmp_path / 'out').iterdir() if d.is_dir()]
    report = json.loads((run / 'report' / 'report.json').read_text())
    assert report['verdict'] == 'cancelled'
    assert report['reason'].endswith("cancelled by the operator (step 'te')")
    assert 'report:' in out
    # the record in the user's results store (the command's environment): not judged,
    # with the reason
    from rv_te_bench.store import ResultFilter, open_store

    with open_store(default_store) as store:
        (rec,) = store.query(ResultFilter(test='test-plan'))
    assert (rec.serial, rec.verdict, rec.status) == ('SN-C', 'not-judged', 'failed')
    assert "cancelled by the operator (step 'te')" in rec.failure
    with AnyReader([run / 'bag'], default_typestore=rv_te_typestore()) as bag:
        conns = [c for c in bag.connections if c.topic.endswith('bench/encoders')]
        seqs = [bag.deserialize(raw, c.msgtype).seq for c, _t, raw in bag.messages(conns)]
        reps = [bag.deserialize(raw, c.msgtype) for c, _t, raw in bag.messages(
            [c for c in bag.connections if c.topic.endswith('test/report')])]
    assert len(seqs) > 10
    assert seqs == list(range(seqs[0], seqs[0] + len(seqs)))   # no gap in what was measured
    assert reps[-1].verdict == 'cancelled' and 'cancelled by the operator' in reps[-1].reason
