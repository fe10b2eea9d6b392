"""ReplayNode: publish a bag's messages raw (no decode) with the recorded timing.

``Publisher.publish(bytes)`` in rclpy 7.1 publishes serialised CDR (``publish_raw``), so
the bytes in the bag go on the wire unchanged. Timing: message i is published at
``t_start + (stamp_i - stamp_first) / rate`` on the monotonic clock, by a playback thread
(rclpy publishers are thread-safe), so the executor only serves the node's services.
Topics recorded with transient-local publishers (bench/info) are republished
transient-local, so late joiners get them as from the live bench. With ``clock`` the node
publishes the playback time on /clock (for ``use_sim_time`` consumers) at ``clock_rate_hz``.

Run: ``python -m rv_te_bench.nodes.replay --ros-args -p bag:=out/bags/x -p rate:=2.0``.
"""

from __future__ import annotations

import sys
import threading
import time
from collections.abc import Sequence
from typing import Any

from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock

from rv_te_bench.errors import BagError, YamlInputError
from rv_te_bench.io._legacy_msgs import upgrade_cdr
from rv_te_bench.io.bag_reader import bag_topics, iter_messages, open_bag
from rv_te_bench.io.msgdefs import BENCH_INFO, ENCODER_BLOCK
from rv_te_bench.nodes import qos
from rv_te_bench.nodes.common import declare_from_specs, run_node
from rv_te_bench.nodes.convert import message_class
from rv_te_bench.nodes.params.replay import PARAMS, ReplayParams
from rv_te_bench.params import params_record
from rv_te_bench.safe_yaml import SMALL_TEXT_LIMITS, load_yaml

__all__ = ['ReplayNode', 'main']

_THROTTLE_S = 5.0


#: Types whose topics are latched by the suite's contract (bench/info): a bag written by
#: another tool that recorded no QoS still replays them transient-local, as subscribers ask.
_LATCHED_TYPES = frozenset({'rv_te_msgs/msg/BenchInfo'})


def _recorded_qos(offered: Any, msgtype: str = '') -> QoSProfile:
    """Publisher QoS from a topic's recorded offered profiles (rosbag2 v8 string or v9 list);
    none recorded: latched for the types in :data:`_LATCHED_TYPES`, else reliable volatile."""
    try:   # bounded: the string comes from a file we did not write
        profiles = load_yaml(offered, origin='offered_qos_profiles',
                             limits=SMALL_TEXT_LIMITS) if isinstance(offered, str) else offered
    except YamlInputError:
        profiles = []   # unreadable: reliable, volatile (what most publishers offer)
    profiles = profiles if isinstance(profiles, list) else []
    latched = bool(profiles) and all(
        str(p.get('durability', '')).lower() == 'transient_local' for p in profiles)
    best_effort = bool(profiles) and all(
        str(p.get('reliability', '')).lower() == 'best_effort' for p in profiles)
    if latched or (not profiles and msgtype in _LATCHED_TYPES):
        return qos.LATCHED_QOS
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST, depth=qos.ENCODER_QUEUE_DEPTH,
        reliability=ReliabilityPolicy.BEST_EFFORT if best_effort else ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.VOLATILE)


class ReplayNode(Node):
    """Publish a recorded bag with its timing.

    Parameters (read-only): ``bag`` (path), ``rate`` (playback speed factor), ``loop``,
    ``topics`` (empty: all), ``start_offset_s``, ``clock``, ``clock_rate_hz``,
    ``wait_for_subscribers_s``.

    Attributes:
        finished: True when playback ended (never with ``loop`` until ``stop()``).
        published: Messages published per topic.

    Raises:
        BagError: The bag cannot be opened or a topic type cannot be imported.
    """

    def __init__(self, node_name: str = 'replay',
                 **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        p = self._declare_parameters()
        self.bag = open_bag(p.bag)
        self.rate = p.rate
        self.loop = p.loop
        self.start_offset_s = p.start_offset_s
        self.clock_period_s = 1.0 / p.clock_rate_hz
        self._wait_s = p.wait_for_subscribers_s
        wanted = set(p.topics or [])
        # metadata.yaml of a bag folder, or the MCAP channels of a lone .mcap file (rosbag2
        # keeps the offered QoS in each channel's metadata there too)
        topics = bag_topics(self.bag.path)
        qos_by_topic = {t: info['offered_qos_profiles'] for t, info in topics.items()}
        types = {t: info['type'] for t, info in topics.items() if info['type']}
        if not types:
            where = 'its MCAP channels' if self.bag.path.is_file() else 'metadata.yaml'
            msg = f'Bag {self.bag.path} lists no topics in {where}.'
            raise BagError(msg)
        if unknown := sorted(wanted - set(types)):
            msg = f'Bag {self.bag.path} has no topics {unknown}; it has {sorted(types)}.'
            raise BagError(msg)
        self._replay_pubs: dict[str, Any] = {}
        self._latched_topics: set[str] = set()
        self._types = types
        self._legacy: dict[str, bool] = {}   # topic -> recorded in the pre-issue-36 layout
        for topic, msgtype in types.items():
            if wanted and topic not in wanted:
                continue
            try:
                cls = message_class(msgtype)
            except (ImportError, AttributeError, ValueError) as exc:
                msg = f'Bag {self.bag.path}: cannot publish {topic}, type {msgtype}: {exc}'
                raise BagError(msg) from None
            profile = _recorded_qos(qos_by_topic.get(topic), msgtype)
            self._replay_pubs[topic] = self.create_publisher(cls, topic, profile)
            if profile.durability == DurabilityPolicy.TRANSIENT_LOCAL:
                self._latched_topics.add(topic)
        self._clock_pub = self.create_publisher(Clock, '/clock', qos.CLOCK_QOS) \
            if p.clock else None
        self.published = dict.fromkeys(self._replay_pubs, 0)
        self.finished = False
        self.exit_code = 0
        self.loops_done = 0
        self.out_of_order = 0       # logged before the file's first message: published at once
        self.skipped_by_offset = 0  # before --start-offset (latched topics excepted)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._play, name='rv_te_replay', daemon=True)
        self._thread.start()
        self.get_logger().info(f'replaying {self.bag.path} at {self.rate}x: '
                               f'{sorted(self._replay_pubs)}')

    def _declare_parameters(self) -> ReplayParams:
        p = params_record(ReplayParams, declare_from_specs(self, PARAMS))
        if not p.bag:
            msg = "Parameter 'bag' is empty: give the bag folder to play"
            raise BagError(msg)
        return p

    # ------------------------------------------------------------------ playback
    def _sleep_until(self, due: float, base_ns: int, wall0: float) -> bool:
        """Sleep until monotonic ``due``, publishing /clock; False when stopped.

        The bag time published at monotonic ``now`` is ``base_ns + (now - wall0) * rate``.
        """
        while True:
            now = time.monotonic()
            if self._clock_pub is not None:
                self._publish_clock(base_ns + (now - wall0) * self.rate * 1e9)
            remaining = due - now
            if remaining <= 0:
                return not self._stop.is_set()
            step = min(remaining, self.clock_period_s) if self._clock_pub else remaining
            if self._stop.wait(step):
                return False

    def _publish_clock(self, stamp_ns: float) -> None:
        msg = Clock()
        msg.clock.sec, msg.clock.nanosec = divmod(int(stamp_ns), 1_000_000_000)
        self._clock_pub.publish(msg)  # type: ignore[union-attr]

    def _wait_for_subscribers(self) -> None:
        end = time.monotonic() + self._wait_s
        while time.monotonic() < end and not self._stop.is_set():
            if all(p.get_subscription_count() > 0 for p in self._replay_pubs.values()):
                return
            self._stop.wait(0.05)

    def _play(self) -> None:
        try:
            if self._wait_s > 0:
                self._wait_for_subscribers()
            while not self._stop.is_set():
                self._play_once()
                self.loops_done += 1
                if not self.loop:
                    break
            if not self._stop.is_set() and not any(self.published.values()):
                # a replay that published nothing has failed, whatever the reason
                self.exit_code = 1
                self.get_logger().error(
                    f'replay published nothing: {self.bag.path} has no readable message on '
                    f'{", ".join(sorted(self._replay_pubs))}')
        except BagError as exc:
            self.exit_code = 1
            self.get_logger().error(f'replay stopped: {exc}')
        except Exception as exc:  # noqa: BLE001 - the thread must report, not vanish
            self.exit_code = 1
            self.get_logger().error(f'replay failed: {exc!r}')
        finally:
            self.finished = True

    def _bytes(self, topic: str, data: bytes | memoryview) -> bytes:
        """The message as today's definition lays it out: a bag recorded before issue 36
        (no read-head fields) is brought up to date, decided on each topic's first
        message (a subscriber would otherwise fail to deserialise it)."""
        msgtype = self._types.get(topic, '')
        if msgtype not in (ENCODER_BLOCK, BENCH_INFO):
            return bytes(data)
        old = self._legacy.get(topic)
        if old is None:
            try:
                up = upgrade_cdr(msgtype, data)
            except Exception:  # noqa: BLE001 - neither layout: published as recorded
                up = bytes(data)
            old = self._legacy[topic] = up != bytes(data)
            if old:
                self.get_logger().info(f'{topic}: recorded before the read-head fields; '
                                       'published in the current layout')
            return up
        return upgrade_cdr(msgtype, data) if old else bytes(data)

    def _play_once(self) -> None:
        stream = iter_messages(self.bag.path, list(self._replay_pubs), strict=False)
        start_ns: int | None = None
        base_ns = 0
        wall0 = 0.0
        for topic, _, stamp_ns, data in stream:
            if start_ns is None:
                start_ns = stamp_ns
                base_ns = start_ns + round(self.start_offset_s * 1e9)
                wall0 = time.monotonic()
            if stamp_ns < base_ns and self.start_offset_s > 0:
                # skipped by --start-offset; latched state (bench/info) still holds then,
                # as it would for a late joiner of the live session
                if topic in self._latched_topics:
                    self._replay_pubs[topic].publish(self._bytes(topic, data))
                    self.published[topic] += 1
                else:
                    self.skipped_by_offset += 1
                continue
            if stamp_ns < start_ns:
                # logged before the first message of the file (written out of order): due
                # already, published at once rather than dropped
                self.out_of_order += 1
            due = wall0 + (stamp_ns - base_ns) * 1e-9 / self.rate
            if not self._sleep_until(due, base_ns, wall0):
                return
            self._replay_pubs[topic].publish(self._bytes(topic, data))
            self.published[topic] += 1
        if self.out_of_order:
            self.get_logger().warning(
                f'{self.out_of_order} message(s) logged before the first one in the file were '
                'published at once (out of order)', throttle_duration_sec=_THROTTLE_S)
        if self.skipped_by_offset:
            self.get_logger().info(
                f'{self.skipped_by_offset} message(s) before the start offset '
                f'({self.start_offset_s} s) not published', throttle_duration_sec=_THROTTLE_S)
        if stream.partial:
            self.get_logger().warning(f'bag partly unreadable: {stream.problems}',
                                      throttle_duration_sec=_THROTTLE_S)

    def stop(self) -> None:
        """Stop playback and wait for the playback thread (idempotent)."""
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=5.0)

    def destroy_node(self) -> None:
        """Stop playback, then destroy the node."""
        self.stop()
        super().destroy_node()


def main(argv: Sequence[str] | None = None) -> int:
    """Run one ReplayNode until the bag ends (or SIGINT/SIGTERM); 0 ok, 1 error."""
    return run_node(lambda ctx: ReplayNode(context=ctx),
                    list(sys.argv if argv is None else argv), linger_s=0.5)


if __name__ == '__main__':
    sys.exit(main())
