"""The node processes' middleware settings (rv_te_bench.nodes.middleware): a reliable sample
sent to a reader in another process is acknowledged within a fraction of a second, so the
nodes' waits for acknowledgement (the sequencer's zero setpoint on stop, a finished bench's
last blocks, the recorder's 'closed' status) end when the reader has the data, not when
their timeout runs out. With Fast DDS's own defaults (a heartbeat every 3 s) the wait below
took 2.7-3.0 s and fails."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from rv_te_bench.nodes.middleware import PROFILE, PROFILE_ENV, use_quick_acknowledgements

_SCRIPT = textwrap.dedent("""
    import sys, time
    import rclpy
    from rclpy.duration import Duration
    from std_msgs.msg import Float64MultiArray
    from rv_te_bench.nodes import qos
    from rv_te_bench.nodes.middleware import use_quick_acknowledgements
    import os
    if sys.argv[1] == 'sub':
        use_quick_acknowledgements(os.environ)
        rclpy.init()
        node = rclpy.create_node('ack_reader')
        node.create_subscription(Float64MultiArray, 'ack_probe/commands',
                                 lambda m: print('got', flush=True), qos.COMMAND_QOS)
        print('ready', flush=True)
        rclpy.spin(node)
    else:
        from rv_te_bench.nodes.common import run_node
        # as a node process: run_node sets the middleware up before rclpy.init
        acked = []

        def factory(ctx):
            node = rclpy.create_node('ack_writer', context=ctx)
            pub = node.create_publisher(Float64MultiArray, 'ack_probe/commands',
                                        qos.COMMAND_QOS)
            end = time.monotonic() + 60.0
            while pub.get_subscription_count() == 0 and time.monotonic() < end:
                time.sleep(0.05)
            pub.publish(Float64MultiArray(data=[0.0]))
            t0 = time.monotonic()
            ok = pub.wait_for_all_acked(Duration(seconds=float(sys.argv[2])))
            print(f'acked {ok} {time.monotonic() - t0:.3f}', flush=True)
            node.finished = True
            return node

        sys.exit(run_node(factory, []))
""")


@pytest.mark.ros
@pytest.mark.timeout(120)
def test_a_sample_is_acknowledged_across_processes_at_once(tmp_path: Path) -> None:
    script = tmp_path / 'ack.py'
    script.write_text(_SCRIPT, encoding='utf-8')
    env = {k: v for k, v in os.environ.items() if k not in PROFILE_ENV}
    env['PYTHONPATH'] = str(Path(__file__).resolve().parents[2])
    reader = subprocess.Popen([sys.executable, str(script), 'sub'], env=env,
                              stdout=subprocess.PIPE, text=True)
    try:
        assert reader.stdout is not None
        assert reader.stdout.readline().strip() == 'ready'
        # 2 s: Fast DDS's 3 s heartbeat never answers in time; 0.1 s ones do, loaded or not
        out = subprocess.run([sys.executable, str(script), 'pub', '2.0'], env=env,
                             capture_output=True, text=True, timeout=90, check=False)
    finally:   # (the reader's own exit is not what is tested: rclpy.spin in it once
        reader.terminate()   # outlived a SIGTERM by 30 s in a full run)
        try:
            reader.wait(timeout=10)
        except subprocess.TimeoutExpired:
            reader.kill()
            reader.wait(timeout=30)
    line = [ln for ln in out.stdout.splitlines() if ln.startswith('acked')]
    assert line and line[0].split()[1] == 'True', (out.stdout, out.stderr)


def test_the_users_profile_and_other_middlewares_are_left_alone() -> None:
    """(QoS from XML: the profile's defaults would replace the nodes' QoS.)"""
    env: dict[str, str] = {}
    assert use_quick_acknowledgements(env) and env == {PROFILE_ENV[0]: str(PROFILE)}
    for mine in ({PROFILE_ENV[0]: '/etc/my.xml'}, {PROFILE_ENV[1]: '/etc/my.xml'},
                 {'RMW_IMPLEMENTATION': 'rmw_cyclonedds_cpp'},
                 {'RMW_FASTRTPS_USE_QOS_FROM_XML': '1'}):
        env = dict(mine)
        assert not use_quick_acknowledgements(env) and env == mine
    env = {'RMW_IMPLEMENTATION': 'rmw_fastrtps_cpp'}
    assert use_quick_acknowledgements(env) and env[PROFILE_ENV[0]] == str(PROFILE)
    assert PROFILE.is_file() and b'<heartbeatPeriod>' in PROFILE.read_bytes()
