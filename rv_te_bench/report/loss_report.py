"""The unit report's parts for the whole-reducer steps (issue 38): efficiency map, no-load
torque, starting and back-driving ramps, temperature rise, run-in trend. Figures (PNG) and
HTML sections from the steps' details in the unit record (SI inside, display units here).
"""

from __future__ import annotations

import html
import math
from typing import TYPE_CHECKING, Any

from rv_te_bench.report.plots import _new_figure, png_bytes
from rv_te_bench.report.unit_doc import angle_unit

if TYPE_CHECKING:
    from collections.abc import Callable

    from matplotlib.figure import Figure

__all__ = ['LOSS_STEP_KINDS', 'loss_condition', 'loss_figures', 'loss_sections']

LOSS_STEP_KINDS = ('efficiency', 'no_load', 'starting_torque', 'back_driving',
                   'temperature_rise', 'life')


def _e(x: object) -> str:
    return html.escape(str(x))


def _f(x: Any, digits: int = 4) -> str:
    return '-' if x is None or not math.isfinite(float(x)) else f'{float(x):.{digits}g}'


def loss_condition(step: dict[str, Any]) -> tuple[str, str] | None:
    """The conditions line of a plan step of these kinds (None: not one of them)."""
    k, n = step['kind'], step['name']
    if k == 'efficiency':
        return (f'efficiency map {n!r}', f"speeds {step['speeds_rpm']} rpm x loads "
                f"{step['loads_nm']} N m, {step['direction']}, settle {step['settle_s']:g} s, "
                f"measure {step['measure_s']:g} s per point")
    if k == 'no_load':
        return (f'no-load torque {n!r}', f"speeds {step['speeds_rpm']} rpm, settle "
                f"{step['settle_s']:g} s, measure {step['measure_s']:g} s")
    if k in ('starting_torque', 'back_driving'):
        shaft = 'input (output free)' if k == 'starting_torque' else 'output (input free)'
        return (f'{k.replace("_", " ")} {n!r}', f"torque ramp on the {shaft} at "
                f"{step['ramp_rate_nm_s']:g} N m/s up to {step['max_torque_nm']:g} N m, "
                f"detected at {step['threshold_rad']:g} rad of travel, directions "
                f"{', '.join(step['directions'])}")
    if k == 'temperature_rise':
        return (f'temperature rise {n!r}', f"{step['speed_rpm']:g} rpm, {step['load_nm']:g} "
                f"N m until |dT/dt| < {step['rate_limit_k_per_min']:g} K/min over "
                f"{step['window_s']:g} s (at most {step['max_duration_s']:g} s)")
    if k == 'life':
        return (f'run-in / life {n!r}', f"{step['checkpoints']} checkpoints, {step['run_s']:g} s "
                f"at {step['speed_rpm']:g} rpm and {step['load_nm']:g} N m between them; "
                f"CUSUM on +{100 * step['growth_fraction']:g} % growth, checkpoint scatter "
                f"{100 * step['noise_rel']:g} %, h = {step['threshold']:g}")
    return None


def _efficiency_fig(s: dict[str, Any]) -> Figure:
    fig = _new_figure(7.5, 3.6, left=0.1, bottom=0.14)
    ax = fig.add_subplot()
    rows = [r for r in s['rows'] if r.get('efficiency') is not None]
    for speed in sorted({r['speed_rpm'] for r in rows}):
        pts = sorted((r for r in rows if r['speed_rpm'] == speed), key=lambda r: r['load_nm'])
        ax.errorbar([r['load_nm'] for r in pts], [100 * r['efficiency'] for r in pts],
                    yerr=[100 * r['expanded_efficiency'] for r in pts], marker='o',
                    capsize=3, label=f'{speed:g} rpm')
    temps = [r['temp_case_degc'] for r in rows if r.get('temp_case_degc') is not None]
    where = (f', case {min(temps):.1f}-{max(temps):.1f} degC' if temps else '')
    ax.set_xlabel('output torque [N m]')
    ax.set_ylabel('efficiency [%] (bars: k = 2)')
    ax.set_title(f'Efficiency map ({s["name"]}{where})', fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return fig


def _xy_fig(title: str, xlabel: str, ylabel: str,
            series: list[tuple[str, list[float], list[float]]], *,
            hline: tuple[float, str] | None = None) -> Figure:
    fig = _new_figure(7.5, 3.4, left=0.12, bottom=0.15)
    ax = fig.add_subplot()
    for label, x, y in series:
        ax.plot(x, y, marker='o' if len(x) < 30 else None, label=label)
    if hline is not None:
        ax.axhline(hline[0], color='#b00020', ls='--', lw=1, label=hline[1])
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3)
    if len(series) > 1 or hline is not None:
        ax.legend(fontsize=8)
    return fig


def loss_figures(report: dict[str, Any]) -> dict[str, bytes]:
    """PNG bytes by file name for the steps of these kinds."""
    out: dict[str, bytes] = {}
    for j, s in enumerate(report['steps']):
        k = s['kind']
        name = f'{k}_{j}.png'
        if k == 'efficiency' and any(r.get('efficiency') is not None for r in s['rows']):
            out[name] = png_bytes(_efficiency_fig(s))
        elif k == 'no_load' and any(r.get('torque_nm') is not None for r in s['rows']):
            rows = [r for r in s['rows'] if r.get('torque_nm') is not None]
            out[name] = png_bytes(_xy_fig(
                f'No-load running torque ({s["name"]})', 'input speed [rpm]',
                'input torque [N m]', [('', [r['speed_rpm'] for r in rows],
                                        [r['torque_nm'] for r in rows])]))
        elif k in ('starting_torque', 'back_driving') and any(r.get('curve')
                                                                for r in s['rows']):
            out[name] = png_bytes(_xy_fig(
                f'{k.replace("_", " ")} ramps ({s["name"]})', 'torque [N m]',
                'shaft travel [rad]', [(r['direction'], r['curve']['torque_nm'],
                                        r['curve']['angle_rad'])
                                       for r in s['rows'] if r.get('curve')],
                hline=(s['rows'][0]['threshold_rad'], 'detection threshold')))
        elif k == 'temperature_rise' and s.get('time_s'):
            out[name] = png_bytes(_xy_fig(
                f'Case temperature ({s["name"]})', 'time [s]', 'case temperature [degC]',
                [('', s['time_s'], s['temp_case_degc'])]))
        elif k == 'life' and any(v.get('tracked') for v in s['trends'].values()):
            n0 = int(s.get('baseline_checkpoints', 3))
            series: list[tuple[str, list[float], list[float]]] = []
            for n, v in s['trends'].items():
                if v.get('tracked'):
                    base = sum(v['values'][:n0]) / n0
                    series.append((n, [float(i) for i in range(1, len(v['values']) + 1)],
                                   [100.0 * (x / base - 1.0) for x in v['values']]))
            out[name] = png_bytes(_xy_fig(
                f'Run-in: change from the baseline (first {n0} checkpoints; {s["name"]})',
                'checkpoint', 'change [%]', series,
                hline=(100.0 * s['growth_fraction'], 'growth the detector must flag')))
    return out


def _ramp_cell(r: dict[str, Any]) -> str:
    return _f(r['torque_nm']) if r.get('torque_nm') is not None else _e(r.get('error', '-'))


def loss_sections(report: dict[str, Any], img: Callable[[str, str], None],
                  p: list[str]) -> None:
    """Append the HTML sections of these steps to ``p`` (``img`` embeds a figure)."""
    for j, s in enumerate(report['steps']):
        k = s['kind']
        if k not in LOSS_STEP_KINDS:
            continue
        p.append(f"<h2>{_e(k.replace('_', ' ').capitalize())} ({_e(s['name'])})</h2>")
        if s.get('error'):
            p.append(f"<p>{_e(s['error'])}</p>")
        if k == 'efficiency':
            p.append('<table><tr><th>speed [rpm]</th><th>load [N m]</th><th>efficiency [%]'
                     '</th><th>U (k=2) [%]</th><th>loss [W]</th><th>case [degC]</th></tr>')
            for r in s['rows']:
                eta = r.get('efficiency')
                p.append(f"<tr><td>{r['speed_rpm']:g}</td><td>{r['load_nm']:g}</td>"
                         f"<td>{_f(100 * eta if eta is not None else None)}</td>"
                         f"<td>{_f(100 * r['expanded_efficiency'] if eta is not None else None, 2)}"
                         f"</td><td>{_f(r.get('power_loss_w'))}</td>"
                         f"<td>{_f(r.get('temp_case_degc'))}</td></tr>")
            p.append(f"</table><p class='muted'>Uncertainty: {_e(s.get('uncertainty', ''))}."
                     '</p>')
        elif k == 'no_load':
            p.append('<table><tr><th>speed [rpm]</th><th>torque [N m]</th><th>u [N m]</th>'
                     '<th>case [degC]</th></tr>' + ''.join(
                         f"<tr><td>{r['speed_rpm']:g}</td><td>{_f(r.get('torque_nm'))}</td>"
                         f"<td>{_f(r.get('u_torque_nm'), 2)}</td>"
                         f"<td>{_f(r.get('temp_case_degc'))}</td></tr>" for r in s['rows'])
                     + '</table>')
        elif k in ('starting_torque', 'back_driving'):
            p.append(f"<p>Detection: {_e(s.get('detection', ''))}; the reading is biased "
                     'high by the torque the ramp adds while the shaft travels the threshold.'
                     '</p><table><tr><th class="l">direction</th><th>torque [N m]</th>'
                     '<th>u (class) [N m]</th></tr>' + ''.join(
                         f"<tr><td class='l'>{_e(r['direction'])}</td><td>{_ramp_cell(r)}"
                         f"</td><td>{_f(r.get('u_torque_nm'), 2)}</td></tr>" for r in s['rows'])
                     + '</table>')
        elif k == 'temperature_rise' and 'rise_k' in s:
            p.append(f"<p>Rise {_f(s['rise_k'])} K (from {_f(s['temp_start_degc'])} to "
                     f"{_f(s['temp_settled_degc'])} degC); settled after "
                     f"{_f(s.get('settle_time_s'))} s (rate below "
                     f"{s['rate_limit_k_per_min']:g} K/min over {s['window_s']:g} s windows, "
                     f"decided at {_f(s.get('decided_at_s'))} s; rate noise "
                     f"{_f(s['u_rate_k_per_min'], 2)} K/min).</p>")
        elif k == 'life':
            rows = s['checkpoints']
            au = angle_unit(report)
            p.append(f'<table><tr><th>checkpoint</th><th>TE p-p [{au.name}]</th>'
                     '<th>no-load torque [N m]</th><th>case [degC]</th></tr>' + ''.join(
                         f"<tr><td>{r['checkpoint'] + 1}</td>"
                         f"<td>{_f((r.get('te_pp_rad') or math.nan) * au.per_rad)}</td>"
                         f"<td>{_f(r.get('no_load_torque_nm'))}</td>"
                         f"<td>{_f(r.get('temp_case_degc'))}</td></tr>" for r in rows)
                     + '</table>')
            flagged = [n for n, v in s['trends'].items() if v.get('alarm_index', -1) >= 0]
            untracked = [n for n, v in s['trends'].items() if v.get('tracked') is False]
            p.append(f"<p>Flagged growth: {_e(', '.join(flagged) or 'none')}. Not tracked "
                     f"(amplitude below 2 % of the TE p-p): {_e(', '.join(untracked) or 'none')}."
                     '</p>')
        img(f'{k}_{j}.png', f'{k} of step {s["name"]}')
