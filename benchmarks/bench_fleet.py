"""Fleet analysis on Dask: 100 bags with 1 and 2 workers, against a plain loop.

Run: ``.venv/bin/python benchmarks/bench_fleet.py [--bags 100] [--dir /tmp/rv-te-fleet-bench]``.
Prints a markdown table (and writes it to ``--out`` if given).

The bags (written once into ``--dir`` and reused) are units of the Wang 2020 2K-V with
random eccentricities and phases (tests/wang2020_reference.py), 2 output revolutions at
10 kHz each (316,000 samples, rosbags-written, uncompressed). Three ways to analyse them
all, each into a fresh SQLite store, in one run:

* plain loop: ``analyse_one`` + ``store.upsert`` per bag in this process (the floor);
* ``run_fleet`` with a local cluster of 1 worker, and of 2 workers (cluster start-up
  included: it is part of what a user waits for); the 2 workers once as shipped (on a
  2-core machine they read without the read-ahead thread) and once with it (as before).

Speed-up = 1-worker time / 2-worker time; per-bag overhead of the engine =
(1-worker time - loop time) / bags.
"""

from __future__ import annotations

import argparse
import os
import platform
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


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark and print the table."""
    from rv_te_bench.fleet import FleetOptions, _run, analyse_one, run_fleet
    from rv_te_bench.store import open_store

    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--bags', type=int, default=100)
    ap.add_argument('--rate-hz', type=float, default=10_000.0)
    ap.add_argument('--revolutions', type=float, default=2.0)
    ap.add_argument('--dir', type=Path, default=Path(tempfile.gettempdir()) / 'rv-te-fleet-bench')
    ap.add_argument('--no-advice', action='store_true')
    ap.add_argument('--out', type=Path, default=None)
    args = ap.parse_args(argv)
    t = time.perf_counter()
    bags = make_bags(args.dir, args.bags, rate_hz=args.rate_hz, revolutions=args.revolutions)
    print(f'{len(bags)} bags ready in {time.perf_counter() - t:.1f} s', file=sys.stderr)
    opts = FleetOptions(with_advice=not args.no_advice)
    env_name = _run.READ_AHEAD_ENV
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        with open_store(Path(tmp) / 'loop.sqlite') as st:
            t = time.perf_counter()
            for b in bags:
                st.upsert(analyse_one(str(b), opts))
            loop_s = time.perf_counter() - t
        rows.append(('plain loop (this process)', loop_s))
        for w, ahead in ((1, None), (2, None), (2, True)):
            if ahead:   # the workers' read-ahead switch disabled: each analysis reads ahead
                _run.READ_AHEAD_ENV = 'RV_TE_BENCH_UNUSED'
            with open_store(Path(tmp) / f'w{w}{ahead}.sqlite') as st:
                t = time.perf_counter()
                s = run_fleet(bags, st, options=opts, workers=w)
                name = f'run_fleet, local cluster of {w} worker(s)'
                if w == 2:
                    name += (', read-ahead thread in each analysis (before)' if ahead else
                             ', read-ahead off (a worker per core; default)')
                rows.append((name, time.perf_counter() - t))
                assert s.ok == len(bags), s
            _run.READ_AHEAD_ENV = env_name
    one, two = rows[1][1], rows[2][1]
    load = os.getloadavg()[0]
    lines = [f'Fleet analysis of {len(bags)} bags ({args.revolutions:g} output revolutions at '
             f'{args.rate_hz:g} Hz each; advice {"off" if args.no_advice else "on"}); '
             f'CPython {platform.python_version()}, {os.cpu_count()} CPUs, load {load:.1f}',
             '', '| how | wall s | bags/s |', '|---|---:|---:|']
    lines += [f'| {name} | {sec:.1f} | {len(bags) / sec:.2f} |' for name, sec in rows]
    lines += ['', f'speed-up 2 workers vs 1: **{one / two:.2f}x** (with the read-ahead thread '
              f'in the 2 workers: {one / rows[3][1]:.2f}x); engine overhead per bag '
              f'(1 worker vs the loop, start-up included): '
              f'{(one - rows[0][1]) / len(bags) * 1e3:.0f} ms']
    text = '\n'.join(lines)
    print(text)
    if args.out is not None:
        args.out.write_text(text + '\n')
    return 0


if __name__ == '__main__':
    sys.exit(main())
