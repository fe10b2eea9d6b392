"""Every step kind a plan accepts has a program, a result and a finder for recorded data
(the registries a new kind, issue 38, adds itself to), and an operator step measures
nothing on every route."""

from __future__ import annotations

import pytest

from rv_te_bench.acceptance import parse_plan
from rv_te_bench.acceptance._results import RESULTS
from rv_te_bench.acceptance.plan import STEP_KINDS
from rv_te_bench.acceptance.recorded import FINDERS
from rv_te_bench.acceptance.runner import PROGRAMS, StepRunner
from rv_te_bench.errors import BenchDescriptionError
from rv_te_bench.io.bench_description import parse_bench_description
from sim.program import ProgramSimulator


def test_registries_agree() -> None:
    assert set(STEP_KINDS) == set(PROGRAMS) == set(RESULTS) == set(FINDERS)


def test_operator_step() -> None:
    plan = parse_plan({'plan': 'p', 'steps': [
        {'kind': 'operator', 'name': 'lock', 'instruction': 'lock the input shaft',
         'timeout_s': 30}]})
    info = ProgramSimulator(preset='li2023-rv', te_mode='dte').info
    r = StepRunner(plan.steps[0], info)
    assert r.program() == [] and r.result() == (
        [], {'kind': 'operator', 'instruction': 'lock the input shaft'})


@pytest.mark.parametrize(('limits', 'expect'), [
    ({'max_input_speed_rpm': 3000, 'max_output_torque_nm': 900.5}, (3000.0, 900.5)),
    ({'max_output_torque_nm': 0}, 'limits.max_output_torque_nm must be a finite number > 0'),
    ({'max_speed': 1}, "unknown key(s) ['max_speed']"),
])
def test_bench_description_limits(limits: dict, expect: object) -> None:
    data = {'bench_id': 'b', 'preset': 'li2023-rv', 'sample_rate_hz': 1000.0, 'limits': limits}
    if isinstance(expect, str):
        with pytest.raises(BenchDescriptionError, match=expect.replace('[', r'\[').replace(
                ']', r'\]').replace('(', r'\(').replace(')', r'\)')):
            parse_bench_description(data, 'bench.yaml')
        return
    d = parse_bench_description(data, 'bench.yaml')
    assert (d.max_input_speed_rpm, d.max_output_torque_nm) == expect
    assert d.to_plain()['limits'] == {'max_input_speed_rpm': expect[0],
                                      'max_output_torque_nm': expect[1]}
