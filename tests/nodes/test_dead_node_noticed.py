"""A node process that dies without a word (SIGKILL, a crash) leaves the ROS graph within
seconds, not after Fast DDS's default 20 s participant lease: the node processes'
middleware profile (rv_te_bench/nodes/fastdds_profile.xml) declares a 6 s lease renewed
every second. What watches the graph notices sooner: the live page says "recorder gone",
``rv-te test`` says the test_sequencer went away (it waits --wait-s more on top).

Real processes: a node started as the launcher starts one (run_node), SIGKILLed; a node in
this process (the profile applied as in every test process) watches the graph.
"""

from __future__ import annotations

import signal
import subprocess
import sys
import textwrap
import time

import pytest

pytestmark = pytest.mark.ros

pytest.importorskip('rclpy')

#: Longest the dead node may stay in the graph: the 6 s lease, the 1 s between
#: announcements, the receiver's check; the middleware's default lease alone is 20 s.
GONE_WITHIN_S = 12.0

_NODE = textwrap.dedent("""
    import sys, rclpy
    from rv_te_bench.nodes.common import run_node

    def factory(ctx):
        node = rclpy.create_node(sys.argv[1], context=ctx)
        print('ready', flush=True)
        return node

    sys.exit(run_node(factory, []))
""")


@pytest.mark.timeout(120)
def test_a_killed_node_process_leaves_the_graph_within_seconds(ros_context, ros_domain_id,
                                                                 tmp_path) -> None:
    import os

    import rclpy

    from rv_te_bench.launch.session import child_env

    name = f'doomed_{os.getpid()}'
    env = {**child_env(), 'ROS_DOMAIN_ID': str(ros_domain_id)}
    watcher = rclpy.create_node('graph_watcher', context=ros_context)
    proc = subprocess.Popen([sys.executable, '-c', _NODE, name], env=env, text=True,
                            stdout=subprocess.PIPE)

    def present() -> bool:
        return any(n == name for n, _ in watcher.get_node_names_and_namespaces())

    try:
        assert proc.stdout is not None and proc.stdout.readline().strip() == 'ready'
        end = time.monotonic() + 60.0
        while not present():
            assert time.monotonic() < end, 'the node never appeared in the graph'
            time.sleep(0.05)
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=10)
        t0 = time.monotonic()
        while present() and time.monotonic() - t0 < 40.0:
            time.sleep(0.05)
        gone_after_s = time.monotonic() - t0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        watcher.destroy_node()
    assert gone_after_s < GONE_WITHIN_S, f'still in the graph {gone_after_s:.1f} s after SIGKILL'
