"""``rv-te spc`` states the measurement variance and gives Cp/Cpk corrected for it (issue 35).

Records written here: 40 units whose TE p-p is N(0.60', 0.03') and whose stored u_c is
0.02' (a budget's combined standard uncertainty): the corrected process sigma is
sqrt(sigma^2 - 0.02^2), computed here from the chart's own sigma."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from rv_te_bench.cli.main import main
from rv_te_bench.store import MetricValue, open_store
from tests.store.conftest import make_record

ARCMIN = 1.0 / 3437.7467707849396


@pytest.fixture(scope='module')
def store(tmp_path_factory: pytest.TempPathFactory) -> Path:
    db = tmp_path_factory.mktemp('spcu') / 'r.sqlite'
    rng = np.random.default_rng(3)
    with open_store(db) as st:
        for i, v in enumerate(rng.normal(0.60, 0.03, 40)):
            rec = make_record(i)
            st.upsert(replace(rec, metrics=(*rec.metrics, MetricValue(
                'te_pp_revolution_max_rad', float(v) * ARCMIN, u95=0.04 * ARCMIN,
                uc=0.02 * ARCMIN))))
    return db


def test_capability_is_corrected_for_the_stored_measurement_sigma(
        store: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(['spc', 'te_pp_revolution_max_rad', '--db', str(store), '--usl', '1.0',
                 '--lsl', '0.2', '--json']) == 0
    doc = json.loads(capsys.readouterr().out)
    cap = doc['capability']
    assert cap['sigma_measurement'] == pytest.approx(0.02, rel=1e-9)
    s = cap['sigma_within']
    assert cap['cp'] == pytest.approx(0.8 / (6 * s), rel=1e-9)
    assert cap['cp_corrected'] == pytest.approx(0.8 / (6 * math.sqrt(s * s - 0.02 ** 2)),
                                                rel=1e-9)
    assert cap['cp_corrected'] > cap['cp'] and cap['cpk_corrected'] > cap['cpk']
    assert main(['spc', 'te_pp_revolution_max_rad', '--db', str(store), '--usl', '1.0']) == 0
    out = capsys.readouterr().out
    assert 'measurement sigma 0.02 arcmin' in out and 'corrected for it' in out


def test_a_measurement_spread_above_the_observed_one_gives_no_corrected_index(
        store: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(['spc', 'te_pp_revolution_max_rad', '--db', str(store), '--usl', '1.0',
                 '--measurement-sigma', '0.5', '--json']) == 0
    cap = json.loads(capsys.readouterr().out)['capability']
    assert cap['sigma_measurement'] == pytest.approx(0.5)
    assert cap['cpk_corrected'] is None and cap['cpk'] is not None


def test_records_without_uncertainty_say_so(tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    db = tmp_path / 'old.sqlite'
    with open_store(db) as st:
        for i in range(10):
            st.upsert(make_record(i))
    assert main(['spc', 'te_pp_rad', '--db', str(db), '--usl', '1.0']) == 0
    assert 'measurement variance: not known' in capsys.readouterr().out
