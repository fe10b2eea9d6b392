"""Publisher process for the cross-process transport test: deterministic EncoderBlocks.

Usage: python block_publisher.py TOPIC N_MESSAGES RATE_HZ BLOCK_SIZE
Waits for one subscriber, publishes, waits until the subscriber has had time to drain.
"""

from __future__ import annotations

import sys
import time

import numpy as np
import rclpy
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from rv_te_msgs.msg import EncoderBlock


def block_arrays(seq: int, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Deterministic content of block ``seq`` (the subscriber regenerates it to compare)."""
    rng = np.random.default_rng(seq)
    t = np.arange(n) / 10_000.0
    theta_in = seq * 100.0 + np.cumsum(rng.random(n))
    theta_out = theta_in / 79.0 + 1e-6 * rng.standard_normal(n)
    return t, theta_in, theta_out


def main() -> int:
    topic, n_msgs, rate_hz, n = sys.argv[1], int(sys.argv[2]), float(sys.argv[3]), int(sys.argv[4])
    rclpy.init()
    node = rclpy.create_node('block_publisher')
    qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE,
                     history=HistoryPolicy.KEEP_LAST)
    pub = node.create_publisher(EncoderBlock, topic, qos)
    try:
        deadline = time.monotonic() + 20.0
        while pub.get_subscription_count() < 1 and time.monotonic() < deadline:
            time.sleep(0.05)
        time.sleep(0.5)  # let reliable matching settle
        t0 = time.monotonic()
        for seq in range(n_msgs):
            t, th_in, th_out = block_arrays(seq, n)
            msg = EncoderBlock()
            msg.header.frame_id = 'bench0'
            msg.seq = seq
            msg.sample_rate_hz = 10_000.0
            msg.time_offset_s = t
            msg.theta_in_rad = th_in
            msg.theta_out_rad = th_out
            pub.publish(msg)
            delay = t0 + (seq + 1) / rate_hz - time.monotonic()
            if delay > 0:
                time.sleep(delay)
        time.sleep(2.0)
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
