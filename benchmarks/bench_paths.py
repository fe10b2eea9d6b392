"""The analysis's two paths (helper thread / one thread) against bag size: which is faster?

`rv-te analyze` runs either all on the calling thread or with one helper thread that
decompresses chunks ahead and computes window spectra (report/analysis.py). This script
times both, forced (``RV_TE_READ_AHEAD=1`` / ``=0``), interleaved repeat by repeat, beside
the path the analysis picks by itself (variable unset), on bags of several lengths and block
sizes: sessions written as the recorder writes them (our BagWriter, zstd, the sample bag's
simulator) and, with ``--unit``, the fleet benchmark's unit bags (rosbags writer, 1 MiB
chunks, uncompressed, 316,000 samples). Wall and CPU time (user + sys) per analysis, medians.
``--busy-core`` runs a CPU-bound process pinned to the other core meanwhile.

    .venv/bin/python benchmarks/bench_paths.py [--seconds 5 20 60 180 600]
        [--blocks 100 1000] [--unit] [--repeats 7] [--busy-core] [--bag-dir DIR]
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / 'bags'))


def _bags(bag_dir: Path, seconds: list[float], blocks: list[int], rate_hz: float,
          unit: bool) -> list[tuple[str, Path]]:
    from make_sample import write_sample

    out = []
    for block in blocks:
        for s in seconds:
            bag = bag_dir / f'sess_b{block}_{s:g}s'
            if not (bag / 'metadata.yaml').is_file():
                import shutil
                shutil.rmtree(bag, ignore_errors=True)
                write_sample(bag, duration_s=s, sample_rate_hz=rate_hz, block_size=block)
            out.append((f'session {s:g} s, blocks of {block}, zstd', bag))
    if unit:
        import numpy as np

        from tests import wang2020_reference as ref
        from tests.unit_bags import unit_bag
        bag = bag_dir / 'unit_fleet'
        if not (bag / 'metadata.yaml').is_file():
            unit_bag(bag, ref.random_unit(np.random.default_rng(2026)),
                     np.random.default_rng(2026), rate_hz=rate_hz,
                     duration_s=2 * 60.0 * ref.RATIO / 300.0)
        out.append(('fleet unit bag (2 rev, 316k samples), blocks of 100, uncompressed', bag))
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--seconds', type=float, nargs='+', default=[5, 20, 60, 180, 600])
    ap.add_argument('--blocks', type=int, nargs='+', default=[100, 1000])
    ap.add_argument('--rate-hz', type=float, default=10_000.0)
    ap.add_argument('--unit', action='store_true', help="also the fleet benchmark's unit bag")
    ap.add_argument('--repeats', type=int, default=7)
    ap.add_argument('--busy-core', action='store_true')
    ap.add_argument('--advice', action='store_true',
                    help='with advice (as `rv-te analyze` and the fleet run by default)')
    ap.add_argument('--bag-dir', type=Path, default=None)
    args = ap.parse_args(argv)

    from rv_te_bench.allocator import tune_for_batch_work
    from rv_te_bench.io._cores import READ_AHEAD_ENV
    from rv_te_bench.report.analysis import analysis_path, analyze_bag

    tune_for_batch_work()
    bag_dir = args.bag_dir or Path(tempfile.mkdtemp(prefix='rv-te-paths-'))
    bag_dir.mkdir(parents=True, exist_ok=True)
    bags = _bags(bag_dir, args.seconds, args.blocks, args.rate_hz, args.unit)
    cores = sorted(os.sched_getaffinity(0))
    burner = None
    if args.busy_core:
        burner = subprocess.Popen([sys.executable, '-c', 'while True: pass'])
        os.sched_setaffinity(burner.pid, {cores[-1]})
    os.environ.pop(READ_AHEAD_ENV, None)
    load0 = os.getloadavg()[0]
    rows = []
    try:
        for label, bag in bags:
            analyze_bag(bag, with_advice=args.advice)          # warm: imports, page cache
            modes = (('helper', '1'), ('one thread', '0'), ('its choice', None))
            wall: dict[str, list[float]] = {m: [] for m, _ in modes}
            cpu: dict[str, list[float]] = {m: [] for m, _ in modes}
            for r in range(args.repeats):
                order = modes if r % 2 == 0 else modes[::-1]
                for name, env in order:
                    if env is None:
                        os.environ.pop(READ_AHEAD_ENV, None)
                    else:
                        os.environ[READ_AHEAD_ENV] = env
                    c0, t0 = time.process_time(), time.perf_counter()
                    analyze_bag(bag, with_advice=args.advice)
                    wall[name].append(time.perf_counter() - t0)
                    cpu[name].append(time.process_time() - c0)
                os.environ.pop(READ_AHEAD_ENV, None)
            choice = analysis_path(bag)
            med = {k: statistics.median(v) for k, v in wall.items()}
            medc = {k: statistics.median(v) for k, v in cpu.items()}
            ratio = statistics.median(h / o for h, o in
                                      zip(wall['helper'], wall['one thread'], strict=True))
            rows.append((label, med, medc, ratio, choice))
            print(f'{label}: helper {med["helper"]:.3f} s, one thread '
                  f'{med["one thread"]:.3f} s, choice {choice}', file=sys.stderr)
    finally:
        if burner is not None:
            burner.kill()
            burner.wait()
    load1 = os.getloadavg()[0]
    print(f'\n{_cpu_model()}, {platform.python_version()}; '
          f'{"a CPU-bound process on the other core" if args.busy_core else "both cores"}'
          f'; load {load0:.2f} -> {load1:.2f}; {time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())}'
          f'; median of {args.repeats}; advice {"on" if args.advice else "off"}\n')
    print('| bag | helper wall [s] (CPU) | one thread wall [s] (CPU) | its choice wall [s] '
          '| helper / one thread (wall, per repeat median) | choice |')
    print('|---|---|---|---|---|---|')
    for label, med, medc, ratio, choice in rows:
        print(f'| {label} | {med["helper"]:.3f} ({medc["helper"]:.3f}) | '
              f'{med["one thread"]:.3f} ({medc["one thread"]:.3f}) | '
              f'{med["its choice"]:.3f} | {ratio:.2f} | {choice} |')
    return 0


def _cpu_model() -> str:
    try:
        for line in Path('/proc/cpuinfo').read_text().splitlines():
            if line.startswith('model name'):
                return line.split(':', 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or 'unknown CPU'


if __name__ == '__main__':
    sys.exit(main())
