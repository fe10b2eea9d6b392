"""The uncertainty of an offline analysis's results (issue 35; docs/UNCERTAINTY.md).

Budgets of the TE p-p (over all clean samples, and the largest of one whole output
revolution), of every labelled line of the averaged spectrum (amplitude and phase), from
the core's budget functions (:mod:`rv_te_bench.core.te_uncertainty`) and the bench's
error model (:func:`bench_uncertainty_of`: the data-sheet defaults of the bag's encoder
models, with the bench description's ``uncertainty:`` section over them when the bag's
BenchInfo carries one).

What the streamed analysis does not keep, and how it is replaced:

* the positions of a revolution's TE maximum and minimum (the p-p's sensitivity to an
  encoder harmonic is 2 |sin(k Delta / 2)|, Delta the angle between them): taken from the
  analysis's TE trace folded onto one output revolution (720 bins; the pattern of a unit
  repeats every revolution); peaks within reach of the encoder errors of the extremes
  (a 2K-V's crank-order ripple) are candidates too, each harmonic at its largest
  sensitivity over them. Without a trace the bound 2 (extremes half a period apart);
* the samples per revolution: from the sample count and the revolutions.

Cost: a few milliseconds per bag (tens of budgets; benchmarks/README.md, offline analysis).
A Monte Carlo propagation of the budgets (GUM Supplement 1, :func:`monte_carlo_check`) is
never part of an analysis: it runs on request (``rv-te analyze --monte-carlo N``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, NotRequired, TypedDict

import numpy as np

from rv_te_bench.core.te_uncertainty import (
    extreme_candidates,
    extreme_reach,
    line_budgets,
    te_pp_budget,
)
from rv_te_bench.io.bench_record import bench_uncertainty_of

if TYPE_CHECKING:
    from rv_te_bench.core.bench_uncertainty import BenchUncertainty, BenchUncertaintyPlain
    from rv_te_bench.core.spectrum import SpectrumSummary
    from rv_te_bench.core.stream_records import WindowResult
    from rv_te_bench.core.te import TeStats
    from rv_te_bench.core.uncertainty import Budget
    from rv_te_bench.core.uncertainty_mc import McResult
    from rv_te_bench.report.trace import TeTrace
    from sim.bench_info import BenchInfoData

__all__ = ['AnalysisUncertainty', 'AnalysisUncertaintyJson', 'MonteCarloCheck',
           'MonteCarloJson', 'analysis_uncertainty',
           'bench_uncertainty_of', 'budget_html', 'display_of', 'line_budget_key',
           'monte_carlo_check']



def line_budget_key(label: str, what: str) -> str:
    """Name of a line's budget: ``'line <label> amplitude'`` / ``'... phase'``."""
    return f'line {label} {what}'


class McRowJson(TypedDict):
    """One budget's U by the law of propagation beside the Monte Carlo one (SI)."""

    u95_gum: float
    u95_mc: float
    difference: float
    low: float
    high: float
    std_mc: float
    u_c: float


class MonteCarloJson(TypedDict):
    """The JSON of :class:`MonteCarloCheck`."""

    draws: int
    notes: list[str]
    results: dict[str, McRowJson]


class AnalysisUncertaintyJson(TypedDict):
    """The analysis JSON's ``uncertainty``: every budget in full (the budgets' own JSON),
    the bench model, the TE p-p's U when there is a revolution, the Monte Carlo check when
    asked for."""

    coverage_probability: float | None
    notes: list[str]
    bench: BenchUncertaintyPlain
    budgets: dict[str, dict[str, Any]]
    te_pp_revolution_max_rad: NotRequired[float]
    te_pp_revolution_max_rad_u95: NotRequired[float]
    monte_carlo: NotRequired[MonteCarloJson]


@dataclass(frozen=True)
class AnalysisUncertainty:
    """The budgets of one analysis (SI; keys as in the analysis JSON).

    Attributes:
        bench: The bench's error model used.
        budgets: ``te_pp_rad`` (all clean samples), ``te_pp_revolution_max_rad`` (the
            largest p-p of one whole revolution), ``line <label> amplitude`` / ``phase``.
        notes: What was assumed for the whole analysis.
        monte_carlo: The Monte Carlo check of the budgets, when requested (None: not run).
    """

    bench: BenchUncertainty
    budgets: dict[str, Budget] = field(default_factory=dict)
    notes: tuple[str, ...] = ()
    monte_carlo: MonteCarloCheck | None = None

    def u95(self, name: str) -> float:
        """U of a budget (NaN when there is none)."""
        b = self.budgets.get(name)
        return math.nan if b is None else b.u95

    def to_json_dict(self) -> AnalysisUncertaintyJson:
        """JSON: every budget in full, the bench model, the values' U under ``*_u95``."""
        out: AnalysisUncertaintyJson = {'coverage_probability': None,
                                        'notes': list(self.notes),
                                        'bench': self.bench.to_plain(), 'budgets': {}}
        for name, b in self.budgets.items():
            out['budgets'][name] = b.to_json_dict()
            out['coverage_probability'] = b.coverage_probability
        rev = self.budgets.get('te_pp_revolution_max_rad')
        if rev is not None:
            out['te_pp_revolution_max_rad'] = rev.value
            out['te_pp_revolution_max_rad_u95'] = rev.u95
        if self.monte_carlo is not None:
            out['monte_carlo'] = self.monte_carlo.to_json_dict()
        return out


def _extremes(trace: TeTrace | None, reach_rad: float,
              ) -> tuple[tuple[float, float], list[tuple[float, float]]] | None:
    """The TE extremes of the trace (:func:`~.te_uncertainty.extreme_candidates`)."""
    if trace is None:
        return None
    th = np.asarray(trace.theta_out_rad, dtype=np.float64)
    te = np.asarray(trace.te_rad, dtype=np.float64)
    return extreme_candidates(th - te, te, reach_rad)


def analysis_uncertainty(*, info: BenchInfoData | None, gear_ratio: float,
                         windows: tuple[WindowResult, ...], cumulative: TeStats,
                         spectrum: SpectrumSummary | None,
                         trace: TeTrace | None) -> AnalysisUncertainty:
    """The budgets of an analysis's TE p-p and lines (see the module docstring)."""
    bench, notes = bench_uncertainty_of(info)
    complete = [w for w in windows if w.complete]
    pps = np.array([w.stats.pp_rad for w in complete], dtype=np.float64)
    pps = pps[np.isfinite(pps)]
    revs = cumulative.revolutions if math.isfinite(cumulative.revolutions) else math.nan
    spr = cumulative.n_samples / revs if math.isfinite(revs) and revs > 0 else math.nan
    reach = extreme_reach(bench, gear_ratio)
    found = _extremes(trace, reach)
    others: list[tuple[float, float]] = []
    if found is None:
        ext = (math.pi, 0.0)      # the bound: extremes half a revolution apart
        notes.append('positions of the TE extremes unknown (no trace): the p-p budgets use '
                     'the bound 2 g for every harmonic')
    else:
        ext, others = found
        if others:
            notes.append(f'{len(others) + 1} pairs of near-equal TE extremes (within '
                         f'{reach * 648000 / math.pi:.2g}" of the max and min): each encoder '
                         'harmonic at its largest sensitivity over them')
    dominant = None
    if spectrum is not None and spectrum.lines:
        big = max(spectrum.lines, key=lambda ln: ln.amplitude_rad)
        dominant = (big.amplitude_rad, big.output_order)
    budgets: dict[str, Budget] = {}

    def pp_budget(name: str, value: float) -> Budget:
        return te_pp_budget(name, value, phi_max_rad=ext[0], phi_min_rad=ext[1],
                            gear_ratio=gear_ratio, bench=bench, samples_per_rev=spr,
                            dominant=dominant, other_extremes=others,
                            per_revolution_rad=pps if pps.size >= 2 else None)

    if math.isfinite(cumulative.pp_rad):
        budgets['te_pp_rad'] = pp_budget('te_pp_rad', cumulative.pp_rad)
    if pps.size:
        budgets['te_pp_revolution_max_rad'] = pp_budget('te_pp_revolution_max_rad',
                                                        float(np.max(pps)))
    if spectrum is not None:
        per_window = [w.spectrum for w in complete if w.spectrum is not None]
        grid = per_window[0].samples_per_rev if per_window else math.nan
        for ln in spectrum.lines:
            amps, phs = [], []
            for sp in per_window:
                try:
                    x = sp.line(ln.label)
                except KeyError:
                    continue
                amps.append(x.amplitude_rad)
                phs.append(x.phase_rad)
            out_hz = ln.frequency_hz / ln.output_order if ln.output_order > 0 else math.nan
            a, p = line_budgets(ln.label, ln.amplitude_rad, ln.phase_rad, ln.output_order,
                                gear_ratio=gear_ratio, bench=bench, output_hz=out_hz,
                                window_amplitudes_rad=amps if len(amps) >= 2 else None,
                                window_phases_rad=phs if len(phs) >= 2 else None,
                                samples_per_rev=float(grid), n_samples=cumulative.n_samples)
            budgets[line_budget_key(ln.label, 'amplitude')] = a
            budgets[line_budget_key(ln.label, 'phase')] = p
    return AnalysisUncertainty(bench=bench, budgets=budgets, notes=tuple(notes))


@dataclass(frozen=True)
class MonteCarloCheck:
    """A Monte Carlo propagation (GUM Supplement 1) of an analysis's budgets, on request.

    Attributes:
        draws: Draws per budget.
        results: Budget name -> its :class:`~rv_te_bench.core.uncertainty_mc.McResult`.
        notes: What the check ran on.
    """

    draws: int
    results: dict[str, McResult] = field(default_factory=dict)
    notes: tuple[str, ...] = ()

    def to_json_dict(self) -> MonteCarloJson:
        """JSON (SI): each budget's U (law of propagation) beside the Monte Carlo one."""
        return {'draws': self.draws, 'notes': list(self.notes), 'results': {
            name: {'u95_gum': r.u_gum, 'u95_mc': r.u_mc, 'difference': r.difference,
                   'low': r.low, 'high': r.high, 'std_mc': r.std_mc, 'u_c': r.u_c}
            for name, r in self.results.items()}}


def monte_carlo_check(unc: AnalysisUncertainty, trace: TeTrace | None,
                      spectrum: SpectrumSummary | None, *, gear_ratio: float, draws: int,
                      seed: int = 0) -> MonteCarloCheck:
    """Propagate the TE p-p (largest of one revolution) and every line's budgets by Monte
    Carlo through the measurement model (:mod:`rv_te_bench.core.uncertainty_mc`), on the
    analysis's TE trace (the recorded samples thinned to at most
    ``report.analysis.MAX_TRACE_POINTS``; rows at gaps dropped): the encoders' error
    functions drawn at new phases and removed from the record, the p-p and the lines'
    phasors taken again. For validation or on request (``rv-te analyze --monte-carlo N``),
    never part of an analysis: it costs seconds to minutes.

    Raises:
        TeInputError: ``draws`` below 100, or no trace of a whole output revolution.
    """
    from rv_te_bench.core.uncertainty_mc import mc_line, mc_te_pp
    from rv_te_bench.errors import TeInputError

    if draws < 100:
        msg = f'a Monte Carlo check needs >= 100 draws, got {draws}'
        raise TeInputError(msg)
    if trace is None:
        msg = 'no TE trace in this analysis: nothing to propagate'
        raise TeInputError(msg)
    th = np.asarray(trace.theta_out_rad, dtype=np.float64)
    te = np.asarray(trace.te_rad, dtype=np.float64)
    ok = np.isfinite(th) & np.isfinite(te)
    th, te = th[ok], te[ok]
    phi = th - te
    if th.size < 16 or abs(float(phi[-1] - phi[0])) < 2 * math.pi:
        msg = 'the TE trace holds less than one whole output revolution'
        raise TeInputError(msg)
    rng = np.random.default_rng(seed)
    out: dict[str, McResult] = {}
    pp = unc.budgets.get('te_pp_revolution_max_rad')
    if pp is not None:
        out['te_pp_revolution_max_rad'] = mc_te_pp(pp, phi, te, gear_ratio=gear_ratio,
                                                   bench=unc.bench, draws=draws, rng=rng)
    travel = np.abs(phi - phi[0])
    whole = travel < 2 * math.pi * math.floor(float(travel[-1]) / (2 * math.pi))
    for ln in spectrum.lines if spectrum is not None else ():
        a = unc.budgets.get(line_budget_key(ln.label, 'amplitude'))
        p = unc.budgets.get(line_budget_key(ln.label, 'phase'))
        if a is None or p is None or not (a.u_c > 0 and p.u_c > 0):
            continue
        ma, mp = mc_line(a, p, phi[whole], te[whole], ln.output_order, gear_ratio=gear_ratio,
                         bench=unc.bench, draws=draws, rng=rng)
        out[line_budget_key(ln.label, 'amplitude')] = ma
        out[line_budget_key(ln.label, 'phase')] = mp
    notes = (f'propagated on the analysis TE trace: {th.size} samples (every '
             f'{trace.stride}th recorded sample), seed {seed}',)
    return MonteCarloCheck(draws=draws, results=out, notes=notes)


def display_of(name: str) -> tuple[float, str]:
    """(scale from SI, unit shown) of a budget: arcmin for angles (arcsec for encoder
    inputs), deg for phases, N m/arcmin for rigidity, um for identified eccentricities."""
    if name.endswith(('phase', '_phase_rad')) or name == 'theta_ot_rad':
        return 180.0 / math.pi, 'deg'
    if name.endswith('_nm_per_rad'):
        return math.pi / 10800.0, 'N m/arcmin'
    if name.endswith('_m'):
        return 1e6, 'um'
    if name.endswith('_j'):
        return 1.0, 'J'
    return 10800.0 / math.pi, 'arcmin'


def budget_html(title: str, b: Budget) -> str:
    """A budget as an HTML table: the inputs (name, type, distribution, u, sensitivity,
    contribution, share, source), largest first, and the notes."""
    from html import escape

    sc, unit = display_of(b.measurand if not title.startswith('line ') else title)
    head = (f'<h4>{escape(title)}: {b.value * sc:.6g} {unit}, U = {b.u95 * sc:.3g} {unit} '
            f'(k = {b.k:.3f}, {escape(b.k_basis)}; u<sub>c</sub> = {b.u_c * sc:.3g} {unit}'
            + (f'; bias bound {max(b.bias_bound, b.bias_low_bound) * sc:.3g} {unit}'
               if max(b.bias_bound, b.bias_low_bound) > 0 else '') + ')</h4>')
    rows = ['<table><tr><th class="l">input</th><th class="l">type</th>'
            '<th class="l">distribution</th><th>u(x)</th><th class="l">unit</th>'
            f'<th>|c| u [{unit}]</th><th>share</th><th class="l">source</th></tr>']
    for x, share in zip(b.inputs, b.shares, strict=True):
        if x.contribution <= 0:
            continue
        ux, uu = (x.u * 648000.0 / math.pi, 'arcsec') if x.unit == 'rad' else (x.u, x.unit)
        src = x.source.split(';')[0][:90]
        rows.append(f'<tr><td class="l">{escape(x.name)}</td><td class="l">{x.kind}</td>'
                    f'<td class="l">{x.distribution}</td><td>{ux:.3g}</td>'
                    f'<td class="l">{escape(uu)}</td><td>{x.contribution * sc:.3g}</td>'
                    f'<td>{100 * share:.1f} %</td><td class="l">{escape(src)}</td></tr>')
    rows.append('</table>')
    notes = ''.join(f'<li>{escape(n)}</li>' for n in b.notes)
    return head + ''.join(rows) + (f'<ul class="muted">{notes}</ul>' if notes else '')
