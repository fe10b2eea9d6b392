"""``rv-te unit-report BAG``: a unit's acceptance test again, from its session bag.

Reads the last ended test in the bag (``test/report``; ``--serial`` picks a unit), computes
every finished step's metrics again from the recorded encoder blocks (the ``test/step``
records give each step's block range and blocks per segment), judges them against the
recorded tolerance profile, checks that the values equal the ones recorded live, and writes
the unit report. No ROS needed. Exit code as ``rv-te test``: 0 pass, 3 fail, 4 indeterminate
(guarded decision rule), 1 error (also a cancelled test, or values that differ from the
recorded ones).

A record judged offline (``rv-te test PLAN --from BAG|FILE``) has no test/report: give the
output folder of that command (or the imported bag in it). Its ``judged.json`` names the
bag, the plan, the tolerance and how the record was read; the record is judged again the
same way and every metric compared with the recorded one.

Usage examples:
  rv-te unit-report out/tests/RV80E-0042_20261124T092855Z/bag
  rv-te unit-report bags/tests/rv_te_20261124_093122 --serial RV-C1 --report out/rv-c1
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rv_te_bench.cli._test_report import show_report, verdict_exit
from rv_te_bench.errors import AcceptanceError

if TYPE_CHECKING:
    from rv_te_bench.cli.argtypes import Subparsers

__all__ = ['register', 'run']

#: Relative difference allowed between a recomputed and the recorded value (same numbers,
#: same arithmetic: only the JSON round trip).
_SAME_REL = 1e-9


def register(subparsers: Subparsers) -> None:
    """Add the ``unit-report`` subcommand."""
    p = subparsers.add_parser(
        'unit-report', help="a unit's acceptance test again from its session bag (no ROS)",
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('bag', help='the session bag folder (or the output folder of rv-te test '
                               '--from)')
    p.add_argument('--serial', default=None, help='the unit (default: the last test)')
    p.add_argument('--report', default=None, metavar='DIR',
                   help='where the report goes (default: <bag>/../unit-report)')
    p.add_argument('--pdf', action='store_true',
                   help='also print the report to report.pdf with headless Chromium (A4, to sign)')
    p.add_argument('--json', action='store_true', help='print the record as JSON on stdout')
    p.set_defaults(func=run)


def _differences(new: dict[str, Any], old: dict[str, Any]) -> list[str]:
    recorded = {(m['name'], m['step']): m for m in old.get('metrics', [])}
    out = []
    for m in new['metrics']:
        r = recorded.get((m['name'], m['step']))
        if r is None:
            out.append(f'{m["name"]}: not in the recorded result')
            continue
        a, b = m['value'], r['value']
        if (a is None) != (b is None) or (a is not None and not math.isclose(
                a, b, rel_tol=_SAME_REL, abs_tol=1e-15)) or m['verdict'] != r['verdict']:
            out.append(f'{m["name"]}: {a!r} ({m["verdict"]}) recomputed, {b!r} '
                       f'({r["verdict"]}) recorded')
    return out


def run(args: argparse.Namespace) -> int:
    """Recompute, compare, report; 0 pass, 3 fail, 4 indeterminate, 1 error."""
    from rv_te_bench.acceptance import load_tolerance, parse_plan
    from rv_te_bench.acceptance._files import parse_yaml_text
    from rv_te_bench.acceptance.runner import reanalyse
    from rv_te_bench.acceptance.tolerance import parse_tolerance
    from rv_te_bench.cli._judged import find_judged, rejudge
    from rv_te_bench.io.recorded_test import read_recorded_test

    bag = Path(args.bag)
    judged = find_judged(bag)
    if judged is not None:
        return rejudge(judged, report_dir=Path(args.report) if args.report else None,
                       as_json=args.json, differences=_differences, pdf=args.pdf)
    rec = read_recorded_test(bag, serial=args.serial)
    r = rec.report
    plan = parse_plan(parse_yaml_text(r['plan_yaml'], 'recorded plan', AcceptanceError),
                      'recorded plan')
    info = rec.bench_info
    if r['tolerance_yaml'].strip():
        profile = parse_tolerance(parse_yaml_text(r['tolerance_yaml'], 'recorded tolerance',
                                                  AcceptanceError), 'recorded tolerance')
    else:
        profile, _ = load_tolerance(plan.tolerance or info.preset)
    old = json.loads(r['report_json']) if r['report_json'] else {}
    status = 'completed' if r['verdict'] in {'pass', 'fail', 'indeterminate'} else r['verdict']
    from rv_te_bench.io.bench_record import bench_uncertainty_of

    new = reanalyse(plan=plan, profile=profile, info=info, steps=rec.steps, blocks=rec.blocks,
                    serial=r['serial'], operator=r['operator_name'],
                    uncertainty=bench_uncertainty_of(info)[0],
                    conditions=old.get('conditions'),
                    started_utc=old.get('unit', {}).get('date_utc', ''), status=status,
                    times=rec.block_times)
    new['bench']['bag'] = str(bag)
    show_report(new, Path(args.report) if args.report else bag.parent / 'unit-report',
                as_json=args.json, pdf=args.pdf)
    diffs = _differences(new, old) if old else []
    if diffs:
        print(f'ERROR: recomputed from the bag, {len(diffs)} metric(s) differ from the '
              f'recorded result: {"; ".join(diffs[:3])}', file=sys.stderr)
        return 1
    if old:
        print(f'recomputed from {len(rec.blocks)} recorded blocks: every metric equals the '
              'recorded result', file=sys.stderr)
    return verdict_exit(new['verdict'], r['serial'], new['reason'], new, as_json=args.json)
