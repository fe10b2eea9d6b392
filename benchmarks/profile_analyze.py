"""Where the offline analysis spends its CPU, stage by stage (issue 41: profile first).

Runs ``analyze_bag`` on the one-thread path (``RV_TE_READ_AHEAD=0``: every stage on the
caller's thread, so that each stage's CPU time is its own) over bags written as
``bench_analyze.py`` writes them, with the stage functions wrapped by CPU-time counters,
and the bare rosbags read beside it (the floor of issue 41). Stages (nested ones are
part of their parent's time):

  decompress     zstd of the MCAP chunks (rosbags pays it too)
  chunk CRC      the chunk's CRC-32
  decode         EncoderBlock CDR parse and the copy of the arrays into one batch
  block checks   per-block checks of a batch (finite values, time order, seq)
  Eq. 22         phi = theta_in / i and TE = theta_out - phi
  windowing      finding window ends, copying samples into the window buffer
  statistics     window min/max/mean/std (and the plot's min/max envelope)
  spectrum       order spectrum of a complete window, of which
    resampling   to the output-angle grid (4-point Lagrange), the FFT (numpy's pocketfft),
    FFT          and the rest (amplitudes, phases, lines)
  plot trace     the thinned TE trace for the plot

    .venv/bin/python benchmarks/profile_analyze.py [--minutes 10] [--blocks 1000 10000]
        [--repeats 5] [--bag-dir DIR]

The counters cost a few microseconds per call (a few per window and per chunk); the
'total' row is measured without them, in the same process, interleaved.
"""

from __future__ import annotations

import argparse
import collections
import functools
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / 'bags'))
sys.path.insert(0, str(ROOT / 'benchmarks'))

STAGES = (  # (label, module, attribute): the wrapped callables
    ('decompress', 'rv_te_bench.io._mcap_scan', '_decompress'),
    ('chunk CRC', 'rv_te_bench.io._mcap_scan', '_crc32'),
    ('decode', 'rv_te_bench.io._encoder_cdr', '_parse_encoder_blocks'),
    ('decode', 'rv_te_bench.io._encoder_cdr', '_concat_f64'),
    ('block checks', 'rv_te_bench.core.stream', '_batch_flags'),
    ('Eq. 22', 'rv_te_bench.core.stream', 'output_phase_and_te'),
    ('windowing', 'rv_te_bench.core.stream', '_first_reach'),
    ('windowing', 'rv_te_bench.core.stream.WindowBuffer', 'append'),
    ('statistics', 'rv_te_bench.core.stream', 'moments_of_finite'),
    ('statistics', 'rv_te_bench.core.envelope.MinMaxEnvelope', 'add'),
    ('spectrum', 'rv_te_bench.core.stream', 'order_spectrum'),
    ('  resampling', 'rv_te_bench.core.spectrum', 'resample_to_output_angle'),
    ('  FFT', 'numpy.fft', 'rfft'),
    ('plot trace', 'rv_te_bench.report._guarded._GuardedBlocks', '_keep_batch'),
)


def _target(path: str) -> object:
    import importlib

    parts = path.split('.')
    for k in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module('.'.join(parts[:k]))
        except ModuleNotFoundError:
            continue
        for name in parts[k:]:
            obj = getattr(obj, name)
        return obj
    raise ModuleNotFoundError(path)


def _wrap(spent: collections.Counter, label: str, owner: object, name: str) -> None:
    real = getattr(owner, name)

    @functools.wraps(real)
    def timed(*args: object, **kwargs: object) -> object:
        c0 = time.process_time()
        try:
            return real(*args, **kwargs)
        finally:
            spent[label] += time.process_time() - c0
    setattr(owner, name, timed)
    return real


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--minutes', type=float, default=10.0)
    ap.add_argument('--rate-hz', type=float, default=10_000.0)
    ap.add_argument('--blocks', type=int, nargs='+', default=[1000, 10000])
    ap.add_argument('--repeats', type=int, default=5)
    ap.add_argument('--bag-dir', type=Path, default=None,
                    help='write the bags here, or reuse those already there')
    args = ap.parse_args(argv)
    os.environ['RV_TE_READ_AHEAD'] = '0'
    from bench_analyze import rosbags_read, sample_bag

    from rv_te_bench.allocator import tune_for_batch_work
    from rv_te_bench.report.analysis import analyze_bag

    tune_for_batch_work()
    bag_dir = args.bag_dir or Path(tempfile.mkdtemp(prefix='rv-te-profile-'))
    load0 = os.getloadavg()
    print(f'{_cpu_model()}; load {load0[0]:.2f} at the start', file=sys.stderr)
    for block in args.blocks:
        bag, n = sample_bag(bag_dir, block, args.minutes, args.rate_hz)
        analyze_bag(bag, with_advice=False)   # warm: imports, caches
        spent: collections.Counter[str] = collections.Counter()
        bare: dict[str, list[float]] = {'rosbags read': [], 'analysis': []}
        windows = 0
        for _ in range(args.repeats):
            c0 = time.process_time()
            rosbags_read(bag)
            bare['rosbags read'].append(time.process_time() - c0)
            c0 = time.process_time()
            res = analyze_bag(bag, with_advice=False)
            bare['analysis'].append(time.process_time() - c0)
            windows = len(res.windows)
            saved = [(owner, name, _wrap(spent, label, owner, name))
                     for label, where, name in STAGES for owner in [_target(where)]]
            try:
                analyze_bag(bag, with_advice=False)
            finally:
                for owner, name, real in reversed(saved):
                    setattr(owner, name, real)
        total = statistics.median(bare['analysis'])
        floor = statistics.median(bare['rosbags read'])
        print(f'\nblock {block}: {n} samples, {windows} windows; CPU seconds per analysis, '
              f'median of {args.repeats} (stages: mean); load {os.getloadavg()[0]:.2f}\n')
        print('| stage | CPU [s] | per window [ms] | share of the analysis |')
        print('|---|---|---|---|')
        for label in dict.fromkeys(lb for lb, _w, _n in STAGES):
            s = spent[label] / args.repeats
            print(f'| {label} | {s:.3f} | {1e3 * s / max(windows, 1):.2f} | '
                  f'{100 * s / total:.0f} % |')
        print(f'| **analysis, one thread (unwrapped)** | **{total:.3f}** | '
              f'{1e3 * total / max(windows, 1):.2f} | 100 % |')
        print(f'| rosbags read + deserialise (floor) | {floor:.3f} | - | '
              f'{100 * floor / total:.0f} % |')
    return 0


def _cpu_model() -> str:
    try:
        for line in Path('/proc/cpuinfo').read_text().splitlines():
            if line.startswith('model name'):
                return f'CPU {line.split(":", 1)[1].strip()} x {os.cpu_count()}'
    except OSError:
        pass
    return f'{os.cpu_count()} CPUs'


if __name__ == '__main__':
    sys.exit(main())
