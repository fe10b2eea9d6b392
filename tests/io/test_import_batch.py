"""The import's whole-block path (issue 41): blocks laid out many at once, the usual chunk
converted and unwrapped in a few passes. The bags must be those of the block-by-block,
sample-checking path, byte for byte: the messages, their stamps, the chunks."""

from __future__ import annotations

import glob
import math
from typing import TYPE_CHECKING

import numpy as np
import pytest
from mcap.reader import make_reader

from rv_te_bench.io import _encoder_cdr_out
from rv_te_bench.io.bag_writer import BagWriter
from rv_te_bench.io.bench_description import parse_bench_description
from rv_te_bench.io.importers import ImportOptions, _convert, _to_bag, _turns, import_file
from rv_te_bench.io.msgdefs import ENCODER_BLOCK

if TYPE_CHECKING:
    from pathlib import Path

RATE_HZ = 2000.0


def test_layout_of_many_blocks_is_the_bytes_of_one_block_at_a_time() -> None:
    rng = np.random.default_rng(5)
    for fid in ('b', 'bench-12', 'abcdefg'):
        for n in (1, 3, 250):
            for n_torque in (0, n):
                for n_heads in (0, 1, 4):
                    k = 4
                    ids = np.arange(n_heads, dtype=np.uint8)
                    lay = _encoder_cdr_out.EncoderBlocksLayout(fid, n, n_torque, ids)
                    t = np.cumsum(rng.random((k, n)), axis=1) + 7.0
                    a, b, tq = rng.normal(size=(3, k, n))
                    heads = rng.normal(size=(k, n_heads, n))
                    stamps = rng.integers(0, 2**31 * 10**9, k)
                    out = np.zeros((k, lay.size), dtype=np.uint8)
                    lay.fill(out, stamps, 41, 2000.0, t, a, b, tq if n_torque else None,
                             heads if n_heads else None)
                    for i in range(k):
                        one = _encoder_cdr_out.encoder_block_cdr(
                            int(stamps[i]), fid, 41 + i, 2000.0, t[i] - t[i, 0], a[i], b[i],
                            tq[i] if n_torque else np.zeros(0), np.zeros(0, np.uint8),
                            np.zeros(0), ids, heads[i].ravel())
                        assert out[i].tobytes() == one, (fid, n, n_torque, n_heads, i)


def _records(bag: Path) -> tuple[list[tuple[str, int, bytes]], list[tuple[int, int, int]]]:
    msgs, chunks = [], []
    for f in sorted(glob.glob(str(bag / '*.mcap'))):
        with open(f, 'rb') as fh:
            r = make_reader(fh)
            msgs += [(ch.topic, m.log_time, m.data)
                     for _, ch, m in r.iter_messages(log_time_order=False)]
            summary = r.get_summary()
            assert summary is not None
            chunks += [(c.message_start_time, c.uncompressed_size, c.compressed_size)
                       for c in summary.chunk_indexes]
    return msgs, chunks


def test_write_batch_gives_the_file_of_one_write_per_message(tmp_path: Path) -> None:
    """Chunk boundaries (a chunk closes after the message that fills it), index, records:
    the .mcap bytes are the same, with a message already in the open chunk."""
    rng = np.random.default_rng(2)
    size = 1000
    payload = rng.integers(0, 256, (37, size), dtype=np.uint8)
    stamps = 10**18 + np.arange(37, dtype=np.int64) * 5_000_000
    files = []
    for name, batch in (('one', False), ('batch', True)):
        with BagWriter(tmp_path / name / 'bag', chunk_size_bytes=7000) as w:
            w.add_topic('/x', ENCODER_BLOCK)
            w.write('/x', 10**18 - 1, b'\x00\x01\x00\x00' + bytes(20))
            if batch:
                def fill(rows: np.ndarray, i: int, j: int) -> None:
                    rows[...] = payload[i:j]
                w.write_batch('/x', stamps[:30], size, fill)
                w.write_batch('/x', stamps[30:], size, fill=lambda r, i, j: fill(r, 30 + i,
                                                                                  30 + j))
            else:
                for i in range(37):
                    w.write('/x', int(stamps[i]), payload[i].tobytes())
        files.append(next((tmp_path / name / 'bag').glob('*.mcap')).read_bytes())
    assert files[0] == files[1]
    assert len(_records(tmp_path / 'one' / 'bag')[1]) == math.ceil((24 + 31 + 37 * 1031) / 7000)


def _odd_csv(path: Path) -> Path:
    """Single-turn angles (wraps), missing rows, a long gap, a NaN, time going backwards,
    trailing bad rows, two output heads."""
    n = 60_000
    t = np.arange(n) / RATE_HZ
    phi = 2 * np.pi * 5 * t / 79
    th_in = (2 * np.pi * 5 * t) % (2 * np.pi)
    th_out = (phi + 3e-4 * np.cos(25 * phi)) % (2 * np.pi)
    h1 = (th_out + 1.3 + 2e-6 * np.sin(phi)) % (2 * np.pi)
    tq = 30 + 0.1 * np.sin(t)
    keep = np.ones(n, bool)
    keep[9_000:9_030] = False
    keep[31_000:31_500] = False
    th_in[40_000] = np.nan
    t[50_000] = t[49_990]
    h1[45_000] = np.nan
    th_out[-3:] = np.nan
    with path.open('w') as f:
        f.write('t_s,theta_in_rad,theta_out_rad,h1,torque_nm\n')
        np.savetxt(f, np.c_[t, th_in, th_out, h1, tq][keep], fmt='%.17g', delimiter=',')
    return path


def _old_wrap_turns(x: np.ndarray, prev: float) -> np.ndarray:
    """The unwrapping before issue 41 (always an array), for the comparison."""
    d = np.diff(x, prepend=prev)
    big = np.flatnonzero(np.abs(d) >= math.pi)
    k = np.zeros(x.size, dtype=np.int64)
    if big.size:
        db = d[big]
        dmod = np.mod(db + math.pi, 2 * math.pi) - math.pi
        dmod[(dmod == -math.pi) & (db > 0)] = math.pi
        k[big] = np.rint((dmod - db) / (2 * math.pi)).astype(np.int64)
        np.cumsum(k, out=k)
    return k


@pytest.mark.parametrize(('block', 'chunk'), [(100, 7_777), (500, 20_000), (1, 3_000)])
def test_import_bag_same_as_the_block_by_block_path(tmp_path: Path,
                                                    monkeypatch: pytest.MonkeyPatch,
                                                    block: int, chunk: int) -> None:
    src = _odd_csv(tmp_path / 'odd.csv')
    desc = parse_bench_description({'bench_id': 'b', 'preset': 'wang2020-2kv',
                                    'sample_rate_hz': RATE_HZ, 'block_size': block,
                                    'encoders': {'output': {'heads_deg': [0.0, 74.5]}}})
    opts = ImportOptions(time='t_s', theta_in='theta_in_rad',
                         theta_out_heads=('theta_out_rad', 'h1'), torque='torque_nm',
                         turns_in='single', turns_out='single', chunk_samples=chunk,
                         start_ns=1_700_000_000 * 10**9)
    fast = import_file(src, desc, tmp_path / 'fast', options=opts)
    with monkeypatch.context() as m:     # the paths before issue 41
        m.setattr(_to_bag, 'BATCH_BLOCKS', False)
        m.setattr(_convert.ChunkConverter, '_clean', lambda *_a, **_k: None)
        m.setattr(_turns, '_wrap_turns', _old_wrap_turns)
        slow = import_file(src, desc, tmp_path / 'slow', options=opts)
    assert fast.gaps_total == slow.gaps_total >= 3
    assert fast.wraps_in == slow.wraps_in > 10
    assert (fast.samples, fast.blocks, fast.samples_dropped) == (slow.samples, slow.blocks,
                                                                  slow.samples_dropped)
    msgs_fast, chunks_fast = _records(tmp_path / 'fast')
    msgs_slow, chunks_slow = _records(tmp_path / 'slow')
    assert len(msgs_fast) == fast.blocks + 1
    assert msgs_fast == msgs_slow
    assert chunks_fast == chunks_slow


@pytest.mark.parametrize('compression', ['zstd-fast', 'zstd', 'lz4', 'none'])
def test_every_compression_read_back_by_rosbags_and_mcap(tmp_path: Path,
                                                         compression: str) -> None:
    """Each ``--compression`` makes a bag that rosbags and mcap + mcap-ros2-support read
    (chunks compressed as declared), holding the samples of the file."""
    from mcap_ros2.decoder import DecoderFactory
    from rosbags.highlevel import AnyReader

    n = 12_345
    t = np.arange(n) / RATE_HZ
    th_in = 2 * np.pi * 5 * t
    th_out = th_in / 79 + 1e-4 * np.sin(th_in / 79 * 25)
    tq = 30 + np.cos(t)
    src = tmp_path / 'run.csv'
    with src.open('w') as f:
        f.write('t_s,theta_in_rad,theta_out_rad,torque_nm\n')
        np.savetxt(f, np.c_[t, th_in, th_out, tq], fmt='%.17g', delimiter=',')
    desc = parse_bench_description({'bench_id': 'b', 'preset': 'wang2020-2kv',
                                    'sample_rate_hz': RATE_HZ, 'block_size': 500})
    out = tmp_path / 'bag'
    import_file(src, desc, out, options=ImportOptions(
        time='t_s', theta_in='theta_in_rad', theta_out='theta_out_rad', torque='torque_nm',
        start_ns=1_700_000_000 * 10**9, chunk_samples=4000, compression=compression))
    mcap_path = next(out.glob('*.mcap'))
    with mcap_path.open('rb') as fh:
        r = make_reader(fh, decoder_factories=[DecoderFactory()])
        summary = r.get_summary()
        assert summary is not None
        assert {c.compression for c in summary.chunk_indexes} == {
            {'zstd-fast': 'zstd', 'zstd': 'zstd', 'lz4': 'lz4', 'none': ''}[compression]}
        decoded = [m for _, ch, _, m in r.iter_decoded_messages()
                   if ch.topic == '/bench/encoders']
    got_in = np.concatenate([np.asarray(m.theta_in_rad) for m in decoded])
    got_tq = np.concatenate([np.asarray(m.torque_out_nm) for m in decoded])
    assert got_in.size == n
    np.testing.assert_array_equal(got_in, th_in)
    np.testing.assert_array_equal(got_tq, tq)
    with AnyReader([out]) as reader:
        conns = [c for c in reader.connections if c.topic == '/bench/encoders']
        msgs = [reader.deserialize(raw, c.msgtype)
                for c, _, raw in reader.messages(connections=conns)]
    np.testing.assert_array_equal(np.concatenate([m.theta_out_rad for m in msgs]), th_out)
    offsets = np.concatenate([m.time_offset_s + (m.header.stamp.sec - 1_700_000_000
                                                 + m.header.stamp.nanosec * 1e-9)
                              for m in msgs])
    np.testing.assert_allclose(offsets, t, atol=1e-9)


def test_a_level_for_another_compression_is_refused(tmp_path: Path) -> None:
    from rv_te_bench.errors import BagError, DataImportError

    with pytest.raises(BagError, match='zstd setting'):
        BagWriter(tmp_path / 'b', compression='lz4', compression_level=3)
    with pytest.raises(DataImportError, match=r"--compression must be one of .*'brotli'"):
        ImportOptions(compression='brotli')
