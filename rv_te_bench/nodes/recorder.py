"""RecorderNode: record the suite's topics to a rosbag2 (MCAP) bag, raw, without decoding.

Raw subscriptions (``raw=True``) hand the CDR bytes straight to ``BagWriter``; the only
parsing on the hot path is the EncoderBlock ``seq`` (a fixed offset after the header's
frame_id) to count sequence gaps. Topic types come from the graph (the node keeps
discovering, so late publishers are recorded too) or from ``topic_types``; the
subscription QoS follows the publishers (rosbag2's rule: reliable if all publishers are,
transient-local if all are), so latched messages (bench/info) are captured.

Run: ``python -m rv_te_bench.nodes.recorder --ros-args -p output_dir:=out/bags``;
SIGINT/SIGTERM close the bag; a SIGKILL loses at most the last ``flush_interval_s``.

A full disk does not stop the node: the bag is closed at its last complete chunk, messages
are held in memory (``stall_buffer_bytes``) and recording resumes into a new split file when
space returns; what could not be kept is counted per topic, logged, published on
/diagnostics (ERROR), stated in metadata.yaml, and the process exits with code 1.
"""

from __future__ import annotations

import datetime as dt
import platform
import struct
import sys
import time
from collections.abc import Callable, Sequence
from importlib import metadata as importlib_metadata
from pathlib import Path
from typing import Any

import yaml
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock as ClockMsg

from rv_te_bench.errors import BagError, BagExistsError, YamlInputError
from rv_te_bench.io.bag_reader import encoder_block_seq
from rv_te_bench.io.bag_writer import BagWriter, qos_profile_dict
from rv_te_bench.io.files import write_atomic
from rv_te_bench.io.msgdefs import ENCODER_BLOCK
from rv_te_bench.nodes import qos
from rv_te_bench.nodes.backpressure import BlockAcks
from rv_te_bench.nodes.common import (
    DRAIN_MAX_S,
    declare_from_specs,
    note_stop_phase,
    run_node,
)
from rv_te_bench.nodes.convert import message_class
from rv_te_bench.nodes.params.recorder import DEFAULT_TOPICS, PARAMS, RecorderParams
from rv_te_bench.params import params_record, params_values
from rv_te_bench.safe_yaml import PARAMETER_FILE_LIMITS, brief, load_yaml

__all__ = ['DEFAULT_TOPICS', 'PARAMS', 'RecorderNode', 'main']

_THROTTLE_S = 5.0
#: How long a closing recorder waits for its final 'closed' status to be acknowledged [s].
FINAL_STATUS_ACK_S = 1.0
#: Messages held while a sim-time recorder waits for its first /clock (10 s at 100 blocks/s
#: on every suite topic); beyond that they are written at time 0.
MAX_HELD_MESSAGES = 10_000


def _qos_dict(profile: QoSProfile) -> dict[str, Any]:
    return qos_profile_dict(reliability=profile.reliability.name.lower(),
                            durability=profile.durability.name.lower(),
                            history=profile.history.name.lower(), depth=profile.depth)


def check_config(p: RecorderParams) -> dict[str, str]:
    """The recorder's start-up checks (also run by ``rv-te launch --check``).

    Returns:
        Explicit topic types (topic as given -> ``pkg/msg/Type``).

    Raises:
        BagError: A ``topic_types`` entry that is malformed or names a type that cannot be
            imported, ``session_metadata_yaml`` that is not a bounded YAML document, or a
            bag folder that exists already or cannot be made.
    """
    explicit = {}
    for item in p.topic_types:
        name, sep, msgtype = item.partition('=')
        msgtype = msgtype.strip()
        if not sep or not name.strip() or msgtype.count('/') != 2:
            msg = f"topic_types entry {brief(item)} must be 'topic=pkg/msg/Type'"
            raise BagError(msg)
        try:
            message_class(msgtype)
        except (ImportError, AttributeError, ValueError) as exc:
            msg = f'topic_types entry {brief(item)}: type {brief(msgtype)} not importable ({exc})'
            raise BagError(msg) from None
        explicit[name.strip()] = msgtype
    _parse_metadata(p.session_metadata_yaml)
    if p.bag_name:
        path = Path(p.output_dir) / p.bag_name
        if path.exists() or path.is_symlink():
            msg = f'Bag {path} exists already, not overwriting.'
            raise BagError(msg)
    parent = Path(p.output_dir)
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    if parent.exists() and not parent.is_dir():
        msg = f'Cannot create bag folder under {p.output_dir}: {parent} is not a folder.'
        raise BagError(msg)
    return explicit


def _parse_metadata(text: str) -> dict[str, Any]:
    """``session_metadata_yaml`` -> mapping (a scalar or list is kept under 'session')."""
    try:
        given = load_yaml(text, origin="parameter 'session_metadata_yaml'",
                          limits=PARAMETER_FILE_LIMITS) if text else {}
    except YamlInputError as exc:
        raise BagError(str(exc)) from None
    return given if isinstance(given, dict) else {'session': given}


class _TopicState:
    __slots__ = ('count', 'gaps', 'last_seq', 'malformed', 'max_publishers', 'missing',
                 'msgtype', 'name')

    def __init__(self, name: str, msgtype: str) -> None:
        self.name = name
        self.msgtype = msgtype
        self.count = 0
        self.gaps = 0
        self.missing = 0
        self.malformed = 0
        self.max_publishers = 0   # EncoderBlock topics: most publishers seen at once
        self.last_seq: int | None = None


class RecorderNode(Node):
    """Record topics raw into a rosbag2 bag folder (MCAP storage).

    Parameters (read-only): ``output_dir``, ``bag_name``, ``topics``, ``topic_types``,
    ``compression``, ``chunk_size_bytes``, ``flush_interval_s``, ``split_size_bytes``,
    ``split_duration_s``, ``duration_s``, ``discovery_period_s``, ``session_metadata_yaml``.

    Messages are logged at the node's clock. With ``use_sim_time`` a message that arrives
    before the first ``/clock`` (a latched BenchInfo, typically) is held and written at the
    first clock time, so no message of the session lies at time 0 (1970).

    Attributes:
        bag_path: The bag folder being written.
        finished: True once the bag was closed (``duration_s`` reached or ``close()``).

    Raises:
        BagError: The bag folder exists already or cannot be created.
    """

    #: A stopping recorder takes every message already queued for it (run_node's drain).
    drain_max_s = DRAIN_MAX_S

    def __init__(self, node_name: str = 'recorder',
                 **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        p = self._declare_parameters()
        self.finished = False
        self._topics: dict[str, _TopicState] = {}
        # messages that arrived in sim time before the first /clock, written at its time
        self._held: list[tuple[_TopicState, bytes]] = []
        self._subscriptions_by_topic: dict[str, Any] = {}
        given_types = check_config(p)
        self._wanted = [self._resolve(t) for t in p.topics]
        self._explicit = {self._resolve(t): m for t, m in given_types.items()}
        self._summary_file = p.summary_file
        self.exit_code = 0
        self.bag_path, self._writer = self._open_bag(p)
        self.write_errors = 0
        #: Messages handed to a callback after the bag was closed (not recorded).
        self.after_close = 0
        self._duration_s = p.duration_s
        self._start = self.get_clock().now()
        self._sim_clock_ns = 0
        self._use_sim_time = bool(self.get_parameter('use_sim_time').value)
        if self._use_sim_time:
            # The log clock: every /clock in arrival order. The node clock's own /clock
            # subscription keeps only the last message, so blocks that arrive while the
            # executor is busy (subscribing to newly found topics) would all be logged at
            # the clock of the last of them.
            self.create_subscription(ClockMsg, '/clock', self._on_clock, QoSProfile(
                history=HistoryPolicy.KEEP_LAST, depth=qos.ENCODER_QUEUE_DEPTH,
                reliability=ReliabilityPolicy.BEST_EFFORT,
                durability=DurabilityPolicy.VOLATILE))
        self._pub_diag = self.create_publisher(DiagnosticArray, '/diagnostics',
                                               qos.DIAGNOSTICS_QOS)
        # flushing and discovery pace on the steady clock: with use_sim_time the node clock
        # stands still until the first /clock, and a bench that waits for the recorder to
        # subscribe publishes no /clock before that (a deadlock until its wait times out)
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.create_timer(min(0.25, p.flush_interval_s / 2), self._on_flush_timer,
                          clock=steady)
        self.create_timer(1.0, self._publish_diagnostics, clock=steady)
        self.create_timer(p.discovery_period_s, self._discover, clock=steady)
        # a fast bench waits while the blocks recorded are too far behind its newest
        encoders = self._resolve('bench/encoders')
        self.block_acks = BlockAcks(self, lambda: (
            s.last_seq if (s := self._topics.get(encoders)) is not None else None))
        self._discover()
        self.get_logger().info(f'recording {self._wanted} to {self.bag_path}')

    # ---------------------------------------------------------------- parameters
    def _declare_parameters(self) -> RecorderParams:
        return params_record(RecorderParams, declare_from_specs(self, PARAMS))

    def _open_bag(self, p: RecorderParams) -> tuple[Path, BagWriter]:
        """Create the bag; a default name gets _2, _3, ... when taken (two recorders
        started in the same second), a given name must be free."""
        stamp = dt.datetime.now(dt.UTC).strftime('%Y%m%d_%H%M%S')
        base = p.bag_name or f'rv_te_{stamp}'
        meta = self._session_metadata(p)
        for attempt in range(1, 1000):
            path = Path(p.output_dir) / (base if attempt == 1 else f'{base}_{attempt}')
            try:
                return path, BagWriter(
                    path, compression=p.compression,
                    chunk_size_bytes=p.chunk_size_bytes,
                    flush_interval_s=p.flush_interval_s,
                    split_size_bytes=p.split_size_bytes or None,
                    split_duration_s=p.split_duration_s or None,
                    session_metadata=meta, stall_buffer_bytes=p.stall_buffer_bytes,
                    on_event=self._on_writer_event)
            except BagExistsError:
                if p.bag_name:
                    raise
        msg = f'no free bag name {base}_<n> in {p.output_dir}'
        raise BagError(msg)

    def _on_writer_event(self, line: str) -> None:
        """The writer's report of a failed write (ERROR) or of writing again (WARN)."""
        writer = getattr(self, '_writer', None)
        if writer is not None and not writer.stalled:
            self.get_logger().warning(line)
        else:
            self.get_logger().error(line)

    def _resolve(self, topic: str) -> str:
        try:
            return self.resolve_topic_name(topic)
        except Exception as exc:  # noqa: BLE001 - _rclpy.RCLError
            detail = str(exc).removeprefix('failed to resolve name: ').split(', at ')[0]
            msg = f'topic {brief(topic)} is not a valid ROS topic name: {detail}'
            raise BagError(msg) from None

    def _session_metadata(self, p: RecorderParams) -> dict[str, Any]:
        given = _parse_metadata(p.session_metadata_yaml)

        def version(dist: str) -> str:
            try:
                return importlib_metadata.version(dist)
            except importlib_metadata.PackageNotFoundError:
                return 'unknown'

        meta = {
            'recorder_node': self.get_fully_qualified_name(),
            'namespace': self.get_namespace(),
            'started_utc': dt.datetime.now(dt.UTC).isoformat(timespec='seconds'),
            'software': {'rv_te_bench': version('rv-te-bench'),
                         'rclpy': version('ros-jazzy-rclpy'),
                         'rosbags': version('rosbags'), 'mcap': version('mcap'),
                         'python': platform.python_version()},
            'recorder_parameters': {k: v for k, v in params_values(p).items()
                                    if k != 'session_metadata_yaml'},
            'log_time': self._log_time_statement(),
        }
        meta.update(given)
        return meta

    def _log_time_statement(self) -> str:
        if self.get_parameter('use_sim_time').value:
            return ('sim: the session clock from /clock (use_sim_time), as ros2 bag record '
                    '--use-sim-time; a fast session spans its simulated duration')
        return 'system: wall-clock time of receipt'

    # ---------------------------------------------------------------- discovery
    def _discover(self) -> None:
        if self.finished:
            return
        missing = [t for t in self._wanted if t not in self._subscriptions_by_topic]
        if not missing:
            return
        graph = dict(self.get_topic_names_and_types())
        # encoder blocks last: a bench that waits for the recorder starts once that
        # subscription is there, and the recorder is then done creating the others (~5 ms
        # each) instead of falling behind the first blocks (and their /clock) while it works
        missing.sort(key=lambda t: ENCODER_BLOCK in (self._explicit.get(t), *graph.get(t, ())))
        for topic in missing:
            msgtype = self._explicit.get(topic)
            if msgtype is None and not self.get_publishers_info_by_topic(topic):
                # Only subscribers so far: wait for a publisher, whose QoS (reliability,
                # transient-local) the subscription must match to get latched messages.
                continue
            if msgtype is None:
                types = graph.get(topic, [])
                if len(types) != 1:
                    if len(types) > 1:
                        self.get_logger().warning(
                            f'{topic} has several types {types}; give one in topic_types',
                            throttle_duration_sec=_THROTTLE_S)
                    continue
                msgtype = types[0]
            self._subscribe(topic, msgtype)

    def _subscription_qos(self, topic: str) -> QoSProfile:
        infos = self.get_publishers_info_by_topic(topic)
        reliable = bool(infos) and all(
            i.qos_profile.reliability == ReliabilityPolicy.RELIABLE for i in infos)
        latched = bool(infos) and all(
            i.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL for i in infos)
        if not infos:  # explicit type, no publisher yet: reliable, volatile (matches most)
            reliable = True
        return QoSProfile(
            depth=qos.ENCODER_QUEUE_DEPTH,
            reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
            durability=(DurabilityPolicy.TRANSIENT_LOCAL if latched
                        else DurabilityPolicy.VOLATILE))

    def _subscribe(self, topic: str, msgtype: str) -> None:
        try:
            cls = message_class(msgtype)
        except (ImportError, AttributeError, ValueError) as exc:
            self.get_logger().error(f'cannot record {topic}: type {msgtype} not importable '
                                    f'({exc})', throttle_duration_sec=_THROTTLE_S)
            return
        profile = self._subscription_qos(topic)
        infos = self.get_publishers_info_by_topic(topic)
        offered = [_qos_dict(i.qos_profile) for i in infos]
        # The publisher's own RIHS01 hash where the graph reports one (else the typestore's).
        hashes = {str(i.topic_type_hash) for i in infos if i.topic_type_hash.version > 0}
        digest = hashes.pop() if len(hashes) == 1 else None
        try:
            if topic not in self._writer.counts:
                self._writer.add_topic(topic, msgtype, offered_qos_profiles=offered,
                                       digest=digest)
        except BagError as exc:
            self.get_logger().error(f'cannot record {topic}: {exc}',
                                    throttle_duration_sec=_THROTTLE_S)
            self._subscriptions_by_topic[topic] = None
            return
        state = _TopicState(topic, msgtype)
        self._topics[topic] = state
        callback = (self._make_encoder_callback(state) if msgtype == ENCODER_BLOCK
                    else self._make_callback(state))
        self._subscriptions_by_topic[topic] = self.create_subscription(
            cls, topic, callback, profile, raw=True)
        self.get_logger().info(
            f'recording {topic} [{msgtype}] ({profile.reliability.name.lower()}, '
            f'{profile.durability.name.lower()})')

    # ---------------------------------------------------------------- hot path
    def _on_clock(self, msg: ClockMsg) -> None:
        self._sim_clock_ns = max(self._sim_clock_ns,
                                 msg.clock.sec * 1_000_000_000 + msg.clock.nanosec)

    def _log_time_ns(self) -> int:
        """The log time of a message received now: the session's /clock with use_sim_time
        (0 before the first), else the node's (system) clock."""
        if self._use_sim_time:
            return self._sim_clock_ns
        return self.get_clock().now().nanoseconds

    def _make_callback(self, state: _TopicState) -> Callable[[bytes], None]:
        # without sim time the node's clock is the system clock: read it directly
        # (Clock.now() builds a Time object per message; issue 41 item 4)
        now = self._log_time_ns if self._use_sim_time else time.time_ns
        record = self._record

        def on_message(data: bytes) -> None:
            t_ns = now()
            if t_ns == 0:   # sim time before the first /clock: no time to log it at yet
                self._hold(state, data)
                return
            if self._held:
                self._release_held(t_ns)
            record(state, t_ns, data)

        return on_message

    def _record(self, state: _TopicState, t_ns: int, data: bytes) -> None:
        """Write one message at log time ``t_ns`` and count it (a failed write is logged).

        After :meth:`close` a message is not recorded and not a write failure: close()
        destroys the subscriptions first, but an executor may still hand over a message it
        took before (in a one-process session the EventsExecutor dispatched one of another
        session's /diagnostics after the recorder had left it, which logged "bag write
        failed: Bag ... is closed"); it is counted in ``after_close``."""
        if self.finished:
            self.after_close += 1
            return
        try:
            self._writer.write(state.name, t_ns, data)
        except BagError as exc:
            self._write_failed(exc)
            return
        state.count += 1

    def _hold(self, state: _TopicState, data: bytes) -> None:
        """Keep a message that arrived before the first /clock (sim time), bounded."""
        if len(self._held) >= MAX_HELD_MESSAGES:
            self._release_held(0)
            self.get_logger().warning(
                f'no /clock after {MAX_HELD_MESSAGES} messages (use_sim_time): recorded them '
                'at time 0', throttle_duration_sec=_THROTTLE_S)
        self._held.append((state, data))

    def _release_held(self, t_ns: int) -> None:
        """Write the held messages, in arrival order, at the first clock time ``t_ns``."""
        held, self._held = self._held, []
        for state, data in held:
            self._record(state, t_ns, data)

    def _make_encoder_callback(self, state: _TopicState) -> Callable[[bytes], None]:
        plain = self._make_callback(state)

        def on_block(data: bytes) -> None:
            plain(data)
            try:
                seq = encoder_block_seq(data)
            except (struct.error, IndexError):
                state.malformed += 1
                self.get_logger().warning(
                    f'{state.name}: malformed EncoderBlock ({len(data)} bytes), recorded as '
                    f'is; {state.malformed} so far', throttle_duration_sec=_THROTTLE_S)
                return
            last = state.last_seq
            if last is not None and seq != last + 1:
                state.gaps += 1
                if seq > last:
                    state.missing += seq - last - 1
                self.get_logger().warning(
                    f'{state.name}: sequence gap {last} -> {seq}; {state.gaps} gaps, '
                    f'{state.missing} blocks missing so far', throttle_duration_sec=_THROTTLE_S)
            state.last_seq = seq

        return on_block

    def _write_failed(self, exc: BagError) -> None:
        self.write_errors += 1
        self.get_logger().error(f'bag write failed ({self.write_errors} so far): {exc}',
                                throttle_duration_sec=_THROTTLE_S)

    # ---------------------------------------------------------------- timers
    def _on_flush_timer(self) -> None:
        if self.finished:
            return
        if self._held:
            t_ns = self._log_time_ns()
            if t_ns:   # the clock has started
                self._release_held(t_ns)
        try:
            self._writer.flush_if_due()
        except BagError as exc:
            self._write_failed(exc)
        if self._duration_s > 0 and (
                self.get_clock().now() - self._start).nanoseconds * 1e-9 >= self._duration_s:
            self.get_logger().info(f'duration {self._duration_s} s reached')
            self.close()

    @property
    def counts(self) -> dict[str, int]:
        """Messages received per topic and given to the bag (``written``: those on disk,
        ``lost``: those a full disk cost)."""
        return {t: s.count for t, s in self._topics.items()}

    @property
    def gaps(self) -> dict[str, tuple[int, int]]:
        """(gaps, missing blocks) per EncoderBlock topic."""
        return {t: (s.gaps, s.missing) for t, s in self._topics.items()
                if s.msgtype == ENCODER_BLOCK}

    @property
    def written(self) -> dict[str, int]:
        """Messages per topic on disk (in complete chunks): what a reader of the bag finds."""
        return self._writer.counts

    @property
    def lost(self) -> dict[str, int]:
        """Messages per topic received but not written (the disk was full)."""
        return self._writer.lost

    def loss_report(self) -> list[str]:
        """One line per write gap (empty when nothing went wrong writing the bag)."""
        return [g.describe() for g in self._writer.write_gaps]

    def _check_publishers(self) -> list[str]:
        """EncoderBlock topics with more than one publisher: a foreign one (a second bench,
        ``rv-te replay`` into this namespace) mixes its blocks into the session's data."""
        foreign = []
        for s in self._topics.values():
            if s.msgtype != ENCODER_BLOCK:
                continue
            n = self.count_publishers(s.name)
            s.max_publishers = max(s.max_publishers, n)
            if n > 1:
                foreign.append(s.name)
                self.get_logger().error(
                    f'{s.name}: {n} publishers: a foreign publisher (a second bench, or a '
                    'replay into this namespace) mixes its blocks into this session; the '
                    'recording will end with an error', throttle_duration_sec=_THROTTLE_S)
        return foreign

    def foreign_publishers(self) -> dict[str, int]:
        """EncoderBlock topics that had more than one publisher, with the most seen."""
        return {s.name: s.max_publishers for s in self._topics.values()
                if s.max_publishers > 1}

    def _publish_diagnostics(self) -> None:
        foreign = [] if self.finished else self._check_publishers()
        states = list(self._topics.values())
        lost = self._writer.lost_messages
        bad = sum(s.gaps + s.malformed for s in states) + self.write_errors + lost
        stalled = self._writer.stalled
        level = (DiagnosticStatus.ERROR if stalled or lost or foreign
                 else DiagnosticStatus.WARN if bad else DiagnosticStatus.OK)
        state = ('closed' if self.finished else 'DISK FULL' if stalled
                 else f'FOREIGN PUBLISHER on {", ".join(foreign)}' if foreign else 'recording')
        status = DiagnosticStatus(
            level=level, name=f'{self.get_name()}: recorder', hardware_id=str(self.bag_path),
            message=state + (f', {lost} messages lost' if lost else '') +
            (f', {bad} problems' if bad else ''))
        values = [KeyValue(key='bag', value=str(self.bag_path)),
                  KeyValue(key='write_errors', value=str(self.write_errors)),
                  KeyValue(key='lost_messages', value=str(lost))]
        for s in states:
            values.append(KeyValue(key=f'{s.name} count', value=str(s.count)))
            if s.msgtype == ENCODER_BLOCK:
                values += [KeyValue(key=f'{s.name} gaps', value=str(s.gaps)),
                           KeyValue(key=f'{s.name} missing_blocks', value=str(s.missing)),
                           KeyValue(key=f'{s.name} malformed', value=str(s.malformed))]
        status.values = values
        msg = DiagnosticArray(status=[status])
        msg.header.stamp = self.get_clock().now().to_msg()
        self._pub_diag.publish(msg)

    # ---------------------------------------------------------------- shutdown
    def close(self) -> None:
        """Stop recording and finalise the bag (idempotent)."""
        if self.finished:
            return
        if self._held:   # (sim time and /clock never came: time 0 is all there is)
            t_ns = self._log_time_ns()
            if not t_ns:
                self.get_logger().warning(f'no /clock received (use_sim_time): '
                                          f'{len(self._held)} messages recorded at time 0')
            self._release_held(t_ns)
        # only now: the held messages above are written, what an executor hands over from
        # here on is not (see _record)
        self.finished = True
        try:
            self._writer.close()
        except BagError as exc:
            self.exit_code = 1
            self.get_logger().error(f'closing {self.bag_path} failed: {exc}')
        on_disk = self.written
        self.get_logger().info(f'bag {self.bag_path} closed: {sum(on_disk.values())} '
                               f'messages on disk {on_disk}')
        lost = self._writer.lost_messages
        if lost:
            self.exit_code = 1
            self.get_logger().error(
                f'bag {self.bag_path}: {lost} messages could not be written '
                f'{ {t: n for t, n in self.lost.items() if n} }')
            for line in self.loss_report():
                self.get_logger().error(f'bag {self.bag_path}: {line}')
        foreign = self.foreign_publishers()
        if foreign:
            self.exit_code = 1
            self.get_logger().error(f'bag {self.bag_path}: more than one publisher on '
                                    f'{foreign} (topic: most at once): the data mixes sources')
        if self._summary_file:
            self._write_summary_file()
        self._publish_final_status()
        # The subscriptions go last, once the bag is closed and the summary written (what
        # the executor hands over from now on is counted, not recorded: see _record).
        # Destroying one blocked for ~20 s inside rclpy / Fast DDS at load 20-40 (eight
        # benches, 2026-11-28), and the launcher killed the recorder before it had closed
        # its bag: 6895 of 9000 blocks in it, the session's stop failed.
        note_stop_phase('bag closed and summary written; destroying its subscriptions')
        for sub in self._subscriptions_by_topic.values():
            if sub is not None:
                self.destroy_subscription(sub)
        self._subscriptions_by_topic.clear()

    def _publish_final_status(self) -> None:
        """The 'closed' status once, waited for until acknowledged (at most
        :data:`FINAL_STATUS_ACK_S`): a monitor (the live page) would otherwise keep showing
        the last periodic 'recording' status of a bag that is closed."""
        from rclpy.duration import Duration

        try:
            self._publish_diagnostics()
            self._pub_diag.wait_for_all_acked(Duration(seconds=FINAL_STATUS_ACK_S))
        except Exception as exc:  # noqa: BLE001 - a context already shut down: nobody listens
            self.get_logger().debug(f'final status not sent: {exc}')

    def summary(self) -> dict[str, Any]:
        """What was recorded: bag, messages on disk, lost (per topic, and each write gap),
        EncoderBlock sequence gaps on receipt."""
        return {'bag': str(self.bag_path), 'messages_on_disk': self.written,
                'lost_messages': self._writer.lost_messages,
                'lost': {t: n for t, n in self.lost.items() if n},
                'write_gaps': self.loss_report(),
                'sequence_gaps': {t: {'gaps': g, 'missing_blocks': m}
                                  for t, (g, m) in self.gaps.items() if g},
                'foreign_publishers': self.foreign_publishers()}

    def _write_summary_file(self) -> None:
        """The closing summary as YAML (``summary_file``), read by the launcher."""
        try:
            write_atomic(self._summary_file, yaml.safe_dump(self.summary(), sort_keys=False))
        except OSError as exc:
            self.get_logger().error(f'cannot write summary_file {self._summary_file}: {exc}')

    def destroy_node(self) -> None:
        """Close the bag, then destroy the node."""
        self.close()
        super().destroy_node()


def main(argv: Sequence[str] | None = None) -> int:
    """Run one RecorderNode until SIGINT/SIGTERM or ``duration_s``; 0 ok, 1 error."""
    return run_node(lambda ctx: RecorderNode(context=ctx),
                    list(sys.argv if argv is None else argv))


if __name__ == '__main__':
    sys.exit(main())
