"""Issue 38's plateau steps (no-load, efficiency, temperature rise, life) driven through
setpoints (:func:`run_plan_commanded`, the loop the test_sequencer runs over the
middleware) on the simulated bench with its losses, against the same plan run as the
bench's own programs (:func:`run_plan_offline`, ``rv-te test --sim``): the same verdicts,
the metrics within tolerance. The two differ only in where each plateau is cut (the
setpoint route starts a segment where the bench reached its setpoint), so the case
temperature, and with it the oil viscosity, differs by the transitions' heat.
"""

from __future__ import annotations

import math

import pytest

from rv_te_bench.acceptance import parse_plan
from rv_te_bench.acceptance.commanded import run_plan_commanded
from rv_te_bench.acceptance.driver import DriverSettings, plan_limits
from rv_te_bench.acceptance.runner import run_plan_offline
from rv_te_bench.acceptance.tolerance import parse_tolerance
from rv_te_bench.errors import AcceptanceError
from sim.commanded import CommandedBench
from sim.loss_bench import LossConfig
from sim.program import ProgramSimulator
from tests.acceptance.test_recorded_loss import LIMITS, LOSS_PLAN

PLAN = {'plan': 'plateaus', 'steps': [s for s in LOSS_PLAN['steps']
                                      if s['kind'] not in ('starting_torque', 'back_driving')]}
PROFILE = {**LIMITS, 'limits': {k: v for k, v in LIMITS['limits'].items()
                                if k not in ('starting_torque_nm', 'back_driving_torque_nm')}}
#: metric -> absolute tolerance (the viscosity moves the no-load torque ~1e-3 per 0.1 K)
TOL = {'no_load_torque_max_nm': 0.003, 'efficiency_at_max_load': 5e-4,
       'temperature_rise_k': 0.01, 'trend_alarms': 0.0}


def _sim() -> ProgramSimulator:
    return ProgramSimulator(preset='rv-80e-101', te_mode='elastic', sample_rate_hz=1000.0,
                            block_size=20, seed=5, losses=LossConfig())


def test_plateau_steps_through_setpoints_give_the_program_verdicts() -> None:
    plan, profile = parse_plan(PLAN, 'plan'), parse_tolerance(PROFILE, 'profile')
    programs = run_plan_offline(plan, profile, serial='S', operator='o', sim=_sim())
    setpoints = run_plan_commanded(plan, profile, bench=CommandedBench(_sim()), serial='S',
                                   operator='o', limits=plan_limits(plan),
                                   settings=DriverSettings(torque_tolerance_nm=4.0))
    assert setpoints['verdict'] == programs['verdict'] == 'pass', setpoints['reason']
    assert [m['name'] for m in setpoints['metrics']] == [m['name'] for m in
                                                         programs['metrics']]
    for a, b in zip(programs['metrics'], setpoints['metrics'], strict=True):
        assert b['verdict'] == a['verdict'], b
        assert b['value'] == pytest.approx(a['value'], abs=TOL[a['name']]), b['name']
    life = next(s for s in setpoints['steps'] if s['kind'] == 'life')
    assert all(math.isfinite(c['no_load_torque_nm']) for c in life['checkpoints'])


def test_plan_limits_cover_the_loss_steps() -> None:
    """A plateau step's speed and load bound the safety limits, and one above the bench's
    limit is refused before anything moves (they were not counted before: the limits fell
    to 1 rpm 'no drive step')."""
    plan = parse_plan(PLAN, 'plan')
    lim = plan_limits(plan)
    assert lim.max_input_speed_rad_s == pytest.approx(1.25 * 2000 * 2 * math.pi / 60)
    assert lim.max_output_torque_nm == pytest.approx(1.25 * 784)
    with pytest.raises(AcceptanceError, match=r"step 'no-load' commands 2000 rpm, above the "
                                              r"limit 1500 rpm of bench"):
        plan_limits(plan, bench_max_input_speed_rpm=1500.0)
