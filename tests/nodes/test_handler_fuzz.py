"""Fuzz the node message handlers: any EncoderBlock content is handled, never fatal."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

pytestmark = pytest.mark.ros

rclpy = pytest.importorskip('rclpy')

from rclpy.parameter import Parameter  # noqa: E402
from rclpy.serialization import serialize_message  # noqa: E402
from rv_te_msgs.msg import EncoderBlock, TransmissionError  # noqa: E402

from rv_te_bench.nodes.compensation_node import CompensationNode  # noqa: E402
from rv_te_bench.nodes.te_node import TeNode  # noqa: E402

floats = st.floats(allow_nan=True, allow_infinity=True, width=64)
arrays = hnp.arrays(np.float64, st.integers(0, 40), elements=floats)


@pytest.fixture(scope='module')
def nodes():
    ctx = rclpy.context.Context()
    rclpy.init(context=ctx)
    te = TeNode(context=ctx, parameter_overrides=[
        Parameter('gear_ratio', value=79.0), Parameter('crank_per_output', value=25.0)])
    # an RV preset: complete windows go to the (fast) tooth-profile compensation
    comp = CompensationNode(context=ctx, parameter_overrides=[
        Parameter('preset', value='hu2020-rv'), Parameter('optimize_phases', value=False)])
    yield te, comp
    te.destroy_node()
    comp.destroy_node()
    rclpy.try_shutdown(context=ctx)


@settings(max_examples=150, deadline=None)
@given(seq=st.integers(0, 2**64 - 1), sec=st.integers(0, 2**31 - 1),
       nsec=st.integers(0, 999_999_999), rate=floats, t=arrays, a=arrays, b=arrays,
       torque=arrays)
def test_te_node_handles_any_encoder_block(nodes, seq: int, sec: int, nsec: int, rate: float,
                                           t: np.ndarray, a: np.ndarray, b: np.ndarray,
                                           torque: np.ndarray) -> None:
    te, _ = nodes
    msg = EncoderBlock()
    msg.seq = seq
    msg.header.stamp.sec = sec
    msg.header.stamp.nanosec = nsec
    msg.sample_rate_hz = rate
    msg.time_offset_s = t
    msg.theta_in_rad = a
    msg.theta_out_rad = b
    msg.torque_out_nm = torque
    assert te.analyzer is not None   # configured by its parameters: no block waits
    blocks, drops = te._blocks, te.drops.total
    te._on_block(msg)  # must not raise
    pushed, dropped = te._blocks - blocks, te.drops.total - drops
    # every block is accounted for: handed to the core (a malformed one also counted as a
    # drop) or refused at conversion and counted as a drop; none vanishes silently
    assert (pushed, dropped) in {(1, 0), (1, 1), (0, 1)}
    # the same block as the subscription hands it over (raw CDR bytes): the same outcome
    blocks, drops = te._blocks, te.drops.total
    te._on_block(serialize_message(msg))
    assert (te._blocks - blocks, te.drops.total - drops) == (pushed, dropped)
    # and bytes cut short anywhere: counted, never fatal
    data = serialize_message(msg)
    blocks, drops = te._blocks, te.drops.total
    te._on_block(data[:len(data) // 2])
    assert te._blocks - blocks + te.drops.total - drops >= 1


@settings(max_examples=60, deadline=None)
@given(te_rad=arrays, th=arrays, complete=st.booleans(), pp=floats)
def test_compensation_node_handles_any_te_message(nodes, te_rad: np.ndarray, th: np.ndarray,
                                                  complete: bool, pp: float) -> None:
    _, comp = nodes
    msg = TransmissionError()
    msg.te_rad = te_rad
    msg.theta_out_rad = th
    msg.window_complete = complete
    msg.window.pp_rad = pp
    comp._on_samples(msg)
    comp._on_samples(serialize_message(msg))      # raw, as the subscription hands it over
    data = serialize_message(msg)
    comp._on_samples(data[:len(data) // 2])       # cut short: counted, never fatal
    comp._on_window(msg)
    for _, fut in comp.jobs:
        exc = fut.exception(timeout=30)
        # a bad TE value is a clear CompensationError (a ValueError), nothing else
        assert exc is None or isinstance(exc, ValueError), repr(exc)
    comp._collect()
