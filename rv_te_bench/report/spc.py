"""Control-chart report of one metric across units: PNG, one HTML page, JSON.

The chart (I-MR, or X-bar/R by lot) from :mod:`rv_te_bench.core.spc` is drawn with the
centre line, the 3-sigma limits, the baseline shaded and every point a run rule flags in
red with the rule's name; capability against the tolerance sits under it. Values are
stored in SI and converted here, at the edge (radians -> arcmin, N m/rad -> N m/arcmin).
"""

from __future__ import annotations

import base64
import html
import io
import json
import math
from typing import TYPE_CHECKING, Any

import numpy as np

from rv_te_bench.io.files import write_all

if TYPE_CHECKING:
    from pathlib import Path

    from matplotlib.figure import Figure

    from rv_te_bench.core.spc import Capability, ControlChart
    from rv_te_bench.store import Series

__all__ = ['display_unit', 'spc_document', 'spc_figure', 'write_spc_report']


def display_unit(metric: str) -> tuple[float, str]:
    """(scale from the stored SI value, unit shown) of a metric name or ``line:LABEL``,
    from the one metric unit table (:func:`rv_te_bench.core.units.metric_unit`); a name
    the table does not know is shown as stored, without a unit."""
    from rv_te_bench.core.units import metric_unit

    try:
        unit = metric_unit(metric)
    except KeyError:
        return 1.0, ''
    return unit.per_si, unit.shown


def _labels(series: Series, chart: ControlChart) -> list[str]:
    if chart.kind == 'xbar-r':
        return [str(k) for k in dict.fromkeys(series.lots)]
    return [s or f'#{i}' for i, s in zip(series.result_ids, series.serials, strict=True)]


def spc_figure(chart: ControlChart, series: Series, *, title: str,
               capability: Capability | None = None) -> Figure:
    """The two-panel control chart (values above, moving range / range below)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    scale, unit = display_unit(series.metric)
    fig = Figure(figsize=(10.0, 6.0), dpi=110)
    FigureCanvasAgg(fig)
    fig.subplots_adjust(left=0.09, right=0.97, top=0.91, bottom=0.16, hspace=0.35)
    ax, ax_r = fig.add_subplot(2, 1, 1), fig.add_subplot(2, 1, 2, sharex=None)
    x = np.arange(chart.values.size)
    y = chart.values * scale
    if chart.baseline.size:
        lo, hi = chart.baseline.min() - 0.5, chart.baseline.max() + 0.5
        for a in (ax, ax_r):
            a.axvspan(lo, hi, color='#e8f0fe', zorder=0,
                      label='baseline' if a is ax else None)
    ax.plot(x, y, '-o', color='#1f4e79', ms=3.5, lw=1.0, zorder=2)
    ax.axhline(chart.centre * scale, color='#2e7d32', lw=1.0, label='centre')
    ax.step(x, chart.ucl * scale, where='mid', color='#c62828', lw=1.0, ls='--',
            label='3-sigma limits')
    ax.step(x, chart.lcl * scale, where='mid', color='#c62828', lw=1.0, ls='--')
    if capability is not None:
        for lim, name in ((capability.usl, 'USL'), (capability.lsl, 'LSL')):
            if lim is not None:
                ax.axhline(lim * scale, color='#6a1b9a', lw=1.2, ls=':', label=name)
    flagged: dict[int, list[str]] = {}
    for h in chart.hits:
        flagged.setdefault(h.index, []).append(h.rule)
    if flagged:
        idx = np.array(sorted(flagged))
        ax.plot(idx, y[idx], 'o', color='#d50000', ms=6, zorder=3, label='rule violated')
        for i in idx:   # name a rule where it starts firing, not at every point of a run
            new = [r for r in flagged[int(i)] if r not in flagged.get(int(i) - 1, ())]
            if new:
                ax.annotate(','.join(new), (i, y[i]), textcoords='offset points',
                            xytext=(0, 6), ha='center', fontsize=7, color='#d50000')
    ax.set_title(title, fontsize=11)
    kind = 'individual values' if chart.kind == 'individuals' else 'lot means (X-bar)'
    ax.set_ylabel(f'{kind} [{unit}]' if unit else kind, fontsize=9)
    ax.legend(fontsize=7, loc='upper left', ncols=4)
    r = chart.spread * scale
    ax_r.plot(x, r, '-o', color='#455a64', ms=3, lw=1.0)
    ax_r.axhline(chart.spread_centre * scale, color='#2e7d32', lw=1.0)
    ax_r.step(x, chart.spread_ucl * scale, where='mid', color='#c62828', lw=1.0, ls='--')
    over = np.flatnonzero(chart.spread > chart.spread_ucl)
    if over.size:
        ax_r.plot(over, r[over], 'o', color='#d50000', ms=6, zorder=3)
    ax_r.set_ylabel(('moving range' if chart.kind == 'individuals' else 'range')
                    + (f' [{unit}]' if unit else ''), fontsize=9)
    labels = _labels(series, chart)
    step = max(1, len(labels) // 25)
    for a in (ax, ax_r):
        a.set_xticks(x[::step])
        a.set_xlim(-0.5, max(x.size - 0.5, 0.5))
        a.grid(alpha=0.3)
    ax.set_xticklabels([])
    ax_r.set_xticklabels(labels[::step], rotation=60, ha='right', fontsize=7)
    ax_r.set_xlabel('unit (test order)' if chart.kind == 'individuals' else 'lot', fontsize=9)
    return fig


def spc_document(chart: ControlChart, series: Series, *, title: str,
                 capability: Capability | None, baseline_text: str) -> dict[str, Any]:
    """The JSON of an SPC run (display units, unit tagged; strict JSON: a value that is not
    finite, such as Cpk of a series without spread, is null)."""
    scale, unit = display_unit(series.metric)
    doc: dict[str, Any] = _finite({
        'title': title, 'metric': series.metric, 'direction': series.direction,
        'unit': unit, 'baseline': baseline_text, 'n_points': int(chart.values.size),
        'chart': chart.to_json_dict(scale, unit),
        'units': [{'result_id': i, 'serial': s, 'lot': lot, 'tested_at': t.isoformat(),
                   'value': v * scale}
                  for i, s, lot, t, v in zip(series.result_ids, series.serials, series.lots,
                                             series.tested_at, series.values, strict=True)],
        'capability': None if capability is None else capability.to_json_dict(scale, unit),
    })
    return doc


def _finite(obj: Any) -> Any:
    """``obj`` with every non-finite float replaced by None (JSON has no NaN/Infinity)."""
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_finite(v) for v in obj]
    if isinstance(obj, float | np.floating):
        return float(obj) if math.isfinite(obj) else None
    return obj


def write_spc_report(directory: Path, chart: ControlChart, series: Series, *, title: str,
                     capability: Capability | None, baseline_text: str) -> list[Path]:
    """Write spc.png, spc.json and spc.html into ``directory`` (all or nothing)."""
    directory.mkdir(parents=True, exist_ok=True)
    fig = spc_figure(chart, series, title=title, capability=capability)
    buf = io.BytesIO()
    fig.savefig(buf, format='png')
    png = buf.getvalue()
    doc = spc_document(chart, series, title=title, capability=capability,
                       baseline_text=baseline_text)
    page = _html(doc, base64.b64encode(png).decode('ascii'))
    write_all({directory / 'spc.png': png,   # all or nothing (no 0-byte PNG on a full disk)
               directory / 'spc.json': json.dumps(doc, indent=2, allow_nan=False) + '\n',
               directory / 'spc.html': page})
    return [directory / n for n in ('spc.png', 'spc.json', 'spc.html')]


def _n(v: float | None, digits: int = 4) -> str:
    return '&ndash;' if v is None else f'{v:.{digits}g}'


def _html(doc: dict[str, Any], png_b64: str) -> str:
    e = html.escape
    unit = doc['unit']
    ch = doc['chart']

    def serial(h: dict[str, Any]) -> str:
        return str(doc['units'][h['index']]['serial']) if ch['kind'] == 'individuals' else ''

    rows = ''.join(
        f'<tr><td>{h["index"]}</td><td class="l">{e(serial(h))}'
        f'</td><td class="l">{e(h["rule"])}</td><td class="l">{e(h["description"])}</td></tr>'
        for h in ch['hits'])
    cap = doc['capability']
    cap_html = '<p class="muted">No tolerance given: no capability (use --usl/--lsl).</p>'
    if cap is not None:
        cap_html = (
            '<table><tr><th>LSL</th><th>USL</th><th>mean</th><th>sigma within</th>'
            '<th>sigma overall</th><th>n</th><th>Cp</th><th>Cpk</th><th>Pp</th><th>Ppk</th>'
            '<th>out of tolerance</th></tr>'
            f'<tr><td>{_n(cap["lsl"])}</td><td>{_n(cap["usl"])}</td><td>{_n(cap["mean"])}</td>'
            f'<td>{_n(cap["sigma_within"])}</td><td>{_n(cap["sigma_overall"])}</td>'
            f'<td>{cap["n"]}</td><td>{_n(cap["cp"], 3)}</td><td>{_n(cap["cpk"], 3)}</td>'
            f'<td>{_n(cap["pp"], 3)}</td><td>{_n(cap["ppk"], 3)}</td>'
            f'<td>{100 * cap["fraction_out"]:.1f} %</td></tr></table>'
            + (f'<p>Measurement sigma {_n(cap["sigma_measurement"])} {e(unit)} (the stored '
               'u<sub>c</sub> of the values\' uncertainty budgets, rms): corrected for it, '
               f'Cp {_n(cap["cp_corrected"], 3)}, Cpk {_n(cap["cpk_corrected"], 3)}, '
               f'Pp {_n(cap["pp_corrected"], 3)}, Ppk {_n(cap["ppk_corrected"], 3)} '
               '(&sigma;<sub>process</sub><sup>2</sup> = &sigma;<sup>2</sup> &minus; '
               '&sigma;<sub>measurement</sub><sup>2</sup>; &ndash; where the measurement '
               'spread is not below the observed one).</p>'
               if cap.get('sigma_measurement') is not None else
               '<p class="muted">Measurement variance not known (no stored uncertainty): '
               'Cp/Cpk include the measurement\'s spread.</p>')
            + f'<p class="muted">Values in {e(unit) or "the metric unit"}. Cp/Cpk use the '
            'within sigma of the chart; Pp/Ppk the overall standard deviation.</p>')
    return (
        '<!DOCTYPE html><html lang="en"><head><meta charset="utf-8">'
        f'<title>{e(doc["title"])}</title><style>'
        'body{font-family:system-ui,Helvetica,Arial,sans-serif;margin:1.5em auto;'
        'max-width:1100px;color:#222;padding:0 1em}table{border-collapse:collapse;'
        'margin:.5em 0 1em}td,th{border:1px solid #ccc;padding:.2em .6em;text-align:right}'
        'th{background:#f0f0f0}td.l{text-align:left}img{max-width:100%;border:1px solid #ddd}'
        '.muted{color:#666}.bad{color:#b00020;font-weight:bold}.ok{color:#2e7d32}'
        '</style></head><body>'
        f'<h1>{e(doc["title"])}</h1>'
        f'<p>{doc["n_points"]} points; centre {_n(ch["centre"])} {e(unit)}, process sigma '
        f'{_n(ch["process_sigma"])} {e(unit)} from the baseline ({e(doc["baseline"])}); '
        f'run rules: {e(ch["rules"])}. '
        + (f'<span class="bad">{len(ch["hits"])} rule violation(s), first at point '
           f'{ch["hits"][0]["index"]}.</span>' if ch['hits'] else
           '<span class="ok">No rule violated.</span>')
        + '</p>'
        f'<img src="data:image/png;base64,{png_b64}" alt="control chart">'
        '<h2>Capability</h2>' + cap_html
        + '<h2>Rule violations</h2>'
        + ('<table><tr><th>point</th><th>unit</th><th>rule</th><th>meaning</th></tr>'
           + rows + '</table>' if rows else '<p>None.</p>')
        + '</body></html>\n')
