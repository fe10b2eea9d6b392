"""Shared test set-up: hypothesis profiles, ROS isolation (own domain id, localhost only)."""

from __future__ import annotations

import os

import pytest
from hypothesis import HealthCheck, settings

settings.register_profile('dev', deadline=None, max_examples=60)
settings.register_profile('ci', deadline=None, max_examples=100,
                          suppress_health_check=[HealthCheck.too_slow])
settings.load_profile('ci' if os.environ.get('CI') else 'dev')

# Every test run gets its own DDS domain derived from the process id, so that two runs on one
# machine (or a run beside the demo) never see each other's messages; discovery stays on
# this host. Set before any test imports rclpy.
os.environ.setdefault('ROS_DOMAIN_ID', str(100 + os.getpid() % 100))
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.pop('ROS_LOCALHOST_ONLY', None)


@pytest.fixture
def ros_domain_id() -> int:
    """The DDS domain id of this test run."""
    return int(os.environ['ROS_DOMAIN_ID'])


@pytest.fixture
def ros_context(ros_domain_id: int):  # noqa: ANN201
    """An initialised rclpy Context of its own, shut down after the test."""
    rclpy = pytest.importorskip('rclpy')
    ctx = rclpy.context.Context()
    rclpy.init(context=ctx, domain_id=ros_domain_id)
    try:
        yield ctx
    finally:
        rclpy.try_shutdown(context=ctx)
