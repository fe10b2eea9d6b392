"""The queue depths of nodes/qos.py are what the middleware really holds.

Fast DDS caps a history at its default resource limits (``max_samples`` 5000) whatever the
KEEP_LAST depth. A depth above the cap made a long backlog lose its *newest* messages, with
no stamp jump to show it (the joint_state_adapter test lost the last 2,101 of 7,400
JointStates so, with 0 gaps reported, on a busy machine). At the cap, KEEP_LAST replaces the
*oldest*, which the adapter reports as a gap. Here: a burst published with nothing taken,
then read.
"""

from __future__ import annotations

import time

import pytest

pytestmark = pytest.mark.ros

rclpy = pytest.importorskip('rclpy')

from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402

from rv_te_bench.nodes import qos  # noqa: E402


def burst(ctx, profile: QoSProfile, n: int) -> list[int]:
    """Publish ``n`` JointStates (seq in the stamp) before the subscriber takes any; the seqs
    it then receives, in order."""
    pub_node = rclpy.create_node('burst_pub', context=ctx)
    sub_node = rclpy.create_node('burst_sub', context=ctx)
    ex = SingleThreadedExecutor(context=ctx)
    ex.add_node(sub_node)
    got: list[int] = []
    try:
        sub_node.create_subscription(JointState, 'burst', lambda m: got.append(
            m.header.stamp.nanosec), profile)
        pub = pub_node.create_publisher(JointState, 'burst', profile)
        end = time.monotonic() + 10.0
        while pub.get_subscription_count() < 1 and time.monotonic() < end:
            ex.spin_once(timeout_sec=0.05)
        assert pub.get_subscription_count() == 1
        for i in range(n):
            m = JointState()
            m.header.stamp.nanosec = i
            m.name = ['a']
            m.position = [float(i)]
            pub.publish(m)
        # take until nothing more comes for 1 s (the last one, or a lost end, 20 s at most)
        end, quiet_since, seen = time.monotonic() + 20.0, time.monotonic(), 0
        while time.monotonic() < end and time.monotonic() - quiet_since < 1.0:
            ex.spin_once(timeout_sec=0.05)
            if len(got) != seen:
                seen, quiet_since = len(got), time.monotonic()
    finally:
        ex.shutdown()
        sub_node.destroy_node()
        pub_node.destroy_node()
    return got


@pytest.mark.timeout(120)
def test_joint_state_queue_holds_its_depth_and_drops_the_oldest(ros_context) -> None:
    depth = qos.JOINT_STATE_QUEUE_DEPTH
    assert qos.JOINT_STATE_QOS.depth == depth == 5000
    assert burst(ros_context, qos.JOINT_STATE_QOS, depth) == list(range(depth))
    over = depth + 1500
    # the newest `depth` arrive: the loss is at the start of the backlog, where the adapter
    # sees the stamp jump (before the fix: the first 5000, and the end lost unseen)
    assert burst(ros_context, qos.JOINT_STATE_QOS, over) == list(range(over - depth, over))


@pytest.mark.timeout(120)
def test_a_depth_above_the_middleware_cap_loses_the_newest(ros_context) -> None:
    """Why the depth is 5000: asking for 10000 keeps the first 5000 of 6500."""
    deep = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10_000,
                      reliability=ReliabilityPolicy.RELIABLE)
    assert burst(ros_context, deep, 6500) == list(range(5000))
