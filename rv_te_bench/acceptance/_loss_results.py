"""Metrics and report details of the whole-reducer steps (issue 38) from their segments.

The segments carry, besides the angles and the output torque, the input torque and the
case temperature (``SegmentData.torque_in_nm``, ``temp_case_degc``; empty when the bench
has no such channel: the step's metrics are then NaN with the reason). The transducers'
ranges and classes come from the bench record (``parameters_yaml``: ``bench.loss_channels``).
Names starting ``sweep:`` are per-point values shown in the step but not judged.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np
import yaml

from rv_te_bench.acceptance.tolerance import Measured
from rv_te_bench.core.directional import direction_te
from rv_te_bench.core.loss_uncertainty import (
    breakaway_budget,
    efficiency_budget,
    mean_torque_budget,
    temperature_rise_budget,
)
from rv_te_bench.core.orders import OrderSet
from rv_te_bench.core.thermal_metrics import temperature_rise
from rv_te_bench.core.torque_metrics import (
    breakaway_torque,
    class_uncertainty_nm,
    efficiency_point,
    no_load_torque,
)
from rv_te_bench.core.trend import TrendConfig, cusum_growth
from rv_te_bench.errors import TeInputError

if TYPE_CHECKING:
    from collections.abc import Callable

    from rv_te_bench.acceptance._segments import SegmentData
    from rv_te_bench.acceptance.loss_steps import (
        BackDrivingStep,
        EfficiencyStep,
        LifeStep,
        NoLoadStep,
        StartingTorqueStep,
        TemperatureRiseStep,
    )
    from rv_te_bench.core.uncertainty import Budget
    from sim.bench_info import BenchInfoData

__all__ = ['LOSS_RESULTS', 'bench_channels']

_CURVE_POINTS = 2000
_SQRT3 = math.sqrt(3.0)
#: A crank-order line is tracked over the checkpoints when its baseline amplitude is at
#: least this fraction of the baseline TE p-p (below, its amplitude is noise).
_LINE_FLOOR = 0.02
Result = tuple[list[Measured], dict[str, Any]]


def _fin(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def bench_channels(info: BenchInfoData) -> dict[str, dict[str, Any]]:
    """The bench's loss channels (``torque_in``, ``torque_out``, ``temperature`` -> spec
    dict with ``full_scale`` and ``accuracy_class_pct``) from its record; {} if none."""
    try:
        data = yaml.safe_load(info.parameters_yaml or '') or {}
    except yaml.YAMLError:
        return {}
    ch = (data.get('bench') or {}).get('loss_channels') if isinstance(data, dict) else None
    return ch if isinstance(ch, dict) else {}


def _u_class(info: BenchInfoData, which: str) -> float:
    spec = bench_channels(info).get(which) or {}
    try:
        return class_uncertainty_nm(float(spec['full_scale']), float(spec['accuracy_class_pct']))
    except (KeyError, TypeError, ValueError, TeInputError):
        return math.nan


def _m(name: str, step: str, unit: str, value: float, note: str,
       budget: Budget | None) -> Measured:
    """A metric with its budget's U (the interval's reach below and above)."""
    if budget is None or not (math.isfinite(value) and math.isfinite(budget.u95)):
        return Measured(name, step, unit, value, note)
    return Measured(name, step, unit, value, note, u95=budget.u95, u_below=budget.u_below,
                    u_above=budget.u_above, budget=budget.to_json_dict())


def _cut(seg: SegmentData, info: BenchInfoData, need: tuple[str, ...]
         ) -> tuple[dict[str, np.ndarray], str]:
    """The analysed part of a segment (after settle_s) and why it cannot be analysed."""
    if seg.note:
        return {}, seg.note
    n = seg.theta_in_rad.size
    names = {'torque_in': 'input torque', 'temperature': 'case temperature',
             'torque_out': 'output torque'}
    arrays = {'torque_in': seg.torque_in_nm, 'temperature': seg.temp_case_degc,
              'torque_out': seg.torque_out_nm}
    for k in need:
        if arrays[k].size != n:
            return {}, f'no {names[k]} channel in the data: this step needs it'
    skip = round(float(seg.label.get('settle_s', 0.0)) * info.sample_rate_hz)
    t = seg.time_s if seg.time_s is not None else np.arange(n) / info.sample_rate_hz
    out = {'time_s': t[skip:], 'theta_in_rad': seg.theta_in_rad[skip:],
           'theta_out_rad': seg.theta_out_rad[skip:],
           **{k: arrays[k][skip:] for k in need}}
    if out['time_s'].size < 3:
        return {}, 'fewer than 3 samples after the settling time'
    return out, ''


def _ramp_residual(time_s: np.ndarray, torque_nm: np.ndarray, t_found: float,
                   ) -> tuple[float, int] | None:
    """Scatter of the torque about a line over the ramp before the shaft turned (s, dof)."""
    before = time_s < t_found
    n = int(np.count_nonzero(before))
    if n < 4:
        return None
    tt, yy = time_s[before], np.abs(torque_nm[before])
    res = yy - np.polyval(np.polyfit(tt - tt[0], yy, 1), tt - tt[0])
    return float(np.std(res, ddof=2)), n - 2


def _efficiency_result(step: EfficiencyStep, info: BenchInfoData,
                       segments: list[SegmentData]) -> Result:
    u_in, u_out = _u_class(info, 'torque_in'), _u_class(info, 'torque_out')
    # the speed ratio from the angles: one increment (uniform) per reading
    u_angle = max(info.encoder_in_resolution_rad, info.encoder_out_resolution_rad) \
        / math.sqrt(12.0)
    rows, measured, budgets = [], [], []
    for seg in (s for s in segments if s.role == 'efficiency'):
        d, note = _cut(seg, info, ('torque_in', 'torque_out', 'temperature'))
        row: dict[str, Any] = {'speed_rpm': seg.label['speed_rpm'],
                               'load_nm': seg.label['load_nm'], 'efficiency': None}
        if not note and not (math.isfinite(u_in) and math.isfinite(u_out)):
            note = 'the bench record does not state the torque transducers\' classes'
        if not note:
            try:
                p = efficiency_point(d['time_s'], d['theta_in_rad'], d['theta_out_rad'],
                                     d['torque_in'], d['torque_out'], u_class_in_nm=u_in,
                                     u_class_out_nm=u_out, u_angle_rad=u_angle,
                                     temp_case_degc=d['temperature'])
            except TeInputError as exc:
                note = str(exc)
            else:
                b = efficiency_budget(
                    p.efficiency, torque_in_nm=d['torque_in'], torque_out_nm=d['torque_out'],
                    d_theta_in_rad=float(d['theta_in_rad'][-1] - d['theta_in_rad'][0]),
                    d_theta_out_rad=float(d['theta_out_rad'][-1] - d['theta_out_rad'][0]),
                    class_in_nm=u_in * _SQRT3, class_out_nm=u_out * _SQRT3,
                    q_in_rad=info.encoder_in_resolution_rad,
                    q_out_rad=info.encoder_out_resolution_rad)
                row.update({'efficiency': p.efficiency, 'u_efficiency': b.u_c,
                            'expanded_efficiency': b.u95, 'efficiency_u95': b.u95,
                            'budget': b.to_json_dict(),
                            'torque_in_nm': p.torque_in_nm, 'torque_out_nm': p.torque_out_nm,
                            'power_in_w': p.power_in_w, 'power_loss_w': p.power_loss_w,
                            'temp_case_degc': p.temp_case_degc})
        if note:
            row['error'] = note
        rows.append(row)
        budgets.append(None if note else b)
        measured.append(_m(
            f'sweep:efficiency_{row["speed_rpm"]:g}rpm_{row["load_nm"]:g}nm', step.name, '1',
            row['efficiency'] if row['efficiency'] is not None else math.nan, note,
            budgets[-1]))
    top = max(step.loads_nm)
    at_top = [(r, b) for r, b in zip(rows, budgets, strict=True) if r['load_nm'] == top]
    vals = [r['efficiency'] for r, _ in at_top]
    worst = min(vals) if vals and all(v is not None for v in vals) else math.nan
    why = '' if math.isfinite(worst) else next((r.get('error', '') for r, _ in at_top
                                                if r.get('error')), 'no data')
    wb = next((b for r, b in at_top if r['efficiency'] == worst), None)
    measured.insert(0, _m('efficiency_at_max_load', step.name, '1', worst, why, wb))
    return measured, {'kind': step.kind, 'rows': rows, 'max_load_nm': top,
                      'uncertainty': 'GUM budget per point (core/loss_uncertainty.py): '
                                     'torque transducer classes (c FS / 100, rectangular, '
                                     'not averaged), type A of each mean torque by batch '
                                     'means, the speed ratio from the encoder angles (+-q/2 '
                                     'per reading); U (k from the distribution, 95.45 %); '
                                     'the judged value carries its point\'s budget'}


def _no_load_result(step: NoLoadStep, info: BenchInfoData, segments: list[SegmentData]) -> Result:
    u_in = _u_class(info, 'torque_in')
    rows, measured, budgets = [], [], []
    for seg in (s for s in segments if s.role == 'no_load'):
        d, note = _cut(seg, info, ('torque_in', 'temperature'))
        row: dict[str, Any] = {'speed_rpm': seg.label['speed_rpm'], 'torque_nm': None}
        if not note:
            try:
                p = no_load_torque(d['time_s'], d['theta_in_rad'], d['torque_in'],
                                   u_class_nm=0.0 if math.isnan(u_in) else u_in,
                                   temp_case_degc=d['temperature'])
            except TeInputError as exc:
                note = str(exc)
            else:
                b = (mean_torque_budget('no_load_torque_nm', p.torque_nm,
                                        math.copysign(1.0, p.omega_in_rad_s) * d['torque_in'],
                                        class_nm=u_in * _SQRT3)
                     if math.isfinite(u_in) else None)
                row.update({'torque_nm': p.torque_nm, 'u_torque_nm': p.u_torque_nm,
                            'temp_case_degc': p.temp_case_degc})
                if b is not None:
                    row.update({'u_torque_nm': b.u_c, 'torque_nm_u95': b.u95,
                                'budget': b.to_json_dict()})
        if note:
            row['error'] = note
        rows.append(row)
        budgets.append(None if note else b)
        measured.append(_m(f'sweep:no_load_torque_{row["speed_rpm"]:g}rpm_nm', step.name,
                           'N m', math.nan if row['torque_nm'] is None
                           else row['torque_nm'], note, budgets[-1]))
    vals = [r['torque_nm'] for r in rows]
    top = max(vals) if vals and all(v is not None for v in vals) else math.nan
    why = '' if math.isfinite(top) else next((r['error'] for r in rows if r.get('error')),
                                             'no data')
    tb = next((b for r, b in zip(rows, budgets, strict=True) if r['torque_nm'] == top), None)
    measured.insert(0, _m('no_load_torque_max_nm', step.name, 'N m', top, why, tb))
    return measured, {'kind': step.kind, 'rows': rows}


def _ramp_result(metric: str, channel: str,
                 ) -> Callable[[StartingTorqueStep | BackDrivingStep, BenchInfoData,
                                list[SegmentData]], Result]:
    def result(step: StartingTorqueStep | BackDrivingStep, info: BenchInfoData,
               segments: list[SegmentData]) -> Result:
        rows, measured, budgets = [], [], []
        u = _u_class(info, channel)
        for seg in (s for s in segments if s.role == 'ramp'):
            bud = None
            d, note = _cut(seg, info, (channel,))
            row: dict[str, Any] = {'direction': seg.label['direction'], 'torque_nm': None,
                                   'threshold_rad': step.threshold_rad,
                                   'ramp_rate_nm_s': step.ramp_rate_nm_s}
            if not note:
                angle = d['theta_in_rad'] if channel == 'torque_in' else d['theta_out_rad']
                b = breakaway_torque(d['time_s'], d[channel], angle,
                                     threshold_rad=step.threshold_rad)
                if b.found:
                    row.update({'torque_nm': b.torque_nm, 'u_torque_nm': _fin(u),
                                'time_s': b.time_s, 'torque_before_nm': b.torque_before_nm})
                    if math.isfinite(u):
                        bud = breakaway_budget(
                            metric, b.torque_nm, class_nm=u * _SQRT3,
                            ramp_rate_nm_s=b.ramp_rate_nm_s,
                            sample_rate_hz=info.sample_rate_hz,
                            ramp_residual_nm=_ramp_residual(d['time_s'], d[channel], b.time_s),
                            channel='input' if channel == 'torque_in' else 'output')
                        row.update({'u_torque_nm': bud.u_c, 'torque_nm_u95': bud.u95,
                                    'budget': bud.to_json_dict()})
                else:
                    note = (f'did not turn by {step.threshold_rad:g} rad up to '
                            f'{b.max_torque_nm:.4g} N m (self-locking, or above the ramp\'s '
                            f'max_torque_nm)')
                n = int(np.argmax(np.abs(d[channel]))) + 1   # the ramp, not the release
                k = max(1, math.ceil(n / _CURVE_POINTS))
                row['curve'] = {'time_s': d['time_s'][:n:k].tolist(),
                                'torque_nm': np.abs(d[channel][:n:k]).tolist(),
                                'angle_rad': np.abs(angle[:n:k] - angle[0]).tolist()}
            if note:
                row['error'] = note
            rows.append(row)
            budgets.append(None if note else bud)
            measured.append(_m(f'sweep:{metric}_{row["direction"]}_nm', step.name, 'N m',
                               math.nan if row['torque_nm'] is None
                               else row['torque_nm'], note, budgets[-1]))
        vals = [r['torque_nm'] for r in rows]
        top = max(vals) if vals and all(v is not None for v in vals) else math.nan
        why = '' if math.isfinite(top) else next((r['error'] for r in rows
                                                  if r.get('error')), 'no data')
        tb = next((bb for r, bb in zip(rows, budgets, strict=True) if r['torque_nm'] == top),
                  None)
        measured.insert(0, _m(f'{metric}_nm', step.name, 'N m', top, why, tb))
        return measured, {'kind': step.kind, 'rows': rows,
                          'detection': f'shaft travel > {step.threshold_rad:g} rad, ramp '
                                       f'{step.ramp_rate_nm_s:g} N m/s'}
    return result


def _temperature_result(step: TemperatureRiseStep, info: BenchInfoData,
                        segments: list[SegmentData]) -> Result:
    segs = [s for s in segments if s.role == 'temperature']
    details: dict[str, Any] = {'kind': step.kind, 'speed_rpm': step.speed_rpm,
                               'load_nm': step.load_nm,
                               'rate_limit_k_per_min': step.rate_limit_k_per_min,
                               'window_s': step.window_s}
    note = 'no data' if not segs else ''
    rise = settle = math.nan
    bud = None
    if segs:
        d, note = _cut(segs[0], info, ('temperature',))
    if not note:
        try:
            r = temperature_rise(d['time_s'], d['temperature'],
                                 rate_limit_k_per_min=step.rate_limit_k_per_min,
                                 window_s=step.window_s)
        except TeInputError as exc:
            note = str(exc)
        else:
            k = max(1, math.ceil(d['time_s'].size / _CURVE_POINTS))
            details.update({'settled': r.settled, 'rise_k': r.rise_k,
                            'settle_time_s': _fin(r.settle_time_s),
                            'decided_at_s': _fin(r.decided_at_s),
                            'temp_start_degc': r.temp_start_degc,
                            'temp_settled_degc': r.temp_settled_degc,
                            'final_rate_k_per_min': r.final_rate_k_per_min,
                            'u_rate_k_per_min': r.u_rate_k_per_min,
                            'time_s': (d['time_s'][::k] - d['time_s'][0]).tolist(),
                            'temp_case_degc': d['temperature'][::k].tolist()})
            if r.settled:
                rise, settle = r.rise_k, r.settle_time_s
                bud = temperature_rise_budget(rise, d['time_s'], d['temperature'],
                                              window_s=step.window_s)
                details.update({'rise_k_u95': bud.u95, 'budget': bud.to_json_dict()})
            else:
                note = (f'not settled within {step.max_duration_s:g} s: last rate '
                        f'{r.final_rate_k_per_min:.3g} K/min, limit '
                        f'{step.rate_limit_k_per_min:g} K/min (rise so far {r.rise_k:.3g} K)')
    if note:
        details['error'] = note
    return [_m('temperature_rise_k', step.name, 'K', rise, note, bud),
            Measured('sweep:temperature_settle_time_s', step.name, 's', settle, note)], details


def _checkpoint(step: LifeStep, info: BenchInfoData, k: int, segs: list[SegmentData],
                orders: OrderSet | None) -> dict[str, Any]:
    row: dict[str, Any] = {'checkpoint': k}
    te = [s for s in segs if s.role == 'life_te']
    nl = [s for s in segs if s.role == 'life_no_load']
    if te and not te[0].note:
        skip = round(step.settle_s * info.sample_rate_hz)
        th_in, th_out = te[0].theta_in_rad[skip:], te[0].theta_out_rad[skip:]
        try:
            d = direction_te(th_in, th_out, gear_ratio=info.gear_ratio, orders=orders,
                             duration_s=max(th_in.size - 1, 1) / info.sample_rate_hz)
        except TeInputError as exc:
            row['error'] = str(exc)
        else:
            row['te_pp_rad'] = d.te_pp_rad
            if d.spectrum is not None:
                row['lines'] = {ln.label: ln.amplitude_rad for ln in d.spectrum.lines
                                if ln.crank_order and float(ln.crank_order).is_integer()}
    if nl:
        dd, note = _cut(nl[0], info, ('torque_in', 'temperature'))
        if not note:
            p = no_load_torque(dd['time_s'], dd['theta_in_rad'], dd['torque_in'],
                               u_class_nm=0.0, temp_case_degc=dd['temperature'])
            row['no_load_torque_nm'] = p.torque_nm
            row['temp_case_degc'] = p.temp_case_degc
        else:
            row.setdefault('error', note)
    return row


def _life_result(step: LifeStep, info: BenchInfoData, segments: list[SegmentData]) -> Result:
    orders = OrderSet.from_bench_info(info) if info.crank_per_input else None
    rows = [_checkpoint(step, info, k, [s for s in segments
                                        if s.label.get('checkpoint') == k], orders)
            for k in range(step.checkpoints)]
    cfg = TrendConfig(growth_fraction=step.growth_fraction, noise_rel=step.noise_rel,
                      baseline_checkpoints=step.baseline_checkpoints, threshold=step.threshold)
    series: dict[str, list[float]] = {'te_pp_rad': [r.get('te_pp_rad', math.nan) for r in rows],
                                      'no_load_torque_nm': [r.get('no_load_torque_nm', math.nan)
                                                            for r in rows]}
    labels = sorted({lab for r in rows for lab in r.get('lines', {})})
    trends: dict[str, Any] = {}
    n0 = step.baseline_checkpoints
    te_base = float(np.mean(series['te_pp_rad'][:n0]))
    for lab in labels:
        vals = [r.get('lines', {}).get(lab, math.nan) for r in rows]
        base = float(np.mean(vals[:n0]))
        if math.isfinite(te_base) and base >= _LINE_FLOOR * te_base:
            series[f'line {lab}'] = vals
        else:   # a line at the noise floor has no growth to speak of
            trends[f'line {lab}'] = {'tracked': False, 'baseline_rad': _fin(base),
                                     'why': f'below {_LINE_FLOOR:.0%} of the TE p-p'}
    alarms = 0
    notes = [r['error'] for r in rows if r.get('error')]
    for name, vals in series.items():
        if not all(math.isfinite(v) and v > 0 for v in vals):
            trends[name] = {'error': 'missing or non-positive checkpoint values'}
            continue
        t = cusum_growth(vals, cfg)
        trends[name] = {'tracked': True, 'values': vals, 'growth': [_fin(g) for g in t.growth],
                        'statistic': list(t.statistic), 'alarm_index': t.alarm_index}
        alarms += int(t.alarm)
    judged = not notes and len(series) > 0 and all('error' not in v for v in trends.values())
    note = '' if judged else (notes[0] if notes else 'a tracked quantity has no values')
    measured = [Measured('trend_alarms', step.name, '1', float(alarms) if judged else math.nan,
                         note)]
    measured += [Measured(f'sweep:life_te_pp_cp{r["checkpoint"]}_rad', step.name, 'rad',
                          r.get('te_pp_rad', math.nan), r.get('error', '')) for r in rows]
    return measured, {'kind': step.kind, 'checkpoints': rows, 'trends': trends,
                      'threshold': step.threshold, 'noise_rel': step.noise_rel,
                      'baseline_checkpoints': step.baseline_checkpoints,
                      'growth_fraction': step.growth_fraction,
                      'temperature_degc': [r.get('temp_case_degc') for r in rows]}


#: kind -> result (the acceptance _results.RESULTS takes these). The step is Any: each
#: result takes the step class of its key's kind, which the table cannot say.
LOSS_RESULTS: dict[str, Callable[[Any, BenchInfoData, list[SegmentData]], Result]] = {
    'efficiency': _efficiency_result, 'no_load': _no_load_result,
    'starting_torque': _ramp_result('starting_torque', 'torque_in'),
    'back_driving': _ramp_result('back_driving_torque', 'torque_out'),
    'temperature_rise': _temperature_result, 'life': _life_result}
