"""Fleet analysis on Dask: 100 bags with 1 and 2 workers, against a plain loop.

Run: ``.venv/bin/python benchmarks/bench_fleet.py [--bags 100] [--dir /tmp/rv-te-fleet-bench]``
(``--engine-only --engine-repeats 3`` for the engine alone, a few minutes).
Prints a markdown table (and writes it to ``--out`` if given).

The bags (written once into ``--dir`` and reused) are units of the Wang 2020 2K-V with
random eccentricities and phases (tests/wang2020_reference.py), 2 output revolutions at
10 kHz each (316,000 samples, rosbags-written, uncompressed). Three ways to analyse them
all, each into a fresh SQLite store, side by side in one run (``--repeats`` rounds, the
order rotated; medians printed):

* plain loop: ``analyse_one`` + ``store.upsert`` per bag in this process (the floor);
* ``run_fleet`` with a local cluster of 1 worker, and of 2 workers (cluster start-up and
  shut-down included: they are part of what a user waits for).

Besides wall times, CPU times: this process (client, scheduler, nannies) and the fork
server the workers are forked from (its imports, once per run, and its reaped children, the
workers: utime + stime + cutime + cstime from ``/proc``). The per-bag overhead of the engine
is (CPU of the 1-worker run - CPU of the loop) / bags: the work the fleet adds, which a
loaded machine does not inflate the way it inflates wall times; the wall figure is beside it.
The speed-up (loop wall / 2-worker wall) needs two free cores: the load is printed with it.

First, the engine alone (``--engine-only`` stops there): the same three ways with the
analysis replaced by a stub that returns a ready record (``_fleet_stub.py``, sent to the
workers by reference like the real analysis), so that what is left is the engine's own
cost (cluster start-up and shut-down, hand-over, results back, store writes), which the
analyses' run-to-run spread on a loaded machine (+-10 % of ~0.5 CPU s per bag) would hide
in the full comparison. It runs at two numbers of bags (``--engine-sizes``, default a
fifth of ``--bags`` and ``--bags``), which splits the engine's cost into a fixed cost per
run (the cluster, the fork server's imports) and a cost per bag: "overhead per bag" at 100
bags is both, the fixed part divided by 100.
"""

from __future__ import annotations

import argparse
import os
import platform
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def make_bags(directory: Path, n: int, *, rate_hz: float, revolutions: float) -> list[Path]:
    """``n`` unit bags in ``directory`` (kept: reused by later runs)."""
    from tests import wang2020_reference as ref
    from tests.unit_bags import unit_bag
    directory.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(2026)
    duration_s = revolutions * 60.0 * ref.RATIO / 300.0
    bags = []
    for i in range(n):
        unit = ref.random_unit(rng)
        path = directory / f'unit{i:04d}'
        if not path.exists():
            unit_bag(path, unit, rng, rate_hz=rate_hz, duration_s=duration_s)
        bags.append(path.resolve())
    return bags


def _cpu_self() -> float:
    ru = resource.getrusage(resource.RUSAGE_SELF)
    return ru.ru_utime + ru.ru_stime


def _forkserver_cpu() -> tuple[float, float]:
    """CPU seconds of multiprocessing's fork server so far: (its own: its imports and the
    forking, its children that ended: the workers forked from it, reaped by it), zeros
    when none runs."""
    from multiprocessing import forkserver
    pid = getattr(forkserver._forkserver, '_forkserver_pid', None)
    if not pid:
        return 0.0, 0.0
    try:
        fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    except OSError:
        return 0.0, 0.0
    tck = os.sysconf('SC_CLK_TCK')
    return sum(int(f) for f in fields[11:13]) / tck, sum(int(f) for f in fields[13:15]) / tck


def _fleet(bags: list[Path], store_path: Path, opts: object, workers: int
           ) -> tuple[float, float, float]:
    """(wall, CPU, the fork server's own CPU) of one run_fleet: CPU of this process + the
    workers + the fork server (its own: its imports, what the loop's process imported
    before its clock started)."""
    from rv_te_bench.fleet import run_fleet
    from rv_te_bench.store import open_store

    c0, t = _cpu_self(), time.perf_counter()
    with open_store(store_path) as st:
        s = run_fleet(bags, st, options=opts, workers=workers)  # type: ignore[arg-type]
    wall = time.perf_counter() - t
    assert s.ok == len(bags), s
    time.sleep(1.0)      # the fork server reaps the workers (their CPU joins its children's)
    own, children = _forkserver_cpu()
    cpu = _cpu_self() - c0 + own + children
    # stopped, so that each run starts (and pays for) its own, as each rv-te command does
    from multiprocessing import forkserver
    forkserver._forkserver._stop()  # type: ignore[attr-defined]
    return wall, cpu, own


def engine_overhead(bags: list[Path], opts: object, repeats: int, sizes: list[int]) -> str:
    """Cost of the engine alone: run_fleet with 1 and 2 workers whose analysis is a stub
    returning a ready record (``_fleet_stub``), against a loop of the same stub +
    store.upsert, each at every number of bags in ``sizes`` (medians of ``repeats``
    rotated rounds; start-up and shut-down included). Two sizes split the engine's cost
    into a fixed cost per run (the intercept) and a cost per bag (the slope)."""
    import pickle

    import _fleet_stub

    from rv_te_bench.fleet import _run, analyse_one
    from rv_te_bench.store import open_store

    ways = ('loop', '1', '2')
    got: dict[tuple[str, int], list[tuple[float, float, float]]] = {
        (w, n): [] for w in ways for n in sizes}
    loads = [os.getloadavg()[0]]
    with tempfile.TemporaryDirectory() as tmp:
        template = Path(tmp) / 'template.pickle'
        template.write_bytes(pickle.dumps(analyse_one(str(bags[0]), opts)))  # type: ignore[arg-type]
        os.environ[_fleet_stub.TEMPLATE_ENV] = str(template)
        real = _run.analyse_batch
        try:
            _run.analyse_batch = _fleet_stub.stub_batch   # type: ignore[assignment]
            for r in range(repeats):
                for k in range(len(ways) * len(sizes)):
                    j = (k + r) % (len(ways) * len(sizes))
                    how, n = ways[j % len(ways)], sizes[j // len(ways)]
                    db = Path(tmp) / f'e{r}{k}.sqlite'
                    if how == 'loop':
                        c0, t = _cpu_self(), time.perf_counter()
                        with open_store(db) as st:
                            for rec in _fleet_stub.stub_batch([str(b) for b in bags[:n]],
                                                              opts):
                                st.upsert(rec)
                        got[how, n].append((time.perf_counter() - t, _cpu_self() - c0, 0.0))
                    else:
                        got[how, n].append(_fleet(bags[:n], db, opts, int(how)))
                    loads.append(os.getloadavg()[0])
        finally:
            _run.analyse_batch = real
            os.environ.pop(_fleet_stub.TEMPLATE_ENV, None)
    med = {key: tuple(statistics.median(x[i] for x in v) for i in range(3))
           for key, v in got.items()}
    names = {'loop': 'loop: stub + store.upsert', '1': 'run_fleet, 1 worker, stub analysis',
             '2': 'run_fleet, 2 workers, stub analysis'}
    rows = []
    for n in sizes:
        for w in ways:
            (mw, mc, mo), (lw, lc, _) = med[w, n], med['loop', n]
            rows.append(f'| {names[w]} | {n} | {mw:.2f} | {mc:.2f} | {mo:.2f} | '
                        f'{(mw - lw) / n * 1e3:.1f} | {(mc - lc) / n * 1e3:.1f} | '
                        f'{(mc - mo - lc) / n * 1e3:.1f} |')
    lines = [f'Engine alone, median of {repeats} (load {min(loads):.1f}-{max(loads):.1f}):', '',
             '| how | bags | wall s | CPU s | of which the fork server\'s imports, CPU s | '
             'wall overhead per bag [ms] | CPU overhead per bag [ms] | CPU overhead per bag '
             'without those imports [ms] |', '|---|---:|---:|---:|---:|---:|---:|---:|', *rows]
    if len(sizes) >= 2:
        a, b = sizes[0], sizes[-1]
        lines.append('')
        for w in ('1', '2'):
            # overhead = fleet - loop, split into a line through the two sizes
            ow = [med[w, n][0] - med['loop', n][0] for n in (a, b)]
            oc = [med[w, n][1] - med['loop', n][1] for n in (a, b)]
            imports = statistics.median(med[w, n][2] for n in (a, b))
            slope_w, slope_c = (ow[1] - ow[0]) / (b - a), (oc[1] - oc[0]) / (b - a)
            lines.append(f'- {w} worker(s): fixed per run **{oc[0] - slope_c * a:.2f} CPU s** '
                         f'(of which the fork server\'s imports {imports:.2f} s), '
                         f'{ow[0] - slope_w * a:.2f} s wall; per bag beyond that '
                         f'**{slope_c * 1e3:.1f} ms CPU**, {slope_w * 1e3:.1f} ms wall '
                         f'(a line through {a} and {b} bags)')
    return '\n'.join(lines)


def _loop_child(bags: list[Path], with_advice: bool) -> None:
    """One plain loop of ``analyse_one`` (no store) in this fresh process: prints wall, CPU."""
    import json

    from rv_te_bench.fleet import FleetOptions, analyse_one
    opts = FleetOptions(with_advice=with_advice)
    analyse_one(str(bags[0]), opts)   # imports and first-call costs outside the clock
    c0, t = _cpu_self(), time.perf_counter()
    for b in bags:
        analyse_one(str(b), opts)
    print(json.dumps({'wall_s': time.perf_counter() - t, 'cpu_s': _cpu_self() - c0}))


def blas_loop(bags: list[Path], with_advice: bool, repeats: int) -> str:
    """The plain loop with OpenBLAS's pool of a thread per core (before c8be8b8, forced here
    with OPENBLAS_NUM_THREADS=2) and with the batch setting's one thread, each in a fresh
    process, alternating; on both cores and pinned to one (``taskset -c 0``)."""
    import json
    ways = [('both cores', 'a BLAS thread per core (before)', '2', False),
            ('both cores', 'one BLAS thread (batch setting)', None, False),
            ('one core', 'a BLAS thread per core (before)', '2', True),
            ('one core', 'one BLAS thread (batch setting)', None, True)]
    got: dict[int, list[tuple[float, float]]] = {k: [] for k in range(len(ways))}
    loads = [os.getloadavg()[0]]
    for r in range(repeats):
        for k in (range(len(ways)) if r % 2 == 0 else reversed(range(len(ways)))):
            _, _, threads, pin = ways[k]
            env = dict(os.environ)
            env.pop('OPENBLAS_NUM_THREADS', None)
            if threads is not None:
                env['OPENBLAS_NUM_THREADS'] = threads
            cmd = [*(['taskset', '-c', '0'] if pin else []), sys.executable, __file__,
                   '--loop-child', *map(str, bags), *(['--no-advice'] if not with_advice
                                                       else [])]
            out = subprocess.run(cmd, capture_output=True, text=True, check=True, env=env)
            d = json.loads(out.stdout.strip().splitlines()[-1])
            got[k].append((d['wall_s'], d['cpu_s']))
            loads.append(os.getloadavg()[0])
            print(f'{ways[k][0]}, {ways[k][1]}: wall {d["wall_s"]:.2f} s, CPU '
                  f'{d["cpu_s"]:.2f} s, load {loads[-1]:.1f}', file=sys.stderr, flush=True)
    lines = [f'Plain loop of analyse_one over {len(bags)} bags (advice '
             f'{"on" if with_advice else "off"}), fresh process per run, alternating; '
             f'{_cpu_model()}, load {min(loads):.1f}-{max(loads):.1f}; median of {repeats}',
             '', '| cores | BLAS | wall s | CPU s | CPU / wall | CPU vs one BLAS thread |',
             '|---|---|---:|---:|---:|---:|']
    for k, (cores, blas, _, _) in enumerate(ways):
        w = statistics.median(x[0] for x in got[k])
        c = statistics.median(x[1] for x in got[k])
        ref = statistics.median(x[1] for x in got[k | 1])
        lines.append(f'| {cores} | {blas} | {w:.2f} | {c:.2f} | {c / w:.2f} | '
                     f'{c / ref:.2f}x |')
    return '\n'.join(lines)


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark and print the table."""
    if argv is None and '--loop-child' in sys.argv:
        paths = [Path(a) for a in sys.argv[sys.argv.index('--loop-child') + 1:]
                 if not a.startswith('--')]
        _loop_child(paths, '--no-advice' not in sys.argv)
        return 0
    import distributed  # noqa: F401 - imported up front: charged to neither side

    import rv_te_bench.fleet._warm  # noqa: F401 - the loop's imports, outside its clock
    from rv_te_bench.fleet import FleetOptions, analyse_one
    from rv_te_bench.store import open_store

    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--bags', type=int, default=100)
    ap.add_argument('--rate-hz', type=float, default=10_000.0)
    ap.add_argument('--revolutions', type=float, default=2.0)
    ap.add_argument('--repeats', type=int, default=1)
    ap.add_argument('--dir', type=Path, default=Path(tempfile.gettempdir()) / 'rv-te-fleet-bench')
    ap.add_argument('--no-advice', action='store_true')
    ap.add_argument('--out', type=Path, default=None)
    ap.add_argument('--engine-only', action='store_true',
                    help='only the engine alone (a stub analysis): per-bag hand-over cost')
    ap.add_argument('--engine-sizes', type=int, nargs='+', default=None,
                    help='numbers of bags of the engine-alone runs (default: a fifth of '
                         '--bags and --bags: the fixed cost per run and the cost per bag)')
    ap.add_argument('--engine-repeats', type=int, default=3,
                    help='rounds of the engine-alone runs (0: none, only the full runs)')
    ap.add_argument('--blas-loop', type=int, default=0, metavar='BAGS',
                    help='only the plain loop over the first BAGS bags with a BLAS thread '
                         'per core and with one, side by side (--repeats rounds)')
    args = ap.parse_args(argv)
    t = time.perf_counter()
    bags = make_bags(args.dir, args.bags, rate_hz=args.rate_hz, revolutions=args.revolutions)
    print(f'{len(bags)} bags ready in {time.perf_counter() - t:.1f} s', file=sys.stderr)
    if args.blas_loop:
        print(blas_loop(bags[:args.blas_loop], not args.no_advice, args.repeats), flush=True)
        return 0
    opts = FleetOptions(with_advice=not args.no_advice)
    print(f'{_cpu_model()}, {os.cpu_count()} CPUs, load {os.getloadavg()[0]:.1f} at the start',
          flush=True)
    sizes = args.engine_sizes or sorted({max(1, len(bags) // 5), len(bags)})
    if args.engine_repeats > 0:
        print(engine_overhead(bags, opts, args.engine_repeats, sizes), flush=True)
    if args.engine_only:
        return 0
    loads = [os.getloadavg()[0]]
    names = ['plain loop (this process)', 'run_fleet, local cluster of 1 worker',
             'run_fleet, local cluster of 2 workers']
    got: dict[str, list[tuple[float, float, float]]] = {n: [] for n in names}
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(args.repeats):
            for k in range(3):
                name = names[(k + r) % 3]
                db = Path(tmp) / f'{r}-{k}.sqlite'
                if name.startswith('plain'):
                    c0, t = _cpu_self(), time.perf_counter()
                    with open_store(db) as st:
                        for b in bags:
                            st.upsert(analyse_one(str(b), opts))
                    got[name].append((time.perf_counter() - t, _cpu_self() - c0, 0.0))
                else:
                    got[name].append(_fleet(bags, db, opts, 1 if '1 worker' in name else 2))
                loads.append(os.getloadavg()[0])
                print(f'{name}: wall {got[name][-1][0]:.1f} s, CPU {got[name][-1][1]:.1f} s, '
                      f'load {loads[-1]:.1f}', file=sys.stderr, flush=True)
    med = {n: (statistics.median(x[0] for x in v), statistics.median(x[1] for x in v))
           for n, v in got.items()}
    (loop_w, loop_c), (one_w, one_c), (two_w, two_c) = (med[n] for n in names)
    n = len(bags)
    lines = [f'Fleet analysis of {n} bags ({args.revolutions:g} output revolutions at '
             f'{args.rate_hz:g} Hz each; advice {"off" if args.no_advice else "on"}); '
             f'{_cpu_model()}, {os.cpu_count()} CPUs, CPython {platform.python_version()}, '
             f'load {min(loads):.1f}-{max(loads):.1f}; median of {args.repeats}',
             '', '| how | wall s | CPU s | bags/s |', '|---|---:|---:|---:|']
    lines += [f'| {name} | {med[name][0]:.1f} | {med[name][1]:.1f} | {n / med[name][0]:.2f} |'
              for name in names]
    lines += ['', f'2 workers vs the plain loop: **{loop_w / two_w:.2f}x** (vs 1 worker '
              f'{one_w / two_w:.2f}x); engine overhead per bag (1 worker vs the loop, start-up '
              f'and shut-down included): CPU **{(one_c - loop_c) / n * 1e3:.0f} ms**, wall '
              f'{(one_w - loop_w) / n * 1e3:.0f} ms; 2 workers vs the loop: CPU '
              f'{(two_c - loop_c) / n * 1e3:.0f} ms per bag']
    text = '\n'.join(lines)
    print(text)
    if args.out is not None:
        args.out.write_text(text + '\n')
    return 0


def _cpu_model() -> str:
    try:
        out = subprocess.run(['lscpu'], capture_output=True, text=True, check=False).stdout
    except OSError:
        return platform.processor() or '?'
    return next((ln.split(':', 1)[1].strip() for ln in out.splitlines()
                 if ln.startswith('Model name')), '?')


if __name__ == '__main__':
    sys.exit(main())
