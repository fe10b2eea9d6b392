"""The result types of the offline analysis and their JSON (unit-suffixed keys).

:class:`AnalysisResult` is what :func:`rv_te_bench.report.analysis.analyze_bag` returns for
one bag; the types are re-exported by :mod:`rv_te_bench.report.analysis`. Everything inside
is SI; arcminutes appear only in ``to_json_dict`` (keys ending in ``_arcmin``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypedDict

import numpy as np

from rv_te_bench.core.spectrum import SpectrumSummary, spectrum_line_json
from rv_te_bench.core.units import json_float
from rv_te_bench.report.trace import TeTrace
from sim.units import rad_to_arcmin

if TYPE_CHECKING:
    import numpy.typing as npt

    from rv_te_bench.core.advice import Advice
    from rv_te_bench.core.identification import IdentificationJson
    from rv_te_bench.core.orders import OrderSet
    from rv_te_bench.core.spectrum import SpectrumLine
    from rv_te_bench.core.stream_records import GapEvent, WindowResult
    from rv_te_bench.core.te import TeStats
    from rv_te_bench.core.te_zero import TeReference
    from rv_te_bench.report.uncertainty import AnalysisUncertainty
    from sim.bench_info import BenchInfoData

    FloatArray = npt.NDArray[np.float64]

__all__ = [
    'AnalysisBench',
    'AnalysisBenchJson',
    'AnalysisResult',
    'DominantHarmonic',
    'Recommendation',
    'RecommendationJson',
    'SessionInfo',
    'SpectrumSummary',
    'TeStatsJson',
    'TeTrace',
    'report_title',
    'stats_json',
]


class AnalysisBenchJson(TypedDict):
    """The analysis JSON's ``bench``: what the record says of its bench."""

    source: str
    bench_id: str
    preset: str
    reducer_type: str
    gear_ratio: float
    crank_per_output: float
    mesh_orders_out: list[float]
    mesh_labels: list[str]
    sample_rate_hz: float | None
    encoder_in_model: str
    encoder_out_model: str


class TeStatsJson(TypedDict):
    """TE statistics in the analysis JSON (None: not finite)."""

    te_pp_arcmin: float | None
    te_amplitude_arcmin: float | None
    te_mean_arcmin: float | None
    te_std_arcmin: float | None
    te_pp_rad: float | None
    te_amplitude_rad: float | None
    te_mean_rad: float | None
    te_std_rad: float | None
    revolutions: float | None
    n_samples: int


@dataclass(frozen=True)
class AnalysisBench:
    """The bench as the analysis of one bag uses it: the bag's record and the lines.

    Attributes:
        source: ``'bench_info'`` (from the bag), ``'cli'`` (from --ratio/--crank-per-output)
            or ``'bench_info+cli'`` (bag values overridden by flags).
        orders: Ratio, crank order and mesh lines the analysis reports (the bag's
            :meth:`OrderSet.from_bench_info <rv_te_bench.core.orders.OrderSet.from_bench_info>`,
            with the flags over it).
        info: The bag's ``BenchInfo`` record, None when the bag has none (or it is damaged).

    The record's fields read through the properties ('' / NaN / empty when unknown).
    """

    source: str
    orders: OrderSet
    info: BenchInfoData | None = None

    @property
    def gear_ratio(self) -> float:
        """Overall ratio i, input revolutions per output revolution."""
        return self.orders.gear_ratio

    @property
    def crank_per_output(self) -> float:
        """|Absolute crank revolutions per output revolution|."""
        return self.orders.crank_per_output

    @property
    def mesh_orders_out(self) -> tuple[float, ...]:
        """Mesh frequencies as orders of the output rotation."""
        return self.orders.mesh_orders_out

    @property
    def mesh_labels(self) -> tuple[str, ...]:
        """One label per mesh order."""
        return self.orders.mesh_labels

    @property
    def bench_id(self) -> str:
        """Bench id ('' when unknown)."""
        return '' if self.info is None else self.info.bench_id

    @property
    def preset(self) -> str:
        """Reducer preset name ('' when unknown)."""
        return '' if self.info is None else self.info.preset

    @property
    def reducer_type(self) -> str:
        """``'2kv'``, ``'rv'``, ``'other'`` or ''."""
        return '' if self.info is None else self.info.reducer_type

    @property
    def sample_rate_hz(self) -> float:
        """Nominal DAQ rate from BenchInfo (NaN when unknown or recorded as 0)."""
        return math.nan if self.info is None else (self.info.sample_rate_hz or math.nan)

    @property
    def encoder_in_model(self) -> str:
        """Input encoder model ('' when unknown)."""
        return '' if self.info is None else self.info.encoder_in_model

    @property
    def encoder_out_model(self) -> str:
        """Output encoder model ('' when unknown)."""
        return '' if self.info is None else self.info.encoder_out_model

    def to_json_dict(self) -> AnalysisBenchJson:
        """JSON-friendly dict (unit-suffixed keys)."""
        return {
            'source': self.source, 'bench_id': self.bench_id, 'preset': self.preset,
            'reducer_type': self.reducer_type, 'gear_ratio': self.gear_ratio,
            'crank_per_output': self.crank_per_output,
            'mesh_orders_out': list(self.mesh_orders_out), 'mesh_labels': list(self.mesh_labels),
            'sample_rate_hz': json_float(self.sample_rate_hz),
            'encoder_in_model': self.encoder_in_model,
            'encoder_out_model': self.encoder_out_model,
        }


@dataclass(frozen=True)
class DominantHarmonic:
    """The labelled line with the largest averaged amplitude and its likely source."""

    line: SpectrumLine
    likely_source: str

    def to_json_dict(self) -> dict[str, Any]:
        """JSON-friendly dict."""
        return {**spectrum_line_json(self.line, math.nan), 'likely_source': self.likely_source}


class RecommendationJson(TypedDict):
    """The analysis JSON's ``recommendation``."""

    available: bool
    reason: str
    advice: dict[str, Any] | None
    identification: IdentificationJson | None
    encoder_flag: str


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
    identification: IdentificationJson | None = None
    encoder_flag: str = ''

    def to_json_dict(self) -> RecommendationJson:
        """JSON-friendly dict (``encoder_flag``: why the advice may rest on the output
        encoder's once-per-revolution error, '' when it does not)."""
        return {'available': self.available, 'reason': self.reason,
                'advice': None if self.advice is None else self.advice.to_json_dict(),
                'identification': self.identification, 'encoder_flag': self.encoder_flag}


@dataclass(frozen=True)
class SessionInfo:
    """What the bag says about its session (metadata.yaml ``custom_data``).

    Attributes:
        name: ``session`` from the metadata, else the bag folder's name (its parent's when
            the folder is a generic ``bag``, as in ``bags/<session>/bag``).
        started_utc: When the recorder started ('' when unknown).
        unit_serial: Serial number of the unit under test (``unit_serial`` in the session
            metadata, e.g. ``--param recorder.session_metadata_yaml='unit_serial: SN-42'``).
        operator: ``operator`` in the session metadata ('' when unknown).
        temperature_c: ``temperature_c`` in the session metadata, as written ('' unknown).
        unit_notes: ``unit_notes`` in the session metadata (a bench description's notes).
        imported_from: ``imported_from``: the DAQ file ``rv-te import`` read ('' if none).
    """

    name: str
    started_utc: str = ''
    unit_serial: str = ''
    operator: str = ''
    temperature_c: str = ''
    unit_notes: str = ''
    imported_from: str = ''

    def to_json_dict(self) -> dict[str, Any]:
        """JSON-friendly dict (the optional fields only when known)."""
        out = {'name': self.name, 'started_utc': self.started_utc,
               'unit_serial': self.unit_serial}
        out.update({k: v for k, v in (('operator', self.operator),
                                      ('temperature_c', self.temperature_c),
                                      ('unit_notes', self.unit_notes),
                                      ('imported_from', self.imported_from)) if v})
        return out


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
        encoder: How the shaft angles were formed from the read heads and any calibration
            (``heads``: ``HeadCombiner.report()`` of :mod:`rv_te_bench.core.head_combine`)
            and what the output encoder could put on the once-per-revolution line
            (``once_per_rev``: :class:`~rv_te_bench.core.encoder_attribution.OncePerRevNote`).
        uncertainty: The budgets of the TE p-p and the lines (docs/UNCERTAINTY.md), None
            when not computed.
        te_reference: The zero the TE was referred to (encoder zeros or the first sample;
            :mod:`rv_te_bench.core.te_zero`), None when no sample was clean.
        not_te_record: Why the record is not a TE record (a locked-input hysteresis test:
            ``rv-te analyze`` finds its load cycles and no whole output revolution), one
            line; '' for a TE record. When set, no TE result is reported (JSON, text,
            report): the TE of a locked input is the output's torsion, not a TE.
        hysteresis: The record's lost motion, backlash and rigidity as ``rv-te analyze``
            read them (JSON-ready, SI keys), or None.
    """

    path: Path
    topic: str | None
    bench: AnalysisBench
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
    encoder: dict[str, Any] = field(default_factory=dict)
    uncertainty: AnalysisUncertainty | None = None
    te_reference: TeReference | None = None
    not_te_record: str = ''
    hysteresis: dict[str, Any] | None = None

    @property
    def complete_windows(self) -> tuple[WindowResult, ...]:
        """The windows that cover whole output revolutions."""
        return tuple(w for w in self.windows if w.complete)

    def to_json_dict(self) -> dict[str, Any]:
        """JSON-friendly dict with unit-suffixed keys (``te_pp_arcmin``, ``frequency_hz``).

        A record that is not a TE record has ``not_te_record`` (the reason) and no TE
        result: ``cumulative``, ``spectrum``, ``dominant``, ``te_reference`` and
        ``recommendation`` are null, ``windows`` is empty, no ``uncertainty``.
        """
        doc = self._json_dict()
        if self.not_te_record:
            doc.update(not_te_record=self.not_te_record, cumulative=None, windows=[],
                       spectrum=None, dominant=None, te_reference=None, recommendation=None)
            doc.pop('uncertainty', None)
        if self.hysteresis is not None:
            doc['hysteresis'] = self.hysteresis
        return doc

    def _json_dict(self) -> dict[str, Any]:
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
            'te_reference': (None if self.te_reference is None
                             else self.te_reference.to_json_dict()),
            'cumulative': {**stats_json(self.cumulative), **self._u95('te_pp_rad')},
            'windows': [{
                'index': int(w.index), 'complete': bool(w.complete),
                'start_stamp_s': json_float(w.start_stamp_s),
                'end_stamp_s': json_float(w.end_stamp_s),
                'first_seq': int(w.first_seq), 'last_seq': int(w.last_seq),
                **stats_json(w.stats)} for w in self.windows],
            'spectrum': None if self.spectrum is None else self._spectrum_json(),
            'dominant': None if self.dominant is None else self.dominant.to_json_dict(),
            'gaps': [{'kind': g.kind, 'seq': int(g.seq), 'detail': g.detail,
                      'at_s': g.at_s, 'missing_s': g.missing_s, 't_before_s': g.t_before_s,
                      't_after_s': g.t_after_s} for g in self.gaps],
            'counters': {k: _jsonable(v) for k, v in self.counters.items()},
            'recommendation': self.recommendation.to_json_dict(),
            'encoder': _jsonable(self.encoder),
            **({} if self.uncertainty is None
               else {'uncertainty': self.uncertainty.to_json_dict()}),
        }

    def _u95(self, name: str, key: str | None = None) -> dict[str, Any]:
        """``{key or name + '_u95': U}`` when the budget exists (else nothing)."""
        if self.uncertainty is None or name not in self.uncertainty.budgets:
            return {}
        return {key or f'{name}_u95': json_float(self.uncertainty.u95(name))}

    def _spectrum_json(self) -> dict[str, Any]:
        """The spectrum's JSON with each line's ``amplitude_rad_u95`` / ``phase_rad_u95``."""
        from rv_te_bench.report.uncertainty import line_budget_key

        assert self.spectrum is not None
        doc = self.spectrum.to_json_dict()
        for ln in doc['lines']:
            ln.update(self._u95(line_budget_key(ln['label'], 'amplitude'), 'amplitude_rad_u95'))
            ln.update(self._u95(line_budget_key(ln['label'], 'phase'), 'phase_rad_u95'))
        return doc


def stats_json(stats: TeStats) -> TeStatsJson:
    """TE statistics as a JSON dict in arcmin (and rad), keys carrying the unit."""
    return {
        'te_pp_arcmin': json_float(rad_to_arcmin(stats.pp_rad)),
        'te_amplitude_arcmin': json_float(rad_to_arcmin(stats.amplitude_rad)),
        'te_mean_arcmin': json_float(rad_to_arcmin(stats.mean_rad)),
        'te_std_arcmin': json_float(rad_to_arcmin(stats.std_rad)),
        'te_pp_rad': json_float(stats.pp_rad),
        'te_amplitude_rad': json_float(stats.amplitude_rad),
        'te_mean_rad': json_float(stats.mean_rad),
        'te_std_rad': json_float(stats.std_rad),
        'revolutions': json_float(stats.revolutions),
        'n_samples': int(stats.n_samples),
    }


# --------------------------------------------------------------------------------------
# analysis


def _jsonable(v: Any) -> Any:
    if isinstance(v, np.generic):
        return v.item()
    if isinstance(v, dict):
        return {str(k): _jsonable(x) for k, x in v.items()}
    if isinstance(v, list | tuple):
        return [_jsonable(x) for x in v]
    return v
