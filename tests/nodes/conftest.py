"""Fixtures of the node tests."""

from __future__ import annotations

import pytest


@pytest.fixture
def graph(ros_context):  # noqa: ANN001, ANN201
    """(context, single-threaded executor, add): nodes given to ``add`` spin on the executor
    and are destroyed at the end, the last added first."""
    from rclpy.executors import SingleThreadedExecutor  # noqa: PLC0415

    nodes = []
    ex = SingleThreadedExecutor(context=ros_context)

    def add(node):  # noqa: ANN001, ANN202
        nodes.append(node)
        ex.add_node(node)
        return node

    yield ros_context, ex, add
    ex.shutdown()
    for n in reversed(nodes):
        n.destroy_node()
