"""Foundation acceptance: the generated rv_te_msgs types cross processes over the middleware."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.ros

rclpy = pytest.importorskip('rclpy')

from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy  # noqa: E402
from rv_te_msgs.msg import EncoderBlock  # noqa: E402

from tests.msgs.block_publisher import block_arrays  # noqa: E402

N_MSGS = 500          # 100 messages/s for 5 s
RATE_HZ = 100.0
BLOCK = 1000


def child_env() -> dict[str, str]:
    """Environment for a child venv Python: the bootstrap marker must not be inherited."""
    env = dict(os.environ)
    env.pop('_ROS_WHEELS_BOOTSTRAP_COMPLETE', None)
    return env


def test_generated_types_import() -> None:
    from rclpy.serialization import deserialize_message, serialize_message
    from rv_te_msgs.msg import (
        BenchInfo,
        CompensationAdvice,
        Modification,
        SpectrumLine,
        TeSpectrum,
        TeStatistics,
        TransmissionError,
    )

    msg = EncoderBlock()
    msg.theta_in_rad = np.array([1.0, 2.0])
    assert msg.theta_in_rad.typecode == 'd'  # float64 keeps arcseconds after many turns
    # every generated type goes through CDR and back unchanged (the typesupport works)
    info = BenchInfo()
    info.bench_id, info.gear_ratio, info.mesh_labels = 'b1', 79.0, ['z_g', 'z_p']
    msg.seq = 2**40 + 3
    msg.theta_out_rad = np.array([np.pi, -0.5])
    line = SpectrumLine()
    line.label, line.amplitude_rad = '1 f_w', 1.5e-4
    for sample in (msg, info, line, CompensationAdvice(), Modification(), TeSpectrum(),
                   TeStatistics(), TransmissionError()):
        back = deserialize_message(serialize_message(sample), type(sample))
        assert type(back) is type(sample)
        assert back == sample
    back = deserialize_message(serialize_message(msg), EncoderBlock)
    assert back.seq == 2**40 + 3
    assert back.theta_out_rad.tolist() == [np.pi, -0.5]


def test_blocks_cross_processes_without_loss(ros_context, ros_domain_id: int) -> None:
    topic = f'/transport_test_{os.getpid()}'
    node = rclpy.create_node('transport_sub', context=ros_context)
    received: list[EncoderBlock] = []
    qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE,
                     history=HistoryPolicy.KEEP_LAST)
    node.create_subscription(EncoderBlock, topic, received.append, qos)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    script = Path(__file__).with_name('block_publisher.py')
    env = child_env()
    env['ROS_DOMAIN_ID'] = str(ros_domain_id)
    env['PYTHONPATH'] = str(Path(__file__).resolve().parents[2])
    proc = subprocess.Popen(
        [sys.executable, str(script), topic, str(N_MSGS), str(RATE_HZ), str(BLOCK)], env=env)
    try:
        deadline = time.monotonic() + 60.0
        while len(received) < N_MSGS and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.1)
            if proc.poll() is not None and len(received) < N_MSGS:
                # drain what is still queued, then stop
                for _ in range(50):
                    executor.spin_once(timeout_sec=0.05)
                break
        assert proc.wait(timeout=30) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
        executor.shutdown()
        node.destroy_node()
    assert len(received) == N_MSGS, f'lost {N_MSGS - len(received)} of {N_MSGS} blocks'
    assert [m.seq for m in received] == list(range(N_MSGS))
    for m in [*received[:: max(1, N_MSGS // 50)], received[-1]]:
        t, th_in, th_out = block_arrays(m.seq, BLOCK)
        np.testing.assert_array_equal(m.time_offset_s, t)
        np.testing.assert_array_equal(m.theta_in_rad, th_in)
        np.testing.assert_array_equal(m.theta_out_rad, th_out)
        assert m.header.frame_id == 'bench0'
