"""The test sequencer's side of a ros2_control bench: the setpoints.

Setpoints go to the forward command controllers' ``commands`` topics
(``std_msgs/Float64MultiArray``, one value each, :data:`~rv_te_bench.nodes.qos.COMMAND_QOS`):
the drive joint's velocity, the load joint's effort or position. The last setpoint is sent
again every ``period_s`` (a controller started late, or one that missed a message, gets it)
and the zero setpoint (drive stopped, load effort 0) on every end, abort, cancel and
shutdown.

The joint states come back through the JointState adapter (``bench/encoders``): the
sequencer does not subscribe to ``joint_states`` itself. One message per sample costs a
Python node ~0.3-0.5 ms in a single-threaded executor; at 2000 samples/s that alone kept the
sequencer seconds behind its data on a loaded 2-core machine, so that setpoints reached the
bench late and looked "not reached". A stale joint_states stream stops the adapter's blocks:
the sequencer times those.
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING

from std_msgs.msg import Float64MultiArray

from rv_te_bench.acceptance.driver import ZERO, Setpoint
from rv_te_bench.nodes import qos

if TYPE_CHECKING:
    from rclpy.node import Node

__all__ = ['SetpointLink']


class SetpointLink:
    """Publishers of the three setpoint topics.

    Args:
        node: The sequencer node.
        drive_topic, effort_topic, position_topic: The controllers' command topics.
    """

    def __init__(self, node: Node, *, drive_topic: str, effort_topic: str,
                 position_topic: str) -> None:
        """Create the publishers."""
        self.node = node
        self.pubs = {
            'drive': node.create_publisher(Float64MultiArray, drive_topic, qos.COMMAND_QOS),
            'effort': node.create_publisher(Float64MultiArray, effort_topic, qos.COMMAND_QOS),
            'position': node.create_publisher(Float64MultiArray, position_topic,
                                              qos.COMMAND_QOS)}
        self.last: Setpoint | None = None
        self.last_sent = 0.0

    def missing(self, load_modes: set[str]) -> list[str]:
        """The command topics nobody subscribes to (no controller there)."""
        want = {'drive', *load_modes}
        return [self.pubs[k].topic_name for k in sorted(want)
                if self.pubs[k].get_subscription_count() == 0]

    def send(self, sp: Setpoint) -> None:
        """Publish a setpoint (the drive's and the load interface's)."""
        self.pubs['drive'].publish(Float64MultiArray(data=[float(sp.drive_velocity_rad_s)]))
        self.pubs[sp.load_mode].publish(Float64MultiArray(data=[float(sp.load_value)]))
        self.last = sp
        self.last_sent = time.monotonic()

    def refresh(self, period_s: float) -> None:
        """Send the last setpoint again when ``period_s`` has passed."""
        if self.last is not None and time.monotonic() - self.last_sent >= period_s:
            self.send(self.last)

    def zero(self, *, wait_s: float = 0.0) -> None:
        """The zero setpoint; with ``wait_s`` wait until the controllers acknowledged it."""
        self.send(ZERO)
        if wait_s > 0:
            from rclpy.duration import Duration

            for pub in (self.pubs['drive'], self.pubs['effort']):
                pub.wait_for_all_acked(Duration(seconds=wait_s))
