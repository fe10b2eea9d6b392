"""Issue #15 item 4: a session stopped while the compensation node still searched ended
without the advice. A stopping node with work under way (``busy``) finishes it and
publishes within FINISH_MAX_S before it is destroyed; a search cut off is said."""

from __future__ import annotations

import os
import signal
import threading
import time

import pytest

pytestmark = pytest.mark.ros

pytest.importorskip('rclpy')


@pytest.mark.timeout(60)
def test_a_busy_node_finishes_before_it_is_destroyed() -> None:
    from rclpy.node import Node  # noqa: PLC0415

    from rv_te_bench.nodes.common import run_node  # noqa: PLC0415

    events: dict[str, float] = {}

    class Busy(Node):
        """Busy (a search running) until 2 s after it was built."""

        def __init__(self, ctx: object) -> None:
            super().__init__('busy_probe', context=ctx)
            self.until = time.monotonic() + 2.0

        @property
        def busy(self) -> bool:
            return time.monotonic() < self.until

        def destroy_node(self) -> None:
            events['destroyed'] = time.monotonic()
            super().destroy_node()

    timer = threading.Timer(0.3, os.kill, (os.getpid(), signal.SIGTERM))   # stop at once
    timer.start()
    try:
        t0 = time.monotonic()
        holder: list[Busy] = []
        code = run_node(lambda ctx: holder.append(Busy(ctx)) or holder[0], ['finish_test'])
    finally:
        timer.cancel()
    assert code == 0
    assert events['destroyed'] >= holder[0].until   # not destroyed while busy
    assert events['destroyed'] - t0 < 6.0


def test_compensation_node_is_busy_while_a_job_is_unpublished() -> None:
    from concurrent.futures import Future  # noqa: PLC0415

    from rv_te_bench.nodes.compensation_node import CompensationNode  # noqa: PLC0415

    node = object.__new__(CompensationNode)   # the property alone, no ROS node needed
    node.jobs = []
    assert node.busy is False
    node.jobs = [('assembly-phases', Future())]
    assert node.busy is True
