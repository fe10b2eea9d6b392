"""Offline analysis throughput: `rv-te analyze` core path on a long bag vs a bare rosbags read.

Writes a wang2020-2kv bench session (default 10 minutes at 10 kHz, RON 886) with the same
code as bags/make_sample.py, once per block size (default 100, 1000, 3000 and 10000 samples per
EncoderBlock: the bench node's default, the large end of DESIGN.md's range and beyond), then
times, side by side and interleaved in one run:

  * rosbags AnyReader reading and deserialising every EncoderBlock (the floor),
  * rv_te_bench.io.read_encoder_batches (our reader: chunk-wise numpy decode),
  * rv_te_bench.report.analysis.analyze_bag (read + Eq. 22 + windows + spectra; no advice).

By default the process first applies the allocator setting `rv-te analyze` applies to
itself (rv_te_bench/allocator.py), so every path, rosbags included, runs as in that
command; `--allocator default` keeps glibc's defaults (every path again). Wall time is
the measure; the analysis also reports its CPU time (it reads ahead on a second thread).

Then, as whole commands in fresh processes (interpreter start and imports included): the
`rv-te analyze BAG --json --no-advice` command against a Python process that imports
rosbags and reads the bag as above.

Issue 41's rows: ``--one-core`` pins the process to one core first (as ``taskset -c 0``:
the analysis then runs on its one-thread path), ``--busy-core`` runs a CPU-bound process
pinned to another core while it measures (a fleet worker or a busy line PC beside it), and
``--paths both`` adds the analysis forced on each of its two paths (``RV_TE_READ_AHEAD=1``:
helper thread; ``=0``: one thread) beside the one it picks itself (unset), so that the
choice can be checked against both in the same run. ``--bag-dir`` keeps the bags for the
next run (written once, reused when there). ``--floor`` adds the least work any order-spectrum
analysis of the bag does, interleaved with the rest: our reader (zstd, CRC, CDR decode)
plus the resampling to the angle grid and the FFT of every complete window (the windows'
phi and TE captured once from an analysis, not timed): what the analysis cannot go below
without a faster read, resampler or FFT. Every row also gives its CPU time (user + sys of
this process) over the rosbags read's in the same repeat (median of the repeats): on a
shared machine the CPU ratio moves much less than the wall ratio.

With ``--baseline REV`` the analysis as of that git revision also runs, interleaved with the
others (the "before"): ``analyze_bag`` (report/analysis.py: how it drives the core and its
threads), the TE core (core/te.py, core/spectrum.py, core/stream.py) and the bag reader
(io/: record walk, storage, opener, CDR decode) at REV, its read-ahead and CRC-32 as REV's.

    .venv/bin/python benchmarks/bench_analyze.py [--minutes 10]
        [--blocks 100 1000 3000 10000] [--repeats 5] [--allocator tuned|default]
        [--baseline REV] [--one-core] [--busy-core] [--paths auto|both] [--bag-dir DIR]
        [--floor]
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
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / 'bags'))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--minutes', type=float, default=10.0)
    ap.add_argument('--rate-hz', type=float, default=10_000.0)
    ap.add_argument('--blocks', type=int, nargs='+', default=[100, 1000, 3000, 10000])
    ap.add_argument('--baseline', default=None, metavar='REV',
                    help='also run analyze_bag with the TE core of this git revision')
    ap.add_argument('--repeats', type=int, default=5)
    ap.add_argument('--allocator', choices=('tuned', 'default'), default='tuned')
    ap.add_argument('--process-repeats', type=int, default=3,
                    help='repeats of the whole-command comparison (0: skip it)')
    ap.add_argument('--one-core', action='store_true',
                    help='pin this process (and the commands it runs) to one core first')
    ap.add_argument('--busy-core', action='store_true',
                    help='a CPU-bound process on another core while measuring')
    ap.add_argument('--paths', choices=('auto', 'both'), default='auto',
                    help='both: also the analysis forced on each of its two paths')
    ap.add_argument('--bag-dir', type=Path, default=None,
                    help='write the bags here, or reuse the ones already there')
    ap.add_argument('--floor', action='store_true',
                    help='also the read + resampling + FFT alone (the least work of any '
                         'order-spectrum analysis)')
    args = ap.parse_args(argv)
    cores = sorted(os.sched_getaffinity(0))
    if args.one_core:
        os.sched_setaffinity(0, {cores[0]})
    burner = _burner(cores[-1] if len(cores) > 1 else None) if args.busy_core else None
    try:
        return _run(args, burner is not None)
    finally:
        if burner is not None:
            burner.kill()
            burner.wait()


def _burner(core: int | None) -> subprocess.Popen[bytes]:
    """A CPU-bound process pinned to ``core`` (None: not pinned)."""
    proc = subprocess.Popen([sys.executable, '-c', 'while True: pass'])
    if core is not None:
        os.sched_setaffinity(proc.pid, {core})
    return proc


def sample_bag(bag_dir: Path, block: int, minutes: float, rate_hz: float) -> tuple[Path, int]:
    """The benchmark's bag with ``block`` samples per EncoderBlock in ``bag_dir`` (written
    when not there yet); its path and sample count."""
    from make_sample import write_sample

    bag = bag_dir / f'bag{block}_{minutes:g}min_{rate_hz:g}hz'
    n = round(minutes * 60.0 * rate_hz)
    if not (bag / 'metadata.yaml').is_file():
        import shutil

        shutil.rmtree(bag, ignore_errors=True)
        t0 = time.perf_counter()
        info = write_sample(bag, duration_s=minutes * 60.0, sample_rate_hz=rate_hz,
                            block_size=block)
        n = info['samples']
        print(f'bag: {info["blocks"]} blocks of {block}, {n} samples '
              f'(written in {time.perf_counter() - t0:.1f} s)', file=sys.stderr)
    return bag, n


def _run(args: argparse.Namespace, busy: bool) -> int:

    from rv_te_bench.allocator import tune_for_batch_work

    tuned = tune_for_batch_work() if args.allocator == 'tuned' else False
    from rv_te_bench.core.stream_records import EncoderBatch
    from rv_te_bench.io.bag_reader import read_encoder_batches
    from rv_te_bench.report.analysis import analyze_bag

    sys.path.insert(0, str(ROOT / 'benchmarks'))
    from _taken import Taken
    taken = Taken()

    base_core = None
    if args.baseline:
        sys.path.insert(0, str(ROOT / 'benchmarks'))
        from _baseline import load_at, load_core_at, load_io_at, swapped
        base_core = load_core_at(args.baseline)
        base_core.update(load_io_at(args.baseline))   # its bag reader too
        with swapped(base_core):
            # the result types of that revision too (the analysis builds them)
            base_core['rv_te_bench.report.results'] = load_at(
                args.baseline, 'rv_te_bench/report/results.py', 'rv_te_bench.report.results')
        with swapped(base_core):
            # and the analysis's block guard (plot trace, angle fold) as then
            base_core['rv_te_bench.report._guarded'] = load_at(
                args.baseline, 'rv_te_bench/report/_guarded.py', 'rv_te_bench.report._guarded')
        with swapped(base_core):
            base_analysis = load_at(args.baseline, 'rv_te_bench/report/analysis.py',
                                    'rv_te_bench.report.analysis')

        reader_as_then = _reader_as_at(args.baseline, base_core)   # (git show: not timed)

        def analyze_base(bag: Path) -> int:
            with swapped(base_core), reader_as_then:
                return int(base_analysis.analyze_bag(bag, with_advice=False)
                           .cumulative.n_samples)

        def read_base(bag: Path) -> int:
            with swapped(base_core), reader_as_then:
                reader = base_core['rv_te_bench.io.bag_reader']
                return sum(it.n_samples if hasattr(it, 'n_samples') else len(it.theta_in_rad)
                           for it in reader.read_encoder_batches(
                               bag, read_ahead=helper_threads_allowed()))
    from rv_te_bench.io.bag_reader import READ_AHEAD_ENV, helper_threads_allowed

    os.environ.pop(READ_AHEAD_ENV, None)   # the analysis as a user runs it: its own choice
    chose: dict[int, list[bool]] = {b: [] for b in args.blocks}
    load0 = os.getloadavg()
    tmp = args.bag_dir or Path(tempfile.mkdtemp(prefix='rv-te-analyze-bench-'))
    tmp.mkdir(parents=True, exist_ok=True)
    rows = []
    budget_cpu: dict[int, float] = {}
    proc_rows: list[tuple[int, dict[str, float]]] = []
    for block in args.blocks:
        bag, n = sample_bag(tmp, block, args.minutes, args.rate_hz)
        size_mb = sum(f.stat().st_size for f in bag.iterdir()) / 1e6

        def ours_read(bag: Path = bag) -> int:
            return sum(it.n_samples if isinstance(it, EncoderBatch) else len(it.theta_in_rad)
                       for it in read_encoder_batches(bag,
                                                      read_ahead=helper_threads_allowed()))

        def analyze(bag: Path = bag) -> int:
            return int(analyze_bag(bag, with_advice=False).cumulative.n_samples)

        def forced(mode: str, bag: Path = bag) -> int:
            os.environ[READ_AHEAD_ENV] = mode
            try:
                return int(analyze_bag(bag, with_advice=False).cumulative.n_samples)
            finally:
                os.environ.pop(READ_AHEAD_ENV, None)

        paths = [('rosbags', lambda bag=bag: rosbags_read(bag)), ('read', ours_read),
                 ('analyze', analyze)]
        if args.paths == 'both':
            paths += [('helper', lambda: forced('1')), ('inline', lambda: forced('0'))]
        if base_core is not None:
            paths.insert(2, ('base', lambda bag=bag: analyze_base(bag)))
            paths.insert(1, ('baseread', lambda bag=bag: read_base(bag)))
        if args.floor:
            windows = _spectrum_inputs(bag)
            paths.insert(2, ('floor', lambda windows=windows: ours_read() + _spectra(windows)))
        wall: dict[str, list[float]] = {name: [] for name, _fn in paths}
        cpu: dict[str, list[float]] = {name: [] for name, _fn in paths}
        for _ in range(args.repeats):   # interleaved, so machine noise hits all alike
            for name, fn in paths:
                taken.clear()
                c0, t0 = time.process_time(), time.perf_counter()
                got = fn()
                wall[name].append(time.perf_counter() - t0)
                cpu[name].append(time.process_time() - c0)
                if name == 'analyze':
                    chose[block].append(taken.path() == 'helper')
                if got < n * 0.99:
                    print(f'ERROR: {name} saw {got} of {n} samples', file=sys.stderr)
                    return 1
        med = {k: statistics.median(v) for k, v in wall.items()}
        med_cpu = {k: statistics.median(v) for k, v in cpu.items()}
        budget_cpu[block] = _budget_cpu(bag)
        ratios = {k: sorted(a / r for a, r in zip(wall[k], wall['rosbags'], strict=True))
                  for k in ('analyze', 'base', 'helper', 'inline') if k in wall}
        # CPU over the rosbags read's CPU, repeat by repeat (the same stretch of load)
        cpu_ratio = {k: statistics.median(a / r for a, r in zip(v, cpu['rosbags'], strict=True))
                     for k, v in cpu.items()}
        rows.append((block, n, size_mb, med, med_cpu, ratios, cpu_ratio))
        if args.process_repeats > 0:
            proc_rows.append((block, _whole_commands(bag, args.process_repeats)))

    print(f'\nmachine: {platform.node()} {platform.machine()}, {_cpu_model()}, '
          f'{os.cpu_count()} cores, '
          f'{"this process on ONE core (as taskset -c 0)" if args.one_core else "both cores"}'
          f'{", a CPU-bound process on the other core" if busy else ""}, '
          f'python {platform.python_version()}, date {time.strftime("%Y-%m-%d")}; '
          f'{args.minutes:g} min at {args.rate_hz:g} Hz, median of {args.repeats}; '
          f'allocator: {"tuned as rv-te analyze" if tuned else "glibc defaults"}; '
          f'load average {load0[0]:.2f} at the start, {os.getloadavg()[0]:.2f} at the end'
          + (f'; before = analysis at {args.baseline}' if args.baseline else '') + '\n')
    print('| block | path | wall [s] | CPU [s] | samples/s | wall / rosbags read | '
          'CPU / rosbags read |')
    print('|---|---|---|---|---|---|---|')
    for block, n, size_mb, med, med_cpu, ratios, cpu_ratio in rows:
        picked = chose[block]
        auto = ('helper thread' if all(picked) else 'one thread' if not any(picked)
                else f'helper thread {sum(picked)} of {len(picked)}')
        for name, label in (('rosbags', 'rosbags AnyReader read + deserialise (floor)'),
                            ('baseread', f'read_encoder_batches before (reader at '
                                         f'{args.baseline})'),
                            ('read', 'read_encoder_batches (our reader)'),
                            ('floor', 'our reader + resampling + FFT of every window (the '
                                      'least work of an order spectrum)'),
                            ('base', f'analyze_bag before (analysis at {args.baseline})'),
                            ('analyze', 'analyze_bag (read + TE + windows + spectra)'
                             + (f'; its choice: {auto}' if args.paths == 'both' else '')),
                            ('helper', 'analyze_bag forced on the helper-thread path'),
                            ('inline', 'analyze_bag forced on the one-thread path')):
            if name not in med:
                continue
            extra = ''
            if name in ratios:
                extra = f' (per repeat {ratios[name][0]:.2f}..{ratios[name][-1]:.2f})'
            if name == 'analyze' and 'base' in med:
                extra += f'; {med["base"] / med["analyze"]:.2f}x faster than before'
            print(f'| {block} ({size_mb:.0f} MB) | {label} | {med[name]:.2f} | '
                  f'{med_cpu[name]:.2f} | {n / med[name] / 1e6:.2f} M | '
                  f'{med[name] / med["rosbags"]:.2f}{extra} | {cpu_ratio[name]:.2f} |')
    if budget_cpu:
        print('\nThe uncertainty budgets alone (issue 35: TE p-p, every line; '
              '`report.uncertainty.analysis_uncertainty` on the analysis of the bag, CPU time of '
              'this thread, median of 21; the load does not enter a CPU time):\n')
        print('| block | budgets CPU [ms] | analyze_bag CPU [ms] | budgets / analysis |')
        print('|---|---|---|---|')
        for (block, _n, _size, _med, med_cpu, _r, _c) in rows:
            b = budget_cpu[block]
            print(f'| {block} | {1e3 * b:.1f} | {1e3 * med_cpu["analyze"]:.0f} | '
                  f'{100 * b / med_cpu["analyze"]:.1f} % |')
    if proc_rows:
        print('\nWhole commands in fresh processes (median of '
              f'{args.process_repeats}; interpreter start and imports included):\n')
        print('| block | rosbags read script [s] | `rv-te analyze --json --no-advice` [s] | '
              'ratio |')
        print('|---|---|---|---|')
        for block, t in proc_rows:
            print(f'| {block} | {t["rosbags"]:.2f} | {t["analyze"]:.2f} | '
                  f'{t["analyze"] / t["rosbags"]:.2f} |')
    return 0


def _spectrum_inputs(bag: Path) -> list[tuple[np.ndarray, np.ndarray, int]]:
    """(phi, TE, revolutions) of every complete window whose spectrum the analysis of
    ``bag`` computes (copies, captured from one analysis; not timed)."""
    import numpy as np

    from rv_te_bench.core import stream
    from rv_te_bench.report.analysis import analyze_bag

    got: list[tuple[np.ndarray, np.ndarray, int]] = []
    real = stream.order_spectrum

    def keep(phi: np.ndarray, te: np.ndarray, *args: object, **kwargs: Any) -> object:
        got.append((np.array(phi), np.array(te), kwargs.get('revolutions')))
        return real(phi, te, *args, **kwargs)

    stream.order_spectrum = keep
    try:
        analyze_bag(bag, with_advice=False)
    finally:
        stream.order_spectrum = real
    return got


def _spectra(windows: list[tuple[np.ndarray, np.ndarray, int]]) -> int:
    """Resample each window to the angle grid and FFT it, as the analysis does (one
    workspace, numpy's FFT); 0 samples (the reader beside it counts them)."""
    import numpy as np

    from rv_te_bench.core.spectrum import SpectrumWorkspace, resample_to_output_angle

    work = SpectrumWorkspace()
    for phi, te, revolutions in windows:
        res = resample_to_output_angle(phi, te, revolutions=revolutions, workspace=work)
        np.fft.rfft(res.te_rad)
    return 0


def _budget_cpu(bag: Path) -> float:
    """CPU time [s] of the analysis's uncertainty budgets (median of 21 runs)."""
    from rv_te_bench.report.analysis import analyze_bag
    from rv_te_bench.report.uncertainty import analysis_uncertainty

    res = analyze_bag(bag, with_advice=False)
    times = []
    for _ in range(21):
        c0 = time.thread_time()
        analysis_uncertainty(info=res.bench.info, gear_ratio=res.bench.gear_ratio,
                             windows=res.windows, cumulative=res.cumulative,
                             spectrum=res.spectrum, trace=res.trace)
        times.append(time.thread_time() - c0)
    return statistics.median(times)


class _reader_as_at:  # noqa: N801 - used like a function
    """Today's bag reader set as at git revision ``rev``, for the "before" rows.

    The chunks read ahead (``PREFETCH_CHUNKS``, 2 before issue 23's round 4) and the CRC-32
    (isal's from round 4, zlib's before) are read from ``rev``'s _mcap_scan.py; an old
    ``analyze_blocks`` without ``spectra_thread`` gets the call without it (its spectra
    then run in line, as they did); an analysis from before the bench record (issue 39)
    gets ``read_bench_info`` as the dict of fields it read then.
    """

    def __init__(self, rev: str, core: dict) -> None:
        import re
        import subprocess

        text = subprocess.run(
            ['git', '-C', str(ROOT), 'show', f'{rev}:rv_te_bench/io/_mcap_scan.py'],
            check=True, capture_output=True, text=True).stdout
        found = re.search(r'^PREFETCH_CHUNKS = (\d+)', text, re.MULTILINE)
        self._prefetch = int(found.group(1)) if found else 2
        self._isal = 'isal' in text
        self._stream = core['rv_te_bench.core.offline']   # where analyze_blocks is
        self._info_dict = subprocess.run(
            ['git', '-C', str(ROOT), 'cat-file', '-e', f'{rev}:sim/bench_info.py'],
            check=False, capture_output=True).returncode != 0

    def __enter__(self) -> None:
        import inspect
        import zlib

        from rv_te_bench.io import _mcap_scan, bag_reader

        self._saved = (_mcap_scan.PREFETCH_CHUNKS, _mcap_scan._crc32,
                       self._stream.analyze_blocks, bag_reader.read_bench_info)
        if self._info_dict:
            record = bag_reader.read_bench_info

            def as_dict(path: str | Path, topic: str | None = None) -> dict | None:
                info = record(path, topic)
                return None if info is None else info.message_values()

            bag_reader.read_bench_info = as_dict
        _mcap_scan.PREFETCH_CHUNKS = self._prefetch
        if not self._isal:
            _mcap_scan._crc32 = zlib.crc32
        old = self._stream.analyze_blocks
        if 'spectra_thread' not in inspect.signature(old).parameters:
            self._stream.analyze_blocks = (
                lambda blocks, config, *, on_window=None, spectra_thread=False:
                old(blocks, config, on_window=on_window))

    def __exit__(self, *exc: object) -> None:
        from rv_te_bench.io import _mcap_scan, bag_reader

        (_mcap_scan.PREFETCH_CHUNKS, _mcap_scan._crc32, self._stream.analyze_blocks,
         bag_reader.read_bench_info) = self._saved


def _cpu_model() -> str:
    """The CPU model (as ``lscpu`` prints 'Model name')."""
    try:
        for line in Path('/proc/cpuinfo').read_text().splitlines():
            if line.startswith('model name'):
                return line.split(':', 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or 'unknown CPU'


def rosbags_read(bag: str | Path) -> int:
    """The floor: rosbags AnyReader reads and deserialises every EncoderBlock; samples seen."""
    from rosbags.highlevel import AnyReader

    from rv_te_bench.io.msgdefs import rv_te_typestore

    count = 0
    with AnyReader([Path(bag)], default_typestore=rv_te_typestore()) as reader:
        conns = [c for c in reader.connections if c.topic.endswith('bench/encoders')]
        for conn, _t, raw in reader.messages(connections=conns):
            count += len(reader.deserialize(raw, conn.msgtype).theta_in_rad)
    return count


# the floor as a command: this file's rosbags_read in a fresh interpreter
_ROSBAGS_SCRIPT = ('import sys; sys.path[:0] = sys.argv[2:]; '
                   'from bench_analyze import rosbags_read; print(rosbags_read(sys.argv[1]))')


def _whole_commands(bag: Path, repeats: int) -> dict[str, float]:
    """Median wall time of the two commands, interleaved."""
    commands = {
        'rosbags': [sys.executable, '-c', _ROSBAGS_SCRIPT, str(bag), str(ROOT / 'benchmarks'),
                    str(ROOT)],
        'analyze': [sys.executable, '-m', 'rv_te_bench.cli.main', 'analyze', str(bag),
                    '--json', '--no-advice', '--quiet'],
    }
    times: dict[str, list[float]] = {k: [] for k in commands}
    for _ in range(repeats):
        for name, cmd in commands.items():
            t0 = time.perf_counter()
            proc = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, timeout=600,
                                  check=False)
            times[name].append(time.perf_counter() - t0)
            if proc.returncode != 0:   # say why (a bare CalledProcessError did not)
                msg = f'{name} exited {proc.returncode}: {proc.stderr.strip()[-2000:]}'
                raise RuntimeError(msg)
    return {k: statistics.median(v) for k, v in times.items()}


if __name__ == '__main__':
    sys.exit(main())
