"""Fleet analysis on Dask: 100 bags with 1 and 2 workers, against a plain loop.

Run: ``.venv/bin/python benchmarks/bench_fleet.py [--bags 100] [--dir /tmp/rv-te-fleet-bench]``.
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
analysis replaced by a stub that returns a ready record, so that what is left is the
engine's own cost per bag (cluster start-up and shut-down, hand-over, results back), which
the analyses' run-to-run spread on a loaded machine (+-10 % of ~0.5 CPU s per bag) would
hide in the full comparison.
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


def _forkserver_cpu() -> float:
    """CPU seconds of multiprocessing's fork server so far, with its children that ended
    (the workers forked from it, reaped by it), 0 when none runs."""
    from multiprocessing import forkserver
    pid = getattr(forkserver._forkserver, '_forkserver_pid', None)
    if not pid:
        return 0.0
    try:
        fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    except OSError:
        return 0.0
    return sum(int(f) for f in fields[11:15]) / os.sysconf('SC_CLK_TCK')


def _fleet(bags: list[Path], store_path: Path, opts: object, workers: int
           ) -> tuple[float, float]:
    """(wall, CPU) of one run_fleet: this process + the workers + the fork server."""
    from rv_te_bench.fleet import run_fleet
    from rv_te_bench.store import open_store

    fs0, c0, t = 0.0, _cpu_self(), time.perf_counter()
    with open_store(store_path) as st:
        s = run_fleet(bags, st, options=opts, workers=workers)  # type: ignore[arg-type]
    wall = time.perf_counter() - t
    assert s.ok == len(bags), s
    time.sleep(1.0)      # the fork server reaps the workers (their CPU joins its children's)
    cpu = _cpu_self() - c0 + _forkserver_cpu() - fs0
    # stopped, so that each run starts (and pays for) its own, as each rv-te command does
    from multiprocessing import forkserver
    forkserver._forkserver._stop()  # type: ignore[attr-defined]
    return wall, cpu


def _stub_batch(paths: list[str], options: object) -> list[object]:
    """The engine without the analysis: each bag's record is a copy of one made before
    (defined in ``__main__``, so Dask ships it to the workers by value)."""
    import dataclasses
    return [dataclasses.replace(_TEMPLATE[0], bag_path=p,
                                bag_sha256=f'{abs(hash(p)):064x}'[-64:]) for p in paths]


_TEMPLATE: list[object] = []


def engine_overhead(bags: list[Path], opts: object, repeats: int) -> str:
    """Per-bag cost of the engine alone: run_fleet with 1 and 2 workers whose analysis is a
    stub returning a ready record, against a loop of the same stub + store.upsert (medians
    of ``repeats`` rotated rounds; start-up and shut-down included)."""
    from rv_te_bench.fleet import _run, analyse_one
    from rv_te_bench.store import open_store

    _TEMPLATE.append(analyse_one(str(bags[0]), opts))   # type: ignore[arg-type]
    real = _run.analyse_batch
    got: dict[str, list[tuple[float, float]]] = {'loop': [], '1': [], '2': []}
    with tempfile.TemporaryDirectory() as tmp:
        try:
            _run.analyse_batch = _stub_batch   # type: ignore[assignment]
            for r in range(repeats):
                for k in range(3):
                    how = ('loop', '1', '2')[(k + r) % 3]
                    db = Path(tmp) / f'e{r}{k}.sqlite'
                    if how == 'loop':
                        c0, t = _cpu_self(), time.perf_counter()
                        with open_store(db) as st:
                            for rec in _stub_batch([str(b) for b in bags], opts):
                                st.upsert(rec)   # type: ignore[arg-type]
                        got[how].append((time.perf_counter() - t, _cpu_self() - c0))
                    else:
                        got[how].append(_fleet(bags, db, opts, int(how)))
        finally:
            _run.analyse_batch = real
    med = {k: (statistics.median(w for w, _ in v), statistics.median(c for _, c in v))
           for k, v in got.items()}
    n = len(bags)
    rows = [f'| {name} | {med[k][0]:.2f} | {med[k][1]:.2f} | '
            f'{(med[k][0] - med["loop"][0]) / n * 1e3:.1f} | '
            f'{(med[k][1] - med["loop"][1]) / n * 1e3:.1f} |'
            for k, name in (('loop', 'loop: stub + store.upsert'),
                            ('1', 'run_fleet, 1 worker, stub analysis'),
                            ('2', 'run_fleet, 2 workers, stub analysis'))]
    return '\n'.join([f'Engine alone, {n} bags, median of {repeats} (load '
                      f'{os.getloadavg()[0]:.1f} at the end):', '',
                      '| how | wall s | CPU s | wall overhead per bag [ms] | CPU overhead per '
                      'bag [ms] |', '|---|---:|---:|---:|---:|', *rows])


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark and print the table."""
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
    args = ap.parse_args(argv)
    t = time.perf_counter()
    bags = make_bags(args.dir, args.bags, rate_hz=args.rate_hz, revolutions=args.revolutions)
    print(f'{len(bags)} bags ready in {time.perf_counter() - t:.1f} s', file=sys.stderr)
    opts = FleetOptions(with_advice=not args.no_advice)
    print(f'{_cpu_model()}, {os.cpu_count()} CPUs, load {os.getloadavg()[0]:.1f} at the start',
          flush=True)
    print(engine_overhead(bags, opts, max(args.repeats, 3)), flush=True)
    if args.engine_only:
        return 0
    loads = [os.getloadavg()[0]]
    names = ['plain loop (this process)', 'run_fleet, local cluster of 1 worker',
             'run_fleet, local cluster of 2 workers']
    got: dict[str, list[tuple[float, float]]] = {n: [] for n in names}
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
                    got[name].append((time.perf_counter() - t, _cpu_self() - c0))
                else:
                    got[name].append(_fleet(bags, db, opts, 1 if '1 worker' in name else 2))
                loads.append(os.getloadavg()[0])
                print(f'{name}: wall {got[name][-1][0]:.1f} s, CPU {got[name][-1][1]:.1f} s, '
                      f'load {loads[-1]:.1f}', file=sys.stderr, flush=True)
    med = {n: (statistics.median(w for w, _ in v), statistics.median(c for _, c in v))
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
