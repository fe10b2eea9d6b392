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


def _geometry_calibration(serial: str = SERIAL) -> EncoderCalibration:
    """The heads bags' scale eccentricity as a calibration, from the geometry: (e/R)
    sin(u + psi) with e = 5 um, R = 50 mm, psi = 2.5 rad."""
    return EncoderCalibration(
        scale_serial=serial, date=dt.date.today().isoformat(), method='test geometry',
        harmonics=(CalibrationHarmonic(1, 5e-6 / 0.05, 2.5, 1e-8),))


def _te_node_record(cal: EncoderCalibration, problem: str = '') -> str:
    """What the TE node publishes on te/encoder_heads (its own code: HeadCombiner.describe
    and the ROS YAML dump) for a one-head bench applying ``cal``."""
    from rv_te_bench.core.head_combine import HeadCombiner
    from rv_te_bench.safe_yaml import dump_ros_yaml
    from sim.bench_info import BenchInfoData

    info = BenchInfoData(gear_ratio=ref.RATIO, encoder_out_scale_serial=cal.scale_serial)
    return dump_ros_yaml({**HeadCombiner(info, calibration_out=cal).describe(),
                          'problem': problem})


def test_the_calibration_the_session_applied_is_applied_offline_and_named(tmp_path) -> None:
    """A one-head session whose TE node took the scale's calibration off live: rv-te
    analyze of its bag forms the same angle (the line is the reducer's, within 0.2" of the
    test's FFT of the paper's TE) and says where the calibration came from; without it
    (--no-session-calibration) head 0 carries the scale's 20.6" again."""
    bag = write_heads_bag(tmp_path / 'b', (0.0,),
                          heads_record=_te_node_record(_geometry_calibration()))
    res = analyze_bag(bag, with_advice=False)
    assert abs(_line1_arcsec(res) - _true_line1_arcsec()) < 0.2
    assert res.encoder['calibration_source'] == 'session'
    assert res.encoder['once_per_rev']['separated']
    desc = res.encoder['heads']['output']['description']
    assert SERIAL in desc and "session's TE node applied it" in desc
    raw = analyze_bag(bag, with_advice=False, session_calibration=False)
    assert abs(_line1_arcsec(raw) - _true_line1_arcsec()) > 5.0
    assert not raw.encoder['once_per_rev']['separated']
    # a calibration given on the command line wins over the session's
    given = analyze_bag(bag, with_advice=False, calibration=_geometry_calibration())
    assert given.encoder['calibration_source'] == 'file'


@pytest.mark.parametrize(('record', 'problem'), [
    (lambda: _te_node_record(_geometry_calibration('RING-100-8')), 'is left out'),
    (lambda: '- just\n- a list\n', 'is not a mapping'),
    (lambda: 'output: {calibration: {scale_serial: 3}}\n', 'not used'),
])
def test_a_session_record_that_does_not_fit_is_reported_and_left_out(tmp_path, record,
                                                                     problem) -> None:
    """Another scale's calibration in the record (the bench's scale was changed), a record
    that is not a mapping, a damaged calibration: the analysis goes on with the raw head,
    says why in its problems, and reads every sample."""
    bag = write_heads_bag(tmp_path / 'b', (0.0,), heads_record=record())
    res = analyze_bag(bag, with_advice=False)
    assert any(problem in p for p in res.problems), res.problems
    assert 'calibration_source' not in res.encoder
    assert abs(_line1_arcsec(res) - _true_line1_arcsec()) > 5.0
    assert res.counters['samples'] == analyze_bag(
        write_heads_bag(tmp_path / 'c', (0.0,)), with_advice=False).counters['samples']


def test_a_calibration_is_judged_valid_on_the_day_the_session_was_recorded(tmp_path) -> None:
    """Valid 2023-06-01 .. 2024-01-01: a session recorded 2023-11-14 is corrected with it
    (re-analysed any day later); a bag that does not say when it was recorded is judged
    today, when the calibration has expired (refused, naming the date)."""
    cal = EncoderCalibration(
        scale_serial=SERIAL, date='2023-06-01', method='test geometry',
        harmonics=(CalibrationHarmonic(1, 5e-6 / 0.05, 2.5, 1e-8),), valid_until='2024-01-01')
    bag = write_heads_bag(tmp_path / 'b', (0.0,), started_utc='2023-11-14T22:13:20Z')
    res = analyze_bag(bag, with_advice=False, calibration=cal)
    assert abs(_line1_arcsec(res) - _true_line1_arcsec()) < 0.2
    undated = write_heads_bag(tmp_path / 'u', (0.0,))
    with pytest.raises(EncoderCalibrationError, match='expired on 2024-01-01'):
        analyze_bag(undated, with_advice=False, calibration=cal)


def test_rv_te_analyze_and_identify_name_the_session_calibration(tmp_path, capsys) -> None:
    """The command line: analyze --json says where the calibration came from and
    --no-session-calibration leaves it out; identify applies it too and says so."""
    import json

    from rv_te_bench.cli.main import main

    bag = write_heads_bag(tmp_path / 'b', (0.0,),
                          heads_record=_te_node_record(_geometry_calibration()))

    def run(command: str, argv: list[str]) -> tuple[int, str, str]:
        rc = main([command, *argv, '--quiet'])
        out, err = capsys.readouterr()
        return rc, out, err

    rc, out, _ = run('analyze', [str(bag), '--no-advice', '--no-db', '--json'])
    assert rc == 0
    enc = json.loads(out)['bags'][0]['encoder']
    assert enc['calibration_source'] == 'session' and enc['once_per_rev']['separated']
    rc, out, _ = run('analyze', [str(bag), '--no-advice', '--no-db', '--json',
                                 '--no-session-calibration'])
    enc = json.loads(out)['bags'][0]['encoder']
    assert 'calibration_source' not in enc and not enc['once_per_rev']['separated']
    rc, out, err = run('identify', [str(bag), '--json', '--no-recommend'])
    assert rc == 0, err
    assert json.loads(out)['encoder']['calibration_source'] == 'session'
    assert "the calibration the session's TE node applied is applied" in err
