"""DashboardBridge: the node that subscribes to a session's topics for the live page.

Every subscription is raw (CDR bytes): encoder blocks are decoded straight into numpy
(:func:`rv_te_bench.io.bag_reader.decode_encoder_block`, several times faster than rclpy's
deserialisation), the small messages with rclpy, and the same bytes go unchanged to the
Foxglove WebSocket relay (:mod:`rv_te_bench.dashboard.foxglove_relay`), so a Foxglove or
Lichtblick user sees the topics as a bag holds them. A callback only converts and appends
to the :class:`~rv_te_bench.dashboard.model.DashboardModel`: it never waits for a browser.
A malformed message is counted and logged (throttled), never fatal.

The node also watches the ROS graph once a second: a session node that leaves the graph
while the bench still sends is reported as gone (crashed), and a bench that stops sending
marks the session finished.
"""

from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING, Any

from diagnostic_msgs.msg import DiagnosticArray
from rclpy.node import Node
from rclpy.serialization import deserialize_message
from rv_te_msgs.action import RunTestPlan
from rv_te_msgs.msg import (
    BenchInfo,
    CompensationAdvice,
    EncoderBlock,
    TePlot,
    TeSpectrum,
    TestReport,
    TestStep,
    TransmissionError,
)

from rv_te_bench.dashboard.model import DashboardModel, EncoderSamples
from rv_te_bench.errors import BagError
from rv_te_bench.io.bag_reader import decode_encoder_block
from rv_te_bench.nodes import convert, qos
from rv_te_bench.nodes.common import DropCounter
from sim.bench_info import BenchInfoData

if TYPE_CHECKING:
    from collections.abc import Callable

    from rv_te_bench.dashboard.foxglove_relay import FoxgloveRelay

__all__ = ['SESSION_NODES', 'TOPICS', 'DashboardBridge']

#: (relative topic, message class, type name, QoS) the page and the relay take.
TOPICS: tuple[tuple[str, Any, str, Any], ...] = (
    ('bench/info', BenchInfo, 'rv_te_msgs/msg/BenchInfo', qos.LATCHED_QOS),
    ('bench/encoders', EncoderBlock, 'rv_te_msgs/msg/EncoderBlock', qos.ENCODER_QOS),
    ('te/samples', TransmissionError, 'rv_te_msgs/msg/TransmissionError', qos.TE_SAMPLES_QOS),
    ('te/statistics', TransmissionError, 'rv_te_msgs/msg/TransmissionError', qos.LATCHED_QOS),
    ('te/spectrum', TeSpectrum, 'rv_te_msgs/msg/TeSpectrum', qos.LATCHED_QOS),
    ('te/plot', TePlot, 'rv_te_msgs/msg/TePlot', qos.TE_SAMPLES_QOS),
    ('compensation/advice', CompensationAdvice, 'rv_te_msgs/msg/CompensationAdvice',
     qos.LATCHED_QOS),
    ('test/step', TestStep, 'rv_te_msgs/msg/TestStep', qos.TE_SAMPLES_QOS),
    ('test/report', TestReport, 'rv_te_msgs/msg/TestReport', qos.LATCHED_QOS),
    ('/diagnostics', DiagnosticArray, 'diagnostic_msgs/msg/DiagnosticArray',
     qos.DIAGNOSTICS_QOS),
)
#: Nodes of a session whose disappearance the page reports.
SESSION_NODES = ('bench', 'te_node', 'compensation', 'recorder', 'test_sequencer',
                 'joint_state_adapter')
#: The bench counts as stopped after this long without a block [s].
IDLE_FINISHED_S = 3.0


def _stamp(h: Any) -> float:
    return convert.stamp_to_s(h.stamp)


def _stats(s: Any) -> dict[str, float]:
    return {'pp_rad': s.pp_rad, 'amplitude_rad': s.amplitude_rad, 'mean_rad': s.mean_rad,
            'std_rad': s.std_rad, 'revolutions': s.revolutions_covered,
            'n_samples': int(s.n_samples)}


class DashboardBridge(Node):
    """Subscribes to one session's topics and feeds the page's model (module docstring)."""

    def __init__(self, model: DashboardModel, *, relay: FoxgloveRelay | None = None,
                 **kwargs: Any) -> None:
        """``kwargs`` go to ``Node`` (context, namespace)."""
        super().__init__('dashboard', **kwargs)
        self.model = model
        self.relay = relay
        self.drops = DropCounter(self)
        self._seen_nodes: set[str] = set()
        handlers: dict[str, Callable[[Any], None]] = {
            'bench/info': self._on_info, 'bench/encoders': self._on_block,
            'te/statistics': self._on_stats, 'te/spectrum': self._on_spectrum,
            'compensation/advice': self._on_advice, 'test/step': self._on_step,
            'test/report': self._on_report, '/diagnostics': self._on_diagnostics}
        for topic, cls, type_name, profile in TOPICS:
            name = self.resolve_topic_name(topic)
            handler = handlers.get(topic)
            if handler is None and relay is None:
                continue   # only the relay wants te/samples and te/plot
            if relay is not None:
                relay.add_channel(name, type_name)
            self.create_subscription(cls, topic, self._make_callback(name, cls, handler),
                                     profile, raw=True)
        feedback = RunTestPlan.Impl.FeedbackMessage
        self.create_subscription(feedback, 'run_test_plan/_action/feedback',
                                 self._make_callback('feedback', feedback, self._on_feedback),
                                 10, raw=True)
        self.create_timer(1.0, self._watch)

    def _make_callback(self, name: str, cls: Any,
                       handler: Callable[[Any], None] | None) -> Callable[[bytes], None]:
        relay = self.relay
        decode = cls is not EncoderBlock

        def on_message(data: bytes) -> None:
            if relay is not None and name != 'feedback':
                relay.log(name, data)
            if handler is None:
                return
            try:
                handler(deserialize_message(data, cls) if decode else data)
            except (ValueError, TypeError, KeyError, BagError) as exc:
                self.drops.drop('malformed', f'{name}: {exc}')

        return on_message

    # -- callbacks (convert, hand over; no maths) -------------------------------------------
    def _on_info(self, m: BenchInfo) -> None:
        # every field of the bench's record (BenchInfoData: the one field list) but the
        # settings YAML, which the page does not show
        info = BenchInfoData.from_message(m).message_values()
        del info['parameters_yaml']
        self.model.on_bench_info(info)

    def _on_block(self, data: bytes) -> None:
        b = decode_encoder_block(data)
        self.model.on_encoders(EncoderSamples(
            seq=b.seq, stamp_s=b.stamp_s, time_offset_s=b.time_offset_s,
            theta_in_rad=b.theta_in_rad, theta_out_rad=b.theta_out_rad,
            torque_out_nm=b.torque_out_nm))

    def _on_stats(self, m: TransmissionError) -> None:
        self.model.on_window({'index': int(m.window_index), 'complete': bool(m.window_complete),
                              'stamp_s': _stamp(m.header), **_stats(m.window),
                              'cumulative_pp_rad': m.cumulative.pp_rad, 'gaps': int(m.gaps)})

    def _on_spectrum(self, m: TeSpectrum) -> None:
        self.model.on_spectrum({
            'window_index': int(m.window_index), 'crank_hz': m.crank_hz,
            'output_hz': m.output_hz, 'revolutions': m.revolutions_covered,
            'lines': [{'output_order': ln.output_order, 'crank_order': ln.crank_order,
                       'frequency_hz': ln.frequency_hz, 'amplitude_rad': ln.amplitude_rad,
                       'phase_rad': ln.phase_rad, 'label': ln.label} for ln in m.lines]})

    def _on_advice(self, m: CompensationAdvice) -> None:
        self.model.on_advice({
            'method': m.method, 'preset': m.preset, 'summary': m.summary,
            'te_metric': m.te_metric, 'te_before_rad': m.te_before_rad,
            'te_after_rad': m.te_after_rad,
            'modifications': [{'factor': x.factor, 'symbol': x.symbol, 'unit': x.unit,
                               'current_value': x.current_value,
                               'recommended_value': x.recommended_value}
                              for x in m.modifications]})

    def _on_step(self, m: TestStep) -> None:
        self.model.on_step({
            'serial': m.serial, 'step_index': int(m.step_index),
            'step_count': int(m.step_count), 'step_name': m.step_name,
            'step_kind': m.step_kind, 'state': m.state, 'first_seq': int(m.first_seq),
            'last_seq': int(m.last_seq), 'result_yaml': m.result_yaml})

    def _on_report(self, m: TestReport) -> None:
        self.model.on_report({
            'serial': m.serial, 'operator_name': m.operator_name, 'plan_name': m.plan_name,
            'verdict': m.verdict, 'reason': m.reason, 'plan_yaml': m.plan_yaml,
            'tolerance_yaml': m.tolerance_yaml, 'final': bool(m.report_json),
            'metrics': [{'name': x.name, 'step': x.step, 'unit': x.unit, 'value': x.value,
                         'limit_min': x.limit_min, 'limit_max': x.limit_max,
                         'margin': x.margin, 'verdict': x.verdict, 'source': x.source}
                        for x in m.metrics]})

    def _on_feedback(self, m: Any) -> None:
        f = m.feedback
        self.model.on_feedback({
            'step_index': int(f.step_index), 'step_count': int(f.step_count),
            'step_name': f.step_name, 'step_kind': f.step_kind,
            'step_progress': f.step_progress, 'plan_progress': f.plan_progress,
            'live_metric': f.live_metric, 'live_value': f.live_value, 'message': f.message})

    def _on_diagnostics(self, m: DiagnosticArray) -> None:
        ns = self.get_namespace().rstrip('/')
        for st in m.status:
            node_fqn, _, what = st.name.partition(': ')
            values = {kv.key: kv.value for kv in st.values}
            level = st.level[0] if isinstance(st.level, bytes) else int(st.level)
            if what == 'recorder' and self._recorder_ours(node_fqn, values):
                self.model.on_recorder(_recorder_status(st.message, level, values))
                continue
            node_ns, _, node = node_fqn.rpartition('/')
            if node_ns != ns or node not in SESSION_NODES:
                continue
            self.model.on_node_status(node, {
                'level': level, 'message': st.message, 'what': what,
                'gaps': _int(values.get('gaps_reported', values.get('gaps', 0))),
                'dropped': _int(values.get('dropped_total', 0))})

    def _recorder_ours(self, node_fqn: str, values: dict[str, str]) -> bool:
        """A recorder status of this namespace (its name, or its topics' namespace)."""
        ns = self.get_namespace().rstrip('/')
        if node_fqn.startswith('/'):
            return node_fqn.rpartition('/')[0] == ns
        encoder_topic = self.resolve_topic_name('bench/encoders')
        return any(k.startswith(encoder_topic + ' ') for k in values) or not any(
            k.endswith(' count') for k in values)

    # -- graph watch ------------------------------------------------------------------------
    def _watch(self) -> None:
        ns = self.get_namespace()
        present = {n for n, node_ns in self.get_node_names_and_namespaces()
                   if node_ns == ns and n in SESSION_NODES}
        wall = time.time()
        last = self.model.last_block_wall_s
        sending = math.isfinite(last) and wall - last < IDLE_FINISHED_S
        for n in self._seen_nodes - present:
            if n == 'recorder':
                self.model.on_recorder_gone()
            if sending and n != 'bench':
                self.model.on_node_status(n, {'gone': True, 'message': 'left the graph while '
                                              'the bench was sending (crashed?)'})
        for n in present - self._seen_nodes:
            self.model.on_node_status(n, {'gone': False, 'level': 0, 'message': 'running'})
        self._seen_nodes = present
        if math.isfinite(last) and not sending and self.model.state == 'running':
            self.model.set_state(f'finished (no encoder block for {IDLE_FINISHED_S:g} s)')


def _int(x: Any) -> int:
    try:
        return int(float(x))
    except (TypeError, ValueError):
        return 0


def _recorder_status(message: str, level: int, values: dict[str, str]) -> dict[str, Any]:
    """The recorder's diagnostics as the page shows them (bag, messages, losses, size)."""
    counts = {k[:-6]: _int(v) for k, v in values.items() if k.endswith(' count')}
    out: dict[str, Any] = {
        'message': message, 'level': level, 'bag': values.get('bag', ''),
        'lost_messages': _int(values.get('lost_messages')),
        'write_errors': _int(values.get('write_errors')), 'counts': counts,
        'messages': sum(counts.values()),
        'missing_blocks': sum(_int(v) for k, v in values.items()
                              if k.endswith(' missing_blocks')),
        'gaps': sum(_int(v) for k, v in values.items() if k.endswith(' gaps'))}
    out['size_bytes'] = _bag_size(out['bag'])
    return out


def _bag_size(bag: str) -> int | None:
    """Bytes of the bag folder's files so far (None when it is not on this machine)."""
    from pathlib import Path

    try:
        p = Path(bag)
        if not bag or not p.exists():
            return None
        files = [p] if p.is_file() else list(p.iterdir())
        return sum(f.stat().st_size for f in files if f.is_file())
    except OSError:
        return None
