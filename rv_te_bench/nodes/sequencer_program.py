"""The test_sequencer's program path: a plan with whole-reducer steps (issue 38) on the
simulated bench.

Efficiency, no-load, starting and back-driving torque, temperature rise and life steps
need the input torque and the case temperature (``bench/channels``, one BenchChannels per
EncoderBlock) and torque ramps, which a bench's ros2_control forward command controllers
do not carry. For such a plan the sequencer sends each step's program to the simulated
bench's ``bench/run_program`` (``commanded: true``, ``losses: true``), which answers with
the blocks per segment, and feeds the runner the bench's own ``bench/encoders`` with their
channels (a block is held until its channels come, or :data:`HOLD_BLOCKS` blocks later
goes without and its segment is not analysed). In fast mode the bench waits for the
sequencer as for its recorder (:class:`~rv_te_bench.nodes.backpressure.BlockAcks`: the
last block whose encoders and channels both came), so a sequencer that falls behind loses
neither. A cancel stops the bench (``bench/stop``).
Every other plan is driven through setpoints (:mod:`rv_te_bench.nodes.test_sequencer`).
"""

from __future__ import annotations

import collections
import dataclasses
import math
import time
from typing import TYPE_CHECKING, Any

import numpy as np
import yaml
from rv_te_msgs.msg import BenchChannels, EncoderBlock
from rv_te_msgs.srv import RunBenchProgram
from std_srvs.srv import Trigger

from rv_te_bench.acceptance import StepRunner
from rv_te_bench.acceptance._loss_results import bench_channels
from rv_te_bench.acceptance.preflight import NEEDS
from rv_te_bench.errors import AcceptanceError
from rv_te_bench.io.bench_record import bench_uncertainty_of
from rv_te_bench.nodes import qos
from rv_te_bench.nodes.backpressure import BlockAcks

if TYPE_CHECKING:
    from rclpy.action.server import ServerGoalHandle
    from rv_te_msgs.action import RunTestPlan

    from rv_te_bench.acceptance.plan import Step, TestPlan
    from rv_te_bench.acceptance.tolerance import Measured
    from sim.bench_info import BenchInfoData

__all__ = ['HOLD_BLOCKS', 'Aborted', 'Cancelled', 'ProgramSteps', 'needs_programs']

#: Blocks held waiting for their bench/channels before one goes without.
HOLD_BLOCKS = 50
#: bench/channels messages kept for blocks still to come.
_KEEP_CHANNELS = 5000


class Cancelled(Exception):  # noqa: N818 - a control-flow signal, not an error
    """The operator cancelled the test (the reason in the message)."""


class Aborted(Exception):  # noqa: N818 - a control-flow signal carrying the reason
    """A step ended early for a reason of the bench or the plan (in the message)."""


def needs_programs(plan: TestPlan) -> bool:
    """Whether the plan has whole-reducer steps (run as bench programs)."""
    return any(st.kind in NEEDS and st.kind != 'hysteresis' for st in plan.steps)


class ProgramSteps:
    """Mixin of TestSequencerNode: steps run as the simulated bench's programs."""

    # provided by the node
    busy: dict[str, Any] | None
    bench_info: BenchInfoData | None
    drops: Any
    p: Any

    def _init_programs(self) -> None:
        node: Any = self
        self._runner: StepRunner | None = None
        self._prog: dict[str, Any] = {}
        # blocks that arrive between a program's start on the bench and the answer to its
        # service call (the bench publishes at once): replayed when the answer is in
        self._early: collections.deque[EncoderBlock] = collections.deque(maxlen=5000)
        self._want_channels = False
        self._channels: dict[int, BenchChannels] = {}
        self._held: dict[int, EncoderBlock] = {}
        # how far the blocks came in (whether a program runs or not): a fast bench holds
        # while the last block with both its encoders and its channels is too far behind
        self._last_encoders_seq: int | None = None
        self._last_channels_seq: int | None = None
        node.create_subscription(BenchChannels, 'bench/channels', self._on_channels,
                                 qos.ENCODER_QOS)
        self.block_acks = BlockAcks(node, self._taken_seq)
        self.cli_program = node.create_client(RunBenchProgram, 'bench/run_program')
        self.cli_stop = node.create_client(Trigger, 'bench/stop')

    def _reset_programs(self) -> None:
        self._early.clear()
        self._channels.clear()
        self._held.clear()
        self._runner, self._prog = None, {}

    # -- data -------------------------------------------------------------------------------
    def _taken_seq(self) -> int | None:
        """The last block taken: its encoders, and its channels where the bench sends them."""
        enc, ch = self._last_encoders_seq, self._last_channels_seq
        return enc if ch is None or enc is None else min(enc, ch)

    def _saw_encoders(self, seq: int) -> None:
        if self._last_encoders_seq is None or seq > self._last_encoders_seq:
            self._last_encoders_seq = seq

    def _on_channels(self, msg: BenchChannels) -> None:
        if self._last_channels_seq is None or int(msg.seq) > self._last_channels_seq:
            self._last_channels_seq = int(msg.seq)
        if self.busy is None:
            return
        self._channels[int(msg.seq)] = msg
        if len(self._channels) > _KEEP_CHANNELS:   # those of blocks not in a step
            for seq in sorted(self._channels)[:len(self._channels) - _KEEP_CHANNELS]:
                del self._channels[seq]
        if getattr(self, '_drive', None) is not None:   # a step driven by setpoints
            self._release_driven()   # type: ignore[attr-defined]
        elif self._held:
            self._release_held()

    def _release_held(self) -> None:
        """Feed the held blocks whose channels came, in order; a block held longer than
        HOLD_BLOCKS blocks goes without (its segment is then not analysed)."""
        while self._held:
            seq = min(self._held)
            ch = self._channels.pop(seq, None)
            if ch is None and len(self._held) <= HOLD_BLOCKS:
                return
            self._take(self._held.pop(seq), ch, lost=ch is None)

    def _on_program_block(self, msg: EncoderBlock) -> None:
        """A bench/encoders block while no setpoint-driven step runs."""
        if self._runner is None or not self._prog:
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
            self._poke()   # type: ignore[attr-defined]

    # -- steps ------------------------------------------------------------------------------
    async def _program_bench(self) -> BenchInfoData:
        """Wait for bench/info and the simulated bench's bench/run_program."""
        deadline = time.monotonic() + self.p.bench_timeout_s
        while self.bench_info is None or not self.cli_program.service_is_ready():
            if time.monotonic() > deadline:
                what = 'bench/info' if self.bench_info is None else 'the bench/run_program service'
                msg = (f'no bench: {what} not seen in {self.p.bench_timeout_s:g} s (a plan with '
                       'whole-reducer steps runs on the simulated bench with commanded: true '
                       'and losses: true)')
                raise AcceptanceError(msg)
            await self._sleep()   # type: ignore[attr-defined]
        # the bench runs a program the moment it gets one, without waiting for subscribers
        # itself: the session's recorder must be on bench/encoders first, or the first
        # blocks of the first step are not in the bag
        await self._wait_for_recorder()   # type: ignore[attr-defined]
        return self.bench_info

    async def _run_program_step(self, goal_handle: ServerGoalHandle, req: RunTestPlan.Goal,
                                j: int, step: Step, info: BenchInfoData,
                                n_steps: int) -> tuple[list[Measured], dict[str, Any]]:
        node: Any = self
        runner = StepRunner(step, info, uncertainty=bench_uncertainty_of(info)[0])
        call = RunBenchProgram.Request(program_yaml=yaml.safe_dump(runner.program()))
        future = self.cli_program.call_async(call)
        while not future.done():
            await node._sleep()
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
        for m in early:
            self._on_program_block(m)
        params = yaml.safe_dump(_plain(dataclasses.asdict(step)), default_flow_style=True)
        node._publish_step(req, j, n_steps, step, 'started', params, '')
        last_feedback = 0.0
        done_segments = 0
        step_decided: list[Measured] = []
        while self._prog['next'] < self._prog['total']:
            # a segment is complete once a block of a later one came: its metric is decided
            while done_segments < self._prog['segment']:
                step_decided += runner.segment_metrics(done_segments)
                done_segments += 1
                if step_decided:
                    node._publish_running(req, j, step_decided)
            if goal_handle.is_cancel_requested:
                await self._stop_bench()
                node._publish_step(req, j, n_steps, step, 'cancelled', params, yaml.safe_dump(
                    {'reason': 'cancelled by the operator'}))
                msg = f'cancelled by the operator (step {step.name!r})'
                raise Cancelled(msg)
            if time.monotonic() - self._prog['last_wall'] > self.p.bench_timeout_s:
                await self._stop_bench()
                why = f'no block from the bench for {self.p.bench_timeout_s:g} s'
                node._publish_step(req, j, n_steps, step, 'aborted', params,
                                   yaml.safe_dump({'reason': why}))
                msg = f'step {step.name!r}: {why}'
                raise Aborted(msg)
            now = time.monotonic()
            if now - last_feedback >= self.p.feedback_period_s:
                last_feedback = now
                node._feedback(goal_handle, j, n_steps, step, runner)
            await node._sleep()
        node._feedback(goal_handle, j, n_steps, step, runner)
        measured, details = runner.result()
        details['blocks_missing'] = self._prog['missing']
        node._publish_step(req, j, n_steps, step, 'finished', params, yaml.safe_dump(
            {m.name: (None if not math.isfinite(m.value) else m.value) for m in measured}))
        self._runner, self._prog = None, {}
        self._held.clear()
        return measured, details

    async def _stop_bench(self) -> None:
        if not self.cli_stop.service_is_ready():
            node: Any = self
            node.get_logger().error('bench/stop not available: the bench may still run')
            return
        future = self.cli_stop.call_async(Trigger.Request())
        deadline = time.monotonic() + 5.0
        while not future.done() and time.monotonic() < deadline:
            await self._sleep()   # type: ignore[attr-defined]

    def program_step_fields(self) -> dict[str, Any] | None:
        """The running program step's TestStep fields and progress, or None."""
        prog = self._prog
        if not prog:
            return None
        first = int(prog.get('first_seq', 0))
        return {'first_seq': first, 'last_seq': first + max(int(prog.get('next', 0)) - 1, 0),
                'segment_blocks': [int(n) for n in prog.get('segment_blocks', ())],
                'frac': prog['next'] / prog['total'] if prog.get('total') else 0.0,
                'live': float(prog.get('live', math.nan))}


def _plain(x: object) -> object:
    if isinstance(x, dict):
        return {k: _plain(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_plain(v) for v in x]
    return x
