"""A step's metrics and report details from the data of its segments, wherever they came
from: the live sequencer (blocks of a program it ran), a recorded session or an imported
DAQ file (segments found in the data, :mod:`rv_te_bench.acceptance.recorded`). One code
path, so that a verdict rule applies to every route alike.

A segment that cannot be analysed carries a ``note`` (what is missing); its metrics are
NaN with that note, which the tolerance evaluation turns into ``not_judged``.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np

from rv_te_bench.acceptance._loss_results import LOSS_RESULTS
from rv_te_bench.acceptance._segments import SegmentData
from rv_te_bench.acceptance._uncertainty import (
    constant_speed_budgets,
    hysteresis_point_budgets,
    te_direction_budget,
)
from rv_te_bench.acceptance.plan import HysteresisStep, OperatorStep
from rv_te_bench.acceptance.tolerance import Measured
from rv_te_bench.core.bench_uncertainty import BenchUncertainty
from rv_te_bench.core.directional import direction_te
from rv_te_bench.core.hysteresis_measured import (
    HysteresisReading,
    measured_hysteresis,
    metric_names,
)
from rv_te_bench.core.orders import OrderSet
from rv_te_bench.core.te import output_phase_and_te
from rv_te_bench.core.units import metric_unit
from rv_te_bench.errors import TeInputError

if TYPE_CHECKING:
    from collections.abc import Callable

    from rv_te_bench.acceptance.plan import Step
    from rv_te_bench.core.uncertainty import Budget
    from sim.bench_info import BenchInfoData

__all__ = ['RESULTS', 'SegmentData', 'hysteresis_reading', 'step_result']

_MAX_CURVE_POINTS = 4000
#: The step class a result function takes.
_S = TypeVar('_S')
#: Spectrum bins kept for the report (the labelled lines are kept whatever their order).
_SPECTRUM_BINS = 400


def _orders(info: BenchInfoData) -> OrderSet | None:
    """Spectral lines of the reducer (None without a crank rate)."""
    if not info.crank_per_input:
        return None
    return OrderSet.from_bench_info(info)


def _decimate(*arrays: np.ndarray, limit: int = _MAX_CURVE_POINTS) -> list[list[float]]:
    n = arrays[0].size
    step = max(1, math.ceil(n / limit))
    return [a[::step].tolist() for a in arrays]


def _fin(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def _measured(name: str, step: str, unit: str, value: float, note: str,
              budget: Budget | None) -> Measured:
    """A metric with its budget's U (its interval's reach below and above)."""
    if budget is None or not math.isfinite(value):
        return Measured(name, step, unit, value, note)
    return Measured(name, step, unit, value, note, u95=budget.u95, u_below=budget.u_below,
                    u_above=budget.u_above, budget=budget.to_json_dict())


def _unit(name: str) -> str:
    return metric_unit(name).si


def step_result(step: Step, info: BenchInfoData, segments: list[SegmentData],
                uncertainty: BenchUncertainty | None = None,
                ) -> tuple[list[Measured], dict[str, Any]]:
    """Metrics (SI) and the details the report shows, of one step.

    Args:
        step: The plan step.
        info: The bench's record.
        segments: The step's segments: for TE and sweep steps one per direction or sweep
            point, in the order of :class:`~rv_te_bench.acceptance.runner.StepRunner`'s
            program; for a hysteresis step those of role 'preload' and 'cycle' are read per
            ``position`` label.
        uncertainty: The bench's error model for the metrics' budgets (default: the
            data-sheet values of the BenchInfo encoder models).
    """
    if uncertainty is None:
        uncertainty = BenchUncertainty.defaults(
            info.encoder_in_model, info.encoder_out_model,
            resolution_in_rad=info.encoder_in_resolution_rad,
            resolution_out_rad=info.encoder_out_resolution_rad)
    return RESULTS[step.kind](step, info, segments, uncertainty)


def _te_result(step: Step, info: BenchInfoData, segments: list[SegmentData],
               bench: BenchUncertainty) -> tuple[list[Measured], dict[str, Any]]:
    segments = [s for s in segments if s.role in {'te', 'sweep'}]
    measured: list[Measured] = []
    rows = []
    for seg in segments:
        th_in, th_out = seg.theta_in_rad, seg.theta_out_rad
        settle = round(seg.label['settle_s'] * info.sample_rate_hz)
        row: dict[str, Any] = {**seg.label, 'samples': int(th_in.size), **seg.found}
        note = seg.note
        value = math.nan
        budget = None
        if not note:
            try:
                d = direction_te(th_in[settle:], th_out[settle:], gear_ratio=info.gear_ratio,
                                 orders=_orders(info),
                                 duration_s=max(th_in[settle:].size - 1, 1)
                                 / info.sample_rate_hz)
            except TeInputError as exc:
                note = str(exc)
            else:
                value = d.te_pp_rad
                budget = te_direction_budget('te_pp_rad', th_in[settle:], th_out[settle:], d,
                                             gear_ratio=info.gear_ratio, bench=bench)
                pos, curve = _decimate(d.position_rad, d.te_by_position_rad)
                row.update({
                    'revolutions': d.revolutions, 'te_pp_per_rev_rad': list(d.pp_per_rev_rad),
                    'stats': d.stats.to_json_dict(), 'position_rad': pos,
                    'te_by_position_rad': [_fin(x) for x in curve],
                    'spectrum': [ln.to_json_dict() for ln in d.spectrum.lines]
                    if d.spectrum is not None else [],
                    'spectrum_orders': d.spectrum.orders[:_SPECTRUM_BINS].tolist()
                    if d.spectrum is not None else [],
                    'spectrum_amplitude_rad': d.spectrum.amplitude_rad[:_SPECTRUM_BINS].tolist()
                    if d.spectrum is not None else []})
        if note:
            row['error'] = note
        row['te_pp_rad'] = _fin(value)
        if budget is not None:
            row['te_pp_rad_u95'] = _fin(budget.u95)
        rows.append(row)
        what = (f'{seg.label["direction"]} at {seg.label["speed_rpm"]:g} rpm, '
                f'{seg.label["load_nm"]:g} N m')
        note_line = f'{what}: {note}' if note else ''
        if seg.role == 'te':
            measured.append(_measured(f'te_pp_{seg.label["direction"]}_rad', step.name,
                                      'rad', value, note_line, budget))
        else:
            name = (f'te_pp_{seg.label["direction"]}_{seg.label["speed_rpm"]:g}rpm_'
                    f'{seg.label["load_nm"]:g}nm_rad')
            measured.append(_measured(f'sweep:{name}', step.name, 'rad', value, note_line,
                                      budget))
    return measured, {'kind': step.kind, 'rows': rows}


def hysteresis_reading(step: HysteresisStep, sample_rate_hz: float) -> HysteresisReading:
    """How the step's record is read: dwells of at least 30 % of the planned dwell, torque
    resolution a quarter of the smallest planned step (or 0.1 % of T_R if finer)."""
    if step.method == 'constant_speed':
        return HysteresisReading('constant_speed')
    cfg = step.config()
    tr = step.rated_torque_nm
    n = round(1.0 / step.step_fraction)
    levels = sorted({round(k / n, 12) * tr for k in range(n + 1)}
                    | {abs(p) for p in cfg.torque_points_nm()})
    smallest = float(np.min(np.diff(levels))) if len(levels) > 1 else tr
    return HysteresisReading(
        'torque_steps', min_dwell_samples=max(5, int(0.3 * step.dwell_s * sample_rate_hz)),
        resolution_nm=max(0.25 * smallest, 1e-3 * tr))


def _hysteresis_result(step: HysteresisStep, info: BenchInfoData, segments: list[SegmentData],
                       bench: BenchUncertainty) -> tuple[list[Measured], dict[str, Any]]:
    """Metrics per measurement position; the unit's value is the worst position's."""
    names = metric_names(step.config())
    details: dict[str, Any] = {'kind': 'hysteresis', 'method': step.method,
                               'rated_torque_nm': step.rated_torque_nm, 'positions': []}
    per: list[dict[str, float]] = []
    budgets: list[dict[str, Budget]] = []
    notes: list[str] = []
    for pos in range(step.positions):
        segs = [s for s in segments if s.role in {'preload', 'cycle'}
                and s.label.get('position') == pos]
        values, curve, buds = _one_position(step, info, segs, names, bench)
        per.append(values)
        budgets.append(buds)
        details['positions'].append(curve)
        if curve.get('error'):
            where = f'position {pos + 1}: ' if step.positions > 1 else ''
            notes.append(where + curve['error'])
    worst = {}
    worst_budget: dict[str, Budget | None] = {}
    for n in names:
        vals = [v[n] for v in per if math.isfinite(v[n])]
        pick = min if n.startswith('torsional_rigidity_') else max
        worst[n] = pick(vals) if len(vals) == len(per) else math.nan
        at = [k for k, v in enumerate(per) if v[n] == worst[n]]
        worst_budget[n] = budgets[at[0]].get(n) if at else None
    spread = {n: (max(v[n] for v in per) - min(v[n] for v in per))
              if step.positions > 1 and all(math.isfinite(v[n]) for v in per) else math.nan
              for n in ('lost_motion_rad', 'backlash_rad')}
    details['per_position'] = [{n: _fin(v[n]) for n in names} for v in per]
    details['position_spread'] = {n: _fin(x) for n, x in spread.items()}
    # the curve shown: the position with the largest lost motion
    lm = [v['lost_motion_rad'] for v in per]
    shown = int(np.nanargmax(lm)) if np.any(np.isfinite(lm)) else 0
    details.update(details['positions'][shown])
    details['shown_position'] = shown
    note = '; '.join(notes)
    details['u95'] = {n: _fin(b.u95) for n, b in worst_budget.items() if b is not None}
    out = [_measured(n, step.name, _unit(n), worst[n],
                     note if not math.isfinite(worst[n]) else '', worst_budget[n])
           for n in names]
    if step.positions > 1:   # GB/T 40731 and catalogues: the maximum and the spread
        out += [Measured(f'sweep:{n[:-4]}_spread_rad', step.name, 'rad', x,
                         note if not math.isfinite(x) else '') for n, x in spread.items()]
    return out, details


def _one_position(step: HysteresisStep, info: BenchInfoData, segs: list[SegmentData],
                  names: list[str], bench: BenchUncertainty,
                  ) -> tuple[dict[str, float], dict[str, Any], dict[str, Budget]]:
    nan = dict.fromkeys(names, math.nan)
    if not segs:
        return nan, {'error': 'no data'}, {}
    bad = [s.note for s in segs if s.note]
    if bad:
        return nan, {'error': bad[0], **segs[0].found}, {}
    th_in = np.concatenate([s.theta_in_rad for s in segs])
    th_out = np.concatenate([s.theta_out_rad for s in segs])
    torque = np.concatenate([s.torque_out_nm for s in segs])
    found = {k: v for s in segs for k, v in s.found.items()}
    if torque.size != th_in.size:
        return nan, {'error': 'no torque channel in the record: a hysteresis curve needs the '
                              'output torque', **found}, {}
    times = [s.time_s for s in segs if s.time_s is not None]
    time_s: np.ndarray
    if len(times) == len(segs):
        time_s = np.concatenate(times)
    else:
        time_s = np.arange(th_in.size) / info.sample_rate_hz
    _, angle = output_phase_and_te(th_in, th_out, gear_ratio=info.gear_ratio, check=False)
    applied = -torque                      # the bench's load convention -> applied torque
    curve: dict[str, Any] = {'samples': int(applied.size), **found}
    if th_in.size:
        curve['output_position_deg'] = _fin(float(np.degrees(np.mod(
            np.mean(th_in) / info.gear_ratio, 2 * math.pi))))
        curve['input_travel_rad'] = _fin(float(np.ptp(th_in)))
    # a torque channel of the opposite sign: the angle falls as the applied torque rises
    if applied.size > 2 and np.ptp(applied) > 0 and np.ptp(angle) > 0 and \
            float(np.corrcoef(applied, angle)[0, 1]) < -0.5:
        applied = -applied
        curve['torque_sign'] = ('reversed: the record\'s torque channel reads the applied '
                                'torque (the angle rises with it), not the bench convention '
                                '(torque_out_nm resists positive rotation)')
    reading = hysteresis_reading(step, info.sample_rate_hz)
    try:
        m = measured_hysteresis(time_s, applied, angle, step.config(), reading)
    except TeInputError as exc:
        curve['error'] = str(exc)
        return nan, curve, {}
    first = m.cycles[0]
    asc_t, asc_a = _decimate(*first.ascending)
    dn_t, dn_a = _decimate(*first.descending)
    curve.update({
        'cycles': len(m.cycles), 'torque_noise_nm': m.torque_noise_nm, 'dwells': m.dwells,
        'reading': 'dwell points (time and stability)' if reading.method == 'torque_steps'
        else 'local fits against time',
        'spread': {k: _fin(v) for k, v in m.spread.items()},
        'per_cycle': [{'lost_motion_rad': _fin(c.lost_motion_rad),
                       'backlash_rad': _fin(c.backlash_rad),
                       'hysteresis_loss_j': _fin(c.hysteresis_loss_j),
                       'rigidity_nm_per_rad': {k: [_fin(v[0]), _fin(v[1])]
                                               for k, v in c.rigidity_nm_per_rad.items()}}
                      for c in m.cycles],
        'centre_rad': _fin(0.5 * (first.zero_width_rad[0] + first.zero_width_rad[1])),
        'ascending_torque_nm': asc_t, 'ascending_angle_rad': asc_a,
        'descending_torque_nm': dn_t, 'descending_angle_rad': dn_a,
        'zero_width_rad': [_fin(x) for x in first.zero_width_rad],
        'lost_motion_torque_nm': first.lost_motion_torque_nm,
        'lost_motion_mid_rad': [_fin(x) for x in first.lost_motion_mid_rad],
        'rigidity_nm_per_rad': {k: [_fin(float(np.mean([c.rigidity_nm_per_rad[k][j]
                                                         for c in m.cycles])))
                                    for j in (0, 1)] for k in first.rigidity_nm_per_rad},
        'rigidity_points': {k: [[_fin(x) for x in side] for side in v]
                            for k, v in first.rigidity_points.items()},
        'max_torque_nm': first.max_torque_nm, 'min_torque_nm': first.min_torque_nm,
        'lost_motion_rad': _fin(m.values['lost_motion_rad']),
        'backlash_rad': _fin(m.values['backlash_rad'])})
    if m.missing:
        curve['error'] = '; '.join(m.missing)
    buds: dict[str, Budget] = {}
    try:
        if reading.method == 'torque_steps':
            buds = hysteresis_point_budgets(m.points, float(th_out[0]), step.config(),
                                            bench=bench)
        else:
            buds = constant_speed_budgets(time_s, applied, angle, float(th_out[0]),
                                          step.config(), reading, m, bench=bench)
    except TeInputError:
        buds = {}
    return {n: m.values[n] for n in names}, curve, buds


def _operator_result(step: OperatorStep, _info: BenchInfoData, _segments: list[SegmentData],
                     _bench: BenchUncertainty) -> tuple[list[Measured], dict[str, Any]]:
    return [], {'kind': 'operator', 'instruction': step.instruction}


def _without_budget(f: Callable[[_S, BenchInfoData, list[SegmentData]],
                                 tuple[list[Measured], dict[str, Any]]],
                    ) -> Callable[[_S, BenchInfoData, list[SegmentData], BenchUncertainty],
                                  tuple[list[Measured], dict[str, Any]]]:
    """A whole-reducer step's result: its budgets come from the bench record's transducer
    classes and the data (core/loss_uncertainty.py), not from the encoders' error model."""
    def run(step: _S, info: BenchInfoData, segments: list[SegmentData],
            _bench: BenchUncertainty) -> tuple[list[Measured], dict[str, Any]]:
        return f(step, info, segments)

    return run


#: Step kind -> its result from the segments' data (see plan._KINDS for a new kind). The
#: step is Any: each result takes the step class of its key's kind, which the table cannot say.
RESULTS: dict[str, Callable[[Any, BenchInfoData, list[SegmentData], BenchUncertainty],
                            tuple[list[Measured], dict[str, Any]]]] = {
    'te': _te_result, 'sweep': _te_result, 'hysteresis': _hysteresis_result,
    'operator': _operator_result,
    **{kind: _without_budget(f) for kind, f in LOSS_RESULTS.items()}}

