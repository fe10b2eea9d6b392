"""The page's recorder panel follows the real recorder (``rv-te record`` in a child process)
to its end: 'closed' once the bag is closed, and never 'recording' after a recorder that was
killed (the bridge node runs in this process, its model read directly)."""

from __future__ import annotations

import os
import signal
from typing import Any

import pytest

pytestmark = [pytest.mark.ros, pytest.mark.timeout(180)]

rclpy = pytest.importorskip('rclpy')

from rclpy.experimental import EventsExecutor  # noqa: E402
from rv_te_msgs.msg import EncoderBlock  # noqa: E402

from rv_te_bench.dashboard.bridge import DashboardBridge  # noqa: E402
from rv_te_bench.dashboard.model import DashboardModel  # noqa: E402
from rv_te_bench.nodes import qos  # noqa: E402
from tests.nodes.conftest import cli_process, make_block  # noqa: E402
from tests.nodes.rosutil import spin_until  # noqa: E402


def _session(ros_context: Any, ros_domain_id: int, tmp_path: Any, tag: str, duration: str):
    ns = f'/rec{tag}{os.getpid() % 10000}'
    model = DashboardModel(namespace=ns)
    bridge = DashboardBridge(model, context=ros_context, namespace=ns)
    pub_node = rclpy.create_node('rec_pub', namespace=ns, context=ros_context)
    pub = pub_node.create_publisher(EncoderBlock, 'bench/encoders', qos.ENCODER_QOS)
    ex = EventsExecutor(context=ros_context)
    ex.add_node(bridge)
    ex.add_node(pub_node)
    proc = cli_process(['record', '--out', str(tmp_path), '--name', f'bag{tag}', '--namespace',
                        ns, '--topics', 'bench/encoders', '--duration', duration],
                       ros_domain_id)
    return model, bridge, pub_node, pub, ex, proc


def test_the_recorder_panel_says_closed_when_the_bag_is_closed(ros_context, ros_domain_id,
                                                                tmp_path):
    model, bridge, pub_node, pub, ex, proc = _session(ros_context, ros_domain_id, tmp_path,
                                                      'c', '6')
    try:
        assert spin_until(ex, lambda: pub.get_subscription_count() >= 2
                          or proc.poll() is not None, 60), proc.communicate(timeout=10)
        for seq in range(20):
            pub.publish(make_block(seq))
            ex.spin_once(timeout_sec=0.02)
        assert spin_until(ex, lambda: str(model.recorder.get('message', '')).startswith(
            'recording'), 20), model.recorder
        assert spin_until(ex, lambda: proc.poll() is not None, 60)
        assert proc.returncode == 0, proc.communicate(timeout=10)
        # the recorder's own final status (it waited for the acknowledgement before it went)
        assert spin_until(ex, lambda: model.recorder.get('message') == 'closed', 5), \
            model.recorder
        assert model.recorder['counts'] == {f'{bridge.get_namespace()}/bench/encoders': 20}
        assert not [e for e in model.events if e['kind'] == 'recorder gone']
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.communicate(timeout=10)
        ex.shutdown()
        bridge.destroy_node()
        pub_node.destroy_node()


def test_a_killed_recorder_is_not_shown_recording(ros_context, ros_domain_id, tmp_path):
    model, _, pub_node, pub, ex, proc = _session(ros_context, ros_domain_id, tmp_path, 'k',
                                                 '60')
    bridge = next(n for n in ex.get_nodes() if n is not pub_node)
    try:
        assert spin_until(ex, lambda: pub.get_subscription_count() >= 2
                          or proc.poll() is not None, 60)
        pub.publish(make_block(0))
        assert spin_until(ex, lambda: str(model.recorder.get('message', '')).startswith(
            'recording') and 'recorder' in model.nodes, 20), (model.recorder, model.nodes)
        proc.send_signal(signal.SIGKILL)
        proc.communicate(timeout=10)
        assert spin_until(ex, lambda: 'gone' in str(model.recorder.get('message')), 30), \
            model.recorder
        assert model.recorder['level'] == 2
        assert 'recording' in model.recorder['message']     # what it said last, named
        assert [e for e in model.events if e['kind'] == 'recorder gone']
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate(timeout=10)
        ex.shutdown()
        bridge.destroy_node()
        pub_node.destroy_node()
