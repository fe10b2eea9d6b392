"""BagWriter: bags other readers open (rosbags, mcap + mcap_ros2), crash tolerance, splits.

Expected values come from the messages rosbags serialised (tests/io/__init__.py), read back
through readers that share no code with the writer.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from mcap.reader import NonSeekingReader, make_reader
from mcap_ros2.decoder import DecoderFactory
from rosbags.highlevel import AnyReader

from rv_te_bench.errors import BagError
from rv_te_bench.io.bag_reader import bag_summary, read_encoder_blocks
from rv_te_bench.io.bag_writer import BagWriter
from rv_te_bench.io.msgdefs import ENCODER_BLOCK, full_msgdef
from tests.io.bag_fixtures import (
    ENCODER_TOPIC,
    INFO_TOPIC,
    T0_NS,
    block_arrays,
    encoder_cdr,
    write_sample_bag,
)

ROOT = Path(__file__).resolve().parents[2]


def _yaml_counts(bag: Path) -> dict[str, int]:
    info = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    return {t['topic_metadata']['name']: t['message_count']
            for t in info['topics_with_message_count']}


def _rosbags_seqs(bag: Path) -> list[int]:
    """Read with rosbags AnyReader using only the definitions stored in the bag."""
    with AnyReader([bag]) as reader:
        conns = [c for c in reader.connections if c.topic == ENCODER_TOPIC]
        out = []
        for conn, _, raw in reader.messages(connections=conns):
            msg = reader.deserialize(raw, conn.msgtype)
            ref = block_arrays(int(msg.seq), len(msg.theta_in_rad))
            np.testing.assert_array_equal(msg.theta_in_rad, ref['theta_in_rad'])
            out.append(int(msg.seq))
        return out


def _mcap_seqs(file: Path, *, seeking: bool) -> list[int]:
    """Read with mcap (+ mcap_ros2 decoding from the stored schema)."""
    with file.open('rb') as fh:
        reader = (make_reader(fh, decoder_factories=[DecoderFactory()]) if seeking else
                  NonSeekingReader(fh, decoder_factories=[DecoderFactory()]))
        out = []
        for _, channel, _, msg in reader.iter_decoded_messages():
            if channel.topic == ENCODER_TOPIC:
                ref = block_arrays(int(msg.seq), len(msg.theta_out_rad))
                np.testing.assert_array_equal(msg.theta_out_rad, ref['theta_out_rad'])
                out.append(int(msg.seq))
        return out


@pytest.mark.parametrize('compression', ['zstd', 'lz4', 'none'])
def test_round_trip_through_independent_readers(tmp_path: Path, compression: str) -> None:
    bag = tmp_path / 'bag'
    write_sample_bag(bag, n_blocks=30, compression=compression)
    assert _yaml_counts(bag) == {INFO_TOPIC: 1, ENCODER_TOPIC: 30}
    assert _rosbags_seqs(bag) == list(range(30))
    (file,) = sorted(bag.glob('*.mcap'))
    assert _mcap_seqs(file, seeking=True) == list(range(30))
    assert _mcap_seqs(file, seeking=False) == list(range(30))
    with file.open('rb') as fh:
        reader = make_reader(fh)
        summary = reader.get_summary()
        assert summary is not None
        assert summary.statistics.message_count == 31
        schema = next(s for s in summary.schemas.values() if s.name == ENCODER_BLOCK)
        assert schema.encoding == 'ros2msg'
        assert schema.data.decode() == full_msgdef(ENCODER_BLOCK)
        assert 'MSG: std_msgs/Header' in schema.data.decode()
        meta = {m.name: m.metadata for m in reader.iter_metadata()}
    assert meta['rv_te_session'] == {'preset': 'wang2020-2kv'}
    with AnyReader([bag]) as reader:
        info = next(c for c in reader.connections if c.topic == INFO_TOPIC)
        assert info.ext.offered_qos_profiles[0].durability.name == 'TRANSIENT_LOCAL'


def test_refuses_existing_path(tmp_path: Path) -> None:
    bag = tmp_path / 'bag'
    bag.mkdir()
    with pytest.raises(BagError, match='exists already'):
        BagWriter(bag)


def test_rejects_unknown_topic_and_bad_settings(tmp_path: Path) -> None:
    with pytest.raises(BagError, match='compression'):
        BagWriter(tmp_path / 'a', compression='bz2')  # type: ignore[arg-type]
    with BagWriter(tmp_path / 'b') as writer:
        with pytest.raises(BagError, match='was not added'):
            writer.write('/nope', 1, b'\x00\x01\x00\x00')
        writer.add_topic('/x', ENCODER_BLOCK)
        with pytest.raises(BagError, match='added to bag'):
            writer.add_topic('/x', ENCODER_BLOCK)


def test_time_based_flush_makes_messages_readable_while_open(tmp_path: Path) -> None:
    bag = tmp_path / 'bag'
    writer = write_sample_bag(bag, n_blocks=5, close=False, flush_interval_s=0.05)
    # 5 small messages: far below the chunk size, so only the interval can flush them.
    assert bag_summary(bag)['topics'][ENCODER_TOPIC]['count'] == 0
    time.sleep(0.06)
    assert writer.flush_if_due()
    assert _rosbags_seqs(bag) == list(range(5))
    assert _yaml_counts(bag)[ENCODER_TOPIC] == 5
    assert bag_summary(bag)['finalized'] is False
    writer.close()
    assert bag_summary(bag)['finalized'] is True


@pytest.mark.parametrize('split', [{'split_size_bytes': 20_000},
                                   {'split_duration_s': 0.05}])
def test_split_files_all_read_back(tmp_path: Path, split: dict) -> None:
    bag = tmp_path / 'bag'
    write_sample_bag(bag, n_blocks=40, compression='none', chunk_size_bytes=4096, **split)
    # in split order (bag_2 before bag_10)
    files = sorted(bag.glob('*.mcap'), key=lambda f: int(f.stem.rsplit('_', 1)[1]))
    assert len(files) > 2
    info = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert info['relative_file_paths'] == [f.name for f in files]
    assert sum(f['message_count'] for f in info['files']) == 41
    assert _rosbags_seqs(bag) == list(range(40))
    seqs = [s for f in files for s in _mcap_seqs(f, seeking=True)]
    assert seqs == list(range(40))
    assert [b.seq for b in read_encoder_blocks(bag)] == list(range(40))


_KILLED_WRITER = r'''
import sys, time
from tests.io.bag_fixtures import write_sample_bag, encoder_cdr, ENCODER_TOPIC, T0_NS
from pathlib import Path
w = write_sample_bag(Path(sys.argv[1]), n_blocks=0, close=False, flush_interval_s=0.2)
seq = 0
t0 = time.monotonic()
while True:
    w.write(ENCODER_TOPIC, T0_NS + seq * 10_000_000, encoder_cdr(seq, 100))
    print(seq, flush=True)
    seq += 1
    time.sleep(max(0.0, t0 + seq / 100.0 - time.monotonic()))
'''


def test_sigkilled_writer_leaves_a_readable_bag(tmp_path: Path) -> None:
    bag = tmp_path / 'bag'
    env = dict(os.environ)
    env.pop('_ROS_WHEELS_BOOTSTRAP_COMPLETE', None)
    env['PYTHONPATH'] = str(ROOT)
    proc = subprocess.Popen([sys.executable, '-c', _KILLED_WRITER, str(bag)], cwd=ROOT,
                            env=env, stdout=subprocess.PIPE, text=True)
    try:
        last = -1
        assert proc.stdout is not None
        while last < 150:  # about 1.5 s of writing at 100 msg/s
            line = proc.stdout.readline()
            assert line, 'writer process died'
            last = int(line)
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
    # Everything but at most the last flush interval (0.2 s = 20 messages, + margin for
    # the scheduler on a loaded machine: 1 s = 100 messages) must be readable.
    ours = [b.seq for b in read_encoder_blocks(bag)]
    assert ours == list(range(len(ours)))
    assert len(ours) >= last + 1 - 100
    assert _rosbags_seqs(bag) == ours
    (file,) = sorted(bag.glob('*.mcap'))
    assert _mcap_seqs(file, seeking=False) == ours
    assert _mcap_seqs(file, seeking=True) == ours
    assert _yaml_counts(bag)[ENCODER_TOPIC] <= len(ours)
    summary = bag_summary(bag)
    assert summary['finalized'] is False
    assert summary['partial'] is False
    assert summary['session'] == {'preset': 'wang2020-2kv'}


def test_writer_does_not_decode(tmp_path: Path) -> None:
    """Bytes go in and come out unchanged, whatever they hold (raw path, no decode)."""
    payload = encoder_cdr(7, 10)
    with BagWriter(tmp_path / 'bag', compression='none') as writer:
        writer.add_topic(ENCODER_TOPIC, ENCODER_BLOCK)
        writer.write(ENCODER_TOPIC, T0_NS, payload)
        writer.write(ENCODER_TOPIC, T0_NS + 1, b'\x00\x01\x00\x00garbage')
    with AnyReader([tmp_path / 'bag']) as reader:
        raws = [bytes(raw) for _, _, raw in reader.messages()]
    assert raws == [payload, b'\x00\x01\x00\x00garbage']
