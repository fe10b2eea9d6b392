"""Report figures (matplotlib, Agg; no pyplot state, safe in threads and without a display).

* :func:`te_figure`: TE [arcmin] against output angle [deg] for one or several bags;
* :func:`spectrum_figure`: the full order spectrum (log axes) with the labelled lines marked,
  and a bar chart of the labelled lines ('1 f_w', 'f_w - f_out', 'mesh 52 f_w', ...);
* :func:`comparison_figure`: TE statistics of several bags side by side (before / after);
* :func:`windows_figure`: TE p-p and mean of every window over the session (a life test).

Values are converted from radians to arcmin here, at the edge, with :mod:`sim.units`.
"""

from __future__ import annotations

import io
import math
from typing import TYPE_CHECKING

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.ticker import FuncFormatter, NullFormatter

from rv_te_bench.io.files import write_atomic
from rv_te_bench.safe_yaml import printable
from sim.units import rad_to_arcmin, rad_to_deg

if TYPE_CHECKING:
    from collections.abc import Sequence
    from pathlib import Path

    from matplotlib.axes import Axes

    from rv_te_bench.report.analysis import AnalysisResult

__all__ = ['comparison_figure', 'png_bytes', 'save_png', 'spectrum_figure', 'te_figure',
           'windows_figure']

#: Records longer than this many output revolutions are folded onto 0..360 deg.
OVERLAY_REVOLUTIONS = 4

#: Largest number of labelled lines drawn as bars (the strongest ones, in order).
MAX_BARS = 14
_COLORS = ('tab:blue', 'tab:orange', 'tab:green', 'tab:red', 'tab:purple', 'tab:brown')
_DPI = 110


def _name(res: AnalysisResult) -> str:
    return printable(res.path.name or str(res.path))   # a non-UTF-8 folder name too


def _short(label: str) -> str:
    """A label short enough for a tick: 'stage-2 mesh (52 f_w, ...)' -> 'stage-2 mesh'."""
    return label.split(' (')[0] if len(label) > 16 else label


def _new_figure(width_in: float, height_in: float, **adjust: float) -> Figure:
    # Fixed margins: constrained layout costs seconds on log axes with many ticks.
    fig = Figure(figsize=(width_in, height_in), dpi=_DPI)
    FigureCanvasAgg(fig)
    fig.subplots_adjust(**{'left': 0.08, 'right': 0.98, 'top': 0.92, 'bottom': 0.12, **adjust})
    return fig


def png_bytes(fig: Figure) -> bytes:
    """Render a figure to PNG bytes."""
    buf = io.BytesIO()
    fig.savefig(buf, format='png', dpi=_DPI)
    return buf.getvalue()


def save_png(fig: Figure, path: Path) -> bytes:
    """Write a figure as PNG (atomically: never a 0-byte file) and return the bytes."""
    data = png_bytes(fig)
    write_atomic(path, data)
    return data


def te_figure(results: Sequence[AnalysisResult]) -> Figure:
    """TE against output angle, one trace per bag.

    The x axis is the output-shaft angle from the first sample of each bag [deg]. Up to
    ``OVERLAY_REVOLUTIONS`` revolutions are drawn end to end (dotted lines mark whole
    revolutions); longer records are folded onto 0..360 deg, one curve per revolution, so
    that repeatability shows. Gaps in a recording show as breaks.

    A record with more samples than its thinned trace keeps (``trace.stride`` > 1) is drawn
    from its min/max envelope instead (:mod:`rv_te_bench.core.envelope`: every sample lies
    in the band, however long the record): folded records as the band of all revolutions
    per bin of angle (half a degree), and a second panel shows the band over the whole
    session against output revolutions (a life test's drift).

    Args:
        results: One or more analyses (their thinned TE traces are drawn).

    Returns:
        The figure.
    """
    spans = [_span_deg(r) for r in results]
    fold = max(spans, default=0.0) > OVERLAY_REVOLUTIONS * 360.0
    banded = [r.trace.stride > 1 and r.trace.envelope is not None
              and r.trace.envelope.size > 0 for r in results]
    session = fold and any(banded)
    fig = _new_figure(10.0, 7.6 if session else 4.6, hspace=0.4,
                      **({'top': 0.95, 'bottom': 0.08} if session else {}))
    ax, ax_session = (fig.subplots(2, 1) if session else (fig.add_subplot(), None))
    for k, res in enumerate(results):
        st = res.cumulative
        label = (f'{_name(res)}: p-p {float(rad_to_arcmin(st.pp_rad)):.3f}\', '
                 f'mean {float(rad_to_arcmin(st.mean_rad)):.3f}\'')
        if res.partial:
            label += ' (PARTIAL)'
        color = _COLORS[k % len(_COLORS)]
        if banded[k]:
            _envelope_band(ax, ax_session, res, fold=fold, color=color, label=label)
            continue
        th = np.asarray(res.trace.theta_out_rad)
        te_am = rad_to_arcmin(np.asarray(res.trace.te_rad))
        finite = np.isfinite(th)
        if not finite.any():
            continue
        x_deg = rad_to_deg(th - th[finite][0])
        if fold:
            x_deg = np.mod(x_deg, 360.0)
            wraps = np.nonzero(np.diff(x_deg) < 0.0)[0] + 1
            x_deg = np.insert(x_deg, wraps, np.nan)
            te_am = np.insert(te_am, wraps, np.nan)
        ax.plot(x_deg, te_am, lw=0.5 if fold else 0.8, alpha=0.6 if fold else 1.0,
                color=color, label=label)
    ax.axhline(0.0, color='0.3', lw=0.6)
    if fold:
        ax.set_xlim(0.0, 360.0)
        ax.set_xticks(np.arange(0.0, 361.0, 45.0))
        ax.set_xlabel('output angle within the revolution [deg]  (all revolutions overlaid)')
    else:
        max_deg = max(spans, default=0.0)
        for rev in range(1, int(max_deg // 360.0) + 1):
            ax.axvline(rev * 360.0, color='0.6', lw=0.8, ls=':')
        if max_deg > 0:
            ax.set_xlim(0.0, max_deg)
        ax.set_xlabel('output angle from start of record [deg]  '
                      '(dotted: whole output revolutions)')
    ax.set_ylabel('transmission error TE [arcmin]')
    title = 'Transmission error  TE = theta_out - theta_in / i'
    if any(banded):
        title += '  (band: min-max of every sample)'
    else:
        stride = max((r.trace.stride for r in results), default=1)
        if stride > 1:
            title += f'  (1 in {stride} samples shown)'
    ax.set_title(title)
    ax.grid(visible=True, alpha=0.3)
    ax.legend(loc='upper right', fontsize=8)
    if ax_session is not None:
        ax_session.axhline(0.0, color='0.3', lw=0.6)
        ax_session.set_xlabel('output revolutions from start of record')
        ax_session.set_ylabel('TE [arcmin]')
        ax_session.set_title('TE over the whole session (band: min-max of every sample)')
        ax_session.grid(visible=True, alpha=0.3)
    return fig


def _envelope_band(ax: Axes, ax_session: Axes | None, res: AnalysisResult, *, fold: bool,
                   color: str, label: str) -> None:
    """Draw a record's min/max envelope: against angle (folded or not) and over the
    session (``ax_session``, when given); breaks at gaps."""
    env = res.trace.envelope
    assert env is not None
    lo = rad_to_arcmin(env.min_rad)
    hi = rad_to_arcmin(env.max_rad)
    x_rad = np.abs(env.phi_rad - env.phi_rad[0])
    if fold:
        nb = env.fold_min_rad.size
        x = (np.arange(nb) + 0.5) * (360.0 / nb)
        ax.fill_between(x, rad_to_arcmin(env.fold_min_rad), rad_to_arcmin(env.fold_max_rad),
                        color=color, alpha=0.5, lw=0.0, label=label)
    else:
        x, blo, bhi = _breaks(rad_to_deg(x_rad), lo, hi, env.segment)
        ax.fill_between(x, blo, bhi, color=color, alpha=0.6, lw=0.0, label=label)
    if ax_session is not None:
        x, slo, shi, seg = _coarser(x_rad / (2 * math.pi), lo, hi, env.segment,
                                    SESSION_BUCKETS)
        x, blo, bhi = _breaks(x, slo, shi, seg)
        ax_session.fill_between(x, blo, bhi, color=color, alpha=0.6, lw=0.0)


#: Buckets drawn across the session panel (~1000 pixels wide): 20000 buckets of a 10-hour
#: record drawn there alias the once-per-revolution swing of their maxima into stripes
#: that move at every gap; merged to about one bucket per pixel, the band is what each
#: pixel's samples span.
SESSION_BUCKETS = 1000


def _coarser(x: np.ndarray, lo: np.ndarray, hi: np.ndarray, segment: np.ndarray,
             most: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Merge runs of ``k`` neighbouring buckets (min of the mins, max of the maxes; never
    across a gap) so that about ``most`` remain; unchanged when there are no more."""
    k = -(-x.size // most)
    if k <= 1:
        return x, lo, hi, segment
    # a group starts every k buckets and at every segment start
    cuts = np.flatnonzero(np.r_[True, segment[1:] != segment[:-1]])
    starts = np.unique(np.concatenate([np.arange(c, e, k) for c, e in
                                       zip(cuts, [*cuts[1:], x.size], strict=True)]))
    return (x[starts], np.minimum.reduceat(lo, starts), np.maximum.reduceat(hi, starts),
            segment[starts])


def _breaks(x: np.ndarray, lo: np.ndarray, hi: np.ndarray, segment: np.ndarray,
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """NaN rows between segments (a gap shows as a break in the band)."""
    cuts = np.flatnonzero(segment[1:] != segment[:-1]) + 1
    return (np.insert(x, cuts, np.nan), np.insert(lo, cuts, np.nan),
            np.insert(hi, cuts, np.nan))


def _span_deg(res: AnalysisResult) -> float:
    """Output angle covered by a bag's trace [deg] (0 when empty)."""
    th = np.asarray(res.trace.theta_out_rad)
    th = th[np.isfinite(th)]
    return float(rad_to_deg(np.ptp(th))) if th.size else 0.0


def _strong_labels(results: Sequence[AnalysisResult]) -> list[tuple[float, str]]:
    """Labelled lines worth a bar: the strongest ones over all bags, in order of frequency."""
    best: dict[str, tuple[float, float]] = {}
    for res in results:
        if res.spectrum is None:
            continue
        for ln in res.spectrum.lines:
            old = best.get(ln.label, (ln.output_order, 0.0))
            best[ln.label] = (ln.output_order, max(old[1], ln.amplitude_rad))
    strongest = sorted(best.items(), key=lambda kv: -kv[1][1])[:MAX_BARS]
    return sorted(((order, label) for label, (order, _) in strongest), key=lambda x: x[0])


def _line_u95_arcmin(res: AnalysisResult) -> np.ndarray | None:
    """U of each labelled line's amplitude [arcmin], in the spectrum's order (None
    without budgets)."""
    from rv_te_bench.report.uncertainty import line_budget_key

    if res.uncertainty is None or res.spectrum is None:
        return None
    return rad_to_arcmin(np.array([res.uncertainty.u95(line_budget_key(ln.label, 'amplitude'))
                                   for ln in res.spectrum.lines]))


def spectrum_figure(results: Sequence[AnalysisResult]) -> Figure:
    """Order spectrum with labelled crank harmonics, sidebands and mesh orders.

    Top: full amplitude spectrum against output order (log axes), labelled lines marked.
    Bottom: bars of the labelled lines (peak amplitude [arcmin]), grouped by bag.

    Args:
        results: One or more analyses; those without a spectrum are listed as such.

    Returns:
        The figure.
    """
    fig = _new_figure(10.0, 7.6, top=0.95, bottom=0.12, hspace=0.45)
    ax_full, ax_bar = fig.subplots(2, 1, height_ratios=(1.0, 1.1))
    with_spec = [r for r in results if r.spectrum is not None]
    if not with_spec:
        for ax in (ax_full, ax_bar):
            ax.text(0.5, 0.5, 'no complete output revolution: no spectrum',
                    ha='center', va='center', transform=ax.transAxes)
            ax.set_axis_off()
        return fig
    peak = max(float(rad_to_arcmin(max((ln.amplitude_rad for ln in r.spectrum.lines),
                                           default=0.0))) for r in with_spec
               if r.spectrum is not None)
    floor = peak * 1e-4 if peak > 0 else 1e-9
    x_max = 1.0
    for k, res in enumerate(results):
        spec = res.spectrum
        if spec is None:
            continue
        color = _COLORS[k % len(_COLORS)]
        orders = np.asarray(spec.orders)[1:]
        amp = np.maximum(rad_to_arcmin(np.asarray(spec.amplitude_rad)[1:]), floor)
        ax_full.vlines(orders, floor, amp, lw=0.6, color=color, alpha=0.7,
                       label=f'{_name(res)} ({spec.n_windows} window(s) averaged)')
        line_o = np.array([ln.output_order for ln in spec.lines])
        line_a = np.maximum(rad_to_arcmin(np.array([ln.amplitude_rad for ln in spec.lines])),
                            floor)
        ax_full.plot(line_o, line_a, 'o', ms=4, mfc='none', color=color)
        line_u = _line_u95_arcmin(res)
        if line_u is not None:
            lo = np.minimum(line_u, line_a - floor)      # the bar stays on the log axis
            ax_full.errorbar(line_o, line_a, yerr=(lo, line_u), fmt='none', ecolor=color,
                             elinewidth=0.8, capsize=2)
        if line_o.size:
            x_max = max(x_max, float(line_o.max()))
        if k == 0:
            done: list[float] = []
            for ln, a in sorted(zip(spec.lines, line_a, strict=True),
                                key=lambda z: -z[1])[:6]:
                # Skip a label that would overlap a stronger one's (within 15 % in order).
                if a > 10 * floor and all(abs(math.log(ln.output_order / o)) > 0.14
                                          for o in done):
                    done.append(ln.output_order)
                    ax_full.annotate(_short(ln.label), (ln.output_order, a), xytext=(3, 4),
                                     textcoords='offset points', fontsize=7)
    ax_full.set_xscale('log')
    ax_full.set_yscale('log')
    # Plain tick labels: readable, and much faster than mathtext's 10^k.
    ax_full.xaxis.set_major_formatter(FuncFormatter(lambda v, _pos: f'{v:g}'))
    ax_full.yaxis.set_major_formatter(FuncFormatter(lambda v, _pos: f'{v:g}'))
    ax_full.xaxis.set_minor_formatter(NullFormatter())
    ax_full.yaxis.set_minor_formatter(NullFormatter())
    ax_full.set_xlim(0.7, x_max * 3.0)
    ax_full.set_ylim(floor, peak * 3.0)
    cpo = with_spec[0].bench.crank_per_output
    ax_full.set_xlabel(f'output order [cycles per output revolution]; k f_w is order {cpo:g} k'
                       '  (o: labelled lines)')
    ax_full.set_ylabel('peak amplitude [arcmin] (log)')
    ax_full.grid(visible=True, which='major', alpha=0.3)
    ax_full.legend(loc='upper right', fontsize=8)
    first = with_spec[0].spectrum
    assert first is not None
    ax_full.set_title(f'TE order spectrum: f_out = {first.output_hz:.4g} Hz, '
                      f'f_w = {first.crank_hz:.4g} Hz (mean speed)')

    chosen = _strong_labels(results)
    n_bags = len(results)
    width = 0.8 / max(n_bags, 1)
    xs = np.arange(len(chosen))
    for k, res in enumerate(results):
        if res.spectrum is None:
            continue
        amp_by = {ln.label: ln.amplitude_rad for ln in res.spectrum.lines}
        vals = rad_to_arcmin(np.array([amp_by.get(lab, math.nan) for _, lab in chosen]))
        u_lines = _line_u95_arcmin(res)
        u_by = dict(zip((ln.label for ln in res.spectrum.lines),
                        u_lines if u_lines is not None
                        else [math.nan] * len(res.spectrum.lines), strict=True))
        errs = np.array([u_by.get(lab, math.nan) for _, lab in chosen])
        bars = ax_bar.bar(xs + (k - (n_bags - 1) / 2) * width, vals, width,
                          color=_COLORS[k % len(_COLORS)], label=_name(res),
                          yerr=np.where(np.isfinite(errs), errs, 0.0), capsize=3,
                          error_kw={'elinewidth': 0.9})
        if n_bags == 1:  # values stay readable on single bars only
            texts = [f'{v:.3f}' if np.isfinite(v) and v >= 0.01 * peak else '' for v in vals]
            ax_bar.bar_label(bars, labels=texts, fontsize=7, padding=1)
    ax_bar.set_xticks(xs, [_short(lab) for _, lab in chosen], rotation=35, ha='right',
                      fontsize=8)
    ax_bar.set_ylabel('peak amplitude [arcmin]')
    ax_bar.set_title(f'The {len(chosen)} strongest labelled lines (crank harmonics, sidebands, '
                     'mesh orders) by frequency, +-U (~95 %)')
    ax_bar.grid(visible=True, axis='y', alpha=0.3)
    if n_bags > 1:
        ax_bar.legend(fontsize=8)
    return fig


def comparison_figure(results: Sequence[AnalysisResult]) -> Figure:
    """TE statistics of several bags side by side (the first is the reference).

    Args:
        results: Two or more analyses.

    Returns:
        The figure: grouped bars of p-p, amplitude, |mean| and std [arcmin].
    """
    fig = _new_figure(9.0, 4.2)
    ax = fig.add_subplot()
    names = ('p-p', 'amplitude max|TE|', '|mean|', 'std')
    n_bags = len(results)
    width = 0.8 / max(n_bags, 1)
    xs = np.arange(len(names))
    for k, res in enumerate(results):
        st = res.cumulative
        vals = rad_to_arcmin(np.array([st.pp_rad, st.amplitude_rad, abs(st.mean_rad),
                                       st.std_rad]))
        label = _name(res) + (' (PARTIAL)' if res.partial else '')
        bars = ax.bar(xs + (k - (n_bags - 1) / 2) * width, vals, width,
                      color=_COLORS[k % len(_COLORS)], label=label)
        ax.bar_label(bars, fmt='%.3f', fontsize=7, padding=1)
    ax.set_xticks(xs, names)
    ax.set_ylabel('TE [arcmin]')
    ax.set_title('TE statistics over all clean samples, bag by bag')
    ax.grid(visible=True, axis='y', alpha=0.3)
    ax.legend(fontsize=8)
    return fig


def windows_figure(results: Sequence[AnalysisResult]) -> Figure:
    """TE p-p and mean of each complete window against time from the start of the record.

    The trend of a long session (a life test's wear, a warm-up's drift), one point per
    window (one output revolution by default: ~2000 over 10 hours at 1 rev/16 s), where
    the report's table lists only the first and last windows and the extremes. Time in
    hours, minutes or seconds by the longest record.

    Args:
        results: One or more analyses.

    Returns:
        The figure: TE p-p per window (top), mean per window (bottom) [arcmin].
    """
    fig = _new_figure(10.0, 6.4, top=0.94, bottom=0.09, hspace=0.35)
    ax_pp, ax_mean = fig.subplots(2, 1, sharex=True)
    span_s = max((w.end_stamp_s - r.windows[0].start_stamp_s for r in results
                  for w in r.windows[-1:]), default=0.0)
    unit, per_s = (('h', 3600.0) if span_s > 7200.0 else ('min', 60.0) if span_s > 120.0
                   else ('s', 1.0))
    for k, res in enumerate(results):
        done = [w for w in res.windows if w.complete]
        if not done:
            continue
        t0 = res.windows[0].start_stamp_s
        t = np.array([0.5 * (w.start_stamp_s + w.end_stamp_s) - t0 for w in done]) / per_s
        pp = rad_to_arcmin(np.array([w.stats.pp_rad for w in done]))
        mean = rad_to_arcmin(np.array([w.stats.mean_rad for w in done]))
        color = _COLORS[k % len(_COLORS)]
        style = {'color': color, 'lw': 0.6, 'marker': '.', 'ms': 2.0 if t.size > 200 else 4.0}
        ax_pp.plot(t, pp, label=f'{_name(res)} ({t.size} windows)', **style)
        ax_mean.plot(t, mean, **style)
    # p-p from zero (a wear of 10 % looks like 10 %), the mean over at least a tenth of the
    # largest p-p: the noise of a steady unit is no trend; plain numbers on the ticks
    top = max((float(np.nanmax(line.get_ydata())) for line in ax_pp.lines), default=0.0)
    if math.isfinite(top) and top > 0:
        ax_pp.set_ylim(0.0, 1.15 * top)
        lo, hi = ax_mean.get_ylim()
        if hi - lo < 0.1 * top:
            mid = 0.5 * (lo + hi)
            ax_mean.set_ylim(mid - 0.05 * top, mid + 0.05 * top)
    for ax in (ax_pp, ax_mean):
        ax.ticklabel_format(axis='y', useOffset=False, style='plain')
    ax_pp.set_ylabel('TE p-p per window [arcmin]')
    ax_pp.set_title('TE of each complete window over the session')
    ax_pp.legend(loc='upper right', fontsize=8)
    ax_mean.set_ylabel('mean TE per window [arcmin]')
    ax_mean.set_xlabel(f'time from start of record [{unit}] (window centre)')
    for ax in (ax_pp, ax_mean):
        ax.grid(visible=True, alpha=0.3)
    return fig
