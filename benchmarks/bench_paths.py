"""The analysis's two paths (helper thread / one thread) against bag size: which is faster?

`rv-te analyze` runs either all on the calling thread or with one helper thread that
decompresses chunks ahead and computes window spectra (report/analysis.py); which one, it
decides by itself (io/_cores.py: two cores, a bag >= 8 MiB, and after 30 ms a machine with
an idle core or an overloaded one). This script times both, forced (``RV_TE_READ_AHEAD=1`` /
``=0``), the analysis's own choice (variable unset; the column "taken" says which path it
took, from its logged decision) and the one-core figure (this thread pinned to the first
core, as ``taskset -c 0``), interleaved repeat by repeat, on bags of several lengths and
block sizes: sessions written as the recorder writes them (our BagWriter, zstd, the sample
bag's simulator) and, with ``--unit``, the fleet benchmark's unit bags (rosbags writer,
1 MiB chunks, uncompressed, 316,000 samples). Wall and CPU time (user + sys) per analysis,
medians; ratios are per-repeat medians. ``--busy-core`` runs a CPU-bound process pinned to
the other core meanwhile (the one-core figure then runs on the free core); ``--hogs N``
runs N CPU-bound processes the scheduler places (an overloaded machine).

    .venv/bin/python benchmarks/bench_paths.py [--seconds 5 20 60 180 600]
        [--blocks 100 1000] [--unit] [--repeats 7] [--busy-core] [--hogs N] [--bag-dir DIR]
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
sys.path.insert(0, str(ROOT / 'benchmarks'))


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
    ap.add_argument('--busy-core', action='store_true',
                    help='a CPU-bound process pinned to the other core meanwhile')
    ap.add_argument('--hogs', type=int, default=0,
                    help='N CPU-bound processes placed by the scheduler meanwhile')
    ap.add_argument('--advice', action='store_true',
                    help='with advice (as `rv-te analyze` and the fleet run by default)')
    ap.add_argument('--bag-dir', type=Path, default=None)
    args = ap.parse_args(argv)

    from _taken import Taken

    from rv_te_bench.allocator import tune_for_batch_work
    from rv_te_bench.io._cores import READ_AHEAD_ENV
    from rv_te_bench.report.analysis import analyze_bag

    tune_for_batch_work()
    taken = Taken()
    bag_dir = args.bag_dir or Path(tempfile.mkdtemp(prefix='rv-te-paths-'))
    bag_dir.mkdir(parents=True, exist_ok=True)
    bags = _bags(bag_dir, args.seconds, args.blocks, args.rate_hz, args.unit)
    cores = sorted(os.sched_getaffinity(0))
    burners = []
    if args.busy_core:
        burners.append(subprocess.Popen([sys.executable, '-c', 'while True: pass']))
        os.sched_setaffinity(burners[-1].pid, {cores[-1]})
    burners += [subprocess.Popen([sys.executable, '-c', 'while True: pass'])
                for _ in range(args.hogs)]
    os.environ.pop(READ_AHEAD_ENV, None)
    if burners:
        time.sleep(0.5)
    load0 = os.getloadavg()[0]
    rows = []
    modes = (('helper', '1'), ('one thread', '0'), ('its choice', None), ('one core', None))
    try:
        for label, bag in bags:
            analyze_bag(bag, with_advice=args.advice)          # warm: imports, page cache
            wall: dict[str, list[float]] = {m: [] for m, _ in modes}
            cpu: dict[str, list[float]] = {m: [] for m, _ in modes}
            paths: list[str] = []
            for r in range(args.repeats):
                order = modes if r % 2 == 0 else modes[::-1]
                for name, env in order:
                    if env is None:
                        os.environ.pop(READ_AHEAD_ENV, None)
                    else:
                        os.environ[READ_AHEAD_ENV] = env
                    if name == 'one core':            # (this thread: taskset -c 0)
                        os.sched_setaffinity(0, {cores[0]})
                    taken.clear()
                    try:
                        c0, t0 = time.process_time(), time.perf_counter()
                        analyze_bag(bag, with_advice=args.advice)
                        wall[name].append(time.perf_counter() - t0)
                        cpu[name].append(time.process_time() - c0)
                    finally:
                        os.sched_setaffinity(0, set(cores))
                    if name == 'its choice':
                        paths.append(taken.path())
                os.environ.pop(READ_AHEAD_ENV, None)
            med = {k: statistics.median(v) for k, v in wall.items()}
            medc = {k: statistics.median(v) for k, v in cpu.items()}

            def ratio(a: str, b: str, wall: dict[str, list[float]] = wall) -> float:
                return statistics.median(x / y for x, y in zip(wall[a], wall[b], strict=True))
            choice = ', '.join(f'{p} {paths.count(p)}/{len(paths)}'
                               for p in sorted(set(paths), key=paths.index))
            rows.append((label, med, medc, ratio('helper', 'one thread'),
                         ratio('its choice', 'one thread'), ratio('its choice', 'one core'),
                         choice))
            print(f'{label}: helper {med["helper"]:.3f} s, one thread '
                  f'{med["one thread"]:.3f} s, choice {med["its choice"]:.3f} s ({choice}), '
                  f'one core {med["one core"]:.3f} s', file=sys.stderr)
    finally:
        for burner in burners:
            burner.kill()
            burner.wait()
    load1 = os.getloadavg()[0]
    beside = ', '.join([*(['a CPU-bound process on the other core'] if args.busy_core else []),
                        *([f'{args.hogs} CPU-bound processes'] if args.hogs else [])])
    print(f'\n{_cpu_model()}, {platform.python_version()}; {beside or "both cores free"}'
          f'; load {load0:.2f} -> {load1:.2f}; {time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())}'
          f'; median of {args.repeats}; advice {"on" if args.advice else "off"}\n')
    print('| bag | helper wall [s] (CPU) | one thread wall [s] (CPU) | one core wall [s] (CPU) '
          '| its choice wall [s] (CPU) | helper / one thread | its choice / one thread '
          '| its choice / one core | taken |')
    print('|---|---|---|---|---|---|---|---|---|')
    for label, med, medc, r_h, r_c, r_c1, choice in rows:
        cells = ' | '.join(f'{med[m]:.3f} ({medc[m]:.3f})'
                           for m in ('helper', 'one thread', 'one core', 'its choice'))
        print(f'| {label} | {cells} | {r_h:.2f} | {r_c:.2f} | {r_c1:.2f} | {choice} |')
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
