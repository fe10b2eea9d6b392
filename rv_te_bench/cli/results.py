"""``rv-te results [filters] [--export FILE] [--json]``: the records of the results store.

Lists the units and tests recorded by ``rv-te analyze``, ``rv-te fleet analyze`` and
``rv-te test`` in test order, filtered by serial, date range, verdict, preset, status or
lot, and exports them as CSV or Parquet (one row per record, one column per metric, SI
values; the table on screen shows arcmin).

Exit codes: 0 ok (also when nothing matches), 1 failed (one ``ERROR: ...`` line), 2 bad usage.
"""

from __future__ import annotations

import argparse
import fnmatch
import json
import os
import sys
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rv_te_bench.cli._db import add_db_argument, db_to_read, store_summary
from sim.units import rad_to_arcmin

if TYPE_CHECKING:
    from rv_te_bench.cli.argtypes import Subparsers
    from rv_te_bench.store import ResultFilter
    from rv_te_bench.store.records import UnitRecord

__all__ = ['add_filter_arguments', 'filter_from_args', 'register', 'run']

EXAMPLES = """\
examples:
  rv-te results                                   every record (of the default store)
  rv-te results --serial SN1042                   one unit's tests
  rv-te results --since 2026-11-01 --until 2026-11-24 --verdict fail
  rv-te results --preset wang2020-2kv --export units.csv        (or units.parquet)
  rv-te results --db postgresql://qa@db-host/line3 --json
  rv-te results --serial RV80E-0042 --metrics 'life_cp*'    a run-in's checkpoints (SI)

exit codes: 0 ok, 1 failed (one ERROR: line on stderr), 2 bad usage
"""


def _date(text: str) -> datetime:
    try:
        d = datetime.fromisoformat(text)
    except ValueError:
        msg = f'not an ISO 8601 date or date-time: {text[:100]!r}'
        raise argparse.ArgumentTypeError(msg) from None
    return d if d.tzinfo is not None else d.replace(tzinfo=UTC)


def _date_until(text: str) -> datetime:
    """End of the range (exclusive): a bare date YYYY-MM-DD means the end of that day
    (9999-12-31 as a bare date: no end)."""
    d = _date(text)
    if len(text.strip()) == 10:
        try:
            d += timedelta(days=1)
        except OverflowError:
            d = datetime.max.replace(tzinfo=UTC)
    return d


def _filter_text(text: str) -> str:
    """A filter value (serial, preset, lot): UTF-8 text, as the store keeps it."""
    try:
        text.encode('utf-8')
    except UnicodeEncodeError:
        shown = text.encode('utf-8', 'surrogateescape').decode('utf-8', 'replace')
        msg = f'{shown!r} is not UTF-8 text (the store keeps UTF-8; no record can match)'
        raise argparse.ArgumentTypeError(msg) from None
    return text


def add_filter_arguments(p: argparse.ArgumentParser) -> None:
    """The record filters (shared with ``rv-te spc``)."""
    p.add_argument('--serial', type=_filter_text, default=None, help='unit serial number')
    p.add_argument('--since', type=_date, default=None, metavar='DATE',
                   help='tested at or after DATE (ISO 8601; no zone = UTC)')
    p.add_argument('--until', type=_date_until, default=None, metavar='DATE',
                   help='tested before DATE; a bare date includes that whole day')
    p.add_argument('--verdict', choices=('pass', 'fail', 'indeterminate', 'not-judged'),
                   default=None)
    p.add_argument('--preset', type=_filter_text, default=None,
                   help='reducer preset (e.g. wang2020-2kv)')
    p.add_argument('--status', choices=('ok', 'partial', 'failed'), default=None,
                   help='analysis status')
    p.add_argument('--lot', type=_filter_text, default=None, help='production lot')


def filter_from_args(args: argparse.Namespace) -> ResultFilter:
    """The :class:`ResultFilter` of the parsed filter options."""
    from rv_te_bench.store import ResultFilter
    return ResultFilter(serial=args.serial, since=args.since, until=args.until,
                        verdict=args.verdict, preset=args.preset, status=args.status,
                        lot=args.lot)


def register(subparsers: Subparsers) -> None:
    """Add the ``results`` subcommand."""
    p = subparsers.add_parser(
        'results', help='list, filter and export the records of the results store',
        description=__doc__.split('\n\n')[1], epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter)
    add_db_argument(p, mode='read')
    add_filter_arguments(p)
    p.add_argument('--export', type=Path, metavar='FILE', default=None,
                   help='write the records to FILE (.csv or .parquet)')
    p.add_argument('--json', action='store_true', help='print the records as JSON')
    p.add_argument('--metrics', metavar='GLOB', default=None,
                   help="also list each record's metrics whose name matches GLOB (SI "
                        "values), e.g. 'life_cp*' for a run-in's checkpoints; with --json "
                        'only those metrics')
    p.set_defaults(func=run)


def _am(v: float | None) -> str:
    return f'{float(rad_to_arcmin(v)):9.4f}' if v is not None else f'{"-":>9}'


def run(args: argparse.Namespace) -> int:
    """List or export the records; 0 ok."""
    from rv_te_bench.store import export_records, open_store
    flt = filter_from_args(args)
    with open_store(db_to_read(args), create=False) as st:
        rows = st.query(flt)
        where = store_summary(st.url, st.count())
    if args.export is not None:
        n = export_records(rows, args.export)
        print(f'{n} record(s) written to {args.export}', file=sys.stderr)
    try:
        glob = getattr(args, 'metrics', None)
        if args.json:
            docs = [_json(r) for r in rows]
            if glob:
                for d in docs:
                    d['metrics'] = [m for m in d['metrics'] if fnmatch.fnmatchcase(m['name'],
                                                                                    glob)]
            print(json.dumps(docs, indent=2))
        elif args.export is None:
            _table(rows, where, glob)
    except BrokenPipeError:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    print(f'{where}: {len(rows)} match', file=sys.stderr)
    return 0


def _json(r: UnitRecord) -> dict[str, Any]:
    return {'id': r.id, 'serial': r.serial, 'lot': r.lot, 'operator': r.operator,
            'preset': r.preset,
            'bench_id': r.bench_id, 'test': r.test, 'plan': r.plan,
            'tested_at': r.tested_at.isoformat(), 'analysed_at': r.analysed_at.isoformat(),
            'status': r.status, 'failure': r.failure, 'verdict': r.verdict,
            'bag_path': r.bag_path, 'bag_sha256': r.bag_sha256,
            'software_version': r.software_version,
            'metrics': [{'name': n, 'direction': d, 'value': v,
                         'limit_low': r.limits[(n, d)][0], 'limit_high': r.limits[(n, d)][1],
                         'verdict': r.limits[(n, d)][2], 'u95': r.u95.get((n, d))}
                        for (n, d), v in r.metrics.items()],
            'lines': [{'label': lab, 'amplitude_rad': a, 'phase_rad': ph,
                       'amplitude_rad_u95': r.line_u95.get(lab, (None, None))[0],
                       'phase_rad_u95': r.line_u95.get(lab, (None, None))[1]}
                      for lab, (a, ph) in r.lines.items()],
            'advice': r.advice}


_PP_HEAD = "TE p-p [']"
_FW_HEAD = "1 f_w [']"


def _table(rows: list[Any], where: str, glob: str | None = None) -> None:
    if not rows:
        print(f'no records match in the {where}')
        return
    print(f'{"tested (UTC)":<17} {"serial":<14} {"preset":<16} {"status":<8} {"verdict":<13} '
          f'{_PP_HEAD:>9} {_FW_HEAD:>9}  bag')
    for r in rows:
        pp = r.metrics.get(('te_pp_revolution_max_rad', 'all'), r.metrics.get(('te_pp_rad', 'all')))
        if pp is None:   # a test measures TE per direction: the worse one
            both = [r.metrics.get(('te_pp_revolution_max_rad', d)) for d in ('ccw', 'cw')]
            pp = max((v for v in both if v is not None), default=None)
        fw = r.lines.get('1 f_w')
        print(f'{r.tested_at.strftime("%Y-%m-%d %H:%M"):<17} {(r.serial or "-")[:14]:<14} '
              f'{(r.preset or "-")[:16]:<16} {r.status:<8} {r.verdict:<13} {_am(pp)} '
              f'{_am(fw[0] if fw else None)}  {r.bag_path}'
              + (f'\n{"":<17} failed: {r.failure}' if r.failure else ''))
        if glob:
            for (name, d), v in sorted(r.metrics.items()):
                if fnmatch.fnmatchcase(name, glob):
                    print(f'{"":<17} {name}{"" if d == "all" else f" ({d})"} = {v:.6g}')
    print(f'{len(rows)} record(s)')
