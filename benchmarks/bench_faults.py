"""Faults survived by the bag writer: a disk that fills while recording (issue #16).

Records 10 kHz EncoderBlocks (blocks of 100 samples, 100 blocks/s of log time, zstd, 1 MiB
chunks: the recorder's defaults) onto a small disk and prints a markdown table: blocks sent,
what the writer says is on disk and lost, what rosbags and mcap (seeking and streaming) read
back, and how the loss is reported. The disk is ``SmallDisk`` (tests/io/faults.py, fault
injection, no root needed) or, with ``--tmpfs`` as root, a real tmpfs.

    .venv/bin/python benchmarks/bench_faults.py [--tmpfs]
"""

from __future__ import annotations

import argparse
import contextlib
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import yaml
from mcap.reader import NonSeekingReader, make_reader
from rosbags.highlevel import AnyReader

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from rv_te_bench.io.bag_writer import BagWriter  # noqa: E402
from rv_te_bench.io.msgdefs import ENCODER_BLOCK  # noqa: E402
from tests.io.bag_fixtures import ENCODER_TOPIC, T0_NS, encoder_cdr  # noqa: E402
from tests.io.faults import SmallDisk  # noqa: E402

MiB = 1 << 20
FLUSH_S = 0.05
_CDR = [encoder_cdr(s, 100) for s in range(200)]


def _read_back(bag: Path) -> tuple[int, int, int]:
    """EncoderBlocks read by rosbags, by mcap seeking, by mcap streaming."""
    with AnyReader([bag]) as reader:
        n_rosbags = sum(1 for c, _, _ in reader.messages() if c.topic == ENCODER_TOPIC)
    info = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    n_seek = n_stream = 0
    for name in info['relative_file_paths']:
        with (bag / name).open('rb') as fh:
            n_seek += sum(1 for _, c, _ in make_reader(fh).iter_messages()
                          if c.topic == ENCODER_TOPIC)
        with (bag / name).open('rb') as fh:
            n_stream += sum(1 for _, c, _ in NonSeekingReader(fh).iter_messages()
                            if c.topic == ENCODER_TOPIC)
    return n_rosbags, n_seek, n_stream


class _Disk:
    """SmallDisk, or a real tmpfs whose space is taken / given back with a ballast file."""

    def __init__(self, root: Path, size: int, *, real: bool) -> None:
        self.real = real
        self.storage: SmallDisk | None = None
        if real:
            self.mnt = root / 'mnt'
            self.mnt.mkdir()
            subprocess.run(['mount', '-t', 'tmpfs', '-o', f'size={size + 16 * MiB}', 'tmpfs',
                            str(self.mnt)], check=True, timeout=10)
            for k in range(2):   # each one given back = space returns
                (self.mnt / f'ballast{k}').write_bytes(bytes(8 * MiB))
        else:
            self.mnt = root
            self.storage = SmallDisk(size)

    def give_back(self) -> None:
        if self.real:
            next(self.mnt.glob('ballast*')).unlink()
        else:
            assert self.storage is not None
            self.storage.capacity_bytes += 8 * MiB

    def close(self) -> None:
        if self.real:
            subprocess.run(['umount', '-l', str(self.mnt)], check=False, timeout=10)


def _case(root: Path, *, real: bool, full_for: int | None, times: int = 1,
          stall_buffer_bytes: int = 64 * MiB, n_after: int = 300) -> dict[str, Any]:
    """Write until the disk fills (``times`` times), then ``full_for`` blocks while full
    (None: it stays full), then ``n_after`` more blocks; close and read back."""
    disk = _Disk(root, 4 * MiB, real=real)
    try:
        events: list[str] = []
        kwargs: dict[str, Any] = {'storage': disk.storage} if disk.storage else {}
        w = BagWriter(disk.mnt / 'bag', flush_interval_s=FLUSH_S, on_event=events.append,
                      stall_buffer_bytes=stall_buffer_bytes, **kwargs)
        w.add_topic(ENCODER_TOPIC, ENCODER_BLOCK)
        seq = 0

        def send(n: int) -> None:
            nonlocal seq
            for _ in range(n):
                w.write(ENCODER_TOPIC, T0_NS + seq * 10_000_000, _CDR[seq % len(_CDR)])
                seq += 1

        for _ in range(times):
            while not w.stalled:
                send(1)
            if full_for is None:
                break
            send(full_for)
            disk.give_back()
            time.sleep(2 * FLUSH_S)
            send(1)
        send(n_after)
        t = time.perf_counter()
        w.close()
        close_ms = (time.perf_counter() - t) * 1e3
        rb, seek, stream = _read_back(disk.mnt / 'bag')
        return {'sent': seq, 'on_disk': w.counts[ENCODER_TOPIC],
                'lost': w.lost[ENCODER_TOPIC], 'rosbags': rb, 'seek': seek,
                'stream': stream, 'files': len(w.files), 'gaps': len(w.write_gaps),
                'close_ms': close_ms,
                'lost_s': sum(((g.lost_last_ns or 0) - (g.lost_first_ns or 0)) * 1e-9
                              + (0.01 if g.lost_messages else 0.0) for g in w.write_gaps)}
    finally:
        disk.close()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--tmpfs', action='store_true', help='a real tmpfs (needs root)')
    args = parser.parse_args()
    if args.tmpfs and os.geteuid() != 0:
        print('ERROR: --tmpfs needs root', file=sys.stderr)
        return 2
    cases = [
        ('full once, stays full', {'full_for': None}),
        ('full for 500 blocks (5 s), then space returns', {'full_for': 500}),
        ('full for 500 blocks, stall buffer 256 KiB', {'full_for': 500,
                                                       'stall_buffer_bytes': 256 << 10}),
        ('full twice, 500 blocks each, stall buffer 256 KiB',
         {'full_for': 500, 'times': 2, 'stall_buffer_bytes': 256 << 10}),
    ]
    disk = 'tmpfs' if args.tmpfs else 'SmallDisk'
    print(f'| case ({disk}, 4 MiB) | blocks sent | on disk: writer / rosbags / mcap seek / '
          'mcap stream | lost (writer) | lost span | files | write gaps | close |')
    print('|---|---|---|---|---|---|---|---|')
    for label, kw in cases:
        root = Path(tempfile.mkdtemp(prefix='bench_faults_'))
        try:
            r = _case(root, real=args.tmpfs, **kw)
        finally:
            with contextlib.suppress(OSError):
                shutil.rmtree(root)
        print(f"| {label} | {r['sent']} | {r['on_disk']} / {r['rosbags']} / {r['seek']} / "
              f"{r['stream']} | {r['lost']} | {r['lost_s']:.2f} s | {r['files']} | "
              f"{r['gaps']} | {r['close_ms']:.0f} ms |")
    return 0


if __name__ == '__main__':
    sys.exit(main())
