"""Bag I/O benchmarks: write MB/s (BagWriter vs raw mcap.writer vs rosbags Writer), read
samples/s (read_encoder_blocks vs a bare rosbags AnyReader read + deserialise), and a
recorded 10 kHz session (100 blocks/s of 100 samples) for loss.

Usage:
  .venv/bin/python benchmarks/bench_io.py                 # all, 60 s session
  .venv/bin/python benchmarks/bench_io.py --session-s 0   # no ROS session
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from mcap.writer import CompressionType  # noqa: E402
from mcap.writer import Writer as McapWriter  # noqa: E402
from rosbags.highlevel import AnyReader  # noqa: E402
from rosbags.rosbag2 import StoragePlugin  # noqa: E402
from rosbags.rosbag2 import Writer as RosbagsWriter  # noqa: E402

from rv_te_bench.io.bag_reader import read_encoder_blocks  # noqa: E402
from rv_te_bench.io.bag_writer import BagWriter  # noqa: E402
from rv_te_bench.io.msgdefs import ENCODER_BLOCK, full_msgdef, rv_te_typestore  # noqa: E402
from tests.io.bag_fixtures import encoder_cdr  # noqa: E402

TOPIC = '/bench/encoders'


def _best_of(fn, repeats: int = 3) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def bench_write(tmp: Path, n_msgs: int, block: int) -> list[tuple[str, float, float]]:
    payloads = [encoder_cdr(seq, block) for seq in range(50)]
    total = sum(len(payloads[i % 50]) for i in range(n_msgs))
    rows = []
    comp_map = {'zstd': CompressionType.ZSTD, 'lz4': CompressionType.LZ4,
                'none': CompressionType.NONE}
    for comp in ('zstd', 'lz4', 'none'):
        def ours(comp: str = comp) -> None:
            path = tmp / f'ours_{comp}_{time.perf_counter_ns()}'
            with BagWriter(path, compression=comp) as w:  # type: ignore[arg-type]
                w.add_topic(TOPIC, ENCODER_BLOCK)
                for i in range(n_msgs):
                    w.write(TOPIC, i * 10_000_000, payloads[i % 50])

        def raw_mcap(comp: str = comp) -> None:
            path = tmp / f'mcap_{comp}_{time.perf_counter_ns()}.mcap'
            with path.open('wb') as fh:
                w = McapWriter(fh, compression=comp_map[comp])
                w.start(profile='ros2')
                sid = w.register_schema(ENCODER_BLOCK, 'ros2msg',
                                        full_msgdef(ENCODER_BLOCK).encode())
                cid = w.register_channel(TOPIC, 'cdr', sid)
                for i in range(n_msgs):
                    w.add_message(cid, i * 10_000_000, payloads[i % 50], i * 10_000_000)
                w.finish()

        t_ours, t_raw = _best_of(ours), _best_of(raw_mcap)
        rows.append((f'BagWriter {comp}', total / t_ours / 1e6, n_msgs / t_ours))
        rows.append((f'mcap.writer {comp}', total / t_raw / 1e6, n_msgs / t_raw))

    store = rv_te_typestore()

    def rosbags_writer() -> None:
        path = tmp / f'rosbags_{time.perf_counter_ns()}'
        with RosbagsWriter(path, version=9, storage_plugin=StoragePlugin.MCAP) as w:
            conn = w.add_connection(TOPIC, ENCODER_BLOCK, typestore=store)
            for i in range(n_msgs):
                w.write(conn, i * 10_000_000, payloads[i % 50])

    t = _best_of(rosbags_writer)
    rows.append(('rosbags Writer (no compression, 1 MiB chunks)', total / t / 1e6, n_msgs / t))
    return rows


def bench_read(tmp: Path, n_msgs: int, block: int) -> list[tuple[str, float, float]]:
    bag = tmp / 'read_bag'
    with BagWriter(bag, compression='zstd') as w:
        w.add_topic(TOPIC, ENCODER_BLOCK)
        for i in range(n_msgs):
            w.write(TOPIC, i * 10_000_000, encoder_cdr(i, block))
    samples = n_msgs * block

    def ours() -> None:
        n = 0
        for b in read_encoder_blocks(bag):
            n += b.theta_in_rad.size
        assert n == samples

    def rosbags_bare() -> None:
        n = 0
        with AnyReader([bag]) as reader:
            for conn, _, raw in reader.messages():
                msg = reader.deserialize(raw, conn.msgtype)
                n += msg.theta_in_rad.size
        assert n == samples

    t_ours, t_rb = _best_of(ours), _best_of(rosbags_bare)
    return [('read_encoder_blocks', samples / t_ours, t_ours),
            ('rosbags AnyReader + deserialize', samples / t_rb, t_rb)]


def bench_session(tmp: Path, seconds: float) -> str:
    import rclpy
    from rclpy.experimental import EventsExecutor
    from rclpy.parameter import Parameter

    from rv_te_bench.nodes.recorder import RecorderNode

    n_blocks = int(seconds * 100)
    topic = f'/bench_io_{os.getpid()}/bench/encoders'
    ctx = rclpy.context.Context()
    domain = 150 + os.getpid() % 50
    rclpy.init(context=ctx, domain_id=domain)
    recorder = RecorderNode(context=ctx, parameter_overrides=[
        Parameter('output_dir', value=str(tmp)), Parameter('bag_name', value='session'),
        Parameter('topics', value=[topic]), Parameter('discovery_period_s', value=0.1)])
    executor = EventsExecutor(context=ctx)
    executor.add_node(recorder)
    env = dict(os.environ)
    env.pop('_ROS_WHEELS_BOOTSTRAP_COMPLETE', None)
    env['ROS_DOMAIN_ID'] = str(domain)
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    proc = subprocess.Popen([sys.executable, str(ROOT / 'tests/msgs/block_publisher.py'),
                             topic, str(n_blocks), '100', '100'], env=env)
    cpu0 = time.process_time()
    t0 = time.monotonic()
    try:
        while proc.poll() is None or recorder.counts.get(topic, 0) < n_blocks:
            executor.spin_once(timeout_sec=0.05)
            if proc.poll() is not None and time.monotonic() - t0 > seconds + 30:
                break
    finally:
        cpu = time.process_time() - cpu0
        wall = time.monotonic() - t0
        counts, gaps = recorder.counts, recorder.gaps
        recorder.destroy_node()
        executor.shutdown()
        rclpy.try_shutdown(context=ctx)
    got = [b.seq for b in read_encoder_blocks(tmp / 'session')]
    lost = n_blocks - len(got)
    return (f'{seconds:.0f} s session, {n_blocks} blocks of 100 samples (10 kHz): recorded '
            f'{counts.get(topic, 0)}, read back {len(got)}, lost {lost}, gaps {gaps[topic]}; '
            f'recorder CPU {cpu:.1f} s over {wall:.1f} s wall ({100 * cpu / wall:.0f} %)')


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--messages', type=int, default=3000)
    parser.add_argument('--block', type=int, default=1000, help='samples per block')
    parser.add_argument('--session-s', type=float, default=60.0)
    args = parser.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix='bench_io_', dir=ROOT / 'out' if (ROOT / 'out').is_dir()
                                else None))
    try:
        print(f'## write: {args.messages} EncoderBlocks of {args.block} samples '
              f'({len(encoder_cdr(0, args.block))} B each), best of 3')
        print('| writer | MB/s | msg/s |\n|---|---|---|')
        for name, mbs, rate in bench_write(tmp, args.messages, args.block):
            print(f'| {name} | {mbs:.0f} | {rate:.0f} |')
        print(f'\n## read: {args.messages} blocks of {args.block} samples (zstd), best of 3')
        print('| reader | samples/s | time s |\n|---|---|---|')
        rows = bench_read(tmp, args.messages, args.block)
        for name, sps, t in rows:
            print(f'| {name} | {sps / 1e6:.1f} M | {t:.3f} |')
        print(f'\nratio time(read_encoder_blocks) / time(rosbags) = {rows[0][2] / rows[1][2]:.2f}')
        if args.session_s > 0:
            print('\n## recorded session')
            print(bench_session(tmp, args.session_s))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
