"""A setpoint-driven step analysed again from its bag (``rv-te unit-report``) with blocks
missing: a segment the hole reaches into is not measured, and says which block is missing;
a hole the bench spent between two segments costs no segment. Truth: the live run's own
values (a different code path: the driver's cut, not the recorded time ranges)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
import yaml

from rv_te_bench.acceptance import load_tolerance, parse_plan
from rv_te_bench.acceptance.commanded import run_plan_commanded
from rv_te_bench.acceptance.driver import plan_limits
from rv_te_bench.acceptance.runner import reanalyse
from sim.commanded import CommandedBench
from sim.program import ProgramSimulator

#: One TE step, both directions (li2023-rv: ratio 121); 1 kHz in blocks of 20 (20 ms).
PLAN = {'plan': 'te', 'steps': [{'kind': 'te', 'name': 'te', 'speed_rpm': 3000,
                                 'load_nm': 200, 'settle_s': 0.2}]}


@pytest.fixture(scope='module')
def run() -> dict[str, Any]:
    bench = CommandedBench(ProgramSimulator(preset='li2023-rv', te_mode='dte',
                                            sample_rate_hz=1000.0, block_size=20, seed=3))
    plan = parse_plan(PLAN)
    profile, _ = load_tolerance('li2023-rv')
    blocks: list[Any] = []
    rep = run_plan_commanded(plan, profile, bench=bench, serial='SN', operator='live',
                             limits=plan_limits(plan), on_block=blocks.append)
    step = rep['steps'][0]
    return {'plan': plan, 'profile': profile, 'info': bench.sim.info, 'report': rep,
            'spans': step['segments_s'],
            'blocks': {k: (np.asarray(b.theta_in_rad), np.asarray(b.theta_out_rad),
                           np.asarray(b.torque_out_nm), b.torque_in_nm, b.temp_case_degc)
                       for k, b in enumerate(blocks)},
            'times': {k: b.t0_s + np.asarray(b.time_offset_s) for k, b in enumerate(blocks)},
            'steps': [{'step_index': 0, 'step_name': 'te', 'state': 'finished',
                       'first_seq': 0, 'last_seq': len(blocks) - 1, 'segment_blocks': [],
                       'result_yaml': yaml.safe_dump({'segments_s': step['segments_s']})}]}


def _again(run: dict[str, Any], drop: set[int]) -> dict[str, Any]:
    blocks = {k: v for k, v in run['blocks'].items() if k not in drop}
    return reanalyse(plan=run['plan'], profile=run['profile'], info=run['info'],
                     steps=run['steps'], blocks=blocks, serial='SN', operator='live',
                     times=run['times'])


def _values(rep: dict[str, Any]) -> dict[str, float | None]:
    return {m['name']: m['value'] for m in rep['steps'][0]['metrics']}


def _blocks_in(run: dict[str, Any], lo: float, hi: float) -> list[int]:
    """Blocks with every sample inside [lo, hi]."""
    return [k for k, t in run['times'].items() if t[0] >= lo and t[-1] <= hi]


def test_whole_bag_gives_the_live_values(run: dict[str, Any]) -> None:
    live = _values(run['report'])
    again = _values(_again(run, set()))
    assert set(live) == {'te_pp_cw_rad', 'te_pp_ccw_rad'}
    for name, value in live.items():
        assert again[name] == pytest.approx(value, rel=1e-12)


def test_a_hole_at_the_step_s_start_reaching_into_its_first_segment(
        run: dict[str, Any]) -> None:
    (lo0, _), _ = run['spans']
    first = [k for k, t in run['times'].items() if t[0] <= lo0]   # up to the segment's start
    assert first == [0, 1]     # 20 ms blocks; the first segment starts at 20 ms
    rep = _again(run, set(first))
    live, again = _values(run['report']), _values(rep)
    first_dir = rep['steps'][0]['rows'][0]['direction']
    other = 'cw' if first_dir == 'ccw' else 'ccw'
    assert again[f'te_pp_{first_dir}_rad'] is None, 'analysed across the missing start'
    assert again[f'te_pp_{other}_rad'] == pytest.approx(live[f'te_pp_{other}_rad'], rel=1e-12)
    assert 'block 0 of the step is not in the bag' in rep['reason']


def test_a_hole_between_two_segments_costs_neither(run: dict[str, Any]) -> None:
    (_, hi0), (lo1, _) = run['spans']
    between = _blocks_in(run, np.nextafter(hi0, np.inf), np.nextafter(lo1, -np.inf))
    assert between, 'no block lies wholly between the two segments'
    rep = _again(run, set(between))
    live, again = _values(run['report']), _values(rep)
    for name, value in live.items():
        assert again[name] == pytest.approx(value, rel=1e-12), name
    assert 'not in the bag' not in rep.get('reason', '')


@pytest.mark.parametrize('where', ['middle', 'end'])
def test_a_hole_in_the_second_segment(run: dict[str, Any], where: str) -> None:
    _, (lo1, hi1) = run['spans']
    inside = _blocks_in(run, lo1, hi1)
    last = max(run['times'])
    drop = ({inside[len(inside) // 2]} if where == 'middle'
            else {k for k, t in run['times'].items() if t[-1] >= hi1})
    assert drop and (where == 'middle' or last in drop)
    rep = _again(run, drop)
    live, again = _values(run['report']), _values(rep)
    second_dir = rep['steps'][0]['rows'][1]['direction']
    first_dir = rep['steps'][0]['rows'][0]['direction']
    assert again[f'te_pp_{second_dir}_rad'] is None
    assert again[f'te_pp_{first_dir}_rad'] == pytest.approx(live[f'te_pp_{first_dir}_rad'],
                                                            rel=1e-12)
    assert f'block {min(drop)} of the step is not in the bag' in rep['reason']
