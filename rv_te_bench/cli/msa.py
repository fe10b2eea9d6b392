"""``rv-te msa``: measurement-system analysis from the results store (issue 35).

``type1``: a type 1 study of one reference unit measured n >= 25 times (Cg = 0.2 T / (6 s),
Cgk with the bias against a reference value). ``grr``: a gauge R&R study by ANOVA of
parts x operators (or mountings, benches) x repeats: %GRR of the tolerance and of the
process variation, ndc. Both read a stored metric (as ``rv-te spc``: ``--list`` shows
them) of the records selected; values are shown in arcmin for angles, N m/arcmin for
rigidity, and tolerances are given in that unit. ``demo``: the simulated bench measures
parts with re-mounting between repeats and a second operator (other torque-step timing)
into a store, then runs both studies.

Exit codes: 0 ok (whatever the verdict), 1 failed (one ``ERROR: ...`` line), 2 bad usage.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rv_te_bench.cli._db import add_db_argument, db_to_read, store_summary
from rv_te_bench.cli.argtypes import finite_float, int_between, positive_float
from rv_te_bench.cli.results import add_filter_arguments, filter_from_args
from rv_te_bench.errors import MsaError

if TYPE_CHECKING:
    from rv_te_bench.cli.argtypes import Subparsers
    from rv_te_bench.store import StoredResult

__all__ = ['register', 'run']

EXAMPLES = """\
examples:
  rv-te msa demo --parts 5 --repeats 2        simulated study into out/msa-demo/, both analyses
  rv-te msa grr te_pp_revolution_max_rad --direction ccw --lot msa-grr \\
      --db out/msa-demo/rv-te-results.sqlite --tolerance 1
  rv-te msa type1 te_pp_revolution_max_rad --direction ccw --serial MSA-P01 \\
      --lot msa-type1 --db out/msa-demo/rv-te-results.sqlite --reference 1.605
  rv-te msa grr lost_motion_rad --lot msa-grr --repeats 2 --json \\
      --db out/msa-demo/rv-te-results.sqlite

exit codes: 0 ok, 1 failed (one ERROR: line on stderr), 2 bad usage
"""


def register(subparsers: Subparsers) -> None:
    """Add the ``msa`` subcommand and its three studies."""
    p = subparsers.add_parser(
        'msa', help='measurement-system analysis: type 1 study (Cg, Cgk), gauge R&R (ANOVA)',
        description=__doc__.split('\n\n')[1], epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest='study', metavar='STUDY', required=True)
    for name, text in (('type1', 'type 1 study of one reference unit (n >= 25 repeats)'),
                       ('grr', 'gauge R&R by ANOVA (parts x operators x repeats)')):
        q = sub.add_parser(name, help=text, description=text, epilog=EXAMPLES,
                           formatter_class=argparse.RawDescriptionHelpFormatter)
        q.add_argument('metric', metavar='METRIC', help='stored metric name (rv-te spc --list)')
        q.add_argument('--direction', choices=('all', 'cw', 'ccw'), default='all',
                       help='direction of the metric (TE p-p per direction: ccw / cw)')
        add_db_argument(q, mode='read')
        add_filter_arguments(q)
        q.add_argument('--operator', default=None, help='only this operator\'s records'
                       if name == 'type1' else argparse.SUPPRESS)
        _tolerance_arguments(q)
        q.add_argument('--json', action='store_true', help='print the study as JSON')
        q.set_defaults(func=run)
    t1 = sub.choices['type1']
    t1.add_argument('--reference', type=finite_float, default=None, metavar='X',
                    help='the unit\'s reference value (shown unit): bias and Cgk')
    g = sub.choices['grr']
    g.add_argument('--repeats', type=int_between(2, 1000), default=None, metavar='N',
                   help='repeats per part and operator (default: the fewest any cell has; '
                        'the first N of each cell in test order are used)')
    g.add_argument('--process-sigma', type=positive_float, default=None, metavar='S',
                   help='a known process standard deviation (shown unit) for %%GRR of the '
                        'process variation (default: the study\'s total variation)')
    d = sub.add_parser('demo', help='simulated study (re-mounting, two operators) into a store',
                       description='Simulated parts measured with re-mounting between repeats '
                                   'and a second operator (other torque-step timing), recorded '
                                   'into a results store; then both studies.',
                       epilog=EXAMPLES, formatter_class=argparse.RawDescriptionHelpFormatter)
    d.add_argument('--db', metavar='PATH|URL', default='out/msa-demo/rv-te-results.sqlite',
                   help='results store to write (default out/msa-demo/rv-te-results.sqlite)')
    d.add_argument('--preset', default='rv-80e-101', help='reducer preset (default rv-80e-101)')
    d.add_argument('--parts', type=int_between(2, 50), default=10)
    d.add_argument('--operators', type=int_between(1, 2), default=2)
    d.add_argument('--repeats', type=int_between(2, 20), default=3)
    d.add_argument('--type1-repeats', type=int_between(0, 200), default=25)
    d.add_argument('--mount-eccentricity-um', type=float, default=2.0, metavar='E',
                   help='largest mounting eccentricity of the output scale drawn at each '
                        're-mounting [um] (default 2)')
    d.add_argument('--seed', type=int_between(0, 2**31 - 1), default=35)
    d.add_argument('--json', action='store_true', help='print both studies as JSON')
    d.set_defaults(func=run)


def _tolerance_arguments(q: argparse.ArgumentParser) -> None:
    q.add_argument('--tolerance', type=positive_float, default=None, metavar='T',
                   help='tolerance width in the shown unit (default: --usl - --lsl, or the '
                        'records\' stored limits; a one-sided upper limit counts from 0)')
    q.add_argument('--usl', type=finite_float, default=None, metavar='X')
    q.add_argument('--lsl', type=finite_float, default=None, metavar='X')


def run(args: argparse.Namespace) -> int:
    """Run the study; 0 ok."""
    if args.study == 'demo':
        return _demo(args)
    from rv_te_bench.store import open_store

    with open_store(db_to_read(args), create=False) as st:   # reading changes nothing
        rows = st.query(filter_from_args(args))
        where = store_summary(st.url, st.count())
    doc = (_type1(args, rows) if args.study == 'type1' else _grr(args, rows))
    _emit(args, doc)
    print(f'{where}: {len(rows)} match', file=sys.stderr)
    return 0


def _emit(args: argparse.Namespace, doc: dict[str, Any]) -> None:
    if args.json:
        print(json.dumps(doc, indent=2))
    else:
        print('\n'.join(doc.pop('_lines')))


def _values(rows: list[StoredResult], metric: str, direction: str,
            ) -> list[tuple[StoredResult, float]]:
    out = [(r, r.metrics[(metric, direction)]) for r in rows
           if (metric, direction) in r.metrics]
    if not out:
        names = sorted({n if d == 'all' else f'{n} --direction {d}' for r in rows
                        for n, d in r.metrics})
        hint = ', '.join(names[:8]) + (' ...' if len(names) > 8 else '')
        msg = (f'no values of {metric[:80]!r} (direction {direction}) in the {len(rows)} '
               f'records selected; stored: {hint or "nothing"}')
        raise MsaError(msg)
    return out


def _tolerance(args: argparse.Namespace, vals: list[tuple[StoredResult, float]],
               scale: float, metric: str, direction: str) -> tuple[float, str]:
    """(T in the shown unit, where it comes from); NaN when none."""
    if args.tolerance is not None:
        return args.tolerance, 'given'
    if args.usl is not None or args.lsl is not None:
        if args.usl is None:
            msg = 'a lower limit alone has no tolerance width: give --usl or --tolerance'
            raise MsaError(msg)
        lsl = 0.0 if args.lsl is None else args.lsl
        if not args.usl > lsl:
            msg = f'--usl {args.usl:g} must lie above --lsl {lsl:g}'
            raise MsaError(msg)
        return args.usl - lsl, 'usl - lsl' if args.lsl is not None else 'usl (natural zero)'
    for r, _ in vals:
        low, high, _ = r.limits.get((metric, direction), (None, None, None))
        if high is not None:
            lo = 0.0 if low is None else low
            return (high - lo) * scale, 'stored limits' + (' (natural zero)' if low is None
                                                           else '')
    return math.nan, 'none'


def _g(x: float | None, digits: int = 4) -> str:
    return '-' if x is None or not math.isfinite(x) else f'{x:.{digits}g}'


def _type1(args: argparse.Namespace, rows: list[StoredResult]) -> dict[str, Any]:
    from rv_te_bench.core.msa import type1_study
    from rv_te_bench.report.spc import display_unit

    if args.serial is None:
        msg = 'a type 1 study is of one reference unit: give --serial'
        raise MsaError(msg)
    if args.operator is not None:
        rows = [r for r in rows if r.operator == args.operator]
    vals = _values(rows, args.metric, args.direction)
    scale, unit = display_unit(args.metric)
    tol, tol_src = _tolerance(args, vals, scale, args.metric, args.direction)
    if not math.isfinite(tol):
        msg = 'no tolerance: give --tolerance, --usl/--lsl, or analyse with limits'
        raise MsaError(msg)
    ref = math.nan if args.reference is None else args.reference
    st = type1_study([v * scale for _, v in vals], tolerance=tol, reference=ref)
    what = f'{args.metric}' + ('' if args.direction == 'all' else f' ({args.direction})')
    lines = [f'type 1 study: {what}, unit {args.serial}, {st.n} repeats [{unit}]',
             f'  mean {_g(st.mean, 6)}, s {_g(st.std)}'
             + (f', reference {_g(ref, 6)}: bias {_g(st.bias)} (t {_g(st.t_bias, 3)}, '
                f'p {_g(st.p_bias, 2)})' if math.isfinite(ref) else ', no reference value: '
                'bias and Cgk not computed (--reference)'),
             f'  tolerance {_g(tol)} {unit} ({tol_src}): Cg {_g(st.cg, 3)}'
             + (f', Cgk {_g(st.cgk, 3)}' if math.isfinite(st.cgk) else ''),
             '  verdict: ' + {True: 'capable (Cg and Cgk >= 1.33)',
                              False: 'NOT capable (Cg or Cgk < 1.33)',
                              None: 'Cgk unknown' + (' (Cg >= 1.33)' if st.cg >= 1.33
                                                     else ' (Cg < 1.33: not capable)')}[
                                                         st.capable]]
    return {'study': 'type1', 'metric': args.metric, 'direction': args.direction,
            'serial': args.serial, 'unit': unit, 'tolerance_source': tol_src,
            **st.to_json_dict(), '_lines': lines}


def _grr(args: argparse.Namespace, rows: list[StoredResult]) -> dict[str, Any]:
    import numpy as np

    from rv_te_bench.core.msa import gauge_rr_anova
    from rv_te_bench.report.spc import display_unit

    vals = _values(rows, args.metric, args.direction)
    scale, unit = display_unit(args.metric)
    cells: dict[tuple[str, str], list[float]] = {}
    for r, v in vals:
        if r.serial is None or r.operator is None:
            msg = f'record {r.id} ({r.bag_path[:60]}) has no serial or operator'
            raise MsaError(msg)
        cells.setdefault((r.serial, r.operator), []).append(v * scale)
    parts = sorted({s for s, _ in cells})
    ops = sorted({o for _, o in cells})
    missing = [(s, o) for s in parts for o in ops if (s, o) not in cells]
    if missing:
        shown = ', '.join(f'{s}/{o}' for s, o in missing[:5])
        msg = (f'unbalanced study: {len(missing)} part/operator cell(s) have no record '
               f'({shown}); every operator must measure every part')
        raise MsaError(msg)
    fewest = min(len(c) for c in cells.values())
    r_use = args.repeats or fewest
    if r_use > fewest:
        (s, o) = min(cells, key=lambda k: len(cells[k]))
        msg = f'--repeats {r_use}: part {s} operator {o} has only {fewest} records'
        raise MsaError(msg)
    dropped = sum(len(c) - r_use for c in cells.values())
    y = np.array([[cells[(s, o)][:r_use] for o in ops] for s in parts])
    tol, tol_src = _tolerance(args, vals, scale, args.metric, args.direction)
    g = gauge_rr_anova(y, tolerance=tol,
                       process_sigma=math.nan if args.process_sigma is None
                       else args.process_sigma)
    what = f'{args.metric}' + ('' if args.direction == 'all' else f' ({args.direction})')
    lines = [f'gauge R&R (ANOVA): {what}, {len(parts)} parts x {len(ops)} operators '
             f'({", ".join(ops)}) x {r_use} repeats [{unit}]'
             + (f'; {dropped} later records left out' if dropped else ''),
             f'  {"source":<28}{"df":>4}{"SS":>12}{"MS":>12}{"F":>9}{"p":>9}']
    for row in g.anova:
        lines.append(f'  {row.source:<28}{row.dof:>4}{_g(row.ss):>12}{_g(row.ms):>12}'
                     f'{_g(row.f, 3):>9}{_g(row.p, 2):>9}')
    pint = g.anova[2].p
    lines.append('  interaction ' + (f'pooled into the repeatability (p {_g(pint, 2)} > 0.25)'
                                     if g.interaction_pooled else
                                     f'kept (p {_g(pint, 2)} <= 0.25)'))
    lines.append(f'  EV {_g(g.ev)}  AV {_g(g.av)}  INT {_g(g.interaction)}  GRR {_g(g.grr)}  '
                 f'PV {_g(g.pv)}  TV {_g(g.tv)} {unit} (standard deviations)')
    lines.append(f'  %GRR of the process variation {_g(g.pct_process, 3)} %'
                 + (f', of the tolerance {_g(tol)} {unit} ({tol_src}) '
                    f'{_g(g.pct_tolerance, 3)} %' if math.isfinite(tol) else '')
                 + f'; ndc {g.ndc}')
    lines.append(f'  verdict: {g.verdict()} (AIAG: %GRR <= 10 % acceptable, <= 30 % '
                 'conditional; ndc >= 5)')
    return {'study': 'grr', 'metric': args.metric, 'direction': args.direction,
            'unit': unit, 'part_serials': parts, 'operator_names': ops,
            'tolerance_source': tol_src, 'records_left_out': dropped,
            **g.to_json_dict(), '_lines': lines}


def _demo(args: argparse.Namespace) -> int:
    from rv_te_bench.acceptance.msa_demo import MsaDemoConfig, run_msa_demo
    from rv_te_bench.cli._progress import ProgressBar
    from rv_te_bench.report.spc import display_unit
    from rv_te_bench.store import open_store, upsert_all

    cfg = MsaDemoConfig(preset=args.preset, parts=args.parts, operators=args.operators,
                        repeats=args.repeats, type1_repeats=args.type1_repeats,
                        mount_eccentricity_um=args.mount_eccentricity_um, seed=args.seed)
    if '://' not in args.db:
        Path(args.db).parent.mkdir(parents=True, exist_ok=True)

    bar = ProgressBar('simulated runs')
    try:
        result = run_msa_demo(cfg, on_run=lambda n, total, _what: bar(n / total))
        bar(1.0)
    finally:
        bar.close()
    records = result.records
    with open_store(args.db) as st:
        upsert_all(st, records)
    print(f'{len(records)} simulated runs recorded in {args.db}; reference part '
          f'{records[0].serial} measured with ideal encoders for the type 1 reference values',
          file=sys.stderr)
    docs = []
    for metric, direction in (('te_pp_revolution_max_rad', 'ccw'), ('lost_motion_rad', 'all')):
        ns = argparse.Namespace(metric=metric, direction=direction, db=args.db, serial=None,
                                since=None, until=None, verdict=None, preset=args.preset,
                                status=None, lot='msa-grr', operator=None, tolerance=None,
                                usl=None, lsl=None, json=args.json, repeats=args.repeats,
                                process_sigma=None, reference=None)
        with open_store(args.db) as st:
            docs.append(_grr(ns, st.query(filter_from_args(ns))))
            if cfg.type1_repeats >= 25:
                ns.lot, ns.serial = 'msa-type1', records[0].serial
                ref = result.reference.get((metric, direction))
                ns.reference = None if ref is None else ref * display_unit(metric)[0]
                docs.append(_type1(ns, st.query(filter_from_args(ns))))
    if args.json:
        for d in docs:
            d.pop('_lines')
        print(json.dumps({'records': len(records), 'db': args.db, 'studies': docs}, indent=2))
    else:
        for d in docs:
            print('\n'.join(d.pop('_lines')))
    return 0

