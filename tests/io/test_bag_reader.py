"""bag_reader: content equals what rosbags serialised; bad input gives BagError naming file
and problem; partial results are marked."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from mcap_ros2.writer import Writer as McapRos2Writer

from rv_te_bench.errors import BagError
from rv_te_bench.io.bag_reader import (
    bag_summary,
    decode_encoder_block,
    decode_encoder_block_rosbags,
    iter_messages,
    open_bag,
    read_bench_info,
    read_encoder_blocks,
)
from rv_te_bench.io.bag_writer import BagWriter
from rv_te_bench.io.msgdefs import BENCH_INFO, ENCODER_BLOCK, full_msgdef, rv_te_typestore
from tests.io.bag_fixtures import (
    ENCODER_TOPIC,
    INFO_TOPIC,
    SAMPLE_RATE_HZ,
    T0_NS,
    bench_info_cdr,
    block_arrays,
    encoder_cdr,
    write_sample_bag,
)

FIELDS = ('time_offset_s', 'theta_in_rad', 'theta_out_rad', 'torque_out_nm')


def _assert_block(block: object, seq: int, n: int, *, torque: bool = True) -> None:
    ref = block_arrays(seq, n, torque=torque)
    assert block.seq == seq  # type: ignore[attr-defined]
    assert block.sample_rate_hz == SAMPLE_RATE_HZ  # type: ignore[attr-defined]
    for name in FIELDS:
        np.testing.assert_array_equal(getattr(block, name), ref[name])  # exact: same bytes
    t_ns = T0_NS + round(seq * n / SAMPLE_RATE_HZ * 1e9)
    # float64 seconds since 1970 resolve ~0.24 us: that is the tolerance of stamp_s.
    assert abs(block.stamp_s - t_ns * 1e-9) < 1e-6  # type: ignore[attr-defined]


@pytest.fixture
def sample_bag(tmp_path: Path) -> Path:
    bag = tmp_path / 'bag'
    write_sample_bag(bag, n_blocks=20, compression='zstd', chunk_size_bytes=8192)
    return bag


def test_encoder_blocks_equal_what_was_serialised(sample_bag: Path) -> None:
    blocks = read_encoder_blocks(sample_bag)
    got = list(blocks)
    assert len(got) == 20
    for seq, block in enumerate(got):
        _assert_block(block, seq, 100)
        assert not block.theta_in_rad.flags.writeable
    assert blocks.partial is False


@pytest.mark.parametrize('little_endian', [True, False])
@pytest.mark.parametrize(('n', 'torque', 'frame_id'),
                         [(1, True, ''), (7, False, 'b'), (100, True, 'bench-longer-id')])
def test_numpy_decode_matches_rosbags(n: int, torque: bool, frame_id: str,
                                      little_endian: bool) -> None:
    store = rv_te_typestore()
    msg = store.deserialize_cdr(encoder_cdr(3, n, frame_id=frame_id, torque=torque),
                                ENCODER_BLOCK)
    raw = bytes(store.serialize_cdr(msg, ENCODER_BLOCK, little_endian=little_endian))
    ours, ref = decode_encoder_block(raw), decode_encoder_block_rosbags(raw)
    _assert_block(ours, 3, n, torque=torque)
    assert (ours.seq, ours.stamp_s, ours.sample_rate_hz) == (ref.seq, ref.stamp_s,
                                                             ref.sample_rate_hz)
    for name in FIELDS:
        np.testing.assert_array_equal(getattr(ours, name), getattr(ref, name))


def test_reads_a_file_written_by_mcap_ros2(tmp_path: Path) -> None:
    """An independent writer (mcap_ros2 serialises dicts itself) and a lone .mcap file."""
    path = tmp_path / 'other.mcap'
    with path.open('wb') as fh:
        writer = McapRos2Writer(fh)
        schema = writer.register_msgdef(ENCODER_BLOCK, full_msgdef(ENCODER_BLOCK))
        for seq in range(5):
            t_ns = T0_NS + round(seq * 50 / SAMPLE_RATE_HZ * 1e9)
            writer.write_message(ENCODER_TOPIC, schema, {
                'header': {'stamp': {'sec': t_ns // 10**9, 'nanosec': t_ns % 10**9},
                           'frame_id': 'bench0'},
                'seq': seq, 'sample_rate_hz': SAMPLE_RATE_HZ,
                **{k: v.tolist() for k, v in block_arrays(seq, 50).items()}},
                log_time=t_ns, publish_time=t_ns)
        writer.finish()
    blocks = list(read_encoder_blocks(path))
    assert [b.seq for b in blocks] == list(range(5))
    for block in blocks:
        _assert_block(block, block.seq, 50)


def test_summary_counts_and_metadata(sample_bag: Path) -> None:
    summary = bag_summary(sample_bag)
    assert summary['topics'] == {
        INFO_TOPIC: {'type': BENCH_INFO, 'count': 1, 'count_metadata_yaml': 1},
        ENCODER_TOPIC: {'type': ENCODER_BLOCK, 'count': 20, 'count_metadata_yaml': 20},
    }
    assert summary['message_count'] == 21
    assert summary['start_ns'] == T0_NS
    assert summary['end_ns'] == T0_NS + 19 * 10_000_000 + 1
    assert summary['duration_s'] == pytest.approx(0.19, abs=1e-9)
    assert summary['session'] == {'preset': 'wang2020-2kv'}
    assert summary['finalized'] is True
    assert summary['partial'] is False


def test_iter_messages_filters_topics_and_returns_stored_bytes(sample_bag: Path) -> None:
    msgs = [(t, ty, ts, bytes(d)) for t, ty, ts, d in iter_messages(sample_bag, [INFO_TOPIC])]
    assert msgs == [(INFO_TOPIC, BENCH_INFO, T0_NS, bench_info_cdr())]
    enc = [bytes(d) for _, _, _, d in iter_messages(sample_bag, [ENCODER_TOPIC])]
    assert enc == [encoder_cdr(seq, 100) for seq in range(20)]


def test_bench_info(sample_bag: Path, tmp_path: Path) -> None:
    info = read_bench_info(sample_bag)
    assert info is not None
    assert info.preset == 'wang2020-2kv'
    assert info.gear_ratio == 79.0
    assert info.mesh_labels == ('stage-2 mesh (52 f_w)',)
    bare = tmp_path / 'bare'
    with BagWriter(bare) as writer:
        writer.add_topic(ENCODER_TOPIC, ENCODER_BLOCK)
    assert read_bench_info(bare) is None


# ------------------------------------------------------------------ bad input
def test_missing_and_not_a_bag(tmp_path: Path) -> None:
    with pytest.raises(BagError, match='does not exist'):
        open_bag(tmp_path / 'nope')
    (tmp_path / 'dir').mkdir()
    with pytest.raises(BagError, match=r'no metadata\.yaml'):
        open_bag(tmp_path / 'dir')
    (tmp_path / 'x.mcap').write_bytes(b'')
    with pytest.raises(BagError, match=r'x\.mcap is empty'):
        open_bag(tmp_path / 'x.mcap')
    (tmp_path / 'y.mcap').write_bytes(b'not an mcap file')
    with pytest.raises(BagError, match=r'y\.mcap is not an MCAP file'):
        read_encoder_blocks(tmp_path / 'y.mcap')


def test_bad_metadata_yaml(sample_bag: Path) -> None:
    (sample_bag / 'metadata.yaml').write_text('rosbag2_bagfile_information: {version: 9}\n')
    with pytest.raises(BagError, match=r'metadata\.yaml is not rosbag2 metadata'):
        open_bag(sample_bag)
    (sample_bag / 'metadata.yaml').write_text(': : :\n  - [')
    with pytest.raises(BagError, match=r'Cannot read .*metadata\.yaml'):
        open_bag(sample_bag)


def test_missing_file(sample_bag: Path) -> None:
    for f in sample_bag.glob('*.mcap'):
        f.unlink()
    with pytest.raises(BagError, match='missing'):
        open_bag(sample_bag)


def test_empty_bag_and_no_encoder_topic(tmp_path: Path) -> None:
    empty = tmp_path / 'empty'
    with BagWriter(empty) as writer:
        writer.add_topic(ENCODER_TOPIC, ENCODER_BLOCK)
    assert list(read_encoder_blocks(empty)) == []
    assert bag_summary(empty)['message_count'] == 0
    info_only = tmp_path / 'info_only'
    with BagWriter(info_only) as writer:
        writer.add_topic(INFO_TOPIC, BENCH_INFO)
        writer.write(INFO_TOPIC, T0_NS, bench_info_cdr())
    with pytest.raises(BagError, match=f'info_only has no topic of type {ENCODER_BLOCK}'):
        read_encoder_blocks(info_only)


def test_ambiguous_and_wrong_topic(tmp_path: Path) -> None:
    bag = tmp_path / 'two'
    with BagWriter(bag) as writer:
        for topic in ('/a/bench/encoders', '/b/bench/encoders'):
            writer.add_topic(topic, ENCODER_BLOCK)
            writer.write(topic, T0_NS, encoder_cdr(0, 10))
        writer.add_topic(INFO_TOPIC, BENCH_INFO)
    with pytest.raises(BagError, match=r"several .*'/a/bench/encoders', '/b/bench/encoders'"):
        read_encoder_blocks(bag)
    assert [b.seq for b in read_encoder_blocks(bag, '/b/bench/encoders')] == [0]
    with pytest.raises(BagError, match=f"'{INFO_TOPIC}' has type '{BENCH_INFO}'"):
        read_encoder_blocks(bag, INFO_TOPIC)
    with pytest.raises(BagError, match="no topic '/c'"):
        read_encoder_blocks(bag, '/c')


def test_malformed_message_is_skipped_and_reported(tmp_path: Path) -> None:
    bag = tmp_path / 'bag'
    with BagWriter(bag) as writer:
        writer.add_topic(ENCODER_TOPIC, ENCODER_BLOCK)
        writer.write(ENCODER_TOPIC, T0_NS, encoder_cdr(0, 10))
        writer.write(ENCODER_TOPIC, T0_NS + 1, encoder_cdr(1, 10)[:40])  # cut short
        writer.write(ENCODER_TOPIC, T0_NS + 2, encoder_cdr(2, 10))
    stream = read_encoder_blocks(bag, strict=False)
    assert [b.seq for b in stream] == [0, 2]
    assert stream.partial
    assert 'message 1' in stream.problems[0]
    with pytest.raises(BagError, match=r'bag: /bench/encoders message 1 .*partial'):
        list(read_encoder_blocks(bag))


def test_truncated_file_reads_the_sound_part(sample_bag: Path) -> None:
    (file,) = sample_bag.glob('*.mcap')
    data = file.read_bytes()
    file.write_bytes(data[: len(data) * 2 // 3])
    stream = read_encoder_blocks(sample_bag, strict=False)
    seqs = [b.seq for b in stream]
    assert 0 < len(seqs) < 20
    assert seqs == list(range(len(seqs)))
    assert stream.partial
    assert any('truncated' in p and file.name in p for p in stream.problems)
    strict = read_encoder_blocks(sample_bag)
    got = []
    with pytest.raises(BagError, match=rf'{file.name}.*truncated.*partial'):
        got.extend(b.seq for b in strict)
    assert got == seqs  # the sound blocks came before the error
    summary = bag_summary(sample_bag)
    assert summary['partial']
    assert summary['topics'][ENCODER_TOPIC]['count'] == len(seqs)


def test_corrupt_chunk_is_reported(tmp_path: Path) -> None:
    bag = tmp_path / 'bag'
    write_sample_bag(bag, n_blocks=20, compression='none', chunk_size_bytes=4096)
    (file,) = bag.glob('*.mcap')
    data = bytearray(file.read_bytes())
    first = data.find(encoder_cdr(5, 100)[1000:1060])  # inside theta_in_rad of block 5
    assert first > 0
    data[first + 10] ^= 0xFF
    file.write_bytes(bytes(data))
    stream = read_encoder_blocks(bag, strict=False)
    seqs = [b.seq for b in stream]
    assert 5 not in seqs
    assert 0 < len(seqs) < 20
    assert any('CRC mismatch' in p and file.name in p for p in stream.problems)


def test_definition_change_is_refused(sample_bag: Path, tmp_path: Path) -> None:
    copy = tmp_path / 'copy'
    shutil.copytree(sample_bag, copy)
    meta = copy / 'metadata.yaml'
    ours = rv_te_typestore().hash_rihs01(ENCODER_BLOCK)
    assert ours in meta.read_text()
    meta.write_text(meta.read_text().replace(ours, 'RIHS01_' + '0' * 64))
    with pytest.raises(BagError, match='definition changed'):
        read_encoder_blocks(copy)


def test_the_definition_before_read_heads_is_read(sample_bag: Path, tmp_path: Path) -> None:
    """A bag whose metadata names the EncoderBlock hash of before issue 36 is read (older
    bags stay readable); its blocks carry no heads."""
    copy = tmp_path / 'copy'
    shutil.copytree(sample_bag, copy)
    meta = copy / 'metadata.yaml'
    ours = rv_te_typestore().hash_rihs01(ENCODER_BLOCK)
    meta.write_text(meta.read_text().replace(
        ours, 'RIHS01_1229821431777e90a6034a2640f4811afa7b42cdd596471fe57b8be9481d6c4d'))
    blocks = list(read_encoder_blocks(copy))
    assert blocks and blocks[0].out_head_ids == ()


def test_reads_a_bag_folder_written_by_rosbags(tmp_path: Path) -> None:
    """rosbags' own rosbag2 writer (metadata.yaml + <name>.mcap) is an independent layout."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    bag = tmp_path / 'rb'
    store = rv_te_typestore()
    with Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        conn = writer.add_connection(ENCODER_TOPIC, ENCODER_BLOCK, typestore=store)
        info = writer.add_connection(INFO_TOPIC, BENCH_INFO, typestore=store)
        writer.write(info, T0_NS, bench_info_cdr())
        for seq in range(8):
            writer.write(conn, T0_NS + seq, encoder_cdr(seq, 30))
    blocks = list(read_encoder_blocks(bag))
    assert [b.seq for b in blocks] == list(range(8))
    for block in blocks:
        _assert_block(block, block.seq, 30)
    assert read_bench_info(bag).preset == 'wang2020-2kv'  # type: ignore[union-attr]
    summary = bag_summary(bag)
    assert summary['topics'][ENCODER_TOPIC]['count'] == 8
    assert summary['finalized'] is None  # not written by BagWriter: state unknown


def test_empty_unlisted_split_file_does_not_hide_the_bag(tmp_path) -> None:
    """A recorder killed right after creating the next split file leaves it empty."""
    import shutil
    from pathlib import Path

    from rv_te_bench.io.bag_reader import read_encoder_blocks

    sample = Path(__file__).resolve().parents[2] / 'bags' / 'sample'
    bag = tmp_path / 'bag'
    shutil.copytree(sample, bag)
    (bag / 'sample_1.mcap').write_bytes(b'')
    assert sum(1 for _ in read_encoder_blocks(bag)) == 320   # 32 s at 1 kHz, blocks of 100
