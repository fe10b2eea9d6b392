"""CompensationNode: turns the measured TE into advice a designer or assembler can act on.

Subscribes ``bench/info`` (preset and ratio), ``te/statistics`` (closed windows) and
``te/samples`` (decimated TE with the output angle). Publishes ``compensation/advice``
(CompensationAdvice, transient-local) and ``/diagnostics`` (search progress).

* 2K-V presets (wang2020-2kv): the Wang 2020 Eq. 21 assembly-phase optimisation of the
  preset (predicted before/after), and, after each complete window, identification of this
  unit's eccentricities from the measured TE with re-assembly phases for it.
* RV presets with a tooth-profile model (hu2020-rv): the Hu 2020 Eqs 24-27 tooth-profile
  compensation of the measured TE.

Long searches run off the executor, in a worker process of the node's own
(:mod:`rv_te_bench.nodes.search_process`; ``search_process: false``: on a thread), on the
pure functions of :mod:`rv_te_bench.core.compensation_search`; results are published from a
timer.

Advice only where the data holds it, gated as ``rv-te analyze`` gates it
(:mod:`rv_te_bench.core.advice_gate`): advice from the measured TE is asked for on complete
windows only (whole output revolutions without a gap), and before it is published it must act
on the cause the spectrum names. The dominant line is the largest of ``te/spectrum``'s lines
averaged over the windows so far (mean amplitude per order); a tooth-profile change is
published as withheld (the reason as its summary, no modifications, ``te_after_rad`` NaN) when
that line is not a mesh line, and identified assembly phases carry a note when it is. A
finished search waits (at most :data:`SPECTRUM_WAIT_S`) for the spectrum of its window.
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import replace
from typing import TYPE_CHECKING, Any

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.node import Node
from rv_te_msgs.msg import BenchInfo, CompensationAdvice, TeSpectrum, TransmissionError
from std_msgs.msg import String

from rv_te_bench.core import compensation_search
from rv_te_bench.core.advice import advice_kind
from rv_te_bench.core.advice_gate import check_cause, dominant_line, is_mesh_line, likely_source
from rv_te_bench.errors import BagError, RvTeError, YamlInputError
from rv_te_bench.nodes import convert, qos
from rv_te_bench.nodes.common import (
    OK,
    WARN,
    DropCounter,
    declare_from_specs,
    diagnostic_array,
    reject_invalid_changes,
    run_node,
)
from rv_te_bench.nodes.params.compensation import PARAMS, CompensationParams
from rv_te_bench.nodes.search_process import Cancelled, SearchJob, SearchRunner
from rv_te_bench.params import params_record
from rv_te_bench.safe_yaml import DOCUMENT_LIMITS, load_yaml
from sim.bench_info import BenchInfoData

if TYPE_CHECKING:
    from collections.abc import Callable
    from concurrent.futures import Future

    from rv_te_bench.core.advice import Advice, AdviceKind
    from sim.presets import Preset


_MAX_SAMPLES = 2_000_000  # bound on the decimated TE kept for identification
#: Longest wait of a finished search for the spectrum of the window it was asked for [s].
SPECTRUM_WAIT_S = 2.0
#: Advice computed from the measured TE (gated); the preset's optimum is a prediction.
_MEASURED = ('tooth-profile', 'identified-assembly-phases')
#: The kinds of search (and of advice).
KINDS = ('assembly-phases', 'identified-assembly-phases', 'tooth-profile')


def check_config(p: CompensationParams) -> None:
    """The compensation node's start-up checks (also run by ``rv-te launch --check``).

    Raises:
        sim.errors.PresetError: The ``preset`` parameter names no loadable preset, or an
            override is invalid.
    """
    if p.preset:
        from sim.presets import load_preset

        load_preset(p.preset, list(p.overrides))


class CompensationNode(Node):
    """Advice from the measured TE; searches in a worker process (or thread)."""

    def __init__(self, **kwargs: Any) -> None:
        """Declare parameters and topics; ``kwargs`` go to ``Node``."""
        super().__init__('compensation', **kwargs)
        self.p = params_record(CompensationParams, declare_from_specs(self, PARAMS))
        reject_invalid_changes(self, PARAMS)
        self.drops = DropCounter(self)
        #: Where the searches run: a worker process (the node's interpreter lock stays
        #: free), or with ``search_process: false`` a thread; niced by ``search_nice``.
        self.searches = SearchRunner(KINDS, in_process=not self.p.search_process,
                                     nice=int(self.p.search_nice))
        self.jobs: list[tuple[str, Future[Advice]]] = []
        #: A request of a kind whose search still runs: the newest one (a builder of the job
        #: from the data at the time it starts), run when the current search ends.
        self.pending: dict[str, Callable[[], SearchJob]] = {}
        #: Requests folded into a later run of the same kind, by kind.
        self.coalesced: dict[str, int] = {}
        self._submitted: set[str] = set()   # kinds submitted at least once
        self.preset: Any = None
        self.model_name = ''
        self.advice: AdviceKind | None = None
        self.bench_id = ''
        self.published: dict[str, int] = {}
        self.errors: list[str] = []
        self._te: list[np.ndarray] = []
        self._phase: list[np.ndarray] = []
        self._n_buffered = 0
        #: The spectrum so far: per output order, [sum of the windows' amplitudes, windows,
        #: label]; and the last window whose spectrum came (-1: none).
        self._lines: dict[float, list[Any]] = {}
        self._spectrum_window = -1
        self._last_window = -1
        #: Per running search: the window it was asked on, and when it was found done.
        self._job_window: dict[Future[Advice], int] = {}
        self._done_at: dict[Future[Advice], float] = {}
        self.withheld: dict[str, int] = {}
        self.pub_advice = self.create_publisher(CompensationAdvice, 'compensation/advice',
                                                qos.LATCHED_QOS)
        self.pub_diag = self.create_publisher(DiagnosticArray, '/diagnostics',
                                              qos.DIAGNOSTICS_QOS)
        self.create_subscription(BenchInfo, 'bench/info', self._on_info, qos.LATCHED_QOS)
        # what the TE node did with the read heads: whether the once-per-revolution line can
        # hold the output encoder's error (issue 36)
        self.create_subscription(String, 'te/encoder_heads', self._on_heads, qos.LATCHED_QOS)
        self.info: BenchInfoData | None = None
        self.heads_record: dict[str, Any] | None = None
        self.create_subscription(TransmissionError, 'te/statistics', self._on_window,
                                 qos.LATCHED_QOS)
        # raw: only the two sample arrays are taken from the bytes (io._te_cdr), not the
        # whole message with its statistics (issue 41 item 4)
        self.create_subscription(TransmissionError, 'te/samples', self._on_samples,
                                 qos.ENCODER_QOS, raw=True)
        self.create_subscription(TeSpectrum, 'te/spectrum', self._on_spectrum,
                                 qos.LATCHED_QOS)
        self.create_timer(0.2, self._collect)
        self.create_timer(self.p.diagnostics_period_s, self._publish_diagnostics)
        if self.p.preset:   # a bad preset parameter stops the node at start-up
            from sim.presets import load_preset

            try:
                self._set_preset(self.p.preset,
                                 lambda: load_preset(self.p.preset, list(self.p.overrides)),
                                 strict=True)
            except BaseException:
                self.searches.shutdown(wait=False)   # (its worker process ends with it)
                raise

    @property
    def search_nice(self) -> int | None:
        """Niceness the searches run at (None: not set, e.g. not Linux)."""
        return self.searches.search_nice

    @property
    def progress(self) -> dict[str, float]:
        """Fraction done of the latest search of each kind submitted (0..1)."""
        return {k: self.searches.progress(k) for k in KINDS if k in self._submitted}

    # -- inputs ---------------------------------------------------------------------------
    def _set_preset(self, name: str, load: Callable[[], Preset], *,
                    strict: bool = False) -> None:
        """Load the preset ``name`` with ``load()``; ``strict`` (our own parameter) raises,
        a bench's is logged."""
        if self.preset is not None:
            return
        try:
            self.preset = load()
        except ValueError as exc:
            if strict:
                raise
            self.errors.append(str(exc))
            self.get_logger().error(f'cannot load preset {name!r}: {exc}')
            return
        self.model_name = self.preset.model
        self.advice = advice_kind(self.model_name)
        self.get_logger().info(f'preset {self.preset.name} (model {self.model_name})')
        if self.advice == 'assembly-phases' and self.p.optimize_phases:
            self._submit('assembly-phases', self._job_phases())

    def _on_info(self, msg: BenchInfo) -> None:
        self.bench_id = msg.bench_id
        try:
            self.info = BenchInfoData.from_message(msg)
        except (ValueError, TypeError) as exc:
            self.drops.drop('bad_bench_info', str(exc))
            return
        if not self.p.preset:
            from rv_te_bench.io.bench_record import preset_from_bench_info

            info = self.info
            self._set_preset(info.preset, lambda: preset_from_bench_info(info))

    def _on_heads(self, msg: String) -> None:
        try:
            record = load_yaml(msg.data, origin='te/encoder_heads', limits=DOCUMENT_LIMITS)
        except YamlInputError as exc:
            self.drops.drop('bad_encoder_heads', str(exc))
            return
        self.heads_record = record if isinstance(record, dict) else None

    def _encoder_note(self, advice: Advice) -> Advice:
        """The identified advice with what the output encoder could put on the
        once-per-revolution line it rests on; flagged in the summary when comparable."""
        if self.info is None or not self._te:
            return advice
        from rv_te_bench.core.encoder_attribution import line_amplitude_rad, note_for_bench

        try:
            note = note_for_bench(self.info, self.heads_record, line_amplitude_rad(
                np.concatenate(self._phase), np.concatenate(self._te)))
        except (RvTeError, KeyError, TypeError, ValueError) as exc:
            self.drops.drop('bad_encoder_heads', str(exc))
            return advice
        details = {**advice.details, 'encoder_once_per_rev': note.to_plain()}
        summary = advice.summary
        if note.comparable and not note.separated:
            summary = f'{summary} [ENCODER: {note.text()}]'
        return replace(advice, details=details, summary=summary)

    def _on_samples(self, msg: TransmissionError | bytes) -> None:
        """Samples of one te/samples message (raw, the subscription's form, or a message)."""
        if isinstance(msg, bytes):
            from rv_te_bench.io._te_cdr import te_samples_of

            try:
                seq, te, ph = te_samples_of(msg)
            except BagError as exc:
                self.drops.drop('malformed', f'te/samples: {exc}')
                return
        else:
            seq = msg.seq
            te = np.asarray(msg.te_rad, dtype=np.float64)
            ph = np.asarray(msg.theta_out_rad, dtype=np.float64)
        if te.shape != ph.shape or not np.isfinite(te).all() or not np.isfinite(ph).all():
            self.drops.drop('malformed', f'te/samples seq {seq}: lengths {te.shape} vs '
                            f'{ph.shape} or non-finite values')
            return
        self._te.append(te)
        self._phase.append(ph)
        self._n_buffered += te.size
        while self._n_buffered > _MAX_SAMPLES and self._te:
            self._n_buffered -= self._te.pop(0).size
            self._phase.pop(0)

    def _on_spectrum(self, msg: TeSpectrum) -> None:
        if int(msg.window_index) <= self._spectrum_window:
            return   # (a latched repeat)
        for ln in msg.lines:
            o, a = float(ln.output_order), float(ln.amplitude_rad)
            if not (math.isfinite(o) and math.isfinite(a)):
                self.drops.drop('malformed', f'te/spectrum window {msg.window_index}: '
                                f'non-finite line {ln.label!r}')
                continue
            entry = self._lines.setdefault(round(o, 6), [0.0, 0, str(ln.label)])
            entry[0] += a
            entry[1] += 1
        self._spectrum_window = int(msg.window_index)

    def _gate(self, advice: Advice) -> tuple[Advice, bool]:
        """The advice as the data holds it (core.advice_gate, as rv-te analyze); True when
        withheld. Unchanged without a spectrum or bench orders (nothing to check against)."""
        if advice.method not in _MEASURED or not self._lines or self.info is None:
            return advice, False
        from rv_te_bench.core.orders import OrderSet

        try:
            orders = OrderSet.from_bench_info(self.info)
        except RvTeError as exc:
            self.drops.drop('bad_bench_info', str(exc))
            return advice, False
        keys = list(self._lines)
        k = dominant_line(keys, [v[0] / v[1] for v in self._lines.values()])
        if k is None:
            return advice, False
        order = keys[k]
        amp_sum, n, label = self._lines[order]
        gate = check_cause(advice.method, label=label, amplitude_rad=amp_sum / n,
                           source=likely_source(order, orders, self.info.reducer_type),
                           mesh=is_mesh_line(order, orders))
        if gate.withheld is not None:
            return replace(advice, summary=gate.withheld, te_after_rad=math.nan,
                           modifications=(), details={**advice.details,
                                                      'withheld': gate.withheld}), True
        if gate.note:
            return replace(advice, summary=f'{advice.summary}; {gate.note}'), False
        return advice, False

    def _on_window(self, msg: TransmissionError) -> None:
        if self.preset is None or not msg.window_complete:
            return
        self._last_window = int(msg.window_index)
        measured = msg.window.pp_rad if self.p.te_metric == 'pp' else msg.window.amplitude_rad
        if self.advice == 'assembly-phases' and self.p.identify and self._te:
            self._request('identified-assembly-phases', self._identify_job)
        elif self.advice == 'tooth-profile' and math.isfinite(measured) and measured > 0:
            self._request('tooth-profile', lambda: self._job_tooth(measured))

    def _identify_job(self) -> SearchJob:
        """The identification job on all the decimated TE received so far."""
        te = np.concatenate(self._te)
        ph = np.concatenate(self._phase)
        return self._job_identify(ph, te)

    # -- jobs (core.compensation_search, run by self.searches) ----------------------------
    def _request(self, name: str, build: Callable[[], SearchJob]) -> None:
        """Run the job ``build()`` returns now, or, while a search of this kind still runs,
        once it ends, on the data there is then (issue #15: a request that came during a
        search was dropped, and the last advice missed the last windows)."""
        if any(n == name for n, _ in self.jobs):
            if name in self.pending:
                self.coalesced[name] = self.coalesced.get(name, 0) + 1
            self.pending[name] = build
            self.get_logger().info(f'{name}: a search is running; the newest request runs '
                                   'when it ends')
            return
        self._submit(name, build())

    def _submit(self, name: str, job: SearchJob) -> None:
        self._submitted.add(name)
        fut = self.searches.submit(job)
        self._job_window[fut] = self._last_window
        self.jobs.append((name, fut))

    def _job_phases(self) -> SearchJob:
        return SearchJob('assembly-phases', compensation_search.preset_phases_advice,
                         (self.preset,), {'step_deg': self.p.step_deg,
                                          'refine': self.p.refine})

    def _job_identify(self, phase_out_rad: np.ndarray, te_rad: np.ndarray) -> SearchJob:
        # the same search as the preset's optimum: the two then differ only in the unit
        return SearchJob('identified-assembly-phases',
                         compensation_search.identified_phases_advice,
                         (self.preset, phase_out_rad, te_rad),
                         {'step_deg': self.p.step_deg, 'refine': self.p.refine})

    def _job_tooth(self, measured_rad: float) -> SearchJob:
        return SearchJob('tooth-profile', compensation_search.tooth_advice,
                         (self.preset, measured_rad), {'te_metric': self.p.te_metric},
                         progress=False)

    # -- outputs (executor thread) --------------------------------------------------------
    def _collect(self) -> None:
        still = []
        now = time.monotonic()
        for name, fut in self.jobs:
            if not fut.done() or (
                    name in _MEASURED and self._spectrum_window < self._job_window[fut]
                    and now - self._done_at.setdefault(fut, now) < SPECTRUM_WAIT_S):
                still.append((name, fut))   # (done: waits for its window's spectrum)
                continue
            self._job_window.pop(fut, None)
            self._done_at.pop(fut, None)
            self.searches.set_progress(name, 1.0)
            exc = fut.exception()
            if isinstance(exc, Cancelled):
                continue
            if exc is not None:
                self.errors.append(f'{name}: {exc}')
                self.get_logger().error(f'{name} failed: {exc}', throttle_duration_sec=10.0)
                continue
            advice = fut.result()
            if name == 'identified-assembly-phases':
                advice = self._encoder_note(advice)
            advice, withheld = self._gate(advice)
            self.pub_advice.publish(convert.make_compensation_advice(
                advice, self.get_clock().now().to_msg(), self.bench_id))
            self.published[name] = self.published.get(name, 0) + 1
            if withheld:
                self.withheld[name] = self.withheld.get(name, 0) + 1
            self.get_logger().info(f'advice ({name}): {advice.summary}')
        self.jobs = still
        for name in [n for n in self.pending if all(n != m for m, _ in self.jobs)]:
            self._submit(name, self.pending.pop(name)())

    def _publish_diagnostics(self) -> None:
        values: dict[str, Any] = {f'progress_{k}': v for k, v in self.progress.items()}
        values.update({f'published_{k}': v for k, v in self.published.items()})
        values.update({f'withheld_{k}': v for k, v in self.withheld.items()})
        values['dropped_total'] = self.drops.total
        values.update({f'coalesced_{k}': v for k, v in self.coalesced.items()})
        values['errors'] = len(self.errors)
        running = [n for n, f in self.jobs if not f.done()]
        message = (f'running {", ".join(running)}' if running else
                   'waiting for bench/info' if self.preset is None else 'idle')
        level = WARN if self.errors else OK
        self.pub_diag.publish(diagnostic_array(self, 'compensation', level, message, values))

    @property
    def busy(self) -> bool:
        """A search is running or its advice is not published yet (run_node lets it finish
        before the node stops, so that a session ends with its advice recorded)."""
        return bool(self.jobs or self.pending)

    def destroy_node(self) -> None:
        """Abort a search still running (said on /diagnostics and in the log) and stop."""
        running = sorted({n for n, f in self.jobs if not f.done()} | set(self.pending))
        # set by run_node when the launcher died: the search is cut off, not waited for
        reason = getattr(self, 'stop_reason', '')
        if running:
            why = ('stopped before the search finished'
                   + (f' (search cut off: {reason})' if reason else '')
                   + f': no advice from {", ".join(running)}')
            self.get_logger().error(why)
            self.errors.append(why)
            self._publish_diagnostics()
        self.searches.shutdown(wait=not reason)
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    """Run the compensation node in its own process."""
    return run_node(lambda ctx: CompensationNode(context=ctx),
                    list(sys.argv if args is None else args))


if __name__ == '__main__':
    sys.exit(main())
