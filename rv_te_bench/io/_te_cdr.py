"""TransmissionError CDR -> (seq, te_rad, theta_out_rad): the compensation node's hot path.

A ``te/samples`` message carries its statistics too (two nested TeStatistics); a reader
that needs only the samples takes them straight from the serialised bytes (read-only numpy
views, no message object): 4 us instead of 25 us per message (issue 41 item 4).

Layout after the 4-byte encapsulation header (XCDR1, alignment from there): ``stamp``
(int32, uint32), ``frame_id`` (uint32 length with the NUL, bytes), ``seq`` and
``window_index`` (uint64, aligned to 8), ``window_complete`` (bool, 1 byte),
``sample_rate_hz`` (float64, aligned to 8), then ``te_rad`` and ``theta_out_rad``: each a
uint32 count (aligned to 4), then its float64 elements (aligned to 8 when not empty).
"""

from __future__ import annotations

import struct

import numpy as np

from rv_te_bench.errors import BagError

__all__ = ['te_samples_of']


def te_samples_of(data: bytes) -> tuple[int, np.ndarray, np.ndarray]:
    """(seq, te_rad, theta_out_rad) of a serialised ``rv_te_msgs/TransmissionError``.

    Raises:
        BagError: Not a CDR message, or truncated before the end of ``theta_out_rad``.
    """
    size = len(data)
    if size < 16 or data[0] != 0 or data[1] not in (0, 1):
        msg = f'not a CDR TransmissionError ({size} bytes)'
        raise BagError(msg)
    order = '<' if data[1] == 1 else '>'
    try:
        (flen,) = struct.unpack_from(order + 'I', data, 12)
        off = (12 + flen + 7) & ~7             # payload offset of seq
        (seq,) = struct.unpack_from(order + 'Q', data, 4 + off)
        # seq and window_index (8 + 8), window_complete (1), padding to 8, sample_rate_hz
        off += 32
        out = []
        for _ in range(2):
            off = (off + 3) & ~3
            (n,) = struct.unpack_from(order + 'I', data, 4 + off)
            off += 4
            if n:
                off = (off + 7) & ~7
            if 4 + off + 8 * n > size:
                msg = f'an array of {n} float64 runs past the message end ({size} bytes)'
                raise BagError(msg)
            a = np.frombuffer(data, order + 'f8', n, 4 + off)
            out.append(a if order == '<' else a.astype(np.float64))
            off += 8 * n
    except struct.error as exc:
        msg = f'TransmissionError CDR truncated ({size} bytes): {exc}'
        raise BagError(msg) from None
    return int(seq), out[0], out[1]
