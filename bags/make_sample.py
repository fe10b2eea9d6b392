"""Regenerate the sample session ``bags/sample`` from the bench simulator (no ROS needed).

The session: the Wang 2020 2K-V preset (``wang2020-2kv``, no-load NLTE model), input at a
constant 300 rpm (output period 15.8 s, f_w = 1.582 Hz), Heidenhain RON 886 encoders on
both shafts, sampled at 1 kHz in blocks of 100 samples, for 32 s (a little over two output
revolutions). It is written the way the recorder writes a live session: ``bench/info``
once (BenchInfo) and ``bench/encoders`` (EncoderBlock), CDR via the rosbags typestore,
through :class:`rv_te_bench.io.bag_writer.BagWriter` (rosbag2 folder, MCAP, zstd).

Usage::

    .venv/bin/python bags/make_sample.py            # writes bags/sample (refuses to overwrite)
    .venv/bin/python bags/make_sample.py --force    # replace it
    rv-te analyze bags/sample --report /tmp/sample-report

The same seed gives the same data (the simulator is deterministic per seed).
"""

from __future__ import annotations

import argparse
import shutil
import sys
from pathlib import Path

PRESET = 'wang2020-2kv'
INPUT_SPEED_RPM = 300.0
SAMPLE_RATE_HZ = 1000.0
BLOCK_SIZE = 100
DURATION_S = 32.0
SEED = 2020
BENCH_ID = 'sample-bench'
ENCODER_TOPIC = '/bench/encoders'
INFO_TOPIC = '/bench/info'
#: Nanoseconds since the epoch of sample 0 (a fixed date keeps the bag reproducible).
START_NS = 1_767_225_600_000_000_000  # 2026-01-01T00:00:00Z


def write_sample(path: Path, *, duration_s: float = DURATION_S,
                 sample_rate_hz: float = SAMPLE_RATE_HZ, block_size: int = BLOCK_SIZE,
                 compression: str = 'zstd') -> dict[str, float]:
    """Simulate the session and write it as a bag at ``path`` (must not exist).

    The keyword arguments let benchmarks write longer or faster sessions the same way.

    Returns:
        ``{'blocks', 'samples', 'duration_s'}``.
    """
    import numpy as np

    from rv_te_bench.io._legacy_msgs import added_field_defaults
    from rv_te_bench.io.bag_writer import BagWriter, qos_profile_dict
    from rv_te_bench.io.bench_record import bench_info_cdr
    from rv_te_bench.io.msgdefs import BENCH_INFO, ENCODER_BLOCK, rv_te_typestore
    from sim.bench import BenchConfig, BenchSimulator
    from sim.drive import ConstantSpeed

    sim = BenchSimulator(BenchConfig(
        preset=PRESET, drive=ConstantSpeed(INPUT_SPEED_RPM), te_mode='nlte',
        encoder_in='heidenhain-ron886', encoder_out='heidenhain-ron886',
        sample_rate_hz=sample_rate_hz, block_size=block_size, seed=SEED, bench_id=BENCH_ID))
    store = rv_te_typestore()
    types = store.types
    time_cls = types['builtin_interfaces/msg/Time']
    header_cls = types['std_msgs/msg/Header']

    def header(stamp_ns: int) -> object:
        return header_cls(stamp=time_cls(sec=stamp_ns // 1_000_000_000,
                                         nanosec=stamp_ns % 1_000_000_000), frame_id=BENCH_ID)

    n_blocks = round(duration_s * sample_rate_hz / block_size)
    session = {'preset': PRESET, 'input_speed_rpm': INPUT_SPEED_RPM, 'seed': SEED,
               'made_by': 'bags/make_sample.py'}
    with BagWriter(path, compression=compression, session_metadata=session) as writer:
        # The QoS the bench node offers (rv_te_bench.nodes.qos), as a recorder stores it.
        writer.add_topic(INFO_TOPIC, BENCH_INFO, offered_qos_profiles=[qos_profile_dict(
            durability='transient_local', depth=1)])
        writer.add_topic(ENCODER_TOPIC, ENCODER_BLOCK,
                         offered_qos_profiles=[qos_profile_dict(depth=1000)])
        # every field of the simulated bench's record (the one field list: BenchInfoData)
        writer.write(INFO_TOPIC, START_NS, bench_info_cdr(sim.info, START_NS))
        samples = 0
        for _ in range(n_blocks):
            block = sim.next_block()
            stamp_ns = START_NS + round(block.t0_s * 1e9)
            msg = types[ENCODER_BLOCK](
                header=header(stamp_ns), seq=block.seq, sample_rate_hz=sample_rate_hz,
                time_offset_s=np.asarray(block.time_offset_s, dtype=np.float64),
                theta_in_rad=np.asarray(block.theta_in_rad, dtype=np.float64),
                theta_out_rad=np.asarray(block.theta_out_rad, dtype=np.float64),
                torque_out_nm=np.asarray(block.torque_out_nm, dtype=np.float64),
                **added_field_defaults(ENCODER_BLOCK))
            writer.write(ENCODER_TOPIC, stamp_ns, store.serialize_cdr(msg, ENCODER_BLOCK))
            samples += len(block.theta_in_rad)
    return {'blocks': n_blocks, 'samples': samples, 'duration_s': samples / sample_rate_hz}


def main(argv: list[str] | None = None) -> int:
    """Command line: 0 ok, 1 the bag exists (without --force), 2 bad usage."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0],
                                     formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    parser.add_argument('--out', type=Path, default=Path(__file__).resolve().parent / 'sample',
                        help='bag folder to write')
    parser.add_argument('--force', action='store_true', help='replace an existing bag')
    args = parser.parse_args(argv)
    if args.out.exists():
        if not args.force:
            print(f'ERROR: {args.out} exists already; use --force to replace it.',
                  file=sys.stderr)
            return 1
        shutil.rmtree(args.out)
    done = write_sample(args.out)
    size = sum(f.stat().st_size for f in args.out.iterdir())
    print(f'{args.out}: {done["blocks"]} blocks, {done["samples"]} samples '
          f'({done["duration_s"]:.1f} s), {size / 1e6:.2f} MB')
    return 0


if __name__ == '__main__':
    sys.exit(main())
