"""TeNode: transmission error online (Wang 2020 Eq. 22), window statistics and order spectra.

Subscribes ``bench/encoders`` (EncoderBlock) and ``bench/info`` (BenchInfo, transient-local).
Publishes ``te/samples`` (TransmissionError, decimated TE for live display), ``te/plot``
(TePlot, flat scalars in arcmin for plot panels, at ``plot_rate_hz``), ``te/statistics``
(TransmissionError with ``window_complete`` when a window closes, latched), ``te/spectrum``
(TeSpectrum, one per complete window) and ``/diagnostics``.

The gear ratio and orders come from BenchInfo, or from parameters for a real bench
(``gear_ratio`` > 0 makes the parameters win). All maths is in :mod:`rv_te_bench.core.stream`;
a bad block is counted, logged (throttled) and skipped, never fatal.
"""

from __future__ import annotations

import math
import sys
import time
from collections import deque
from dataclasses import replace
from typing import Any

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.node import Node
from rv_te_msgs.msg import BenchInfo, EncoderBlock, TePlot, TeSpectrum, TransmissionError
from std_msgs.msg import String

from rv_te_bench.core.head_combine import HeadCombiner
from rv_te_bench.core.orders import OrderSet
from rv_te_bench.core.stream import StreamingTeAnalyzer
from rv_te_bench.core.stream_records import StreamUpdate, TeAnalysisConfig
from rv_te_bench.core.te_zero import EncoderZero, TeZero
from rv_te_bench.errors import EncoderCalibrationError, HeadLayoutError, RvTeError
from rv_te_bench.nodes import convert, qos
from rv_te_bench.nodes.backpressure import BlockAcks
from rv_te_bench.nodes.common import (
    DRAIN_MAX_S,
    ERROR,
    OK,
    WARN,
    DropCounter,
    declare_from_specs,
    diagnostic_array,
    launcher_gone,
    reject_invalid_changes,
    run_node,
    wait_for_readers,
)
from rv_te_bench.nodes.params.te import PARAMS, TeParams
from rv_te_bench.params import params_changed, params_record
from rv_te_bench.safe_yaml import dump_ros_yaml
from sim.bench_info import BenchInfoData

_MAX_PENDING_BLOCKS = 1000   # blocks kept while waiting for bench/info



def load_calibrations(p: TeParams) -> dict[str, Any]:
    """The calibration files a TE node's parameters name, read and checked (``'in'`` /
    ``'out'`` -> EncoderCalibration). Run by the node and by ``rv-te launch --check``.

    Raises:
        EncoderCalibrationError: A file that cannot be read or is invalid (one line).
    """
    from rv_te_bench.io.calibration_file import load_encoder_calibration

    files = {'in': p.encoder_in_calibration, 'out': p.encoder_out_calibration}
    return {side: load_encoder_calibration(path) for side, path in files.items() if path}


def initial_orders(p: TeParams) -> OrderSet | None:
    """The orders a TE node configured by parameters starts with (None: from bench/info).

    Run by the node and by ``rv-te launch --check`` (the same checks).

    Raises:
        TeConfigError: An invalid ratio / crank / mesh combination or window.
    """
    if not p.gear_ratio > 0:
        return None
    cpo = float(p.crank_per_output)
    if cpo == 0.0 and float(p.crank_per_input) != 0.0:
        cpo = OrderSet.crank_per_output_of(p.crank_per_input, p.gear_ratio)
    orders = OrderSet(gear_ratio=p.gear_ratio, crank_per_output=cpo,
                      mesh_orders_out=tuple(p.mesh_orders),
                      mesh_labels=tuple(f'mesh {o:g} f_out' for o in p.mesh_orders),
                      n_crank_harmonics=p.n_crank_harmonics)
    TeAnalysisConfig(orders=orders, window_revolutions=float(p.window_revolutions),
                     decimated_rate_hz=p.decimated_rate_hz)
    return orders


class TeNode(Node):
    """Online TE analysis on top of :class:`StreamingTeAnalyzer`."""

    #: A stopping TE node takes every block already queued for it (run_node's drain).
    drain_max_s = DRAIN_MAX_S

    def __init__(self, **kwargs: Any) -> None:
        """Declare parameters, create topics; ``kwargs`` go to ``Node`` (context, overrides)."""
        super().__init__('te_node', **kwargs)
        self.p = params_record(TeParams, declare_from_specs(self, PARAMS))
        orders = initial_orders(self.p)   # a bad combination stops the node here
        self.calibrations = load_calibrations(self.p)   # a bad file stops it here too
        self.combiner: HeadCombiner | None = None
        self.heads_problem = ''      # why a calibration or the averaging is not applied
        self._heads_used: Any = None
        reject_invalid_changes(self, PARAMS)
        self.add_post_set_parameters_callback(self._on_params_set)
        self.drops = DropCounter(self)
        self.analyzer: StreamingTeAnalyzer | None = None
        self.zero: TeZero | None = None           # the TE's zero (core.te_zero)
        self._declared_zero: EncoderZero | None = None
        self.bench_id = ''
        self._gaps_total = 0
        self.last_gap = ''   # the latest gap's detail (when and how long), for diagnostics
        self._seq_samples = 0
        self._seq_stats = 0
        self._latency_ms: list[float] = []
        self._blocks = 0
        self._last_window: Any = None
        self._first_seq: int | None = None
        self._last_seq: int | None = None   # the last block analysed, acknowledged (fast mode)
        # blocks that arrive before the gear ratio is known (bench/info is latched but may
        # land after the first blocks): kept, bounded, and analysed once configured
        self._pending: deque[EncoderBlock | bytes] = deque()
        self.recent_windows: deque[Any] = deque(maxlen=64)  # for diagnostics and tests
        # reliable: the compensation node identifies the unit from these samples and the
        # recorder keeps them; best-effort viewers are still compatible
        self.pub_samples = self.create_publisher(TransmissionError, 'te/samples',
                                                 qos.TE_SAMPLES_QOS)
        # flat scalars for plot panels; kept for late joiners like te/samples (the recorder)
        self.pub_plot = self.create_publisher(TePlot, 'te/plot', qos.TE_SAMPLES_QOS)
        self._last_plot_s = -math.inf
        self._last_complete: Any = None
        self.pub_stats = self.create_publisher(TransmissionError, 'te/statistics',
                                               qos.LATCHED_QOS)
        self.pub_spectrum = self.create_publisher(TeSpectrum, 'te/spectrum', qos.LATCHED_QOS)
        self.pub_diag = self.create_publisher(DiagnosticArray, '/diagnostics',
                                              qos.DIAGNOSTICS_QOS)
        # how the angles are formed from the read heads (and the calibration), latched:
        # the recorder keeps it in the bag
        self.pub_heads = self.create_publisher(String, 'te/encoder_heads', qos.LATCHED_QOS)
        self.create_subscription(BenchInfo, 'bench/info', self._on_info, qos.LATCHED_QOS)
        # raw: the CDR bytes are decoded straight into numpy arrays (decode_encoder_block,
        # the bag reader's); no message object per block (issue 41 item 4)
        self.create_subscription(EncoderBlock, 'bench/encoders', self._on_block,
                                 qos.ENCODER_QOS, raw=True)
        self.create_timer(self.p.diagnostics_period_s, self._publish_diagnostics)
        # a fast bench waits for the analysis; a one-process session for its last block
        self.block_acks = BlockAcks(self, lambda: self._last_seq)
        if orders is not None:
            self._crank_per_output()   # warns when the deprecated spelling is used
            self._configure(orders)

    def _crank_per_output(self) -> float:
        """crank_per_output, or from the deprecated crank_per_input (with a warning)."""
        cpo = float(self.p.crank_per_output)
        old = float(self.p.crank_per_input)
        if old != 0.0:
            derived = OrderSet.crank_per_output_of(old, self.p.gear_ratio)
            use = cpo if cpo > 0.0 else derived
            self.get_logger().warning(
                f"parameter 'crank_per_input' is deprecated: use crank_per_output "
                f'(= |crank_per_input| x gear_ratio = {derived:.6g}); using {use:.6g}')
            return use
        return cpo

    # -- configuration --------------------------------------------------------------------
    def _configure(self, orders: OrderSet) -> None:
        config = TeAnalysisConfig(orders=orders,
                                  window_revolutions=float(self.p.window_revolutions),
                                  decimated_rate_hz=self.p.decimated_rate_hz)
        if self.zero is None or self.zero.reference is None or \
                self.zero.gear_ratio != orders.gear_ratio:
            self.zero = TeZero(self.p.te_zero, gear_ratio=orders.gear_ratio,
                               declared=self._declared_zero)
        if self.analyzer is None:
            self.analyzer = StreamingTeAnalyzer(config)
            pending, self._pending = self._pending, deque()
            for msg in pending:
                self._on_block(msg)
        else:
            self._publish_windows(self.analyzer.flush())
            self.analyzer.reconfigure(config)
        self.get_logger().info(
            f'TE analysis configured: i={orders.gear_ratio:.6g}, '
            f'crank/output={orders.crank_per_output:.6g}, '
            f'window={self.p.window_revolutions:g} rev')

    def _on_params_set(self, params: list[Any]) -> None:
        self.p = params_changed(self.p, {prm.name: prm.value for prm in params})
        if self.analyzer is not None and any(p.name == 'decimated_rate_hz' for p in params):
            self.analyzer.set_decimated_rate(self.p.decimated_rate_hz)  # window stays

    def _on_info(self, msg: BenchInfo) -> None:
        from rv_te_bench.io.bench_record import encoder_zero_of

        self.bench_id = msg.bench_id
        try:
            info = BenchInfoData.from_message(msg)
        except (ValueError, TypeError) as exc:
            self.drops.drop('bad_bench_info', str(exc))
            return
        self._configure_heads(info)
        self._declared_zero = encoder_zero_of(info)
        if self.zero is not None and self.zero.reference is None:
            self.zero = TeZero(self.p.te_zero, gear_ratio=self.zero.gear_ratio,
                               declared=self._declared_zero)   # no sample referred yet
        if self.p.gear_ratio > 0:
            return  # parameters win (real bench)
        try:
            orders = OrderSet.from_bench_info(info, self.p.n_crank_harmonics)
        except (ValueError, TypeError) as exc:
            self.drops.drop('bad_bench_info', str(exc))
            return
        if self.analyzer is not None and self.analyzer.config.orders == orders:
            return
        self._configure(orders)

    def _configure_heads(self, info: BenchInfoData) -> None:
        """The head combination of this bench; a calibration of another scale or head
        angles that cannot be averaged are reported (log, diagnostics, te/encoder_heads)
        and left out: the TE goes on from what can be used (nothing is lost)."""
        mode = self.p.heads_mode
        cal = {f'calibration_{k}': v for k, v in self.calibrations.items()}
        problems = []
        try:
            combiner = HeadCombiner(info, mode=mode, **cal)
        except (EncoderCalibrationError, HeadLayoutError) as exc:
            problems.append(str(exc))
            try:   # without the calibrations
                combiner = HeadCombiner(info, mode=mode)
            except HeadLayoutError as exc2:
                problems.append(str(exc2))
                combiner = HeadCombiner(replace(info, encoder_in_head_angles_rad=(),
                                                encoder_out_head_angles_rad=()), mode=mode)
        self.combiner = combiner
        self.heads_problem = '; '.join(problems)
        for text in problems:
            self.get_logger().error(f'encoder heads: {text}; not applied, the TE goes on '
                                    'without it')
        plain = {**combiner.describe(), 'problem': self.heads_problem}
        self.pub_heads.publish(String(data=dump_ros_yaml(plain)))
        self.get_logger().info(
            f"encoder heads: output {combiner.scales['out'].describe()}")

    # -- data path ------------------------------------------------------------------------
    def _on_block(self, msg: EncoderBlock | bytes) -> None:
        """One block, as a message or raw (serialised CDR, the subscription's form)."""
        t_arrival = time.perf_counter()
        if self.analyzer is None:
            if len(self._pending) >= _MAX_PENDING_BLOCKS:
                self._pending.popleft()
                self.drops.drop('no_config', 'no gear ratio yet (waiting for bench/info); '
                                f'kept the last {_MAX_PENDING_BLOCKS} blocks')
            self._pending.append(msg)
            return
        try:
            block, frame_id = convert.encoder_block_data_of(msg)
        except (ValueError, TypeError, RvTeError) as exc:
            self.drops.drop('malformed', str(exc))
            return
        if self.combiner is not None and self.combiner.active:
            block, events = self.combiner.block(block)
            used = tuple((e.side, e.used) for e in events) or 'all'
            if self._heads_used is not None and used != self._heads_used:
                self.analyzer.split_window()   # no window mixes two sets of heads
            self._heads_used = used
            for e in events:
                self.get_logger().warning(f'encoder heads: {e.detail}',
                                          throttle_duration_sec=5.0)
        if self._first_seq is None:
            self._first_seq = block.seq
            if block.seq != 0:
                # The bench counts from 0: joining later (e.g. after a restart) missed blocks.
                self._gaps_total += 1
                self.get_logger().warning(
                    f'joined the stream at seq {block.seq}: blocks 0..{block.seq - 1} not seen')
        if self.zero is not None:
            latched = self.zero.reference is not None
            block = self.zero.apply(block)
            if not latched and self.zero.reference is not None:
                self.get_logger().info(self.zero.reference.describe())
        update = self.analyzer.push(block)
        self._blocks += 1
        self._last_seq = block.seq
        for gap in update.gaps:
            self._gaps_total += 1
            self.last_gap = f'{gap.kind} at seq {gap.seq}: {gap.detail}'
            if gap.kind == 'malformed':
                self.drops.drop('malformed', gap.detail)
            else:
                self.get_logger().warning(f'gap ({gap.kind}) at seq {gap.seq}: {gap.detail}',
                                          throttle_duration_sec=5.0)
        if len(update.te_rad):
            self._publish_samples(update, frame_id)
        self._publish_windows(update.windows)
        if len(update.te_rad):
            # a window that closed here shows in te/plot at once (not rate-limited)
            self._publish_plot(update, frame_id,
                               force=any(w.complete for w in update.windows))
        self._latency_ms.append((time.perf_counter() - t_arrival) * 1e3)
        if len(self._latency_ms) > 1000:
            del self._latency_ms[:500]

    def _publish_samples(self, update: StreamUpdate, frame_id: str) -> None:
        msg = TransmissionError()
        msg.header.stamp = convert.s_to_stamp(update.stamp_s)
        msg.header.frame_id = frame_id
        msg.seq = self._seq_samples
        self._seq_samples += 1
        msg.window_index = self.analyzer.counters.get('windows', 0) if self.analyzer else 0
        msg.window_complete = False
        msg.sample_rate_hz = float(self.p.decimated_rate_hz)
        msg.te_rad = convert.float64_field(update.te_rad)
        msg.theta_out_rad = convert.float64_field(update.phase_out_rad)
        if self.analyzer is not None:
            msg.cumulative = convert.make_te_statistics(self.analyzer.cumulative)
        if self._last_window is not None:
            msg.window = convert.make_te_statistics(self._last_window.stats)
        msg.gaps = self._gaps_total
        self.pub_samples.publish(msg)

    def _publish_plot(self, update: StreamUpdate, frame_id: str, *, force: bool) -> None:
        rate = self.p.plot_rate_hz
        t_s = float(update.time_s[-1]) if len(update.time_s) else float(update.stamp_s)
        if rate <= 0 or self.analyzer is None or (
                not force and t_s - self._last_plot_s < 1.0 / rate - 1e-9):
            return
        self._last_plot_s = t_s
        self.pub_plot.publish(convert.make_te_plot(
            te_rad=float(update.te_rad[-1]), theta_out_rad=float(update.phase_out_rad[-1]),
            stamp_s=t_s, frame_id=frame_id, window=self._last_complete,
            cumulative=self.analyzer.cumulative, gaps=self._gaps_total))

    def _publish_windows(self, windows: tuple[Any, ...]) -> None:
        for w in windows:
            self._last_window = w
            if w.complete:
                self._last_complete = w
            self.recent_windows.append(w)
            msg = TransmissionError()
            msg.header.stamp = convert.s_to_stamp(w.start_stamp_s)
            msg.header.frame_id = self.bench_id
            msg.seq = self._seq_stats
            self._seq_stats += 1
            msg.window_index = int(w.index)
            msg.window_complete = bool(w.complete)
            msg.window = convert.make_te_statistics(w.stats)
            if self.analyzer is not None:
                msg.cumulative = convert.make_te_statistics(self.analyzer.cumulative)
            msg.gaps = self._gaps_total
            self.pub_stats.publish(msg)
            if w.spectrum is not None:
                self.pub_spectrum.publish(convert.make_te_spectrum(
                    w.spectrum, window_index=w.index, stamp_s=w.start_stamp_s,
                    bench_id=self.bench_id))

    def _publish_diagnostics(self) -> None:
        counters = dict(self.analyzer.counters) if self.analyzer is not None else {}
        lat = np.asarray(self._latency_ms) if self._latency_ms else np.asarray([np.nan])
        heads = {} if self.combiner is None else {
            f'heads_{k}': v for k, v in self.combiner.counters.items()}
        if self.heads_problem:
            heads['heads_problem'] = self.heads_problem
        values = {**counters, **heads, 'gaps_reported': self._gaps_total,
                  'dropped_total': self.drops.total,
                  **{f'dropped_{k}': v for k, v in self.drops.counts.items()},
                  'latency_median_ms': float(np.median(lat)),
                  'latency_max_ms': float(np.max(lat)),
                  **({'last_gap': self.last_gap} if self.last_gap else {}),
                  **({'te_zero': self.zero.reference.describe()}
                     if self.zero is not None and self.zero.reference is not None else {})}
        level = OK if self.drops.total == 0 and self._gaps_total == 0 else WARN
        if self.heads_problem:
            level = ERROR
        message = ('waiting for bench/info' if self.analyzer is None
                   else f'{self._blocks} blocks, {self._gaps_total} gaps')
        self.pub_diag.publish(diagnostic_array(self, 'te analysis', level, message, values))

    def destroy_node(self) -> None:
        """Close the open (partial) window so its statistics are published, then destroy."""
        if self.analyzer is not None:
            try:
                self._publish_windows(self.analyzer.flush())
            except Exception as exc:  # noqa: BLE001 - shutting down: report, do not raise
                self.get_logger().warning(f'final flush failed: {exc}')
            if not launcher_gone():   # (the recorder stops now too: nobody to wait for)
                wait_for_readers(self)   # the final window reaches the recorder's queue
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    """Run the TE node in its own process."""
    return run_node(lambda ctx: TeNode(context=ctx), list(sys.argv if args is None else args))


if __name__ == '__main__':
    sys.exit(main())
