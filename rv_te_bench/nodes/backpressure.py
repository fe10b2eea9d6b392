"""Back-pressure of a fast session: the bench waits for the consumers that must not lose.

In ``fast`` time mode the bench makes blocks faster than real time; a reader that falls
further behind than the encoder queue (:data:`qos.ENCODER_QUEUE_DEPTH` blocks) loses the
oldest. So each consumer that must not lose data (the recorder, the TE node) says, a few
times per second, how far it has taken the blocks: the last ``seq`` received, a
``std_msgs/UInt64`` on ``bench/acked/<node name>`` (relative: the session's namespace). The
bench publishes only while its newest block is less than :data:`ACK_WINDOW_BLOCKS` ahead of
the slowest of them (:class:`AckGate`); one whose acknowledgement has not moved for
``ack_timeout_s`` while it holds the bench (it died, or hangs) is let go, logged once.
Real-time mode does not wait (a DAQ does not): there the gate is not made. A bench that
runs programs (``commanded``) starts the gate again at each program's first block (its
``seq`` continues across programs): a reader that acknowledged before holds from where it
was, one that did not from the program's first block.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable
from typing import Any

from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import UInt64

from rv_te_bench.nodes import qos

__all__ = ['ACK_PERIOD_S', 'ACK_REPEAT_PERIODS', 'ACK_TOPIC_PREFIX', 'ACK_WINDOW_BLOCKS', 'AckGate',
           'BlockAcks']

#: Topic (relative to the session's namespace) + node name of a consumer's acknowledgements.
ACK_TOPIC_PREFIX = 'bench/acked/'
#: How often a consumer says how far it is [s].
ACK_PERIOD_S = 0.05
#: A consumer whose position stands says it again after this many periods (0.5 s).
ACK_REPEAT_PERIODS = 10
#: Blocks the bench may be ahead of its slowest consumer: half the encoder queue, so an
#: acknowledgement that is one period old still leaves room in the reader's queue.
ACK_WINDOW_BLOCKS = qos.ENCODER_QUEUE_DEPTH // 2

ACK_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                     reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.VOLATILE)


class BlockAcks:
    """Consumer side: publish ``last_seq()`` on ``bench/acked/<node name>`` every
    :data:`ACK_PERIOD_S` (steady clock) when it moved, and every :data:`ACK_REPEAT_PERIODS`
    periods when it did not; ``None`` = no block yet."""

    def __init__(self, node: Node, last_seq: Callable[[], int | None]) -> None:
        self._last_seq = last_seq
        self._sent: int | None = None
        self._quiet = 0     # timer periods since the last acknowledgement sent
        self._pub = node.create_publisher(UInt64, ACK_TOPIC_PREFIX + node.get_name(),
                                          ACK_QOS)
        node.create_timer(ACK_PERIOD_S, self._on_timer,
                          clock=Clock(clock_type=ClockType.STEADY_TIME))

    def last(self) -> int | None:
        """The last block the node took (None: none yet)."""
        return self._last_seq()

    def _on_timer(self) -> None:
        seq = self._last_seq()
        if seq is None:
            return
        self._quiet += 1
        # when it moved, and again every ACK_REPEAT_PERIODS while it stands: an
        # acknowledgement sent before the bench's reader matched ours is lost, and a bench
        # held at its first block (AckGate) would wait for it until its ack timeout
        if seq != self._sent or self._quiet >= ACK_REPEAT_PERIODS:
            self._sent = seq
            self._quiet = 0
            self._pub.publish(UInt64(data=seq))


class AckGate:
    """Bench side: how many blocks may leave now, from the consumers' acknowledgements.

    Subscribes ``bench/acked/<name>`` for each of ``names`` at once (they match while the
    bench waits for its subscribers); :meth:`start` says which of them hold the bench: the
    ones that are in the session and publish acknowledgements (a node of older code, or
    one not there, does not).
    """

    def __init__(self, node: Node, names: Iterable[str], timeout_s: float,
                 window: int = ACK_WINDOW_BLOCKS) -> None:
        self._node = node
        self.window = window
        self.timeout_s = timeout_s
        self._acked: dict[str, int] = {}       # holding consumer -> last seq it received
        self._seen: dict[str, int] = {}        # any consumer -> last seq it acknowledged
        self._moved: dict[str, float] = {}     # ... -> when its acknowledgement last moved
        self._low = -1                         # min(self._acked.values())
        self._first = 0                        # the first block of the current start
        self.released: list[str] = []          # let go after the timeout
        self.held_s = 0.0                      # time spent waiting for them (diagnostics)
        self._held_since: float | None = None
        self._subs: dict[str, Any] = {
            n: node.create_subscription(UInt64, ACK_TOPIC_PREFIX + n,
                                        lambda m, n=n: self._on_ack(n, m.data), ACK_QOS)
            for n in names}

    def start(self, present: Iterable[str], first_seq: int = 0) -> list[str]:
        """Hold for the ``present`` nodes that publish acknowledgements, from block
        ``first_seq`` on (a program's first block: the seq continues across programs);
        returns them. Called again, it starts over (who holds, the timeouts)."""
        ns = self._node.get_namespace()
        now = time.monotonic()
        if self._held_since is not None:
            self.held_s += now - self._held_since
            self._held_since = None
        self._acked.clear()
        self._moved.clear()
        self._first = first_seq
        for name in present:
            sub = self._subs.get(name)
            if sub is None:
                continue
            pubs = self._node.get_publishers_info_by_topic(sub.topic_name)
            if any(i.node_name == name and i.node_namespace == ns for i in pubs):
                # where it was (still behind on an earlier program?), else before the first
                self._acked[name] = self._seen.get(name, first_seq - 1)
                self._moved[name] = now
        self._low = min(self._acked.values()) if self._acked else -1
        return sorted(self._acked)

    def _on_ack(self, name: str, seq: int) -> None:
        if seq > self._seen.get(name, -1):
            self._seen[name] = seq
        old = self._acked.get(name)
        if old is None or seq <= old:
            return
        self._acked[name] = seq
        self._moved[name] = time.monotonic()
        self._low = min(self._acked.values())

    def room(self, last_seq: int) -> int:
        """Blocks that may leave after block ``last_seq`` (-1: none yet); a large number
        when nobody holds the bench."""
        if not self._acked:
            return 1 << 30
        if any(n not in self._seen for n in self._acked):
            # first contact: one block, then wait until every holding reader has taken it.
            # A reader's side of the match can come after ours; blocks sent before it came
            # late (by the reliable protocol's repair) and a sim-time recorder, whose /clock
            # had moved on meanwhile, logged the first blocks 0.3 s late
            room = self._first - last_seq
        else:
            room = self.window - (last_seq - self._low)
        now = time.monotonic()
        if room > 0:
            if self._held_since is not None:
                self.held_s += now - self._held_since
                self._held_since = None
            return room
        if self._held_since is None:
            self._held_since = now
        stale = [n for n, seq in self._acked.items()
                 if seq <= self._low and now - self._moved[n] > self.timeout_s]
        if not stale:
            return 0
        for name in stale:
            self._release(name)
        return self.room(last_seq)

    def _release(self, name: str) -> None:
        seq = self._acked.pop(name)
        self.released.append(name)
        self._low = min(self._acked.values()) if self._acked else -1
        self._node.get_logger().warning(
            f'{name} took no block for {self.timeout_s:g} s (last seq {seq}); going on '
            f'without waiting for it: it may lose blocks')
