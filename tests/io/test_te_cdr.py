"""io._te_cdr: the samples of a TransmissionError read from bytes the rosbags typestore wrote
(little- and big-endian), as the compensation node reads te/samples raw (issue 41 item 4)."""

from __future__ import annotations

import numpy as np
import pytest

from rv_te_bench.errors import BagError
from rv_te_bench.io._te_cdr import te_samples_of
from rv_te_bench.io.msgdefs import rv_te_typestore

TE = 'rv_te_msgs/msg/TransmissionError'


def _rosbags(frame_id: str, seq: int, te: np.ndarray, th: np.ndarray, *,
             little: bool = True) -> bytes:
    store = rv_te_typestore()
    t = store.types
    stats = t['rv_te_msgs/msg/TeStatistics'](
        pp_rad=1.5, amplitude_rad=0.8, mean_rad=0.1, std_rad=0.2, revolutions_covered=3.0,
        n_samples=7)
    msg = t[TE](
        header=t['std_msgs/msg/Header'](
            stamp=t['builtin_interfaces/msg/Time'](sec=12, nanosec=34), frame_id=frame_id),
        seq=seq, window_index=5, window_complete=True, sample_rate_hz=500.0, te_rad=te,
        theta_out_rad=th, window=stats, cumulative=stats, gaps=3)
    data = store.serialize_cdr(msg, TE, little_endian=little)
    return bytes(data)


@pytest.mark.parametrize('little', [True, False])
@pytest.mark.parametrize('frame_id', ['', 'b', 'bench', 'bench_07', 'abcdefgh', 'µ'])
@pytest.mark.parametrize('n', [0, 1, 5, 50])
def test_samples_equal_what_rosbags_wrote(little: bool, frame_id: str, n: int) -> None:
    rng = np.random.default_rng(n + 3 * len(frame_id))
    te, th = rng.normal(size=n) * 1e-4, rng.normal(size=n) * 10.0
    seq, got_te, got_th = te_samples_of(_rosbags(frame_id, 2**63 + n, te, th, little=little))
    assert seq == 2**63 + n
    np.testing.assert_array_equal(got_te, te)
    np.testing.assert_array_equal(got_th, th)


def test_cut_short_or_foreign_bytes_are_a_bag_error() -> None:
    data = _rosbags('bench1', 9, np.ones(5), np.ones(5))
    # (the two statistics and the gap count, 104 bytes, follow the arrays: not needed)
    for cut in (0, 3, 15, 30, 60, len(data) - 110):
        with pytest.raises(BagError):
            te_samples_of(data[:cut])
    with pytest.raises(BagError, match='not a CDR'):
        te_samples_of(b'\x07\x07' + data[2:])
