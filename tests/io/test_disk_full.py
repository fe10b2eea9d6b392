"""A disk that fills while recording (issue #16 item 1): the bag stays readable, counts are
what is on disk, the loss is stated, recording resumes when space returns.

Two disks: ``SmallDisk`` (tests/io/faults.py, fault injection, no mount) and a real small
tmpfs (needs root; CI runs as root). Expected values come from what the test itself wrote
(sequence numbers and log times it chose) and from readers that share no code with the
writer: rosbags AnyReader and mcap (seeking and streaming, decoded with mcap_ros2).
"""

from __future__ import annotations

import contextlib
import os
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from mcap.reader import NonSeekingReader, make_reader
from mcap_ros2.decoder import DecoderFactory
from rosbags.highlevel import AnyReader

from rv_te_bench.core.offline import analyze_blocks
from rv_te_bench.core.orders import OrderSet
from rv_te_bench.core.stream_records import TeAnalysisConfig
from rv_te_bench.io.bag_reader import bag_summary, read_encoder_blocks
from rv_te_bench.io.bag_writer import RESERVE_NAME, BagWriter
from tests.io.bag_fixtures import ENCODER_TOPIC, INFO_TOPIC, block_arrays
from tests.io.conftest import BLOCK, FLUSH_S, block, log_ns, start_bag, write_until_stalled
from tests.io.faults import SmallDisk, tmpfs

pytestmark = pytest.mark.timeout(60)


def metadata(bag: Path) -> dict:
    return yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']


def read_back(bag: Path, per_file: dict[str, list[int]] | None = None) -> list[int]:
    """EncoderBlock seqs of the bag, the same from every reader, content checked
    (``per_file``: filled with each file's seqs)."""
    with AnyReader([bag]) as reader:
        conns = [c for c in reader.connections if c.topic == ENCODER_TOPIC]
        by_rosbags = []
        for conn, t_ns, raw in reader.messages(connections=conns):
            msg = reader.deserialize(raw, conn.msgtype)
            np.testing.assert_array_equal(msg.theta_in_rad,
                                          block_arrays(int(msg.seq), BLOCK)['theta_in_rad'])
            assert t_ns == log_ns(int(msg.seq))
            by_rosbags.append(int(msg.seq))
    files = [bag / name for name in metadata(bag)['relative_file_paths']]
    assert sorted(bag.glob('*.mcap')) == sorted(files)
    by_mcap: dict[bool, list[int]] = {True: [], False: []}
    for file in files:
        with file.open('rb') as fh:
            summary = make_reader(fh).get_summary()
            assert summary is not None, f'{file.name} has no summary'
            offsets = [ci.chunk_start_offset for ci in summary.chunk_indexes]
            assert len(offsets) == len(set(offsets)), 'a chunk indexed twice'
            end = file.stat().st_size
            assert all(ci.chunk_start_offset + ci.chunk_length < end
                       for ci in summary.chunk_indexes)
            n_stat = summary.statistics.message_count
        for seeking in (True, False):
            with file.open('rb') as fh:
                reader = (make_reader(fh, decoder_factories=[DecoderFactory()]) if seeking
                          else NonSeekingReader(fh, decoder_factories=[DecoderFactory()]))
                n = 0
                for _, channel, _, msg in reader.iter_decoded_messages():
                    n += 1
                    if channel.topic == ENCODER_TOPIC:
                        np.testing.assert_array_equal(
                            msg.theta_out_rad,
                            block_arrays(int(msg.seq), BLOCK)['theta_out_rad'])
                        by_mcap[seeking].append(int(msg.seq))
                        if per_file is not None and seeking:
                            per_file.setdefault(file.name, []).append(int(msg.seq))
            assert n == n_stat, f'{file.name}: {n} messages, statistics say {n_stat}'
    ours = [b.seq for b in read_encoder_blocks(bag)]
    assert by_rosbags == by_mcap[True] == by_mcap[False] == ours
    return ours


def check_yaml_counts(bag: Path, writer: BagWriter) -> dict:
    info = metadata(bag)
    counts = {t['topic_metadata']['name']: t['message_count']
              for t in info['topics_with_message_count']}
    assert counts == writer.counts
    assert info['custom_data']['rv_te_bench.writer_state'] == 'closed'
    assert not (bag / RESERVE_NAME).exists()
    assert not (bag / '.metadata.yaml.tmp').exists()
    return info


def gaps_in_yaml(info: dict) -> list[dict]:
    return yaml.safe_load(info['custom_data']['rv_te_bench.write_gaps'])


# ------------------------------------------------------------------ fault injection
def test_disk_full_once_bag_cut_back_and_closed(tmp_path: Path) -> None:
    """The disk fills and stays full: everything up to the last complete chunk is read by
    every reader, the rest (held in memory, then the close) is counted lost exactly."""
    disk = SmallDisk(1_000_000)
    bag = tmp_path / 'bag'
    writer, events = start_bag(bag, storage=disk)
    n_sent = write_until_stalled(writer) + 60
    for seq in range(n_sent - 60, n_sent):
        writer.write(ENCODER_TOPIC, log_ns(seq), block(seq))
    assert writer.stalled
    writer.close()
    seqs = read_back(bag)
    k = len(seqs)
    assert seqs == list(range(k))
    assert 100 < k < n_sent - 60
    assert writer.counts == {INFO_TOPIC: 1, ENCODER_TOPIC: k}
    assert writer.lost == {INFO_TOPIC: 0, ENCODER_TOPIC: n_sent - k}
    assert disk.failed_writes + disk.short_writes >= 1
    info = check_yaml_counts(bag, writer)
    assert info['custom_data']['rv_te_bench.lost_messages'] == str(n_sent - k)
    (gap,) = gaps_in_yaml(info)
    assert gap['lost'] == {ENCODER_TOPIC: n_sent - k}
    assert gap['lost_log_time_ns'] == [log_ns(k), log_ns(n_sent - 1)]
    assert gap['resumed_utc'] is None
    assert gap['error'] == os.strerror(28)
    assert len(info['relative_file_paths']) == 1
    assert any('No space left on device' in e for e in events)
    summary = bag_summary(bag)
    assert summary['finalized'] is True
    assert summary['partial'] is False


@pytest.mark.parametrize('stall_buffer_bytes', [20_000, 5_000, 0])
def test_disk_full_for_a_while_resumes_in_a_new_file(tmp_path: Path,
                                                     stall_buffer_bytes: int) -> None:
    """Space returns: recording goes on in bag_1.mcap with the messages held in memory
    first (the oldest, up to the buffer; 5 kB holds part of the failed 10 kB chunk); what
    did not fit is one contiguous gap of sequence numbers, stated in metadata.yaml, in the
    new file and seen by the analysis."""
    disk = SmallDisk(1_000_000)
    bag = tmp_path / 'bag'
    writer, events = start_bag(bag, storage=disk, stall_buffer_bytes=stall_buffer_bytes)
    full_at = write_until_stalled(writer)
    for seq in range(full_at, full_at + 40):     # while the disk is full
        writer.write(ENCODER_TOPIC, log_ns(seq), block(seq))
    assert writer.stalled
    disk.capacity_bytes = 3_000_000               # space returns
    time.sleep(2 * FLUSH_S)
    n_sent = full_at + 40 + 100
    for seq in range(full_at + 40, n_sent):
        writer.write(ENCODER_TOPIC, log_ns(seq), block(seq))
        if seq == full_at + 45:
            assert not writer.stalled
    writer.close()
    per_file: dict[str, list[int]] = {}
    seqs = read_back(bag, per_file)
    a = len(per_file['bag_0.mcap'])               # bag_0 was cut back after block a - 1
    assert per_file['bag_0.mcap'] == list(range(a))
    missing = sorted(set(range(n_sent)) - set(seqs))
    first, last = missing[0], missing[-1]
    assert missing == list(range(first, last + 1))          # one contiguous gap
    assert per_file['bag_1.mcap'] == [*range(a, first), *range(last + 1, n_sent)]
    record_bytes = 31 + len(block(0))             # message record header + CDR
    assert first - a == stall_buffer_bytes // record_bytes  # the oldest held, in order
    assert full_at - 3 <= a <= full_at            # the failed chunk: at most 3 blocks
    assert last < full_at + 40                    # nothing lost after space returned
    assert writer.counts[ENCODER_TOPIC] == len(seqs) == n_sent - len(missing)
    assert writer.lost[ENCODER_TOPIC] == len(missing)
    info = check_yaml_counts(bag, writer)
    assert info['relative_file_paths'] == ['bag_0.mcap', 'bag_1.mcap']
    (gap,) = gaps_in_yaml(info)
    assert gap['lost'] == {ENCODER_TOPIC: len(missing)}
    assert gap['lost_log_time_ns'] == [log_ns(first), log_ns(last)]
    assert gap['held_and_written'] == first - a
    assert gap['file_before'] == 'bag_0.mcap'
    assert gap['file_after'] == 'bag_1.mcap'
    assert gap['resumed_utc'] is not None
    with (bag / 'bag_1.mcap').open('rb') as fh:
        records = {m.name: m.metadata for m in make_reader(fh).iter_metadata()}
    assert yaml.safe_load(records['rv_te_write_gap']['lost']) == {ENCODER_TOPIC: len(missing)}
    assert any('writing again' in e for e in events)
    # the offline analysis sees exactly this gap in the encoder stream
    config = TeAnalysisConfig(orders=OrderSet(gear_ratio=79.0, crank_per_output=25.0),
                              compute_spectrum=False)
    result = analyze_blocks(read_encoder_blocks(bag), config)
    assert [(g.kind, g.seq) for g in result.gaps] == [('seq_jump', last + 1)]
    assert f'expected seq {first}, got {last + 1}' in result.gaps[0].detail


def test_disk_full_nothing_lost_when_memory_holds_the_outage(tmp_path: Path) -> None:
    disk = SmallDisk(1_000_000)
    bag = tmp_path / 'bag'
    writer, _ = start_bag(bag, storage=disk)   # 64 MB held in memory by default
    full_at = write_until_stalled(writer)
    for seq in range(full_at, full_at + 40):
        writer.write(ENCODER_TOPIC, log_ns(seq), block(seq))
    disk.capacity_bytes = 3_000_000
    time.sleep(2 * FLUSH_S)
    writer.close()
    assert read_back(bag) == list(range(full_at + 40))
    assert writer.lost_messages == 0
    (gap,) = gaps_in_yaml(check_yaml_counts(bag, writer))
    assert gap['lost_messages'] == 0
    assert gap['held_and_written'] >= 40


def test_disk_full_twice_two_gaps_three_files(tmp_path: Path) -> None:
    disk = SmallDisk(1_000_000)
    bag = tmp_path / 'bag'
    writer, _ = start_bag(bag, storage=disk, stall_buffer_bytes=0)
    seq = 0
    for _ in range(2):
        seq = write_until_stalled(writer, seq)
        for seq in range(seq, seq + 10):  # noqa: B020
            writer.write(ENCODER_TOPIC, log_ns(seq), block(seq))
        disk.capacity_bytes += 1_000_000
        time.sleep(2 * FLUSH_S)
        seq += 1
        writer.write(ENCODER_TOPIC, log_ns(seq), block(seq))
        assert not writer.stalled
        seq += 1
    writer.close()
    seqs = read_back(bag)
    info = check_yaml_counts(bag, writer)
    assert info['relative_file_paths'] == ['bag_0.mcap', 'bag_1.mcap', 'bag_2.mcap']
    gaps = gaps_in_yaml(info)
    assert len(gaps) == 2
    assert sum(g['lost_messages'] for g in gaps) == seq - len(seqs) == writer.lost_messages


def test_no_room_even_for_the_summary_leaves_a_scannable_file(tmp_path: Path) -> None:
    """The reserve was taken by someone else: the file is closed with the trailer only
    (no summary); rosbags and the streaming mcap reader still read every complete chunk."""

    class Thief(SmallDisk):
        def reserve(self, path: Path, size: int) -> None:
            super().reserve(path, size)
            if size < 100_000:                   # the writer shrinks it: space is given
                self.capacity_bytes = self.used_bytes   # back, and someone takes it

    disk = Thief(1_000_000)
    bag = tmp_path / 'bag'
    writer, events = start_bag(bag, storage=disk, stall_buffer_bytes=0)
    n = write_until_stalled(writer)
    with contextlib.suppress(Exception):
        writer.close()
    assert any('no room for the summary' in e for e in events)
    with AnyReader([bag]) as reader:
        seqs = [int(reader.deserialize(raw, c.msgtype).seq)
                for c, _, raw in reader.messages() if c.topic == ENCODER_TOPIC]
    with (bag / 'bag_0.mcap').open('rb') as fh:
        streamed = [int(m.seq) for _, ch, _, m in NonSeekingReader(
            fh, decoder_factories=[DecoderFactory()]).iter_decoded_messages()
            if ch.topic == ENCODER_TOPIC]
    assert seqs == streamed == list(range(len(seqs)))
    assert 0 < len(seqs) < n
    assert writer.counts[ENCODER_TOPIC] == len(seqs)


# ------------------------------------------------------------------ a real tmpfs
def test_tmpfs_full_once(tmp_path: Path) -> None:
    with tmpfs(tmp_path / 'mnt', 1 << 20) as mnt:
        bag = mnt / 'bag'
        writer, events = start_bag(bag)
        n_sent = write_until_stalled(writer) + 30
        for seq in range(n_sent - 30, n_sent):
            writer.write(ENCODER_TOPIC, log_ns(seq), block(seq))
        writer.close()
        seqs = read_back(bag)
        assert seqs == list(range(len(seqs)))
        assert len(seqs) > 100
        assert writer.counts[ENCODER_TOPIC] == len(seqs)
        assert writer.lost[ENCODER_TOPIC] == n_sent - len(seqs)
        (gap,) = gaps_in_yaml(check_yaml_counts(bag, writer))
        assert gap['lost_log_time_ns'] == [log_ns(len(seqs)), log_ns(n_sent - 1)]
        assert any('No space left on device' in e for e in events)


def test_tmpfs_full_for_a_while(tmp_path: Path) -> None:
    with tmpfs(tmp_path / 'mnt', 2 << 20) as mnt:
        ballast = mnt / 'ballast'
        ballast.write_bytes(bytes(1 << 20))
        bag = mnt / 'bag'
        writer, _ = start_bag(bag, stall_buffer_bytes=20_000)
        full_at = write_until_stalled(writer)
        for seq in range(full_at, full_at + 40):
            writer.write(ENCODER_TOPIC, log_ns(seq), block(seq))
        ballast.unlink()                              # space returns
        time.sleep(2 * FLUSH_S)
        n_sent = full_at + 40 + 60
        for seq in range(full_at + 40, n_sent):
            writer.write(ENCODER_TOPIC, log_ns(seq), block(seq))
        writer.close()
        seqs = read_back(bag)
        missing = sorted(set(range(n_sent)) - set(seqs))
        assert missing == list(range(missing[0], missing[-1] + 1))
        assert writer.lost[ENCODER_TOPIC] == len(missing) > 0
        info = check_yaml_counts(bag, writer)
        assert info['relative_file_paths'] == ['bag_0.mcap', 'bag_1.mcap']
        (gap,) = gaps_in_yaml(info)
        assert gap['lost_log_time_ns'] == [log_ns(missing[0]), log_ns(missing[-1])]


class _Killed(BaseException):
    """The process dies here (a SIGKILL, as seen by the files)."""


def test_killed_while_resuming_the_new_file_is_already_listed(tmp_path: Path) -> None:
    """metadata.yaml names the new file before the held messages go into it (readers skip
    unlisted files): a recorder killed while writing them leaves a bag whose files are all
    listed and read."""

    class DiesOnFirstMessages(SmallDisk):
        def pwritev(self, fd: int, parts: list, offset: int) -> int:  # type: ignore[override]
            if self._paths[fd].endswith('bag_1.mcap') and offset > 0:
                raise _Killed
            return super().pwritev(fd, parts, offset)

    disk = DiesOnFirstMessages(1_000_000)
    bag = tmp_path / 'bag'
    writer, _ = start_bag(bag, storage=disk)
    full_at = write_until_stalled(writer)
    for seq in range(full_at, full_at + 20):
        writer.write(ENCODER_TOPIC, log_ns(seq), block(seq))
    disk.capacity_bytes = 3_000_000
    time.sleep(2 * FLUSH_S)
    with pytest.raises(_Killed):
        writer.flush_if_due()                 # resumes: dies writing the held blocks
    assert metadata(bag)['relative_file_paths'] == ['bag_0.mcap', 'bag_1.mcap']
    with AnyReader([bag]) as reader:
        seqs = [int(reader.deserialize(raw, c.msgtype).seq)
                for c, _, raw in reader.messages() if c.topic == ENCODER_TOPIC]
    assert seqs == list(range(writer.counts[ENCODER_TOPIC]))
