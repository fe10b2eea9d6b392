"""EncoderBlocks with read heads, and older bags without them (issue 36), through every reader.

Messages are serialised by rosbags' typestore (not by the suite's writers): today's
definition with heads, and the definition before issue 36 (the older bags).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
import pytest

from rv_te_bench.errors import BagError
from rv_te_bench.io._legacy_msgs import legacy_typestore, upgrade_cdr
from rv_te_bench.io.bag_reader import (
    decode_encoder_block,
    decode_encoder_block_rosbags,
    read_bench_info,
    read_encoder_batches,
    read_encoder_blocks,
)
from rv_te_bench.io.msgdefs import BENCH_INFO, ENCODER_BLOCK, rv_te_typestore

if TYPE_CHECKING:
    from pathlib import Path

RATE = 1000.0


def _block(store, seq: int, n: int, heads: dict[str, tuple[tuple[int, ...], np.ndarray]]):
    types = store.types
    t0 = 1_700_000_000 + seq
    fields = {
        'header': types['std_msgs/msg/Header'](
            stamp=types['builtin_interfaces/msg/Time'](sec=t0, nanosec=0), frame_id='b'),
        'seq': seq, 'sample_rate_hz': RATE, 'time_offset_s': np.arange(n) / RATE,
        'theta_in_rad': np.arange(n) * 0.1 + seq, 'theta_out_rad': np.arange(n) * 1e-3 + seq,
        'torque_out_nm': np.zeros(0)}
    if store is not legacy_typestore():
        for side in ('in', 'out'):
            ids, vals = heads.get(side, ((), np.zeros(0)))
            fields[f'{side}_head_ids'] = np.array(ids, dtype=np.uint8)
            fields[f'theta_{side}_heads_rad'] = np.ascontiguousarray(vals, dtype=np.float64).ravel()
    return bytes(store.serialize_cdr(types[ENCODER_BLOCK](**fields), ENCODER_BLOCK))


def _heads(seq: int, n: int, ids=(0, 1, 2, 3)) -> np.ndarray:
    return np.array([np.arange(n) * 1e-3 + seq + 1e-6 * (h + 1) for h in ids])


def test_one_block_with_heads_decodes_the_same_by_hand_and_by_rosbags() -> None:
    store = rv_te_typestore()
    data = _block(store, 3, 7, {'out': ((0, 1, 2, 3), _heads(3, 7))})
    for decode in (decode_encoder_block, decode_encoder_block_rosbags):
        b = decode(data)
        assert b.out_head_ids == (0, 1, 2, 3) and b.in_head_ids == ()
        np.testing.assert_array_equal(b.theta_out_heads_rad, _heads(3, 7))
        np.testing.assert_array_equal(b.theta_out_rad, np.arange(7) * 1e-3 + 3)


def test_older_messages_decode_without_heads_even_with_end_padding() -> None:
    """The definition before issue 36 (rosbags' legacy serialisation), also with the up to
    7 bytes of end padding some serialisers add: no heads, the same samples."""
    old = _block(legacy_typestore(), 2, 5, {})
    for pad in (b'', b'\0' * 4, b'\xaa' * 7):
        b = decode_encoder_block(old + pad)
        assert b.out_head_ids == () and b.theta_out_heads_rad.size == 0
        np.testing.assert_array_equal(b.theta_out_rad, np.arange(5) * 1e-3 + 2)
    up = upgrade_cdr(ENCODER_BLOCK, old)
    msg = rv_te_typestore().deserialize_cdr(up, ENCODER_BLOCK)
    assert len(msg.out_head_ids) == 0 and list(msg.theta_out_rad) == list(np.arange(5) * 1e-3 + 2)
    assert decode_encoder_block_rosbags(old).out_head_ids == ()


def test_readings_that_do_not_fit_the_ids_are_refused() -> None:
    store = rv_te_typestore()
    bad = _block(store, 1, 4, {'out': ((0, 1), np.zeros(6))})     # 2 heads x 4 needs 8
    with pytest.raises(BagError, match='names 2 heads but theta_out_heads_rad holds 6'):
        decode_encoder_block(bad)
    with pytest.raises(BagError, match='names 2 heads'):
        decode_encoder_block_rosbags(bad)


def _write_bag(path: Path, blocks: list[bytes], info: bytes | None, store) -> Path:
    from rosbags.rosbag2 import StoragePlugin, Writer

    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        ci = writer.add_connection('/bench/info', BENCH_INFO, typestore=store) if info else None
        ce = writer.add_connection('/bench/encoders', ENCODER_BLOCK, typestore=store)
        if ci is not None:
            writer.write(ci, 1, info)
        for k, data in enumerate(blocks):
            writer.write(ce, 10 + k, data)
    return path


def test_a_bag_with_heads_reads_back_in_batches_and_a_block_missing_a_head_alone(
        tmp_path: Path) -> None:
    """Blocks 0-3 and 5-9 carry 4 heads, block 4 lacks head 2: the batch reader gives the
    full blocks as batches with (4, N) heads and block 4 on its own with heads 0, 1, 3;
    every value is what was written."""
    store = rv_te_typestore()
    blocks = []
    for seq in range(10):
        ids = (0, 1, 3) if seq == 4 else (0, 1, 2, 3)
        blocks.append(_block(store, seq, 20, {'out': (ids, _heads(seq, 20, ids))}))
    bag = _write_bag(tmp_path / 'b', blocks, None, store)
    got = {}
    for item in read_encoder_batches(bag):
        if hasattr(item, 'n_blocks'):
            assert item.out_head_ids == (0, 1, 2, 3)
            assert item.theta_out_heads_rad.shape == (4, item.n_samples)
            for k in range(item.n_blocks):
                got[int(item.seq[k])] = item.block(k)
        else:
            got[item.seq] = item
    assert sorted(got) == list(range(10))
    for seq, b in got.items():
        ids = (0, 1, 3) if seq == 4 else (0, 1, 2, 3)
        assert b.out_head_ids == ids
        np.testing.assert_array_equal(b.theta_out_heads_rad, _heads(seq, 20, ids))
    single = {b.seq: b for b in read_encoder_blocks(bag)}
    assert single[4].out_head_ids == (0, 1, 3)


def test_an_older_bag_reads_with_its_bench_info(tmp_path: Path) -> None:
    """A bag written with the definitions before issue 36 (hashes and all): BenchInfo and
    blocks read; the scale fields are 'not stated'."""
    old = legacy_typestore()
    types = old.types
    info = types[BENCH_INFO](
        header=types['std_msgs/msg/Header'](
            stamp=types['builtin_interfaces/msg/Time'](sec=1, nanosec=0), frame_id='b'),
        bench_id='b', preset='wang2020-2kv', reducer_type='2kv', gear_ratio=79.0,
        crank_per_input=-25 / 79, crank_rel_per_input=-26 / 79,
        mesh_orders=np.array([1300.0]), mesh_labels=['m'], encoder_in_model='x',
        encoder_out_model='y', encoder_in_resolution_rad=0.0, encoder_out_resolution_rad=0.0,
        sample_rate_hz=RATE, block_size=20, parameters_yaml='')
    bag = _write_bag(tmp_path / 'old', [_block(old, s, 20, {}) for s in range(3)],
                     bytes(old.serialize_cdr(info, BENCH_INFO)), old)
    rec = read_bench_info(bag)
    assert rec is not None and rec.gear_ratio == 79.0
    assert rec.encoder_out_head_angles_rad == () and rec.encoder_out_scale_serial == ''
    assert [b.seq for b in read_encoder_blocks(bag)] == [0, 1, 2]
    assert math.isclose(next(iter(read_encoder_batches(bag))).theta_out_rad[1], 1e-3)
