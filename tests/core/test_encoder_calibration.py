"""The encoder calibration record, its file, and the once-per-revolution note."""

from __future__ import annotations

import datetime as dt
import math

import numpy as np
import pytest
import yaml

from rv_te_bench.core.bench_uncertainty import default_encoder_errors
from rv_te_bench.core.encoder_attribution import once_per_rev_note
from rv_te_bench.core.encoder_calibration import (
    CalibrationHarmonic,
    EncoderCalibration,
    calibration_from_plain,
)
from rv_te_bench.core.heads import HeadLayout
from rv_te_bench.errors import EncoderCalibrationError
from rv_te_bench.io.calibration_file import load_encoder_calibration, write_encoder_calibration

AS = math.pi / 648000.0


def _cal(**kw) -> EncoderCalibration:
    base = {'scale_serial': 'RING-42', 'date': '2026-11-20', 'method': 'self-calibration',
                'harmonics': (CalibrationHarmonic(1, 20.6 * AS, 0.5, 0.01 * AS),
                           CalibrationHarmonic(3, 0.3 * AS, 2.0, 0.01 * AS)),
                'undetermined_orders': (4, 8), 'max_order': 8, 'valid_until': '2027-11-20'}
    base.update(kw)
    return EncoderCalibration(**base)


def test_correct_takes_off_the_curve_at_the_head_and_index() -> None:
    """A head at beta on a scale at index iota reads e(reading - iota - beta): corrected
    readings of exactly that error come back to the true angle."""
    cal = _cal()
    theta = np.linspace(0.0, 20.0, 5000)
    beta, iota = 1.2, math.pi
    def err(u):  # written out here: a1 sin(u + p1) + a3 sin(3u + p3)
        return 20.6 * AS * np.sin(u + 0.5) + 0.3 * AS * np.sin(3 * u + 2.0)
    reading = theta + err(theta - iota - beta)
    got = cal.correct(reading, head_angle_rad=beta, index_rad=iota)
    assert float(np.max(np.abs(got - theta))) / AS < 0.01      # second order: k a * a


def test_the_file_round_trips_in_catalogue_units(tmp_path) -> None:
    cal = _cal()
    path = write_encoder_calibration(tmp_path / 'ring.yaml', cal)
    text = path.read_text()
    assert 'amplitude_arcsec: 20.6' in text and 'phase_deg:' in text
    back = load_encoder_calibration(path)
    assert back.scale_serial == 'RING-42' and back.undetermined_orders == (4, 8)
    for a, b in zip(back.harmonics, cal.harmonics, strict=True):
        assert a.order == b.order
        assert a.amplitude_rad == pytest.approx(b.amplitude_rad, rel=1e-12)
        assert a.phase_rad == pytest.approx(b.phase_rad, rel=1e-12)
    with pytest.raises(FileExistsError, match='exists already'):
        write_encoder_calibration(path, cal)


def test_another_scale_or_an_expired_calibration_is_refused() -> None:
    cal = _cal()
    cal.check_for('RING-42', when=dt.date(2027, 1, 1))
    with pytest.raises(EncoderCalibrationError, match="for scale 'RING-42', the bench reports "
                       "scale 'RING-7'"):
        cal.check_for('RING-7')
    with pytest.raises(EncoderCalibrationError, match='no serial given'):
        cal.check_for('')
    with pytest.raises(EncoderCalibrationError, match='expired on 2027-11-20'):
        cal.check_for('RING-42', when=dt.date(2028, 1, 1))


@pytest.mark.parametrize(('change', 'match'), [
    ({'format': 'other'}, 'format must be'),
    ({'scale_serial': ''}, 'scale_serial is required'),
    ({'date': 'yesterday'}, 'date must be an ISO date'),
    ({'harmonics': [{'order': 0, 'amplitude_arcsec': 1, 'phase_deg': 0, 'u_arcsec': 0}]},
     'order must be an integer >= 1'),
    ({'harmonics': [{'order': 1, 'amplitude_arcsec': -1, 'phase_deg': 0, 'u_arcsec': 0}]},
     'amplitude_arcsec must be a finite number >= 0'),
    ({'harmonics': [{'order': 1, 'amplitude': 1}]}, 'must have exactly order'),
    ({'colour': 'red'}, "unknown key\\(s\\) \\['colour'\\]"),
    ({'undetermined_orders': [1]}, 'both determined and undetermined'),
])
def test_bad_files_are_named(tmp_path, change, match) -> None:
    plain = _cal().to_plain()
    plain.update(change)
    path = tmp_path / 'bad.yaml'
    path.write_text(yaml.safe_dump(plain))
    with pytest.raises(EncoderCalibrationError, match=match):
        load_encoder_calibration(path)
    with pytest.raises(EncoderCalibrationError, match='must be a mapping'):
        calibration_from_plain([1, 2])


def test_residual_model_keeps_only_the_uncertainty_of_calibrated_orders() -> None:
    base = default_encoder_errors('heidenhain-ron886')
    left = _cal().residual_error_model(base)
    g = dict(left.graduation)
    assert g[1] == pytest.approx(0.01 * AS) and g[3] == pytest.approx(0.01 * AS)
    assert g[2] == dict(base.graduation)[2]                  # not calibrated: data sheet
    assert left.eccentricity_rad == 0.0


def test_once_per_rev_note_states_the_possible_share_and_flags_it() -> None:
    """5 um on a 100 mm ring: 20.6" possible; against a 30" line that is comparable."""
    note = once_per_rev_note(line_rad=30 * AS, eccentricity_m=5e-6, diameter_m=0.1)
    assert note.possible_rad / AS == pytest.approx(20.63, abs=0.01)
    assert note.comparable and not note.separated
    assert '20.6"' in note.text() and 'measure with two or more read heads' in note.text()
    small = once_per_rev_note(line_rad=3000 * AS, eccentricity_m=5e-6, diameter_m=0.1)
    assert not small.comparable
    two = once_per_rev_note(line_rad=30 * AS, eccentricity_m=5e-6, diameter_m=0.1,
                            layout=HeadLayout.of([0.0, math.pi]))
    assert two.separated and two.possible_rad < 1e-9 and not two.comparable
    cal = once_per_rev_note(line_rad=30 * AS, calibration=_cal())
    assert cal.separated and 'RING-42' in cal.text()
    sheet = once_per_rev_note(line_rad=1 * AS,
                              error_model=default_encoder_errors('heidenhain-ron886'))
    assert 'data sheet' in sheet.source and sheet.comparable


def test_note_for_a_bench_record_and_its_te_nodes_heads() -> None:
    """What the compensation node sees: BenchInfo (5 um on 100 mm) and te/encoder_heads."""
    from rv_te_bench.core.encoder_attribution import line_amplitude_rad, note_for_bench
    from sim.bench_info import BenchInfoData

    info = BenchInfoData(gear_ratio=79.0, encoder_out_model='renishaw-resm',
                         encoder_out_scale_eccentricity_m=5e-6, encoder_out_scale_diameter_m=0.1,
                         encoder_out_head_angles_rad=(0.0, math.pi))
    th = np.linspace(0.0, 2.2 * math.pi, 30_000)
    line = line_amplitude_rad(th, 15 * AS * np.sin(th + 0.3))
    assert line / AS == pytest.approx(15.0, rel=1e-3)
    assert math.isnan(line_amplitude_rad(th[:1000], th[:1000]))     # under one turn
    one = note_for_bench(info, None, line)
    assert one.comparable and not one.separated
    assert one.possible_rad / AS > 20.6                              # + the data sheet
    avg = note_for_bench(info, {'output': {'mode': 'average', 'layout': {
        'angles_rad': [0.0, math.pi]}, 'calibration': None}}, line)
    assert avg.separated and not avg.comparable
    cal = note_for_bench(info, {'output': {'mode': 'head0', 'layout': None,
                                           'calibration': _cal().to_plain()}}, line)
    assert cal.separated and 'RING-42' in cal.text()
