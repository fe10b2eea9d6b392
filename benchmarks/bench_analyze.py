"""Offline analysis throughput: `rv-te analyze` core path on a long bag vs a bare rosbags read.

Writes a wang2020-2kv bench session (default 10 minutes at 10 kHz, blocks of 1000, RON 886)
with the same code as bags/make_sample.py, then times, side by side in one run:

  * rosbags AnyReader reading and deserialising every EncoderBlock (the floor),
  * rv_te_bench.io.read_encoder_blocks (our numpy decode),
  * rv_te_bench.report.analysis.analyze_bag (read + Eq. 22 + windows + spectra; no advice).

    .venv/bin/python benchmarks/bench_analyze.py [--minutes 10] [--rate-hz 10000] [--repeats 3]
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / 'bags'))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--minutes', type=float, default=10.0)
    ap.add_argument('--rate-hz', type=float, default=10_000.0)
    ap.add_argument('--block', type=int, default=1000)
    ap.add_argument('--repeats', type=int, default=3)
    args = ap.parse_args()

    from make_sample import write_sample  # noqa: PLC0415
    from rosbags.highlevel import AnyReader  # noqa: PLC0415

    from rv_te_bench.io.bag_reader import read_encoder_blocks  # noqa: PLC0415
    from rv_te_bench.io.msgdefs import rv_te_typestore  # noqa: PLC0415
    from rv_te_bench.report.analysis import analyze_bag  # noqa: PLC0415

    tmp = Path(tempfile.mkdtemp(prefix='rv-te-analyze-bench-'))
    bag = tmp / 'bag'
    t0 = time.perf_counter()
    info = write_sample(bag, duration_s=args.minutes * 60.0, sample_rate_hz=args.rate_hz,
                        block_size=args.block)
    t_write = time.perf_counter() - t0
    size_mb = sum(f.stat().st_size for f in bag.iterdir()) / 1e6
    n = info['samples']
    print(f'bag: {info["blocks"]} blocks, {n} samples, {size_mb:.1f} MB (written in '
          f'{t_write:.1f} s)', file=sys.stderr)
    store = rv_te_typestore()

    def rosbags_read() -> int:
        count = 0
        with AnyReader([bag], default_typestore=store) as reader:
            conns = [c for c in reader.connections if c.topic.endswith('bench/encoders')]
            for conn, _t, raw in reader.messages(connections=conns):
                msg = reader.deserialize(raw, conn.msgtype)
                count += len(msg.theta_in_rad)
        return count

    def ours_read() -> int:
        return sum(len(b.theta_in_rad) for b in read_encoder_blocks(bag))

    def analyze() -> int:
        res = analyze_bag(bag, with_advice=False)
        return int(res.cumulative.n_samples)

    times: dict[str, list[float]] = {'rosbags': [], 'read': [], 'analyze': []}
    for _ in range(args.repeats):   # interleaved, so machine noise hits all alike
        for name, fn in (('rosbags', rosbags_read), ('read', ours_read),
                         ('analyze', analyze)):
            t0 = time.perf_counter()
            got = fn()
            times[name].append(time.perf_counter() - t0)
            if got < n * 0.99:
                print(f'ERROR: {name} saw {got} of {n} samples', file=sys.stderr)
                return 1
    med = {k: statistics.median(v) for k, v in times.items()}
    print(f'\nmachine: {platform.node()} {platform.machine()}, {os.cpu_count()} cores, '
          f'python {platform.python_version()}, date {time.strftime("%Y-%m-%d")}; '
          f'{args.minutes:g} min at {args.rate_hz:g} Hz, blocks of {args.block}, '
          f'median of {args.repeats}\n')
    print('| path | time [s] | samples/s | time / rosbags read |')
    print('|---|---|---|---|')
    for name, label in (('rosbags', 'rosbags AnyReader read + deserialise (floor)'),
                        ('read', 'read_encoder_blocks (numpy decode)'),
                        ('analyze', 'analyze_bag (read + TE + windows + spectra)')):
        print(f'| {label} | {med[name]:.2f} | {n / med[name] / 1e6:.2f} M | '
              f'{med[name] / med["rosbags"]:.2f} |')
    return 0


if __name__ == '__main__':
    sys.exit(main())
