"""JointStateAdapterNode: a ros2_control bench's ``sensor_msgs/JointState`` -> EncoderBlocks.

Subscribes ``joint_states`` (JointState, reliable, keep last
:data:`~rv_te_bench.nodes.qos.JOINT_STATE_QUEUE_DEPTH`; QoS overridable by parameters).
Publishes ``bench/encoders`` (EncoderBlock, as the simulated bench does), ``bench/info``
(BenchInfo, transient-local, once, from the bench description file) and ``/diagnostics``.
The TE node, compensation node and recorder then run unchanged on a real bench.

All logic is in :mod:`rv_te_bench.core.joint_state`: header stamps give the sample times, a
stamp jump > 1.5 sample periods, a stamp going backwards, a missing joint or a non-finite
position closes the block and is reported (log, throttled; diagnostics) and the next block's
``seq`` skips one number, so the TE node and ``rv-te analyze`` see a ``seq_jump`` there,
never a splice. A malformed message is counted and logged, never fatal.

Joints that never arrive (a name that does not match the broadcaster's): when no sample of
both joints came ``joints_timeout_s`` after start, the adapter says which names it expected
and which the messages carry (log, ``/diagnostics`` ERROR) and ends with exit code 1, so the
session ends non-zero with that line instead of recording an empty bag.

The whole-reducer steps' channels (issue 38), when the bench description has
``loss_channels``: the drive (input) joint's effort x ``loss_channels.torque_in.
scale_nm_per_unit`` is the input torque, and the case temperature comes from a
``sensor_msgs/Temperature`` topic (``temperature_topic``; readings interpolated onto the
samples, held after the last one, none older than 10 s: NaN). Both go on ``bench/channels``
(``rv_te_msgs/BenchChannels``), one message with each EncoderBlock (the same seq, stamp and
sample count; published just before it), as the simulated bench publishes them.

Parameters left at their "from the description" value (empty joint names, 0 rate, 0 block
size, 0 counts per revolution, 0 effort scale) take the bench description's values.
"""

from __future__ import annotations

import dataclasses
import math
import sys
import time
from collections import deque
from typing import Any

import numpy as np
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.node import Node
from rclpy.qos_overriding_options import QoSOverridingOptions
from rv_te_msgs.msg import BenchChannels, BenchInfo, EncoderBlock
from sensor_msgs.msg import JointState, Temperature

from rv_te_bench.core.joint_state import (
    JointStateAssembler,
    JointStateBlock,
    JointStateConfig,
    JointStateGap,
)
from rv_te_bench.errors import ParameterFileError
from rv_te_bench.nodes import convert, qos
from rv_te_bench.nodes.common import (
    ERROR,
    OK,
    WARN,
    DropCounter,
    declare_from_specs,
    diagnostic_array,
    reject_invalid_changes,
    run_node,
)
from rv_te_bench.nodes.params.joint_state_adapter import PARAMS, JointStateAdapterParams
from rv_te_bench.params import params_record

#: A case temperature reading farther than this from a sample leaves it without one [ns].
_TEMP_MAX_AGE_NS = 10e9
#: Most blocks held while waiting for the session's subscribers (then the oldest go).
_MAX_HELD_BLOCKS = 10000


def build_config(p: JointStateAdapterParams) -> tuple[JointStateConfig, Any]:
    """The adapter's start-up: assembler config and BenchInfo fields from its parameters.

    Run by the node and by ``rv-te launch --check`` (the same checks).

    Returns:
        (:class:`JointStateConfig`, :class:`sim.bench.BenchInfoData` or None without a
        bench description).

    Raises:
        ParameterFileError: No sample rate, or counts without counts per revolution.
        BenchDescriptionError: The bench description file is invalid (file, key, rule).
        TeConfigError: An invalid combination (named by the core's validation).
    """
    desc = None
    if p.bench_description:
        from rv_te_bench.io.bench_description import load_bench_description

        desc = load_bench_description(p.bench_description)
    rate = p.sample_rate_hz or (desc.sample_rate_hz if desc is not None else 0.0)
    if not rate > 0:
        msg = ('sample_rate_hz is 0 and no bench_description gives it: set the expected '
               'JointState rate [Hz]')
        raise ParameterFileError(msg)
    block = p.block_size or (desc.block_size if desc is not None else 100)
    in_name = p.input_joint or (desc.joint_in_name if desc is not None else None) \
        or 'input_joint'
    heads = tuple(p.output_head_joints) or (desc.encoder_out.head_joints
                                             if desc is not None else ())
    out_name = p.output_joint or (heads[0] if heads else None) or (
        desc.joint_out_name if desc is not None else None) or 'output_joint'
    cpr = [p.counts_per_rev_in, p.counts_per_rev_out]
    if p.position_unit == 'counts':
        for k, (name, enc) in enumerate((('counts_per_rev_in', 'input'),
                                         ('counts_per_rev_out', 'output'))):
            if cpr[k] == 0 and desc is not None:
                cpr[k] = float((desc.encoder_in if k == 0 else desc.encoder_out)
                               .counts_per_rev or 0)
            if not cpr[k] > 0:
                msg = (f'position_unit counts needs {name} > 0 (or encoders.{enc}.'
                       f'counts_per_rev in the bench description), got {cpr[k]!r}')
                raise ParameterFileError(msg)
    scale = p.effort_scale
    if scale == 0 and desc is not None and desc.torque_sensor.present:
        scale = desc.torque_sensor.scale_nm_per_unit
    tol = p.pairing_tolerance_s if p.pairing_tolerance_s >= 0 else 0.25 / rate
    loss = dict(desc.loss_channels or {}) if desc is not None else {}
    scale_in = float(loss['torque_in'].get('scale_nm_per_unit', 1.0)) if 'torque_in' in loss \
        else 0.0
    config = JointStateConfig(
        input_joint=in_name, output_joint=out_name, sample_rate_hz=float(rate),
        block_size=int(block), position_unit=p.position_unit,
        counts_per_rev_in=float(cpr[0]), counts_per_rev_out=float(cpr[1]),
        wrap_in=p.wrap in {'input', 'both'}, wrap_out=p.wrap in {'output', 'both'},
        effort_scale=float(scale), input_effort_scale=scale_in, pairing_tolerance_s=float(tol),
        max_unpaired=int(p.max_unpaired), output_head_joints=_further_heads(heads, out_name))
    info = None
    if desc is not None:
        info = dataclasses.replace(desc.bench_info(), sample_rate_hz=float(rate),
                                   block_size=int(block))
    return config, info


def _further_heads(heads: tuple[str, ...], out_name: str) -> tuple[str, ...]:
    """Heads 1..N-1 of the output scale (head 0 is the output joint).

    Raises:
        ParameterFileError: The first head joint is not the output joint.
    """
    if not heads:
        return ()
    if heads[0] != out_name:
        msg = (f'output_head_joints must start with the output joint {out_name!r} (head 0), '
               f'got {list(heads)!r}')
        raise ParameterFileError(msg)
    return heads[1:]


def check_config(p: JointStateAdapterParams) -> None:
    """What the node checks at start (for ``rv-te launch --check``).

    Raises:
        ParameterFileError, TeConfigError: As :func:`build_config`.
    """
    build_config(p)


class JointStateAdapterNode(Node):
    """JointState (ros2_control) in, EncoderBlock + BenchInfo out; logic in the core."""

    def __init__(self, **kwargs: Any) -> None:
        """Declare parameters, read the bench description; ``kwargs`` go to ``Node``.

        Raises:
            InvalidParameterValueException, ParameterFileError, TeConfigError: Bad
                parameters or bench description (named), at start-up.
        """
        super().__init__('joint_state_adapter', **kwargs)
        self.p = params_record(JointStateAdapterParams, declare_from_specs(self, PARAMS))
        reject_invalid_changes(self, PARAMS)
        self.config, info = build_config(self.p)
        self.assembler = JointStateAssembler(self.config)
        self.bench_id = info.bench_id if info is not None else 'joint_states'
        self.drops = DropCounter(self)
        self.blocks_published = 0
        self.recent_gaps: deque[JointStateGap] = deque(maxlen=64)   # diagnostics and tests
        self._last_msg = time.monotonic()
        self._start = time.monotonic()
        #: Why the adapter ends with an error (joints that never came); '' while all is well.
        self.failure = ''
        self.exit_code = 0
        self.finished = False
        self._finish_at: float | None = None
        self._held: deque[tuple[BenchChannels | None, EncoderBlock]] | None = (
            deque() if self.p.wait_for_nodes else None)
        self.pub_blocks = self.create_publisher(EncoderBlock, 'bench/encoders', qos.ENCODER_QOS)
        loss: dict[str, Any] = {}
        if info is not None:
            from rv_te_bench.acceptance._loss_results import bench_channels

            loss = bench_channels(info)
        self.has_torque_in = 'torque_in' in loss
        self.has_temperature = 'temperature' in loss
        self._temps: deque[tuple[int, float]] = deque(maxlen=256)   # (stamp ns, degC)
        self.pub_channels = None
        if self.has_torque_in or self.has_temperature:
            self.pub_channels = self.create_publisher(BenchChannels, 'bench/channels',
                                                      qos.ENCODER_QOS)
        if self.has_temperature:
            self.create_subscription(Temperature, self.p.temperature_topic, self._on_temp,
                                     qos.ENCODER_QOS)
        self.pub_info = self.create_publisher(BenchInfo, 'bench/info', qos.LATCHED_QOS)
        self.pub_diag = self.create_publisher(DiagnosticArray, '/diagnostics',
                                              qos.DIAGNOSTICS_QOS)
        self.create_subscription(
            JointState, 'joint_states', self._on_joint_state, qos.JOINT_STATE_QOS,
            qos_overriding_options=QoSOverridingOptions.with_default_policies())
        self.create_timer(self.p.idle_flush_s / 2.0, self._on_idle)
        self.create_timer(self.p.diagnostics_period_s, self._publish_diagnostics)
        self._joints_timer = self.create_timer(0.2, self._check_joints)
        self._wait_timer = (self.create_timer(0.1, self._check_subscribers)
                            if self._held is not None else None)
        c = self.config
        if info is not None:
            self.pub_info.publish(convert.make_bench_info(info, self.get_clock().now().to_msg()))
        else:
            self.get_logger().warning('no bench_description: bench/info is not published '
                                      '(give the TE node its gear_ratio parameter)')
        self.get_logger().info(
            f'joint_states -> bench/encoders: {c.input_joint!r} / {c.output_joint!r}, '
            f'{c.sample_rate_hz:g} Hz, blocks of {c.block_size}, {c.position_unit}, wrap '
            f'{self.p.wrap}, pairing tolerance {c.pairing_tolerance_s:.3g} s')

    # -- data path (lean: one sample per message is the usual case) ------------------------
    def _on_temp(self, msg: Temperature) -> None:
        t = float(msg.temperature)
        if not math.isfinite(t):
            self.drops.drop('malformed', f'case temperature {t!r} is not finite')
            return
        self._temps.append((msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec,
                            t))

    def _channels(self, b: JointStateBlock) -> BenchChannels:
        """The block's input torque and case temperature (bench/channels)."""
        n = b.theta_in_rad.size
        temp = np.zeros(0)
        if self.has_temperature:
            temp = np.full(n, np.nan)
            if self._temps:
                ts = np.array([x[0] for x in self._temps], dtype=np.float64)
                vs = np.array([x[1] for x in self._temps], dtype=np.float64)
                t = (b.stamp_ns - ts[0]) + b.time_offset_s * 1e9   # ns after the first
                rel = ts - ts[0]
                temp = np.interp(t, rel, vs)
                k = np.searchsorted(rel, t)
                near = np.minimum(np.abs(t - rel[np.clip(k - 1, 0, rel.size - 1)]),
                                  np.abs(t - rel[np.clip(k, 0, rel.size - 1)]))
                temp[near > _TEMP_MAX_AGE_NS] = np.nan
        t_in = b.torque_in_nm if self.has_torque_in and b.torque_in_nm.size == n \
            else (np.full(n, np.nan) if self.has_torque_in else np.zeros(0))
        msg = BenchChannels(seq=int(b.seq), torque_in_nm=np.asarray(t_in, dtype=np.float64)
                            .tolist(), temp_case_degc=temp.tolist())
        msg.header.stamp = Time(sec=b.stamp_ns // 1_000_000_000,
                                nanosec=b.stamp_ns % 1_000_000_000)
        msg.header.frame_id = self.bench_id
        return msg

    def _on_joint_state(self, msg: JointState) -> None:
        self._last_msg = time.monotonic()
        stamp = msg.header.stamp
        try:
            items = self.assembler.push(stamp.sec * 1_000_000_000 + stamp.nanosec, msg.name,
                                        msg.position, msg.effort)
        except Exception as exc:  # noqa: BLE001 - a malformed message must never stop spin
            self.drops.drop('malformed', f'{type(exc).__name__}: {exc}')
            return
        if items:
            self._emit(items)

    def _emit(self, items: tuple[JointStateBlock | JointStateGap, ...]) -> None:
        for item in items:
            if isinstance(item, JointStateBlock):
                self._publish_block(item)
            else:
                self.recent_gaps.append(item)
                self.get_logger().warning(
                    f'gap ({item.reason}): {item.detail}; {item.samples_dropped} sample(s) '
                    f'dropped, {item.samples_missing} missing, stamps {item.stamp_before_ns} '
                    f'-> {item.stamp_after_ns} ns, next block seq {item.seq_after}; totals '
                    f'{self.assembler.counters["gaps"]} gaps', throttle_duration_sec=5.0)

    def _publish_block(self, b: JointStateBlock) -> None:
        msg = convert.make_encoder_block(
            bench_id=self.bench_id, seq=b.seq, stamp_s=b.stamp_s,
            sample_rate_hz=b.sample_rate_hz, time_offset_s=b.time_offset_s,
            theta_in_rad=b.theta_in_rad, theta_out_rad=b.theta_out_rad,
            torque_out_nm=b.torque_out_nm if b.torque_out_nm.size else None,
            theta_out_heads_rad=b.theta_out_heads_rad if b.out_head_ids else None,
            out_head_ids=b.out_head_ids or None)
        msg.header.stamp = Time(sec=b.stamp_ns // 1_000_000_000,
                                nanosec=b.stamp_ns % 1_000_000_000)   # exact, not via float
        ch = self._channels(b) if self.pub_channels is not None else None
        if self._held is not None:
            if len(self._held) >= _MAX_HELD_BLOCKS:
                self._held.popleft()
                self.drops.drop('held_overflow', f'kept the last {_MAX_HELD_BLOCKS} blocks '
                                'while waiting for subscribers')
            self._held.append((ch, msg))
            return
        if ch is not None and self.pub_channels is not None:
            self.pub_channels.publish(ch)   # before its block: a reader pairs them by seq
        self.pub_blocks.publish(msg)
        self.blocks_published += 1

    @property
    def busy(self) -> bool:
        """Blocks held for the session's readers. A stop waits for them (run_node: work
        under way, FINISH_MAX_S at most): a short fast session's bench can be done before
        the recorder subscribed to bench/encoders, and the held blocks were lost with the
        adapter (a bag of 0 blocks, 1 full suite in 5 once the fixed 2 s after the bench
        went)."""
        return bool(self._held)

    def _check_subscribers(self) -> None:
        """Release the held blocks once the waited-for nodes subscribe and our writers
        matched them (or on time-out)."""
        if self._held is None:
            return
        ns = self.get_namespace()
        have = {i.node_name for i in self.get_subscriptions_info_by_topic(
            self.pub_blocks.topic_name) if i.node_namespace == ns}
        missing = sorted(set(self.p.wait_for_nodes) - have)
        if not missing:
            missing = self._not_matched(ns)
        waited = time.monotonic() - self._start
        if missing and waited < self.p.wait_timeout_s:
            return
        if missing:
            self.get_logger().warning(f'publishing without {missing} on '
                                      f'{self.pub_blocks.topic_name} after {waited:.1f} s')
        self._release()

    def _not_matched(self, ns: str) -> list[str]:
        """What is still missing once the waited-for nodes subscribe to bench/encoders: our
        writers matched to the readers in the graph (a block sent before is lost to them),
        and, where blocks have channels, the session's recorder on bench/channels and
        matched. The recorder subscribes to each topic as it finds it: the first channels,
        sent once it had bench/encoders, went unrecorded, and ``rv-te unit-report`` could
        not compute a temperature rise from the bag that the live test had."""
        out = []
        for pub in (self.pub_blocks, self.pub_channels):
            if pub is not None and pub.get_subscription_count() < len(
                    self.get_subscriptions_info_by_topic(pub.topic_name)):
                out.append(f'({pub.topic_name} matching)')
        if self.pub_channels is not None and 'recorder' in self.p.wait_for_nodes and not any(
                i.node_name == 'recorder' and i.node_namespace == ns
                for i in self.get_subscriptions_info_by_topic(self.pub_channels.topic_name)):
            out.append(f'recorder ({self.pub_channels.topic_name})')
        return out

    def _release(self) -> None:
        held, self._held = self._held, None
        if self._wait_timer is not None:
            self._wait_timer.cancel()
        for ch, msg in held or ():
            if ch is not None and self.pub_channels is not None:
                self.pub_channels.publish(ch)
            self.pub_blocks.publish(msg)
            self.blocks_published += 1

    def joints_missing(self) -> str:
        """What is wrong while no sample of both joints has come ('' once one has)."""
        if self.assembler.has_samples:
            return ''
        c = self.config
        expected = [c.input_joint, c.output_joint]
        seen = self.assembler.names_seen
        n = self.assembler.counters['messages']
        topic = self.resolve_topic_name('joint_states')
        if not n:
            return (f'no JointState message on {topic}: expected joints {expected} '
                    '(is joint_state_broadcaster running, in this namespace and domain?)')
        missing = [j for j in expected if j not in seen]
        why = (f'{missing} never in a message' if missing else
               'both named but never paired (stamps or positions: see the gaps)')
        return (f'no sample of joints {expected} from {n} JointState message(s) on {topic}: '
                f'{why}; the messages carry {list(seen)} (set input_joint / output_joint '
                'or the bench description\'s joints)')

    def _check_joints(self) -> None:
        """After ``joints_timeout_s`` without a sample of both joints: fail, naming them."""
        now = time.monotonic()
        if self._finish_at is not None:
            if now >= self._finish_at:
                self.finished = True   # (run_node ends the process with exit_code)
            return
        if self.assembler.has_samples:
            self._joints_timer.cancel()
            return
        waited = now - self._start
        if not self.p.joints_timeout_s or waited < self.p.joints_timeout_s:
            return
        self.failure = (f'after {waited:.1f} s (joints_timeout_s '
                        f'{self.p.joints_timeout_s:g}) {self.joints_missing()}')
        self.exit_code = 1
        self.get_logger().error(self.failure)
        self._publish_diagnostics()
        # one more diagnostics period so subscribers get the ERROR, then the process ends
        self._finish_at = now + min(1.0, self.p.diagnostics_period_s)

    def _on_idle(self) -> None:
        """The stream paused: publish the open block so the TE node is not kept waiting."""
        if self.assembler.pending_samples and \
                time.monotonic() - self._last_msg >= self.p.idle_flush_s:
            self._emit(self.assembler.flush())

    def _publish_diagnostics(self) -> None:
        counters = self.assembler.counters
        values: dict[str, Any] = {**counters, 'blocks_published': self.blocks_published,
                                  'dropped_malformed_messages': self.drops.total}
        if self.recent_gaps:
            g = self.recent_gaps[-1]
            values.update({'last_gap_reason': g.reason,
                           'last_gap_stamp_before_ns': g.stamp_before_ns,
                           'last_gap_stamp_after_ns': g.stamp_after_ns})
        bad = counters['gaps'] or self.drops.total
        message = (f'{counters["gaps"]} gaps, {self.drops.total} malformed messages' if bad
                   else f'{self.blocks_published} blocks')
        level = WARN if bad else OK
        if not self.assembler.has_samples:
            c = self.config
            values.update({'expected_joints': f'{c.input_joint}, {c.output_joint}',
                           'seen_joints': ', '.join(self.assembler.names_seen)})
            if self.failure:
                level, message = ERROR, self.failure
            elif time.monotonic() - self._start >= min(5.0, self.p.joints_timeout_s or 5.0):
                level, message = WARN, f'waiting: {self.joints_missing()}'
        self.pub_diag.publish(diagnostic_array(self, 'joint_state_adapter', level, message,
                                               values))

    def destroy_node(self) -> None:
        """Publish the open block and report an open gap before going."""
        try:
            self._emit(self.assembler.finish())
            self._release()
            self._publish_diagnostics()
        except Exception as exc:  # noqa: BLE001 - shutting down: report, do not raise
            self.get_logger().warning(f'final flush failed: {exc}')
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    """Run the adapter in its own process."""
    return run_node(lambda ctx: JointStateAdapterNode(context=ctx),
                    list(sys.argv if args is None else args))


__all__ = ['PARAMS', 'JointStateAdapterNode', 'build_config', 'check_config', 'main']

if __name__ == '__main__':
    sys.exit(main())
