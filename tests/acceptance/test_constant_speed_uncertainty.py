"""A constant-speed hysteresis test carries U (issue 35): its budgets' sensitivities through
the local-fit reading against closed forms, type A over its cycles.

The Li 2023 RV unit is linear above its play (static stiffness K from the lumped model,
computed here with the model's own static response, as test_unit_accuracy does): a torque
sensor reading (1 + e) T scales every torque the reading sees, so the rigidity moves by
K e (dK/de = K) and the loop's area, an integral of torque over angle, by L e (dL/de = L);
a zero offset z of the torque channel moves neither the rigidity (a slope) nor, to first
order, the lost motion (both branches' mid points move together)."""

from __future__ import annotations

import math

import pytest

from sim import li2023
from sim.presets import load_preset
from tests.acceptance.test_unit_accuracy import hysteresis_plan, run_unit

ARCMIN = math.pi / 10800


@pytest.fixture(scope='module')
def report() -> dict:
    plan = hysteresis_plan(450.0, 'constant_speed')
    return run_unit('li2023-rv', [f'torsion.clearance_rad={0.6 * ARCMIN}'], plan)


def _m(report: dict, name: str) -> dict:
    return next(m for m in report['metrics'] if m['name'] == name)


def test_every_metric_has_u_from_its_budget(report: dict) -> None:
    for n in ('lost_motion_rad', 'backlash_rad', 'hysteresis_loss_j',
              'torsional_rigidity_K_nm_per_rad'):
        m = _m(report, n)
        assert m['u95'] is not None and 0 < m['u95'] < 0.05 * abs(m['value']), (n, m)
        names = {x['name'] for x in m['budget']['inputs']}
        assert 'torque sensor: sensitivity (gain)' in names
        assert any(x.startswith('output encoder: graduation') for x in names)
        cycles = report['steps'][0]['cycles']
        rep = [x for x in m['budget']['inputs'] if x['name'].startswith('repeatability')]
        if cycles > 1:        # type A over the cycles, cycles - 1 dof
            assert rep and rep[0]['dof'] == cycles - 1
        else:
            assert not rep and any('one cycle' in t for t in m['budget']['notes'])


def test_sensitivities_are_the_closed_forms(report: dict) -> None:
    """Closed forms of the reading, independent of the code:
    * an output-scale harmonic g sin(k theta + rho) over readings a small angle apart
      (k x span << 1): a difference of two angles (lost motion, backlash) changes by
      g k cos(.) x (their difference), so dM/dg = k M; the rigidity dT / d theta by
      -K k g cos(.): dK/dg = k K; the loop's area by g k x the area: dL/dg = k L;
    * a gain e of the torque channel scales every torque: the loop's area (an integral of
      torque over angle) by (1 + e): dL/de = L;
    * a zero offset moves both branches' mid points alike: d(lost motion)/dz ~ 0;
    * the rigidity's gain sensitivity is at least K (the reading's own; the end of the
      record at T_R adds to it, see constant_speed_budgets)."""
    over = [f'torsion.clearance_rad={0.6 * ARCMIN}']
    model = li2023.build_te_model(load_preset('li2023-rv', over), 'dte')
    i = model.state_index('output')
    k = 100.0 / (model.static_response(0.0, 0.0)[i] - model.static_response(0.0, 100.0)[i])

    def c(name: str, inp: str) -> float:
        b = _m(report, name)['budget']
        return next(x['sensitivity'] for x in b['inputs'] if x['name'] == inp)

    for name in ('lost_motion_rad', 'backlash_rad', 'hysteresis_loss_j',
                 'torsional_rigidity_K_nm_per_rad'):
        value = _m(report, name)['value']
        for order in (1, 2, 3, 4):
            assert c(name, f'output encoder: graduation, order {order}') == pytest.approx(
                order * value, rel=0.02), (name, order)
    gain = 'torque sensor: sensitivity (gain)'
    loss = _m(report, 'hysteresis_loss_j')['value']
    assert c('hysteresis_loss_j', gain) == pytest.approx(loss, rel=0.01)
    assert c('torsional_rigidity_K_nm_per_rad', gain) >= 0.98 * k
    lm = _m(report, 'lost_motion_rad')['value']
    assert abs(c('lost_motion_rad', 'torque sensor: zero and linearity')) < 0.01 * lm / 13.5
