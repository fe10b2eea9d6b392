"""The unit report a lab signs (issue 33 point 5), without a browser: both TE directions
visible, the limits drawn, one angle unit, unassigned lines, the document's identity, limit
sources the user has. Figures are checked by their pixels (the PNGs as the page shows them);
the expected values come from the record's SI numbers and constants written here."""

from __future__ import annotations

import io
import json
import re
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from rv_te_bench.report.html import write_report
from rv_te_bench.report.unit import unit_figures, write_unit_report
from tests.report.synthetic_bags import Harmonic, write_bag
from tests.report.unit_report_data import (
    ARCMIN_PER_RAD,
    ARCSEC_LIMITS,
    ARCSEC_PER_RAD,
    quick_report,
    same_te_both_directions,
    visible_text,
)

REPO = Path(__file__).resolve().parents[2]
BLUE, RED, GREEN = (31, 119, 180), (214, 39, 40), (46, 125, 50)   # tab:blue, tab:red, limits


@pytest.fixture(scope='module')
def report() -> dict[str, Any]:
    return quick_report()


def pixels(png: bytes, rgb: tuple[int, int, int], tol: int = 30) -> int:
    from PIL import Image

    a = np.asarray(Image.open(io.BytesIO(png)).convert('RGB'), dtype=int)
    return int((np.abs(a - np.array(rgb)).max(axis=2) <= tol).sum())


def test_both_te_directions_are_visible_when_their_curves_are_equal(report) -> None:
    """Equal ccw and cw curves: drawn over each other, the cw line hid the ccw one."""
    png = unit_figures(same_te_both_directions(report))['te.png']
    ccw, cw = pixels(png, BLUE), pixels(png, RED)
    # (new: 925 and 562 px; overlaid, the old figure had none of the ccw colour left)
    assert ccw > 400 and cw > 300, (ccw, cw)
    assert ccw > 0.5 * cw


def test_limit_bands_on_the_te_and_hysteresis_plots(report) -> None:
    figs = unit_figures(report)
    band = (228, 238, 229)   # the limits' green at 12 % over white
    assert pixels(figs['te.png'], band, tol=6) > 50_000   # two panels' +-limit/2 bands
    assert pixels(figs['te.png'], GREEN, tol=20) > 1000   # the band's edges
    assert pixels(figs['hysteresis.png'], GREEN, tol=20) > 500   # backlash limit lines
    assert pixels(figs['hysteresis.png'], band, tol=6) > 5000   # lost-motion box


def test_one_angle_unit_arcmin_with_an_arcmin_profile(report, tmp_path: Path) -> None:
    write_unit_report(report, tmp_path)
    text = visible_text((tmp_path / 'report.html').read_text())
    assert 'arcsec' not in text                      # the spectrum and advice were in arcsec
    assert 'in arcmin throughout this report' in text
    pp = next(m for m in report['metrics'] if m['name'] == 'te_pp_ccw_rad')['value']
    assert f'{pp * ARCMIN_PER_RAD:.4g}' in text


def test_one_angle_unit_arcsec_with_an_arcsec_profile(tmp_path: Path) -> None:
    rep = quick_report(limits=ARCSEC_LIMITS)
    write_unit_report(rep, tmp_path)
    text = visible_text((tmp_path / 'report.html').read_text())
    units = set(re.findall(r'\[([^\]]*arc[^\]]*)\]', text))
    assert units == {'arcsec', 'N m/arcsec'}, units
    assert 'arcmin' not in text
    pp = next(m for m in rep['metrics'] if m['name'] == 'te_pp_cw_rad')['value']
    assert f'{pp * ARCSEC_PER_RAD:.4g}' in text
    k = next(m for m in rep['metrics'] if m['name'].startswith('torsional_rigidity'))['value']
    assert f'{k / ARCSEC_PER_RAD:.4g}' in text


def test_unassigned_lines_are_in_the_spectrum_table(report, tmp_path: Path) -> None:
    """The simulated unit's order-2 line (no part of an RV at order 2) is in the table with
    the amplitude of its bin in the record."""
    write_unit_report(report, tmp_path)
    text = visible_text((tmp_path / 'report.html').read_text())
    row = report['steps'][0]['rows'][0]
    a2 = row['spectrum_amplitude_rad'][row['spectrum_orders'].index(2.0)] * ARCMIN_PER_RAD
    assert a2 > max(ln['amplitude_arcmin'] for ln in row['spectrum'] if ln['output_order'] > 1)
    assert re.search(rf'ccw \(output \+\)\s+unassigned\s+2\s+{a2:.3g}\s', text), text[-3000:]


def test_the_analysis_report_lists_an_unassigned_line(tmp_path: Path) -> None:
    """The demo's report (rv-te analyze / demo): an order-2 line of 0.15 arcmin, larger than
    the labelled crank sideband, is in the spectrum table as unassigned."""
    from rv_te_bench.report.analysis import analyze_bag

    arcmin = 1 / ARCMIN_PER_RAD
    write_bag(tmp_path / 'bag', duration_s=4.0, harmonics=[
        Harmonic(2.0, 0.15 * arcmin, 0.2), Harmonic(25.0, 0.6 * arcmin, 0.3),
        Harmonic(24.0, 0.05 * arcmin, 0.1)])
    res = analyze_bag(tmp_path / 'bag', with_advice=False)
    write_report([res], tmp_path / 'rep')
    text = visible_text((tmp_path / 'rep' / 'report.html').read_text())
    m = re.search(r'unassigned\s+2\s+-\s+\S+\s+(\S+)', text)
    assert m, text
    assert float(m.group(1)) == pytest.approx(0.15, rel=0.02)


def test_report_number_software_and_sign_off(report, tmp_path: Path) -> None:
    a = write_unit_report(report, tmp_path / 'a')
    doc = json.loads(a['json'].read_text())['document']
    assert re.fullmatch(r'RVTE-\d{8}-RV-4711-[0-9A-F]{8}', doc['number'])
    head = subprocess.run(['git', '-C', str(REPO), 'rev-parse', '--short=12', 'HEAD'],
                          capture_output=True, text=True, check=True).stdout.strip()
    assert doc['software']['commit'].removesuffix('+dirty') == head
    # the same record, the same number; another unit's, another number
    again = write_unit_report(report, tmp_path / 'b')
    assert json.loads(again['json'].read_text())['document']['number'] == doc['number']
    other = json.loads(json.dumps(report))
    other['unit']['serial'] = 'RV-4712'
    n2 = json.loads(write_unit_report(other, tmp_path / 'c')['json'].read_text())
    assert n2['document']['number'] != doc['number']
    text = visible_text(a['html'].read_text())
    for words in (doc['number'], 'RV-4711', 'A. Tester', 'tested by', 'approved by',
                  'signature', f"commit {doc['software']['commit']}", 'calibration references'):
        assert words in text, words


def test_limit_sources_cite_documents_in_the_repository() -> None:
    """'DESIGN.md s.6' was a file the user does not have: every document a shipped profile
    cites by file name is in the repository."""
    cited = set()
    for f in (REPO / 'rv_te_bench' / 'acceptance' / 'tolerances').glob('*.yaml'):
        cited |= {(f.name, m) for m in re.findall(r'[\w./-]+\.md', f.read_text())}
    assert cited
    missing = [(f, m) for f, m in cited if not (REPO / m).exists()]
    assert not missing, missing


def test_calibration_references_from_the_bench_description(tmp_path: Path,
                                                            capsys: pytest.CaptureFixture[str]
                                                            ) -> None:
    """A DAQ's CSV judged with its bench description (rv-te test --from): the certificates
    the description's metadata names are in the report's identity block and report.json."""
    import yaml

    from rv_te_bench.cli.main import main
    from tests.acceptance.recorded_data import QUICK, bench_yaml, run_plan, write_csv

    run = run_plan(QUICK)
    csv = write_csv(tmp_path / 'run.csv', run)
    bench = bench_yaml(tmp_path / 'bench.yaml', run, metadata={
        'encoder_out_calibration': 'DKD-K-12345 2026-03-02', 'daq': 'NI PXIe-4492'})
    (tmp_path / 'plan.yaml').write_text(yaml.safe_dump(QUICK), encoding='utf-8')
    rc = main(['test', str(tmp_path / 'plan.yaml'), '--serial', 'LI-42', '--operator', 'kim',
               '--out-dir', str(tmp_path / 'out'), '--from', str(csv), '--bench', str(bench),
               '--time', 't_s', '--theta-in', 'theta_in_rad', '--theta-out', 'theta_out_rad',
               '--torque', 'torque_nm', '--condition', 'bench_calibration=QP-12/2026-10'])
    assert rc == 0, capsys.readouterr().err
    (run_dir,) = [d for d in (tmp_path / 'out').iterdir() if d.is_dir()]
    doc = json.loads((run_dir / 'report' / 'report.json').read_text())['document']
    assert doc['calibrations'] == {'bench_calibration': 'QP-12/2026-10',
                                   'encoder_out_calibration': 'DKD-K-12345 2026-03-02'}
    text = visible_text((run_dir / 'report' / 'report.html').read_text())
    assert ('bench_calibration: QP-12/2026-10; encoder_out_calibration: DKD-K-12345 '
            '2026-03-02') in text


def test_pdf_without_chromium_is_one_warning_and_the_report_stays(
        report, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    from rv_te_bench.cli.test import show_report
    from rv_te_bench.report.unit_doc import software_identity

    software_identity()   # the commit read (and kept) while git is on the PATH
    monkeypatch.setenv('PATH', str(tmp_path / 'empty'))
    show_report(report, tmp_path / 'r', as_json=False, pdf=True)
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ['WARNING: no report.pdf: no Chromium to print report.pdf (looked for '
                   'chromium, chromium-browser, google-chrome on the PATH; Debian: apt-get '
                   'install chromium)']
    assert (tmp_path / 'r' / 'report.html').exists()
    assert not (tmp_path / 'r' / 'report.pdf').exists()
