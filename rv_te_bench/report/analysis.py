"""Offline analysis of recorded sessions: bag(s) -> :class:`AnalysisResult`.

One bag is read an MCAP chunk at a time (:func:`rv_te_bench.io.bag_reader.read_encoder_batches`),
fed to the TE core (:func:`rv_te_bench.core.stream.analyze_blocks`, the same windowing the TE
node uses, with the same result as block by block) and summarised in memory that does not
grow with the recording (each window's spectrum is folded into a running average):

* statistics per window of whole output revolutions and cumulative over every clean sample;
* the order spectrum of the **complete** windows, averaged: the amplitude of each labelled
  line is the arithmetic mean of its per-window peak amplitudes, the phase the angle of the
  mean phasor (``method`` in :class:`SpectrumSummary` says so);
* the gaps the core reported (sequence jumps, time going backwards, non-finite data) and
  read errors (a truncated or corrupted file ends the read; what came before is kept and
  the result is marked ``partial``);
* the dominant labelled harmonic and its likely physical source;
* a recommendation from the compensation code when the preset has a model for it.

Everything inside is SI (radians, seconds, hertz); arcminutes appear only in
:meth:`AnalysisResult.to_json_dict` (keys ending in ``_arcmin``) and in the plots/HTML.
No rclpy import: this runs on a laptop without ROS.
"""

from __future__ import annotations

import itertools
import math
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from rv_te_bench.core.advice import advice_kind
from rv_te_bench.core.angle_fold import AngleFold
from rv_te_bench.core.units import json_deg
from rv_te_bench.errors import BagError, RvTeError, TeConfigError
from sim.units import rad_to_arcmin

if TYPE_CHECKING:
    from collections.abc import Callable, Iterable, Iterator

    import numpy.typing as npt

    from rv_te_bench.core.advice import Advice
    from rv_te_bench.core.angle_fold import FoldedTe
    from rv_te_bench.core.spectrum import OrderSpectrum, SpectrumLine
    from rv_te_bench.core.stream import EncoderBatch, EncoderBlockData, GapEvent, WindowResult
    from rv_te_bench.core.te import TeStats

    FloatArray = npt.NDArray[np.float64]
    ProgressFn = Callable[[int, int, float], None]

__all__ = [
    'AnalysisResult',
    'BenchDescription',
    'DominantHarmonic',
    'Recommendation',
    'SpectrumAverager',
    'SpectrumSummary',
    'TeTrace',
    'SessionInfo',
    'analyze_bag',
    'compare_results',
    'describe_identification',
    'likely_source',
    'report_title',
    'session_info',
]

#: Most (theta_out, TE) points kept for the TE plot; the trace is thinned by 2 when exceeded.
MAX_TRACE_POINTS = 40_000

#: Lines weaker than this fraction of the strongest line show no phase in tables (it is
#: the phase of noise).
PHASE_MIN_FRACTION = 1e-3

#: Relative tolerance when matching a line's output order to a known order.
_ORDER_RTOL = 1e-6


@dataclass(frozen=True)
class BenchDescription:
    """What the analysis knows about the bench that recorded a bag.

    Attributes:
        source: ``'bench_info'`` (from the bag), ``'cli'`` (from --ratio/--crank-per-output)
            or ``'bench_info+cli'`` (bag values overridden by flags).
        bench_id: Bench id ('' when unknown).
        preset: Reducer preset name ('' when unknown).
        reducer_type: ``'2kv'``, ``'rv'`` or ''.
        gear_ratio: Overall ratio i, input revolutions per output revolution.
        crank_per_output: |Absolute crank revolutions per output revolution|.
        mesh_orders_out: Mesh frequencies as orders of the output rotation.
        mesh_labels: One label per mesh order.
        sample_rate_hz: Nominal DAQ rate from BenchInfo (NaN when unknown).
        encoder_in_model: Input encoder model ('' when unknown).
        encoder_out_model: Output encoder model ('' when unknown).
        parameters_yaml: Effective preset values as YAML ('' when unknown).
    """

    source: str
    gear_ratio: float
    crank_per_output: float
    bench_id: str = ''
    preset: str = ''
    reducer_type: str = ''
    mesh_orders_out: tuple[float, ...] = ()
    mesh_labels: tuple[str, ...] = ()
    sample_rate_hz: float = math.nan
    encoder_in_model: str = ''
    encoder_out_model: str = ''
    parameters_yaml: str = field(default='', repr=False)

    def __post_init__(self) -> None:
        """Validate ratio and crank order.

        Raises:
            TeConfigError: A non-finite or non-positive ratio / crank order.
        """
        for name in ('gear_ratio', 'crank_per_output'):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                msg = f'{name} must be finite and > 0, got {value!r} (source: {self.source})'
                raise TeConfigError(msg)

    def to_json_dict(self) -> dict[str, Any]:
        """JSON-friendly dict (unit-suffixed keys)."""
        return {
            'source': self.source, 'bench_id': self.bench_id, 'preset': self.preset,
            'reducer_type': self.reducer_type, 'gear_ratio': self.gear_ratio,
            'crank_per_output': self.crank_per_output,
            'mesh_orders_out': list(self.mesh_orders_out), 'mesh_labels': list(self.mesh_labels),
            'sample_rate_hz': _num(self.sample_rate_hz),
            'encoder_in_model': self.encoder_in_model,
            'encoder_out_model': self.encoder_out_model,
        }


@dataclass(frozen=True)
class SpectrumSummary:
    """Order spectrum of a bag: the complete windows, averaged.

    Attributes:
        method: How the lines were combined, in words (shown in reports).
        n_windows: Complete windows averaged.
        output_hz: Mean output rotation frequency f_out over those windows [Hz].
        crank_hz: Mean absolute crank frequency f_w [Hz].
        revolutions: Output revolutions covered by the averaged windows.
        lines: Averaged labelled lines (peak amplitude [rad], phase of the cosine [rad]).
        amplitude_spread_rad: Per line, the standard deviation of the per-window amplitudes.
        orders: Output orders of the full spectrum (for plots), read-only.
        amplitude_rad: Mean peak amplitude at ``orders`` [rad], read-only.
    """

    method: str
    n_windows: int
    output_hz: float
    crank_hz: float
    revolutions: float
    lines: tuple[SpectrumLine, ...]
    amplitude_spread_rad: tuple[float, ...]
    orders: FloatArray = field(repr=False)
    amplitude_rad: FloatArray = field(repr=False)

    def to_json_dict(self) -> dict[str, Any]:
        """JSON-friendly dict; line amplitudes in rad and arcmin, phases in rad and deg."""
        return {
            'method': self.method, 'n_windows': self.n_windows,
            'output_hz': _num(self.output_hz), 'crank_hz': _num(self.crank_hz),
            'revolutions': _num(self.revolutions),
            'lines': [_line_json(ln, spread) for ln, spread in
                      zip(self.lines, self.amplitude_spread_rad, strict=True)],
        }


@dataclass(frozen=True)
class DominantHarmonic:
    """The labelled line with the largest averaged amplitude and its likely source."""

    line: SpectrumLine
    likely_source: str

    def to_json_dict(self) -> dict[str, Any]:
        """JSON-friendly dict."""
        return {**_line_json(self.line, math.nan), 'likely_source': self.likely_source}


@dataclass(frozen=True)
class Recommendation:
    """Compensation advice, or why there is none.

    Attributes:
        available: True when ``advice`` holds a recommendation.
        reason: Why there is no recommendation, or where the advice comes from.
        advice: The advice (``rv_te_bench.core.advice.Advice``) or None.
        identification: The 2K-V identification the advice rests on, or that was judged
            too poor for advice (JSON dict with the fit quality), or None.
    """

    available: bool
    reason: str
    advice: Advice | None = None
    identification: dict[str, Any] | None = None

    def to_json_dict(self) -> dict[str, Any]:
        """JSON-friendly dict."""
        return {'available': self.available, 'reason': self.reason,
                'advice': None if self.advice is None else self.advice.to_json_dict(),
                'identification': self.identification}


@dataclass(frozen=True)
class SessionInfo:
    """What the bag says about its session (metadata.yaml ``custom_data``).

    Attributes:
        name: ``session`` from the metadata, else the bag folder's name (its parent's when
            the folder is a generic ``bag``, as in ``bags/<session>/bag``).
        started_utc: When the recorder started ('' when unknown).
        unit_serial: Serial number of the unit under test (``unit_serial`` in the session
            metadata, e.g. ``--param recorder.session_metadata_yaml='unit_serial: SN-42'``).
    """

    name: str
    started_utc: str = ''
    unit_serial: str = ''

    def to_json_dict(self) -> dict[str, Any]:
        """JSON-friendly dict."""
        return {'name': self.name, 'started_utc': self.started_utc,
                'unit_serial': self.unit_serial}


def session_info(path: str | Path) -> SessionInfo:
    """The session of a bag from its metadata (never raises: falls back to the path)."""
    from rv_te_bench.io.bag_reader import open_bag  # noqa: PLC0415

    p = Path(path)
    folder = p.parent.name if p.name in {'bag', 'bag_0'} and p.parent.name else p.name
    try:
        custom = open_bag(p).info.get('custom_data') or {}
    except BagError:
        custom = {}
    if not isinstance(custom, dict):
        custom = {}
    return SessionInfo(name=str(custom.get('session') or folder),
                       started_utc=str(custom.get('started_utc') or ''),
                       unit_serial=str(custom.get('unit_serial') or ''))


def report_title(result: AnalysisResult) -> str:
    """What a bag is, for titles: preset, bench, session, start and the unit serial."""
    b, sess = result.bench, result.session
    parts = [b.preset or 'unknown reducer']
    if b.bench_id:
        parts.append(f'bench {b.bench_id}')
    parts.append(f'session {sess.name}' + (f' ({sess.started_utc})' if sess.started_utc else ''))
    if sess.unit_serial:
        parts.append(f'unit {sess.unit_serial}')
    return ', '.join(parts)


@dataclass(frozen=True)
class TeTrace:
    """A thinned TE trace for plots: every ``stride``-th sample, NaN rows at gaps.

    Attributes:
        theta_out_rad: Output angle [rad] (unwrapped, as recorded).
        te_rad: TE at those samples [rad].
        stride: Every how many samples one was kept.
    """

    theta_out_rad: FloatArray = field(repr=False)
    te_rad: FloatArray = field(repr=False)
    stride: int = 1


@dataclass(frozen=True)
class AnalysisResult:
    """Everything the offline analysis found in one bag.

    Attributes:
        path: The bag.
        topic: Encoder topic asked for (None: the reader's choice).
        bench: Ratio, orders and bench metadata used.
        windows: Per-window results of the TE core (complete and the trailing partial one);
            their spectra keep the labelled lines only (``OrderSpectrum.lines_only``: the
            per-bin arrays are folded into ``spectrum`` as the windows close, so memory
            does not grow with the length of the recording).
        cumulative: Statistics over every clean sample.
        spectrum: Averaged spectrum of the complete windows, or None when there is none.
        dominant: Dominant labelled line, or None without a spectrum.
        gaps: Gap events reported by the core.
        counters: Counters reported by the core (blocks, samples, ...).
        trace: Thinned TE trace for plots.
        recommendation: Compensation advice or the reason there is none.
        partial: True when the read ended early (see ``problems``).
        problems: Human-readable problems met (read errors, no complete window, ...), one
            line each; a long list of read errors is shortened (all are in ``read_problems``).
        blocks_read: Encoder blocks read from the bag.
        elapsed_s: Wall time of the analysis [s].
        read_problems: Every problem the reader met (file, byte offset, what), in order.
        session: The bag's session (name, start, unit serial) for titles.
    """

    path: Path
    topic: str | None
    bench: BenchDescription
    windows: tuple[WindowResult, ...]
    cumulative: TeStats
    spectrum: SpectrumSummary | None
    dominant: DominantHarmonic | None
    gaps: tuple[GapEvent, ...]
    counters: dict[str, Any]
    trace: TeTrace
    recommendation: Recommendation
    partial: bool
    problems: tuple[str, ...]
    blocks_read: int
    elapsed_s: float
    read_problems: tuple[str, ...] = ()
    session: SessionInfo = field(default_factory=lambda: SessionInfo(name=''))

    @property
    def complete_windows(self) -> tuple[WindowResult, ...]:
        """The windows that cover whole output revolutions."""
        return tuple(w for w in self.windows if w.complete)

    def to_json_dict(self) -> dict[str, Any]:
        """JSON-friendly dict with unit-suffixed keys (``te_pp_arcmin``, ``frequency_hz``)."""
        return {
            'bag': str(self.path),
            'title': report_title(self),
            'session': self.session.to_json_dict(),
            'topic': self.topic,
            'partial': self.partial,
            'problems': list(self.problems),
            'read_problems': list(self.read_problems),
            'blocks_read': self.blocks_read,
            'bench': self.bench.to_json_dict(),
            'cumulative': stats_json(self.cumulative),
            'windows': [{
                'index': int(w.index), 'complete': bool(w.complete),
                'start_stamp_s': _num(w.start_stamp_s), 'end_stamp_s': _num(w.end_stamp_s),
                'first_seq': int(w.first_seq), 'last_seq': int(w.last_seq),
                **stats_json(w.stats)} for w in self.windows],
            'spectrum': None if self.spectrum is None else self.spectrum.to_json_dict(),
            'dominant': None if self.dominant is None else self.dominant.to_json_dict(),
            'gaps': [{'kind': g.kind, 'seq': int(g.seq), 'detail': g.detail} for g in self.gaps],
            'counters': {k: _jsonable(v) for k, v in self.counters.items()},
            'recommendation': self.recommendation.to_json_dict(),
        }


def stats_json(stats: TeStats) -> dict[str, Any]:
    """TE statistics as a JSON dict in arcmin (and rad), keys carrying the unit."""
    return {
        'te_pp_arcmin': _num(rad_to_arcmin(stats.pp_rad)),
        'te_amplitude_arcmin': _num(rad_to_arcmin(stats.amplitude_rad)),
        'te_mean_arcmin': _num(rad_to_arcmin(stats.mean_rad)),
        'te_std_arcmin': _num(rad_to_arcmin(stats.std_rad)),
        'te_pp_rad': _num(stats.pp_rad),
        'te_amplitude_rad': _num(stats.amplitude_rad),
        'te_mean_rad': _num(stats.mean_rad),
        'te_std_rad': _num(stats.std_rad),
        'revolutions': _num(stats.revolutions),
        'n_samples': int(stats.n_samples),
    }


# --------------------------------------------------------------------------------------
# analysis


def analyze_bag(  # noqa: PLR0913 - keyword-only analysis options
    path: str | Path,
    *,
    topic: str | None = None,
    gear_ratio: float | None = None,
    crank_per_output: float | None = None,
    n_crank_harmonics: int = 10,
    window_revolutions: int = 1,
    with_advice: bool = True,
    advice_search: tuple[float, bool] = (10.0, False),
    progress: ProgressFn | None = None,
) -> AnalysisResult:
    """Analyse one recorded session.

    Args:
        path: rosbag2 folder or .mcap file.
        topic: Encoder topic (None: the reader picks the EncoderBlock topic).
        gear_ratio: Overall ratio i (input revs per output rev); overrides BenchInfo, and
            is required with ``crank_per_output`` for bags without BenchInfo.
        crank_per_output: |Absolute crank revs per output rev| (25 for the Wang 2020 2K-V).
        n_crank_harmonics: Crank harmonics to report (1 f_w .. n f_w).
        window_revolutions: Whole output revolutions per analysis window (>= 1).
        with_advice: Ask the compensation code for a recommendation.
        advice_search: (grid step [deg], refine) of the 2K-V assembly-phase search: the
            paper's 10 deg grid by default; a session's compensation node settings to match
            its live advice (the demo does).
        progress: Called as ``progress(blocks, samples, elapsed_s)`` after each chunk of
            blocks read.

    Returns:
        The analysis; ``partial`` is set when a read error ended the bag early.

    Raises:
        BagError: The bag cannot be opened, has no encoder topic, or no block could be read.
        TeConfigError: Ratio/crank order missing (no BenchInfo and no flags) or invalid.
    """
    from rv_te_bench.core.stream import TeAnalysisConfig, analyze_blocks  # noqa: PLC0415
    from rv_te_bench.io.bag_reader import (  # noqa: PLC0415
        open_bag,
        read_bench_info,
        read_encoder_batches,
        summarize_problems,
    )

    t_start = time.monotonic()
    path = Path(path)
    if not path.exists():
        msg = f'{path}: no such bag'
        raise BagError(msg)
    info, info_problem = _read_bench_info(path, gear_ratio, crank_per_output)
    bench = _bench_description(path, info, gear_ratio, crank_per_output)
    config = TeAnalysisConfig(orders=_order_set(bench, n_crank_harmonics),
                              window_revolutions=window_revolutions)

    stream = read_encoder_batches(path, topic, strict=False)
    # a 2K-V unit is identified from every sample, folded on theta_in / i as it is read
    fold = AngleFold() if with_advice and bench.reducer_type == '2kv' else None
    reader = _GuardedBlocks(stream, bench.gear_ratio, progress=progress, t_start=t_start,
                            fold=fold)
    averager = SpectrumAverager()
    kept: list[WindowResult] = []

    def on_window(w: WindowResult) -> None:
        # fold the spectrum into the average; keep the window without its per-bin arrays
        if w.spectrum is not None:
            if w.complete:
                averager.add(w.spectrum)
            w = replace(w, spectrum=w.spectrum.lines_only())
        kept.append(w)

    offline = analyze_blocks(reader, config, on_window=on_window)
    read_problems = [*([] if info_problem is None else [info_problem]),
                     *stream.problems,
                     *([] if reader.error is None else [reader.error])]
    if reader.blocks == 0:
        detail = summarize_problems(read_problems) or 'the encoder topic holds no messages'
        msg = f'{path}: no encoder block could be read ({detail})'
        raise BagError(msg)

    partial = bool(read_problems) or stream.partial
    problems = list(open_bag(path).notes)   # unlisted files ignored, what was not written
    if partial:
        problems.append(f'{reader.blocks} blocks read; part of the bag is unreadable: '
                        + summarize_problems(read_problems))
    windows = tuple(kept)
    spectrum = averager.result()
    if spectrum is None:
        problems.append('no complete output revolution without a gap: no spectrum, and the '
                        'statistics do not cover whole revolutions')
    dominant = None if spectrum is None else dominant_harmonic(spectrum, bench)
    trace = reader.trace()
    recommendation = (
        _recommend(bench, offline.cumulative, None if fold is None else fold.result(),
                   advice_search)
        if with_advice else
        Recommendation(available=False, reason='not requested (--no-advice)'))
    return AnalysisResult(
        path=path, topic=topic, bench=bench, windows=windows,
        cumulative=offline.cumulative, spectrum=spectrum, dominant=dominant,
        gaps=tuple(offline.gaps), counters=dict(offline.counters), trace=trace,
        recommendation=recommendation, partial=partial,
        problems=tuple(problems), blocks_read=reader.blocks,
        elapsed_s=time.monotonic() - t_start, read_problems=tuple(read_problems),
        session=session_info(path))


def _read_bench_info(path: Path, gear_ratio: float | None, crank_per_output: float | None,
                     ) -> tuple[dict[str, Any] | None, str | None]:
    """(BenchInfo, problem): a damaged chunk holding BenchInfo does not block a bag whose
    ratio and crank order are given (--ratio, --crank-per-output); the result is partial."""
    from rv_te_bench.io.bag_reader import read_bench_info  # noqa: PLC0415

    try:
        return read_bench_info(path), None
    except BagError as exc:
        if gear_ratio is None or crank_per_output is None:
            msg = f'{exc}; pass --ratio and --crank-per-output to analyse the rest of the bag'
            raise BagError(msg) from None
        return None, 'no readable BenchInfo (damaged): --ratio and --crank-per-output used'


class _GuardedBlocks:
    """Iterator over encoder blocks/batches that stops cleanly at a read error, keeps a trace.

    The reader (``strict=False``) stops quietly at a truncated or corrupt part and lists
    the problem; a ``BagError`` raised in the middle of the iteration (e.g. the topic
    carries another type further on) would make the TE core lose every window already
    closed, so this wrapper ends the iteration instead and remembers the error. It also
    counts blocks for the progress callback and keeps a thinned TE trace for the plot.
    """

    def __init__(self, blocks: Iterable[EncoderBlockData | EncoderBatch], gear_ratio: float,
                 *, progress: ProgressFn | None, t_start: float,
                 fold: AngleFold | None = None) -> None:
        self._it = iter(blocks)
        self._fold = fold
        self._ratio = gear_ratio
        self._progress = progress
        self._t0 = t_start
        self.blocks = 0
        self.samples = 0
        self.error: str | None = None
        self._stride = 1
        self._last_seq: int | None = None
        self._parts: list[tuple[npt.NDArray[np.int64], FloatArray, FloatArray]] = []
        self._kept = 0

    def __iter__(self) -> Iterator[EncoderBlockData | EncoderBatch]:
        return self

    def __next__(self) -> EncoderBlockData | EncoderBatch:
        from rv_te_bench.core.stream import EncoderBatch  # noqa: PLC0415

        try:
            item = next(self._it)
        except BagError as exc:
            self.error = str(exc)
            raise StopIteration from None
        if isinstance(item, EncoderBatch):
            self.blocks += item.n_blocks
            self.samples += item.n_samples
            self._keep_batch(item)
        else:
            self.blocks += 1
            self.samples += int(np.size(item.theta_out_rad))
            self._keep(item)
        if self._progress is not None:
            self._progress(self.blocks, self.samples, time.monotonic() - self._t0)
        return item

    def _keep(self, block: EncoderBlockData) -> None:
        """Keep every ``stride``-th sample (by global sample index) and a NaN row at gaps."""
        th_out = np.asarray(block.theta_out_rad, dtype=np.float64)
        th_in = np.asarray(block.theta_in_rad, dtype=np.float64)
        n = th_out.size
        if th_out.shape != th_in.shape or n == 0:
            return  # the core reports malformed blocks; the plot just skips them
        self._keep_run(int(block.seq), int(block.seq), th_in, th_out, self.samples - n)

    def _keep_batch(self, batch: EncoderBatch) -> None:
        """As ``_keep`` for each block of a batch, one run of continuous blocks at a time."""
        seq = np.asarray(batch.seq, dtype=np.int64)
        starts = np.asarray(batch.starts, dtype=np.intp)
        g0 = self.samples - batch.n_samples
        cuts = [0, *(np.flatnonzero(seq[1:] != seq[:-1] + 1) + 1).tolist(), seq.size]
        for k0, k1 in itertools.pairwise(cuts):
            a, b = int(starts[k0]), int(starts[k1])
            self._keep_run(int(seq[k0]), int(seq[k1 - 1]), batch.theta_in_rad[a:b],
                           batch.theta_out_rad[a:b], g0 + a)

    def _keep_run(self, seq_first: int, seq_last: int, th_in: FloatArray,  # noqa: PLR0913
                  th_out: FloatArray, g0: int) -> None:
        """Samples of consecutive blocks seq_first..seq_last, the first at global index g0."""
        from rv_te_bench.core.te import transmission_error_rad  # noqa: PLC0415

        if self._last_seq is not None and seq_first != self._last_seq + 1:
            self._parts.append((np.array([-1]), np.array([np.nan]), np.array([np.nan])))
        self._last_seq = seq_last
        if self._fold is not None:
            self._fold.add_encoders(th_in, th_out, gear_ratio=self._ratio)
        start = (-g0) % self._stride
        th = th_out[start::self._stride]
        te = transmission_error_rad(th_in[start::self._stride], th, gear_ratio=self._ratio)
        g = g0 + np.arange(start, th_out.size, self._stride, dtype=np.int64)
        self._parts.append((g, np.array(th, dtype=np.float64), np.asarray(te, dtype=np.float64)))
        self._kept += th.size
        while self._kept > MAX_TRACE_POINTS:
            g_all, th_all, te_all = self._joined()
            self._stride *= 2
            keep = (g_all < 0) | (g_all % self._stride == 0)
            self._parts = [(g_all[keep], th_all[keep], te_all[keep])]
            self._kept = int(np.count_nonzero(keep))

    def _joined(self) -> tuple[npt.NDArray[np.int64], FloatArray, FloatArray]:
        if not self._parts:
            return np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0)
        g, th, te = (np.concatenate(a) for a in zip(*self._parts, strict=True))
        return g, th, te

    def trace(self) -> TeTrace:
        """The thinned trace collected so far (read-only arrays)."""
        _, th, te = self._joined()
        th.setflags(write=False)
        te.setflags(write=False)
        return TeTrace(theta_out_rad=th, te_rad=te, stride=self._stride)


def _bench_description(path: Path, info: dict[str, Any] | None, gear_ratio: float | None,
                       crank_per_output: float | None) -> BenchDescription:
    """Merge BenchInfo from the bag with the command-line overrides."""
    if info is None:
        missing = [flag for flag, v in (('--ratio', gear_ratio),
                                        ('--crank-per-output', crank_per_output)) if v is None]
        if missing:
            msg = (f'{path}: the bag has no BenchInfo message (bench/info), so the gear ratio '
                   f'and crank order are unknown; pass {" and ".join(missing)}')
            raise TeConfigError(msg)
        assert gear_ratio is not None and crank_per_output is not None  # noqa: S101 - for mypy
        return BenchDescription(source='cli', gear_ratio=float(gear_ratio),
                                crank_per_output=float(crank_per_output))
    try:
        ratio = float(info['gear_ratio'])
        cpo = abs(float(info['crank_per_input']) * ratio)
    except (KeyError, TypeError, ValueError) as exc:
        msg = f'{path}: BenchInfo lacks a usable gear_ratio/crank_per_input ({exc!r})'
        raise TeConfigError(msg) from None
    source = 'bench_info'
    if gear_ratio is not None or crank_per_output is not None:
        source = 'bench_info+cli'
        ratio = float(gear_ratio) if gear_ratio is not None else ratio
        cpo = float(crank_per_output) if crank_per_output is not None else cpo
    return BenchDescription(
        source=source, gear_ratio=ratio, crank_per_output=cpo,
        bench_id=str(info.get('bench_id', '')), preset=str(info.get('preset', '')),
        reducer_type=str(info.get('reducer_type', '')),
        mesh_orders_out=tuple(float(o) for o in info.get('mesh_orders', ()) or ()),
        mesh_labels=tuple(str(s) for s in info.get('mesh_labels', ()) or ()),
        sample_rate_hz=float(info.get('sample_rate_hz', math.nan) or math.nan),
        encoder_in_model=str(info.get('encoder_in_model', '')),
        encoder_out_model=str(info.get('encoder_out_model', '')),
        parameters_yaml=str(info.get('parameters_yaml', '')))


def _order_set(bench: BenchDescription, n_crank_harmonics: int) -> Any:  # noqa: ANN401
    """The core OrderSet for the bench (signs do not matter for frequencies)."""
    from rv_te_bench.core.orders import OrderSet  # noqa: PLC0415

    return OrderSet(gear_ratio=bench.gear_ratio, crank_per_output=bench.crank_per_output,
                    mesh_orders_out=bench.mesh_orders_out, mesh_labels=bench.mesh_labels,
                    n_crank_harmonics=n_crank_harmonics)


class SpectrumAverager:
    """Running average of the spectra of complete windows (memory of one window's bins).

    Line amplitudes: arithmetic mean of the per-window peak amplitudes (robust to the phase
    reference of each window). Line phases: angle of the mean phasor a*exp(j*phase). The
    full amplitude spectrum is averaged bin by bin when every window has the same order
    grid; otherwise the spectrum of the longest window is shown (the method says so).

    Examples:
        >>> import numpy as np
        >>> from rv_te_bench.core.orders import OrderSet
        >>> from rv_te_bench.core.spectrum import order_spectrum
        >>> phi = 2 * np.pi * np.arange(512) / 512
        >>> avg = SpectrumAverager()
        >>> for a in (1e-4, 3e-4):
        ...     avg.add(order_spectrum(phi, a * np.cos(25 * phi), OrderSet(79.0, 25.0)))
        >>> s = avg.result()
        >>> line = next(ln for ln in s.lines if ln.label == '1 f_w')
        >>> s.n_windows, round(line.amplitude_rad, 12), round(float(s.amplitude_rad[25]), 12)
        (2, 0.0002, 0.0002)
    """

    def __init__(self) -> None:
        """Start with no window."""
        self._first: OrderSpectrum | None = None
        self._line_amps: list[dict[str, float]] = []
        self._line_phases: list[dict[str, float]] = []
        self._revs: list[float] = []
        self._out_hz: list[float] = []
        self._crank_hz: list[float] = []
        self._sum: FloatArray | None = None
        self._ref_orders: FloatArray | None = None
        self._same_grid = True
        self._longest: tuple[float, FloatArray, FloatArray] | None = None

    def add(self, spectrum: OrderSpectrum) -> None:
        """Fold in the spectrum of one complete window (it is not kept)."""
        if self._first is None:
            self._first = spectrum.lines_only()
        self._line_amps.append({ln.label: ln.amplitude_rad for ln in spectrum.lines})
        self._line_phases.append({ln.label: ln.phase_rad for ln in spectrum.lines})
        self._revs.append(float(spectrum.revolutions))
        self._out_hz.append(float(spectrum.output_hz))
        self._crank_hz.append(float(spectrum.crank_hz))
        orders = np.asarray(spectrum.orders, dtype=np.float64)
        amp = np.asarray(spectrum.amplitude_rad, dtype=np.float64)
        if self._longest is None or spectrum.revolutions > self._longest[0]:
            self._longest = (float(spectrum.revolutions), orders.copy(), amp.copy())
        if self._sum is None or self._ref_orders is None:
            self._sum = amp.copy()
            self._ref_orders = orders.copy()
            return
        # windows of the same length share the order grid m / R up to their own Nyquist order
        size = min(self._sum.size, amp.size)
        if self._same_grid and not np.allclose(orders[:size], self._ref_orders[:size]):
            self._same_grid = False
        self._sum = self._sum[:size] + amp[:size]
        self._ref_orders = self._ref_orders[:size]

    def result(self) -> SpectrumSummary | None:
        """The average so far, or None when no window was added."""
        first = self._first
        if first is None or self._sum is None or self._ref_orders is None \
                or self._longest is None:
            return None
        n = len(self._revs)
        # lines are matched by label: a line above a window's Nyquist order is missing there
        labels = [ln.label for ln in first.lines
                  if all(ln.label in d for d in self._line_amps)]
        amps = np.array([[d[lab] for lab in labels] for d in self._line_amps],
                        dtype=np.float64).reshape(n, len(labels))
        phases = np.array([[d[lab] for lab in labels] for d in self._line_phases],
                          dtype=np.float64).reshape(n, len(labels))
        mean_amp = amps.mean(axis=0)
        phasor = (amps * np.exp(1j * phases)).mean(axis=0)
        revs = np.array(self._revs)
        out_hz = float(np.mean(self._out_hz))
        crank_hz = float(np.mean(self._crank_hz))
        by_label = {ln.label: ln for ln in first.lines}
        lines = tuple(
            replace(by_label[lab], amplitude_rad=float(mean_amp[k]),
                    phase_rad=float(np.angle(phasor[k])),
                    frequency_hz=float(by_label[lab].output_order * out_hz))
            for k, lab in enumerate(labels))
        what = 'the one complete window' if n == 1 else f'{n} complete windows'
        if self._same_grid:
            orders = self._ref_orders.copy()
            amp = self._sum / n
            method = (f'mean of {what} ({revs.sum():.3g} output revolution(s)): line amplitude '
                      '= mean of the per-window peak amplitudes, phase = angle of the mean '
                      'phasor')
        else:
            orders = self._longest[1].copy()
            amp = self._longest[2].copy()
            method = (f'lines: mean of {what}; full spectrum: the longest window '
                      f'({float(revs.max()):.3g} output revolutions; window grids differ)')
        orders.setflags(write=False)
        amp.setflags(write=False)
        return SpectrumSummary(
            method=method, n_windows=n, output_hz=out_hz, crank_hz=crank_hz,
            revolutions=float(revs.sum()), lines=lines,
            amplitude_spread_rad=tuple(float(x) for x in amps.std(axis=0)),
            orders=orders, amplitude_rad=amp)


def dominant_harmonic(spectrum: SpectrumSummary,
                      bench: BenchDescription) -> DominantHarmonic | None:
    """The labelled line with the largest averaged amplitude and its likely source."""
    if not spectrum.lines:
        return None
    k = int(np.argmax([ln.amplitude_rad for ln in spectrum.lines]))
    line = spectrum.lines[k]
    return DominantHarmonic(line=line, likely_source=likely_source(line.output_order, bench))


def likely_source(output_order: float, bench: BenchDescription) -> str:
    """Name the likely physical source of a TE harmonic.

    Args:
        output_order: Cycles per output revolution of the harmonic.
        bench: Crank order, mesh orders and reducer type.

    Returns:
        One sentence for people.
    """
    o = abs(float(output_order))
    cpo = bench.crank_per_output

    def near(a: float, b: float) -> bool:
        return abs(a - b) <= _ORDER_RTOL * max(1.0, abs(b))

    for mo, label in zip(bench.mesh_orders_out, bench.mesh_labels, strict=False):
        if near(o, mo):
            return f'tooth profile / pitch error of the {label or "gear mesh"} (mesh order)'
    crank = 'crankshaft (eccentric) eccentricity or crank bearing clearance'
    if bench.reducer_type == '2kv' or not bench.reducer_type:
        crank = 'crank / 2nd-stage planet eccentricity (eccentric error, crank bearing clearance)'
    if near(o, cpo):
        return f'{crank} (once per crank revolution, 1 f_w)'
    if near(o, 1.0):
        return ('output-wheel (carrier) eccentricity or pin-circle / ring run-out '
                '(once per output revolution, f_out)')
    if near(o, cpo - 1.0) or near(o, cpo + 1.0):
        return ('crank eccentricity modulated by output-wheel eccentricity or pin-circle error '
                '(f_w +/- f_out sideband)')
    ratio = o / cpo
    if ratio > 1.5 and near(ratio, round(ratio)):  # noqa: PLR2004 - 2 f_w and above
        return (f'{round(ratio)}x per crank revolution: phase mismatch between the crank '
                'eccentrics, eccentric form error or crank bearing waviness')
    if near(o, round(o)):
        return (f'{round(o)}x per output revolution: output bearing / pin-circle form error')
    return 'not assigned to a known order'


def _recommend(bench: BenchDescription, cumulative: TeStats, folded: FoldedTe | None,
               search: tuple[float, bool] = (10.0, False)) -> Recommendation:
    """Ask the compensation code for advice on the bench's preset (lazy imports).

    * ``wang2020-2kv`` model: eccentricities and assembly phases identified from the
      measured TE folded on theta_in / i (``core.identify``; withheld on a poor fit, with
      the fit quality), else, with nothing to identify from, the Eq. 21 optimisation on the
      preset's own eccentricities (``core.phases``; then the advice is model-based);
    * ``hu2020-rv`` model: tooth-profile compensation for the measured TE peak-to-peak
      over all clean samples (``core.tooth_compensation``);
    * any other preset: no compensation model.
    """
    if not bench.preset:
        return Recommendation(available=False, reason='no recommendation available: the bag '
                              'has no BenchInfo preset, so there is no reducer model')
    from rv_te_bench.io.bench_record import preset_from_bench_info  # noqa: PLC0415
    from sim.errors import SimError  # noqa: PLC0415

    try:
        preset = preset_from_bench_info(bench.preset, bench.parameters_yaml)
    except SimError as exc:
        return Recommendation(available=False, reason=(
            f'no recommendation available: preset {bench.preset!r} cannot be loaded ({exc})'))
    kind = advice_kind(preset.model)
    try:
        if kind == 'assembly-phases':
            return _advice_2kv(preset, folded, search)
        if kind == 'tooth-profile':
            from rv_te_bench.core.tooth_compensation import (  # noqa: PLC0415
                tooth_profile_advice,
            )

            # Hu 2020 compensates the TE "value for a period", a peak-to-peak value.
            advice = tooth_profile_advice(preset, cumulative.pp_rad, te_metric='pp')
            return Recommendation(available=True, reason=(
                'tooth-profile compensation (Hu 2020 Eqs 24-27) for the measured TE '
                'peak-to-peak'), advice=advice)
    except (RvTeError, SimError) as exc:
        return Recommendation(available=False, reason=(
            f'no recommendation available for preset {bench.preset!r}: {exc}'))
    return Recommendation(available=False, reason=(
        f'no recommendation available: preset {bench.preset!r} (model {preset.model!r}) has '
        'no compensation model'))


def _advice_2kv(preset: Any, folded: FoldedTe | None,  # noqa: ANN401
                search: tuple[float, bool]) -> Recommendation:
    """Identified assembly phases when possible, else the model-based Eq. 21 optimum;
    ``search`` = (grid step [deg], refine) for both."""
    from rv_te_bench.core.identify import PoorFitError, identified_advice  # noqa: PLC0415
    from rv_te_bench.core.phases import optimise_phases  # noqa: PLC0415
    from sim.wang2020 import Wang2kvParams  # noqa: PLC0415

    params = Wang2kvParams.from_preset(preset)
    if folded is not None and folded.n_samples > 0:
        try:
            advice = identified_advice(folded, None, params, preset_name=preset.name,
                                       step_deg=search[0], refine=search[1])
        except PoorFitError as exc:
            return Recommendation(available=False, reason=str(exc),
                                  identification=exc.identification.to_json_dict())
        return Recommendation(available=True, reason=(
            'assembly phases from eccentricities identified in the measured TE'),
            advice=advice, identification=advice.details.get('identification'))
    advice = optimise_phases(params, step_deg=search[0], refine=search[1]).to_advice(
        preset.name)
    return Recommendation(available=True, reason=(
        "Eq. 21 assembly-phase optimum for the preset's own eccentricities (model-based, "
        'not identified from this measurement)'), advice=advice)


def describe_identification(ident: dict[str, Any]) -> list[str]:
    """Lines for people about an identification (the JSON of ``Identification``): what one
    TE record identified, what rests on assumed part magnitudes, and the notes."""
    e, ph = ident['e_um'], ident['phases_deg']
    out = [f"identified from the TE (up to the label swap): Q1 = e_p1 + e_g {e['pair1']:.3f} um "
           f"at {ph['pair1']:.1f} deg, Q2 = e_p2 - e_g {e['pair2']:.3f} um at "
           f"{ph['pair2']:.1f} deg, E = e_ot {e['e_ot']:.3f} um at {ph['theta_ot']:.1f} deg"]
    assumed = ident.get('assumed_e_um') or {}
    if assumed and 'theta_g' in ph:
        mags = '/'.join(f'{assumed[k]:.3g}' for k in ('e_p1', 'e_p2', 'e_g'))
        out.append(f'theta_p1/theta_p2/theta_g {ph["theta_p1"]:.1f}/{ph["theta_p2"]:.1f}/'
                   f'{ph["theta_g"]:.1f} deg rest on the part magnitudes e_p1/e_p2/e_g = '
                   f'{mags} um (the preset\'s unless measured ones are given): one TE record '
                   'cannot separate planet and revolution eccentricity')
    out += [f'note: {n}' for n in ident.get('notes') or ()]
    return out


def compare_results(results: list[AnalysisResult]) -> list[dict[str, Any]]:
    """Comparison rows for several bags, the first one being the reference ("before").

    Args:
        results: Analyses in the order given on the command line.

    Returns:
        One dict per bag: cumulative statistics in arcmin, the dominant line, and the change
        of p-p and amplitude relative to the first bag (``*_change_pct``).
    """
    rows: list[dict[str, Any]] = []
    ref = results[0].cumulative if results else None
    for res in results:
        st = res.cumulative
        row: dict[str, Any] = {'bag': str(res.path), 'partial': res.partial,
                               **{k: v for k, v in stats_json(st).items()
                                  if k.endswith('_arcmin') or k in ('revolutions', 'n_samples')}}
        if res.dominant is not None:
            row['dominant_label'] = res.dominant.line.label
            row['dominant_amplitude_arcmin'] = _num(rad_to_arcmin(res.dominant.line.amplitude_rad))
        else:
            row['dominant_label'] = None
            row['dominant_amplitude_arcmin'] = None
        if ref is not None:
            row['te_pp_change_pct'] = _pct(st.pp_rad, ref.pp_rad)
            row['te_amplitude_change_pct'] = _pct(st.amplitude_rad, ref.amplitude_rad)
        rows.append(row)
    return rows


# --------------------------------------------------------------------------------------
# helpers


def _line_json(line: SpectrumLine, spread_rad: float) -> dict[str, Any]:
    out = {
        'label': line.label,
        'output_order': _num(line.output_order),
        'crank_order': _num(line.crank_order),
        'frequency_hz': _num(line.frequency_hz),
        'amplitude_arcmin': _num(rad_to_arcmin(line.amplitude_rad)),
        'amplitude_rad': _num(line.amplitude_rad),
        'phase_rad': _num(line.phase_rad),
        'phase_deg': json_deg(line.phase_rad),
    }
    if math.isfinite(spread_rad):
        out['amplitude_spread_arcmin'] = _num(rad_to_arcmin(spread_rad))
    return out


def _pct(value: float, ref: float) -> float | None:
    if not (math.isfinite(value) and math.isfinite(ref)) or ref == 0:
        return None
    return 100.0 * (value - ref) / ref


def _num(x: Any) -> float | None:  # noqa: ANN401 - numpy scalars and floats
    v = float(x)
    return v if math.isfinite(v) else None


def _jsonable(v: Any) -> Any:  # noqa: ANN401
    if isinstance(v, np.generic):
        return v.item()
    if isinstance(v, dict):
        return {str(k): _jsonable(x) for k, x in v.items()}
    if isinstance(v, list | tuple):
        return [_jsonable(x) for x in v]
    return v
