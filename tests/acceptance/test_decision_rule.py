"""Tolerance profiles name their decision rule; verdicts PASS / FAIL / INDETERMINATE per
metric and for the unit; the acceptance runner gives every metric its U (issue 35).

Constructed borderline cases: a TE p-p of 0.99' against <= 1' with U = 0.05' passes under
simple acceptance and is INDETERMINATE under guarded acceptance (value + U straddles the
limit); 0.90' passes both; 1.06' fails both (ISO 14253-1 zones, worked by hand)."""

from __future__ import annotations

import dataclasses
import math

import pytest

from rv_te_bench.acceptance import Measured, evaluate, load_plan, parse_tolerance, run_plan_offline
from rv_te_bench.acceptance._store import record_of_report
from rv_te_bench.core.units import ARCMIN_PER_RAD
from rv_te_bench.errors import ToleranceError
from sim.program import ProgramSimulator

AM = 1.0 / ARCMIN_PER_RAD      # rad per arcmin


def _profile(rule: object = None) -> object:
    data = {'profile': 'p', 'limits': {'te_pp_arcmin': {'max': 1.0},
                                       'lost_motion_arcmin': {'max': 1.0}}}
    if rule is not None:
        data['decision_rule'] = rule
    return parse_tolerance(data)


@pytest.mark.parametrize(('te', 'simple', 'guarded'), [
    (0.90, 'pass', 'pass'), (0.99, 'pass', 'indeterminate'), (1.03, 'fail', 'indeterminate'),
    (1.06, 'fail', 'fail')])
def test_verdicts_per_rule(te: float, simple: str, guarded: str) -> None:
    measured = [Measured('te_pp_ccw_rad', 'te', 'rad', te * AM, u95=0.05 * AM),
                Measured('lost_motion_rad', 'h', 'rad', 0.5 * AM, u95=0.05 * AM)]
    for rule, want in (('simple', simple), ('guarded', guarded)):
        verdicts, unit, reason = evaluate(measured, _profile(rule))
        assert verdicts[0].verdict == want
        assert unit == want                         # lost motion passes under both
        assert verdicts[0].u95 == pytest.approx(0.05 * AM)
        if want == 'indeterminate':
            assert 'neither conformance nor non-conformance proven' in reason
            assert verdicts[0].borderline and 0 < verdicts[0].pfa < 1


def test_a_failed_metric_beats_an_indeterminate_one() -> None:
    measured = [Measured('te_pp_ccw_rad', 'te', 'rad', 0.99 * AM, u95=0.05 * AM),
                Measured('lost_motion_rad', 'h', 'rad', 1.2 * AM, u95=0.05 * AM)]
    _, unit, reason = evaluate(measured, _profile('guarded'))
    assert unit == 'fail' and 'out of limit: lost_motion_rad' in reason


def test_the_rule_is_named_and_checked() -> None:
    p = _profile({'kind': 'guarded', 'guard_fraction': 0.5, 'source': 'QP-12'})
    plain = p.to_plain()['decision_rule']
    assert plain['kind'] == 'guarded' and plain['guard_fraction'] == 0.5
    assert 'w = 0.5 U' in plain['statement'] and plain['source'] == 'QP-12'
    assert _profile().to_plain()['decision_rule']['kind'] == 'simple'   # the default
    for bad, says in (('strict', 'decision_rule: decision rule must be one of'),
                      ({'kind': 'guarded', 'guard_fraction': 5}, 'guard_fraction must lie'),
                      ({'kind': 'simple', 'guard_fraction': 1}, 'goes with kind guarded'),
                      ({'kind': 'guarded', 'band': 1}, "unknown field(s) ['band']"),
                      (3, 'must be "simple", "guarded" or a mapping')):
        with pytest.raises(ToleranceError, match=None) as exc:
            _profile(bad)
        assert says in str(exc.value)


@pytest.fixture(scope='module')
def offline_report() -> dict:
    """An RV-80E-101 unit through the plan's TE and hysteresis steps, offline."""
    plan, _ = load_plan('rv-80e')
    plan = dataclasses.replace(plan, steps=plan.steps[:2])
    sim = ProgramSimulator(preset='rv-80e-101', te_mode='elastic', seed=1)
    prof = parse_tolerance({'profile': 'p', 'decision_rule': 'guarded', 'limits': {
        'te_pp_arcmin': {'max': 1.0}, 'lost_motion_arcmin': {'max': 1.0},
        'torsional_rigidity_nm_per_arcmin': {'min': 196, 'region': 'K'}}})
    return run_plan_offline(plan, prof, serial='SN', operator='op', sim=sim)


def test_the_runner_gives_every_metric_its_budget(offline_report: dict) -> None:
    by = {m['name']: m for m in offline_report['metrics']}
    for name in ('te_pp_ccw_rad', 'te_pp_cw_rad', 'lost_motion_rad', 'backlash_rad',
                 'torsional_rigidity_K_nm_per_rad'):
        m = by[name]
        assert m['u95'] is not None and m['u95'] > 0, name
        assert m['budget']['u95'] == pytest.approx(m['u95'])
        assert m['budget']['inputs'], name
    # the TE p-p's budget holds the RON 886's graduation harmonics (data-sheet defaults)
    names = [x['name'] for x in by['te_pp_ccw_rad']['budget']['inputs']]
    assert 'output encoder: graduation, order 1' in names
    assert offline_report['tolerance']['decision_rule']['kind'] == 'guarded'


def test_an_indeterminate_unit_and_its_record(offline_report: dict) -> None:
    """The unit's TE p-p is ~1.6': against a limit set at the value, under guarded
    acceptance, it is neither proven in nor out: INDETERMINATE, recorded as such."""
    from rv_te_bench.acceptance.tolerance import Measured, evaluate

    by = {m['name']: m for m in offline_report['metrics']}
    te = by['te_pp_ccw_rad']
    limit_am = te['value'] / AM
    prof = parse_tolerance({'profile': 'p', 'decision_rule': 'guarded',
                            'limits': {'te_pp_arcmin': {'max': round(limit_am, 6)}}})
    meas = [Measured('te_pp_ccw_rad', 'te', 'rad', te['value'], u95=te['u95'],
                     u_below=te['budget']['u95'], u_above=te['budget']['expanded'])]
    verdicts, unit, _ = evaluate(meas, prof)
    assert unit == 'indeterminate' and verdicts[0].verdict == 'indeterminate'
    assert verdicts[0].pfa == pytest.approx(0.5, abs=0.02)   # at the limit: a coin toss
    report = dict(offline_report, verdict='indeterminate',
                  metrics=[v.to_json_dict() for v in verdicts])
    rec = record_of_report(report, bag_path='/b', bag_sha256='a' * 64)
    assert rec.verdict == 'indeterminate' and rec.status == 'ok'
    (m,) = rec.metrics
    assert m.verdict == 'indeterminate' and m.u95 == pytest.approx(te['u95'])
    assert math.isfinite(m.u95)


def test_exit_codes(capsys: pytest.CaptureFixture[str]) -> None:
    from rv_te_bench.cli.test import EXIT_FAIL, EXIT_INDETERMINATE, verdict_exit

    assert verdict_exit('pass', 'S', 'ok', None) == 0
    assert verdict_exit('fail', 'S', 'x', None) == EXIT_FAIL == 3
    assert verdict_exit('indeterminate', 'S', 'x', None) == EXIT_INDETERMINATE == 4
    assert 'VERDICT: INDETERMINATE  unit S' in capsys.readouterr().out
    assert verdict_exit('cancelled', 'S', 'x', None) == 1
