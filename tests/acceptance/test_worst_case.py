"""The unit's value is its worst one: over output positions, sides of the hysteresis loop,
revolutions and directions, up to the verdict (acceptance/runner.py, then the tolerance).

The step runner is fed encoder blocks written here from closed forms (no simulator): a
unit whose rigidity differs per output position and per side, whose TE p-p differs per
revolution. The simulated units of tests/acceptance/test_unit_accuracy.py are symmetric
and run one revolution, where min equals max and mean equals max; here they differ, so
taking the stiffest position or side, or the mean revolution, changes the number and the
verdict.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from rv_te_bench.acceptance import (
    HysteresisStep,
    StepRunner,
    TeStep,
    build_report,
    parse_plan,
    parse_tolerance,
)
from sim.bench_info import BenchInfoData

RATIO = 79.0
FS_HZ = 1000.0
TR = 300.0          # rated torque [N m]
TF = 1.0            # Coulomb friction [N m]
ARCMIN = math.pi / 10800

# four output positions: (positive-side, negative-side) stiffness [N m/rad], free play [rad]
KP = (1.2e5, 1.0e5, 1.1e5, 0.9e5)
KN = (0.8e5, 1.05e5, 0.6e5, 1.3e5)
B = (2.0e-4, 3.0e-4, 2.5e-4, 1.5e-4)


def flank_angle(t: list[float], kp: float, kn: float, b: float) -> np.ndarray:
    """Output angle [rad] of the cycle 0 -> +T_R -> 0 -> -T_R -> 0 at torques ``t`` of a unit
    with flank stiffness kp / kn, free play b and friction TF (the closed form of
    tests/core/test_hysteresis.py's asymmetric loop)."""
    tt = np.asarray(t)
    i_max, i_min = int(np.argmax(tt)), int(np.argmin(tt))
    out = np.empty_like(tt)
    for i, x in enumerate(tt):
        if i <= i_max:
            out[i] = b / 2 + (x - TF) / kp if x > TF else 0.0
        elif i <= i_min:
            out[i] = (b / 2 + (x + TF) / kp if x + TF > 0 else
                      -b / 2 + (x + TF) / kn if x < -TF else b / 2)
        else:
            out[i] = -b / 2 + (x - TF) / kn if x - TF < 0 else -b / 2
    return out


def run_hysteresis(positions: int = 4, skip: int | None = None,
                   ) -> tuple[StepRunner, HysteresisStep]:
    plan = parse_plan({'plan': 'h', 'steps': [{
        'kind': 'hysteresis', 'name': 'hysteresis', 'rated_torque_nm': TR,
        'step_fraction': 0.1, 'dwell_s': 0.01, 'positions': positions}]})
    step = plan.steps[0]
    assert isinstance(step, HysteresisStep)
    runner = StepRunner(step, BenchInfoData(gear_ratio=RATIO, sample_rate_hz=FS_HZ,
                                            block_size=100))
    for pos in range(positions):
        if pos == skip:   # no data from this position
            continue
        cycle = [(j, s) for j, s in enumerate(runner.segments)
                 if s.role == 'cycle' and s.label['position'] == pos]
        torques = [s.plain['torque_nm'] for _, s in cycle]
        angles = flank_angle(torques, KP[pos], KN[pos], B[pos])
        theta_in = RATIO * 2 * math.pi * pos / positions          # the input is locked
        for (j, _), t, a in zip(cycle, torques, angles, strict=True):
            n = 10                                                # one dwell of 10 samples
            runner.feed(j, np.full(n, theta_in), np.full(n, theta_in / RATIO + a),
                        np.full(n, -t))                           # reaction torque
    return runner, step


def test_rigidity_is_the_softest_side_of_the_softest_position() -> None:
    runner, _ = run_hysteresis()
    measured, details = runner.result()
    value = {m.name: m.value for m in measured}
    # per position, both sides as measured (closed form: the flank stiffnesses)
    for pos, curve in enumerate(details['positions']):
        assert curve['rigidity_nm_per_rad']['K'] == pytest.approx([KP[pos], KN[pos]], rel=1e-6)
    softest = min(min(kp, kn) for kp, kn in zip(KP, KN, strict=True))    # 0.6e5, position 2
    assert value['torsional_rigidity_K_nm_per_rad'] == pytest.approx(softest, rel=1e-6)
    # the largest lost motion and backlash over the positions (closed forms)
    t = 0.03 * TR
    lm = [b + t / kp + t / kn for kp, kn, b in zip(KP, KN, B, strict=True)]
    bl = [b + TF / kp + TF / kn for kp, kn, b in zip(KP, KN, B, strict=True)]
    assert value['lost_motion_rad'] == pytest.approx(max(lm), rel=1e-6)
    assert value['backlash_rad'] == pytest.approx(max(bl), rel=1e-6)
    assert details['shown_position'] == int(np.argmax(lm))


def test_a_position_not_measured_is_not_replaced_by_the_others() -> None:
    """A mutation survivor: the unit's value taken from the positions that were measured.
    With position 2 (the softest) missing, the unit's rigidity is not measured and the unit
    does not pass, rather than taking the 80,000 N m/rad of the others."""
    runner, step = run_hysteresis(skip=2)
    measured, details = runner.result()
    spread = [m for m in measured if m.name.startswith('sweep:')]   # shown, not judged
    assert [m.name for m in spread] == ['sweep:lost_motion_spread_rad',
                                        'sweep:backlash_spread_rad']
    assert all(math.isnan(m.value) for m in spread)
    measured = [m for m in measured if m not in spread]
    assert {m.name: m.step for m in measured} == dict.fromkeys(
        ['lost_motion_rad', 'backlash_rad', 'hysteresis_loss_j',
         'torsional_rigidity_K_nm_per_rad'], 'hysteresis')
    assert all(math.isnan(m.value) for m in measured), measured
    assert {m.unit for m in measured} == {'rad', 'J', 'N m/rad'}
    assert 'error' in details['positions'][2]
    profile = parse_tolerance({'profile': 'p', 'limits': {
        'torsional_rigidity_nm_per_arcmin': {'min': 20.0, 'region': 'K'}}})
    report = build_report(plan=parse_plan({'plan': 'h', 'steps': [
        {'kind': 'hysteresis', 'name': 'hysteresis', 'rated_torque_nm': TR,
         'positions': 4}]}), profile=profile, info=runner.info, serial='SN', operator='t',
        results=[(measured, details)])
    (k,) = [m for m in report['metrics'] if m['name'] == 'torsional_rigidity_K_nm_per_rad']
    assert k['verdict'] in {'not_measured', 'not_judged'} and k['value'] is None
    assert report['verdict'] != 'pass' and step.positions == 4


def test_a_unit_soft_at_one_position_fails_its_minimum_rigidity() -> None:
    """A minimum of 20 N m/arcmin (68,755 N m/rad) lies between the softest side (60,000 N
    m/rad, negative side at position 2) and every other side (>= 80,000): the unit fails."""
    runner, step = run_hysteresis()
    limit_nm_per_arcmin = 20.0
    assert 0.6e5 < limit_nm_per_arcmin / ARCMIN < 0.8e5
    profile = parse_tolerance({'profile': 'p', 'limits': {
        'torsional_rigidity_nm_per_arcmin': {'min': limit_nm_per_arcmin, 'region': 'K'}}})
    plan = parse_plan({'plan': 'h', 'steps': [{'kind': 'hysteresis', 'name': 'hysteresis',
                                               'rated_torque_nm': TR, 'positions': 4}]})
    report = build_report(plan=plan, profile=profile, info=runner.info, serial='SN',
                          operator='t', results=[runner.result()])
    (k,) = [m for m in report['metrics'] if m['name'] == 'torsional_rigidity_K_nm_per_rad']
    assert k['verdict'] == 'fail'
    assert k['margin'] == pytest.approx(0.6e5 - limit_nm_per_arcmin / ARCMIN, rel=1e-6)
    assert report['verdict'] == 'fail'
    assert step.positions == 4


# ------------------------------------------------------------------ TE over revolutions

def run_te(amplitudes: dict[str, list[float]], extra_rad: float) -> StepRunner:
    """A TE step of 3 revolutions per direction at 300 rpm (15.8 s per output revolution,
    15,800 samples: a multiple of 4, so every revolution has a sample at the sine's peak and
    trough): TE = A_k sin(s) in revolution k of the output travel s, and ``extra_rad`` in the
    2 % past the third revolution (not a whole revolution: not counted)."""
    step = TeStep(name='te', speed_rpm=300.0, directions=('ccw', 'cw'), revolutions=3,
                  settle_s=0.0)
    runner = StepRunner(step, BenchInfoData(gear_ratio=RATIO, sample_rate_hz=FS_HZ,
                                            block_size=100))
    per_rev = round(RATIO * 60.0 / 300.0 * FS_HZ)
    assert per_rev == 15_800
    for j, seg in enumerate(runner.segments):
        sign = 1 if seg.label['direction'] == 'ccw' else -1
        n = round(seg.plain['duration_s'] * FS_HZ)
        k = np.arange(n) // per_rev
        s = 2 * math.pi * np.arange(n) / per_rev
        amp = np.asarray([*amplitudes[seg.label['direction']], extra_rad])[np.minimum(k, 3)]
        te = amp * np.sin(s)
        theta_in = RATIO * sign * s
        runner.next_segment()
        for a in range(0, n, 100):
            b = min(a + 100, n)
            runner.feed(j, theta_in[a:b], theta_in[a:b] / RATIO + te[a:b], np.zeros(b - a))
    return runner


def test_direction_te_is_the_worst_revolution_and_fails_the_unit() -> None:
    amps = {'ccw': [1e-4, 0.5e-4, 1.5e-4], 'cw': [0.4e-4, 1.2e-4, 0.6e-4]}
    runner = run_te(amps, extra_rad=5e-4)
    measured, details = runner.result()
    value = {m.name: m.value for m in measured}
    assert value['te_pp_ccw_rad'] == pytest.approx(3e-4, rel=1e-9)     # 2 x 1.5e-4, 3rd rev
    assert value['te_pp_cw_rad'] == pytest.approx(2.4e-4, rel=1e-9)    # 2 x 1.2e-4, 2nd rev
    rows = {r['direction']: r for r in details['rows']}
    assert rows['ccw']['te_pp_per_rev_rad'] == pytest.approx([2e-4, 1e-4, 3e-4], rel=1e-9)
    assert rows['ccw']['revolutions'] == 3
    # a limit between the mean (2e-4) and the worst (3e-4) revolution of ccw: ccw fails
    limit_arcmin = 2.5e-4 / ARCMIN
    profile = parse_tolerance({'profile': 'p', 'limits': {'te_pp_arcmin': {
        'max': limit_arcmin}}})
    plan = parse_plan({'plan': 't', 'steps': [{'kind': 'te', 'name': 'te', 'speed_rpm': 300,
                                               'revolutions': 3}]})
    report = build_report(plan=plan, profile=profile, info=runner.info, serial='SN',
                          operator='t', results=[(measured, details)])
    verdicts = {m['name']: m['verdict'] for m in report['metrics']}
    assert verdicts == {'te_pp_ccw_rad': 'fail', 'te_pp_cw_rad': 'pass'}
    assert report['verdict'] == 'fail'


# ------------------------------------------------------------------ what the report shows

def test_te_step_skips_its_settling_and_reports_lines_at_their_frequencies() -> None:
    """Survivors of mutation testing (docs/TESTING.md): the settling time analysed, the
    spectrum's duration (frequencies) wrong, the spectrum or the report's keys dropped, the
    step or unit of a metric lost, sweep points misnamed: each changed what the report shows
    and no test saw it.

    One ccw revolution at 300 rpm after 1 s of settling: TE = A sin(25 phi) (the crank's
    first order of the 2K-V, 25 per output revolution), and in the settling second a 1e-3 rad
    transient that must not count. Closed forms: p-p 2 A; the 25th-order line has amplitude A
    at 25 x 300 / 60 / 79 Hz."""
    a = 1e-4
    info = BenchInfoData(gear_ratio=RATIO, crank_per_input=25.0 / RATIO, sample_rate_hz=FS_HZ,
                         block_size=100)
    plan = parse_plan({'plan': 'd', 'steps': [
        {'kind': 'te', 'name': 'te', 'speed_rpm': 300, 'directions': ['ccw'],
         'revolutions': 1, 'settle_s': 1.0},
        {'kind': 'sweep', 'name': 'sweep', 'speeds_rpm': [300], 'loads_nm': [0, 50],
         'revolutions': 1, 'settle_s': 0.0}]})
    results = []
    for step in plan.steps:
        runner = StepRunner(step, info)
        for j, seg in enumerate(runner.segments):
            n = round(seg.plain['duration_s'] * FS_HZ)
            settle = round(seg.label['settle_s'] * FS_HZ)
            s = 2 * math.pi * (np.arange(n) - settle) / 15_800     # output travel after settle
            te = a * np.sin(25 * s)
            te[:settle] = 1e-3 * np.linspace(1.0, 0.0, settle)    # the settling transient
            runner.next_segment()
            for b0 in range(0, n, 100):
                b1 = min(b0 + 100, n)
                runner.feed(j, RATIO * s[b0:b1], s[b0:b1] + te[b0:b1], np.zeros(b1 - b0))
        results.append(runner.result())
    (te_m,), te_details = results[0]
    assert (te_m.name, te_m.step, te_m.unit) == ('te_pp_ccw_rad', 'te', 'rad')
    assert te_m.value == pytest.approx(2 * a, rel=1e-6)               # the transient left out
    assert te_details['kind'] == 'te'
    (row,) = te_details['rows']
    assert row['samples'] == round(plan.steps[0].settle_s * FS_HZ) + round(
        15_800 * 1.02 + 2)
    assert row['te_pp_rad'] == te_m.value and row['revolutions'] == 1
    assert row['stats']['te_pp_rad'] == pytest.approx(2 * a, rel=1e-6)
    assert len(row['position_rad']) == len(row['te_by_position_rad']) > 100
    line = next(ln for ln in row['spectrum'] if ln['output_order'] == pytest.approx(25.0))
    assert line['amplitude_rad'] == pytest.approx(a, rel=1e-3)
    assert line['frequency_hz'] == pytest.approx(25 * 300 / 60 / RATIO, rel=1e-3)
    peak = int(np.argmax(row['spectrum_amplitude_rad']))
    assert row['spectrum_orders'][peak] == pytest.approx(25.0, abs=0.5)
    sweep_m, sweep_details = results[1]
    assert [(m.name, m.step, m.unit) for m in sweep_m] == [
        ('sweep:te_pp_ccw_300rpm_0nm_rad', 'sweep', 'rad'),
        ('sweep:te_pp_ccw_300rpm_50nm_rad', 'sweep', 'rad')]
    assert [m.value for m in sweep_m] == pytest.approx([2 * a, 2 * a], rel=1e-6)
    assert sweep_details['kind'] == 'sweep'
    # a sweep point is a TE p-p like the TE step's: the same record after settling has the
    # same budget, and its U is in the row and on the metric (issue 35: U on every result)
    assert te_m.u95 > 0 and row['te_pp_rad_u95'] == te_m.u95
    for m, r in zip(sweep_m, sweep_details['rows'], strict=True):
        assert m.u95 == pytest.approx(te_m.u95, rel=1e-9)
        assert r['te_pp_rad_u95'] == m.u95
