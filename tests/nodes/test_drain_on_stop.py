"""A stopping node takes what is queued for it, however long that takes (up to its
``drain_max_s``), and not a fixed 0.5 s: issue 39 item 4 replaced the fixed waits of a
session stop (0.5 s per node, 2 s after the bench, 1 s before the recorder) by waiting for
the condition. A reader that must not lose (the TE node, the recorder) with more than 0.5 s
of work queued when its stop is requested takes all of it: on the single-threaded executor
(one message per pass) the fixed drain cut it off (fails with ``drain_max_s = 0.5``, the old
fixed drain: 20-odd of 40 taken).
"""

from __future__ import annotations

import os
import signal
import threading
import time
from typing import Any

import pytest

pytestmark = pytest.mark.ros

pytest.importorskip('rclpy')

#: Messages queued for the slow reader when it is told to stop, and the time it takes per
#: message: ~1 s of work, twice the old fixed drain, a third of DRAIN_MAX_S.
N_MESSAGES = 40
TAKE_S = 0.025


@pytest.mark.timeout(60)
def test_a_stopping_reader_takes_every_message_queued_for_it(ros_domain_id: int) -> None:
    import rclpy
    from rclpy.duration import Duration
    from rclpy.node import Node
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
    from std_msgs.msg import UInt64

    from rv_te_bench.nodes.common import DRAIN_MAX_S, run_node

    qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=N_MESSAGES,
                     reliability=ReliabilityPolicy.RELIABLE)
    taken: list[int] = []
    sender: dict[str, Any] = {}

    class SlowReader(Node):
        drain_max_s = DRAIN_MAX_S

        def __init__(self, ctx: object) -> None:
            super().__init__('slow_reader', context=ctx)
            self.create_subscription(UInt64, 'drain_probe', self._on_msg, qos)

        def _on_msg(self, msg: UInt64) -> None:
            time.sleep(TAKE_S)
            taken.append(int(msg.data))

    def send() -> None:
        """Publish every message once the reader matched, wait until its middleware has
        them all (acknowledged), then request the stop (SIGTERM, as the launcher does)."""
        ctx = rclpy.context.Context()
        rclpy.init(context=ctx, domain_id=ros_domain_id)
        try:
            node = rclpy.create_node('drain_sender', context=ctx)
            pub = node.create_publisher(UInt64, 'drain_probe', qos)
            end = time.monotonic() + 30.0
            while pub.get_subscription_count() < 1 and time.monotonic() < end:
                time.sleep(0.02)
            for k in range(N_MESSAGES):
                pub.publish(UInt64(data=k))
            sender['acked'] = pub.wait_for_all_acked(Duration(seconds=20.0))
            sender['taken_at_stop'] = len(taken)
        finally:
            os.kill(os.getpid(), signal.SIGTERM)
            sender['done'] = True
            ctx.try_shutdown()

    thread = threading.Thread(target=send, daemon=True)
    thread.start()
    # (the single-threaded executor takes one message per pass; the EventsExecutor takes a
    # subscription's whole queue in one pass, which no drain cuts short)
    code = run_node(SlowReader, ['drain_test'], executor_kind='single')
    thread.join(timeout=10.0)
    assert code == 0
    assert sender.get('acked'), sender
    # (sender['taken_at_stop']: how many were taken before the stop, a few when quiet)
    assert taken == list(range(N_MESSAGES)), (len(taken), sender)
