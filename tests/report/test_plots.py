"""Report figures: what is drawn (data of the artists), not pixels."""

from __future__ import annotations

import numpy as np
import pytest

from rv_te_bench.report.analysis import analyze_bag
from rv_te_bench.report.plots import (
    OVERLAY_REVOLUTIONS,
    png_bytes,
    spectrum_figure,
    te_figure,
)
from sim.units import arcmin_to_rad, rad_to_arcmin
from tests.report.synthetic_bags import Harmonic, write_bag

HARMONICS = (Harmonic(25.0, float(arcmin_to_rad(0.6)), 0.3),
             Harmonic(1300.0, float(arcmin_to_rad(0.02)), 0.0))


@pytest.mark.parametrize(('duration_s', 'folded'), [(3.0, False), (12.0, True)])
def test_te_figure_axes_and_folding(tmp_path, duration_s: float, folded: bool) -> None:
    path = tmp_path / 'bag'
    synth = write_bag(path, harmonics=HARMONICS, duration_s=duration_s)  # 0.5 rev/s
    res = analyze_bag(path, with_advice=False)
    fig = te_figure([res])
    ax = fig.axes[0]
    assert 'arcmin' in ax.get_ylabel() and '[deg]' in ax.get_xlabel()
    (line,) = [ln for ln in ax.get_lines() if ln.get_label().startswith('bag')]
    x = np.asarray(line.get_xdata(), dtype=float)
    y = np.asarray(line.get_ydata(), dtype=float)
    revs = duration_s * 0.5
    assert (revs > OVERLAY_REVOLUTIONS) is folded
    if folded:
        assert np.nanmax(x) < 360.0
        assert np.isnan(x).sum() == int(np.ceil(revs)) - 1  # one break per wrap
    else:
        assert np.nanmax(x) == pytest.approx(revs * 360.0, rel=2e-3)
    # the drawn values are the written TE in arcmin
    assert np.nanmax(y) == pytest.approx(float(rad_to_arcmin(synth.te_rad.max())), rel=1e-12)
    assert png_bytes(fig).startswith(b'\x89PNG')


def test_spectrum_figure_labels_lines(tmp_path) -> None:
    path = tmp_path / 'bag'
    write_bag(path, harmonics=HARMONICS, duration_s=4.5, sample_rate_hz=4000.0)
    res = analyze_bag(path, with_advice=False)
    fig = spectrum_figure([res])
    ax_full, ax_bar = fig.axes
    notes = {t.get_text() for t in ax_full.texts}
    assert {'1 f_w', 'mesh 52 f_w'} <= notes
    ticks = [t.get_text() for t in ax_bar.get_xticklabels()]
    assert '1 f_w' in ticks and 'f_w - f_out' in ticks
    heights = {t: p.get_height() for t, p in zip(ticks, ax_bar.patches, strict=True)}
    assert heights['1 f_w'] == pytest.approx(0.6, rel=1e-6)
    assert heights['mesh 52 f_w'] == pytest.approx(0.02, rel=1e-3)
    assert 'arcmin' in ax_bar.get_ylabel() and 'output order' in ax_full.get_xlabel()


def test_long_record_is_drawn_as_a_band_holding_every_sample(tmp_path) -> None:
    """A record thinned for the plot (stride > 1) is drawn from its min/max envelope: the
    band reaches the written TE's extremes, which a 1-in-k trace can miss, and a second
    panel shows the whole session against output revolutions."""
    from rv_te_bench.report.analysis import MAX_TRACE_POINTS

    path = tmp_path / 'bag'
    fs = 4000.0
    duration_s = 1.5 * MAX_TRACE_POINTS / fs          # thinned at least by 2
    # a narrow spike per revolution (order 300 harmonics summed): peaks between samples
    harmonics = (*HARMONICS, Harmonic(997.0, float(arcmin_to_rad(0.05)), 0.1))
    synth = write_bag(path, harmonics=harmonics, duration_s=duration_s, sample_rate_hz=fs,
                      block_size=400)
    res = analyze_bag(path, with_advice=False)
    assert res.trace.stride > 1
    fig = te_figure([res])
    ax, ax_session = fig.axes
    assert 'band' in ax.get_title() and 'revolutions' in ax_session.get_xlabel()
    (band,) = [c for c in ax.collections if c.get_label().startswith('bag')]
    verts = np.concatenate([p.vertices for p in band.get_paths()])
    te_am = rad_to_arcmin(synth.te_rad)
    assert verts[:, 1].max() == pytest.approx(float(te_am.max()), rel=1e-9)
    assert verts[:, 1].min() == pytest.approx(float(te_am.min()), rel=1e-9)
    assert verts[:, 0].min() >= 0.0 and verts[:, 0].max() <= 360.0
    (session,) = ax_session.collections
    sv = np.concatenate([p.vertices for p in session.get_paths()])
    # x: where each bucket starts (0.5 rev/s): the last within one bucket of the end
    bucket_rev = res.trace.envelope.bucket_samples / fs * 0.5
    assert duration_s * 0.5 - bucket_rev - 1e-9 <= sv[:, 0].max() <= duration_s * 0.5
    assert png_bytes(fig).startswith(b'\x89PNG')


def test_session_band_merges_buckets_to_the_panel_width_never_across_a_gap() -> None:
    """20000 buckets of a 10-hour record are merged for the session panel to about one a
    pixel: each merged bucket spans exactly the samples of the buckets it replaces (checked
    bucket by bucket here), and no merged bucket spans a gap."""
    from rv_te_bench.report.plots import SESSION_BUCKETS, _coarser

    rng = np.random.default_rng(5)
    n = 20_000
    x = np.cumsum(rng.uniform(0.05, 0.15, n))
    lo = rng.normal(-1.0, 0.1, n)
    hi = lo + rng.uniform(0.0, 2.0, n)
    segment = np.repeat([0, 1, 2, 3], [7001, 3, 9000, n - 7001 - 3 - 9000])
    cx, clo, chi, cseg = _coarser(x, lo, hi, segment, SESSION_BUCKETS)
    assert SESSION_BUCKETS / 2 < cx.size <= SESSION_BUCKETS + 4
    # independent: each original bucket belongs to the merged one that starts at or before
    # it in its own segment
    owner = np.searchsorted(cx, x, side='right') - 1
    for j in range(cx.size):
        mine = owner == j
        assert np.all(segment[mine] == cseg[j])            # never across a gap
        assert clo[j] == lo[mine].min() and chi[j] == hi[mine].max()
    assert cseg.tolist() == sorted(cseg.tolist()) and set(cseg.tolist()) == {0, 1, 2, 3}
    # few buckets: drawn as they are
    same = _coarser(x[:500], lo[:500], hi[:500], segment[:500], SESSION_BUCKETS)
    first = (x[:500], lo[:500], hi[:500], segment[:500])
    assert all(np.array_equal(a, b) for a, b in zip(same, first, strict=True))
