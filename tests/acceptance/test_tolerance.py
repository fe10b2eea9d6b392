"""Verdicts against limits (acceptance/tolerance.py): two-sided limits judged on both sides,
values exactly at a limit passing, one ulp past it failing, unmeasured limits failing the unit.

The expected verdicts and margins are the definitions of docs/ACCEPTANCE.md worked by hand:
margin = distance to the nearest limit, positive inside; pass when margin >= 0.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from rv_te_bench.acceptance import Measured, ToleranceProfile, evaluate, parse_tolerance


def profile(limits: dict) -> ToleranceProfile:
    return parse_tolerance({'profile': 'p', 'limits': limits})


def judge(limits: dict, name: str, value: float) -> tuple[str, float, str]:
    """(metric verdict, margin, unit verdict) of one metric against ``limits``."""
    verdicts, unit, _ = evaluate([Measured(name, 's', 'J', value)], profile(limits))
    (v,) = [x for x in verdicts if x.name == name]
    return v.verdict, v.margin, unit


TWO_SIDED = {'hysteresis_loss_j': {'min': 1.0, 'max': 3.0}}


@pytest.mark.parametrize(('value', 'verdict', 'margin'), [
    (0.5, 'fail', -0.5),     # below the minimum: the maximum side (2.5 inside) must not save it
    (3.5, 'fail', -0.5),     # above the maximum: the minimum side (2.5 inside) must not save it
    (1.5, 'pass', 0.5),      # inside: the nearer limit gives the margin
    (2.0, 'pass', 1.0),
    (2.5, 'pass', 0.5),
])
def test_two_sided_limit_judged_on_both_sides(value: float, verdict: str,
                                              margin: float) -> None:
    v, m, unit = judge(TWO_SIDED, 'hysteresis_loss_j', value)
    assert (v, unit) == (verdict, verdict)
    assert m == pytest.approx(margin, abs=1e-12)


@pytest.mark.parametrize(('limits', 'name'), [
    ({'hysteresis_loss_j': {'max': 3.0}}, 'hysteresis_loss_j'),
    ({'hysteresis_loss_j': {'min': 1.0}}, 'hysteresis_loss_j'),
    (TWO_SIDED, 'hysteresis_loss_j'),
    ({'te_pp_arcmin': {'max': 1.0}}, 'te_pp_ccw_rad'),
    ({'lost_motion_arcsec': {'max': 60.0}}, 'lost_motion_rad'),
    ({'torsional_rigidity_nm_per_arcmin': {'min': 196, 'region': 'K'}},
     'torsional_rigidity_K_nm_per_rad'),
])
def test_a_value_exactly_at_its_limit_passes_and_one_ulp_past_fails(limits: dict,
                                                                     name: str) -> None:
    """The catalogue's "<= 1 arcmin" includes 1 arcmin: at the limit the margin is 0 and the
    metric passes; the next float outside fails."""
    (lim,) = profile(limits).limits
    for bound, outward in ((lim.max_si, math.inf), (lim.min_si, -math.inf)):
        if math.isnan(bound):
            continue
        v, m, unit = judge(limits, name, bound)
        assert (v, m, unit) == ('pass', 0.0, 'pass')
        v, m, unit = judge(limits, name, float(np.nextafter(bound, outward)))
        assert (v, unit) == ('fail', 'fail')
        assert m < 0


def test_limits_are_converted_to_si_once() -> None:
    """1 arcmin = pi / 10800 rad; 196 N m/arcmin = 196 * 10800 / pi N m/rad."""
    p = profile({'te_pp_arcmin': {'max': 1.0},
                 'torsional_rigidity_nm_per_arcmin': {'min': 196, 'region': 'K2'}})
    te, k = p.limits
    assert te.max_si == pytest.approx(math.pi / 10800, rel=1e-15) and math.isnan(te.min_si)
    assert k.min_si == pytest.approx(196 * 10800 / math.pi, rel=1e-15)
    # the region is part of the match: K2's limit does not judge K
    verdicts, unit, _ = evaluate([Measured('torsional_rigidity_K_nm_per_rad', 'h', 'N m/rad',
                                           1.0)], p)
    by_name = {x.name: x.verdict for x in verdicts}
    assert by_name['torsional_rigidity_K_nm_per_rad'] == 'info'
    assert by_name['torsional_rigidity_K2_nm_per_rad'] == 'not_measured'
    assert unit == 'fail'


def test_every_direction_is_judged_and_the_worst_decides() -> None:
    """te_pp applies to each direction: one direction out fails the unit."""
    lim = math.pi / 10800
    verdicts, unit, reason = evaluate(
        [Measured('te_pp_ccw_rad', 'te', 'rad', 0.5 * lim),
         Measured('te_pp_cw_rad', 'te', 'rad', 1.5 * lim),
         Measured('backlash_rad', 'h', 'rad', 1e-4)], profile({'te_pp_arcmin': {'max': 1.0}}))
    assert [(v.name, v.verdict) for v in verdicts] == [
        ('te_pp_ccw_rad', 'pass'), ('te_pp_cw_rad', 'fail'), ('backlash_rad', 'info')]
    assert unit == 'fail' and reason == 'out of limit: te_pp_cw_rad'


def test_not_measured_fails_the_unit() -> None:
    p = profile({'backlash_arcmin': {'max': 1.0}, 'lost_motion_arcmin': {'max': 1.0}})
    verdicts, unit, reason = evaluate([Measured('backlash_rad', 'h', 'rad', math.nan)], p)
    assert [(v.name, v.verdict) for v in verdicts] == [
        ('backlash_rad', 'not_measured'), ('lost_motion_rad', 'not_measured')]
    assert unit == 'fail'
    assert reason == 'not measured: backlash_rad, lost_motion_rad'
    _, unit, reason = evaluate([Measured('backlash_rad', 'h', 'rad', 1e-4),
                                Measured('lost_motion_rad', 'h', 'rad', 2e-4)], p)
    assert (unit, reason) == ('pass', 'every limited metric is within its limit')


def test_verdicts_and_profiles_keep_every_field_for_the_report() -> None:
    """Mutation testing's survivors (docs/TESTING.md): the report and the store read these
    keys; a renamed key or a lost step / unit / source was seen by no test."""
    lim = math.pi / 10800
    p = profile({'te_pp_arcmin': {'max': 1.0, 'source': 'catalogue'},
                 'torsional_rigidity_nm_per_arcmin': {'min': 196, 'region': 'K2',
                                                      'source': 'c2'}})
    verdicts, _, _ = evaluate([Measured('te_pp_ccw_rad', 'te', 'rad', 0.25 * lim)], p)
    assert verdicts[0].to_json_dict() == {
        'name': 'te_pp_ccw_rad', 'step': 'te', 'unit': 'rad', 'value': 0.25 * lim,
        'limit_min': None, 'limit_max': pytest.approx(lim, rel=1e-15),
        'margin': pytest.approx(0.75 * lim, rel=1e-12), 'verdict': 'pass',
        'source': 'catalogue', 'u95': None, 'guard': 0.0, 'pfa': None, 'borderline': False}
    assert verdicts[1].to_json_dict() == {
        'name': 'torsional_rigidity_K2_nm_per_rad', 'step': '', 'unit': 'N m/rad',
        'value': None, 'limit_min': pytest.approx(196 / lim, rel=1e-15), 'limit_max': None,
        'margin': None, 'verdict': 'not_measured', 'source': 'c2', 'u95': None, 'guard': None,
        'pfa': None, 'borderline': False}
    assert p.to_plain() == {'profile': 'p', 'description': '', 'decision_rule': {
        'kind': 'simple', 'guard_fraction': 1.0, 'statement':
            'simple acceptance (ILAC-G8 4.2.1): pass when the value is within the limit; the '
            'uncertainty is stated, not applied', 'source': ''}, 'limits': [
        {'key': 'te_pp_arcmin', 'family': 'te_pp', 'unit': 'rad', 'min_si': None,
         'max_si': pytest.approx(lim, rel=1e-15), 'region': '', 'source': 'catalogue'},
        {'key': 'torsional_rigidity_nm_per_arcmin', 'family': 'torsional_rigidity',
         'unit': 'N m/rad', 'min_si': pytest.approx(196 / lim, rel=1e-15), 'max_si': None,
         'region': 'K2', 'source': 'c2'}]}
