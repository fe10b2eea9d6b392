"""Issue 34 part 2: the test sequencer drives a "real" ros2_control bench, a plain rclpy
stand-in written in the test (tests/nodes/real_bench.py: its own closed-form physics), over
the real middleware: setpoints on the forward command controllers' topics, samples back
through joint_states and the JointState adapter (processes, as a session runs them), the
recorder writing the bag. The plan's verdicts against the stand-in's closed-form truth; its
bag judged again offline (``rv-te test --from``, ``rv-te unit-report``); and the safety
paths: a limit exceeded, a stale joint state, an operator acknowledgement timeout, each
commanding zero and leaving a readable bag with an 'aborted' record and its reason.
"""

from __future__ import annotations

import json
import math
import time
from pathlib import Path
from typing import Any

import pytest
import yaml

pytestmark = pytest.mark.ros

rclpy = pytest.importorskip('rclpy')

from rosbags.highlevel import AnyReader  # noqa: E402

from rv_te_bench.cli.ack import acknowledge  # noqa: E402
from rv_te_bench.io.msgdefs import rv_te_typestore  # noqa: E402
from rv_te_bench.launch.session import Session, SessionSpec  # noqa: E402
from tests.nodes.real_bench import DESCRIPTION, Rig  # noqa: E402
from tests.nodes.rosutil import spin_for  # noqa: E402

RATED = 450.0
PLAN = {'plan': 'stand-in', 'safety': {'max_output_torque_nm': 500},
        'steps': [
            {'kind': 'operator', 'name': 'mount', 'instruction': 'mount the unit',
             'timeout_s': 60},
            {'kind': 'te', 'name': 'te', 'speed_rpm': 3000, 'settle_s': 0.2},
            {'kind': 'operator', 'name': 'lock', 'instruction': 'lock the input shaft',
             'timeout_s': 60},
            {'kind': 'hysteresis', 'name': 'hysteresis', 'rated_torque_nm': RATED,
             'dwell_s': 0.1, 'step_fraction': 0.25}]}


@pytest.fixture
def session(tmp_path: Path) -> Any:
    """The adapter (bench description), the sequencer and the recorder in processes."""
    desc = tmp_path / 'bench.yaml'
    desc.write_text(DESCRIPTION, encoding='utf-8')
    spec = SessionSpec(
        nodes=('recorder', 'joint_state_adapter', 'test_sequencer'),
        parameters={'joint_state_adapter': {'bench_description': str(desc)},
                    'recorder': {'output_dir': str(tmp_path), 'bag_name': 'bag'},
                    'test_sequencer': {'bench_description': str(desc)}})
    log = (tmp_path / 'session.log').open('wb')
    s = Session(spec, stdout=log)
    s.start()
    try:
        yield s, tmp_path / 'bag'
    finally:
        s.stop()
        log.close()


@pytest.fixture
def rig_factory(ros_context: Any) -> Any:
    made: list[Rig] = []

    def make(**faults: Any) -> Rig:
        made.append(Rig(ros_context, **faults))
        return made[-1]

    yield make
    for r in made:
        r.close()


def bag_records(bag: Path, serial: str) -> tuple[list[Any], list[Any], int]:
    """(test/step, test/report of the unit, encoder blocks) read back by rosbags."""
    with AnyReader([bag], default_typestore=rv_te_typestore()) as r:
        steps, reports, blocks = [], [], 0
        for conn, _, raw in r.messages():
            if conn.topic.endswith('test/step'):
                steps.append(r.deserialize(raw, conn.msgtype))
            elif conn.topic.endswith('test/report'):
                reports.append(r.deserialize(raw, conn.msgtype))
            elif conn.topic.endswith('bench/encoders'):
                blocks += 1
    return ([s for s in steps if s.serial == serial],
            [m for m in reports if m.serial == serial], blocks)


@pytest.mark.timeout(300)
def test_plan_on_a_real_bench_stand_in(session: Any, rig_factory: Any, tmp_path: Path,
                                       capsys: pytest.CaptureFixture[str]) -> None:
    sess, bag = session
    rig = rig_factory()
    result, feedback = rig.run(PLAN, serial='STAND-1')
    assert result.verdict == 'pass', result.reason
    kinds = [f.step_kind for f in feedback]
    assert kinds.count('operator') >= 2
    assert any(f.message == 'waiting for the operator: lock the input shaft' for f in feedback)
    report = json.loads(result.report_json)
    truth = rig.bench.truth(RATED)
    got = {m['name']: m['value'] for m in report['metrics']}
    for name, value in truth.items():
        tol = 0.01 if name.startswith('te_pp') else 0.02
        assert got[name] == pytest.approx(value, rel=tol), name
    assert report['steps'][0]['acknowledged_after_s'] >= 0
    # the bench was left at zero
    assert rig.bench.velocity == 0.0 and rig.bench.effort == 0.0
    sess.stop()
    steps, reports, blocks = bag_records(bag, 'STAND-1')
    assert [s.state for s in steps] == ['started', 'finished'] * 4
    assert reports[-1].verdict == 'pass' and blocks > 100
    # the same test again from the bag: rv-te unit-report (the recorded time ranges) and
    # rv-te test --from (the parts found in the data)
    from rv_te_bench.cli.main import main

    assert main(['unit-report', str(bag), '--report', str(tmp_path / 'again')]) == 0
    assert 'every metric equals the recorded result' in capsys.readouterr().err
    (tmp_path / 'plan.yaml').write_text(yaml.safe_dump(PLAN), encoding='utf-8')
    assert main(['test', str(tmp_path / 'plan.yaml'), '--serial', 'STAND-1', '--operator',
                 'pytest', '--from', str(bag), '--json', '--out-dir',
                 str(tmp_path / 'judged'), '--no-db']) == 0
    out = capsys.readouterr().out
    judged = json.loads(out[:out.rindex('}') + 1])
    for m in report['metrics']:
        j = next(x for x in judged['metrics'] if x['name'] == m['name'])
        assert j['verdict'] == m['verdict']
        assert j['value'] == pytest.approx(m['value'], rel=0.005), m['name']


def _aborted(bag: Path, serial: str, result: Any, why: str) -> None:
    """An 'aborted' result with its reason, and the same in the readable bag."""
    assert result.verdict == 'aborted', result.reason
    assert why in result.reason, result.reason
    report = json.loads(result.report_json)
    assert report['verdict'] == 'aborted' and why in report['reason']
    steps, reports, blocks = bag_records(bag, serial)
    assert steps[-1].state == 'aborted'
    step_why = why.split(': ', 1)[1] if why.startswith('step ') else why
    assert step_why in yaml.safe_load(steps[-1].result_yaml)['reason']
    assert reports[-1].verdict == 'aborted' and why in reports[-1].reason
    assert blocks > 0


@pytest.mark.timeout(300)
def test_limit_exceeded_commands_zero_and_aborts(session: Any, rig_factory: Any) -> None:
    """The loader overshoots its setpoint changes by 40 %: the step from -225 to -450 N m
    peaks near -540 N m, beyond the plan's 500 N m (the smaller steps stay inside)."""
    sess, bag = session
    rig = rig_factory(overshoot=0.4)
    plan = {**PLAN, 'steps': PLAN['steps'][3:]}
    result, _ = rig.run(plan, serial='STAND-LIMIT')
    why = "step 'hysteresis': output torque -5"
    assert "N m beyond the limit +-500 N m (the plan's safety) at" in result.reason
    spin_for(rig.ex, 0.5)
    assert rig.bench.velocity == 0.0 and rig.bench.effort == 0.0   # zero commanded
    sess.stop()
    _aborted(bag, 'STAND-LIMIT', result, why)


@pytest.mark.timeout(300)
def test_stale_joint_state_commands_zero_and_aborts(session: Any, rig_factory: Any) -> None:
    """The bench's joint_states stop in the middle of the TE step."""
    sess, bag = session
    rig = rig_factory()
    plan = {**PLAN, 'steps': [PLAN['steps'][1]]}

    def silence(feedback: list[Any]) -> None:
        if feedback and feedback[-1].live_value == feedback[-1].live_value and \
                feedback[-1].live_value > 0 and not rig.bench.silent:
            rig.bench.go_silent()

    result, _ = rig.run(plan, serial='STAND-STALE', during=silence)
    assert rig.bench.silent
    spin_for(rig.ex, 0.5)
    assert rig.bench.velocity == 0.0 and rig.bench.effort == 0.0
    sess.stop()
    _aborted(bag, 'STAND-STALE', result, "step 'te': no joint state read back for")
    assert '(limit 1 s; joint_states through the JointState adapter)' in result.reason


@pytest.mark.timeout(300)
def test_operator_acknowledgement_timeout(session: Any, rig_factory: Any) -> None:
    sess, bag = session
    rig = rig_factory()
    plan = {**PLAN, 'steps': [{**PLAN['steps'][0], 'timeout_s': 2}, PLAN['steps'][1]]}
    t0 = time.monotonic()
    result, feedback = rig.run(plan, serial='STAND-ACK', ack=False)
    assert 2.0 <= time.monotonic() - t0 < 30
    assert feedback[0].message == 'waiting for the operator: mount the unit'
    assert rig.bench.setpoints >= 1 and rig.bench.velocity == 0.0   # nothing moved
    # nothing waits any more: an acknowledgement is refused with the reason
    ok, msg = acknowledge(rig.node, rig.ex, wait_s=5.0)
    assert (ok, msg) == (False, 'no operator step is waiting')
    sess.stop()
    _aborted(bag, 'STAND-ACK', result,
             "operator step 'mount': no acknowledgement of 'mount the unit' within 2 s")
    assert math.isfinite(feedback[-1].live_value)
