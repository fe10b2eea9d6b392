"""The chunk record walk of the bag reader: runs of message records parsed as arrays (#41).

A decompressed MCAP chunk is a sequence of records ``opcode (1 B) | length (8 B) | body``;
a message body is ``channel_id u16 | sequence u32 | log_time u64 | publish_time u64 |
data``. The walk parses runs of message records of one length with numpy (one pass over
their headers). The reference here is an independent plain walk written from that layout
(struct, record by record), on chunks built byte by byte: runs of one length, lengths that
vary, other records between them, and a damaged record after sound ones.
"""

from __future__ import annotations

import struct

import numpy as np
import pytest

from rv_te_bench.io import _mcap_scan

MESSAGE, METADATA = 0x05, 0x0C


def _message(cid: int, seq: int, log_time: int, data: bytes) -> bytes:
    body = struct.pack('<HIQQ', cid, seq, log_time, log_time + 7) + data
    return struct.pack('<BQ', MESSAGE, len(body)) + body


def _metadata(name: str) -> bytes:
    key, val = b'k', b'v'
    entries = struct.pack('<I', len(key)) + key + struct.pack('<I', len(val)) + val
    body = (struct.pack('<I', len(name)) + name.encode() + struct.pack('<I', len(entries))
            + entries)
    return struct.pack('<BQ', METADATA, len(body)) + body


def _reference(chunk: bytes) -> list[tuple[int, int, int, int]]:
    """(cid, log_time, data start, data end) of every message, record by record."""
    out, pos = [], 0
    while pos < len(chunk):
        op, length = struct.unpack_from('<BQ', chunk, pos)
        if op == MESSAGE:
            cid, _seq, log_time, _pub = struct.unpack_from('<HIQQ', chunk, pos + 9)
            out.append((cid, log_time, pos + 9 + 22, pos + 9 + length))
        pos += 9 + length
    return out


def _metadata_names(chunk: bytes) -> list[str]:
    out, pos = [], 0
    while pos < len(chunk):
        op, length = struct.unpack_from('<BQ', chunk, pos)
        if op == METADATA:
            (n,) = struct.unpack_from('<I', chunk, pos + 9)
            out.append(chunk[pos + 13:pos + 13 + n].decode())
        pos += 9 + length
    return out


def _walk(chunk: bytes) -> tuple[list[tuple[int, int, int, int]], _mcap_scan._ScanState,
                                  Exception | None]:
    state = _mcap_scan._ScanState()
    found = _mcap_scan._Found()
    damage = None
    try:
        _mcap_scan._walk_chunk(memoryview(chunk), state, found)
    except _mcap_scan._CorruptError as exc:
        damage = exc
    rows = list(found.columns().rows()) if found else []
    return rows, state, damage


def _chunk(rng: np.random.Generator) -> bytes:
    parts = []
    t = 1_700_000_000_000_000_000
    for k in range(40):
        kind = rng.integers(0, 4)
        if kind == 0:    # a run of one length (EncoderBlocks)
            size = int(rng.integers(0, 300))
            parts += [_message(2, k * 100 + i, t + 10 * i, bytes([i % 256]) * size)
                      for i in range(int(rng.integers(1, 40)))]
        elif kind == 1:  # lengths that vary from message to message
            parts += [_message(int(rng.integers(1, 5)), i, t + i,
                               bytes(int(rng.integers(0, 50)))) for i in range(5)]
        elif kind == 2:
            parts.append(_metadata(f'm{k}'))
        else:            # two channels alternating at one length
            parts += [_message(1 + i % 2, i, t - i, b'x' * 16) for i in range(12)]
        t += 10_000
    return b''.join(parts)


@pytest.mark.parametrize('seed', range(12))
def test_walk_equals_a_record_by_record_walk(seed: int) -> None:
    chunk = _chunk(np.random.default_rng(seed))
    rows, state, damage = _walk(chunk)
    assert damage is None
    assert rows == _reference(chunk)
    assert sorted(state.metadata) == sorted(_metadata_names(chunk))


def test_a_long_run_is_parsed_as_arrays_with_the_same_values() -> None:
    data = [bytes((i + j) % 256 for j in range(60)) for i in range(300)]
    chunk = b''.join(_message(7, i, 10**18 + 5 * i, d) for i, d in enumerate(data))
    found = _mcap_scan._Found()
    _mcap_scan._walk_chunk(memoryview(chunk), _mcap_scan._ScanState(), found)
    assert len(found._pieces) >= 1 and not found._rows   # the run, not row by row
    cols = found.columns()
    assert cols.log_time.dtype == np.uint64
    assert cols.cid.tolist() == [7] * 300
    assert cols.log_time.tolist() == [10**18 + 5 * i for i in range(300)]
    assert [chunk[a:b] for a, b in zip(cols.start.tolist(), cols.end.tolist(),
                                       strict=True)] == data
    assert list(cols.rows()) == _reference(chunk)


@pytest.mark.parametrize('where', ['length', 'opcode', 'truncated'])
def test_a_damaged_record_inside_a_run_keeps_the_messages_before_it(where: str) -> None:
    recs = [_message(2, i, 100 + i, b'\x11' * 40) for i in range(30)]
    sound = b''.join(recs[:17])
    bad = bytearray(recs[17])
    if where == 'length':      # claims more bytes than the chunk holds
        bad[1:9] = struct.pack('<Q', 10**6)
    elif where == 'opcode':    # another record kind with a body no parser accepts
        bad[0] = 0x03          # a channel record: its topic string runs past its record
        bad[9 + 4:9 + 8] = struct.pack('<I', 10**6)
    else:
        bad = bad[:20]
    chunk = sound + bytes(bad) + (b''.join(recs[18:]) if where != 'truncated' else b'')
    rows, _state, damage = _walk(chunk)
    assert damage is not None
    assert rows == _reference(sound)
