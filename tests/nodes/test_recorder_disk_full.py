"""`rv-te record` and `rv-te launch` on a disk that fills (issue #16 item 1): the command
exits non-zero and says how much was lost; the counts it prints are what independent
readers find in the bag; metadata.yaml is final. Needs root for a real tmpfs (CI runs as
root); the writer's logic without a mount is in tests/io/test_disk_full.py."""

from __future__ import annotations

import math
import os
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
import yaml

pytestmark = [pytest.mark.ros, pytest.mark.timeout(240)]

rclpy = pytest.importorskip('rclpy')

from mcap.reader import NonSeekingReader, make_reader  # noqa: E402
from mcap_ros2.decoder import DecoderFactory  # noqa: E402
from rclpy.experimental import EventsExecutor  # noqa: E402
from rosbags.highlevel import AnyReader  # noqa: E402
from rv_te_msgs.msg import EncoderBlock  # noqa: E402

from rv_te_bench.io.msgdefs import rv_te_typestore  # noqa: E402
from rv_te_bench.nodes import qos  # noqa: E402
from tests.io.faults import tmpfs  # noqa: E402
from tests.nodes.conftest import ROOT, cli_process, make_block, read_back  # noqa: E402
from tests.nodes.rosutil import spin_until  # noqa: E402


def _metadata(bag: Path) -> dict[str, Any]:
    return yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']


def _counts_by_readers(bag: Path) -> dict[str, int]:
    """Messages per topic: rosbags and mcap (seeking and streaming) must agree."""
    with AnyReader([bag], default_typestore=rv_te_typestore()) as reader:
        by_rosbags: dict[str, int] = {}
        for conn, _, _ in reader.messages():
            by_rosbags[conn.topic] = by_rosbags.get(conn.topic, 0) + 1
    for seeking in (True, False):
        by_mcap: dict[str, int] = {}
        for name in _metadata(bag)['relative_file_paths']:
            with (bag / name).open('rb') as fh:
                reader = (make_reader(fh, decoder_factories=[DecoderFactory()]) if seeking
                          else NonSeekingReader(fh, decoder_factories=[DecoderFactory()]))
                for _, channel, _ in reader.iter_messages():
                    by_mcap[channel.topic] = by_mcap.get(channel.topic, 0) + 1
        assert by_mcap == by_rosbags, (seeking, by_mcap, by_rosbags)
    return by_rosbags


def test_cli_record_disk_full_exits_1_and_says_what_was_lost(
        ros_context: Any, ros_domain_id: int, tmp_path: Path) -> None:
    n_blocks = 400                                   # 3.4 kB each: 1.36 MB > the 1 MiB disk
    ns = f'/full_{os.getpid()}'
    topic = f'{ns}/bench/encoders'
    with tmpfs(tmp_path / 'mnt', 1 << 20) as mnt:
        pub_node = rclpy.create_node('full_pub', context=ros_context)
        pub = pub_node.create_publisher(EncoderBlock, topic, qos.ENCODER_QOS)
        executor = EventsExecutor(context=ros_context)
        executor.add_node(pub_node)
        proc = cli_process(['record', '--out', str(mnt), '--name', 'bag', '--namespace', ns,
                            '--topics', 'bench/encoders', '--compression', 'none',
                            '--flush-interval', '0.2', '--duration', '12'], ros_domain_id)
        try:
            subscribed = spin_until(executor, lambda: pub.get_subscription_count() >= 1
                                    or proc.poll() is not None, 60.0)
            if not subscribed or proc.poll() is not None:
                proc.kill()
                _, err = proc.communicate(timeout=10)
                pytest.fail(f'recorder did not subscribe (exit {proc.returncode}): '
                            f'{err[-2000:]}')
            for seq in range(n_blocks):              # 100 blocks/s
                pub.publish(make_block(seq))
                executor.spin_once(timeout_sec=0.01)
            out, err = proc.communicate(timeout=60)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
            pub_node.destroy_node()
            executor.shutdown()
        bag = mnt / 'bag'
        assert proc.returncode == 1, (out, err)
        rb, mc, yaml_counts = read_back(bag, topic)
        k = len(rb)
        assert rb == mc == list(range(k))            # cut back to a complete prefix
        assert 50 < k < n_blocks
        assert f'{topic}: {k} messages ({n_blocks - k} lost: disk full)' in out
        assert yaml_counts[topic] == k
        errors = [line for line in err.splitlines() if line.startswith('ERROR:')]
        assert errors == [f'ERROR: {n_blocks - k} messages received could not be written to '
                          f'{bag} (disk full); the bag holds the {k} listed above']
        info = _metadata(bag)
        assert info['custom_data']['rv_te_bench.writer_state'] == 'closed'
        assert info['custom_data']['rv_te_bench.lost_messages'] == str(n_blocks - k)
        assert _counts_by_readers(bag) == {topic: k}


def test_launch_disk_full_exits_1_with_the_loss(tmp_path: Path, ros_domain_id: int) -> None:
    """The default session (2 output revolutions at 1 kHz, blocks of 100) on a 400 KiB disk."""
    revs, fs_hz, block = 2.0, 1000.0, 100
    # the bench publishes revs * i / n_in + one sample (i = 79, 300 rpm = 5 rev/s)
    n_blocks = math.ceil((revs * 79 / 5.0 * fs_hz + 1) / block)
    with tmpfs(tmp_path / 'mnt', 400 << 10) as mnt:
        env = dict(os.environ)
        env.pop('_ROS_WHEELS_BOOTSTRAP_COMPLETE', None)
        env['ROS_DOMAIN_ID'] = str(ros_domain_id)
        env['PYTHONPATH'] = str(ROOT)
        cmd = [sys.executable, '-m', 'rv_te_bench.cli.main', 'launch', '--default',
               '--namespace', f'full_{os.getpid()}', '--nodes', 'bench,te_node,recorder',
               '--param', f'recorder.output_dir={mnt}', '--param', 'recorder.bag_name=bag',
               '--param', 'recorder.flush_interval_s=0.2',
               '--param', 'recorder.compression=none']
        done = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True,
                              timeout=200, check=False)
        bag = mnt / 'bag'
        assert done.returncode == 1, done.stderr[-3000:]
        launch_lines = [ln for ln in done.stderr.splitlines() if ln.startswith('[launch]')]
        on_disk = re.search(rf'\[launch\] bag {re.escape(str(bag))}: (\d+) messages on disk',
                            done.stderr)
        lost = re.search(r'\[launch\] ERROR: recording lost (\d+) messages \((.*)\): the disk '
                         r'was full', done.stderr)
        assert on_disk and lost, launch_lines
        counts = _counts_by_readers(bag)
        assert sum(counts.values()) == int(on_disk.group(1))
        enc = f'/full_{os.getpid()}/bench/encoders'
        lost_enc = int(re.search(rf'{re.escape(enc)}: (\d+)', lost.group(2)).group(1))
        assert counts[enc] + lost_enc == n_blocks
        assert "[launch] node 'recorder' ended with code 1" in launch_lines
        info = _metadata(bag)
        assert info['custom_data']['rv_te_bench.writer_state'] == 'closed'
        assert int(info['custom_data']['rv_te_bench.lost_messages']) == int(lost.group(1))


def test_single_process_launch_disk_full_exits_1(tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    from rv_te_bench.cli.main import main

    with tmpfs(tmp_path / 'mnt', 300 << 10) as mnt:
        code = main(['launch', '--default', '--single-process', '--nodes', 'bench,recorder',
                     '--namespace', f'sp_{os.getpid()}',
                     '--param', f'recorder.output_dir={mnt}', '--param', 'recorder.bag_name=bag',
                     '--param', 'recorder.flush_interval_s=0.2',
                     '--param', 'recorder.compression=none', '--param', 'bench.speed_factor=0.0'])
        err = capsys.readouterr().err
        assert code == 1, err[-3000:]
        on_disk = re.search(r'\[launch\] bag .*/bag: (\d+) messages on disk', err)
        assert on_disk, err[-3000:]
        assert re.search(r'\[launch\] ERROR: recording lost \d+ messages', err)
        assert sum(_counts_by_readers(mnt / 'bag').values()) == int(on_disk.group(1))
