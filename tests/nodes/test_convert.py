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


# -- the raw paths of the live nodes (issue 41 item 4): bytes in, bytes out ---------------

def _block_fields(msg: object) -> dict[str, object]:
    names = ('time_offset_s', 'theta_in_rad', 'theta_out_rad', 'torque_out_nm',
             'theta_in_heads_rad', 'theta_out_heads_rad')
    out: dict[str, object] = {k: np.asarray(getattr(msg, k)) for k in names}
    out.update(seq=msg.seq, sample_rate_hz=msg.sample_rate_hz,
               sec=msg.header.stamp.sec, nanosec=msg.header.stamp.nanosec,
               frame_id=msg.header.frame_id, in_ids=bytes(msg.in_head_ids),
               out_ids=bytes(msg.out_head_ids))
    return out


@pytest.mark.parametrize('heads', [0, 3])
@pytest.mark.parametrize('torque', [True, False])
def test_encoder_block_bytes_deserialise_to_the_message_make_encoder_block_builds(
        heads: int, torque: bool) -> None:
    """The bench's serialised block, read back by rclpy's own deserialiser, holds exactly
    the fields of the message the bench built before (stamp rounding, heads numbered)."""
    from rclpy.serialization import deserialize_message
    from rv_te_msgs.msg import EncoderBlock

    rng = np.random.default_rng(41)
    n = 100
    kw = {'bench_id': 'bench7', 'seq': 2**40 + 3, 'stamp_s': 1795806515.0705361,
          'sample_rate_hz': 10000.0, 'time_offset_s': np.arange(n) / 1e4,
          'theta_in_rad': rng.normal(size=n) * 1e3, 'theta_out_rad': rng.normal(size=n),
          'torque_out_nm': rng.normal(size=n) if torque else np.zeros(0),
          'theta_in_heads_rad': None,
          'theta_out_heads_rad': rng.normal(size=(heads, n)) if heads else None}
    want = _block_fields(convert.make_encoder_block(**kw))
    got = _block_fields(deserialize_message(convert.encoder_block_bytes(**kw), EncoderBlock))
    assert got.keys() == want.keys()
    for k, v in want.items():
        if isinstance(v, np.ndarray):
            np.testing.assert_array_equal(got[k], v, err_msg=k)
        else:
            assert got[k] == v, k
    assert got['out_ids'] == bytes(range(heads))


def test_encoder_block_data_of_bytes_equals_the_message_path() -> None:
    """The TE node's raw path (decode from the bytes) gives the core the same block as
    the message path; bytes the fast decoder refuses take the message path; garbage is
    a ValueError (counted as malformed by the node), never a crash."""
    from rclpy.serialization import serialize_message

    rng = np.random.default_rng(7)
    t = np.arange(50) / 1e4
    msg = convert.make_encoder_block(bench_id='b3', seq=9, stamp_s=12.25, sample_rate_hz=1e4,
                                     time_offset_s=t, theta_in_rad=rng.normal(size=50),
                                     theta_out_rad=rng.normal(size=50),
                                     torque_out_nm=rng.normal(size=50),
                                     theta_out_heads_rad=rng.normal(size=(2, 50)))
    want, fid = convert.encoder_block_data_of(msg)
    got, gfid = convert.encoder_block_data_of(serialize_message(msg))
    assert (gfid, fid) == ('b3', 'b3')
    assert (got.seq, got.stamp_s, got.sample_rate_hz) == (want.seq, want.stamp_s,
                                                         want.sample_rate_hz)
    for k in ('time_offset_s', 'theta_in_rad', 'theta_out_rad', 'torque_out_nm',
              'theta_out_heads_rad'):
        np.testing.assert_array_equal(getattr(got, k), getattr(want, k), err_msg=k)
    assert got.out_head_ids == want.out_head_ids == (0, 1)
    # head readings that do not fit their ids: the fast decoder refuses, the message path
    # hands them on as they are (the combiner reports them), as before
    msg.theta_out_heads_rad = convert.float64_field(rng.normal(size=7))
    odd, _ = convert.encoder_block_data_of(serialize_message(msg))
    assert odd.out_head_ids == (0, 1) and np.asarray(odd.theta_out_heads_rad).size == 7
    with pytest.raises(ValueError, match='not a serialised EncoderBlock'):
        convert.encoder_block_data_of(b'\x00\x01\x00\x00' + bytes(9))


def test_te_samples_of_reads_what_rclpy_serialises() -> None:
    """The compensation node's raw path: seq and the two sample arrays, for frame ids of
    every length mod 8 and empty arrays; truncated bytes are a BagError."""
    from rclpy.serialization import serialize_message
    from rv_te_msgs.msg import TransmissionError

    from rv_te_bench.errors import BagError
    from rv_te_bench.io._te_cdr import te_samples_of

    rng = np.random.default_rng(3)
    for fid in ('', 'b', 'bench12', 'abcdefgh'):
        for n in (0, 1, 5):
            m = TransmissionError()
            m.header.frame_id = fid
            m.seq = int(rng.integers(0, 2**62))
            m.window_index, m.window_complete, m.sample_rate_hz = 3, True, 500.0
            m.te_rad = convert.float64_field(rng.normal(size=n))
            m.theta_out_rad = convert.float64_field(rng.normal(size=n))
            m.window.pp_rad, m.gaps = 1.5, 2
            seq, te, th = te_samples_of(serialize_message(m))
            assert seq == m.seq
            np.testing.assert_array_equal(te, np.asarray(m.te_rad))
            np.testing.assert_array_equal(th, np.asarray(m.theta_out_rad))
            data = serialize_message(m)
    with pytest.raises(BagError):
        te_samples_of(data[:40])
