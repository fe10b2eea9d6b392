"""``rv-te selfcal`` on bags written by rosbags from the tests' own scale and TE models.

Truth: the scale's eccentricity written out by geometry in the test (e / R at psi), and the
reducer's once-per-revolution line by the test's FFT of the paper's TE.
"""

from __future__ import annotations

import json
import math
from typing import TYPE_CHECKING

import numpy as np
import pytest

from rv_te_bench.cli.main import main
from rv_te_bench.io.calibration_file import load_encoder_calibration
from tests import wang2020_reference as ref
from tests.heads_bags import UNIT, write_heads_bag
from tests.scale_reference import ARCSEC_RAD, whole_revolutions_fft

if TYPE_CHECKING:
    from pathlib import Path

E_OVER_R = 5e-6 / 0.05          # the scale of tests/heads_bags: 5 um on 100 mm, psi 2.5 rad
PSI = 2.5


@pytest.fixture(scope='module')
def bags(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp('selfcal')
    return {'four': write_heads_bag(d / 'four', (0.0, 90.0, 180.0, 270.0), serial='S-1'),
            'r0': write_heads_bag(d / 'r0', (0.0,), serial='S-1'),
            'r180': write_heads_bag(d / 'r180', (0.0,), serial='S-1', index_deg=180.0),
            'r120': write_heads_bag(d / 'r120', (0.0,), serial='S-1', index_deg=120.0),
            'other': write_heads_bag(d / 'other', (0.0,), serial='S-2', index_deg=180.0)}


def test_heads_self_calibration_file(bags, tmp_path: Path,
                                     capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / 'cal.yaml'
    assert main(['selfcal', 'heads', str(bags['four']), '--out', str(out), '--json']) == 0
    doc = json.loads(capsys.readouterr().out)          # one JSON document on stdout
    cal = load_encoder_calibration(out)
    assert cal.scale_serial == 'S-1' and doc['calibration']['scale_serial'] == 'S-1'
    h1 = next(h for h in cal.harmonics if h.order == 1)
    assert h1.amplitude_rad == pytest.approx(E_OVER_R, rel=1e-3)
    assert h1.phase_rad == pytest.approx(PSI, abs=1e-3)
    assert cal.undetermined_orders == tuple(range(4, 33, 4))
    assert cal.valid_until > cal.date


def test_reversal_separates_and_writes_the_calibration(bags, tmp_path: Path,
                                                       capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / 'cal.yaml'
    plot = tmp_path / 'rev.png'
    assert main(['selfcal', 'reversal', str(bags['r0']), str(bags['r180']), '--index-deg',
                 '0', '180', '--out', str(out), '--plot', str(plot), '--json']) == 0
    doc = json.loads(capsys.readouterr().out)
    cal = load_encoder_calibration(out)
    h1 = next(h for h in cal.harmonics if h.order == 1)
    assert h1.amplitude_rad == pytest.approx(E_OVER_R, rel=0.02)
    phi = np.linspace(0.0, 2 * math.pi * 3, 3 * 65_536, endpoint=False)
    te = ref.nlte_rad(phi, UNIT)
    truth = abs(whole_revolutions_fft(phi + te, te, 1)[0]) / ARCSEC_RAD
    red1 = next(r for r in doc['reducer']['harmonics'] if r['order'] == 1)
    assert red1['amplitude_arcsec'] == pytest.approx(truth, rel=0.02)
    assert 2 in cal.undetermined_orders and 3 not in cal.undetermined_orders
    assert plot.stat().st_size > 10_000


@pytest.mark.parametrize(('argv', 'message'), [
    (['reversal', 'r0'], 'needs two or more bags'),
    (['reversal', 'r0', 'r180', '--index-deg', '0'], 'needs one angle per bag (2), got 1'),
    (['reversal', 'r0', 'r180'], 'needs one angle per bag (2), got 0'),
    (['reversal', 'r0', 'r180', '--index-deg', '30', '30'], 'all the same angle'),
    (['reversal', 'r0', 'other', '--index-deg', '0', '180'], 'name different output scales'),
    (['reversal', 'r0', 'r180', '--index-deg', '0', '180', '--serial', 'S-9'],
     "--serial 'S-9' differs"),
    (['heads', 'r0'], 'needs two or more'),
    (['heads', 'four', 'r0'], 'takes one bag'),
])
def test_bad_requests_are_one_line(bags, argv: list[str], message: str,
                                   capsys: pytest.CaptureFixture[str]) -> None:
    args = [str(bags.get(a, a)) for a in argv]
    assert main(['selfcal', *args]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith('ERROR:') and message in err[0], err


def test_an_existing_output_is_not_overwritten(bags, tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / 'cal.yaml'
    out.write_text('keep me')
    assert main(['selfcal', 'heads', str(bags['four']), '--out', str(out)]) == 1
    assert 'exists already' in capsys.readouterr().err
    assert out.read_text() == 'keep me'


def test_120_degrees_resolves_every_order_but_multiples_of_3(bags, tmp_path: Path) -> None:
    out = tmp_path / 'cal.yaml'
    assert main(['selfcal', 'reversal', str(bags['r0']), str(bags['r120']), '--index-deg',
                 '0', '120', '--out', str(out), '--max-order', '9']) == 0
    cal = load_encoder_calibration(out)
    assert cal.undetermined_orders == (3, 6, 9)
    h1 = next(h for h in cal.harmonics if h.order == 1)
    assert h1.amplitude_rad == pytest.approx(E_OVER_R, rel=0.02)
