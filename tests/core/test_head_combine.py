"""HeadCombiner and combine_stream: blocks' angles from their heads (issue 36)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rv_te_bench.core.encoder_calibration import CalibrationHarmonic, EncoderCalibration
from rv_te_bench.core.head_combine import HeadCombiner, WindowBreak, combine_stream
from rv_te_bench.core.offline import analyze_blocks
from rv_te_bench.core.orders import OrderSet
from rv_te_bench.core.stream_records import EncoderBatch, EncoderBlockData, TeAnalysisConfig
from rv_te_bench.errors import EncoderCalibrationError, HeadLayoutError
from sim.bench_info import BenchInfoData
from tests.scale_reference import ARCSEC_RAD, Scale

FOUR = tuple(math.radians(a) for a in (0.0, 90.0, 180.0, 270.0))
SCALE = Scale(radius_m=0.05, eccentricity_m=5e-6, psi_rad=0.4, orders=(2, 3),
              amplitudes_rad=(2e-6, 1e-6), phases_rad=(0.1, 0.2), heads_rad=FOUR)
RATE = 1000.0


def _info(angles=FOUR, serial='S-1') -> BenchInfoData:
    return BenchInfoData(gear_ratio=10.0, crank_per_input=-0.5,
                         encoder_out_head_angles_rad=tuple(angles),
                         encoder_out_scale_serial=serial)


def _block(seq: int, n: int = 200, ids=(0, 1, 2, 3)) -> EncoderBlockData:
    t = (seq * n + np.arange(n)) / RATE
    theta = 2 * math.pi * 0.5 * t              # half an output turn per second
    heads = SCALE.readings(theta)[list(ids)]
    return EncoderBlockData(seq, float(t[0]), RATE, t - t[0], 10.0 * theta, heads[0],
                            out_head_ids=tuple(ids), theta_out_heads_rad=heads)


def test_full_blocks_take_the_mean_and_cancel_the_eccentricity() -> None:
    comb = HeadCombiner(_info())
    b = _block(0)
    out, events = comb.block(b)
    assert events == []
    np.testing.assert_allclose(out.theta_out_rad, b.theta_out_heads_rad.mean(axis=0))
    theta = out.theta_in_rad / 10.0
    assert np.max(np.abs(out.theta_out_rad - theta)) / ARCSEC_RAD < 0.01   # 2, 3: cancelled
    assert np.max(np.abs(b.theta_out_rad - theta)) / ARCSEC_RAD > 10       # head 0: to 20.6"


def test_a_missing_head_uses_the_rest_and_says_so() -> None:
    comb = HeadCombiner(_info())
    out, (ev,) = comb.block(_block(1, ids=(0, 1, 2)))
    assert ev.missing == (3,) and ev.used == (0, 1, 2)
    assert 'block seq 1: output head(s) [3] missing' in ev.detail
    theta = out.theta_in_rad / 10.0
    assert np.max(np.abs(out.theta_out_rad - theta)) / ARCSEC_RAD < 1.0    # order 1 cancels
    out, (ev,) = comb.block(_block(2, ids=(0, 1)))                          # 0 and 90 deg
    assert ev.used == (0,) and 'not averaged out' in ev.detail
    assert comb.counters == {'blocks': 2, 'blocks_head_missing': 2}


def test_head0_mode_and_a_missing_head_0() -> None:
    cal = EncoderCalibration(scale_serial='S-1', date='2026-11-20', method='geometry',
                             harmonics=(CalibrationHarmonic(1, 5e-6 / 0.05, 0.4, 0.0),
                                        CalibrationHarmonic(2, 2e-6, 0.1, 0.0),
                                        CalibrationHarmonic(3, 1e-6, 0.2, 0.0)))
    comb = HeadCombiner(_info(), mode='head0', calibration_out=cal)
    out, ev = comb.block(_block(0, ids=(1, 2, 3)))         # head 0 lost: head 1 at 90 deg
    theta = out.theta_in_rad / 10.0
    assert ev[0].used == (1,)
    assert np.max(np.abs(out.theta_out_rad - theta)) / ARCSEC_RAD < 0.01   # its own angle


def test_refusals_name_the_problem() -> None:
    with pytest.raises(HeadLayoutError, match=r"output scale: no weighting of heads at \[0, 90\]"):
        HeadCombiner(_info((0.0, math.pi / 2)))
    HeadCombiner(_info((0.0, math.pi / 2)), mode='head0')        # head 0 alone: fine
    other = EncoderCalibration(scale_serial='S-2', date='2026-11-20', method='x',
                               harmonics=())
    with pytest.raises(EncoderCalibrationError, match="for scale 'S-2'"):
        HeadCombiner(_info(), calibration_out=other)


def test_malformed_heads_fall_back_to_head_0_with_an_event() -> None:
    b = _block(0)
    bad = EncoderBlockData(b.seq, b.stamp_s, RATE, b.time_offset_s, b.theta_in_rad,
                           b.theta_out_rad, out_head_ids=(0, 1, 2, 3),
                           theta_out_heads_rad=b.theta_out_heads_rad[:, :10])
    out, events = HeadCombiner(_info()).block(bad)
    assert 'malformed' in events[0].detail
    np.testing.assert_array_equal(out.theta_out_rad, b.theta_out_rad)


def test_stream_breaks_windows_where_the_heads_change_and_loses_nothing() -> None:
    """Blocks 0-29 full, 30-31 without head 3, the rest full: two WindowBreaks; the core
    closes windows there ('heads'); every sample is analysed."""
    blocks = [_block(k, ids=(0, 1, 2) if k in (30, 31) else (0, 1, 2, 3)) for k in range(60)]
    items = [EncoderBatch.from_blocks(blocks[:30]), *blocks[30:32],
             EncoderBatch.from_blocks(blocks[32:])]
    comb = HeadCombiner(_info())
    out = list(combine_stream(items, comb))
    breaks = [x for x in out if isinstance(x, WindowBreak)]
    assert [b.seq for b in breaks] == [30, 32]
    orders = OrderSet.from_bench_info(_info())
    res = analyze_blocks(out, TeAnalysisConfig(orders=orders))
    assert res.counters['samples'] == 60 * 200
    assert [w.close_reason for w in res.windows].count('heads') == 2
    assert res.counters['gaps'] == 0
