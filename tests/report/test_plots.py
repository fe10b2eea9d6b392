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
