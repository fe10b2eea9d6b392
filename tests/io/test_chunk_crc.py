"""The chunk CRC-32 the reader checks: ISA-L's (isal), checked against zlib's.

MCAP chunks carry the CRC-32 (IEEE 802.3, zlib's) of their uncompressed records. The reader
computes it with isal (about 15x faster; issue 23), and zlib's ``crc32`` is the reference
here: every length 0..300 (the SIMD kernels' tails), odd alignments and chunk sizes. A
mismatch is still found (tests/io/test_bag_reader.py, the damaged chunk).
"""

from __future__ import annotations

import struct
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


def test_the_crc_can_be_switched_off_and_is_on_by_default(
        tmp_path, monkeypatch: pytest.MonkeyPatch) -> None:
    """``RV_TE_CHUNK_CRC=0`` skips the check (issue 41: an option, with its cost stated in
    benchmarks/README.md); unset, a damaged chunk that still decompresses is caught."""
    from rv_te_bench.io.bag_reader import read_encoder_batches
    from tests.io.bag_fixtures import encoder_cdr, write_sample_bag

    bag = tmp_path / 'bag'
    write_sample_bag(bag, n_blocks=20, compression='zstd', chunk_size_bytes=4096)
    (file,) = bag.glob('*.mcap')
    # re-write one chunk with a flipped value bit, compressed again: it decompresses, only
    # its CRC (of the records as first written) can tell
    import zstandard

    data = bytearray(file.read_bytes())
    raw_records = None
    for offset, op, body in _mcap_scan._iter_records(memoryview(bytes(data)), 8):
        if op == _mcap_scan._OP_CHUNK:
            inner = bytes(_mcap_scan._chunk_records(body))
            if encoder_cdr(5, 100)[1000:1060] in inner:
                raw_records, at, length = inner, offset, len(body)
                break
    assert raw_records is not None
    hit = raw_records.find(encoder_cdr(5, 100)[1000:1060])
    damaged = bytearray(raw_records)
    damaged[hit + 10] ^= 0x01
    head = bytes(data[at + 9:at + 9 + _mcap_scan._CHUNK.size])
    comp = zstandard.ZstdCompressor().compress(bytes(damaged))
    body = (head + struct.pack('<I', 4) + b'zstd' + struct.pack('<Q', len(comp)) + comp)
    data[at:at + 9 + length] = struct.pack('<BQ', _mcap_scan._OP_CHUNK, len(body)) + body
    file.write_bytes(bytes(data))

    def read() -> tuple[int, list[str]]:
        stream = read_encoder_batches(bag, strict=False, read_ahead=False)
        n = sum(it.n_blocks if hasattr(it, 'n_blocks') else 1 for it in stream)
        return n, list(stream.problems)

    monkeypatch.delenv(_mcap_scan.CHUNK_CRC_ENV, raising=False)
    assert _mcap_scan.chunk_crc_checked()
    n, problems = read()
    assert n < 20 and any('CRC mismatch' in p for p in problems)
    monkeypatch.setenv(_mcap_scan.CHUNK_CRC_ENV, '0')
    assert not _mcap_scan.chunk_crc_checked()
    n, problems = read()
    assert n == 20 and problems == []   # unchecked: the flipped bit goes through unseen
