"""The unit report's sections of the measured curves, in the report's one angle unit: the
TE table per direction, the spectrum lines (labelled and unassigned) and the hysteresis
curve's numbers; and the small formatters the report shares."""

from __future__ import annotations

import html
import math
from typing import Any

from rv_te_bench.core.spectrum_lines import threshold_rule_text
from rv_te_bench.report.unit_doc import ARCMIN, AngleUnit
from rv_te_bench.report.unit_figures import DIRECTION_STYLE, spectrum_table

__all__ = ['direction_html', 'display', 'esc', 'fmt', 'hysteresis_html', 'spectrum_html',
           'te_rows_html']


def display(unit: str, x: float | None, au: AngleUnit = ARCMIN) -> tuple[float, str]:
    """SI value -> (display value, display unit) in the report's angle unit ``au``."""
    shown = {'rad': au.name, 'N m/rad': f'N m/{au.name}'}.get(unit, unit)
    if x is None or not math.isfinite(x):
        return math.nan, shown
    if unit == 'rad':
        return x * au.per_rad, shown
    if unit == 'N m/rad':
        return x / au.per_rad, shown
    return x, shown


def fmt(x: float, digits: int = 4) -> str:
    return '-' if not math.isfinite(x) else f'{x:.{digits}g}'


def _deg(x: float | None) -> str:
    return '-' if x is None or not math.isfinite(x) else f'{x:.1f}'


def esc(x: object) -> str:
    return html.escape(str(x))


def direction_html(direction: str) -> str:
    colour, ls, _, words = DIRECTION_STYLE.get(direction, ('gray', ':', '', direction))
    border = 'dashed' if ls == '--' else 'solid'
    return (f'<span class="dir" style="border-bottom:3px {border} {colour.removeprefix("tab:")}">'
            f'{esc(words)}</span>')


def te_rows_html(te_rows: list[dict[str, Any]], au: AngleUnit) -> list[str]:
    a = au.name
    p = ['<table class="te"><tr><th class="l">direction</th><th>speed [rpm]</th>'
         f'<th>load [N m]</th><th>revolutions</th><th>p-p per revolution [{a}]</th>'
         f'<th>mean [{a}]</th><th>std [{a}]</th></tr>']
    for r in te_rows:
        st = r.get('stats') or {}
        pps = ', '.join(f'{x * au.per_rad:.4g}' for x in r.get('te_pp_per_rev_rad', []))
        mean, std = (math.nan if st.get(k) is None else float(st[k])
                     for k in ('te_mean_rad', 'te_std_rad'))
        p.append(f"<tr><td class='l'>{direction_html(r['direction'])}</td>"
                 f"<td>{r['speed_rpm']:g}</td>"
                 f"<td>{r['load_nm']:g}</td><td>{r.get('revolutions', '-')}</td>"
                 f"<td>{esc(pps or r.get('error', '-'))}</td><td>{fmt(mean * au.per_rad)}</td>"
                 f"<td>{fmt(std * au.per_rad)}</td></tr>")
    p.append('</table>')
    return p


def spectrum_html(te_rows: list[dict[str, Any]], au: AngleUnit) -> list[str]:
    p = [f'<p class="muted">Every labelled line of the reducer, and every line no part explains '
         f'("unassigned"; {esc(threshold_rule_text())}). Peak amplitude in {au.name}.</p>'
         '<table class="lines"><tr><th class="l">direction</th><th class="l">line</th>'
         f'<th>output order</th><th>amplitude [{au.name}]</th><th class="l">status</th></tr>']
    for r in te_rows:
        for ln in spectrum_table(r):
            status = ('unassigned: no part of the reducer at this order' if not ln['assigned']
                      else 'labelled' if ln['above'] else 'labelled, below the threshold')
            p.append(f"<tr><td class='l'>{direction_html(r['direction'])}</td>"
                     f"<td class='l'>{esc(ln['label'])}</td><td>{ln['output_order']:.6g}</td>"
                     f"<td>{fmt(ln['amplitude_rad'] * au.per_rad, 3)}</td>"
                     f"<td class='l'>{status}</td></tr>")
    p.append('</table>')
    return p


def hysteresis_html(s: dict[str, Any], au: AngleUnit) -> list[str]:
    p = [f"<h2>Hysteresis curve ({esc(s['name'])})</h2>"]
    if s.get('error'):
        p.append(f"<p>{esc(s['error'])}</p>")
    else:
        rig = '; '.join(f'{k}: {fmt((v[0] or math.nan) / au.per_rad)} under positive torque, '
                        f'{fmt((v[1] or math.nan) / au.per_rad)} under negative torque '
                        f'[N m/{au.name}]' for k, v in s['rigidity_nm_per_rad'].items())
        p.append(f"<p>Torsional rigidity per side: {esc(rig)}; the verdict uses the smaller.</p>")
        if s.get('cycles'):
            spread = s.get('spread') or {}
            sd = [f'{k.removesuffix("_rad")}: {fmt(display("rad", spread.get(k), au)[0])} '
                  f'{au.name}' for k in ('lost_motion_rad', 'backlash_rad')]
            p.append(f"<p>Read from {esc(s.get('reading', ''))}: {s['cycles']} load cycle(s) "
                     f"averaged (standard deviation over the cycles: {esc('; '.join(sd))}); "
                     f"torque noise {fmt(s.get('torque_noise_nm') or 0.0)} N m.</p>")
    if len(s.get('positions', [])) > 1:
        p.append(f'<table><tr><th>position</th><th>output angle [deg]</th><th>lost motion '
                 f'[{au.name}]</th><th>backlash [{au.name}]</th></tr>')
        for j, c in enumerate(s['positions']):
            lm, bl = (display('rad', c.get(k), au)[0] for k in ('lost_motion_rad',
                                                                  'backlash_rad'))
            shown = ' (curve below)' if j == s['shown_position'] else ''
            p.append(f"<tr><td>{j + 1}{shown}</td><td>{_deg(c.get('output_position_deg'))}</td>"
                     f"<td>{fmt(lm)}</td><td>{fmt(bl)}</td></tr>")
        p.append('</table><p class="muted">The unit\'s lost motion and backlash are the largest '
                 'of the positions, its rigidity the smallest; the curve is the position with '
                 'the largest lost motion.</p>')
    return p
