"""Advice only where the data holds it (issue 33 s.4).

Bags with a known TE (tests.report.synthetic_bags: TE = sum of cosines of phi = theta_in /
i, i = 79, f_w = 25 f_out, mesh orders 936 / 1300) on an RV bench whose preset has Hu 2020's
tooth-profile compensation. Before: a quarter-revolution record got a pin-radius change
(stored as advice), and a TE whose dominant line is crank eccentricity (1 f_w) got a
tooth-profile change while the diagnosis named the crankshaft.
"""

from __future__ import annotations

import json
from typing import TYPE_CHECKING

import pytest

from rv_te_bench.cli.main import main
from rv_te_bench.report.analysis import analyze_bag
from sim.units import arcmin_to_rad
from tests.report.synthetic_bags import Harmonic, write_bag

if TYPE_CHECKING:
    from pathlib import Path

CRANK = Harmonic(25.0, float(arcmin_to_rad(0.6)), 0.3)        # 1 f_w: crank eccentricity
MESH = Harmonic(936.0, float(arcmin_to_rad(0.5)), -0.4)       # a cycloid-pin mesh line
SMALL_CRANK = Harmonic(25.0, float(arcmin_to_rad(0.1)), 0.3)


def _rv(path: Path, harmonics: list[Harmonic], duration_s: float) -> Path:
    write_bag(path, harmonics=harmonics, duration_s=duration_s, sample_rate_hz=4000.0,
              block_size=400, preset='hu2020-rv', reducer_type='rv')
    return path


def test_quarter_revolution_gets_no_advice(tmp_path: Path, default_store: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    bag = _rv(tmp_path / 'quarter', [MESH], duration_s=0.5)     # 0.25 output revolutions
    rec = analyze_bag(bag).recommendation
    assert not rec.available and rec.advice is None
    assert rec.reason.startswith('advice withheld')
    assert '0.25 output revolutions' in rec.reason
    # the store keeps no advice for it; the printed report says why
    assert main(['analyze', str(bag), '--quiet']) == 0
    out = capsys.readouterr().out
    assert 'advice withheld' in out and 'pin' not in out.lower()
    assert main(['results', '--json']) == 0
    (row,) = json.loads(capsys.readouterr().out)
    assert row['advice'] is None


def test_crank_eccentricity_gets_no_tooth_profile_change(tmp_path: Path) -> None:
    bag = _rv(tmp_path / 'crank', [CRANK, MESH], duration_s=2.5)
    res = analyze_bag(bag)
    assert res.dominant is not None and res.dominant.line.label == '1 f_w'
    assert 'eccentricity' in res.dominant.likely_source
    rec = res.recommendation
    assert not rec.available and rec.advice is None
    assert rec.reason.startswith('tooth-profile advice withheld')
    assert '1 f_w (0.6' in rec.reason and res.dominant.likely_source in rec.reason


def test_mesh_line_dominant_gets_the_tooth_profile_change(tmp_path: Path) -> None:
    bag = _rv(tmp_path / 'mesh', [SMALL_CRANK, MESH], duration_s=2.5)
    res = analyze_bag(bag)
    assert res.dominant is not None and res.dominant.line.output_order == pytest.approx(936)
    assert 'tooth profile' in res.dominant.likely_source
    rec = res.recommendation
    assert rec.available, rec.reason
    assert rec.advice is not None and rec.advice.method == 'tooth-profile'
    assert len(rec.advice.modifications) == 3
