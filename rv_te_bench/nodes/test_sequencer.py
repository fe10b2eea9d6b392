"""TestSequencerNode: runs an acceptance test plan on a ros2_control bench, as a ROS 2 action.

Action ``run_test_plan`` (``rv_te_msgs/action/RunTestPlan``): the goal carries the plan and
tolerance texts and the unit's identity; the node runs the plan step by step through the
interfaces a ros2_control bench has (:mod:`rv_te_bench.nodes.sequencer_io`): setpoints on
the forward command controllers' ``commands`` topics (the drive joint's velocity, the load
joint's effort or position; topics are parameters), samples read back through
``joint_states`` and the JointState adapter (``bench/encoders``, ``bench/info``). The
simulated bench serves the same interfaces (``bench`` with ``ros2_control: true``), so this
node cannot tell it from a real one. Each step's program is driven by
:class:`~rv_te_bench.acceptance.driver.ProgramDriver`; its blocks go to the step runner.
Whole-reducer steps that are speed and load plateaus (efficiency map, no-load torque,
temperature rise, life checkpoints; issue 38) are driven the same way: their input torque
(the drive joint's effort) and case temperature (a ``sensor_msgs/Temperature`` topic) come
through the JointState adapter on ``bench/channels``, one BenchChannels per EncoderBlock,
paired by seq (a block whose channels have not come :data:`HOLD_BLOCKS` blocks later goes
without, its segment marked not analysed). Their transducers and classes are the bench
description's ``loss_channels`` (in bench/info); a step needing a channel the bench lacks
is refused in one line before anything moves. Starting and back-driving torque need a
torque ramp on the input or a free input, i.e. an effort command interface on the drive
joint, which this route does not command: such a step is refused in one line before
anything moves. With ``loss_route: programs`` a plan with whole-reducer steps runs instead
as the simulated bench's own programs (:mod:`rv_te_bench.nodes.sequencer_program`; ``rv-te
test --launch --bench-programs``).

Safety: every sample read back is checked against the limits of the plan's ``safety`` and
the bench description's ``limits`` (:func:`~rv_te_bench.acceptance.driver.plan_limits`);
a limit exceeded, a setpoint not reached, a stale joint state (no sample read back for the
plan's ``stale_joint_state_s``, or three of the adapter's block periods if longer), a
cancel (Ctrl-C in ``rv-te test``) or this node's own shutdown command zero (drive stopped,
load effort 0) and end the step with the reason: the test is ``aborted`` (or
``cancelled``) and recorded so. Operator steps wait for ``test/acknowledge``
(``std_srvs/Trigger``; ``rv-te ack``), showing the instruction in the feedback, until their
timeout. A second goal while one runs is rejected (ROS goal rejection has no reason field:
the node logs it and the running test is on the latched ``test/report``).

Recorded for the bag: ``test/step`` (TestStep: started / finished / cancelled / aborted,
the EncoderBlock seq range of the step; its result YAML holds the metrics, each segment's
time range on the bench's clock and, when it ended early, the reason) and ``test/report``.

Executor: single-threaded, the goal executed as a coroutine that awaits futures completed by
the subscriptions and a 10 Hz timer, so the data keeps flowing while a goal runs.
"""

from __future__ import annotations

import contextlib
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
from rv_te_msgs.msg import BenchInfo, EncoderBlock, MetricVerdict, TestReport, TestStep
from std_srvs.srv import Trigger

from rv_te_bench.acceptance import StepRunner, build_report, parse_plan
from rv_te_bench.acceptance._files import parse_yaml_text
from rv_te_bench.acceptance._loss_results import bench_channels
from rv_te_bench.acceptance.commanded import feed_parts
from rv_te_bench.acceptance.driver import DriverSettings, ProgramDriver, plan_limits
from rv_te_bench.acceptance.loss_steps import LOSS_PROGRAMS
from rv_te_bench.acceptance.plan import OperatorStep
from rv_te_bench.acceptance.preflight import check_plan
from rv_te_bench.acceptance.runner import running_verdicts
from rv_te_bench.acceptance.tolerance import load_tolerance, parse_tolerance
from rv_te_bench.errors import AcceptanceError
from rv_te_bench.io.bench_record import bench_uncertainty_of
from rv_te_bench.nodes import qos
from rv_te_bench.nodes.common import DropCounter, declare_from_specs, run_node
from rv_te_bench.nodes.params.test_sequencer import PARAMS, TestSequencerParams
from rv_te_bench.nodes.sequencer_io import SetpointLink
from rv_te_bench.nodes.sequencer_program import HOLD_BLOCKS, ProgramSteps, needs_programs
from rv_te_bench.nodes.sequencer_program import Aborted as _Aborted
from rv_te_bench.nodes.sequencer_program import Cancelled as _Cancelled
from rv_te_bench.params import params_record
from sim.bench_info import BenchInfoData

if TYPE_CHECKING:
    from rclpy.action.server import ServerGoalHandle

    from rv_te_bench.acceptance.driver import SafetyLimits
    from rv_te_bench.acceptance.plan import Step, TestPlan
    from rv_te_bench.acceptance.tolerance import Measured

__all__ = ['PARAMS', 'TestSequencerNode', 'main']


#: Steps the setpoint route refuses: what each needs of the drive joint.
_RAMP_KINDS = {'starting_torque': 'a torque ramp on the input shaft',
               'back_driving': 'a free input shaft (zero effort on the drive joint)'}
#: A stale read-back is confirmed when it lasts this much longer on this node's clock [s].
_STALE_CONFIRM_S = 0.25


class TestSequencerNode(ProgramSteps, Node):
    """Runs test plans on a ros2_control bench (see the module docstring)."""

    __test__ = False

    def __init__(self, **kwargs: Any) -> None:
        """Declare parameters, the action server, the setpoint link, topics, the ack service."""
        super().__init__('test_sequencer', **kwargs)
        self.p = params_record(TestSequencerParams, declare_from_specs(self, PARAMS))
        self.drops = DropCounter(self)
        self.bench_info: BenchInfoData | None = None
        self.busy: dict[str, Any] | None = None
        self._drive: dict[str, Any] | None = None     # the running step's loop state
        self._operator: dict[str, Any] | None = None  # the operator step waiting
        self._live: dict[str, Any] = {}                # metrics decided so far
        self._wake: Future | None = None
        self._last_block_wall = math.nan
        self._bench_limits = self._read_bench_limits()
        self._init_programs()     # a plan with whole-reducer steps (sequencer_program)
        self._drive_held: dict[int, EncoderBlock] = {}   # blocks waiting for their channels
        self.link = SetpointLink(
            self, drive_topic=self.p.drive_command_topic,
            effort_topic=self.p.load_effort_command_topic,
            position_topic=self.p.load_position_command_topic)
        self.create_subscription(BenchInfo, 'bench/info', self._on_info, qos.LATCHED_QOS)
        self.create_subscription(EncoderBlock, 'bench/encoders', self._on_block,
                                 qos.ENCODER_QOS)
        self.pub_step = self.create_publisher(TestStep, 'test/step', qos.TE_SAMPLES_QOS)
        self.pub_report = self.create_publisher(TestReport, 'test/report', qos.LATCHED_QOS)
        self.create_service(Trigger, 'test/acknowledge', self._on_ack)
        self.create_timer(0.1, self._on_timer)
        self.server = ActionServer(
            self, RunTestPlan, 'run_test_plan', execute_callback=self._execute,
            goal_callback=self._on_goal, cancel_callback=lambda _g: CancelResponse.ACCEPT)
        self.get_logger().info('test_sequencer ready (action run_test_plan; setpoints on '
                               f'{self.p.drive_command_topic}, '
                               f'{self.p.load_effort_command_topic}, '
                               f'{self.p.load_position_command_topic})')

    def _read_bench_limits(self) -> dict[str, Any]:
        path = self.p.bench_description
        if not path:
            return {}
        from rv_te_bench.io.bench_description import load_bench_description

        d = load_bench_description(path)
        return {'bench_max_input_speed_rpm': d.max_input_speed_rpm,
                'bench_max_output_torque_nm': d.max_output_torque_nm,
                'bench_origin': d.origin}

    def destroy_node(self) -> None:
        """The zero setpoint before going (a stop of this node stops the bench), and the
        action server goes too: rclpy's destroy_node leaves a node's action servers behind,
        and one left in a process answers no goal while clients there see it ready."""
        with contextlib.suppress(Exception):   # the context may be going already
            if self.busy is not None or self._drive is not None:
                self.get_logger().warning('stopping during a test: zero setpoint sent')
            self.link.zero(wait_s=1.0)
        with contextlib.suppress(Exception):
            self.server.destroy()
        super().destroy_node()

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
        self._reset_programs()
        return GoalResponse.ACCEPT

    def _on_ack(self, _req: Trigger.Request, res: Trigger.Response) -> Trigger.Response:
        op = self._operator
        if op is None or op['acked']:
            res.success, res.message = False, 'no operator step is waiting'
        else:
            op['acked'] = True
            res.success, res.message = True, f'acknowledged: {op["instruction"]}'
            self.get_logger().info(res.message)
            self._poke()
        return res

    def _on_block(self, msg: EncoderBlock) -> None:
        self._last_block_wall = time.monotonic()
        self._saw_encoders(int(msg.seq))
        d = self._drive
        if d is None:
            self._on_program_block(msg)   # a bench program's block, or none runs
            return
        if d['done'] or d['abort']:
            return
        if d['channels']:   # held until its bench/channels came (paired by seq)
            self._drive_held[int(msg.seq)] = msg
            self._release_driven()
            return
        self._drive_block(msg, None)

    def _release_driven(self) -> None:
        """Feed the held blocks whose channels came, in order; one held longer than
        HOLD_BLOCKS blocks goes without (its segment is then not analysed)."""
        held = self._drive_held
        while held and self._drive is not None:
            seq = min(held)
            ch = self._channels.pop(seq, None)
            if ch is None and len(held) <= HOLD_BLOCKS:
                return
            self._drive_block(held.pop(seq), ch, lost=ch is None)

    def _drive_block(self, msg: EncoderBlock, ch: Any, *, lost: bool = False) -> None:
        d = self._drive
        if d is None or d['done'] or d['abort']:
            return
        try:
            th_in = np.asarray(msg.theta_in_rad, dtype=np.float64)
            th_out = np.asarray(msg.theta_out_rad, dtype=np.float64)
            tq = np.asarray(msg.torque_out_nm, dtype=np.float64)
            if th_in.size == 0 or th_out.size != th_in.size or tq.size not in (0, th_in.size):
                msg_ = f'block {msg.seq}: arrays of unequal length or empty'
                raise ValueError(msg_)
            t = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9 + np.asarray(
                msg.time_offset_s, dtype=np.float64)
            t_in = temp = None
            if ch is not None:
                t_in = np.asarray(ch.torque_in_nm, dtype=np.float64)
                temp = np.asarray(ch.temp_case_degc, dtype=np.float64)
                if t_in.size not in (0, th_in.size) or temp.size not in (0, th_in.size):
                    msg_ = f'bench/channels {msg.seq}: not one value per sample of its block'
                    raise ValueError(msg_)
        except (ValueError, TypeError) as exc:
            self.drops.drop('malformed', str(exc))
            return
        seq = int(msg.seq)
        if d['first_seq'] < 0:
            d['first_seq'] = seq
        elif seq != d['last_seq'] + 1 and d['driver'].index >= 0:
            lost = seq - d['last_seq'] - 1
            d['runner'].mark(d['driver'].index, f'{lost} block(s) lost before block {seq} '
                                                '(a gap in the data read back)')
            self.drops.drop('gap', f'{lost} block(s) lost before block {seq}')
        d['last_seq'] = seq
        upd = d['driver'].push(t, th_in, th_out, -tq if tq.size else None)
        if upd.parts:
            d['live'] = feed_parts(d['runner'], upd.parts, th_in, th_out, tq,
                                   d['last_segment'], t_in, temp)
            if lost:
                self.drops.drop('channels', f'no bench/channels for block {seq}')
                for i in {p[0] for p in upd.parts}:
                    d['runner'].mark(i, f'the input torque / case temperature of block {seq} '
                                        'never came (bench/channels); not analysed')
        if upd.setpoint is not None:
            self.link.send(upd.setpoint)
        if upd.abort:
            d['abort'] = upd.abort
        if upd.finished:
            d['done'] = True
        self._poke()

    def _on_timer(self) -> None:
        if self._drive is not None:
            self.link.refresh(self.p.setpoint_period_s)
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
            limits = plan_limits(plan, **self._bench_limits)   # before anything moves
            programs = needs_programs(plan) and self.p.loss_route == 'programs'
            if programs:
                info = await self._program_bench()
                # before anything moves: the channels the whole-reducer steps need
                check_plan(plan, channels={'torque_out', *bench_channels(info)},
                           bench=f'the bench {info.bench_id!r}')
            else:
                info = await self._bench(plan)
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
                if isinstance(step, OperatorStep):
                    results.append(await self._wait_for_operator(goal_handle, req, j, step,
                                                                 len(plan.steps)))
                elif programs:
                    results.append(await self._run_program_step(goal_handle, req, j, step,
                                                                info, len(plan.steps)))
                else:
                    results.append(await self._run_step(goal_handle, req, j, step, info,
                                                        len(plan.steps), plan, limits))
                self._live['decided'] = [m for res in results for m in res[0]]
                self._publish_running(req, j)
            self.link.zero()
            report = build_report(plan=plan, profile=profile, info=info, serial=req.serial,
                                  operator=req.operator_name, results=results,
                                  conditions=conditions, started_utc=_iso(started))
            self._finish(result, req, plan.name, report)
            goal_handle.succeed()
        except (_Cancelled, _Aborted) as exc:
            self.link.zero()
            status = 'cancelled' if isinstance(exc, _Cancelled) else 'aborted'
            report = build_report(plan=plan, profile=profile, info=self.bench_info,
                                  serial=req.serial, operator=req.operator_name, results=results,
                                  started_utc=_iso(started), status=status, why=str(exc))
            self._finish(result, req, plan.name, report)
            if status == 'cancelled':
                goal_handle.canceled()
            else:
                goal_handle.abort()
        except Exception as exc:  # noqa: BLE001 - every failure ends the goal with its reason
            self.link.zero()
            result.verdict, result.reason = 'error', str(exc)
            if not isinstance(exc, AcceptanceError):
                result.reason = f'internal error: {type(exc).__name__}: {exc}'
                self.get_logger().error(traceback.format_exc())
            self.get_logger().error(f'test of unit {req.serial!r}: {result.reason}')
            self._publish_report(req, plan.name if plan else '', 'error', str(exc), [], '')
            goal_handle.abort()
        finally:
            self._drive, self._operator, self.busy, self._live = None, None, None, {}
            self._runner, self._prog = None, {}
        return result

    async def _bench(self, plan: TestPlan) -> BenchInfoData:
        """Wait for bench/info (the adapter), joint states and the controllers' topics."""
        modes = {'effort'} | ({'position'} if any(
            getattr(s, 'method', '') == 'constant_speed' for s in plan.steps) else set())
        deadline = time.monotonic() + self.p.bench_timeout_s
        checked = False
        while True:
            if self.bench_info is not None and not checked:   # before anything moves
                self._check_setpoint_plan(plan, self.bench_info)
                checked = True
            missing = []
            if self.bench_info is None:
                missing.append('bench/info (is the joint_state_adapter running with a bench '
                               'description?)')
            if time.monotonic() - self._last_block_wall > plan.safety.stale_joint_state_s \
                    or math.isnan(self._last_block_wall):
                missing.append('joint states (no sample on bench/encoders from the '
                               'JointState adapter)')
            missing += [f'a controller on {t}' for t in self.link.missing(modes)]
            if not missing:
                break
            if time.monotonic() > deadline:
                msg = (f'no bench: {"; ".join(missing)} not seen in '
                       f'{self.p.bench_timeout_s:g} s')
                raise AcceptanceError(msg)
            await self._sleep()
        await self._wait_for_recorder()
        assert self.bench_info is not None
        return self.bench_info

    async def _wait_for_recorder(self) -> None:
        """Wait (``wait_timeout_s`` at most) until ``wait_for_nodes`` subscribe
        bench/encoders, so every step's blocks are recorded from its first."""
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

    def _check_setpoint_plan(self, plan: TestPlan, info: BenchInfoData) -> None:
        """One line, before anything moves, for a step the setpoint route cannot run on this
        bench: a channel it lacks (bench/info's loss_channels), or a torque ramp on the input
        / a free input (no effort command interface on the drive joint is commanded)."""
        import types

        bench = f'the bench {info.bench_id!r}'
        ramps = [j for j, st in enumerate(plan.steps) if st.kind in _RAMP_KINDS]
        first = ramps[0] if ramps else len(plan.steps)
        # the steps before the first ramp in plan order (the message names the first problem)
        check_plan(types.SimpleNamespace(steps=plan.steps[:first]),  # type: ignore[arg-type]
                   channels={'torque_out', *bench_channels(info)}, bench=bench)
        if ramps:
            st = plan.steps[first]
            msg = (f'step {first} ({st.name!r}, {st.kind}) needs {_RAMP_KINDS[st.kind]}, i.e. '
                   'an effort command interface on the drive joint, which the setpoint route '
                   f'does not command on {bench} (drive velocity only); nothing was run')
            raise AcceptanceError(msg)

    async def _wait_for_operator(self, goal_handle: ServerGoalHandle, req: RunTestPlan.Goal,
                                 j: int, step: OperatorStep,
                                 n_steps: int) -> tuple[list[Measured], dict[str, Any]]:
        self.link.zero()
        self._operator = op = {'instruction': step.instruction, 'acked': False}
        start = time.monotonic()
        self._publish_step(req, j, n_steps, step, 'started', '', '')
        self.get_logger().info(f'waiting for the operator: {step.instruction} (rv-te ack, or '
                               'the test/acknowledge service)')
        last = 0.0
        try:
            while not op['acked']:
                waited = time.monotonic() - start
                if goal_handle.is_cancel_requested:
                    self._publish_step(req, j, n_steps, step, 'cancelled', '', yaml.safe_dump(
                        {'reason': 'cancelled by the operator'}))
                    msg = f'cancelled by the operator (operator step {step.name!r})'
                    raise _Cancelled(msg)
                if waited > step.timeout_s:
                    why = (f'operator step {step.name!r}: no acknowledgement of '
                           f'{step.instruction!r} within {step.timeout_s:g} s')
                    self._publish_step(req, j, n_steps, step, 'aborted', '',
                                       yaml.safe_dump({'reason': why}))
                    raise _Aborted(why)
                if time.monotonic() - last >= self.p.feedback_period_s:
                    last = time.monotonic()
                    goal_handle.publish_feedback(RunTestPlan.Feedback(
                        step_index=j, step_count=n_steps, step_name=step.name,
                        step_kind='operator', step_progress=min(1.0, waited / step.timeout_s),
                        plan_progress=j / n_steps, live_metric='waiting_s',
                        live_value=waited,
                        message=f'waiting for the operator: {step.instruction}'))
                await self._sleep()
        finally:
            self._operator = None
        waited = time.monotonic() - start
        self._publish_step(req, j, n_steps, step, 'finished', '',
                           yaml.safe_dump({'acknowledged_after_s': round(waited, 3)}))
        measured, details = StepRunner(step, self.bench_info).result()  # type: ignore[arg-type]
        return measured, {**details, 'acknowledged_after_s': waited}

    async def _run_step(self, goal_handle: ServerGoalHandle, req: RunTestPlan.Goal, j: int,
                        step: Step, info: BenchInfoData, n_steps: int, plan: TestPlan,
                        limits: SafetyLimits) -> tuple[list[Measured], dict[str, Any]]:
        runner = StepRunner(step, info, uncertainty=bench_uncertainty_of(info)[0])
        program = runner.program()
        torques = [abs(float(s.get('torque_nm', s.get('load_nm', 0.0)))) for s in program]
        settings = DriverSettings(torque_tolerance_nm=max(0.005 * max(torques, default=0.0),
                                                          0.2),
                                  reach_timeout_s=plan.safety.reach_timeout_s)
        driver = ProgramDriver(program, limits=limits, settings=settings,
                               sample_rate_hz=info.sample_rate_hz)
        self._drive_held.clear()
        self._drive = d = {'runner': runner, 'driver': driver, 'first_seq': -1, 'last_seq': -1,
                           'live': math.nan, 'done': False, 'abort': '', 'last_segment': [-1],
                           'channels': step.kind in LOSS_PROGRAMS and bool(
                               {'torque_in', 'temperature'} & set(bench_channels(info)))}
        params = yaml.safe_dump(_plain(dataclasses.asdict(step)), default_flow_style=True)
        self._publish_step(req, j, n_steps, step, 'started', params, '')
        self.link.send(driver.start())
        self.get_logger().info(f'step {j + 1}/{n_steps} {step.name!r}: {len(program)} '
                               'segments, driven through setpoints')
        stale = plan.safety.stale_joint_state_s
        block_s = info.block_size / info.sample_rate_hz
        last_feedback = 0.0
        self._last_block_wall = time.monotonic()
        suspect = math.inf      # when the read-back first looked stale
        done_segments = 0
        step_decided: list[Measured] = []
        while not d['done']:
            why = ''
            # a segment is complete once a block of a later one came: its metric is decided
            while done_segments < d['last_segment'][0]:
                step_decided += runner.segment_metrics(done_segments)
                done_segments += 1
                if step_decided:
                    self._publish_running(req, j, step_decided)
            if goal_handle.is_cancel_requested:
                self._end_step(req, j, n_steps, step, params, 'cancelled',
                               'cancelled by the operator')
                msg = f'cancelled by the operator (step {step.name!r})'
                raise _Cancelled(msg)
            stale_why = ''
            quiet = time.monotonic() - self._last_block_wall
            if quiet > max(stale, 3 * block_s):
                stale_why = (f'no joint state read back for {quiet:.3g} s (limit {stale:g} s; '
                             'joint_states through the JointState adapter)')
            # stale only when it still is after this node has had the CPU for a moment: a
            # node that was itself held up finds the messages waiting, not missing
            if not stale_why:
                suspect = math.inf
            elif suspect == math.inf:
                suspect = time.monotonic()
            elif time.monotonic() - suspect >= _STALE_CONFIRM_S:
                why = stale_why
            if d['abort']:
                why = d['abort']
            if why:
                self._end_step(req, j, n_steps, step, params, 'aborted', why)
                msg = f'step {step.name!r}: {why}'
                raise _Aborted(msg)
            now = time.monotonic()
            if now - last_feedback >= self.p.feedback_period_s:
                last_feedback = now
                self._feedback(goal_handle, j, n_steps, step, runner)
            await self._sleep()
        self._feedback(goal_handle, j, n_steps, step, runner)
        measured, details = runner.result()
        details['segments_s'] = [list(b) for b in driver.boundaries]
        self._publish_step(req, j, n_steps, step, 'finished', params, yaml.safe_dump(
            {**{m.name: (None if not math.isfinite(m.value) else m.value) for m in measured},
             'segments_s': details['segments_s']}))
        self._drive = None
        return measured, details

    def _end_step(self, req: RunTestPlan.Goal, j: int, n: int, step: Step, params: str,
                  state: str, why: str) -> None:
        self.link.zero()
        self._publish_step(req, j, n, step, state, params, yaml.safe_dump({'reason': why}))
        self.get_logger().error(f'step {step.name!r} {state}: {why} (zero setpoint sent)')
        self._drive = None

    # -- messages -------------------------------------------------------------------------
    def _feedback(self, goal_handle: ServerGoalHandle, j: int, n: int, step: Step,
                  runner: StepRunner) -> None:
        d = self._drive or {}
        driver = d.get('driver')
        frac, live = 0.0, float(d.get('live', math.nan))
        if driver is not None and driver.program:
            frac = min(1.0, max(0, driver.index) / len(driver.program))
        prog = self.program_step_fields()
        if prog is not None:
            frac, live = prog['frac'], prog['live']
        fb = RunTestPlan.Feedback(step_index=j, step_count=n, step_name=step.name,
                                  step_kind=step.kind, step_progress=frac,
                                  plan_progress=(j + frac) / n, live_metric=runner.live_name,
                                  live_value=live,
                                  message=f'step {j + 1}/{n} {step.name}: {100 * frac:.0f} %')
        goal_handle.publish_feedback(fb)

    def _publish_step(self, req: RunTestPlan.Goal, j: int, n: int, step: Step, state: str,
                      params: str, result: str) -> None:
        d = self._drive or {}
        first, last = max(0, d.get('first_seq', 0)), max(0, d.get('last_seq', 0))
        blocks: list[int] = []
        prog = self.program_step_fields()
        if prog is not None:    # a bench program: its blocks per segment
            first, last, blocks = prog['first_seq'], prog['last_seq'], prog['segment_blocks']
        msg = TestStep(serial=req.serial, step_index=j, step_count=n, step_name=step.name,
                       step_kind=step.kind, state=state, first_seq=first, last_seq=last,
                       segment_blocks=blocks, parameters_yaml=params, result_yaml=result)
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
