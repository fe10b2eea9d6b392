"""The advice table of the HTML report (issue #15 item 9): no column of NaN sensitivities
for assembly phases; the Hu 2020 sensitivity S_j where it exists."""

from __future__ import annotations

import json
from typing import TYPE_CHECKING

import numpy as np

from rv_te_bench.cli.main import main
from sim.units import arcmin_to_rad
from tests import wang2020_reference as ref
from tests.report.synthetic_bags import Harmonic, write_bag
from tests.unit_bags import unit_bag

if TYPE_CHECKING:
    from pathlib import Path

    import pytest


def _report(bag: Path, out: Path, capsys: pytest.CaptureFixture[str]) -> tuple[dict, str]:
    assert main(['analyze', str(bag), '--report', str(out), '--quiet', '--json']) == 0
    doc = json.loads(capsys.readouterr().out)['bags'][0]
    return doc, (out / 'report.html').read_text(encoding='utf-8')


def test_assembly_phase_advice_has_no_nan_column(tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    bag = unit_bag(tmp_path / 'unit', ref.table2_unit(), np.random.default_rng(5),
                   rate_hz=2000.0, duration_s=16.0, theta_in_start_rad=0.0)
    doc, page = _report(bag, tmp_path / 'rep', capsys)
    advice = doc['recommendation']['advice']
    assert advice is not None and advice['method'] == 'identified-assembly-phases'
    table = page[page.index('<h3>Recommendation</h3>'):]
    assert 'theta_p1' in table
    assert 'nan' not in table.lower()
    assert 'sensitivity' not in table


def test_tooth_profile_advice_shows_the_sensitivity(tmp_path: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / 'rv'
    # a mesh line (order 936) dominant: the tooth-profile change is what the data points to
    write_bag(path, harmonics=[Harmonic(936.0, float(arcmin_to_rad(0.6)), 0.3)], duration_s=2.5,
              preset='hu2020-rv', reducer_type='rv', sample_rate_hz=4000.0, block_size=400)
    doc, page = _report(path, tmp_path / 'rep', capsys)
    mods = doc['recommendation']['advice']['modifications']
    table = page[page.index('<h3>Recommendation</h3>'):]
    assert 'sensitivity S<sub>j</sub>' in table
    for m in mods:
        assert f"{m['sensitivity_index']:.4g}" in table
    assert 'nan' not in table.lower()
