"""rv-te analyze of bags with several read heads (issue 36), written by rosbags.

The unit's TE comes from the paper's equations written out in tests/ (wang2020_reference),
the heads' readings from the tests' exact-geometry scale (scale_reference); the bag is
written by rosbags' own writer and serialiser. Truth: the test's own FFT of its curves.
"""

from __future__ import annotations

import datetime as dt
import math

import numpy as np
import pytest

from rv_te_bench.core.encoder_calibration import CalibrationHarmonic, EncoderCalibration
from rv_te_bench.errors import EncoderCalibrationError
from rv_te_bench.report.analysis import analyze_bag
from tests import wang2020_reference as ref
from tests.heads_bags import SERIAL, UNIT, write_heads_bag
from tests.scale_reference import ARCSEC_RAD, whole_revolutions_fft


def _line1_arcsec(res) -> float:
    return next(ln.amplitude_rad for ln in res.spectrum.lines
                if abs(ln.output_order - 1) < 1e-9) / ARCSEC_RAD


def _true_line1_arcsec() -> float:
    phi = np.linspace(0.0, 2 * math.pi * 3, 3 * 65_536, endpoint=False)
    te = ref.nlte_rad(phi, UNIT)
    return abs(whole_revolutions_fft(phi + te, te, 1)[0]) / ARCSEC_RAD


@pytest.mark.parametrize('heads_deg', [(0.0, 180.0), (0.0, 90.0, 180.0, 270.0)])
def test_analyze_averages_the_heads_and_the_line_is_the_reducers(tmp_path, heads_deg) -> None:
    """Averaged heads: the once-per-rev line is the reducer's (~10" amplitude) within 0.2";
    head 0 alone carries the scale's 20.6" on top (vector sum). The report says which."""
    bag = write_heads_bag(tmp_path / 'b', heads_deg)
    truth = _true_line1_arcsec()
    avg = analyze_bag(bag, with_advice=False)
    one = analyze_bag(bag, with_advice=False, heads_mode='head0')
    assert abs(_line1_arcsec(avg) - truth) < 0.2, (_line1_arcsec(avg), truth)
    assert abs(_line1_arcsec(one) - truth) > 5.0
    enc = avg.to_json_dict()['encoder']
    assert enc['heads']['output']['layout']['n_heads'] == len(heads_deg)
    assert enc['once_per_rev']['separated'] is True
    assert 'equal-division averaging' in enc['heads']['output']['description']
    note = one.encoder['once_per_rev']
    assert not note['separated'] and note['comparable']
    assert '20.6"' in note['text']


def test_a_block_missing_a_head_closes_the_window_and_loses_nothing(tmp_path) -> None:
    bag = write_heads_bag(tmp_path / 'b', (0.0, 90.0, 180.0, 270.0), drop_head=(2, 40))
    res = analyze_bag(bag, with_advice=False)
    full = analyze_bag(write_heads_bag(tmp_path / 'f', (0.0, 90.0, 180.0, 270.0)),
                       with_advice=False)
    assert res.counters['samples'] == full.counters['samples']     # nothing dropped
    assert res.encoder['heads']['counters']['blocks_head_missing'] == 1
    assert 'block seq 40: output head(s) [2] missing' in res.encoder['heads']['events'][0]
    assert any(w.close_reason == 'heads' for w in res.windows)
    assert any('lacked read heads' in p for p in res.problems)


def test_a_calibration_for_another_scale_is_refused_in_one_line(tmp_path) -> None:
    bag = write_heads_bag(tmp_path / 'b', (0.0,))
    other = EncoderCalibration(scale_serial='RING-100-8', date='2026-11-01', method='x',
                               harmonics=(CalibrationHarmonic(1, 1e-4, 0.0, 1e-7),))
    with pytest.raises(EncoderCalibrationError, match="for scale 'RING-100-8', the bench "
                       "reports scale 'RING-100-7'"):
        analyze_bag(bag, with_advice=False, calibration=other)


def test_a_calibration_on_one_head_removes_the_scale_line(tmp_path) -> None:
    """One head with the scale's own calibration (its eccentricity, written in the test
    from the geometry: (e/R) sin(u + psi)): the line is the reducer's again."""
    bag = write_heads_bag(tmp_path / 'b', (0.0,))
    cal = EncoderCalibration(
        scale_serial=SERIAL, date=dt.date.today().isoformat(), method='test geometry',
        harmonics=(CalibrationHarmonic(1, 5e-6 / 0.05, 2.5, 1e-8),))
    res = analyze_bag(bag, with_advice=False, calibration=cal)
    assert abs(_line1_arcsec(res) - _true_line1_arcsec()) < 0.2
    assert res.encoder['once_per_rev']['separated']
    assert SERIAL in res.encoder['heads']['output']['description']


def test_heads_that_cannot_be_averaged_are_refused_with_the_way_out(tmp_path) -> None:
    """Heads at 0 and 90 deg cannot cancel order 1: one line naming the angles and saying
    how to analyse the intact bag (head 0 alone), which then works."""
    from rv_te_bench.errors import HeadLayoutError

    bag = write_heads_bag(tmp_path / 'b', (0.0, 90.0))
    with pytest.raises(HeadLayoutError, match=r'heads at \[0, 90\] deg.*--heads head0'):
        analyze_bag(bag, with_advice=False)
    res = analyze_bag(bag, with_advice=False, heads_mode='head0')
    assert res.counters['samples'] > 0
