"""report.html: the JSON document, the self-contained page, and the report folder rules."""

from __future__ import annotations

import base64
from typing import TYPE_CHECKING

import pytest

from rv_te_bench.report.analysis import analyze_bag
from rv_te_bench.report.html import ReportExistsError, render_html, report_json, write_report
from sim.units import arcmin_to_rad
from tests.report.synthetic_bags import Harmonic, write_bag

if TYPE_CHECKING:
    from pathlib import Path

    from rv_te_bench.report.analysis import AnalysisResult

HARMONICS = (Harmonic(25.0, float(arcmin_to_rad(0.6)), 0.3),)


@pytest.fixture(scope='module')
def results(tmp_path_factory: pytest.TempPathFactory) -> list[AnalysisResult]:
    root = tmp_path_factory.mktemp('html')
    out = []
    for name, scale in (('before', 1.0), ('after', 0.5)):
        write_bag(root / name, duration_s=4.0,
                  harmonics=[Harmonic(h.output_order, h.amplitude_rad * scale, h.phase_rad)
                             for h in HARMONICS])
        out.append(analyze_bag(root / name, with_advice=False))
    return out


def test_report_json_has_a_comparison_only_for_several_bags(
        results: list[AnalysisResult]) -> None:
    one = report_json(results[:1])
    assert one['comparison'] is None
    assert [b['bag'] for b in one['bags']] == [str(results[0].path)]
    two = report_json(results)
    rows = two['comparison']
    assert [r['bag'] for r in rows] == [str(r.path) for r in results]
    assert rows[1]['te_pp_change_pct'] == pytest.approx(-50.0, abs=2.0)


def test_page_embeds_the_images_and_names_the_sessions(results: list[AnalysisResult]) -> None:
    png = b'\x89PNG fake'
    page = render_html(results, {'te.png': png, 'comparison.png': png})
    assert page.startswith('<!DOCTYPE html>')
    assert page.count('data:image/png;base64,' + base64.b64encode(png).decode()) == 2
    assert 'spectrum.png' not in page             # an image not given is left out
    assert 'comparison of 2 sessions' in page
    assert 'Comparison (first bag = reference)' in page
    assert 'PARTIAL' not in page


def test_an_existing_folder_needs_force(results: list[AnalysisResult], tmp_path: Path) -> None:
    folder = tmp_path / 'rep'
    folder.mkdir()
    with pytest.raises(ReportExistsError, match='exists already'):
        write_report(results[:1], folder)
    (tmp_path / 'file').write_text('x')
    with pytest.raises(ReportExistsError, match='not a directory'):
        write_report(results[:1], tmp_path / 'file', force=True)


def _life(res: AnalysisResult, n: int = 2000) -> tuple[AnalysisResult, list[float]]:
    """``res`` with ``n`` windows of 16 s (a 10-hour life test has ~2250), their TE p-p
    [arcmin] a slow wave, the largest at window 1234 and the smallest at 777."""
    from dataclasses import replace

    import numpy as np

    w0 = next(w for w in res.windows if w.complete)
    pp_arcmin = 2.0 + 0.1 * np.sin(np.arange(n) / 50.0)
    pp_arcmin[1234], pp_arcmin[777] = 3.5, 1.25
    windows = tuple(replace(w0, index=k, start_stamp_s=w0.start_stamp_s + 16.0 * k,
                            end_stamp_s=w0.start_stamp_s + 16.0 * (k + 1),
                            stats=replace(w0.stats, pp_rad=float(arcmin_to_rad(pp_arcmin[k]))))
                    for k in range(n))
    return replace(res, windows=windows), pp_arcmin.tolist()


def test_a_life_test_lists_the_ends_and_extremes_of_its_windows(
        results: list[AnalysisResult]) -> None:
    """2000 windows (10 hours) are no table to read: the page lists the first and last
    ones and those of the largest and smallest TE p-p, says so, and the JSON keeps all."""
    import re
    from dataclasses import replace

    import numpy as np

    from rv_te_bench.report.html import MAX_WINDOW_ROWS

    n = 2000
    life, pp_arcmin = _life(results[0], n)
    page = render_html([life], {})
    table = page[page.index('<h3>Statistics</h3>'):page.index('cumulative (all clean')]
    listed = [int(i) for i in re.findall(r'<tr><td class="l">(\d+)</td>', table)]
    assert listed == [*range(8), 777, 1234, *range(n - 8, n)]
    assert '... 769 windows ...' in table and '... 456 windows ...' in table
    assert f'{n} windows: the first and last 8' in page
    assert f'median {np.median(pp_arcmin):.4f}, max 3.5000 arcmin' in page
    assert 'min 1.2500' in page
    assert len(report_json([life])['bags'][0]['windows']) == n
    # a record of a few windows keeps its whole table
    short = replace(results[0], windows=life.windows[:MAX_WINDOW_ROWS])
    table = render_html([short], {})
    assert len(re.findall(r'<tr><td class="l">\d+</td>', table)) == MAX_WINDOW_ROWS
    assert 'windows ...' not in table


def test_a_life_test_report_plots_every_window_over_hours(
        results: list[AnalysisResult], tmp_path: Path) -> None:
    """The windows the table leaves out are in windows.png: TE p-p and mean of each
    window against hours from the start; a short record has no such figure."""
    import numpy as np

    from rv_te_bench.report.plots import windows_figure

    life, pp_arcmin = _life(results[0])
    fig = windows_figure([life])
    ax_pp, ax_mean = fig.axes
    t_h, pp = ax_pp.lines[0].get_data()
    np.testing.assert_allclose(pp, pp_arcmin, rtol=1e-12)
    np.testing.assert_allclose(t_h, (np.arange(2000) + 0.5) * 16.0 / 3600.0, rtol=1e-9)
    assert ax_mean.get_xlabel().startswith('time from start of record [h]')
    files = write_report([life], tmp_path / 'life')
    assert tmp_path / 'life' / 'windows.png' in files
    assert 'alt="TE p-p and mean of each window' in (tmp_path / 'life' / 'report.html').read_text()
    short = write_report(results[:1], tmp_path / 'short')
    assert not any(f.name == 'windows.png' for f in short)
