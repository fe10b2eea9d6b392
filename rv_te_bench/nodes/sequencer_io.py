"""The test sequencer's side of a ros2_control bench: setpoints out, joint states watched.

Setpoints go to the forward command controllers' ``commands`` topics
(``std_msgs/Float64MultiArray``, one value each, :data:`~rv_te_bench.nodes.qos.COMMAND_QOS`):
the drive joint's velocity, the load joint's effort or position. The last setpoint is sent
again every ``period_s`` (a controller started late, or one that missed a message, gets it)
and the zero setpoint (drive stopped, load effort 0) on every end, abort, cancel and
shutdown. ``joint_states`` is watched raw (no deserialisation: only the arrival matters)
so that a stale stream is noticed on the sequencer's own clock.
"""

from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING, Any

from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from rv_te_bench.acceptance.driver import ZERO, Setpoint
from rv_te_bench.nodes import qos

if TYPE_CHECKING:
    from rclpy.node import Node

__all__ = ['SetpointLink']


class SetpointLink:
    """Publishers of the three setpoint topics and the joint_states watch.

    Args:
        node: The sequencer node.
        drive_topic, effort_topic, position_topic: The controllers' command topics.
        joint_states_topic: The joint state topic.
    """

    def __init__(self, node: Node, *, drive_topic: str, effort_topic: str, position_topic: str,
                 joint_states_topic: str) -> None:
        """Create the publishers and the raw joint_states subscription."""
        self.node = node
        self.pubs = {
            'drive': node.create_publisher(Float64MultiArray, drive_topic, qos.COMMAND_QOS),
            'effort': node.create_publisher(Float64MultiArray, effort_topic, qos.COMMAND_QOS),
            'position': node.create_publisher(Float64MultiArray, position_topic,
                                              qos.COMMAND_QOS)}
        self.last: Setpoint | None = None
        self.last_sent = 0.0
        self.joint_state_at = math.nan     # monotonic time of the last JointState
        self.joint_states = 0
        node.create_subscription(JointState, joint_states_topic, self._on_joint_state,
                                 qos.JOINT_STATE_QOS, raw=True)

    def _on_joint_state(self, _raw: Any) -> None:
        self.joint_state_at = time.monotonic()
        self.joint_states += 1

    def missing(self, load_modes: set[str]) -> list[str]:
        """The command topics nobody subscribes to (no controller there)."""
        want = {'drive', *load_modes}
        return [self.pubs[k].topic_name for k in sorted(want)
                if self.pubs[k].get_subscription_count() == 0]

    def stale_s(self) -> float:
        """Seconds since the last JointState (inf before the first)."""
        return math.inf if math.isnan(self.joint_state_at) else \
            time.monotonic() - self.joint_state_at

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
