"""The report directory: one self-contained HTML page, its PNGs and a JSON twin.

:func:`write_report` writes ``te.png``, ``spectrum.png`` (and ``comparison.png`` for
several bags), ``report.json`` and ``report.html`` (images embedded as base64 data URIs,
so the page can be mailed on its own).
"""

from __future__ import annotations

import base64
import contextlib
import datetime as dt
import html
import json
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from rv_te_bench.core.advice import modification_value
from rv_te_bench.core.spectrum_lines import threshold_rule_text, unassigned_lines
from rv_te_bench.errors import RvTeError
from rv_te_bench.io.files import write_all
from rv_te_bench.report.analysis import (
    PHASE_MIN_FRACTION,
    compare_results,
    describe_identification,
    report_title,
)
from rv_te_bench.safe_yaml import printable
from sim.units import rad_to_arcmin, rad_to_deg

if TYPE_CHECKING:
    from collections.abc import Sequence

    from rv_te_bench.core.stream_records import WindowResult
    from rv_te_bench.core.te import TeStats
    from rv_te_bench.report.analysis import AnalysisResult

__all__ = ['ReportExistsError', 'render_html', 'report_json', 'write_report']


class ReportExistsError(RvTeError, FileExistsError):
    """The report directory exists and overwriting was not allowed."""


def report_json(results: Sequence[AnalysisResult]) -> dict[str, Any]:
    """The JSON document of a report (also what ``rv-te analyze --json`` prints).

    Args:
        results: One or more analyses.

    Returns:
        ``{'generated_utc', 'bags': [...], 'comparison': [...] | None}``; every quantity
        key carries its unit (``te_pp_arcmin``, ``frequency_hz``, ``output_order``).
    """
    return {
        'generated_utc': dt.datetime.now(dt.UTC).isoformat(timespec='seconds'),
        'bags': [r.to_json_dict() for r in results],
        'comparison': compare_results(list(results)) if len(results) > 1 else None,
    }


def write_report(results: Sequence[AnalysisResult], directory: Path, *,
                 force: bool = False) -> list[Path]:
    """Write the report files into ``directory``.

    Args:
        results: One or more analyses.
        directory: Report directory; created, or reused when ``force``.
        force: Overwrite an existing directory's report files.

    Returns:
        The files written.

    Every file is staged beside its target and renamed into place only once all are on
    disk (``rv_te_bench.io.files.write_all``): a full disk leaves the folder as it was.

    Raises:
        ReportExistsError: ``directory`` exists and ``force`` is False.
        RvTeError: The directory cannot be written (names the file and the reason).
    """
    directory = Path(directory)
    if directory.exists() and not force:
        msg = f'Report directory {directory} exists already; use --force to overwrite.'
        raise ReportExistsError(msg)
    if directory.exists() and not directory.is_dir():
        msg = f'Report path {directory} exists and is not a directory.'
        raise ReportExistsError(msg)
    # matplotlib (0.4 s to import) only when a report is written, not for --json or a table
    from rv_te_bench.report.plots import (
        comparison_figure,
        png_bytes,
        spectrum_figure,
        te_figure,
        windows_figure,
    )

    te = [r for r in results if not r.not_te_record]   # a hysteresis record has no TE
    images = {}
    if te:
        images = {'te.png': png_bytes(te_figure(te)),
                  'spectrum.png': png_bytes(spectrum_figure(te))}
    if len(te) > 1:
        images['comparison.png'] = png_bytes(comparison_figure(te))
    if any(len(r.windows) > MAX_WINDOW_ROWS for r in te):   # the table lists only some
        images['windows.png'] = png_bytes(windows_figure(te))
    doc = report_json(results)
    files: dict[Path, bytes | str] = {directory / name: data for name, data in images.items()}
    files[directory / 'report.json'] = json.dumps(doc, indent=2) + '\n'
    files[directory / 'report.html'] = render_html(results, images, doc)
    created = not directory.exists()
    try:
        directory.mkdir(parents=True, exist_ok=True)
        write_all(files)   # all or nothing: no 0-byte image on a full disk
    except OSError as exc:
        if created:
            with contextlib.suppress(OSError):
                directory.rmdir()
        what = Path(exc.filename).name if exc.filename else str(directory)
        msg = (f'Cannot write report into {directory}: {what}: {exc.strerror or exc} '
               '(no report file was written or changed)')
        raise RvTeError(msg) from None
    return [directory / n for n in (*images, 'report.json', 'report.html')]


# --------------------------------------------------------------------------------------
# HTML

_CSS = """
body{font-family:system-ui,Segoe UI,Helvetica,Arial,sans-serif;margin:1.5em auto;
max-width:1100px;color:#222;padding:0 1em}
h1{font-size:1.5em}h2{font-size:1.2em;border-bottom:1px solid #ccc;padding-bottom:.2em}
h3{font-size:1.05em}
table{border-collapse:collapse;margin:.5em 0 1em}td,th{border:1px solid #ccc;
padding:.2em .6em;text-align:right}th{background:#f0f0f0}td.l,th.l{text-align:left}
img{max-width:100%;border:1px solid #ddd}.warn{background:#fff3cd;border:1px solid #e0c060;
padding:.5em}.muted{color:#666}code{background:#f5f5f5;padding:0 .2em}
"""


def _e(x: object) -> str:
    return html.escape(printable(x))   # undecodable bytes of a path: U+FFFD, not a crash


def _am(x_rad: float, digits: int = 4) -> str:
    v = float(rad_to_arcmin(x_rad))
    return f'{v:.{digits}f}' if math.isfinite(v) else '-'


def _am_g(x_rad: float) -> str:
    """An uncertainty in arcmin to two significant digits."""
    v = float(rad_to_arcmin(x_rad))
    return f'{v:.2g}' if math.isfinite(v) else '-'


def _secs(x: float | None) -> str:
    return '-' if x is None else f'{x:.6g}'


def _stats_cells(st: TeStats) -> str:
    revs = f'{st.revolutions:.3f}' if math.isfinite(st.revolutions) else '-'
    return (f'<td>{_am(st.pp_rad)}</td><td>{_am(st.amplitude_rad)}</td>'
            f'<td>{_am(st.mean_rad)}</td><td>{_am(st.std_rad)}</td>'
            f'<td>{revs}</td><td>{st.n_samples}</td>')


#: A record with more windows than this lists the first and last ones and those of the
#: largest and smallest TE p-p in the report's table (a 10-hour life test has ~2000).
MAX_WINDOW_ROWS = 40
_END_ROWS = 8


def _window_rows(windows: Sequence[WindowResult]) -> tuple[list[int], str]:
    """Indices of the windows the table lists, and a note on the ones it leaves out."""
    n = len(windows)
    if n <= MAX_WINDOW_ROWS:
        return list(range(n)), ''
    pps = np.array([w.stats.pp_rad if w.complete else np.nan for w in windows])
    keep = set(range(_END_ROWS)) | set(range(n - _END_ROWS, n))
    finite = np.flatnonzero(np.isfinite(pps))
    if finite.size:
        keep |= {int(finite[np.argmax(pps[finite])]), int(finite[np.argmin(pps[finite])])}
    note = (f'{n} windows: the first and last {_END_ROWS} and those of the largest and '
            'smallest TE p-p are listed; report.json holds every one')
    if finite.size:
        q = rad_to_arcmin(np.percentile(pps[finite], [0.0, 50.0, 100.0]))
        note += (f'. TE p-p of the {finite.size} complete windows: min {q[0]:.4f}, median '
                 f'{q[1]:.4f}, max {q[2]:.4f} arcmin')
    return sorted(keep), note + '.'


_STATS_HEAD = ('<th>TE p-p [arcmin]</th><th>amplitude max|TE| [arcmin]</th>'
               '<th>mean [arcmin]</th><th>std [arcmin]</th><th>output revs</th>'
               '<th>samples</th>')


def _img(images: dict[str, bytes], name: str, alt: str) -> str:
    data = images.get(name)
    if data is None:
        return ''
    b64 = base64.b64encode(data).decode('ascii')
    return f'<p><img alt="{_e(alt)}" src="data:image/png;base64,{b64}"></p>'


def _bag_section(res: AnalysisResult) -> str:
    out = [f'<h2>{_e(report_title(res))}</h2>', f'<p class="muted">bag {_e(res.path)}</p>']
    if res.partial or res.problems:
        kind = 'PARTIAL result' if res.partial else 'Note'
        out.append(f'<p class="warn"><b>{kind}:</b> '
                   + '<br>'.join(_e(p) for p in res.problems) + '</p>')
    b = res.bench
    out.append('<table>')
    rows = [('preset', b.preset or '(unknown)'), ('reducer type', b.reducer_type or '-'),
            ('bench id', b.bench_id or '-'),
            ('gear ratio i', f'{b.gear_ratio:.6g}'),
            ('crank revs per output rev (f_w / f_out)', f'{b.crank_per_output:.6g}'),
            ('mesh orders', ', '.join(f'{lab} = {o:.6g}' for o, lab in
                                      zip(b.mesh_orders_out, b.mesh_labels, strict=False))
             or '-'),
            ('encoders (in / out)', f'{b.encoder_in_model or "-"} / {b.encoder_out_model or "-"}'),
            ('ratio source', b.source), ('blocks read', str(res.blocks_read))]
    if not res.not_te_record:
        rows.append(('TE zero', res.te_reference.describe() if res.te_reference is not None
                     else 'no clean sample'))
    sess = res.session   # the unit under test, from the bag's metadata (bench description)
    rows += [(k, v) for k, v in (('unit serial', sess.unit_serial), ('operator', sess.operator),
                                 ('temperature [degC]', sess.temperature_c),
                                 ('notes', sess.unit_notes),
                                 ('imported from', sess.imported_from)) if v]
    out += [f'<tr><th class="l">{_e(k)}</th><td class="l">{_e(v)}</td></tr>' for k, v in rows]
    out.append('</table>')
    if res.not_te_record:
        out.append(f'<h3>TE</h3><p class="warn">{_e(res.not_te_record[0].upper())}'
                   f'{_e(res.not_te_record[1:])}.</p>')
    else:
        out.append(_te_section(res))
    if res.hysteresis is not None:
        out.append(_hysteresis_section(res.hysteresis))
    out.append(_gaps_section(res))
    if not res.not_te_record:
        out.append(_recommendation_section(res))
    return '\n'.join(out)


def _te_section(res: AnalysisResult) -> str:
    """Statistics, TE p-p with U, spectrum, budgets, dominant line, encoders."""
    out = []
    out.append('<h3>Statistics</h3><table><tr><th class="l">window</th><th>start [s]</th>'
               f'<th>end [s]</th><th class="l">complete</th>{_STATS_HEAD}</tr>')
    t0 = res.windows[0].start_stamp_s if res.windows else 0.0
    shown, note = _window_rows(res.windows)
    previous = -1
    for k in shown:
        w = res.windows[k]
        if k > previous + 1:
            out.append(f'<tr><td class="l muted" colspan="10">... {k - previous - 1} '
                       'windows ...</td></tr>')
        previous = k
        out.append(f'<tr><td class="l">{w.index}</td><td>{w.start_stamp_s - t0:.3f}</td>'
                   f'<td>{w.end_stamp_s - t0:.3f}</td><td class="l">{"yes" if w.complete else "no"}'
                   f'</td>{_stats_cells(w.stats)}</tr>')
    out.append(f'<tr><th class="l" colspan="4">cumulative (all clean samples)</th>'
               f'{_stats_cells(res.cumulative)}</tr></table>')
    if note:
        out.append(f'<p class="muted">{_e(note)}</p>')
    unc = res.uncertainty
    if unc is not None:
        parts = [f'{what} <b>{_am(bud.value)} &plusmn; {_am_g(bud.u95)}</b> arcmin'
                 for name, what in (('te_pp_revolution_max_rad',
                                     'largest of one output revolution'),
                                    ('te_pp_rad', 'all clean samples'))
                 if (bud := unc.budgets.get(name)) is not None]
        if parts:
            out.append(f'<p><b>TE p-p</b>: {"; ".join(parts)} (&plusmn; U, about 95 %; the '
                       'budgets below, docs/UNCERTAINTY.md).</p>')

    spec = res.spectrum
    out.append('<h3>Spectrum</h3>')
    if spec is None:
        out.append('<p>No complete output revolution: no spectrum.</p>')
    else:
        out.append(f'<p class="muted">{_e(spec.method)}. f_out = {spec.output_hz:.5g} Hz, '
                   f'f_w = {spec.crank_hz:.5g} Hz. Amplitude: peak of '
                   'a&middot;cos(order&middot;&phi; + phase), &phi; = &theta;<sub>in</sub>/i.</p>')
        out.append('<table><tr><th class="l">line</th><th>output order</th>'
                   '<th>crank order</th><th>frequency [Hz]</th><th>amplitude [arcmin]</th>'
                   '<th>&plusmn; U [arcmin]</th><th>spread between windows [arcmin]</th>'
                   '<th>phase [deg]</th><th>&plusmn; U [deg]</th></tr>')
        strongest = max((ln.amplitude_rad for ln in spec.lines), default=0.0)
        for ln, spread in zip(spec.lines, spec.amplitude_spread_rad, strict=True):
            phase = (f'{float(rad_to_deg(ln.phase_rad)):.1f}'
                     if ln.amplitude_rad > PHASE_MIN_FRACTION * strongest else '-')
            u_a, u_p = _line_u95(res, ln.label)
            u_p_text = f'{math.degrees(u_p):.2g}' if phase != '-' and math.isfinite(u_p) \
                else '-'
            out.append(f'<tr><td class="l">{_e(ln.label)}</td><td>{ln.output_order:.6g}</td>'
                       f'<td>{ln.crank_order:.4g}</td><td>{ln.frequency_hz:.5g}</td>'
                       f'<td>{_am(ln.amplitude_rad)}</td><td>{_am_g(u_a)}</td>'
                       f'<td>{_am(spread, 5)}</td><td>{phase}</td><td>{u_p_text}</td></tr>')
        lost = unassigned_lines(spec.orders, spec.amplitude_rad,
                                [ln.output_order for ln in spec.lines])
        out += [f'<tr class="unassigned"><td class="l">unassigned</td><td>{u.output_order:.6g}'
                f'</td><td>-</td><td>{u.output_order * spec.output_hz:.5g}</td>'
                f'<td>{_am(u.amplitude_rad)}</td><td>-</td><td>-</td><td>-</td><td>-</td></tr>'
                for u in lost]
        out.append(f'</table><p class="muted">Unassigned: a line at an order no part of the '
                   f'reducer explains ({_e(threshold_rule_text())}); {len(lost)} in this '
                   'spectrum.</p>')
    if unc is not None:
        out.append(_budgets_section(res))
    if res.dominant is not None:
        d = res.dominant
        out.append(f'<p><b>Dominant harmonic:</b> {_e(d.line.label)} '
                   f'(output order {d.line.output_order:.6g}, {_am(d.line.amplitude_rad)} '
                   f'arcmin). Likely source: {_e(d.likely_source)}.</p>')

    out.append(_encoder_section(res))
    return '\n'.join(out)


def _gaps_section(res: AnalysisResult) -> str:
    out = ['<h3>Gaps</h3>']
    if res.gaps:
        out.append('<table><tr><th class="l">kind</th><th>seq</th><th>at [s]</th>'
                   '<th>no data for [s]</th><th class="l">detail</th></tr>')
        out += [f'<tr><td class="l">{_e(g.kind)}</td><td>{g.seq}</td>'
                f'<td>{_secs(g.at_s)}</td><td>{_secs(g.missing_s)}</td>'
                f'<td class="l">{_e(g.detail)}</td></tr>' for g in res.gaps]
        out.append('</table>')
    else:
        out.append('<p>None.</p>')
    return '\n'.join(out)


def _recommendation_section(res: AnalysisResult) -> str:
    out = ['<h3>Recommendation</h3>']
    rec = res.recommendation
    ident = ('' if rec.identification is None else
             '<p class="muted">' + '<br>'.join(
                 _e(x) for x in describe_identification(rec.identification)) + '</p>')
    if rec.encoder_flag:
        out.append(f'<p class="warn"><b>Encoder:</b> {_e(rec.encoder_flag)}</p>')
    if rec.advice is None:
        out.append(f'<p>{_e(rec.reason)}</p>{ident}')
    else:
        a = rec.advice
        out.append(f'<p><b>{_e(a.method)}</b>: {_e(a.summary)}<br>TE {_e(a.te_metric)}: '
                   f'{_am(a.te_before_rad)} &rarr; {_am(a.te_after_rad)} arcmin '
                   f'<span class="muted">({_e(rec.reason)})</span></p>')
        if a.modifications:
            # the error sensitivity S_j (Hu 2020) exists for tooth-profile factors only: no
            # column of NaN for assembly phases
            sens = any(math.isfinite(m.sensitivity_index) for m in a.modifications)
            out.append('<table><tr><th class="l">factor</th><th class="l">symbol</th>'
                       '<th class="l">unit</th><th>current</th><th>recommended</th>'
                       + ('<th>sensitivity S<sub>j</sub></th>' if sens else '') + '</tr>')
            out += [f'<tr><td class="l">{_e(m.factor)}</td><td class="l">{_e(m.symbol)}</td>'
                    f'<td class="l">{_e(m.unit)}</td>'
                    f'<td>{modification_value(m.current_value, m.unit, html=True)}</td>'
                    f'<td>{modification_value(m.recommended_value, m.unit, html=True)}</td>'
                    + (f'<td>{_sens(m.sensitivity_index)}</td>' if sens else '') + '</tr>'
                    for m in a.modifications]
            out.append('</table>')
        out.append(ident)
    return '\n'.join(out)


def _hysteresis_section(h: dict[str, Any]) -> str:
    """Lost motion, backlash, rigidity and loss of a locked-input record (rv-te analyze)."""
    if 'error' in h:
        return f'<h3>Hysteresis</h3><p>None ({_e(h["error"])}).</p>'
    per_arcmin = float(rad_to_arcmin(1.0))
    method = 'torque steps' if h.get('method') == 'torque_steps' else 'constant speed'
    out = ['<h3>Hysteresis (input locked)</h3>',
           f'<p class="muted">{_e(h.get("positions"))} stretch(es), cycles '
           f'{_e(", ".join(str(c) for c in h.get("cycles", [])))}; {_e(method)}; T<sub>R</sub> '
           f'= {h["rated_torque_nm"]:.5g} N m ({_e(h.get("rated_from", ""))}); torque noise '
           f'{h["torque_noise_nm"]:.3g} N m. Catalogue definitions; the spread is the sample '
           'standard deviation over the cycles.</p>',
           '<table><tr><th class="l">metric</th><th>value</th><th>spread</th>'
           '<th class="l">unit</th></tr>']
    m, sd = h.get('metrics') or {}, h.get('spread') or {}
    for name, v in m.items():
        if name.endswith('_rad'):
            scale, unit = per_arcmin, 'arcmin'
        elif name.endswith('_nm_per_rad'):
            scale, unit = 1 / per_arcmin, 'N m/arcmin'
        else:
            scale, unit = 1.0, 'J' if name.endswith('_j') else ''
        val = '-' if v is None else f'{v * scale:.5g}'
        spr = '-' if sd.get(name) is None else f'{sd[name] * scale:.2g}'
        out.append(f'<tr><td class="l">{_e(name)}</td><td>{val}</td><td>{spr}</td>'
                   f'<td class="l">{_e(unit)}</td></tr>')
    out.append('</table>')
    if h.get('note'):
        out.append(f'<p class="muted">Not read: {_e(h["note"])}</p>')
    return '\n'.join(out)


def _encoder_section(res: AnalysisResult) -> str:
    """Read heads, calibration and the once-per-revolution note (issue 36)."""
    enc = res.encoder or {}
    out = ['<h3>Encoders and the once-per-revolution line</h3>']
    heads = enc.get('heads') or {}
    for side in ('output', 'input'):
        d = heads.get(side) or {}
        if d.get('layout') or d.get('calibration'):
            out.append(f'<p>{_e(side)} scale: {_e(d.get("description", ""))}</p>')
    events = heads.get('events') or []
    if events:
        n = (heads.get('counters') or {}).get('blocks_head_missing', len(events))
        out.append(f'<p class="warn">{n} blocks lacked read heads (nothing dropped; the windows '
                   'close there):<br>' + '<br>'.join(_e(x) for x in events[:10]) + '</p>')
    note = enc.get('once_per_rev') or {}
    if note:
        cls = 'warn' if note.get('comparable') and not note.get('separated') else 'muted'
        out.append(f'<p class="{cls}">{_e(note.get("text", ""))}</p>')
    return '\n'.join(out)
def _line_u95(res: AnalysisResult, label: str) -> tuple[float, float]:
    from rv_te_bench.report.uncertainty import line_budget_key

    if res.uncertainty is None:
        return math.nan, math.nan
    return (res.uncertainty.u95(line_budget_key(label, 'amplitude')),
            res.uncertainty.u95(line_budget_key(label, 'phase')))


def _budgets_section(res: AnalysisResult) -> str:
    """The budgets people audit: TE p-p of one revolution and the dominant line."""
    from rv_te_bench.report.uncertainty import budget_html, line_budget_key

    unc = res.uncertainty
    assert unc is not None
    shown = [('TE p-p, largest of one output revolution', 'te_pp_revolution_max_rad')]
    if res.dominant is not None:
        lab = res.dominant.line.label
        shown += [(f'line {lab} amplitude', line_budget_key(lab, 'amplitude')),
                  (f'line {lab} phase', line_budget_key(lab, 'phase'))]
    parts = ['<h3>Uncertainty budgets</h3><p class="muted">GUM law of propagation; k from '
             'the inputs\' distributions (about 95 %); every budget in report.json '
             '(uncertainty.budgets). Encoder inputs: '
             f'{_e(unc.bench.encoder_in.model)} (input), {_e(unc.bench.encoder_out.model)} '
             '(output).</p>']
    parts += [budget_html(title, unc.budgets[key]) for title, key in shown
              if key in unc.budgets]
    if unc.monte_carlo is not None and unc.monte_carlo.results:
        from rv_te_bench.report.uncertainty import display_of

        mc = unc.monte_carlo
        parts.append(f'<h4>Monte Carlo check (GUM Supplement 1, {mc.draws} draws)</h4>'
                     '<table><tr><th class="l">result</th><th>U law of propagation</th>'
                     '<th>U Monte Carlo</th><th>difference</th><th class="l">unit</th></tr>')
        for name, r in mc.results.items():
            sc, unit = display_of(name)
            parts.append(f'<tr><td class="l">{_e(name)}</td><td>{r.u_gum * sc:.3g}</td>'
                         f'<td>{r.u_mc * sc:.3g}</td><td>{100 * r.difference:+.1f} %</td>'
                         f'<td class="l">{unit}</td></tr>')
        parts.append('</table>')
    parts += [f'<p class="muted">note: {_e(n)}</p>' for n in unc.notes]
    return ''.join(parts)


def render_html(results: Sequence[AnalysisResult], images: dict[str, bytes],
                doc: dict[str, Any] | None = None) -> str:
    """One self-contained HTML page (PNGs embedded as base64).

    Args:
        results: One or more analyses.
        images: PNG bytes by file name (``te.png``, ``spectrum.png``, ``comparison.png``).
        doc: The report JSON (for the comparison rows); built when None.

    Returns:
        The page.
    """
    doc = report_json(results) if doc is None else doc
    # what the bags are (preset, bench, session, unit), not their folder names ("bag")
    kind = 'Record report' if all(r.not_te_record for r in results) else 'TE report'
    title = (f'{kind}: ' + report_title(results[0]) if len(results) == 1 else
             f'{kind}: comparison of {len(results)} sessions ('
             + '; '.join(report_title(r) for r in results) + ')')
    parts = [f'<!DOCTYPE html><html lang="en"><head><meta charset="utf-8">'
             f'<title>{_e(title)}</title><style>{_CSS}</style></head><body>',
             f'<h1>{_e(title)}</h1>',
             f'<p class="muted">Generated {_e(doc["generated_utc"])} by rv-te analyze. '
             'TE = &theta;<sub>out</sub> &minus; &theta;<sub>in</sub>/i (Wang 2020 Eq. 22, '
             'consistent form); statistics as the papers define them (p-p = max &minus; min, '
             'amplitude = max|TE|).</p>']
    if any(r.partial for r in results):
        parts.append('<p class="warn"><b>PARTIAL:</b> at least one bag could not be read to '
                     'its end; its figures cover what was read before the error.</p>')
    rows = doc.get('comparison')
    if rows:
        parts.append('<h2>Comparison (first bag = reference)</h2><table><tr><th class="l">bag'
                     '</th><th>p-p [arcmin]</th><th>amplitude [arcmin]</th><th>mean [arcmin]'
                     '</th><th>std [arcmin]</th><th class="l">dominant</th>'
                     '<th>p-p change [%]</th><th>amplitude change [%]</th></tr>')
        for row in rows:
            parts.append(
                f'<tr><td class="l">{_e(Path(row["bag"]).name)}'
                f'{" (PARTIAL)" if row["partial"] else ""}</td>'
                + ''.join(f'<td>{_fmt(row[k])}</td>' for k in
                          ('te_pp_arcmin', 'te_amplitude_arcmin', 'te_mean_arcmin',
                           'te_std_arcmin'))
                + f'<td class="l">{_e(row["dominant_label"] or "-")}</td>'
                f'<td>{_fmt(row["te_pp_change_pct"], 1)}</td>'
                f'<td>{_fmt(row["te_amplitude_change_pct"], 1)}</td></tr>')
        parts.append('</table>')
        parts.append(_img(images, 'comparison.png', 'TE statistics per bag'))
    parts.append(_img(images, 'te.png', 'TE against output angle'))
    parts.append(_img(images, 'spectrum.png', 'TE order spectrum'))
    parts.append(_img(images, 'windows.png', 'TE p-p and mean of each window over the session'))
    parts += [_bag_section(r) for r in results]
    parts.append('</body></html>\n')
    return '\n'.join(parts)




def _fmt(x: float | None, digits: int = 4) -> str:
    return '-' if x is None else f'{x:.{digits}f}'


def _sens(x: float) -> str:
    return f'{x:.4g}' if math.isfinite(x) else '-'
