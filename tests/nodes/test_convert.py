"""nodes.convert: messages <-> core records, no node started (needs the rv_te_msgs types)."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip('rclpy')
pytest.importorskip('rv_te_msgs')

from rv_te_bench.core.te import TeStats
from rv_te_bench.nodes import convert
from sim.bench import BenchConfig, BenchSimulator
from sim.bench_info import BenchInfoData
from sim.drive import drive_from_spec


def test_stamps_round_trip_to_the_nanosecond_and_clamp_negative() -> None:
    stamp = convert.s_to_stamp(12.345678901)
    assert (stamp.sec, stamp.nanosec) == (12, 345678901)
    assert convert.stamp_to_s(stamp) == pytest.approx(12.345678901, abs=1e-9)
    assert (convert.s_to_stamp(-1.0).sec, convert.s_to_stamp(-1.0).nanosec) == (0, 0)


def test_encoder_block_round_trip() -> None:
    t = np.arange(4) * 1e-3
    msg = convert.make_encoder_block(bench_id='b1', seq=7, stamp_s=3.5, sample_rate_hz=1000.0,
                                     time_offset_s=t, theta_in_rad=t * 79, theta_out_rad=t,
                                     torque_out_nm=None)
    data = convert.encoder_block_to_data(msg)
    assert (data.seq, data.stamp_s, data.sample_rate_hz) == (7, 3.5, 1000.0)
    np.testing.assert_array_equal(data.theta_in_rad, t * 79)
    np.testing.assert_array_equal(data.theta_out_rad, t)
    assert data.torque_out_nm.size == 0
    assert msg.header.frame_id == 'b1'


def test_bench_info_message_carries_every_bench_info_field() -> None:
    drive = drive_from_spec('constant', speed_rpm=300.0)
    info = BenchSimulator(BenchConfig(preset='wang2020-2kv', drive=drive)).info
    msg = convert.make_bench_info(info, convert.s_to_stamp(1.0))
    assert msg.header.frame_id == info.bench_id
    assert BenchInfoData.from_message(msg) == info
    # the record's fields are the message's, in the message's order (no header)
    assert BenchInfoData.field_names() == tuple(
        f for f in msg.get_fields_and_field_types() if f != 'header')


def test_te_statistics_keep_nan_and_zero_unknown_revolutions() -> None:
    msg = convert.make_te_statistics(TeStats.empty())
    assert math.isnan(msg.pp_rad)
    assert msg.revolutions_covered == 0.0
    assert msg.n_samples == 0
    msg = convert.make_te_statistics(TeStats(1e-4, 6e-5, 1e-6, 2e-5, 2.0, 100))
    assert (msg.pp_rad, msg.revolutions_covered, msg.n_samples) == (1e-4, 2.0, 100)


def test_float64_field_is_an_exact_array_copy() -> None:
    """Issue #23 item 1: float64[] fields get an array.array('d') by one memory copy, equal
    bit for bit to what the message's own setter stores, from any array-like."""
    import array

    from rv_te_msgs.msg import EncoderBlock

    x = np.linspace(-1e6, 1e6, 201) + 1e-9
    for values in (x, x[::2], x.astype(np.float32), list(x[:5]), np.empty(0)):
        got = convert.float64_field(values)
        assert isinstance(got, array.array)
        assert got.typecode == 'd'
        m = EncoderBlock()
        m.theta_in_rad = values
        assert got.tobytes() == m.theta_in_rad.tobytes()
    src = x.copy()
    got = convert.float64_field(src)
    src[0] = 42.0   # a copy, not a view
    assert got[0] == x[0]
