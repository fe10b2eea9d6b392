"""The chunk CRC-32 the reader checks: ISA-L's (isal), checked against zlib's.

MCAP chunks carry the CRC-32 (IEEE 802.3, zlib's) of their uncompressed records. The reader
computes it with isal (about 15x faster; issue 23), and zlib's ``crc32`` is the reference
here: every length 0..300 (the SIMD kernels' tails), odd alignments and chunk sizes. A
mismatch is still found (tests/io/test_bag_reader.py, the damaged chunk).
"""

from __future__ import annotations

import zlib

import numpy as np
import pytest

from rv_te_bench.io import _mcap_scan


def test_the_reader_uses_isal_when_installed() -> None:
    isal_zlib = pytest.importorskip('isal.isal_zlib')   # a dependency: installed by make venv
    assert _mcap_scan._crc32 is isal_zlib.crc32


def test_crc32_equals_zlib() -> None:
    rng = np.random.default_rng(2026)
    data = rng.integers(0, 256, 3_000_000, dtype=np.uint8).tobytes()
    view = memoryview(data)
    for n in range(301):
        assert _mcap_scan._crc32(view[:n]) == zlib.crc32(view[:n]), n
    for start in (1, 3, 7, 13):
        for n in (64, 1000, 65_537, 1_300_003):
            part = view[start:start + n]
            assert _mcap_scan._crc32(part) == zlib.crc32(part), (start, n)
    assert _mcap_scan._crc32(data) == zlib.crc32(data)
    assert _mcap_scan._crc32(data[:777]) == zlib.crc32(data[:777])
    # one flipped bit changes it
    flipped = bytearray(data[:100_000])
    flipped[54_321] ^= 0x10
    assert _mcap_scan._crc32(bytes(flipped)) != _mcap_scan._crc32(data[:100_000])
