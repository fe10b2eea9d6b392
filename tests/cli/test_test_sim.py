"""``rv-te test PLAN --sim PRESET``: the whole-reducer steps on the simulated bench in this
process. Bad input (issue 38): an efficiency map on a bench without torque transducers, a
temperature step without a temperature channel, a speed above the preset's rating: one
clear line each, exit 1, nothing run (no report folder); the ROS route runs these steps
(tests/cli/test_test_loss_ros.py). The shipped ``full`` plans run end to end (slow) and
their unit report is read in a real browser."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from rv_te_bench.cli.main import main


def _plan(tmp_path: Path, *steps: dict) -> str:
    path = tmp_path / 'plan.yaml'
    path.write_text(yaml.safe_dump({'plan': 'p', 'steps': list(steps)}), encoding='utf-8')
    return str(path)


def _one_line(capsys: pytest.CaptureFixture[str]) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert err[0].startswith('ERROR: ')
    return err[0]


EFF = {'kind': 'efficiency', 'name': 'eff', 'speeds_rpm': [1000], 'loads_nm': [392]}
WARM = {'kind': 'temperature_rise', 'name': 'warm', 'speed_rpm': 1000, 'max_duration_s': 600}


@pytest.mark.parametrize(('step', 'extra', 'expect'), [
    (EFF, ['--sim-without', 'torque'],
     "step 0 ('eff', efficiency) needs an input torque transducer, which the simulated "
     'bench (rv-80e-101) does not have; nothing was run'),
    (WARM, ['--sim-without', 'temperature'],
     "step 0 ('warm', temperature_rise) needs a case temperature channel, which the "
     'simulated bench (rv-80e-101) does not have; nothing was run'),
    ({'kind': 'no_load', 'name': 'nl', 'speeds_rpm': [1000, 9000]}, [],
     "step 0 ('nl', no_load) asks for 9000 rpm input, above the unit's rating of 7070 rpm; "
     'nothing was run'),
])
def test_bad_input_one_line_before_anything_runs(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], step: dict, extra: list[str],
        expect: str) -> None:
    out = tmp_path / 'out'
    code = main(['test', _plan(tmp_path, step), '--serial', 'S', '--operator', 'o',
                 '--sim', 'rv-80e-101', '--out-dir', str(out), *extra])
    assert code == 1
    assert _one_line(capsys) == f'ERROR: {expect}'
    assert not out.exists()


def test_speed_above_rating_refused_on_the_ros_route_too(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / 'out'
    code = main(['test', _plan(tmp_path, {'kind': 'te', 'name': 'fast', 'speed_rpm': 8000}),
                 '--serial', 'S', '--operator', 'o', '--launch', 'rv-80e-101', '--out-dir',
                 str(out)])
    assert code == 1
    assert 'above the unit\'s rating of 7070 rpm' in _one_line(capsys)
    assert not out.exists()


def test_small_plan_runs_and_reports(tmp_path: Path, capsys: pytest.CaptureFixture[str]
                                     ) -> None:
    report = tmp_path / 'report'
    code = main(['test', _plan(tmp_path, {**EFF, 'settle_s': 0.2, 'measure_s': 0.5},
                               {'kind': 'starting_torque', 'name': 'start',
                                'ramp_rate_nm_s': 0.5, 'max_torque_nm': 1.0,
                                'threshold_rad': 2e-4}),
                 '--serial', 'S', '--operator', 'o', '--sim', 'rv-80e-101', '--report',
                 str(report), '--tolerance', 'full-rv-80e'])
    out = capsys.readouterr().out
    assert code == 3          # the profile's TE, lost-motion... limits are not measured
    assert 'starting torque (input, output free) [N m]' in out
    assert {'efficiency_0.png', 'starting_torque_1.png', 'report.html'} <= {
        p.name for p in report.iterdir()}


@pytest.mark.slow
@pytest.mark.timeout(900)
def test_full_plan_runs_and_its_report_reads_in_a_browser(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from tests.dashboard.chromium import chromium, missing_reason

    report = tmp_path / 'report'
    code = main(['test', 'full-rv-80e', '--serial', 'RV80E-FULL', '--operator', 'o',
                 '--sim', 'hu2020-rv-modified', '--report', str(report)])
    out = capsys.readouterr().out
    assert code in (0, 3)
    for label in ('no-load running torque', 'starting torque', 'back-driving torque',
                  'case temperature rise', 'efficiency at the largest load',
                  'lost motion', 'run-in: quantities flagged growing'):
        assert label in out, label
    pngs = {p.name for p in report.glob('*.png')}
    assert {'no_load_0.png', 'starting_torque_1.png', 'back_driving_2.png',
            'temperature_rise_3.png', 'efficiency_4.png', 'life_7.png',
            'hysteresis.png'} <= pngs
    why = missing_reason()
    if why:
        pytest.skip(why)
    with chromium() as driver:
        driver.get((report / 'report.html').as_uri())
        heads = [h.text for h in driver.find_elements('tag name', 'h2')]
        for h in ('Efficiency (efficiency)', 'No load (no-load)', 'Temperature rise (warm-up)',
                  'Life (run-in)', 'Starting torque (starting)', 'Back driving (back-driving)'):
            assert h in heads, (h, heads)
        imgs = driver.find_elements('tag name', 'img')
        assert len(imgs) == len(pngs) == 9     # every figure written is on the page
        # every embedded PNG decoded and laid out by the browser
        assert all(driver.execute_script('return arguments[0].naturalWidth', i) > 100
                   for i in imgs)
