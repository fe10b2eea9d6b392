"""Offline analysis of recorded sessions: bag(s) -> :class:`AnalysisResult`.

One bag is read an MCAP chunk at a time (:func:`rv_te_bench.io.bag_reader.read_encoder_batches`),
fed to the TE core (:func:`rv_te_bench.core.offline.analyze_blocks`, the same windowing the TE
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

This module is the orchestration; the pieces live in their own modules and are re-exported
here: the result types and their JSON in :mod:`rv_te_bench.report.results`, the spectrum
average in :mod:`rv_te_bench.core.spectrum` (:class:`SpectrumAverager`,
:class:`SpectrumSummary`), the block guard and TE trace in :mod:`rv_te_bench.report._guarded`.
"""

from __future__ import annotations

import datetime
import math
import time
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from rv_te_bench.core.advice import advice_kind
from rv_te_bench.core.advice_gate import (
    check_cause,
    is_mesh_line,
    likely_source,
    withheld_without_revolution,
)
from rv_te_bench.core.angle_fold import AngleFold
from rv_te_bench.core.encoder_attribution import OncePerRevNote, once_per_rev_note
from rv_te_bench.core.envelope import MinMaxEnvelope
from rv_te_bench.core.head_combine import HeadCombiner, combine_stream
from rv_te_bench.core.orders import OrderSet
from rv_te_bench.core.spectrum import SpectrumAverager, SpectrumSummary
from rv_te_bench.core.units import json_float
from rv_te_bench.errors import (
    BagError,
    BenchInfoError,
    EncoderCalibrationError,
    HeadLayoutError,
    RvTeError,
    TeConfigError,
)
from rv_te_bench.io.session_heads import choose_calibration
from rv_te_bench.report._guarded import _GuardedBlocks
from rv_te_bench.report.results import (
    AnalysisBench,
    AnalysisResult,
    DominantHarmonic,
    Recommendation,
    SessionInfo,
    TeTrace,
    report_title,
    stats_json,
)
from rv_te_bench.report.uncertainty import analysis_uncertainty
from sim.units import rad_to_arcmin

if TYPE_CHECKING:
    from collections.abc import Callable

    from rv_te_bench.core.angle_fold import FoldedTe
    from rv_te_bench.core.bench_uncertainty import BenchUncertainty
    from rv_te_bench.core.encoder_calibration import EncoderCalibration
    from rv_te_bench.core.identification import IdentificationJson
    from rv_te_bench.core.stream_records import WindowResult
    from rv_te_bench.core.te import TeStats
    from sim.bench_info import BenchInfoData
    from sim.presets import Preset

    ProgressFn = Callable[[int, int, float], None]

__all__ = [
    'AnalysisBench',
    'AnalysisResult',
    'DominantHarmonic',
    'Recommendation',
    'SessionInfo',
    'SpectrumAverager',
    'SpectrumSummary',
    'TeTrace',
    'analysis_path',
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

#: The problem of a record without a complete output revolution (no spectrum).
NO_WHOLE_REVOLUTION = ('no complete output revolution without a gap: no spectrum, and the '
                       'statistics do not cover whole revolutions')


def session_info(path: str | Path) -> SessionInfo:
    """The session of a bag from its metadata (never raises: falls back to the path)."""
    from rv_te_bench.io.bag_reader import open_bag

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
                       unit_serial=str(custom.get('unit_serial') or ''),
                       operator=str(custom.get('operator') or ''),
                       temperature_c=str(custom.get('temperature_c') or ''),
                       unit_notes=str(custom.get('unit_notes') or ''),
                       imported_from=str(custom.get('imported_from') or ''))


def analysis_path(path: str | Path) -> Literal['helper', 'one thread', 'machine decides']:
    """Which of its two paths :func:`analyze_bag` takes for the bag at ``path``:
    ``'one thread'`` (everything on the calling thread) where one core is allowed or the
    bag's files hold less than ``HELPER_MIN_BAG_BYTES``; else ``'machine decides'``: it
    starts on one thread and starts the helper thread (reading ahead, window spectra) after
    ~40 ms if the machine has room for it (:mod:`rv_te_bench.io._cores`); ``'helper'``
    from the start with ``RV_TE_READ_AHEAD=1`` (``0``: one thread). Never raises: a bag
    that cannot be opened gets the one-thread path (its analysis reports why)."""
    from rv_te_bench.io._cores import analysis_uses_helper, helper_forced
    from rv_te_bench.io.bag_reader import open_bag

    try:
        size = sum(f.stat().st_size for f in open_bag(path).files)
    except (BagError, OSError):
        return 'one thread'
    if not analysis_uses_helper(size):
        return 'one thread'
    return 'helper' if helper_forced() else 'machine decides'


def analyze_bag(
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
    heads_mode: str = 'average',
    calibration: EncoderCalibration | None = None,
    session_calibration: bool = True,
    te_zero: str = 'auto',
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
        heads_mode: How a scale's read heads form its angle: ``'average'`` (equal-division
            averaging of every head the bag holds) or ``'head0'`` (head 0 alone).
        calibration: A calibration of the output scale to take off its readings (checked
            against the scale serial in BenchInfo, valid on the session's day).
        session_calibration: With no ``calibration``, take off the one the session's TE
            node applied live (its ``te/encoder_heads`` record in the bag), so that the
            offline TE is the live one; the report says where it came from.
        te_zero: The TE's zero (:mod:`rv_te_bench.core.te_zero`): ``'auto'`` (the encoder
            zeros the bench declares, else the first clean sample), ``'encoders'`` or
            ``'first-sample'``; the result's ``te_reference`` states which was used.

    Returns:
        The analysis; ``partial`` is set when a read error ended the bag early.

    Raises:
        BagError: The bag cannot be opened, has no encoder topic, or no block could be read.
        TeConfigError: Ratio/crank order missing (no BenchInfo and no flags) or invalid;
            head angles that cannot be averaged (HeadLayoutError); a calibration for
            another scale or expired (EncoderCalibrationError).
    """
    from rv_te_bench.core.offline import analyze_blocks
    from rv_te_bench.core.plausibility import check_measured_ratio
    from rv_te_bench.core.stream_records import TeAnalysisConfig
    from rv_te_bench.core.te_zero import TeZero
    from rv_te_bench.io._helper import HelperThread
    from rv_te_bench.io.bag_reader import (
        open_bag,
        read_encoder_batches,
        summarize_problems,
    )
    from rv_te_bench.io.bench_record import encoder_zero_of

    t_start = time.monotonic()
    path = Path(path)
    if not path.exists():
        msg = f'{path}: no such bag'
        raise BagError(msg)
    info, info_problem = _read_bench_info(path, gear_ratio, crank_per_output)
    bench = _analysis_bench(path, info, gear_ratio, crank_per_output, n_crank_harmonics)
    config = TeAnalysisConfig(orders=bench.orders, window_revolutions=window_revolutions)
    session = session_info(path)
    when = _session_day(session.started_utc)
    calibration, cal_source, cal_problems = choose_calibration(
        path, info, calibration, from_session=session_calibration, when=when)
    combiner = _combiner(path, info, heads_mode, calibration, when)
    zero = TeZero(te_zero, gear_ratio=bench.gear_ratio, declared=encoder_zero_of(info))

    # one helper thread reads the bag ahead and computes window spectra: with the caller,
    # two runnable threads on two cores (a third preempts the caller: issue 23); where one
    # core is allowed (affinity, cgroup quota), or the bag is too small for the helper to
    # pay, no thread at all, no read-ahead; else it starts once the machine is seen to
    # have room for it, one thread meanwhile (issue 41)
    plan = analysis_path(path)
    helper = None if plan == 'one thread' else HelperThread(decide=plan == 'machine decides')
    try:
        stream = read_encoder_batches(path, topic, strict=False, executor=helper,
                                      read_ahead=helper is not None, merge=True)
        # a 2K-V unit is identified from every sample, folded on theta_in / i as it is read
        fold = AngleFold() if with_advice and bench.reducer_type == '2kv' else None
        # the shaft angles formed from the read heads (and the calibration) before anything
        items = stream if combiner is None else combine_stream(stream, combiner)
        if helper is not None:      # (it may start when the machine has room)
            items = helper.watch(items)
        reader = _GuardedBlocks(zero.stream(items), bench.gear_ratio, progress=progress,
                                t_start=t_start, fold=fold, max_points=MAX_TRACE_POINTS)
        averager = SpectrumAverager()
        kept: list[WindowResult] = []

        def on_window(w: WindowResult) -> None:
            # fold the spectrum into the average; keep the window without its per-bin arrays
            if w.spectrum is not None:
                if w.complete:
                    averager.add(w.spectrum)
                w = replace(w, spectrum=w.spectrum.lines_only())
            kept.append(w)

        envelope = MinMaxEnvelope()
        offline = analyze_blocks(reader, config, on_window=on_window,
                                 spectra_thread=False if helper is None else helper,
                                 envelope=envelope)
    finally:
        if helper is not None:
            helper.shutdown(wait=True, cancel_futures=True)
    read_problems = [*([] if info_problem is None else [info_problem]),
                     *stream.problems,
                     *([] if reader.error is None else [reader.error])]
    if reader.blocks == 0:
        detail = summarize_problems(read_problems) or 'the encoder topic holds no messages'
        msg = f'{path}: no encoder block could be read ({detail})'
        raise BagError(msg)

    wrong = check_measured_ratio(*reader.advance(), bench.gear_ratio,
                                 names=('theta_in_rad', 'theta_out_rad'))
    if wrong is not None:     # swapped encoders: a TE of millions of arcmin is no result
        msg = f'{path}: {wrong}'
        raise BagError(msg)
    partial = bool(read_problems) or stream.partial
    problems = list(open_bag(path).notes)   # unlisted files ignored, what was not written
    problems.extend(cal_problems)
    if partial:
        problems.append(f'{reader.blocks} blocks read; part of the bag is unreadable: '
                        + summarize_problems(read_problems))
    windows = tuple(kept)
    spectrum = averager.result()
    if spectrum is None:
        problems.append(NO_WHOLE_REVOLUTION)
    dominant = None if spectrum is None else dominant_harmonic(spectrum, bench)
    trace = replace(reader.trace(), envelope=envelope.data())
    uncertainty = analysis_uncertainty(info=bench.info, gear_ratio=bench.gear_ratio,
                                       windows=windows, cumulative=offline.cumulative,
                                       spectrum=spectrum, trace=trace)
    withheld = _advice_withheld(offline.cumulative, spectrum) if with_advice else None
    recommendation = (
        Recommendation(available=False, reason='not requested (--no-advice)')
        if not with_advice else
        Recommendation(available=False, reason=withheld) if withheld is not None else
        _agree_with_diagnosis(
            _recommend(bench, offline.cumulative, None if fold is None else fold.result(),
                       advice_search, uncertainty.bench), dominant, bench))
    note = _once_per_rev(info, spectrum, combiner, calibration)
    encoder: dict[str, Any] = {'once_per_rev': note.to_plain()}
    if combiner is not None:
        encoder['heads'] = combiner.report()
        if cal_source:
            encoder['calibration_source'] = cal_source
            out = encoder['heads']['output']
            out['description'] = f"{out['description']} ({_SOURCES[cal_source]})"
        missing = combiner.counters['blocks_head_missing']
        if missing:
            problems.append(f'{missing} blocks lacked read heads: their angle came from the '
                            'heads they had (windows closed there; see encoder.heads.events)')
    if dominant is not None and abs(dominant.line.output_order - 1.0) < 1e-6:
        dominant = replace(dominant, likely_source=f'{dominant.likely_source}. {note.text()}')
    if note.comparable and not note.separated and recommendation.available:
        recommendation = replace(recommendation, encoder_flag=note.text())
    return AnalysisResult(
        path=path, topic=topic, bench=bench, windows=windows,
        cumulative=offline.cumulative, spectrum=spectrum, dominant=dominant,
        gaps=tuple(offline.gaps), counters=dict(offline.counters), trace=trace,
        recommendation=recommendation, partial=partial,
        problems=tuple(problems), blocks_read=reader.blocks,
        elapsed_s=time.monotonic() - t_start, read_problems=tuple(read_problems),
        session=session, encoder=encoder, uncertainty=uncertainty,
        te_reference=zero.reference)


#: Where the output calibration applied offline came from, for people.
_SOURCES = {'file': 'from --calibration',
            'session': "as the session's TE node applied it live, from te/encoder_heads in "
                       'the bag; --no-session-calibration leaves it out'}


def _session_day(started_utc: str) -> datetime.date | None:
    """The day a session was recorded (None: unknown -> today)."""
    try:
        return datetime.date.fromisoformat(started_utc[:10])
    except ValueError:
        return None


def _combiner(path: Path, info: BenchInfoData | None, mode: str,
              calibration: EncoderCalibration | None,
              when: datetime.date | None = None) -> HeadCombiner | None:
    """The head combination of a bag (None: nothing to do).

    Raises:
        EncoderCalibrationError: A calibration for a bag without BenchInfo (no serial to
            check it against), for another scale, or expired.
        HeadLayoutError: BenchInfo's head angles cannot be averaged.
    """
    if info is None:
        if calibration is not None:
            msg = (f'{path}: the bag has no BenchInfo, so the scale serial the calibration of '
                   f'{calibration.scale_serial!r} is for cannot be checked: not applied')
            raise EncoderCalibrationError(msg)
        return None
    try:
        return HeadCombiner(info, mode=mode, calibration_out=calibration, when=when)
    except HeadLayoutError as exc:
        msg = (f'{path}: {str(exc).rstrip(".")}; the bag is intact: analyse head 0 alone '
               'with --heads head0')
        raise HeadLayoutError(msg) from None


def _once_per_rev(info: BenchInfoData | None, spectrum: SpectrumSummary | None,
                  combiner: HeadCombiner | None,
                  calibration: EncoderCalibration | None) -> OncePerRevNote:
    """What the output encoder could put on the measured once-per-revolution line."""
    from rv_te_bench.core.bench_uncertainty import default_encoder_errors

    line = math.nan
    if spectrum is not None:
        for ln in spectrum.lines:
            if abs(ln.output_order - 1.0) < 1e-6:
                line = ln.amplitude_rad
    scale = None if combiner is None else combiner.scales['out']
    layout = scale.layout if scale is not None and scale.mode == 'average' else None
    return once_per_rev_note(
        line_rad=line,
        eccentricity_m=0.0 if info is None else info.encoder_out_scale_eccentricity_m,
        diameter_m=0.0 if info is None else info.encoder_out_scale_diameter_m,
        error_model=(None if info is None or not info.encoder_out_model
                     else default_encoder_errors(info.encoder_out_model,
                                                 info.encoder_out_resolution_rad)),
        layout=layout, calibration=calibration)


def _read_bench_info(path: Path, gear_ratio: float | None, crank_per_output: float | None,
                     ) -> tuple[BenchInfoData | None, str | None]:
    """(BenchInfo, problem): a damaged chunk holding BenchInfo does not block a bag whose
    ratio and crank order are given (--ratio, --crank-per-output); the result is partial."""
    from rv_te_bench.io.bag_reader import read_bench_info

    try:
        return read_bench_info(path), None
    except BenchInfoError as exc:
        # only here does the hint help: the messages are readable, BenchInfo is not (a bag
        # that is no readable bag, a bad metadata.yaml, a FIFO... raise as they are)
        if gear_ratio is None or crank_per_output is None:
            msg = (f'{str(exc).rstrip(".")}; pass --ratio and --crank-per-output to analyse '
                   'the rest of the bag')
            raise BagError(msg) from None
        return None, 'no readable BenchInfo (damaged): --ratio and --crank-per-output used'


def _analysis_bench(path: Path, info: BenchInfoData | None, gear_ratio: float | None,
                    crank_per_output: float | None, n_crank_harmonics: int) -> AnalysisBench:
    """The bag's BenchInfo with the command-line overrides over it."""
    if info is None:
        missing = [flag for flag, v in (('--ratio', gear_ratio),
                                        ('--crank-per-output', crank_per_output)) if v is None]
        if missing:
            msg = (f'{path}: the bag has no BenchInfo message (bench/info), so the gear ratio '
                   f'and crank order are unknown; pass {" and ".join(missing)}')
            raise TeConfigError(msg)
        assert gear_ratio is not None and crank_per_output is not None
        source = 'cli'
    else:
        given = gear_ratio is not None or crank_per_output is not None
        source = 'bench_info+cli' if given else 'bench_info'
    try:
        if info is None:
            assert gear_ratio is not None and crank_per_output is not None   # (checked above)
            orders = OrderSet(gear_ratio=float(gear_ratio),
                              crank_per_output=float(crank_per_output),
                              n_crank_harmonics=n_crank_harmonics)
        else:
            orders = OrderSet.from_bench_info(info, n_crank_harmonics, gear_ratio=gear_ratio,
                                              crank_per_output=crank_per_output)
    except TeConfigError as exc:
        msg = f'{str(exc).rstrip(".")} (source: {source})'
        raise TeConfigError(msg) from None
    return AnalysisBench(source=source, orders=orders, info=info)


def dominant_harmonic(spectrum: SpectrumSummary,
                      bench: AnalysisBench) -> DominantHarmonic | None:
    """The labelled line with the largest averaged amplitude and its likely source."""
    if not spectrum.lines:
        return None
    k = int(np.argmax([ln.amplitude_rad for ln in spectrum.lines]))
    line = spectrum.lines[k]
    return DominantHarmonic(line=line, likely_source=likely_source(
        line.output_order, bench.orders, bench.reducer_type))


def _recommend(bench: AnalysisBench, cumulative: TeStats, folded: FoldedTe | None,
               search: tuple[float, bool] = (10.0, False),
               uncertainty: BenchUncertainty | None = None) -> Recommendation:
    """Ask the compensation code for advice on the bench's preset (lazy imports).

    * ``wang2020-2kv`` model: eccentricities and assembly phases identified from the
      measured TE folded on theta_in / i (``core.identify``; withheld on a poor fit, with
      the fit quality), else, with nothing to identify from, the Wang 2020 Eq. 21
      optimisation on the preset's own eccentricities (``core.phases``; then the advice is
      model-based);
    * ``hu2020-rv`` model: tooth-profile compensation for the measured TE peak-to-peak
      over all clean samples (``core.tooth_compensation``);
    * any other preset: no compensation model.
    """
    if bench.info is None or not bench.info.preset:
        return Recommendation(available=False, reason='no recommendation available: the bag '
                              'has no BenchInfo preset, so there is no reducer model')
    from rv_te_bench.io.bench_record import preset_from_bench_info
    from sim.errors import SimError

    try:
        preset = preset_from_bench_info(bench.info)
    except SimError as exc:
        return Recommendation(available=False, reason=(
            f'no recommendation available: preset {bench.preset!r} cannot be loaded ({exc})'))
    kind = advice_kind(preset.model)
    try:
        if kind == 'assembly-phases':
            return _advice_2kv(preset, folded, search, uncertainty, bench.gear_ratio)
        if kind == 'tooth-profile':
            from rv_te_bench.core.tooth_compensation import (
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


def _advice_withheld(cumulative: TeStats, spectrum: SpectrumSummary | None) -> str | None:
    """Why the data cannot carry advice, or None (:mod:`rv_te_bench.core.advice_gate`)."""
    return withheld_without_revolution(cumulative.revolutions, spectrum is not None)


def _agree_with_diagnosis(rec: Recommendation, dominant: DominantHarmonic | None,
                          bench: AnalysisBench) -> Recommendation:
    """The advice and the diagnosis name the same cause, or the advice says why not
    (:func:`rv_te_bench.core.advice_gate.check_cause`, the compensation node's gate too)."""
    if not rec.available or rec.advice is None or dominant is None:
        return rec
    line = dominant.line
    gate = check_cause(rec.advice.method, label=line.label, amplitude_rad=line.amplitude_rad,
                       source=dominant.likely_source,
                       mesh=is_mesh_line(line.output_order, bench.orders))
    if gate.withheld is not None:
        return Recommendation(available=False, reason=gate.withheld,
                              identification=rec.identification)
    if gate.note:
        return replace(rec, reason=f'{rec.reason}; {gate.note}')
    return rec


def _advice_2kv(preset: Preset, folded: FoldedTe | None, search: tuple[float, bool],
                uncertainty: BenchUncertainty | None = None,
                gear_ratio: float = math.nan) -> Recommendation:
    """Identified assembly phases when possible, else the model-based Wang 2020 Eq. 21
    optimum; ``search`` = (grid step [deg], refine) for both."""
    from rv_te_bench.core.identify import PoorFitError, identified_advice
    from rv_te_bench.core.phases import optimise_phases
    from sim.wang2020 import Wang2kvParams

    params = Wang2kvParams.from_preset(preset)
    if folded is not None and folded.n_samples > 0:
        try:
            advice = identified_advice(folded, None, params, preset_name=preset.name,
                                       step_deg=search[0], refine=search[1],
                                       uncertainty=uncertainty,
                                       gear_ratio=gear_ratio)
        except PoorFitError as exc:
            return Recommendation(available=False, reason=str(exc),
                                  identification=exc.identification.to_json_dict())
        return Recommendation(available=True, reason=(
            'assembly phases from eccentricities identified in the measured TE'),
            advice=advice, identification=advice.details.get('identification'))
    advice = optimise_phases(params, step_deg=search[0], refine=search[1]).to_advice(
        preset.name)
    return Recommendation(available=True, reason=(
        "Wang 2020 Eq. 21 assembly-phase optimum for the preset's own eccentricities "
        '(model-based, not identified from this measurement)'), advice=advice)


def describe_identification(ident: IdentificationJson) -> list[str]:
    """Lines for people about an identification (the JSON of ``Identification``): what one
    TE record identified, what rests on assumed part magnitudes, and the notes."""
    e, ph = ident['e_um'], ident['phases_deg']
    ue, up = ident.get('u95_um') or {}, ident.get('u95_deg') or {}

    def um(k: str) -> str:
        return f'{e[k]:.3f}' + (f' +- {ue[k]:.2g}' if ue.get(k) is not None else '')

    def deg(k: str) -> str:
        return f'{ph[k]:.1f}' + (f' +- {up[k]:.2g}' if up.get(k) is not None else '')

    out = [f'identified from the TE (up to the label swap): Q1 = e_p1 + e_g {um("pair1")} um '
           f'at {deg("pair1")} deg, Q2 = e_p2 - e_g {um("pair2")} um at {deg("pair2")} deg, '
           f'E = e_ot {um("e_ot")} um at {deg("theta_ot")} deg'
           + (' (+- U, about 95 %)' if ue else '')]
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
    ref = results[0].cumulative if results and not results[0].not_te_record else None
    for res in results:
        st = res.cumulative
        row: dict[str, Any] = {'bag': str(res.path), 'partial': res.partial,
                               **{k: v for k, v in stats_json(st).items()
                                  if k.endswith('_arcmin') or k in ('revolutions', 'n_samples')}}
        if res.not_te_record:       # no TE to compare: its row says so, no numbers
            row.update({k: None for k in row if k.endswith('_arcmin')},
                       dominant_label=None, dominant_amplitude_arcmin=None,
                       te_pp_change_pct=None, te_amplitude_change_pct=None,
                       not_te_record=res.not_te_record)
            rows.append(row)
            continue
        if res.dominant is not None:
            row['dominant_label'] = res.dominant.line.label
            row['dominant_amplitude_arcmin'] = json_float(
                rad_to_arcmin(res.dominant.line.amplitude_rad))
        else:
            row['dominant_label'] = None
            row['dominant_amplitude_arcmin'] = None
        if ref is not None:
            row['te_pp_change_pct'] = _pct(st.pp_rad, ref.pp_rad)
            row['te_amplitude_change_pct'] = _pct(st.amplitude_rad, ref.amplitude_rad)
        else:               # the reference is not a TE record: nothing to refer to
            row['te_pp_change_pct'] = row['te_amplitude_change_pct'] = None
        rows.append(row)
    return rows


# --------------------------------------------------------------------------------------
# helpers


def _pct(value: float, ref: float) -> float | None:
    if not (math.isfinite(value) and math.isfinite(ref)) or ref == 0:
        return None
    return 100.0 * (value - ref) / ref
