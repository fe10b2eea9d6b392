"""The report of one unit's acceptance test: HTML page, JSON record, PNG figures.

Input: the unit record of :func:`rv_te_bench.acceptance.build_report` (SI units). At the
top: serial, operator, date, bench, test conditions and the verdict table (metric, value,
limit, margin, pass/fail, where the limit comes from); then the TE per direction, the
hysteresis curve with lost motion, backlash and rigidity marked, the spectrum, the sweep
table and the advice; at the end the sign-off block. One angle unit throughout (the
tolerance profile's, :func:`rv_te_bench.report.unit_doc.angle_unit`), here only, at the
edge. Figures: :mod:`rv_te_bench.report.unit_figures`.
"""

from __future__ import annotations

import base64
import json
import math
from pathlib import Path
from typing import Any

from rv_te_bench.report.loss_report import loss_condition, loss_sections
from rv_te_bench.report.unit_doc import (
    PRINT_CSS,
    angle_unit,
    calibration_references,
    calibrations_of,
    report_number,
    sign_off_html,
    software_identity,
)
from rv_te_bench.report.unit_figures import spectrum_table, unit_figures
from rv_te_bench.report.unit_sections import display as _display
from rv_te_bench.report.unit_sections import esc as _e
from rv_te_bench.report.unit_sections import fmt as _fmt
from rv_te_bench.report.unit_sections import (
    hysteresis_html,
    spectrum_html,
    te_rows_html,
)
from sim.units import ARCMIN_PER_RAD

__all__ = ['decision_rule_text', 'document_of', 'format_live', 'human_reason', 'metric_rows',
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


def _label(name: str) -> str:
    if name.startswith('torsional_rigidity_'):
        return f'torsional rigidity {name[19:].rsplit("_nm_per_rad", 1)[0]}'
    return _LABELS.get(name, name)


def metric_rows(report: dict[str, Any]) -> list[dict[str, str]]:
    """The verdict table in display units (one dict of strings per metric; angles in the
    report's one unit, :func:`~rv_te_bench.report.unit_doc.angle_unit`)."""
    rows = []
    au = angle_unit(report)
    for m in report['metrics']:
        v, unit = _display(m['unit'], m['value'], au)
        lo, _ = _display(m['unit'], m['limit_min'], au)
        hi, _ = _display(m['unit'], m['limit_max'], au)
        mg, _ = _display(m['unit'], m['margin'], au)
        u, _ = _display(m['unit'], m.get('u95'), au)
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
    au = angle_unit(report)
    failed = {m['name'] for m in report['metrics'] if m['verdict'] == 'fail'}
    for s in report['steps']:
        for r in s.get('rows', []) if s['kind'] == 'te' else []:
            if r.get('spectrum'):
                top = max(spectrum_table(r), key=lambda ln: ln['amplitude_rad'])
                what = (likely_source(top['output_order'], orders, reducer_type)
                        if top['assigned'] else 'no part of the reducer has a line at this '
                        'order: look at the bench (encoder mounting, coupling, motor)')
                out.append(f"{r['direction']}: the strongest line is {top['label']} (order "
                           f"{top['output_order']:g}, {top['amplitude_rad'] * au.per_rad:.3g} "
                           f"{au.name}): {what}.")
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
        v, unit = _display(m['unit'], 1.0, angle_unit(report))
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


def _identity(report: dict[str, Any], doc: dict[str, Any]) -> list[tuple[str, str]]:
    u, b, sw = report['unit'], report['bench'], doc['software']
    au = angle_unit(report)
    out = [('report number', doc['number']), ('unit serial', u['serial']),
           ('operator', u['operator']), ('date of the test (UTC)', u['date_utc']),
           ('report issued (UTC)', doc['issued_utc']),
           ('bench', f"{b['bench_id']} ({b['preset']}, ratio {b['gear_ratio']:.6g})"),
           ('encoders', f"input {b['encoder_in']}, output {b['encoder_out']}"),
           ('calibration references', calibration_references(doc['calibrations'])),
           ('software', f"{sw['name']} {sw['version']}, commit {sw['commit']}"),
           ('plan', report['plan']['plan']),
           ('tolerance profile', report['tolerance']['profile']),
           ('angles', f'in {au.name} throughout this report ({au.why}); rigidity in '
                      f'N m/{au.name}; SI values in report.json')]
    if b.get('bag'):
        out.append(('bag', b['bag']))
    return out


def _table(rows: list[tuple[str, str]], cls: str) -> str:
    return (f'<table class="{cls}">' + ''.join(
        f'<tr><th class="l">{_e(k)}</th><td class="l">{_e(v)}</td></tr>' for k, v in rows)
        + '</table>')


def render_unit_html(report: dict[str, Any], images: dict[str, bytes],
                     doc: dict[str, Any] | None = None) -> str:
    """One self-contained page (PNGs embedded); ``doc``: the document's number, software
    and issue time (:func:`document_of`, made here when not given)."""
    doc = doc or document_of(report)
    u, au = report['unit'], angle_unit(report)
    title = f"Acceptance test of unit {u['serial']}: {report['verdict'].upper()}"
    p = [f'<!DOCTYPE html><html lang="en"><head><meta charset="utf-8"><title>{_e(title)}'
         f'</title><style>{_CSS}{PRINT_CSS}</style></head><body>',
         f"<p class='muted'>Acceptance test report {_e(doc['number'])}</p>",
         f"<h1>Unit {_e(u['serial'])} {_badge(report['verdict'])}</h1>",
         f"<p>{_e(human_reason(report))}</p>", _table(_identity(report, doc), 'ident'),
         '<h2 id="conditions">Test conditions</h2>', _table(_conditions(report), 'cond')]
    p.append('<section class="keep"><h2 id="verdict">Verdict</h2>'
             f'<p><b>Decision rule:</b> {_e(decision_rule_text(report))}. U: expanded '
             'uncertainty, about 95 % (docs/UNCERTAINTY.md); P(false accept): the probability '
             'that the true value lies outside the limit, shown for results within 2 U of it.'
             '</p><table class="verdict"><tr><th class="l">metric</th><th>value</th>'
             '<th>&plusmn; U</th><th>limit</th><th>margin</th><th>verdict</th>'
             '<th>P(false accept)</th><th class="l">limit source</th></tr>')
    for r in metric_rows(report):
        p.append(f"<tr><td class='l'>{_e(r['label'])}</td><td>{_e(r['value'])}</td>"
                 f"<td>{_e(r['u95'])}</td><td>{_e(r['limit'])}</td><td>{_e(r['margin'])}</td>"
                 f"<td>{_badge(r['verdict'])}</td><td>{_e(r['pfa'])}</td>"
                 f"<td class='l muted'>{_e(r['source'])}</td></tr>")
    p.append('</table></section>')
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
            p.append(f'<figure><img id="fig-{_e(name[:-4])}" alt="{_e(alt)}" '
                     f'src="data:image/png;base64,{b64}"></figure>')

    te_rows = [r for s in report['steps'] if s['kind'] == 'te' for r in s.get('rows', [])]
    if te_rows:
        p.append('<h2 id="te">Transmission error per direction</h2>')
        p += te_rows_html(te_rows, au)
        img('te.png', 'TE against output position, one panel per direction, limit band')
    for s in report['steps']:
        if s['kind'] == 'hysteresis':
            p += hysteresis_html(s, au)
            img('hysteresis.png', 'hysteresis curve with lost motion, backlash, rigidity and '
                'their limits')
    if te_rows:
        p.append('<h2 id="spectrum">Spectrum</h2>')
        p += spectrum_html([r for r in te_rows if r.get('spectrum')], au)
        img('spectrum.png', 'labelled and unassigned lines of the TE order spectrum')
    for s in report['steps']:
        if s['kind'] == 'sweep':
            p.append(f"<h2>TE p-p against speed and load ({_e(s['name'])})</h2><table>"
                     f'<tr><th>speed [rpm]</th><th>load [N m]</th><th>TE p-p [{au.name}]</th>'
                     f'<th>U [{au.name}]</th><th>mean [{au.name}]</th></tr>')
            for r in s['rows']:
                mean = (r.get('stats') or {}).get('te_mean_rad')
                p.append(f"<tr><td>{r['speed_rpm']:g}</td><td>{r['load_nm']:g}</td>"
                         f"<td>{_fmt((r['te_pp_rad'] or math.nan) * au.per_rad)}</td>"
                         f"<td>{_fmt((r.get('te_pp_rad_u95') or math.nan) * au.per_rad, 2)}"
                         f"</td><td>{_fmt((mean if mean is not None else math.nan) * au.per_rad)}"
                         '</td></tr>')
            p.append('</table>')
    loss_sections(report, img, p)
    p.append('<h2 id="advice">Advice</h2><ul>'
             + ''.join(f'<li>{_e(a)}</li>' for a in _advice(report)) + '</ul>')
    p.append(f'<section class="keep">{sign_off_html(u["operator"])}</section>')
    p.append(f'<p class="muted">Report {_e(doc["number"])}. Definitions and limit sources: '
             'docs/ACCEPTANCE.md (in the rv-te-bench repository). TE = '
             '&theta;<sub>out</sub> &minus; &theta;<sub>in</sub>/i; torsion angles with the '
             'input locked; values in SI in report.json.</p></body></html>\n')
    return '\n'.join(p)


def document_of(report: dict[str, Any]) -> dict[str, Any]:
    """The report as a document: number, software, issue time (UTC)."""
    import datetime as dt

    sw = software_identity()
    return {'number': report_number(report, sw), 'software': sw,
            'issued_utc': dt.datetime.now(dt.UTC).isoformat(timespec='seconds'),
            'angle_unit': angle_unit(report).name, 'calibrations': calibrations_of(report)}


def write_unit_report(report: dict[str, Any], directory: Path) -> dict[str, Path]:
    """Write report.html, report.json (with ``document``: number, software, issue time) and
    the PNGs; returns their paths by kind."""
    directory.mkdir(parents=True, exist_ok=True)
    images = unit_figures(report)
    for name, data in images.items():
        (directory / name).write_bytes(data)
    doc = document_of(report)
    record = {**report, 'advice': _advice(report), 'document': doc}
    (directory / 'report.json').write_text(json.dumps(record, indent=1, allow_nan=False),
                                           encoding='utf-8')
    (directory / 'report.html').write_text(render_unit_html(report, images, doc),
                                           encoding='utf-8')
    return {'html': directory / 'report.html', 'json': directory / 'report.json',
            **{n[:-4]: directory / n for n in images}}
