"""TestSequencerNode: runs an acceptance test plan on the bench, as a ROS 2 action.

Action ``run_test_plan`` (``rv_te_msgs/action/RunTestPlan``): the goal carries the plan and
tolerance texts and the unit's identity; the node runs the plan step by step, sending each
step's bench program to ``bench/run_program`` (the bench in ``commanded`` mode) and feeding
the blocks of ``bench/encoders`` to the step runner (:mod:`rv_te_bench.acceptance.runner`);
feedback gives the step, the progress and a live value; the result gives every metric with
its limit, margin and verdict. A cancel stops the bench (``bench/stop``). A second goal
while one runs is rejected (ROS goal rejection has no reason field: the node logs the reason
and the running test is on the latched ``test/report``, where ``rv-te test`` reads it).

Recorded for the bag: ``test/step`` (TestStep: started / finished / cancelled, with the
EncoderBlock seq range of the step) and ``test/report`` (TestReport: the verdict, the
metrics and the report JSON). While the test runs, ``test/report`` (verdict 'running') is
sent again each time a metric is decided (a TE direction or sweep point when its segment
ends, a hysteresis step's metrics when the step ends): every metric decided so far against
its limit, the others 'pending', and in the reason what is decided of the unit's verdict
(FAIL as soon as one metric is out of its limit) - the live page shows it as it comes.

Executor: single-threaded, with the goal executed as a coroutine that awaits futures
completed by the subscription and a 10 Hz timer, so the data keeps flowing while a goal runs.
"""

from __future__ import annotations

import collections
import dataclasses
import json
import math
import sys
import time
import traceback
from typing import TYPE_CHECKING, Any

import numpy as np
import yaml
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.node import Node
from rclpy.task import Future
from rv_te_msgs.action import RunTestPlan
from rv_te_msgs.msg import (
    BenchChannels,
    BenchInfo,
    EncoderBlock,
    MetricVerdict,
    TestReport,
    TestStep,
)
from rv_te_msgs.srv import RunBenchProgram
from std_srvs.srv import Trigger

from rv_te_bench.acceptance import StepRunner, build_report, parse_plan
from rv_te_bench.acceptance._files import parse_yaml_text
from rv_te_bench.acceptance._loss_results import bench_channels
from rv_te_bench.acceptance.preflight import NEEDS, check_plan
from rv_te_bench.acceptance.runner import running_verdicts
from rv_te_bench.acceptance.tolerance import load_tolerance, parse_tolerance
from rv_te_bench.errors import AcceptanceError
from rv_te_bench.io.bench_record import bench_uncertainty_of
from rv_te_bench.nodes import qos
from rv_te_bench.nodes.common import DropCounter, declare_from_specs, run_node
from rv_te_bench.nodes.params.test_sequencer import PARAMS, TestSequencerParams
from rv_te_bench.params import params_record
from sim.bench_info import BenchInfoData

if TYPE_CHECKING:
    from rclpy.action.server import ServerGoalHandle

    from rv_te_bench.acceptance.plan import Step
    from rv_te_bench.acceptance.tolerance import Measured

__all__ = ['PARAMS', 'TestSequencerNode', 'main']

#: Blocks held waiting for their bench/channels before one goes without.
_HOLD_BLOCKS = 50
#: bench/channels messages kept for blocks still to come.
_KEEP_CHANNELS = 5000


class _Cancelled(Exception):  # noqa: N818 - a control-flow signal, not an error
    pass


class TestSequencerNode(Node):
    """Runs test plans on the bench (see the module docstring)."""

    __test__ = False

    def __init__(self, **kwargs: Any) -> None:
        """Declare parameters, the action server, clients, topics; ``kwargs`` go to Node."""
        super().__init__('test_sequencer', **kwargs)
        self.p = params_record(TestSequencerParams, declare_from_specs(self, PARAMS))
        self.drops = DropCounter(self)
        self.bench_info: BenchInfoData | None = None
        self.busy: dict[str, Any] | None = None
        self._runner: StepRunner | None = None
        self._prog: dict[str, Any] = {}
        self._live: dict[str, Any] = {}
        self._wake: Future | None = None
        # blocks that arrive between a program's start on the bench and the answer to its
        # service call (the bench publishes at once): replayed when the answer is in
        self._early: collections.deque[EncoderBlock] = collections.deque(maxlen=5000)
        self.create_subscription(BenchInfo, 'bench/info', self._on_info, qos.LATCHED_QOS)
        self.create_subscription(EncoderBlock, 'bench/encoders', self._on_block,
                                 qos.ENCODER_QOS)
        # a bench with loss channels (issue 38) sends a BenchChannels per EncoderBlock: a
        # block is fed with its channels, held until they come (or _HOLD_BLOCKS later)
        self.create_subscription(BenchChannels, 'bench/channels', self._on_channels,
                                 qos.ENCODER_QOS)
        self._want_channels = False
        self._channels: dict[int, BenchChannels] = {}
        self._held: dict[int, EncoderBlock] = {}
        self.cli_program = self.create_client(RunBenchProgram, 'bench/run_program')
        self.cli_stop = self.create_client(Trigger, 'bench/stop')
        self.pub_step = self.create_publisher(TestStep, 'test/step', qos.TE_SAMPLES_QOS)
        self.pub_report = self.create_publisher(TestReport, 'test/report', qos.LATCHED_QOS)
        self.create_timer(0.1, self._on_timer)
        self.server = ActionServer(
            self, RunTestPlan, 'run_test_plan', execute_callback=self._execute,
            goal_callback=self._on_goal, cancel_callback=lambda _g: CancelResponse.ACCEPT)
        self.get_logger().info('test_sequencer ready (action run_test_plan)')

    # -- callbacks ------------------------------------------------------------------------------
    def _on_info(self, msg: BenchInfo) -> None:
        self.bench_info = BenchInfoData.from_message(msg)

    def _on_goal(self, goal: RunTestPlan.Goal) -> GoalResponse:
        if self.busy is not None:
            b = self.busy
            self.get_logger().warning(
                f'goal for unit {goal.serial!r} rejected: busy with plan {b["plan"]!r} for '
                f'unit {b["serial"]!r} (step {b["step"] + 1} of {b["steps"]})')
            return GoalResponse.REJECT
        self.busy = {'plan': '?', 'serial': goal.serial, 'step': -1, 'steps': 0}
        self._early.clear()
        self._channels.clear()
        self._held.clear()
        return GoalResponse.ACCEPT

    def _on_channels(self, msg: BenchChannels) -> None:
        if self.busy is None:
            return
        self._channels[int(msg.seq)] = msg
        if len(self._channels) > _KEEP_CHANNELS:   # those of blocks not in a step
            for seq in sorted(self._channels)[:len(self._channels) - _KEEP_CHANNELS]:
                del self._channels[seq]
        if self._held:
            self._release_held()

    def _release_held(self) -> None:
        """Feed the held blocks whose channels came, in order; a block held longer than
        _HOLD_BLOCKS blocks goes without (its segment is then not analysed)."""
        while self._held:
            seq = min(self._held)
            ch = self._channels.pop(seq, None)
            if ch is None and len(self._held) <= _HOLD_BLOCKS:
                return
            self._take(self._held.pop(seq), ch, lost=ch is None)

    def _on_block(self, msg: EncoderBlock) -> None:
        runner, prog = self._runner, self._prog
        if runner is None or not prog:
            if self.busy is not None:
                self._early.append(msg)
            return
        if not self._want_channels:
            self._take(msg, None)
            return
        self._held[int(msg.seq)] = msg
        self._release_held()

    def _take(self, msg: EncoderBlock, ch: BenchChannels | None, *, lost: bool = False) -> None:
        runner, prog = self._runner, self._prog
        if runner is None or not prog:
            return
        k = int(msg.seq) - prog['first_seq']
        if k < 0 or k >= prog['total'] or k < prog['next']:
            return
        if k > prog['next']:
            prog['missing'] += k - prog['next']
            self.drops.drop('gap', f'blocks {prog["next"]}..{k - 1} of the step missing')
        seg = int(np.searchsorted(prog['ends'], k, side='right'))
        if seg != prog['segment']:
            runner.next_segment()
            prog['segment'] = seg
        if lost:
            self.drops.drop('channels', f'no bench/channels for block {int(msg.seq)}')
            runner.mark(seg, f'the input torque / case temperature of block {int(msg.seq)} '
                             'never came (bench/channels); not analysed')
        try:
            prog['live'] = runner.feed(
                seg, np.asarray(msg.theta_in_rad), np.asarray(msg.theta_out_rad),
                np.asarray(msg.torque_out_nm),
                None if ch is None else np.asarray(ch.torque_in_nm),
                None if ch is None else np.asarray(ch.temp_case_degc))
        except (ValueError, IndexError) as exc:
            self.drops.drop('malformed', str(exc))
        prog['next'] = k + 1
        prog['last_wall'] = time.monotonic()
        if prog['next'] >= prog['total']:
            self._poke()

    def _on_timer(self) -> None:
        self._poke()

    def _poke(self) -> None:
        if self._wake is not None and not self._wake.done():
            self._wake.set_result(True)

    async def _sleep(self) -> None:
        self._wake = Future()
        await self._wake

    # -- goal -------------------------------------------------------------------------------------
    async def _execute(self, goal_handle: ServerGoalHandle) -> RunTestPlan.Result:
        req = goal_handle.request
        result = RunTestPlan.Result()
        started = time.time()
        plan = profile = None
        results: list[Any] = []
        try:
            if not req.serial.strip() or not req.operator_name.strip():
                msg = 'serial and operator_name are required'
                raise AcceptanceError(msg)
            plan = parse_plan(parse_yaml_text(req.plan_yaml, 'plan (goal)', AcceptanceError),
                              'plan (goal)')
            conditions = (parse_yaml_text(req.conditions_yaml, 'conditions', AcceptanceError)
                          if req.conditions_yaml.strip() else {}) or {}
            if not isinstance(conditions, dict):
                msg = 'conditions_yaml must be a mapping'
                raise AcceptanceError(msg)
            info = await self._bench()
            if any(st.kind in NEEDS and st.kind != 'hysteresis' for st in plan.steps):
                # before anything moves: the channels the whole-reducer steps need
                check_plan(plan, channels={'torque_out', *bench_channels(info)},
                           bench=f'the bench {info.bench_id!r}')
            if req.tolerance_yaml.strip():
                profile = parse_tolerance(parse_yaml_text(
                    req.tolerance_yaml, 'tolerance (goal)', AcceptanceError), 'tolerance (goal)')
            else:
                profile, _ = load_tolerance(plan.tolerance or info.preset)
            self.busy = {'plan': plan.name, 'serial': req.serial, 'step': 0,
                         'steps': len(plan.steps)}
            self._live = {'plan': plan, 'profile': profile, 'decided': []}
            self._publish_running(req, -1)
            for j, step in enumerate(plan.steps):
                self.busy['step'] = j
                results.append(await self._run_step(goal_handle, req, j, step, info,
                                                    len(plan.steps)))
                self._live['decided'] = [m for res in results for m in res[0]]
                self._publish_running(req, j)
            report = build_report(plan=plan, profile=profile, info=info, serial=req.serial,
                                  operator=req.operator_name, results=results,
                                  conditions=conditions, started_utc=_iso(started))
            self._finish(result, req, plan.name, report)
            goal_handle.succeed()
        except _Cancelled:
            report = build_report(plan=plan, profile=profile, info=self.bench_info,
                                  serial=req.serial, operator=req.operator_name, results=results,
                                  started_utc=_iso(started), status='cancelled')
            self._finish(result, req, plan.name, report)
            goal_handle.canceled()
        except Exception as exc:  # noqa: BLE001 - every failure ends the goal with its reason
            result.verdict, result.reason = 'error', str(exc)
            if not isinstance(exc, AcceptanceError):
                result.reason = f'internal error: {type(exc).__name__}: {exc}'
                self.get_logger().error(traceback.format_exc())
            self.get_logger().error(f'test of unit {req.serial!r}: {result.reason}')
            self._publish_report(req, plan.name if plan else '', 'error', str(exc), [], '')
            goal_handle.abort()
        finally:
            self._runner, self._prog, self.busy, self._live = None, {}, None, {}
        return result

    async def _bench(self) -> BenchInfoData:
        deadline = time.monotonic() + self.p.bench_timeout_s
        while self.bench_info is None or not self.cli_program.service_is_ready():
            if time.monotonic() > deadline:
                what = 'bench/info' if self.bench_info is None else 'the bench/run_program service'
                msg = (f'no bench: {what} not seen in {self.p.bench_timeout_s:g} s (is the '
                       'bench running with commanded: true?)')
                raise AcceptanceError(msg)
            await self._sleep()
        wanted = set(self.p.wait_for_nodes)
        deadline = time.monotonic() + self.p.wait_timeout_s
        ns = self.get_namespace()
        while wanted:
            have = {i.node_name for i in self.get_subscriptions_info_by_topic(
                self.resolve_topic_name('bench/encoders')) if i.node_namespace == ns}
            if wanted <= have:
                break
            if time.monotonic() > deadline:
                self.get_logger().warning(
                    f'starting without {sorted(wanted - have)} on bench/encoders: the steps '
                    'are not recorded by them')
                break
            await self._sleep()
        return self.bench_info

    async def _run_step(self, goal_handle: ServerGoalHandle, req: RunTestPlan.Goal, j: int,
                        step: Step, info: BenchInfoData,
                        n_steps: int) -> tuple[list[Measured], dict[str, Any]]:
        runner = StepRunner(step, info, uncertainty=bench_uncertainty_of(info)[0])
        call = RunBenchProgram.Request(program_yaml=yaml.safe_dump(runner.program()))
        future = self.cli_program.call_async(call)
        while not future.done():
            await self._sleep()
        resp = future.result()
        if not resp.accepted:
            msg = f'step {step.name!r}: the bench refused its program: {resp.reason}'
            raise AcceptanceError(msg)
        runner.expect(list(resp.segment_blocks))
        self._want_channels = bool(bench_channels(info))
        self._runner = runner
        self._prog = {'first_seq': int(resp.first_seq), 'total': int(resp.block_count),
                      'ends': np.cumsum(list(resp.segment_blocks)), 'next': 0, 'segment': 0,
                      'segment_blocks': list(resp.segment_blocks),
                      'missing': 0, 'live': math.nan, 'last_wall': time.monotonic()}
        early, self._early = list(self._early), collections.deque(maxlen=5000)
        for msg in early:
            self._on_block(msg)
        params = yaml.safe_dump(_plain(dataclasses.asdict(step)), default_flow_style=True)
        self._publish_step(req, j, n_steps, step, 'started', params, '')
        last_feedback = 0.0
        done_segments = 0
        step_decided: list[Measured] = []
        while self._prog['next'] < self._prog['total']:
            # a segment is complete once a block of a later one came: its metric is decided
            while done_segments < self._prog['segment']:
                step_decided += runner.segment_metrics(done_segments)
                done_segments += 1
                if step_decided:
                    self._publish_running(req, j, step_decided)
            if goal_handle.is_cancel_requested:
                await self._stop_bench()
                self._publish_step(req, j, n_steps, step, 'cancelled', params, '')
                raise _Cancelled
            if time.monotonic() - self._prog['last_wall'] > self.p.bench_timeout_s:
                await self._stop_bench()
                self._publish_step(req, j, n_steps, step, 'aborted', params, '')
                msg = (f'step {step.name!r}: no block from the bench for '
                       f'{self.p.bench_timeout_s:g} s')
                raise AcceptanceError(msg)
            now = time.monotonic()
            if now - last_feedback >= self.p.feedback_period_s:
                last_feedback = now
                self._feedback(goal_handle, j, n_steps, step, runner)
            await self._sleep()
        self._feedback(goal_handle, j, n_steps, step, runner)
        measured, details = runner.result()
        details['blocks_missing'] = self._prog['missing']
        self._publish_step(req, j, n_steps, step, 'finished', params, yaml.safe_dump(
            {m.name: (None if not math.isfinite(m.value) else m.value) for m in measured}))
        self._runner, self._prog = None, {}
        self._held.clear()
        return measured, details

    async def _stop_bench(self) -> None:
        if not self.cli_stop.service_is_ready():
            self.get_logger().error('bench/stop not available: the bench may still run')
            return
        future = self.cli_stop.call_async(Trigger.Request())
        deadline = time.monotonic() + 5.0
        while not future.done() and time.monotonic() < deadline:
            await self._sleep()

    # -- messages -------------------------------------------------------------------------
    def _feedback(self, goal_handle: ServerGoalHandle, j: int, n: int, step: Step,
                  runner: StepRunner) -> None:
        prog = self._prog
        frac = prog['next'] / prog['total'] if prog.get('total') else 0.0
        fb = RunTestPlan.Feedback(step_index=j, step_count=n, step_name=step.name,
                                  step_kind=step.kind, step_progress=frac,
                                  plan_progress=(j + frac) / n, live_metric=runner.live_name,
                                  live_value=float(prog.get('live', math.nan)),
                                  message=f'step {j + 1}/{n} {step.name}: {100 * frac:.0f} %')
        goal_handle.publish_feedback(fb)

    def _publish_step(self, req: RunTestPlan.Goal, j: int, n: int, step: Step, state: str,
                      params: str, result: str) -> None:
        msg = TestStep(serial=req.serial, step_index=j, step_count=n, step_name=step.name,
                       step_kind=step.kind, state=state,
                       first_seq=self._prog.get('first_seq', 0),
                       last_seq=self._prog.get('first_seq', 0) + max(
                           self._prog.get('next', 0) - 1, 0),
                       segment_blocks=[int(n) for n in self._prog.get('segment_blocks', ())],
                       parameters_yaml=params, result_yaml=result)
        msg.header.stamp = self.get_clock().now().to_msg()
        msg.header.frame_id = self.bench_info.bench_id if self.bench_info else ''
        self.pub_step.publish(msg)

    def _publish_running(self, req: RunTestPlan.Goal, j: int,
                         step_decided: list[Measured] | None = None) -> None:
        """test/report while the test runs: every metric decided so far (finished steps,
        and the complete segments of step ``j``) against its limit, 'pending' for the rest;
        the reason says what is decided of the unit's verdict (FAIL once a metric fails)."""
        live = self._live
        rows, decided = running_verdicts([*live['decided'], *(step_decided or [])],
                                         live['profile'])
        judged = sum(r['verdict'] in {'pass', 'fail'} for r in rows)
        limits = sum(r['verdict'] != 'info' for r in rows)
        n = len(live['plan'].steps)
        where = 'started' if j < 0 else f'step {j + 1}/{n} {live["plan"].steps[j].name}'
        reason = f'{where}: {judged} of {limits} limits judged so far'
        if decided == 'fail':
            failed = ', '.join(r['name'] for r in rows if r['verdict'] == 'fail')
            reason += f'; FAIL decided: out of limit: {failed}'
        self._publish_report(req, live['plan'].name, 'running', reason,
                             [_metric_msg(r) for r in rows], '')

    def _publish_report(self, req: RunTestPlan.Goal, plan_name: str, verdict: str, reason: str,
                        metrics: list[MetricVerdict], report_json: str) -> None:
        msg = TestReport(serial=req.serial, operator_name=req.operator_name, plan_name=plan_name,
                         verdict=verdict, reason=reason, metrics=metrics,
                         plan_yaml=req.plan_yaml, tolerance_yaml=req.tolerance_yaml,
                         report_json=report_json)
        msg.header.stamp = self.get_clock().now().to_msg()
        self.pub_report.publish(msg)

    def _finish(self, result: RunTestPlan.Result, req: RunTestPlan.Goal, plan_name: str,
                report: dict[str, Any]) -> None:
        metrics = [_metric_msg(m) for m in report['metrics']]
        text = json.dumps(report, allow_nan=False)
        result.verdict, result.reason = report['verdict'], report['reason']
        result.metrics, result.report_json = metrics, text
        self._publish_report(req, plan_name, report['verdict'], report['reason'], metrics, text)
        self.get_logger().info(f'unit {req.serial!r}: {report["verdict"]} ({report["reason"]})')


def _plain(x: object) -> object:
    if isinstance(x, dict):
        return {k: _plain(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_plain(v) for v in x]
    return x


def _metric_msg(m: dict[str, Any]) -> MetricVerdict:
    def num(x: float | None) -> float:
        return math.nan if x is None else float(x)
    return MetricVerdict(name=m['name'], step=m['step'], unit=m['unit'], value=num(m['value']),
                         limit_min=num(m['limit_min']), limit_max=num(m['limit_max']),
                         margin=num(m['margin']), verdict=m['verdict'], source=m['source'])


def _iso(t: float) -> str:
    import datetime as dt

    return dt.datetime.fromtimestamp(t, dt.UTC).isoformat(timespec='seconds')


def main(args: list[str] | None = None) -> int:
    """Run the test sequencer in its own process."""
    return run_node(lambda ctx: TestSequencerNode(context=ctx),
                    list(sys.argv if args is None else args), executor_kind='single')


if __name__ == '__main__':
    sys.exit(main())
