"""The test_sequencer pairs each EncoderBlock with the BenchChannels of the same seq
(issue 38), whichever comes first: blocks whose channels come late are held and fed in seq
order with them; a block whose channels never come is fed without them after
``_HOLD_BLOCKS`` more blocks, and its segment is marked not analysed (no number from a
block without its torque), the loss counted. The node's callbacks are driven directly with
messages built here (real rclpy node in this process)."""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np
import pytest

pytestmark = pytest.mark.ros

rclpy = pytest.importorskip('rclpy')

from rv_te_msgs.msg import BenchChannels, EncoderBlock  # noqa: E402

from rv_te_bench.acceptance import StepRunner, parse_plan  # noqa: E402
from rv_te_bench.nodes import sequencer_program as sp  # noqa: E402
from rv_te_bench.nodes import test_sequencer as ts  # noqa: E402
from sim.loss_bench import LossConfig  # noqa: E402
from sim.program import ProgramSimulator  # noqa: E402

N = 100   # samples per block
BLOCKS = 80


def _node(ros_context: Any) -> Any:
    node = ts.TestSequencerNode(context=ros_context)
    info = ProgramSimulator(preset='rv-80e-101', te_mode='elastic', sample_rate_hz=1000.0,
                            block_size=N, losses=LossConfig()).info
    step = parse_plan({'plan': 'p', 'steps': [
        {'kind': 'no_load', 'name': 'nl', 'speeds_rpm': [1000, 2000], 'settle_s': 0.0,
         'measure_s': 4.0}]}).steps[0]
    runner = StepRunner(step, info)
    runner.expect([BLOCKS // 2, BLOCKS // 2])
    node.busy = {'plan': 'p', 'serial': 'S', 'step': 0, 'steps': 1}
    node._runner = runner
    node._want_channels = True
    node._prog = {'first_seq': 0, 'total': BLOCKS, 'ends': np.cumsum([BLOCKS // 2] * 2),
                  'next': 0, 'segment': 0, 'segment_blocks': [BLOCKS // 2] * 2, 'missing': 0,
                  'live': math.nan, 'last_wall': time.monotonic()}
    return node


def _block(seq: int) -> EncoderBlock:
    m = EncoderBlock()
    m.seq = seq
    m.sample_rate_hz = 1000.0
    t = (seq * N + np.arange(N)) / 1000.0
    m.time_offset_s = (t - t[0]).tolist()
    m.theta_in_rad = (100.0 * t).tolist()
    m.theta_out_rad = (100.0 * t / 101.0).tolist()
    m.torque_out_nm = [0.0] * N
    return m


def _channels(seq: int) -> BenchChannels:
    m = BenchChannels()
    m.seq = seq
    m.torque_in_nm = [float(seq)] * N          # the block's number: order is visible
    m.temp_case_degc = [20.0 + seq / 100] * N
    return m


def test_late_channels_are_waited_for_and_fed_in_order(ros_context: Any) -> None:
    node = _node(ros_context)
    try:
        for s in range(BLOCKS):                  # every block before its channels
            node._on_block(_block(s))
        # more than _HOLD_BLOCKS held: the oldest went without their channels
        lost = BLOCKS - sp.HOLD_BLOCKS
        assert len(node._held) == sp.HOLD_BLOCKS
        assert node._prog['next'] == lost and node.drops.counts.get('channels') == lost
        for s in reversed(range(BLOCKS)):        # the channels come, last first
            node._on_channels(_channels(s))
        assert node._prog['next'] == BLOCKS and not node._held
        segs = node._runner.segment_data()
        # segment 0 (blocks 0..39) lost blocks 0..29's channels: not analysed, named
        assert 'never came (bench/channels)' in segs[0].note
        # segment 1 (blocks 40..79): every sample with its own block's channels, in order
        assert segs[1].note == ''
        np.testing.assert_array_equal(segs[1].torque_in_nm,
                                      np.repeat(np.arange(40, 80, dtype=float), N))
    finally:
        node.destroy_node()


def test_channels_first_then_blocks(ros_context: Any) -> None:
    node = _node(ros_context)
    try:
        for s in range(BLOCKS):
            node._on_channels(_channels(s))
        for s in range(BLOCKS):
            node._on_block(_block(s))
        assert node._prog['next'] == BLOCKS and not node._held
        assert not node.drops.counts
        segs = node._runner.segment_data()
        assert [s.note for s in segs] == ['', '']
        np.testing.assert_array_equal(np.concatenate([s.torque_in_nm for s in segs]),
                                      np.repeat(np.arange(BLOCKS, dtype=float), N))
        np.testing.assert_array_equal(segs[0].temp_case_degc[::N],
                                      20.0 + np.arange(40) / 100)
    finally:
        node.destroy_node()


# -- the setpoint route (a ros2_control bench: the adapter's bench/channels) ----------------
W_IN = 1000.0 * 2.0 * math.pi / 60.0    # the step's 1000 rpm [rad/s]


def _driven(ros_context: Any) -> Any:
    """A node with a no-load step of 4 s at 1000 rpm driven through setpoints."""
    from rv_te_bench.acceptance.driver import DriverSettings, ProgramDriver, plan_limits

    node = ts.TestSequencerNode(context=ros_context)
    info = ProgramSimulator(preset='rv-80e-101', te_mode='elastic', sample_rate_hz=1000.0,
                            block_size=N, losses=LossConfig()).info
    plan = parse_plan({'plan': 'p', 'steps': [
        {'kind': 'no_load', 'name': 'nl', 'speeds_rpm': [1000], 'settle_s': 0.0,
         'measure_s': 4.0}]})
    runner = StepRunner(plan.steps[0], info)
    driver = ProgramDriver(runner.program(), limits=plan_limits(plan),
                           settings=DriverSettings(), sample_rate_hz=1000.0)
    driver.start()
    node.busy = {'plan': 'p', 'serial': 'S', 'step': 0, 'steps': 1}
    node._drive = {'runner': runner, 'driver': driver, 'first_seq': -1, 'last_seq': -1,
                   'live': math.nan, 'done': False, 'abort': '', 'last_segment': [-1],
                   'channels': True}
    return node


def _turning(seq: int) -> EncoderBlock:
    m = _block(seq)
    t = (seq * N + np.arange(N)) / 1000.0
    m.header.stamp.sec, m.header.stamp.nanosec = int(t[0]), round((t[0] % 1) * 1e9)
    m.theta_in_rad = (W_IN * t).tolist()
    m.theta_out_rad = (W_IN * t / 101.0).tolist()
    return m


def test_setpoint_route_pairs_blocks_with_their_channels(ros_context: Any) -> None:
    node = _driven(ros_context)
    try:
        for s in range(45):                      # channels first (the adapter's order)
            ch = _channels(s)
            ch.torque_in_nm = (s * N + np.arange(N, dtype=float)).tolist()   # sample index
            node._on_channels(ch)
            node._on_block(_turning(s))
        assert node._drive['done'] and not node.drops.counts
        (seg,) = node._drive['runner'].segment_data()
        assert seg.note == '' and seg.torque_in_nm.size == 4000
        # each sample carries its own sample's input torque: the index its angle says
        np.testing.assert_allclose(seg.torque_in_nm, seg.theta_in_rad / W_IN * 1000.0,
                                   atol=1e-6)
    finally:
        node._drive = None
        node.destroy_node()


def test_setpoint_route_holds_blocks_and_marks_lost_channels(ros_context: Any) -> None:
    node = _driven(ros_context)
    try:
        for s in range(60):                      # every block before its channels
            node._on_block(_turning(s))
        lost = 60 - sp.HOLD_BLOCKS               # the oldest went without
        assert len(node._drive_held) == sp.HOLD_BLOCKS
        assert node.drops.counts.get('channels') == lost
        for s in reversed(range(60)):            # the channels come, last first
            ch = _channels(s)
            ch.torque_in_nm = (s * N + np.arange(N, dtype=float)).tolist()   # sample index
            node._on_channels(ch)
        assert node._drive['done']
        (seg,) = node._drive['runner'].segment_data()
        assert 'never came (bench/channels)' in seg.note    # not analysed, named
        # the held blocks were fed in order, each with its own channels
        assert seg.torque_in_nm[0] == lost * N
        np.testing.assert_array_equal(np.diff(seg.torque_in_nm), 1.0)
    finally:
        node._drive = None
        node.destroy_node()
