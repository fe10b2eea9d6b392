"""The report of one unit's acceptance test: HTML page, JSON record, PNG figures.

Input: the unit record of :func:`rv_te_bench.acceptance.build_report` (SI units). At the
top: serial, operator, date, bench, test conditions and the verdict table (metric, value,
limit, margin, pass/fail, where the limit comes from); then the TE per direction, the
hysteresis curve with lost motion, backlash and rigidity marked, the spectrum, the sweep
table and the advice. Arcmin and N m/arcmin appear here only, at the edge.
"""

from __future__ import annotations

import base64
import html
import json
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from rv_te_bench.report.loss_report import loss_condition, loss_figures, loss_sections
from rv_te_bench.report.plots import _new_figure, _short, png_bytes
from sim.units import ARCMIN_PER_RAD, ARCSEC_PER_RAD

if TYPE_CHECKING:
    import numpy.typing as npt
    from matplotlib.figure import Figure

__all__ = ['decision_rule_text', 'format_live', 'human_reason', 'metric_rows',
           'render_unit_html', 'unit_figures', 'write_unit_report']

_LABELS = {
    'te_pp_ccw_rad': 'TE p-p, ccw (output +)', 'te_pp_cw_rad': 'TE p-p, cw (output -)',
    'te_pp_rad': 'TE p-p', 'lost_motion_rad': 'lost motion', 'backlash_rad': 'backlash',
    'hysteresis_loss_j': 'hysteresis loss (loop area)',
    'efficiency_at_max_load': 'efficiency at the largest load, worst speed (fraction)',
    'no_load_torque_max_nm': 'no-load running torque, largest (input)',
    'starting_torque_nm': 'starting torque (input, output free)',
    'back_driving_torque_nm': 'back-driving torque (output, input free)',
    'temperature_rise_k': 'case temperature rise until settled',
    'trend_alarms': 'run-in: quantities flagged growing',
}
_VERDICT_COLOUR = {'pass': '#1b7f3b', 'fail': '#b00020', 'not_measured': '#9a6700',
                   'indeterminate': '#b35c00', 'not_judged': '#9a6700', 'info': '#555',
                   'cancelled': '#9a6700', 'aborted': '#b00020', 'error': '#b00020'}


def _display(unit: str, x: float | None) -> tuple[float, str]:
    """SI value -> (display value, display unit)."""
    if x is None or not math.isfinite(x):
        return math.nan, {'rad': 'arcmin', 'N m/rad': 'N m/arcmin'}.get(unit, unit)
    if unit == 'rad':
        return x * ARCMIN_PER_RAD, 'arcmin'
    if unit == 'N m/rad':
        return x / ARCMIN_PER_RAD, 'N m/arcmin'
    return x, unit


def _fmt(x: float, digits: int = 4) -> str:
    return '-' if not math.isfinite(x) else f'{x:.{digits}g}'


def _deg(x: float | None) -> str:
    return '-' if x is None or not math.isfinite(x) else f'{x:.1f}'


def _label(name: str) -> str:
    if name.startswith('torsional_rigidity_'):
        return f'torsional rigidity {name[19:].rsplit("_nm_per_rad", 1)[0]}'
    return _LABELS.get(name, name)


def metric_rows(report: dict[str, Any]) -> list[dict[str, str]]:
    """The verdict table in display units (one dict of strings per metric)."""
    rows = []
    for m in report['metrics']:
        v, unit = _display(m['unit'], m['value'])
        lo, _ = _display(m['unit'], m['limit_min'])
        hi, _ = _display(m['unit'], m['limit_max'])
        mg, _ = _display(m['unit'], m['margin'])
        u, _ = _display(m['unit'], m.get('u95'))
        limit = ('<= ' + _fmt(hi) if math.isfinite(hi) else '') + (
            (' and ' if math.isfinite(hi) and math.isfinite(lo) else '')
            + ('>= ' + _fmt(lo) if math.isfinite(lo) else ''))
        pfa = m.get('pfa')
        rows.append({'label': f'{_label(m["name"])} [{unit}]', 'value': _fmt(v),
                     'u95': _u_text(u),
                     'limit': limit or '-', 'margin': _fmt(mg), 'verdict': m['verdict'],
                     'pfa': (f'{100 * pfa:.2g} %' if m.get('borderline') and pfa is not None
                             else ''),
                     'source': m.get('source', ''), 'step': m.get('step', '')})
    return rows


def _u_text(u: float) -> str:
    """An expanded uncertainty to two significant digits (no exponent above 100)."""
    if not math.isfinite(u):
        return '-'
    return f'{u:.0f}' if u >= 100 else f'{u:.2g}'


def decision_rule_text(report: dict[str, Any]) -> str:
    """The rule the verdicts applied, in one sentence (with its source when stated)."""
    rule = report.get('tolerance', {}).get('decision_rule')
    if not rule:
        return ('simple acceptance (ILAC-G8 4.2.1): pass when the value is within the limit; '
                'the uncertainty is stated, not applied')
    src = rule.get('source') or ''
    statement: str = rule['statement']
    return statement + (f' [{src}]' if src else '')


def human_reason(report: dict[str, Any]) -> str:
    """The verdict's reason with the metrics' names as people read them."""
    failed = [_label(m['name']) for m in report['metrics'] if m['verdict'] == 'fail']
    missing = [_label(m['name']) for m in report['metrics'] if m['verdict'] == 'not_measured']
    open_ = [_label(m['name']) for m in report['metrics'] if m['verdict'] == 'indeterminate']
    if report['verdict'] not in {'pass', 'fail', 'indeterminate'}:
        reason: str = report['reason']
        return reason
    if not failed and not missing and not open_:
        return 'Every limited metric is within its limit.'
    parts = []
    if failed:
        parts.append('out of limit: ' + '; '.join(failed))
    if missing:
        parts.append('not measured: ' + '; '.join(missing))
    if open_:
        parts.append('conformance not proven (value and U straddle the limit): '
                     + '; '.join(open_))
    text = '; '.join(parts) + '.'
    return text[0].upper() + text[1:]


def format_live(name: str, value: float) -> str:
    """A live metric of the feedback for the terminal."""
    if not math.isfinite(value):
        return f'{name.removesuffix("_rad").removesuffix("_nm")}: -'
    if name.endswith('_rad'):
        return f'{name[:-4]} so far {value * ARCMIN_PER_RAD:.4f} arcmin'
    if name.endswith('_nm'):
        return f'{name[:-3]} {value:.1f} N m'
    return f'{name} {value:.6g}'


# ----------------------------------------------------------------------------- figures


def _te_figure(rows: list[dict[str, Any]]) -> Figure:
    fig = _new_figure(9.0, 3.6, left=0.09, bottom=0.15)
    ax = fig.add_subplot(1, 1, 1)
    for r in rows:
        if not r.get('position_rad'):
            continue
        te = np.array([np.nan if x is None else x for x in r['te_by_position_rad']])
        ax.plot(np.degrees(r['position_rad']), (te - np.nanmean(te)) * ARCMIN_PER_RAD,
                lw=1.0, label=f"{r['direction']} ({r['speed_rpm']:g} rpm, {r['load_nm']:g} N m)")
    ax.set_xlabel('output position [deg] (one revolution, mean over the revolutions)')
    ax.set_ylabel('TE - mean [arcmin]')
    ax.set_xlim(0, 360)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc='upper right')
    ax.set_title('Transmission error per direction of rotation', fontsize=10)
    return fig


def _hysteresis_figure(h: dict[str, Any]) -> Figure:
    """The whole curve (left) and its middle, |T| <= 4 x the lost-motion torque (right)."""
    fig = _new_figure(10.0, 4.8, left=0.07, bottom=0.12, wspace=0.22)
    grid = fig.add_gridspec(1, 3)
    ax_all, ax_mid = fig.add_subplot(grid[0, :2]), fig.add_subplot(grid[0, 2])
    c = h['centre_rad'] or 0.0

    def am(x: npt.ArrayLike) -> np.ndarray:
        return (np.asarray(x, dtype=float) - c) * ARCMIN_PER_RAD

    t = h['lost_motion_torque_nm']
    for ax in (ax_all, ax_mid):
        ax.plot(am(h['ascending_angle_rad']), h['ascending_torque_nm'], '.-', ms=3, lw=0.9,
                color='tab:blue', label='loading upwards (-T_R -> 0, 0 -> +T_R)')
        ax.plot(am(h['descending_angle_rad']), h['descending_torque_nm'], '.-', ms=3, lw=0.9,
                color='tab:orange', label='loading downwards (+T_R -> -T_R)')
        z = [x for x in h['zero_width_rad'] if x is not None]
        if len(z) == 2:
            ax.annotate('', xy=(am(z[1]), 0), xytext=(am(z[0]), 0),
                        arrowprops={'arrowstyle': '<->', 'color': 'tab:red', 'lw': 1.5})
            ax.plot([], [], color='tab:red', label='backlash: width at zero torque')
        mids = [x for x in h['lost_motion_mid_rad'] if x is not None]
        if len(mids) == 2:
            ax.plot(am(mids), [-t, t], 's--', color='tab:green', ms=6,
                    label=f'lost motion: mid-points at +-{t:.4g} N m')
        for name, sides in h['rigidity_points'].items():
            for side in sides:
                if None not in side:
                    t1, p1, t2, p2 = side
                    ax.plot(am([p1, p2]), [t1, t2], 'o-', color='tab:purple', lw=2, ms=5)
            ax.plot([], [], 'o-', color='tab:purple', lw=2, label=f'rigidity {name}: secant')
        ax.axhline(0, color='k', lw=0.5)
        ax.axvline(0, color='k', lw=0.5)
        ax.grid(alpha=0.3)
        ax.set_xlabel('output torsion angle [arcmin]')
    ax_all.set_ylabel('torque on the output [N m]')
    ax_all.legend(fontsize=7.5, loc='upper left')
    ax_all.set_title(f"Hysteresis curve (input locked, {h['method'].replace('_', ' ')}, "
                     f"T_R = {h['rated_torque_nm']:g} N m; 0 = middle of the backlash)",
                     fontsize=10)
    lim = 4.0 * t
    ax_mid.set_ylim(-lim, lim)
    near = [am(a)[np.abs(np.asarray(tq)) <= lim] for a, tq in (
        (h['ascending_angle_rad'], h['ascending_torque_nm']),
        (h['descending_angle_rad'], h['descending_torque_nm']))]
    xs = np.concatenate(near) if near else np.zeros(1)
    if xs.size:
        pad = 0.15 * max(float(np.ptp(xs)), 1e-3)
        ax_mid.set_xlim(float(xs.min()) - pad, float(xs.max()) + pad)
    ax_mid.set_title('middle (lost motion, backlash)', fontsize=10)
    return fig


def _spectrum_figure(rows: list[dict[str, Any]]) -> Figure:
    fig = _new_figure(9.0, 3.6, left=0.09, bottom=0.3)
    ax = fig.add_subplot(1, 1, 1)
    labels = []
    for r in rows:
        for ln in r.get('spectrum', []):
            if ln['label'] not in labels:
                labels.append(ln['label'])
    labels = labels[:16]
    width = 0.8 / max(1, len(rows))
    for j, r in enumerate(rows):
        amp = {ln['label']: ln['amplitude_rad'] for ln in r.get('spectrum', [])}
        ax.bar(np.arange(len(labels)) + j * width,
               [amp.get(lab, 0.0) * ARCSEC_PER_RAD for lab in labels], width,
               label=r['direction'])
    ax.set_xticks(np.arange(len(labels)) + 0.4 - width / 2)
    # long labels ('15 x crank rel. (1800 f_out)') cut to their name: the tick has no room
    ax.set_xticklabels([_short(lab) for lab in labels], rotation=40, ha='right', fontsize=8)
    ax.set_ylabel('amplitude [arcsec]')
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3, axis='y')
    ax.set_title('TE order spectrum: labelled lines (peak amplitude)', fontsize=10)
    return fig


def unit_figures(report: dict[str, Any]) -> dict[str, bytes]:
    """PNG bytes by file name: te.png, hysteresis.png, spectrum.png (what was measured)."""
    out: dict[str, bytes] = {}
    te_rows = [r for s in report['steps'] if s['kind'] == 'te' for r in s.get('rows', [])]
    if any(r.get('position_rad') for r in te_rows):
        out['te.png'] = png_bytes(_te_figure(te_rows))
        if any(r.get('spectrum') for r in te_rows):
            out['spectrum.png'] = png_bytes(_spectrum_figure(te_rows))
    for s in report['steps']:
        if s['kind'] == 'hysteresis' and s.get('ascending_torque_nm'):
            out['hysteresis.png'] = png_bytes(_hysteresis_figure(s))
            break
    out.update(loss_figures(report))
    return out


# ----------------------------------------------------------------------------- HTML

_CSS = """
body{font-family:system-ui,Segoe UI,Helvetica,Arial,sans-serif;margin:1.5em auto;
max-width:1100px;color:#222;padding:0 1em}h1{font-size:1.5em}
h2{font-size:1.2em;border-bottom:1px solid #ccc;padding-bottom:.2em}
table{border-collapse:collapse;margin:.5em 0 1em}td,th{border:1px solid #ccc;
padding:.25em .6em;text-align:right}th{background:#f0f0f0}td.l,th.l{text-align:left}
img{max-width:100%;border:1px solid #ddd}.muted{color:#666}
.badge{display:inline-block;padding:.15em .7em;border-radius:.3em;color:#fff;font-weight:bold}
"""


def _e(x: Any) -> str:
    return html.escape(str(x))


def _badge(verdict: str) -> str:
    colour = _VERDICT_COLOUR.get(verdict, '#555')
    return f'<span class="badge" style="background:{colour}">{_e(verdict.upper())}</span>'


def _conditions(report: dict[str, Any]) -> list[tuple[str, str]]:
    out = []
    for step in report['plan']['steps']:
        if step['kind'] == 'te':
            out.append((f"TE step {step['name']!r}",
                        f"{step['speed_rpm']:g} rpm input, {step['load_nm']:g} N m resisting, "
                        f"directions {', '.join(step['directions'])}, "
                        f"{step['revolutions']} output rev(s) each"))
        elif step['kind'] == 'hysteresis':
            out.append((f"hysteresis step {step['name']!r}",
                        f"input locked, 0 -> +{step['rated_torque_nm']:g} -> 0 -> "
                        f"-{step['rated_torque_nm']:g} -> 0 N m, {step['method']}"
                        + (f", steps of {100 * step['step_fraction']:g} %, dwell "
                           f"{step['dwell_s']:g} s" if step['method'] == 'torque_steps' else
                           f", {step['output_speed_rad_s']:g} rad/s")
                        + (', preloaded to -T_R' if step['preload'] else '')
                        + (f", at {step['positions']} output positions"
                           if step.get('positions', 1) > 1 else '')))
        elif (line := loss_condition(step)) is not None:
            out.append(line)
        elif step['kind'] == 'sweep':
            out.append((f"sweep {step['name']!r}",
                        f"speeds {step['speeds_rpm']} rpm x loads {step['loads_nm']} N m, "
                        f"{step['direction']}"))
        elif step['kind'] == 'operator':
            out.append((f"operator step {step['name']!r}", step['instruction']))
    cond = report.get('conditions') or {}
    out.append(('temperature', f"{cond['ambient_temperature_c']} degC ambient"
                if 'ambient_temperature_c' in cond else 'not recorded'))
    out += [(str(k), str(v)) for k, v in cond.items() if k != 'ambient_temperature_c']
    b = report['bench']
    out.append(('sample rate', f"{b['sample_rate_hz']:g} Hz"))
    return out


def _advice(report: dict[str, Any]) -> list[str]:
    from rv_te_bench.core.orders import OrderSet
    from rv_te_bench.report import likely_source

    b = report['bench']
    orders = OrderSet(gear_ratio=b['gear_ratio'],
                      crank_per_output=OrderSet.crank_per_output_of(
                          b.get('crank_per_input') or 0.0, b['gear_ratio']) or 1.0,
                      mesh_orders_out=tuple(b.get('mesh_orders', ())),
                      mesh_labels=tuple(b.get('mesh_labels', ())))
    reducer_type = b.get('reducer_type', '')
    out = []
    failed = {m['name'] for m in report['metrics'] if m['verdict'] == 'fail'}
    for s in report['steps']:
        for r in s.get('rows', []) if s['kind'] == 'te' else []:
            if r.get('spectrum'):
                top = max(r['spectrum'], key=lambda ln: ln['amplitude_rad'])
                out.append(f"{r['direction']}: the strongest line is {top['label']} "
                           f"({top['amplitude_rad'] * ARCSEC_PER_RAD:.1f} arcsec): "
                           f"{likely_source(top['output_order'], orders, reducer_type)}.")
    if {'te_pp_ccw_rad', 'te_pp_cw_rad'} & failed:
        out.append('TE out of limit: see the strongest line above; for a 2K-V, rv-te identify '
                   'and the Wang 2020 Eq. 21 re-assembly phases; for an RV, the Hu 2020 '
                   'tooth-profile compensation (rv-te compensate).')
    if {'backlash_rad', 'lost_motion_rad'} & failed:
        out.append('Backlash / lost motion out of limit: clearances of the pin-cycloid mesh '
                   '(tooth-profile modifications), crank bearings and pin holes; a unit with '
                   'much more lost motion than backlash is soft at low torque.')
    if any(n.startswith('torsional_rigidity_') for n in failed):
        out.append('Torsional rigidity below the limit: check the crank bearings, the '
                   'cycloid face contact (load sharing of the discs) and the output bearing.')
    if not failed and report['verdict'] == 'pass':
        out.append('Every limited metric is within its limit: no action needed.')
    return out


def _budget_html(report: dict[str, Any]) -> list[str]:
    """The budgets of the limited metrics (inputs, shares, sources), collapsed."""
    out = []
    for m in report['metrics']:
        b = m.get('budget')
        if not b or m['verdict'] == 'info':
            continue
        v, unit = _display(m['unit'], 1.0)
        rows = ''.join(
            f"<tr><td class='l'>{_e(x['name'])}</td><td class='l'>{_e(x['distribution'])}</td>"
            f"<td>{_fmt((x['contribution'] or 0.0) * v, 3)}</td>"
            f"<td>{100 * (x['share'] or 0.0):.1f} %</td>"
            f"<td class='l muted'>{_e((x['source'] or '').split(';')[0][:80])}</td></tr>"
            for x in b['inputs'] if (x['contribution'] or 0) > 0)
        out.append(f"<details><summary>Uncertainty budget: {_e(_label(m['name']))} "
                   f"(U = {_fmt((m.get('u95') or math.nan) * v, 3)} {_e(unit)}, k = "
                   f"{_fmt(b['k'] or math.nan, 3)})</summary><table><tr><th class='l'>input"
                   f"</th><th class='l'>distribution</th><th>|c| u [{_e(unit)}]</th>"
                   f"<th>share</th><th class='l'>source</th></tr>{rows}</table>"
                   + ''.join(f'<p class="muted">{_e(n)}</p>' for n in b.get('notes', []))
                   + '</details>')
    return out


def render_unit_html(report: dict[str, Any], images: dict[str, bytes]) -> str:
    """One self-contained page (PNGs embedded)."""
    u, b = report['unit'], report['bench']
    title = f"Acceptance test of unit {u['serial']}: {report['verdict'].upper()}"
    p = [f'<!DOCTYPE html><html lang="en"><head><meta charset="utf-8"><title>{_e(title)}'
         f'</title><style>{_CSS}</style></head><body>',
         f"<h1>Unit {_e(u['serial'])} {_badge(report['verdict'])}</h1>",
         f"<p>{_e(human_reason(report))}</p>", '<table>']
    head = [('serial', u['serial']), ('operator', u['operator']), ('date (UTC)', u['date_utc']),
            ('bench', f"{b['bench_id']} ({b['preset']}, ratio {b['gear_ratio']:.6g}; "
                      f"encoders {b['encoder_in']} / {b['encoder_out']})"),
            ('plan', report['plan']['plan']),
            ('tolerance profile', report['tolerance']['profile'])]
    if b.get('bag'):
        head.append(('bag', b['bag']))
    p += [f'<tr><th class="l">{_e(k)}</th><td class="l">{_e(v)}</td></tr>'
          for k, v in head + _conditions(report)]
    p.append('</table><h2>Verdict</h2>'
             f'<p><b>Decision rule:</b> {_e(decision_rule_text(report))}. U: expanded '
             'uncertainty, about 95 % (docs/UNCERTAINTY.md); P(false accept): the probability '
             'that the true value lies outside the limit, shown for results within 2 U of it.'
             '</p><table><tr><th class="l">metric</th><th>value</th><th>&plusmn; U</th>'
             '<th>limit</th><th>margin</th><th>verdict</th><th>P(false accept)</th>'
             '<th class="l">limit source</th></tr>')
    for r in metric_rows(report):
        p.append(f"<tr><td class='l'>{_e(r['label'])}</td><td>{_e(r['value'])}</td>"
                 f"<td>{_e(r['u95'])}</td><td>{_e(r['limit'])}</td><td>{_e(r['margin'])}</td>"
                 f"<td>{_badge(r['verdict'])}</td><td>{_e(r['pfa'])}</td>"
                 f"<td class='l muted'>{_e(r['source'])}</td></tr>")
    p.append('</table>')
    p += _budget_html(report)
    unjudged = [(st['name'], st['not_judged']) for st in report['steps']
                if st.get('not_judged')]
    if unjudged:
        p.append('<h2>Steps not judged</h2><p>The record lacks what these steps need; their '
                 'metrics are not judged (no value is read from the wrong data).</p><ul>'
                 + ''.join(f'<li><b>{_e(n)}</b>: {_e(why)}</li>' for n, why in unjudged)
                 + '</ul>')
    src = report.get('source')
    if src:
        p.append(f"<p class='muted'>Judged from recorded data: {_e(src.get('from', ''))} "
                 f"({src.get('samples', 0)} samples, {src.get('duration_s', 0.0):.1f} s, "
                 f"{src.get('breaks', 0)} break(s); torque: {_e(src.get('torque_from', ''))})"
                 '; the steps were found in the data (report.json: source.steps).</p>')

    def img(name: str, alt: str) -> None:
        if name in images:
            b64 = base64.b64encode(images[name]).decode('ascii')
            p.append(f'<p><img alt="{_e(alt)}" src="data:image/png;base64,{b64}"></p>')

    te_rows = [r for s in report['steps'] if s['kind'] == 'te' for r in s.get('rows', [])]
    if te_rows:
        p.append('<h2>Transmission error per direction</h2><table><tr><th class="l">direction'
                 '</th><th>speed [rpm]</th><th>load [N m]</th><th>revolutions</th>'
                 '<th>p-p per revolution [arcmin]</th><th>mean [arcmin]</th><th>std [arcmin]'
                 '</th></tr>')
        for r in te_rows:
            st = r.get('stats') or {}
            pps = ', '.join(f'{x * ARCMIN_PER_RAD:.4f}' for x in r.get('te_pp_per_rev_rad', []))
            p.append(f"<tr><td class='l'>{_e(r['direction'])}</td><td>{r['speed_rpm']:g}</td>"
                     f"<td>{r['load_nm']:g}</td><td>{r.get('revolutions', '-')}</td>"
                     f"<td>{_e(pps or r.get('error', '-'))}</td>"
                     f"<td>{_fmt(st.get('te_mean_arcmin') or math.nan)}</td>"
                     f"<td>{_fmt(st.get('te_std_arcmin') or math.nan)}</td></tr>")
        p.append('</table>')
        img('te.png', 'TE against output position per direction')
    for s in report['steps']:
        if s['kind'] == 'hysteresis':
            p.append(f"<h2>Hysteresis curve ({_e(s['name'])})</h2>")
            if s.get('error'):
                p.append(f"<p>{_e(s['error'])}</p>")
            else:
                rig = '; '.join(f'{k}: {_fmt((v[0] or math.nan) / ARCMIN_PER_RAD)} under '
                                f'positive torque, {_fmt((v[1] or math.nan) / ARCMIN_PER_RAD)} '
                                'under negative torque [N m/arcmin]'
                                for k, v in s['rigidity_nm_per_rad'].items())
                p.append(f"<p>Torsional rigidity per side: {_e(rig)}; the verdict uses the "
                         "smaller.</p>")
                if s.get('cycles'):
                    spread = s.get('spread') or {}
                    sd = [f'{k.removesuffix("_rad")}: {_fmt(_display("rad", spread.get(k))[0])}'
                          ' arcmin' for k in ('lost_motion_rad', 'backlash_rad')]
                    p.append(f"<p>Read from {_e(s.get('reading', ''))}: {s['cycles']} load "
                             f"cycle(s) averaged (standard deviation over the cycles: "
                             f"{_e('; '.join(sd))}); torque noise "
                             f"{_fmt(s.get('torque_noise_nm') or 0.0)} N m.</p>")
            if len(s.get('positions', [])) > 1:
                p.append('<table><tr><th>position</th><th>output angle [deg]</th>'
                         '<th>lost motion [arcmin]</th><th>backlash [arcmin]</th></tr>')
                for j, c in enumerate(s['positions']):
                    lm, bl = (_display('rad', c.get(k))[0] for k in ('lost_motion_rad',
                                                                      'backlash_rad'))
                    shown = ' (curve below)' if j == s['shown_position'] else ''
                    p.append(f"<tr><td>{j + 1}{shown}</td>"
                             f"<td>{_deg(c.get('output_position_deg'))}</td>"
                             f"<td>{_fmt(lm)}</td><td>{_fmt(bl)}</td></tr>")
                p.append('</table><p class="muted">The unit\'s lost motion and backlash are the '
                         'largest of the positions, its rigidity the smallest; the curve is the '
                         'position with the largest lost motion.</p>')
            img('hysteresis.png', 'hysteresis curve with lost motion, backlash, rigidity')
    if te_rows:
        p.append('<h2>Spectrum</h2>')
        img('spectrum.png', 'labelled lines of the TE order spectrum')
    for s in report['steps']:
        if s['kind'] == 'sweep':
            p.append(f"<h2>TE p-p against speed and load ({_e(s['name'])})</h2><table>"
                     '<tr><th>speed [rpm]</th><th>load [N m]</th><th>TE p-p [arcmin]</th>'
                     '<th>U [arcmin]</th><th>mean [arcmin]</th></tr>')
            for r in s['rows']:
                st = r.get('stats') or {}
                p.append(f"<tr><td>{r['speed_rpm']:g}</td><td>{r['load_nm']:g}</td>"
                         f"<td>{_fmt((r['te_pp_rad'] or math.nan) * ARCMIN_PER_RAD)}</td>"
                         f"<td>{_fmt((r.get('te_pp_rad_u95') or math.nan) * ARCMIN_PER_RAD, 2)}"
                         f"</td><td>{_fmt(st.get('te_mean_arcmin') or math.nan)}</td></tr>")
            p.append('</table>')
    loss_sections(report, img, p)
    p.append('<h2>Advice</h2><ul>' + ''.join(f'<li>{_e(a)}</li>' for a in _advice(report))
             + '</ul>')
    p.append('<p class="muted">Definitions and limit sources: docs/ACCEPTANCE.md. TE = '
             '&theta;<sub>out</sub> &minus; &theta;<sub>in</sub>/i; torsion angles with the '
             'input locked; values in SI in report.json.</p></body></html>\n')
    return '\n'.join(p)


def write_unit_report(report: dict[str, Any], directory: Path) -> dict[str, Path]:
    """Write report.html, report.json and the PNGs; returns their paths by kind."""
    directory.mkdir(parents=True, exist_ok=True)
    images = unit_figures(report)
    for name, data in images.items():
        (directory / name).write_bytes(data)
    doc = {**report, 'advice': _advice(report)}
    (directory / 'report.json').write_text(json.dumps(doc, indent=1, allow_nan=False),
                                           encoding='utf-8')
    (directory / 'report.html').write_text(render_unit_html(report, images), encoding='utf-8')
    return {'html': directory / 'report.html', 'json': directory / 'report.json',
            **{n[:-4]: directory / n for n in images}}
