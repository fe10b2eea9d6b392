"""The whole-reducer plan steps (issue 38) run on the simulated bench through the acceptance
runner, each metric against a truth computed here from the bench's true channels or the
friction model (not from the step's own summary), plus the plan checks and the
lost-motion spread over positions."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rv_te_bench.acceptance import parse_plan, parse_tolerance, run_plan_offline
from rv_te_bench.acceptance.preflight import check_plan
from rv_te_bench.errors import AcceptanceError, PlanError
from sim.loss_bench import LossConfig
from sim.losses import LossModel
from sim.presets import load_preset
from sim.program import ProgramSimulator

RPM = 2 * math.pi / 60
PROFILE = parse_tolerance({'profile': 'p', 'limits': {
    'efficiency_pct': {'min': 50}, 'starting_torque_nm': {'max': 1.0},
    'temperature_rise_k': {'max': 40}}})


def _run(steps: list[dict], overrides: tuple[str, ...] = (), losses: LossConfig | None = None
         ) -> tuple[dict, list]:
    plan = parse_plan({'plan': 'p', 'steps': steps})
    sim = ProgramSimulator(preset='rv-80e-101', overrides=overrides, te_mode='elastic',
                           losses=losses or LossConfig(), sample_rate_hz=1000.0)
    blocks: list = []
    report = run_plan_offline(plan, PROFILE, serial='s', operator='o', sim=sim,
                              on_block=blocks.append)
    return report, blocks


def _metric_row(report: dict, name: str) -> dict:
    return next(m for s in report['steps'] for m in s['metrics'] if m['name'] == name)


def _metric(report: dict, name: str) -> float:
    for s in report['steps']:
        for m in s['metrics']:
            if m['name'] == name:
                return math.nan if m['value'] is None else m['value']
    raise KeyError(name)


def test_efficiency_step_obeys_the_energy_balance() -> None:
    report, blocks = _run([{'kind': 'efficiency', 'name': 'eff', 'speeds_rpm': [1000, 2000],
                            'loads_nm': [392, 784], 'settle_s': 0.3, 'measure_s': 1.0}])
    step = report['steps'][0]
    assert len(step['rows']) == 4
    k = 0
    per_point = 1300 // 100            # blocks of one point (settle + measure)
    for r in step['rows']:
        bl = blocks[k + 3:k + per_point]   # the measured part (after 0.3 s)
        k += per_point
        w = r['speed_rpm'] * RPM
        loss = np.mean(np.concatenate([b.power_loss_w for b in bl]))
        p_in = np.mean(np.concatenate([b.torque_in_true_nm for b in bl])) * w
        truth = 1.0 - loss / p_in
        assert abs(r['efficiency'] - truth) <= r['expanded_efficiency']
        assert r['expanded_efficiency'] < 0.01
        # the GUM budget (issue 35): U beside the value, its inputs named
        assert r['efficiency_u95'] == r['expanded_efficiency'] > 0
        names = {x['name'] for x in r['budget']['inputs']}
        assert {'input torque transducer: class', 'output torque transducer: class'} <= names
    top = min(r['efficiency'] for r in step['rows'] if r['load_nm'] == 784)
    assert _metric(report, 'efficiency_at_max_load') == pytest.approx(top)
    m = _metric_row(report, 'efficiency_at_max_load')
    row = next(r for r in step['rows'] if r['efficiency'] == top)
    assert m['u95'] == pytest.approx(row['efficiency_u95'])


def test_ramp_steps_read_the_friction_models_static_values() -> None:
    report, _ = _run([
        {'kind': 'starting_torque', 'name': 'start', 'ramp_rate_nm_s': 0.2,
         'max_torque_nm': 1.0, 'threshold_rad': 2e-4},
        {'kind': 'back_driving', 'name': 'back', 'ramp_rate_nm_s': 20, 'max_torque_nm': 120,
         'threshold_rad': 5e-5, 'directions': ['ccw', 'cw']}])
    model = LossModel.from_preset(load_preset('rv-80e-101'))
    ts, tbd = float(model.starting_torque_nm(0.0)), model.back_driving_torque_nm()
    for r in report['steps'][0]['rows']:
        # class-0.05 transducer of 20 N m: +-0.01 N m; detection bias < 1 % (core tests)
        assert r['torque_nm'] == pytest.approx(ts, abs=0.01 + 0.01 * ts)
        # the budget: class band p x 0.01 N m at least, the ramp's increment per sample
        # (0.2 N m/s at 1 kHz) as the bias bound reading high
        b = r['budget']
        assert b['bias_bound'] == pytest.approx(0.2 / 1000.0, rel=0.05)
        assert r['torque_nm_u95'] >= 0.95 * 0.01
    for r in report['steps'][1]['rows']:
        assert r['torque_nm'] == pytest.approx(tbd, abs=1.0 + 0.02 * tbd)   # 2000 N m FS
    assert report['metrics'][0]['name'] == 'starting_torque_nm' or any(
        m['name'] == 'starting_torque_nm' and m['verdict'] == 'pass' for m in report['metrics'])


def test_self_locking_unit_is_reported_not_turning() -> None:
    """mesh_loss_static >= 1: the gear self-locks; the back-driving step says so."""
    report, _ = _run([{'kind': 'back_driving', 'name': 'back', 'ramp_rate_nm_s': 50,
                       'max_torque_nm': 100, 'threshold_rad': 5e-5}],
                     overrides=('losses.mesh_loss_static=1.05',))
    row = report['steps'][0]['rows'][0]
    assert row['torque_nm'] is None and 'did not turn' in row['error']


def test_temperature_step_matches_the_true_case_temperature() -> None:
    """A light case (tau about 45 s) so that it settles in a short run; the reported rise
    and settling time against the bench's true temperature channel and its own rate."""
    report, blocks = _run([{'kind': 'temperature_rise', 'name': 'warm', 'speed_rpm': 1000,
                            'load_nm': 392, 'rate_limit_k_per_min': 1.0, 'window_s': 10,
                            'max_duration_s': 400}],
                          overrides=('thermal.case_mass_kg=0.7',))
    s = report['steps'][0]
    assert s['settled']
    temp = np.concatenate([b.temp_case_true_degc for b in blocks])
    t = np.arange(temp.size) / 1000.0
    rate = np.gradient(temp, t) * 60.0
    t_true = t[int(np.argmax(np.abs(rate) < 1.0))]
    assert s['settle_time_s'] == pytest.approx(t_true, abs=3.0)
    rise_true = np.interp(s['settle_time_s'], t, temp) - temp[0]
    assert s['rise_k'] == pytest.approx(rise_true, abs=0.1)
    assert 0 < s['rise_k_u95'] < 0.1
    assert _metric_row(report, 'temperature_rise_k')['u95'] == pytest.approx(s['rise_k_u95'])


def test_life_step_on_a_stable_unit_flags_nothing() -> None:
    report, _ = _run([{'kind': 'life', 'name': 'life', 'checkpoints': 4, 'run_s': 5,
                       'speed_rpm': 1000, 'load_nm': 392, 'te_speed_rpm': 3000,
                       'no_load_speed_rpm': 1000, 'measure_s': 1.0}])
    s = report['steps'][0]
    assert len(s['checkpoints']) == 4
    assert _metric(report, 'trend_alarms') == 0.0
    tracked = [n for n, v in s['trends'].items() if v.get('tracked')]
    assert {'te_pp_rad', 'no_load_torque_nm'} <= set(tracked)
    assert any(n.startswith('line ') for n in tracked)


def test_lost_motion_spread_over_positions() -> None:
    report, _ = _run([{'kind': 'hysteresis', 'name': 'hys', 'rated_torque_nm': 784,
                       'positions': 3, 'dwell_s': 0.1}], losses=LossConfig())
    s = report['steps'][0]
    lm = [p['lost_motion_rad'] for p in s['per_position']]
    assert _metric(report, 'sweep:lost_motion_spread_rad') == pytest.approx(max(lm) - min(lm))
    assert _metric(report, 'lost_motion_rad') == pytest.approx(max(lm))


@pytest.mark.parametrize(('step', 'match'), [
    ({'kind': 'efficiency', 'speeds_rpm': [1000], 'loads_nm': [0]}, r'loads_nm\[0\]'),
    ({'kind': 'starting_torque', 'ramp_rate_nm_s': 0.1, 'max_torque_nm': 1,
      'threshold_rad': 1e-3, 'stop_angle_rad': 1e-4}, 'stop_angle_rad must exceed'),
    ({'kind': 'temperature_rise', 'speed_rpm': 1000, 'window_s': 600,
      'max_duration_s': 600}, 'window_s must be at most half'),
    ({'kind': 'life', 'checkpoints': 3, 'run_s': 10, 'speed_rpm': 1000},
     'checkpoints must exceed'),
])
def test_bad_steps_are_named(step: dict, match: str) -> None:
    with pytest.raises(PlanError, match=match):
        parse_plan({'plan': 'p', 'steps': [step]})


@pytest.mark.parametrize(('step', 'channels', 'match'), [
    ({'kind': 'efficiency', 'speeds_rpm': [1000], 'loads_nm': [392]}, {'temperature'},
     "step 0 .*efficiency.* needs an input torque transducer"),
    ({'kind': 'temperature_rise', 'speed_rpm': 1000}, {'torque_in', 'torque_out'},
     'needs a case temperature channel'),
    ({'kind': 'te', 'speed_rpm': 8000}, {'torque_out'},
     'asks for 8000 rpm input, above the unit.s rating of 7070 rpm'),
])
def test_preflight_refuses_in_one_line(step: dict, channels: set, match: str) -> None:
    plan = parse_plan({'plan': 'p', 'steps': [step]})
    with pytest.raises(AcceptanceError, match=match) as exc:
        check_plan(plan, channels=channels, max_input_speed_rpm=70.0 * 101)
    assert '\n' not in str(exc.value)
