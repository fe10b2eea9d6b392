"""``rv-te fleet analyze BAG|FOLDER|GLOB... [--workers N] [--scheduler ADDRESS]``.

Analyses many bags in parallel with Dask distributed (a local cluster of N worker
processes by default; an existing Dask scheduler when an address is given, so the same
command scales from a laptop to a cluster whose workers see the same paths) and records
one result per bag in the results store as each arrives. Folders are searched for bags;
quote glob patterns (``'bags/2026-11-*'``). A damaged bag is recorded as failed with its
one-line reason and the rest go on; a worker that dies mid-bag has its bag analysed again
by another; bags whose content already has a good record are skipped unless ``--force``
(bags that failed before are tried again): known by path with the recorded size and
modification time, else by content hash. A bag copied to several paths is one record,
analysed once; the run's summary names the paths that hold the same bag.

Exit codes: 0 every bag analysed (partial ones included), 1 some bag failed or the run
could not start (one ``ERROR: ...`` line), 2 bad usage.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING

from rv_te_bench.cli._db import add_db_argument, check_record_text, db_for_bags
from rv_te_bench.cli.argtypes import int_at_least, int_between, positive_float
from rv_te_bench.core.orders import MAX_CRANK_HARMONICS
from rv_te_bench.core.stream_records import MAX_WINDOW_REVOLUTIONS
from rv_te_bench.errors import RvTeError

if TYPE_CHECKING:
    from rv_te_bench.cli.argtypes import Subparsers

__all__ = ['register', 'run']

EXAMPLES = """\
examples:
  rv-te fleet analyze bags/                       every bag below bags/, 2 local workers
  rv-te fleet analyze 'line3/2026-11-*' --workers 4 --db postgresql://qa@db/line3
  rv-te fleet analyze /data/bags --scheduler tcp://10.0.0.5:8786   an existing cluster
  rv-te fleet analyze bags/ --force --no-advice   re-analyse everything, statistics only

exit codes: 0 every bag analysed, 1 some bag failed (recorded) or the run could not start,
2 bad usage
"""

#: Seconds between two progress lines when stderr is not a terminal.
PROGRESS_PERIOD_S = 5.0
MAX_WORKERS = 256


def register(subparsers: Subparsers) -> None:
    """Add ``fleet analyze``."""
    p = subparsers.add_parser(
        'fleet', help='analyse many bags in parallel (Dask) into the results store',
        description=__doc__.split('\n\n')[1], epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest='fleet_command', metavar='ACTION', required=True)
    a = sub.add_parser('analyze', help='analyse bags into the results store',
                       description=__doc__.split('\n\n')[1], epilog=EXAMPLES,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    a.add_argument('bags', nargs='+', metavar='BAG',
                   help='bag folder, .mcap file, folder to search, or quoted glob pattern')
    a.add_argument('--workers', type=_workers_arg, default=2, metavar='N',
                   help=f'worker processes of the local cluster (1-{MAX_WORKERS}; default 2)')
    a.add_argument('--scheduler', default=None, metavar='ADDRESS',
                   help='use an existing Dask scheduler (tcp://host:8786) instead')
    a.add_argument('--force', action='store_true',
                   help='analyse again bags whose unchanged record is in the store')
    add_db_argument(a, mode='write')
    a.add_argument('--serial', default=None, help='unit serial of every bag (default: BenchInfo)')
    a.add_argument('--lot', default=None, help='production lot of every bag')
    a.add_argument('--topic', default=None, metavar='T', help='encoder topic')
    a.add_argument('--ratio', type=positive_float, default=None, metavar='I',
                   help='overall gear ratio (bags without BenchInfo)')
    a.add_argument('--crank-per-output', type=positive_float, default=None, metavar='C',
                   help='absolute crank revs per output rev (bags without BenchInfo)')
    a.add_argument('--harmonics', type=int_between(0, MAX_CRANK_HARMONICS), default=10,
                   metavar='K', help='crank harmonics reported (1 f_w .. K f_w; default 10), '
                                     f'0..{MAX_CRANK_HARMONICS} as analyze')
    a.add_argument('--window-revolutions', type=int_between(1, MAX_WINDOW_REVOLUTIONS),
                   default=1, metavar='W', help='whole output revolutions per analysis '
                   f'window (default 1), 1..{MAX_WINDOW_REVOLUTIONS} as analyze')
    a.add_argument('--no-advice', action='store_true', help='skip the recommendation')
    a.add_argument('--json', action='store_true', help='print the summary as JSON')
    a.add_argument('--quiet', action='store_true', help='no progress on stderr')
    a.set_defaults(func=run)


def _workers_arg(text: str) -> int:
    n = int_at_least(text, 1)
    if n > MAX_WORKERS:
        msg = f'must be <= {MAX_WORKERS}, got {text!r}'
        raise argparse.ArgumentTypeError(msg)
    return n


class _Progress:
    """tqdm bar on a terminal, a line every PROGRESS_PERIOD_S otherwise."""

    def __init__(self, total: int) -> None:
        self.total = total
        self.t0 = time.monotonic()
        self.next_s = PROGRESS_PERIOD_S
        self.bar = None
        if sys.stderr.isatty():
            try:
                from tqdm import tqdm
                self.bar = tqdm(total=total, unit='bag', file=sys.stderr, dynamic_ncols=True)
            except ModuleNotFoundError:
                self.bar = None

    def __call__(self, done: int, total: int, failed: int) -> None:
        if self.bar is not None:
            self.bar.set_postfix(failed=failed, refresh=False)
            self.bar.update(done - self.bar.n)
            return
        el = time.monotonic() - self.t0
        if el >= self.next_s or done == total:
            self.next_s = el + PROGRESS_PERIOD_S
            print(f'fleet: {done}/{total} bags, {failed} failed, {el:.0f} s, '
                  f'{done / el if el > 0 else 0:.2f} bags/s', file=sys.stderr, flush=True)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def run(args: argparse.Namespace) -> int:
    """Analyse the bags; 0 all analysed, 1 some failed."""
    from rv_te_bench.fleet import FleetOptions, discover_bags, run_fleet
    from rv_te_bench.store import open_store

    check_record_text(args)   # before the run: every record would be refused
    bags = discover_bags(list(args.bags))
    db = db_for_bags(args, bags)
    options = FleetOptions(topic=args.topic, gear_ratio=args.ratio,
                           crank_per_output=args.crank_per_output,
                           n_crank_harmonics=args.harmonics,
                           window_revolutions=args.window_revolutions,
                           with_advice=not args.no_advice, serial=args.serial, lot=args.lot)
    with open_store(db) as store:
        shown = store.url   # the password hidden (a URL from --db or $RV_TE_DB)
        if not args.quiet:
            print(f'fleet: {len(bags)} bag(s), results in {shown}', file=sys.stderr)
        progress = None if args.quiet else _Progress(len(bags))
        try:
            summary = run_fleet(bags, store, options=options, workers=args.workers,
                                scheduler=args.scheduler, force=args.force,
                                progress=progress)
        finally:
            if progress is not None:
                progress.close()
    if args.json:
        print(json.dumps({**summary.to_json_dict(), 'db': shown}, indent=2))
    else:
        print(f'{summary.total} bag(s): {summary.ok} analysed, {summary.partial} partial, '
              f'{summary.failed} failed, {summary.skipped} skipped (already in the store; '
              f'--force to redo), {summary.duplicate_paths} duplicate(s) in '
              f'{summary.elapsed_s:.1f} s with {summary.workers} worker(s); results in {shown}')
        for group in summary.duplicates:
            print(f'  {len(group)} paths hold the same bag (one record, {group[0]}): '
                  + ', '.join(group))
        for bag, reason in summary.failures:
            print(f'  FAILED {bag}: {reason}')
    if summary.failed:
        first = summary.failures[0]
        msg = (f'{summary.failed} of {summary.total} bag(s) failed (recorded in the store); '
               f'first: {Path(first[0]).name}: {first[1][:200]}')
        raise RvTeError(msg)
    return 0
