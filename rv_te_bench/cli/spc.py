"""``rv-te spc METRIC``: control chart of one metric across units, with run rules.

Individuals and moving range (one point per unit, in test order), or X-bar/R with one
subgroup per lot (``--by-lot``). The centre line and 3-sigma limits come from a stated
baseline (default: the first 20 points); Nelson or Western Electric run rules flag drift
and shifts; with a tolerance (``--usl``/``--lsl``, in the unit shown) the capability
Cp/Cpk (sigma within) and Pp/Ppk (overall sigma), both of the baseline points only (the
first 20 by default), so that later drift does not widen the sigma it is judged by.
Nelson rules 5 and 6 are read as Minitab and the AIAG SPC manual state them: 2 of 3 (4 of 5)
points in a row beyond 2 (1) sigma on the same side of the centre line, the other point
anywhere, a point beyond 3 sigma counting as beyond 2; a hit is reported at the point that
completes the pattern. METRIC is a stored metric name (``te_pp_revolution_max_rad``,
``te_pp_rad``, ``lost_motion_rad``, ...) or ``line:LABEL`` for a spectral line amplitude
(``line:1 f_w``): ``--list`` shows what the store holds. Every metric is shown in the unit
of the one metric unit table (``rv_te_bench.core.units.metric_unit``): angles in arcmin,
rigidities in N m/arcmin, the hysteresis loss in J; limits are given in that unit.

Exit codes: 0 ok (whether or not a rule fires: see the report / JSON), 1 failed (one
``ERROR: ...`` line), 2 bad usage.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rv_te_bench.cli._db import add_db_argument, db_to_read, store_summary
from rv_te_bench.cli.argtypes import finite_float, int_between
from rv_te_bench.cli.results import add_filter_arguments, filter_from_args
from rv_te_bench.errors import SpcError

if TYPE_CHECKING:
    from rv_te_bench.cli.argtypes import Subparsers

__all__ = ['register', 'run']

EXAMPLES = """\
examples:
  rv-te spc --list                                        metrics and lines in the store
  rv-te spc te_pp_revolution_max_rad --usl 1.0 --report out/spc-te
                                   TE p-p per unit [arcmin] against TE <= 1 arcmin
  rv-te spc "line:1 f_w" --baseline 30 --report out/spc-fw
                                   the crank-frequency line: a drifting part shows here
  rv-te spc te_pp_rad --by-lot --rules western-electric --json

exit codes: 0 ok, 1 failed (one ERROR: line on stderr), 2 bad usage
"""

_DEFAULT_BASELINE = 20
_MAX_BASELINE = 100_000


def register(subparsers: Subparsers) -> None:
    """Add the ``spc`` subcommand."""
    p = subparsers.add_parser(
        'spc', help='control charts across units (I-MR, X-bar/R), run rules, Cp/Cpk',
        description=__doc__.split('\n\n')[1], epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('metric', nargs='?', metavar='METRIC',
                   help='stored metric name, or line:LABEL for a spectral line amplitude')
    p.add_argument('--list', action='store_true', help='list the metrics and lines stored')
    p.add_argument('--direction', choices=('all', 'cw', 'ccw'), default='all',
                   help='direction of rotation of the metric (default: all; cw / ccw where '
                        'the analysis recorded per-direction statistics)')
    add_db_argument(p, mode='read')
    add_filter_arguments(p)
    p.add_argument('--by-lot', action='store_true',
                   help='X-bar/R chart with one subgroup per lot (2-25 units each)')
    p.add_argument('--baseline', type=int_between(2, _MAX_BASELINE), default=_DEFAULT_BASELINE,
                   metavar='N',
                   help=f'the first N points set the centre line and limits (default '
                        f'{_DEFAULT_BASELINE}; all points when there are fewer)')
    p.add_argument('--rules', choices=('nelson', 'western-electric'), default='nelson',
                   help='run rules (default: nelson, rules 1-8; rules 5/6: 2 of 3 / 4 of 5 '
                        'beyond 2 / 1 sigma on one side, the other point anywhere)')
    p.add_argument('--usl', type=finite_float, default=None, metavar='X',
                   help='upper specification limit in the unit shown (arcmin for angles, '
                        'N m/arcmin for rigidities, J for the hysteresis loss); Cp/Cpk and '
                        'Pp/Ppk are of the baseline points')
    p.add_argument('--lsl', type=finite_float, default=None, metavar='X',
                   help='lower specification limit in the unit shown (e.g. --lsl 196 for '
                        'a rigidity of 196 N m/arcmin)')
    p.add_argument('--measurement-sigma', type=finite_float, default=None, metavar='S',
                   help='standard uncertainty of one measurement in the unit shown, for the '
                        'corrected Cp/Cpk (default: the root mean square of the stored u_c '
                        'of the baseline values, when the store has them)')
    p.add_argument('--report', type=Path, default=None, metavar='DIR',
                   help='write spc.png, spc.html and spc.json into DIR')
    p.add_argument('--json', action='store_true', help='print the chart as JSON')
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Chart the metric; 0 ok."""
    from rv_te_bench.core import spc
    from rv_te_bench.report.spc import display_unit, spc_document
    from rv_te_bench.store import open_store

    with open_store(db_to_read(args), create=False) as st:
        where = store_summary(st.url, st.count())
        if args.list:
            names = [n if d == 'all' else f'{n} --direction {d}' for n, d in st.metric_names()]
            names += [f'line:{lab}' for lab in st.line_labels()]
            _print_quietly('\n'.join(names))
            print(where, file=sys.stderr)
            return 0
        if not args.metric:
            msg = 'give a METRIC (rv-te spc --list shows the stored ones)'
            raise SpcError(msg)
        series = st.series(args.metric, direction=args.direction, flt=filter_from_args(args))
        known = ([n for n, d in st.metric_names() if d == args.direction]
                 + [f'line:{lab}' for lab in st.line_labels()])
    if not series.values:
        hint = ', '.join(known[:8]) + (' ...' if len(known) > 8 else '')
        msg = (f'no values of {args.metric[:80]!r} (direction {args.direction}) in the records '
               f'selected of the {where}; stored: {hint or "nothing"}')
        raise SpcError(msg)
    scale, unit = display_unit(args.metric)
    if args.by_lot:
        missing = sum(1 for lot in series.lots if lot is None)
        if missing:
            msg = (f'{missing} of {len(series.lots)} records have no lot: X-bar/R needs a lot '
                   'per unit')
            raise SpcError(msg)
        n_points = len(dict.fromkeys(series.lots))
    else:
        n_points = len(series.values)
    n_base = min(args.baseline, n_points)
    chart = (spc.xbar_r_chart(series.values, series.lots, baseline=slice(0, n_base),
                              rules=args.rules) if args.by_lot
             else spc.individuals_chart(series.values, baseline=slice(0, n_base),
                                        rules=args.rules))
    base_text = (f'first {n_base} {"lots" if args.by_lot else "units"}'
                 + (' (fewer than 20: provisional limits)' if n_base < _DEFAULT_BASELINE else ''))
    cap = None
    if args.usl is not None or args.lsl is not None:
        if args.by_lot:
            first = set(list(dict.fromkeys(series.lots))[:n_base])
            base_vals = [v for v, lot in zip(series.values, series.lots, strict=True)
                         if lot in first]
        else:
            base_vals = series.values[:n_base]
            base_uc = series.uc[:n_base]
        if args.by_lot:
            base_uc = [u for u, lot in zip(series.uc, series.lots, strict=True) if lot in first]
        cap = spc.capability(base_vals, sigma_within=chart.process_sigma,
                             lsl=None if args.lsl is None else args.lsl / scale,
                             usl=None if args.usl is None else args.usl / scale,
                             sigma_measurement=_measurement_sigma(args, base_uc, scale))
    title = f'{args.metric}' + ('' if args.direction == 'all' else f' ({args.direction})') \
        + f' across {len(series.values)} units' + (f' [{unit}]' if unit else '')
    doc = {**spc_document(chart, series, title=title, capability=cap, baseline_text=base_text),
           'db': where}
    if args.report is not None:
        from rv_te_bench.report.spc import write_spc_report
        files = write_spc_report(args.report, chart, series, title=title, capability=cap,
                                 baseline_text=base_text)
        print(f'report written: {", ".join(str(f) for f in files)}', file=sys.stderr)
    if args.json:
        _print_quietly(json.dumps(doc, indent=2, allow_nan=False))
    else:
        _print_quietly('\n'.join(_summary(doc)))
    print(f'{where}: {len(series.values)} values of {args.metric[:80]}', file=sys.stderr)
    return 0


def _measurement_sigma(args: argparse.Namespace, uc: list[float | None],
                       scale: float) -> float:
    """The measurement's standard deviation [SI]: --measurement-sigma, else the rms of the
    stored u_c (every baseline value must have one), else NaN (no correction)."""
    import math

    if args.measurement_sigma is not None:
        if args.measurement_sigma < 0:
            msg = f'--measurement-sigma must be >= 0, got {args.measurement_sigma:g}'
            raise SpcError(msg)
        return args.measurement_sigma / scale
    if not uc or any(u is None for u in uc):
        return math.nan
    return math.sqrt(sum(u * u for u in uc if u is not None) / len(uc))


def _print_quietly(text: str) -> None:
    """Print; a reader that closed the pipe early (``| head``) is not an error."""
    try:
        print(text, flush=True)
    except BrokenPipeError:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())


def _g(v: float | None) -> str:
    return '-' if v is None else f'{v:.4g}'


def _summary(doc: dict[str, Any]) -> list[str]:
    ch, unit = doc['chart'], doc['unit']
    out = [doc['title'],
           f'  chart: {ch["kind"]}, baseline {doc["baseline"]}, rules {ch["rules"]}',
           f'  centre {_g(ch["centre"])} {unit}, process sigma {_g(ch["process_sigma"])} '
           f'{unit}, limits {_g(ch["lcl"][0])} .. {_g(ch["ucl"][0])} {unit}']
    if ch['hits']:
        out.append(f'  {len(ch["hits"])} rule violation(s):')
        for h in ch['hits'][:20]:
            who = doc['units'][h['index']]['serial'] if ch['kind'] == 'individuals' else None
            out.append(f'    point {h["index"]:>4} {who or "-":<14} {h["rule"]:<4} '
                       f'{h["description"]}')
        if len(ch['hits']) > 20:
            out.append(f'    ... {len(ch["hits"]) - 20} more (see --json or --report)')
    else:
        out.append('  no rule violated')
    cap = doc['capability']
    if cap is not None:
        out.append(f'  capability (baseline): Cp {_g(cap["cp"])}, Cpk {_g(cap["cpk"])}, '
                   f'Pp {_g(cap["pp"])}, Ppk {_g(cap["ppk"])}; '
                   f'{100 * cap["fraction_out"]:.1f} % out of tolerance')
        sm = cap.get('sigma_measurement')
        if sm is None:
            out.append('  measurement variance: not known (no stored uncertainty; '
                       '--measurement-sigma): Cp/Cpk include the measurement\'s spread')
        else:
            out.append(f'  measurement sigma {_g(sm)} {unit} (u_c of the budgets): corrected '
                       f'for it Cp {_g(cap["cp_corrected"])}, Cpk {_g(cap["cpk_corrected"])}, '
                       f'Pp {_g(cap["pp_corrected"])}, Ppk {_g(cap["ppk_corrected"])} '
                       '(sigma_process^2 = sigma^2 - sigma_measurement^2)')
    return out
