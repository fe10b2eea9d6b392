"""Fixtures and shared helpers of the node tests.

The helpers (``make_block``, ``read_back``, ``cli_process``) are used by several test files
(the recorder, its disk-full and the replay tests): they live here so that no test file
imports another. ROS and the bag readers are imported inside them, so that collecting the
suite without rclpy still works.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pytest
import yaml

from tests.io.bag_fixtures import block_arrays

if TYPE_CHECKING:
    from rv_te_msgs.msg import EncoderBlock

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture
def graph(ros_context):
    """(context, single-threaded executor, add): nodes given to ``add`` spin on the executor
    and are destroyed at the end, the last added first."""
    from rclpy.executors import SingleThreadedExecutor

    nodes = []
    ex = SingleThreadedExecutor(context=ros_context)

    def add(node):
        nodes.append(node)
        ex.add_node(node)
        return node

    yield ros_context, ex, add
    ex.shutdown()
    for n in reversed(nodes):
        n.destroy_node()


def make_block(seq: int, n: int = 100) -> EncoderBlock:
    """EncoderBlock ``seq`` of ``n`` samples with the contents of ``block_arrays``."""
    from rv_te_msgs.msg import EncoderBlock

    msg = EncoderBlock()
    msg.header.frame_id = 'bench0'
    msg.header.stamp.sec = 1000 + seq
    msg.seq = seq
    msg.sample_rate_hz = 10_000.0
    arrays = block_arrays(seq, n)
    msg.time_offset_s = arrays['time_offset_s']
    msg.theta_in_rad = arrays['theta_in_rad']
    msg.theta_out_rad = arrays['theta_out_rad']
    msg.torque_out_nm = arrays['torque_out_nm']
    return msg


def read_back(bag: Path, topic: str) -> tuple[list[int], list[int], dict[str, int]]:
    """Encoder seqs by rosbags and by mcap_ros2 (content checked), and metadata.yaml counts."""
    from mcap.reader import NonSeekingReader
    from mcap_ros2.decoder import DecoderFactory
    from rosbags.highlevel import AnyReader

    with AnyReader([bag]) as reader:
        rb = []
        for conn, _, raw in reader.messages(
                connections=[c for c in reader.connections if c.topic == topic]):
            msg = reader.deserialize(raw, conn.msgtype)
            ref = block_arrays(int(msg.seq), len(msg.theta_in_rad))
            for key in ('time_offset_s', 'theta_in_rad', 'theta_out_rad', 'torque_out_nm'):
                np.testing.assert_array_equal(getattr(msg, key), ref[key])
            rb.append(int(msg.seq))
    mc = []
    for file in sorted(bag.glob('*.mcap')):
        with file.open('rb') as fh:
            for _, channel, _, msg in NonSeekingReader(
                    fh, decoder_factories=[DecoderFactory()]).iter_decoded_messages():
                if channel.topic == topic:
                    np.testing.assert_array_equal(
                        msg.theta_out_rad, block_arrays(msg.seq, 100)['theta_out_rad'])
                    mc.append(int(msg.seq))
    info = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    counts = {t['topic_metadata']['name']: t['message_count']
              for t in info['topics_with_message_count']}
    return rb, mc, counts


CLI = r'''
import argparse, sys
from rv_te_bench.cli import record, replay
parser = argparse.ArgumentParser(prog='rv-te')
sub = parser.add_subparsers(required=True)
record.register(sub)
replay.register(sub)
args = parser.parse_args(sys.argv[1:])
sys.exit(args.func(args))
'''


def cli_process(argv: list[str], domain: int) -> subprocess.Popen[str]:
    """``rv-te <argv>`` in a child process (cli/main.py belongs to the integrator)."""
    env = dict(os.environ)
    env.pop('_ROS_WHEELS_BOOTSTRAP_COMPLETE', None)
    env['ROS_DOMAIN_ID'] = str(domain)
    env['PYTHONPATH'] = str(ROOT)
    return subprocess.Popen([sys.executable, '-c', CLI, *argv], cwd=ROOT, env=env, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
