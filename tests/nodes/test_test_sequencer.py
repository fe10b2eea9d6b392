"""The RunTestPlan action over the real middleware: the simulated ros2_control bench, the
JointState adapter, the test_sequencer and the recorder in their own processes, as ``rv-te
test --launch`` starts them; this test is the action client. Feedback arrives, a second goal
is rejected while one runs (and the CLI's reason comes from the latched test/report), a
cancel mid-plan stops the bench (zero setpoint: the input stops turning) and the recorder
leaves a bag that rosbags and mcap read back with the 'cancelled' record and its reason."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import pytest
import yaml

pytestmark = pytest.mark.ros

rclpy = pytest.importorskip('rclpy')

from mcap.reader import NonSeekingReader  # noqa: E402
from mcap_ros2.decoder import DecoderFactory  # noqa: E402
from rclpy.action import ActionClient  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rosbags.highlevel import AnyReader  # noqa: E402
from rv_te_msgs.action import RunTestPlan  # noqa: E402
from rv_te_msgs.msg import EncoderBlock  # noqa: E402

from rv_te_bench.cli.test import _busy_reason, simulated_session_spec  # noqa: E402
from rv_te_bench.launch.session import Session  # noqa: E402
from rv_te_bench.nodes import qos  # noqa: E402
from rv_te_bench.nodes.goal_client import TrackedGoal  # noqa: E402
from tests.nodes.rosutil import spin_for, spin_until  # noqa: E402

# slow enough to cancel in the middle: 2 s of simulated data per direction at 4x real time
PLAN = {'plan': 'cancel-me', 'steps': [
    {'kind': 'te', 'name': 'te', 'speed_rpm': 1500, 'directions': ['ccw', 'cw'],
     'revolutions': 1, 'settle_s': 0.2},
    {'kind': 'hysteresis', 'name': 'hysteresis', 'rated_torque_nm': 450.0, 'dwell_s': 0.2}]}


def _session(tmp_path: Path, speed_factor: float) -> Any:
    spec = simulated_session_spec(tmp_path, preset='li2023-rv', te_mode='dte',
                                  speed_factor=speed_factor)
    log = (tmp_path / 'session.log').open('wb')
    s = Session(spec, stdout=log)
    s.start()
    try:
        yield s, tmp_path / 'bag'
    finally:
        s.stop()
        log.close()


@pytest.fixture
def session(tmp_path: Path) -> Any:
    """In real time: slow enough to act in the middle of a step."""
    yield from _session(tmp_path, 1.0)


@pytest.fixture
def fast_session(tmp_path: Path) -> Any:
    """At 2x real time: 2000 joint states/s, what ``rv-te test --launch --speed-factor 0``
    runs at (the rate the adapter and the sequencer are known to keep up with)."""
    yield from _session(tmp_path, 2.0)


@pytest.mark.timeout(240)
def test_feedback_rejection_cancel_and_bag(session: Any, ros_context: Any) -> None:
    sess, bag = session
    node = rclpy.create_node('sequencer_test_client', context=ros_context)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(node)
    blocks: list[tuple[float, int, float]] = []   # (arrival, seq, input angle at its end)
    node.create_subscription(EncoderBlock, 'bench/encoders',
                             lambda m: blocks.append((time.monotonic(), int(m.seq),
                                                      float(m.theta_in_rad[-1]))),
                             qos.ENCODER_QOS)
    try:
        client = ActionClient(node, RunTestPlan, 'run_test_plan')
        other = ActionClient(node, RunTestPlan, 'run_test_plan')
        assert spin_until(ex, client.server_is_ready, 30.0), 'no action server'
        # a bad plan or a missing serial: the goal ends at once with the reason, nothing runs
        for bad, why in ((RunTestPlan.Goal(plan_yaml='plan: x\nsteps: []', serial='S',
                                           operator_name='o'), 'steps must be a list'),
                         (RunTestPlan.Goal(plan_yaml=yaml.safe_dump(PLAN), serial=' ',
                                           operator_name='o'), 'serial and operator_name')):
            sent = client.send_goal_async(bad)
            assert spin_until(ex, sent.done, 20.0) and sent.result().accepted
            res_bad = sent.result().get_result_async()
            assert spin_until(ex, res_bad.done, 20.0)
            assert res_bad.result().result.verdict == 'error'
            assert why in res_bad.result().result.reason
        assert spin_until(ex, lambda: len(blocks) > 5, 30.0), 'no joint states read back'
        assert abs(blocks[-1][2] - blocks[0][2]) < 1e-5, 'a bad goal made the bench run'
        feedback: list[Any] = []
        goal = RunTestPlan.Goal(plan_yaml=yaml.safe_dump(PLAN), serial='SN-CANCEL',
                                operator_name='pytest')
        send = client.send_goal_async(goal, feedback_callback=lambda f: feedback.append(
            f.feedback))
        assert spin_until(ex, send.done, 20.0)
        handle = send.result()
        assert handle.accepted
        # feedback arrives, with the step and a live TE value once data flows
        assert spin_until(ex, lambda: any(f.live_value == f.live_value and f.live_value > 0
                                          for f in feedback), 60.0), 'no live feedback'
        assert feedback[0].step_name == 'te' and feedback[0].step_count == 2
        assert all(0.0 <= f.plan_progress <= 1.0 for f in feedback)
        # a second goal while the first runs: rejected, and the reason names the running test
        second = other.send_goal_async(RunTestPlan.Goal(
            plan_yaml=yaml.safe_dump(PLAN), serial='SN-2', operator_name='pytest'))
        assert spin_until(ex, second.done, 20.0)
        assert not second.result().accepted
        reason = _busy_reason(node, ex)
        assert "'cancel-me'" in reason and "'SN-CANCEL'" in reason
        # cancel mid-plan: the result says cancelled and the bench stops sending
        assert feedback[-1].plan_progress < 0.5
        cancel = handle.cancel_goal_async()
        res = handle.get_result_async()
        assert spin_until(ex, lambda: cancel.done() and res.done(), 30.0)
        assert res.result().result.verdict == 'cancelled'
        assert res.result().result.reason == ("cancelled after 0 of 2 steps: cancelled by "
                                              "the operator (step 'te')")
        spin_for(ex, 1.0)
        n_after = len(blocks)
        spin_for(ex, 2.0)
        assert len(blocks) > n_after, 'a ros2_control bench goes on reporting its state'
        # (stopped: the RON 886 noise and one count of quantisation, no motion)
        assert abs(blocks[-1][2] - blocks[n_after][2]) < 1e-5, 'the input kept turning'
    finally:
        node.destroy_node()
    sess.stop()
    # the bag: encoder blocks, the started and the cancelled step, the final report
    assert (bag / 'metadata.yaml').exists()
    with AnyReader([bag]) as reader:
        steps, reports, seqs = [], [], []
        for conn, _, raw in reader.messages():
            if conn.topic == '/test/step':
                steps.append(reader.deserialize(raw, conn.msgtype))
            elif conn.topic == '/test/report':
                reports.append(reader.deserialize(raw, conn.msgtype))
            elif conn.topic == '/bench/encoders':
                seqs.append(int(reader.deserialize(raw, conn.msgtype).seq))
    assert [s.state for s in steps] == ['started', 'cancelled']
    assert yaml.safe_load(steps[-1].result_yaml) == {'reason': 'cancelled by the operator'}
    assert [r.verdict for r in reports][-1] == 'cancelled'
    assert reports[-1].serial == 'SN-CANCEL'
    assert "cancelled by the operator (step 'te')" in reports[-1].reason
    assert seqs == list(range(len(seqs))) and len(seqs) >= n_after
    assert steps[-1].first_seq <= steps[-1].last_seq <= seqs[-1]
    # and an independent reader: mcap + mcap_ros2 decode the test topics
    topics = set()
    for f in sorted(bag.glob('*.mcap')):
        with f.open('rb') as fh:
            for _, channel, _, _msg in NonSeekingReader(
                    fh, decoder_factories=[DecoderFactory()]).iter_decoded_messages(
                    topics=['/test/step', '/test/report']):
                topics.add(channel.topic)
    assert topics == {'/test/step', '/test/report'}
    # rv-te unit-report: the cancelled test, recomputed from the bag, is no verdict (exit 1)
    from rv_te_bench.cli.main import main

    assert main(['unit-report', str(bag), '--report', str(bag.parent / 'again')]) == 1
    assert (bag.parent / 'again' / 'report.html').exists()


@pytest.mark.timeout(180)
def test_client_notices_a_dead_sequencer(session: Any, tmp_path: Path) -> None:
    """SIGKILL of the test_sequencer mid-plan: rv-te test ends with one line, exit 1."""
    import os
    import signal
    import subprocess
    import sys

    from rv_te_bench.launch.session import child_env

    sess, _bag = session
    plan = tmp_path / 'plan.yaml'
    plan.write_text(yaml.safe_dump(PLAN), encoding='utf-8')
    proc = subprocess.Popen(
        [sys.executable, '-m', 'rv_te_bench.cli.main', 'test', str(plan), '--serial', 'SN-K',
         '--operator', 'pytest', '--wait-s', '4', '--out-dir', str(tmp_path / 'out')],
        env=child_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 60.0
        log = tmp_path / 'session.log'
        while 'driven through setpoints' not in log.read_text(errors='replace'):
            assert time.monotonic() < deadline, 'the plan did not start'
            assert proc.poll() is None, proc.communicate()
            time.sleep(0.2)
        os.kill(sess.procs['test_sequencer'].proc.pid, signal.SIGKILL)
        sess.procs['test_sequencer'].expected_exit = True
        out, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 1, (out, err)
    lines = [ln for ln in err.splitlines() if ln.startswith('ERROR')]
    assert lines == ['ERROR: the test_sequencer went away during the test (no action server '
                     'for 4 s); the bench may still be running']


TE_PLAN = {'plan': 'te-live', 'steps': [
    {'kind': 'te', 'name': 'te', 'speed_rpm': 1500, 'directions': ['ccw', 'cw'],
     'revolutions': 1, 'settle_s': 0.2}]}


@pytest.mark.timeout(240)
def test_each_metric_is_judged_on_test_report_as_it_is_decided(fast_session: Any,
                                                               ros_context: Any) -> None:
    """A TE direction's metric is decided when its segment ends: the running test/report
    carries it against its limit before the step (the other direction) has finished, with
    the value the final report gives it; limits not measured yet are 'pending'. (At 2x
    real time: the order of the reports, not their timing, is what is tested; the cw
    direction still takes ~2.4 s after the ccw metric is decided.)"""
    from rv_te_msgs.msg import TestReport, TestStep

    node = rclpy.create_node('sequencer_live_client', context=ros_context)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(node)
    seen: list[tuple[str, Any]] = []
    node.create_subscription(TestReport, 'test/report', lambda m: seen.append(('report', m)),
                             qos.LATCHED_QOS)
    node.create_subscription(TestStep, 'test/step', lambda m: seen.append(('step', m)),
                             qos.TE_SAMPLES_QOS)
    try:
        client = ActionClient(node, RunTestPlan, 'run_test_plan')
        assert spin_until(ex, client.server_is_ready, 30.0), 'no action server'
        # (a goal reply the middleware lost failed this once: followed on the status topic)
        goal = TrackedGoal(node, client, RunTestPlan, 'run_test_plan',
                           RunTestPlan.Goal(plan_yaml=yaml.safe_dump(TE_PLAN),
                                            serial='SN-LIVE', operator_name='pt'))
        assert spin_until(ex, goal.answered, 20.0) and goal.handle.accepted
        assert spin_until(ex, goal.result_done, 120.0)
        spin_for(ex, 1.0)
    finally:
        node.destroy_node()
    final = goal.result()
    by_name = {m.name: m for m in final.metrics}
    ccw = by_name['te_pp_ccw_rad']
    assert ccw.verdict in {'pass', 'fail'} and ccw.value > 0
    finished = next(i for i, (k, m) in enumerate(seen) if k == 'step' and
                    m.state == 'finished')
    early = [m for k, m in seen[:finished] if k == 'report' and m.verdict == 'running'
             and any(x.name == 'te_pp_ccw_rad' for x in m.metrics)]
    assert early, [(k, getattr(m, 'state', getattr(m, 'verdict', ''))) for k, m in seen]
    first = {x.name: x for x in early[0].metrics}
    assert 'te_pp_cw_rad' not in first                    # the cw direction still ran
    got = first['te_pp_ccw_rad']
    assert (got.value, got.limit_max, got.verdict) == (ccw.value, ccw.limit_max, ccw.verdict)
    assert {x.verdict for x in early[0].metrics if x.name != 'te_pp_ccw_rad'} == {'pending'}
    assert early[0].serial == 'SN-LIVE' and '1 of ' in early[0].reason
    assert seen[-1][0] == 'report' and seen[-1][1].verdict == final.verdict
