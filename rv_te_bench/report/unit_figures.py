"""The unit report's figures, in the report's one angle unit, with the limits drawn.

- ``te.png``: one panel per direction of rotation (ccw above, cw below, the same scales),
  so neither curve can hide the other; each curve referred to its mid-range, with the band
  of the TE p-p limit (+-limit/2): a curve inside the band has a p-p within the limit.
- ``hysteresis.png``: the loop with the limit bands: backlash (the zero-torque width must
  fit between the dashed verticals), lost motion (the box between +-3 % torque) and the
  minimum rigidity (the grey secant each side must be at least as steep as).
- ``spectrum.png``: the lines of each direction side by side (colour and hatch per
  direction), labelled and unassigned, with the threshold.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, TypedDict

import numpy as np

from rv_te_bench.core.spectrum_lines import line_threshold_rad, unassigned_lines
from rv_te_bench.report.loss_report import loss_figures
from rv_te_bench.report.plots import _new_figure, _short, png_bytes
from rv_te_bench.report.unit_doc import angle_unit

if TYPE_CHECKING:
    from collections.abc import Callable

    import numpy.typing as npt
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from rv_te_bench.report.unit_doc import AngleUnit

__all__ = ['DIRECTION_STYLE', 'limit_si', 'spectrum_table', 'unit_figures']

#: Direction -> (colour, line style, hatch, words): the same in every figure.
DIRECTION_STYLE = {'ccw': ('tab:blue', '-', '', 'ccw (output +)'),
                   'cw': ('tab:red', '--', '//', 'cw (output -)')}


class _Shade(TypedDict):
    """Keyword arguments of matplotlib's shading (``axhspan``, ``fill_between``)."""

    color: str
    alpha: float


#: How a limit is drawn.
_LIMIT: _Shade = {'color': '#2e7d32', 'alpha': 0.12}


def _style(direction: str) -> tuple[str, str, str, str]:
    return DIRECTION_STYLE.get(direction, ('tab:gray', ':', '..', direction))


def limit_si(report: dict[str, Any], family: str, side: str, region: str = '') -> float:
    """A limit of the profile in SI (NaN: none)."""
    for lim in (report.get('tolerance') or {}).get('limits', []):
        if lim['family'] == family and (not region or lim.get('region') == region):
            v = lim.get(f'{side}_si')
            return math.nan if v is None else float(v)
    return math.nan


def spectrum_table(row: dict[str, Any]) -> list[dict[str, Any]]:
    """The lines of one TE row: labelled (all) then unassigned (above the threshold), each
    ``{'label', 'output_order', 'amplitude_rad', 'assigned', 'above'}``, by order."""
    orders, amp = row.get('spectrum_orders') or [], row.get('spectrum_amplitude_rad') or []
    thr = line_threshold_rad(orders, amp) if len(orders) else math.nan
    out = [{'label': ln['label'], 'output_order': ln['output_order'],
            'amplitude_rad': ln['amplitude_rad'], 'assigned': True,
            'above': math.isfinite(thr) and ln['amplitude_rad'] >= thr}
           for ln in row.get('spectrum', [])]
    if len(orders):
        out += [{'label': 'unassigned', 'output_order': u.output_order,
                 'amplitude_rad': u.amplitude_rad, 'assigned': False, 'above': True}
                for u in unassigned_lines(orders, amp, [ln['output_order']
                                                        for ln in row.get('spectrum', [])])]
    return sorted(out, key=lambda x: x['output_order'])


def _te_figure(rows: list[dict[str, Any]], au: AngleUnit, limit_rad: float) -> Figure:
    dirs = list(dict.fromkeys(r['direction'] for r in rows if r.get('position_rad')))
    fig = _new_figure(9.0, 1.0 + 2.3 * len(dirs), left=0.09, bottom=0.5 / (1 + 2.3 * len(dirs))
                      + 0.05, top=0.89, hspace=0.4)
    axes = fig.subplots(len(dirs), 1, sharex=True, sharey=True, squeeze=False)[:, 0]
    for ax, d in zip(axes, dirs, strict=True):
        colour, ls, _, words = _style(d)
        for r in rows:
            if r['direction'] != d or not r.get('position_rad'):
                continue
            te = np.array([np.nan if x is None else x for x in r['te_by_position_rad']])
            mid = 0.5 * (np.nanmax(te) + np.nanmin(te))
            ax.plot(np.degrees(r['position_rad']), (te - mid) * au.per_rad, ls, lw=1.1,
                    color=colour, label=f"{words}: {r['speed_rpm']:g} rpm, {r['load_nm']:g} N m")
        if math.isfinite(limit_rad):
            h = 0.5 * limit_rad * au.per_rad
            ax.axhspan(-h, h, **_LIMIT, label=f'TE p-p limit {2 * h:.4g} {au.name} (+-limit/2)')
            for y in (-h, h):
                ax.axhline(y, color=_LIMIT['color'], lw=0.8)
        ax.set_ylabel(f'TE - mid-range\n[{au.name}]', fontsize=8.5)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7.5, loc='upper right')
        ax.set_title(f'direction {words}', fontsize=9, loc='left')
    axes[-1].set_xlabel('output position [deg] (one revolution, mean over the revolutions)')
    axes[-1].set_xlim(0, 360)
    fig.suptitle('Transmission error per direction of rotation (green: limit band)', fontsize=10)
    return fig


def _hysteresis_limits(ax: Axes, report: dict[str, Any], h: dict[str, Any],
                       am: Callable[[npt.ArrayLike], np.ndarray], au: AngleUnit) -> None:
    bl = limit_si(report, 'backlash', 'max')
    if math.isfinite(bl):
        for x in (-0.5 * bl * au.per_rad, 0.5 * bl * au.per_rad):
            ax.axvline(x, color=_LIMIT['color'], ls='--', lw=1.5)
        ax.plot([], [], '--', color=_LIMIT['color'],
                label=f'backlash limit {bl * au.per_rad:.4g} {au.name} (width at T = 0)')
    lm, t = limit_si(report, 'lost_motion', 'max'), h['lost_motion_torque_nm']
    if math.isfinite(lm):
        x = 0.5 * lm * au.per_rad
        ax.fill_between([-x, x], [-t, -t], [t, t], **_LIMIT,
                        label=f'lost motion limit {lm * au.per_rad:.4g} {au.name} '
                              f'(between +-{t:.4g} N m)')
    for name, sides in h['rigidity_points'].items():
        k = limit_si(report, 'torsional_rigidity', 'min', name)
        if not math.isfinite(k):
            continue
        for side in sides:
            if None not in side:
                t1, p1, t2, _ = side
                p_end = p1 + (t2 - t1) / k   # angle at t2 along the limit's slope
                ax.plot(am([p1, p_end]), [t1, t2], '-', color='0.45', lw=2.5, alpha=0.6)
        ax.plot([], [], '-', color='0.45', lw=2.5, alpha=0.6,
                label=f'rigidity {name} limit {k / au.per_rad:.4g} N m/{au.name} (slope)')


def _hysteresis_figure(report: dict[str, Any], h: dict[str, Any], au: AngleUnit) -> Figure:
    """The whole curve (left) and its middle, |T| <= 4 x the lost-motion torque (right)."""
    fig = _new_figure(10.0, 4.8, left=0.07, bottom=0.12, wspace=0.22)
    grid = fig.add_gridspec(1, 3)
    ax_all, ax_mid = fig.add_subplot(grid[0, :2]), fig.add_subplot(grid[0, 2])
    c = h['centre_rad'] or 0.0

    def am(x: npt.ArrayLike) -> np.ndarray:
        return (np.asarray(x, dtype=float) - c) * au.per_rad

    t = h['lost_motion_torque_nm']
    for ax in (ax_all, ax_mid):
        ax.plot(am(h['ascending_angle_rad']), h['ascending_torque_nm'], '.-', ms=3, lw=0.9,
                color='tab:blue', label='loading upwards (-T_R -> 0, 0 -> +T_R)')
        ax.plot(am(h['descending_angle_rad']), h['descending_torque_nm'], '.-', ms=3, lw=0.9,
                color='tab:orange', label='loading downwards (+T_R -> -T_R)')
        _hysteresis_limits(ax, report, h, am, au)
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
        ax.set_xlabel(f'output torsion angle [{au.name}]')
    ax_all.set_ylabel('torque on the output [N m]')
    ax_all.legend(fontsize=7, loc='upper left')
    ax_all.set_title(f"Hysteresis curve (input locked, {h['method'].replace('_', ' ')}, "
                     f"T_R = {h['rated_torque_nm']:g} N m; 0 = middle of the backlash; "
                     'green: limits)', fontsize=9.5)
    lim = 4.0 * t
    ax_mid.set_ylim(-lim, lim)
    near = [am(a)[np.abs(np.asarray(tq)) <= lim] for a, tq in (
        (h['ascending_angle_rad'], h['ascending_torque_nm']),
        (h['descending_angle_rad'], h['descending_torque_nm']))]
    xs = np.concatenate(near) if near else np.zeros(1)
    bl = limit_si(report, 'backlash', 'max') * au.per_rad
    if xs.size:
        lo, hi = float(xs.min()), float(xs.max())
        if math.isfinite(bl):
            lo, hi = min(lo, -0.5 * bl), max(hi, 0.5 * bl)
        pad = 0.15 * max(hi - lo, 1e-3)
        ax_mid.set_xlim(lo - pad, hi + pad)
    ax_mid.set_title('middle (lost motion, backlash)', fontsize=10)
    return fig


def _spectrum_figure(rows: list[dict[str, Any]], au: AngleUnit) -> Figure:
    fig = _new_figure(9.0, 3.8, left=0.09, bottom=0.24)
    ax = fig.add_subplot(1, 1, 1)
    tables = [spectrum_table(r) for r in rows]
    best: dict[tuple[str, float], float] = {}
    for tab in tables:
        for ln in tab:
            key = (ln['label'], round(ln['output_order'], 6))
            best[key] = max(best.get(key, 0.0), ln['amplitude_rad'])
    # the 20 strongest lines (of labelled and unassigned), by order; the table has them all
    keys = sorted(sorted(best, key=lambda k: -best[k])[:20], key=lambda k: k[1])
    width = 0.8 / max(1, len(rows))
    for j, (r, tab) in enumerate(zip(rows, tables, strict=True)):
        amp = {(ln['label'], round(ln['output_order'], 6)): ln['amplitude_rad'] for ln in tab}
        colour, _, hatch, words = _style(r['direction'])
        ax.bar(np.arange(len(keys)) + j * width, [amp.get(k, 0.0) * au.per_rad for k in keys],
               width, color=colour, hatch=hatch, edgecolor='k', lw=0.4,
               label=f"{words}, {r['speed_rpm']:g} rpm, {r['load_nm']:g} N m")
    thr = [line_threshold_rad(r.get('spectrum_orders') or [], r.get('spectrum_amplitude_rad')
                              or []) for r in rows if r.get('spectrum_orders')]
    if thr and math.isfinite(max(thr)):
        ax.axhline(max(thr) * au.per_rad, color='0.4', ls=':', lw=1,
                   label='threshold of an unassigned line')
    ax.set_xticks(np.arange(len(keys)) + 0.4 - width / 2)
    ax.set_xticklabels([f'unassigned {o:g}' if lab == 'unassigned' else _short(lab)
                        for lab, o in keys], rotation=40, ha='right', fontsize=8)
    for tick, (lab, _) in zip(ax.get_xticklabels(), keys, strict=True):
        if lab == 'unassigned':
            tick.set_color('tab:purple')
    ax.set_ylabel(f'amplitude [{au.name}]')
    ax.set_yscale('log')
    ax.legend(fontsize=7.5)
    ax.grid(alpha=0.3, axis='y')
    ax.set_title('TE order spectrum: labelled and unassigned lines (peak amplitude, log scale)',
                 fontsize=10)
    return fig


def unit_figures(report: dict[str, Any]) -> dict[str, bytes]:
    """PNG bytes by file name: te.png, hysteresis.png, spectrum.png (what was measured)."""
    au = angle_unit(report)
    out: dict[str, bytes] = {}
    te_rows = [r for s in report['steps'] if s['kind'] == 'te' for r in s.get('rows', [])]
    if any(r.get('position_rad') for r in te_rows):
        out['te.png'] = png_bytes(_te_figure(te_rows, au, limit_si(report, 'te_pp', 'max')))
        if any(r.get('spectrum') for r in te_rows):
            out['spectrum.png'] = png_bytes(_spectrum_figure(te_rows, au))
    for s in report['steps']:
        if s['kind'] == 'hysteresis' and s.get('ascending_torque_nm'):
            out['hysteresis.png'] = png_bytes(_hysteresis_figure(report, s, au))
            break
    out.update(loss_figures(report))
    return out
