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
