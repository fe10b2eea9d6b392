"""Send an action goal and get its result when the middleware drops a service response.

Under load, Fast DDS (rmw_fastrtps, Jazzy) can drop an action server's reply to a goal
request: the server logs ``failed to send response (timeout): client will not receive
response`` (its writer had not matched the client's reply reader yet), accepts and runs the
goal, and the client's ``send_goal_async`` future never completes - ``rv-te test`` waited
for it forever while the bench ran the test. The same can happen to the reply to a result
request. The goal's fate is also published on the action's status topic (transient local),
so :class:`TrackedGoal` follows that topic for its own goal id: a goal seen there as
accepted whose reply has not come :data:`REPLY_GRACE_S` later gets its handle without the
lost reply, and a goal seen finished whose result reply does not come is asked for its
result again (the server keeps results for minutes). The grace matters: the status message
and the reply travel on different topics, and the status often arrives first (CI saw it:
a reply taken for lost 0 s after the status, while it was on its way).
"""

from __future__ import annotations

import time
import uuid
from typing import Any

from action_msgs.msg import GoalStatus, GoalStatusArray
from rclpy.action.client import ActionClient, ClientGoalHandle
from rclpy.qos import qos_profile_action_status_default
from unique_identifier_msgs.msg import UUID

#: Ask again for the result of a goal the status topic shows finished this long ago [s].
RESULT_AGAIN_S = 3.0
#: Take the goal reply for lost when the status topic has shown the goal this long [s].
REPLY_GRACE_S = 3.0

_TERMINAL = {GoalStatus.STATUS_SUCCEEDED, GoalStatus.STATUS_CANCELED, GoalStatus.STATUS_ABORTED}


class TrackedGoal:
    """One goal sent on ``client``; poll :meth:`answered`, then :meth:`result_done` while
    spinning the executor of ``node``."""

    def __init__(self, node: Any, client: ActionClient, action_type: Any, action_name: str,
                 goal: Any, *, feedback_callback: Any = None) -> None:
        self._node = node
        self._client = client
        self._action_type = action_type
        self._uuid = UUID(uuid=list(uuid.uuid4().bytes))
        self._key = bytes(self._uuid.uuid)
        #: Our goal's last status on the status topic (None: not seen there).
        self.status: int | None = None
        #: What was recovered from the status topic: 'goal response', 'result'.
        self.recovered: list[str] = []
        self._sub = node.create_subscription(GoalStatusArray,
                                             f'{action_name}/_action/status', self._on_status,
                                             qos_profile_action_status_default)
        self._send = client.send_goal_async(goal, feedback_callback=feedback_callback,
                                            goal_uuid=self._uuid)
        self.handle: ClientGoalHandle | None = None
        self._result: Any = None
        self._terminal_at: float | None = None
        self._status_seen_at: float | None = None

    def _on_status(self, msg: GoalStatusArray) -> None:
        for s in msg.status_list:
            if bytes(s.goal_info.goal_id.uuid) == self._key:
                self.status = int(s.status)

    def answered(self) -> bool:
        """True once the goal is known accepted or rejected (``handle`` set)."""
        if self.handle is None:
            if self._send.done():
                self.handle = self._send.result()
            elif self.status is not None and self.status != GoalStatus.STATUS_UNKNOWN:
                now = time.monotonic()
                if self._status_seen_at is None:
                    self._status_seen_at = now
                if now - self._status_seen_at < REPLY_GRACE_S:
                    return False
                reply = self._action_type.Impl.SendGoalService.Response(accepted=True)
                self.handle = ClientGoalHandle(self._client, self._uuid, reply)
                self.recovered.append('goal response')
                self._node.get_logger().warning(
                    'the reply to the goal request was lost; the goal is accepted '
                    '(seen on the status topic)')
        return self.handle is not None

    def result_done(self) -> bool:
        """True once the result is there (:meth:`result`); asks again for a lost one."""
        if self.handle is None or not self.handle.accepted:
            msg = 'result_done() before the goal was accepted'
            raise RuntimeError(msg)
        if self._result is None:
            self._result = self.handle.get_result_async()
        if self._result.done():
            return True
        if self.status in _TERMINAL:
            now = time.monotonic()
            if self._terminal_at is None:
                self._terminal_at = now
            elif now - self._terminal_at > RESULT_AGAIN_S:
                self._result = self.handle.get_result_async()
                self._terminal_at = now
                self.recovered.append('result')
        return False

    def result(self) -> Any:
        """The action's result message (after :meth:`result_done` is True)."""
        return self._result.result().result

    def destroy(self) -> None:
        """Stop following the status topic."""
        self._node.destroy_subscription(self._sub)
