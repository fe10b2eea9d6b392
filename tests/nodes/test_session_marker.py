"""Issue #16 item 3: a bench must wait for the nodes of its own session only. Old node
names (a stale te_node of an earlier session) satisfied a new bench's wait, so the new bag
missed its first blocks. Launched nodes now mark themselves with their session's token (a
publisher on a hidden topic); the bench of a launched session counts only its own
session's nodes and nodes of no session (test probes, tools)."""

from __future__ import annotations

import os
import time

import pytest

pytestmark = pytest.mark.ros

rclpy = pytest.importorskip('rclpy')

from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rv_te_msgs.msg import EncoderBlock  # noqa: E402
from std_msgs.msg import Empty  # noqa: E402

from rv_te_bench.nodes import qos  # noqa: E402
from rv_te_bench.nodes.bench_node import BenchNode  # noqa: E402
from tests.nodes.rosutil import spin_until  # noqa: E402

# the launcher's protocol, written out (rv_te_bench.nodes.common: SESSION_ENV, the prefix)
SESSION_ENV = 'RV_TE_SESSION'
SESSION_TOPIC_PREFIX = '/_rv_te_session/'


def _te_node(ctx: object, ns: str, token: str | None) -> object:
    """A node named te_node subscribing to the bench, marked with ``token`` (None: none)."""
    node = rclpy.create_node('te_node', namespace=ns, context=ctx)
    node.create_subscription(EncoderBlock, 'bench/encoders', lambda _m: None, qos.ENCODER_QOS)
    if token is not None:
        node.create_publisher(Empty, SESSION_TOPIC_PREFIX + token, 1)
    return node


@pytest.mark.timeout(60)
def test_bench_waits_for_its_own_sessions_te_node(ros_context: object,
                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    ns = f'/marker_{os.getpid()}_{time.monotonic_ns() % 10**6}'
    monkeypatch.setenv(SESSION_ENV, 'snew')
    ex = SingleThreadedExecutor(context=ros_context)
    stale = _te_node(ros_context, ns, 'sold')        # left over from an earlier session
    bench = BenchNode(context=ros_context, namespace=ns, parameter_overrides=[
        Parameter('preset', value='wang2020-2kv'), Parameter('te_mode', value='nlte'),
        Parameter('sample_rate_hz', value=1000.0), Parameter('duration_s', value=0.5),
        Parameter('wait_for_nodes', value=['te_node']), Parameter('wait_timeout_s', value=60.0)])
    nodes = [stale, bench]
    for n in nodes:
        ex.add_node(n)
    try:
        spin_until(ex, lambda: bench.started, 3.0)
        assert not bench.started, 'the stale te_node of another session satisfied the wait'
        ours = _te_node(ros_context, ns, 'snew')
        nodes.append(ours)
        ex.add_node(ours)
        assert spin_until(ex, lambda: bench.started, 20.0)
    finally:
        ex.shutdown()
        for n in nodes:
            n.destroy_node()


@pytest.mark.timeout(60)
def test_a_node_of_no_session_still_counts(ros_context: object,
                                           monkeypatch: pytest.MonkeyPatch) -> None:
    ns = f'/nomarker_{os.getpid()}_{time.monotonic_ns() % 10**6}'
    monkeypatch.setenv(SESSION_ENV, 'snew')
    ex = SingleThreadedExecutor(context=ros_context)
    probe = _te_node(ros_context, ns, None)
    bench = BenchNode(context=ros_context, namespace=ns, parameter_overrides=[
        Parameter('preset', value='wang2020-2kv'), Parameter('te_mode', value='nlte'),
        Parameter('sample_rate_hz', value=1000.0), Parameter('duration_s', value=0.5),
        Parameter('wait_for_nodes', value=['te_node']), Parameter('wait_timeout_s', value=60.0)])
    for n in (probe, bench):
        ex.add_node(n)
    try:
        assert spin_until(ex, lambda: bench.started, 20.0)
    finally:
        ex.shutdown()
        probe.destroy_node()
        bench.destroy_node()


def test_the_protocol_written_out_is_the_code_s() -> None:
    from rv_te_bench.nodes import common

    assert (common.SESSION_ENV, common.SESSION_TOPIC_PREFIX) == (SESSION_ENV,
                                                                 SESSION_TOPIC_PREFIX)
