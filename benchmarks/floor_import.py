"""What any import of a TDMS file must spend beyond the bare read (issue 41, the floor).

``rv-te import`` turns the file's three float64 channels (24 bytes per sample, time
implicit) into a bag of EncoderBlocks: four float64 per sample (time offset, input, output,
torque: 32 bytes) in MCAP chunks with a CRC. Whatever the converter does, the bag's bytes
must be made from the arrays once, checksummed and written, and compressed unless
``--compression none``. This script times those steps alone, per sample (CPU, one thread,
the best of five), beside the bare ``nptdms`` read of the same file in the same chunks
(``bench_import.py``'s bare read):

* **records**: the four columns laid out in 1000-sample blocks (one copy, numpy);
* **chunk CRC**: the MCAP chunk CRC32 of those bytes (ISA-L, as the bag writer);
* **write**: the bytes written to a file on the same disk (page cache, 1 MiB writes);
* **zstd -5**: the default ``--compression zstd-fast``.

The floor ratio is (bare read + records + CRC + write [+ zstd]) / bare read: no import can
be faster than that against the bare read.

    .venv/bin/python benchmarks/floor_import.py --samples 1351351
    taskset -c 0 .venv/bin/python benchmarks/floor_import.py --samples 1351351
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / 'benchmarks'))
CHUNK = 100_000


def _best(f, reps: int = 5):
    best, out = float('inf'), None
    for _ in range(reps):
        c = time.process_time()
        out = f()
        best = min(best, time.process_time() - c)
    return best, out


def main() -> None:
    """Write a TDMS file, time the bare read and the bag's unavoidable steps, print them."""
    import zstandard
    from bench_import import machine, write_tdms
    from nptdms import TdmsFile

    from rv_te_bench.io._mcap_file import _chunk_crc32

    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--samples', type=int, default=1_351_351)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix='floor_import_') as tmp:
        path = Path(tmp) / 'run.tdms'
        write_tdms(path, args.samples)

        def read() -> list[list[np.ndarray]]:
            out = []
            with TdmsFile.open(path) as f:
                chans = [f['encoders'][c] for c in ('theta_in', 'theta_out', 'torque')]
                n = len(chans[0])
                for s in range(0, n, CHUNK):
                    out.append([c.read_data(s, min(CHUNK, n - s)) for c in chans])
            return out

        t_read, cols = _best(read)

        def records() -> list[np.ndarray]:
            bufs = []
            for a, b, c in cols:
                k = a.size // 1000
                buf = np.empty((k, 4, 1000))
                buf[:, 0] = 0.0
                for j, x in ((1, a), (2, b), (3, c)):
                    buf[:, j] = x[:k * 1000].reshape(k, 1000)
                bufs.append(buf)
            return bufs

        t_rec, bufs = _best(records)
        chunks = [memoryview(b).cast('B')[i:i + (1 << 20)] for b in bufs
                  for i in range(0, b.nbytes, 1 << 20)]
        t_crc, _ = _best(lambda: [_chunk_crc32(c) for c in chunks])
        out_path = Path(tmp) / 'bag.bin'

        def write() -> None:
            fd = os.open(out_path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC)
            for c in chunks:
                os.write(fd, c)
            os.close(fd)

        t_wr, _ = _best(write)
        z = zstandard.ZstdCompressor(level=-5)
        t_z, _ = _best(lambda: [z.compress(c) for c in chunks])
    n = args.samples
    print(f'{machine()}; affinity {sorted(os.sched_getaffinity(0))}')
    print('| samples | bare read | records (one copy) | chunk CRC | write | zstd -5 | floor / '
          'bare, none | floor / bare, zstd-fast |')
    print('|---|---|---|---|---|---|---|---|')
    ns = [t / n * 1e9 for t in (t_read, t_rec, t_crc, t_wr, t_z)]
    base = t_read + t_rec + t_crc + t_wr
    print(f'| {n:,} | ' + ' | '.join(f'{v:.1f} ns' for v in ns)
          + f' | {base / t_read:.2f}x | {(base + t_z) / t_read:.2f}x |')


if __name__ == '__main__':
    main()
