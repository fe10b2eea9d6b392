"""The importer's direct EncoderBlock serialiser against the rosbags typestore, byte for byte."""

from __future__ import annotations

import numpy as np
import pytest

from rv_te_bench.io._encoder_cdr import decode_encoder_block
from rv_te_bench.io._encoder_cdr_out import encoder_block_cdr
from rv_te_bench.io.msgdefs import ENCODER_BLOCK, rv_te_typestore


def _rosbags(stamp_ns: int, frame_id: str, seq: int, rate: float,
             arrays: list[np.ndarray]) -> bytes:
    store = rv_te_typestore()
    t = store.types
    names = ('time_offset_s', 'theta_in_rad', 'theta_out_rad', 'torque_out_nm', 'in_head_ids',
             'theta_in_heads_rad', 'out_head_ids', 'theta_out_heads_rad')
    msg = t[ENCODER_BLOCK](
        header=t['std_msgs/msg/Header'](
            stamp=t['builtin_interfaces/msg/Time'](sec=stamp_ns // 10**9,
                                                   nanosec=stamp_ns % 10**9),
            frame_id=frame_id),
        seq=seq, sample_rate_hz=rate, **dict(zip(names, arrays, strict=True)))
    return bytes(store.serialize_cdr(msg, ENCODER_BLOCK))


@pytest.mark.parametrize('frame_id', ['', 'b', 'bench', 'bench_07', 'a-much-longer-bench-id', 'µ'])
@pytest.mark.parametrize(('n', 'torque', 'in_heads', 'out_heads'), [
    (1, False, 0, 0), (1000, True, 0, 0), (3, True, 0, 3), (7, False, 2, 0), (5, True, 4, 2),
    (1, True, 1, 1),
])
def test_bytes_equal_rosbags(frame_id: str, n: int, torque: bool, in_heads: int,
                             out_heads: int) -> None:
    rng = np.random.default_rng(n * 31 + in_heads * 7 + out_heads)
    arrays = [np.arange(n) / 1e4, rng.normal(size=n), rng.normal(size=n),
              rng.normal(size=n) if torque else np.zeros(0),
              np.arange(in_heads, dtype=np.uint8), rng.normal(size=in_heads * n),
              np.arange(out_heads, dtype=np.uint8)[::-1].copy(),
              rng.normal(size=out_heads * n)]
    stamp_ns = 1_764_000_000_123_456_789 + n
    want = _rosbags(stamp_ns, frame_id, 12345 + n, 10000.0, arrays)
    got = encoder_block_cdr(stamp_ns, frame_id, 12345 + n, 10000.0, *arrays)
    assert got == want
    # strided views (a column of a 2-D array) are laid out the same
    wide = np.stack([arrays[1], arrays[2]], axis=1)
    assert encoder_block_cdr(stamp_ns, frame_id, 12345 + n, 10000.0, arrays[0], wide[:, 0],
                             wide[:, 1], *arrays[3:]) == want
    block = decode_encoder_block(got)
    np.testing.assert_array_equal(block.theta_out_rad, arrays[2])
