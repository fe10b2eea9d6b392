"""``rv-te analyze`` on 2K-V units: the advice rests on an identification on theta_in / i with
its fit quality; damaged BenchInfo with flags; what the report is titled (issue #15).

Units come from the independent model in tests/wang2020_reference.py, bags from rosbags'
writer (tests/unit_bags.py); the command runs as a user runs it.
"""

from __future__ import annotations

import json
import math
import shutil
from typing import TYPE_CHECKING

import numpy as np
import pytest

from rv_te_bench.cli.main import main
from tests import wang2020_reference as ref
from tests.unit_bags import damage_bench_info, unit_bag

if TYPE_CHECKING:
    from pathlib import Path


def _analyze(capsys: pytest.CaptureFixture[str], argv: list[str]) -> tuple[dict, str]:
    code = main(['analyze', *argv, '--json', '--quiet'])
    out, err = capsys.readouterr()
    assert code == 0, err
    return json.loads(out)['bags'][0], err


@pytest.fixture(scope='module')
def units(tmp_path_factory: pytest.TempPathFactory) -> list[tuple[ref.Unit, Path]]:
    """Three random units (preset part magnitudes, random phases and e_ot) and the Table 2
    unit; random start angles and output-encoder zeros; 20.5 s at 5 kHz, 0.2" noise."""
    rng = np.random.default_rng(9)
    root = tmp_path_factory.mktemp('analyze_units')
    t2 = ref.table2_unit()
    out = [(t2, unit_bag(root / 't2', t2, rng, rate_hz=5000.0))]
    for k in range(3):
        ph = rng.uniform(-math.pi, math.pi, 4)
        u = ref.Unit(t2.e_p1, t2.e_p2, t2.e_g, float(rng.uniform(5e-6, 2.5e-5)), *ph)
        out.append((u, unit_bag(root / f'u{k}', u, rng, rate_hz=5000.0)))
    return out


def test_advice_rests_on_the_right_angle(units, capsys: pytest.CaptureFixture[str]) -> None:
    """The identification behind analyze's advice: Q1, Q2, E within 1 % of the largest, the
    current phases (the part phases: here the part magnitudes are the preset's, so the split
    is the true one) within 1 deg, the residual at the 0.2" noise (3 %), and the fit quality
    reported with it. (Before: identified against theta_out, which carries the output
    encoder's zero and 25 x TE of crank phase.)"""
    for u, bag in units:
        doc, _ = _analyze(capsys, [str(bag)])
        rec = doc['recommendation']
        assert rec['available'], rec['reason']
        ident = rec['identification']
        assert ref.vector_error(u, ref.identified_phasors(ident))[0] <= 0.01
        fit = ident['fit']
        assert fit['residual_rms_arcsec'] == pytest.approx(0.2, rel=0.03)
        assert fit['explained_fraction'] > 0.999
        current = [m['current_value'] for m in rec['advice']['modifications']]
        truth = (u.theta_p1, u.theta_p2, u.theta_g, u.theta_ot)
        assert max(ref.dphase_deg(c, t) for c, t in zip(current, truth, strict=True)) < 1.0
        assert 'of the TE variance' in rec['advice']['summary']


def test_text_says_what_rests_on_part_magnitudes(units, capsys: pytest.CaptureFixture[str]) -> None:
    _, bag = units[0]
    assert main(['analyze', str(bag), '--quiet']) == 0
    out = capsys.readouterr().out
    assert 'identified from the TE (up to the label swap): Q1 = e_p1 + e_g' in out
    assert 'rest on the part magnitudes e_p1/e_p2/e_g = 10/20/10 um' in out
    assert 'cannot separate planet and revolution eccentricity' in out


def test_damaged_bench_info_with_flags(units, tmp_path: Path,
                                       capsys: pytest.CaptureFixture[str]) -> None:
    """The chunk holding BenchInfo is damaged: analyze names the flags to give; with
    --ratio and --crank-per-output the rest of the bag is analysed, marked PARTIAL."""
    _, src = units[1]
    bag = tmp_path / 'noinfo'
    shutil.copytree(src, bag)
    damage_bench_info(bag)
    assert main(['analyze', str(bag), '--quiet']) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith('ERROR: ')
    assert '--ratio and --crank-per-output' in err[0]
    doc, err2 = _analyze(capsys, [str(bag), '--ratio', '79', '--crank-per-output', '25'])
    assert doc['partial'] is True
    assert doc['read_problems'][0].startswith('no readable BenchInfo (damaged)')
    assert doc['bench']['source'] == 'cli'
    # the first 1 MiB chunk (~420 blocks of 100) is lost, the rest of the 102,500 is read
    assert 0.5 < doc['cumulative']['n_samples'] / 102_500 < 0.7
    assert 'PARTIAL' in err2


def test_title_says_what_the_bag_is(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Report title and JSON: preset, bench, session (the folder above a generic 'bag'
    folder) and the unit serial from the session metadata, not the folder name 'bag'."""
    bag = unit_bag(tmp_path / 'sess-0042' / 'bag', ref.table2_unit(), np.random.default_rng(1),
                   rate_hz=1000.0, duration_s=16.0,
                   custom_data={'unit_serial': 'SN-7731', 'started_utc': '2026-11-24T08:00Z'})
    rep = tmp_path / 'rep'
    doc, _ = _analyze(capsys, [str(bag), '--report', str(rep), '--no-advice'])
    want = 'wang2020-2kv, bench unit-bench, session sess-0042 (2026-11-24T08:00Z), unit SN-7731'
    assert doc['title'] == want
    assert doc['session'] == {'name': 'sess-0042', 'started_utc': '2026-11-24T08:00Z',
                              'unit_serial': 'SN-7731'}
    page = (rep / 'report.html').read_text(encoding='utf-8')
    assert f'<title>TE report: {want}</title>' in page
    assert '<title>TE report: bag</title>' not in page


def test_json_phases_rounded(units, capsys: pytest.CaptureFixture[str]) -> None:
    """Degrees in the report JSON carry at most 6 decimals (no 120.00000000000001)."""
    _, bag = units[0]
    doc, _ = _analyze(capsys, [str(bag), '--no-advice'])
    degs = [ln['phase_deg'] for ln in doc['spectrum']['lines']]
    assert degs and all(d == round(d, 6) for d in degs)
