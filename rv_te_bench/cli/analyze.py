"""``rv-te analyze BAG... [--json] [--report DIR] [--topic T] [--force]``: offline TE report.

Reads the encoder blocks of each bag straight into numpy, runs the TE core (windows of
whole output revolutions, order spectrum, gaps), names the dominant harmonic and asks the
compensation code for a recommendation. A record with a torque channel and the input locked
while the output is loaded both ways (a hysteresis test, measured on any bench) also gets
its lost motion, backlash and torsional rigidity, read as a plan's hysteresis step reads
them (catalogue definitions, cycles averaged, spread). Results go to stdout (a table, or JSON with
unit-suffixed keys); progress and diagnostics go to stderr. Several bags give a comparison
table, the first bag being the reference (before / after a modification).

Exit codes: 0 ok (also for partial results, which are marked PARTIAL), 1 failed (one
``ERROR: ...`` line on stderr), 2 bad usage.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any, TextIO

from rv_te_bench import __version__
from rv_te_bench.cli._db import (
    add_db_argument,
    check_record_text,
    db_for_bags,
    store_summary,
)
from rv_te_bench.cli._heads import add_heads_arguments, load_calibration
from rv_te_bench.cli.argtypes import int_between, positive_float
from rv_te_bench.core.orders import MAX_CRANK_HARMONICS
from rv_te_bench.core.stream_records import MAX_WINDOW_REVOLUTIONS
from rv_te_bench.errors import RvTeError, StoreError
from rv_te_bench.safe_yaml import one_line
from sim.units import rad_to_arcmin, rad_to_deg

if TYPE_CHECKING:
    from rv_te_bench.cli.argtypes import Subparsers
    from rv_te_bench.core.te import TeStats
    from rv_te_bench.report.analysis import AnalysisResult
    from rv_te_bench.report.results import Recommendation

__all__ = ['register', 'run']

EXAMPLES = """\
examples:
  rv-te analyze bags/sample                        statistics table of the sample session
  rv-te analyze bags/sample --json                 the same as JSON (te_pp_arcmin, ...)
  rv-te analyze bags/sample --report out/sample    te.png, spectrum.png, report.html/.json
  rv-te analyze before/ after/ --report out/cmp    compare two sessions (first = reference)
  rv-te analyze real.mcap --ratio 79 --crank-per-output 25
                                                   a bag without BenchInfo (real bench)
  rv-te analyze bags/li_session --rated-torque 450   with its hysteresis test: lost
                                                   motion at +-3 % of 450 N m, backlash,
                                                   rigidity K (default T_R: the record's)

exit codes: 0 ok (partial results are marked PARTIAL), 1 failed (one ERROR: line on
stderr), 2 bad usage
"""

#: Largest --harmonics and --window-revolutions: the core's limits (one definition for the
#: TE node's parameters, analyze, fleet and the library).
MAX_HARMONICS = MAX_CRANK_HARMONICS
#: Largest record (samples) whose hysteresis is read without --hysteresis: the record is
#: read whole a second time (a long TE session is not a hysteresis test).
HYSTERESIS_AUTO_MAX_SAMPLES = 2_000_000
#: Seconds between two progress lines on stderr.
PROGRESS_PERIOD_S = 2.0
#: What the TE section of a hysteresis record says instead of TE figures.
NOT_TE_RECORD = ('not a TE record: the input is held while the output is loaded both ways '
                 'and turns through no whole revolution (a hysteresis test; its TE would be '
                 'the torsion under load); no TE is reported')


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Add the ``analyze`` arguments to a parser (shared by ``register`` and tests)."""
    p.add_argument('bags', nargs='+', type=Path, metavar='BAG',
                   help='rosbag2 folder or .mcap file; several: comparison, first = reference')
    p.add_argument('--json', action='store_true',
                   help='print JSON (unit-suffixed keys) instead of the table')
    p.add_argument('--report', type=Path, metavar='DIR',
                   help='write te.png, spectrum.png, report.html and report.json into DIR')
    p.add_argument('--force', action='store_true', help='overwrite an existing report DIR')
    p.add_argument('--topic', metavar='T', default=None,
                   help='encoder topic (default: the one EncoderBlock topic of the bag)')
    p.add_argument('--ratio', type=positive_float, metavar='I', default=None,
                   help='overall gear ratio i (input revs per output rev); required, with '
                        '--crank-per-output, for bags without BenchInfo; overrides BenchInfo')
    p.add_argument('--crank-per-output', type=positive_float, metavar='C', default=None,
                   help='absolute crank revs per output rev (25 for the Wang 2020 2K-V)')
    p.add_argument('--harmonics', type=int_between(0, MAX_HARMONICS), default=10, metavar='K',
                   help=f'crank harmonics reported (1 f_w .. K f_w), 0..{MAX_HARMONICS}')
    p.add_argument('--window-revolutions', type=int_between(1, MAX_WINDOW_REVOLUTIONS),
                   default=1, metavar='W',
                   help='whole output revolutions per analysis window, '
                        f'1..{MAX_WINDOW_REVOLUTIONS}')
    p.add_argument('--te-zero', choices=('auto', 'encoders', 'first-sample'), default='auto',
                   help="the TE's zero: the encoder zeros the bench declares (bench "
                        'description encoders.*.zero_offset_deg, a simulated bench), whole '
                        'output turns removed; the first clean sample; auto = encoders when '
                        'declared, else the first sample. The report states which')
    p.add_argument('--no-advice', action='store_true',
                   help='skip the compensation recommendation (the 2K-V assembly-phase '
                        'search takes several seconds)')
    p.add_argument('--quiet', action='store_true', help='no progress lines on stderr')
    p.add_argument('--monte-carlo', type=int_between(100, 1_000_000), default=None,
                   metavar='N',
                   help='also propagate the uncertainty budgets by Monte Carlo (GUM '
                        'Supplement 1, N draws, 100..1000000) through the measurement model '
                        'on the TE trace, beside the law of propagation (seconds to minutes; '
                        'never part of a plain analysis)')
    add_heads_arguments(p)
    add_db_argument(p, mode='also')
    p.add_argument('--rated-torque', type=positive_float, metavar='NM', default=None,
                   help='rated torque T_R of a hysteresis record [N m] (lost motion at +-3 %% '
                        "of it, rigidity K over 0.5-1.0 T_R); default: the record's largest "
                        'held torque')
    p.add_argument('--hysteresis', choices=('auto', 'on', 'off'), default='auto',
                   help='read lost motion, backlash and rigidity of locked-input stretches '
                        f'(auto: records up to {HYSTERESIS_AUTO_MAX_SAMPLES:,} samples)')
    p.add_argument('--serial', default=None,
                   help="unit serial recorded with the result (default: the bag's, else "
                        "the bag's name, see --serial-pattern)")
    p.add_argument('--serial-pattern', metavar='REGEX', default=None,
                   help="where the serial is in the bag's name when the bag states none: "
                        "the group named serial, else the first group (default: 'SN' + "
                        'letters, digits, dashes with a digit: bags/SN-2026-0042_cw -> '
                        'SN-2026-0042)')
    p.add_argument('--lot', default=None, help='production lot recorded with the result')


def register(subparsers: Subparsers) -> None:
    """Add the ``analyze`` subcommand."""
    p = subparsers.add_parser(
        'analyze', help='offline TE statistics, spectrum and report from recorded bags',
        description=__doc__.split('\n\n')[1],
        epilog=EXAMPLES, formatter_class=_Formatter)
    add_arguments(p)
    p.set_defaults(func=run)


class _Formatter(argparse.ArgumentDefaultsHelpFormatter, argparse.RawDescriptionHelpFormatter):
    """Defaults in the help (except empty ones) and the examples kept as written."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        if action.default in (None, False):
            return action.help
        return super()._get_help_string(action)


class _Progress:
    """A progress line on stderr every ``PROGRESS_PERIOD_S`` (blocks, samples, blocks/s)."""

    def __init__(self, name: str, stream: TextIO) -> None:
        self.name = name
        self.stream = stream
        self.next_s = PROGRESS_PERIOD_S
        self.printed = False

    def __call__(self, blocks: int, samples: int, elapsed_s: float) -> None:
        if elapsed_s < self.next_s:
            return
        self.next_s = elapsed_s + PROGRESS_PERIOD_S
        self.printed = True
        rate = blocks / elapsed_s if elapsed_s > 0 else math.nan
        print(f'{self.name}: {blocks} blocks, {samples / 1e6:.2f} M samples, '
              f'{rate:.0f} blocks/s', file=self.stream, flush=True)


def run(args: argparse.Namespace) -> int:
    """Analyse the bags; 0 ok, 1 failed (``ERROR: ...`` on stderr)."""
    try:
        return _run(args)
    except RvTeError as exc:
        print(f'ERROR: {one_line(exc)}', file=sys.stderr)
        return 1
    except BrokenPipeError:
        # stdout closed early (``rv-te analyze bag | head``): not an error of the analysis.
        # Point stdout at devnull so that the interpreter's final flush stays quiet.
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 0


def _run(args: argparse.Namespace) -> int:
    from rv_te_bench.allocator import tune_for_batch_work
    from rv_te_bench.report.analysis import analyze_bag

    check_record_text(args)  # before the analysis: the store would refuse it at the end
    tune_for_batch_work()   # this process: keep window-sized arrays off fresh pages
    from rv_te_bench.report.html import (
        ReportExistsError,
        report_json,
        write_report,
    )

    if args.report is not None and args.report.exists() and not args.force:
        msg = f'Report directory {args.report} exists already; use --force to overwrite.'
        raise ReportExistsError(msg)
    calibration = load_calibration(args)
    results: list[AnalysisResult] = []
    for bag in args.bags:
        progress = None if args.quiet else _Progress(str(bag), sys.stderr)
        t0 = time.monotonic()
        res = analyze_bag(bag, topic=args.topic, gear_ratio=args.ratio,
                          crank_per_output=args.crank_per_output,
                          n_crank_harmonics=args.harmonics,
                          window_revolutions=args.window_revolutions,
                          with_advice=not args.no_advice, progress=progress,
                          heads_mode=args.heads, calibration=calibration,
                          session_calibration=not args.no_session_calibration,
                          te_zero=args.te_zero)
        if progress is not None and progress.printed:
            dt_s = time.monotonic() - t0
            print(f'{bag}: done, {res.blocks_read} blocks in {dt_s:.1f} s '
                  f'({res.blocks_read / dt_s:.0f} blocks/s)', file=sys.stderr)
        res = _with_hysteresis(res, _hysteresis(bag, res, args))
        for problem in res.problems:
            kind = 'PARTIAL' if res.partial else 'WARNING'
            print(f'{kind}: {bag}: {problem}', file=sys.stderr)
        if res.gaps:
            print(f'WARNING: {bag}: {len(res.gaps)} gap(s) in the encoder stream',
                  file=sys.stderr)
        if res.recommendation.encoder_flag and not res.not_te_record:
            print(f'FLAG: {bag}: {res.recommendation.encoder_flag}', file=sys.stderr)
        if args.monte_carlo is not None and not res.not_te_record:
            res = _with_monte_carlo(res, args.monte_carlo, quiet=args.quiet)
        results.append(res)

    results = [_with_serial(res, args) for res in results]
    doc = report_json(results)
    if args.json:
        print(json.dumps(doc, indent=2), flush=True)
    else:
        _print_tables(results, sys.stdout)
    if args.report is not None:
        files = write_report(results, args.report, force=args.force)
        print(f'report written: {", ".join(str(f) for f in files)}', file=sys.stderr)
    recorded_in = _record(args, doc)
    if recorded_in:
        print(f'recorded in the {recorded_in}',
              file=sys.stderr if args.json else sys.stdout)
    return 0


def _with_serial(res: AnalysisResult, args: argparse.Namespace) -> AnalysisResult:
    """The result with its unit's serial: --serial, the bag's, else the bag's name
    (:mod:`rv_te_bench.io.unit_serial`); where it came from goes to stderr."""
    from dataclasses import replace

    from rv_te_bench.io.unit_serial import SerialChoice, choose_serial

    bag = res.path
    if not args.serial and res.session.unit_serial:
        choice = SerialChoice(res.session.unit_serial, "the bag's metadata")
    else:
        named = bag.parent if bag.name in {'bag', 'bag_0'} and bag.parent.name else bag
        choice = choose_serial(args.serial, path=named, pattern=args.serial_pattern)
    print(f'{bag}: {choice.describe()}', file=sys.stderr)
    if choice.serial == res.session.unit_serial:
        return res
    return replace(res, session=replace(res.session, unit_serial=choice.serial))


def _with_monte_carlo(res: AnalysisResult, draws: int, *, quiet: bool) -> AnalysisResult:
    """``res`` with the Monte Carlo check of its budgets (report.uncertainty)."""
    from dataclasses import replace

    from rv_te_bench.report.uncertainty import monte_carlo_check

    if res.uncertainty is None:
        return res
    t0 = time.monotonic()
    if not quiet:
        print(f'{res.path}: Monte Carlo check of the budgets, {draws} draws ...',
              file=sys.stderr)
    check = monte_carlo_check(res.uncertainty, res.trace, res.spectrum,
                              gear_ratio=res.bench.gear_ratio, draws=draws)
    if not quiet:
        print(f'{res.path}: Monte Carlo done in {time.monotonic() - t0:.1f} s', file=sys.stderr)
    return replace(res, uncertainty=replace(res.uncertainty, monte_carlo=check))


def _hysteresis(bag: Path, res: AnalysisResult, args: argparse.Namespace,
                ) -> dict[str, Any] | None:
    """The hysteresis of the record (JSON-ready), or None (none there, or not read)."""
    if args.hysteresis == 'off' or (args.hysteresis == 'auto' and (
            res.cumulative.n_samples > HYSTERESIS_AUTO_MAX_SAMPLES or args.topic)):
        return None
    from rv_te_bench.cli._analyze_hysteresis import hysteresis_json

    return hysteresis_json(bag, rated_torque_nm=args.rated_torque,
                           required=args.hysteresis == 'on' or args.rated_torque is not None)


def _with_hysteresis(res: AnalysisResult, h: dict[str, Any] | None) -> AnalysisResult:
    """``res`` with the record's hysteresis; a record whose input is locked while the output
    is loaded both ways and that turns through no whole output revolution is a hysteresis
    test, not a TE record: its TE (the output's torsion under load) is not reported."""
    from dataclasses import replace

    from rv_te_bench.report.analysis import NO_WHOLE_REVOLUTION

    if h is None:
        return res
    if 'error' in h or res.complete_windows:
        return replace(res, hysteresis=h)
    return replace(res, hysteresis=h, not_te_record=NOT_TE_RECORD,
                   problems=tuple(p for p in res.problems if p != NO_WHOLE_REVOLUTION))


def _record(args: argparse.Namespace, doc: dict[str, Any]) -> str | None:
    """One record per analysed bag in the results store; the store's name, or None.

    A result that cannot be stored is an error (exit 1 after the analysis is shown), the
    default store's as much as one given with --db: a record silently missing from the
    store is worse than a failed command (``--no-db`` analyses without recording).
    """
    from rv_te_bench.store import open_store, records_from_analysis_json

    db = db_for_bags(args, args.bags)
    if db is None:
        return None
    try:
        records = records_from_analysis_json(doc, bag_paths=list(args.bags), command='analyze',
                                             software_version=__version__,
                                             serial=args.serial, lot=args.lot)
        with open_store(db) as store:
            for rec in records:
                store.upsert(rec)
            return store_summary(store.url, store.count())
    except StoreError as exc:
        msg = (f'the analysis was not recorded in the results store: {exc} (--db elsewhere, '
               'or --no-db to analyse without recording)')
        raise StoreError(msg) from None


# --------------------------------------------------------------------------------------
# text output

def _am(x_rad: float, width: int = 9, digits: int = 4) -> str:
    v = float(rad_to_arcmin(x_rad))
    return f'{v:>{width}.{digits}f}' if math.isfinite(v) else f'{"-":>{width}}'


def _stats_row(st: TeStats) -> str:
    revs = f'{st.revolutions:>6.3f}' if math.isfinite(st.revolutions) else f'{"-":>6}'
    return (f'{_am(st.pp_rad)} {_am(st.amplitude_rad)} {_am(st.mean_rad)} {_am(st.std_rad)} '
            f'{revs} {st.n_samples:>9}')


def _print_tables(results: list[AnalysisResult], out: TextIO) -> None:
    for res in results:
        _print_one(res, out)
    if len(results) > 1:
        from rv_te_bench.report.analysis import compare_results

        print('comparison (first bag = reference; TE in arcmin)', file=out)
        print(f'  {"bag":<28} {"p-p":>9} {"ampl":>9} {"mean":>9} {"std":>9} '
              f'{"dominant":<14} {"p-p chg %":>9} {"ampl chg %":>10}', file=out)
        for row in compare_results(results):
            name = Path(row['bag']).name + (' (PARTIAL)' if row['partial'] else '')
            vals = ' '.join(_fmt(row[k], 9, 4) for k in (
                'te_pp_arcmin', 'te_amplitude_arcmin', 'te_mean_arcmin', 'te_std_arcmin'))
            print(f'  {name:<28} {vals} {row["dominant_label"] or "-":<14} '
                  f'{_fmt(row["te_pp_change_pct"], 9, 1)} '
                  f'{_fmt(row["te_amplitude_change_pct"], 10, 1)}', file=out)


def _fmt(x: float | None, width: int, digits: int) -> str:
    return f'{"-":>{width}}' if x is None else f'{x:>{width}.{digits}f}'


def _am_u(u_rad: float | None, width: int) -> str:
    """An expanded uncertainty in arcmin, two significant digits ('-' when unknown)."""
    if u_rad is None or not math.isfinite(u_rad):
        return f'{"-":>{width}}'
    return f'{float(rad_to_arcmin(u_rad)):>{width}.2g}'


def _line_u95(res: AnalysisResult, label: str) -> tuple[float | None, float | None]:
    from rv_te_bench.report.uncertainty import line_budget_key

    if res.uncertainty is None:
        return None, None
    b = res.uncertainty.budgets
    a, p = (b.get(line_budget_key(label, w)) for w in ('amplitude', 'phase'))
    return (None if a is None else a.u95), (None if p is None else p.u95)


def _print_te_pp_u95(res: AnalysisResult, out: TextIO) -> None:
    """TE p-p with its expanded uncertainty (the line people quote)."""
    if res.uncertainty is None:
        return
    parts = []
    for name, what in (('te_pp_revolution_max_rad', 'largest of one output revolution'),
                       ('te_pp_rad', 'all clean samples')):
        b = res.uncertainty.budgets.get(name)
        if b is not None:
            parts.append(f'{what} {float(rad_to_arcmin(b.value)):.4f} +- '
                         f'{float(rad_to_arcmin(b.u95)):.2g}')
    if parts:
        p = next(iter(res.uncertainty.budgets.values())).coverage_probability
        print(f'  TE p-p [arcmin]: {"; ".join(parts)} (+- U, {100 * p:.2f} % coverage; '
              'budgets in --json)', file=out)
    mc = res.uncertainty.monte_carlo
    if mc is not None and mc.results:
        pp = mc.results.get('te_pp_revolution_max_rad')
        budgets = res.uncertainty.budgets

        def resolved(name: str) -> bool:
            # a line at the noise floor (amplitude < 10 U): its phase is not a linear
            # function of the inputs, and the two propagations need not agree there
            amp = budgets.get(name.replace(' phase', ' amplitude'))
            return not name.startswith('line ') or (amp is not None
                                                     and amp.value > 10 * amp.u95)

        shown = {n: r for n, r in mc.results.items() if resolved(n)} or mc.results
        worst = max(shown.items(), key=lambda kv: abs(kv[1].difference)
                    if math.isfinite(kv[1].difference) else -1.0)
        head = (f'TE p-p U {float(rad_to_arcmin(pp.u_mc)):.2g} (law of propagation '
                f'{float(rad_to_arcmin(pp.u_gum)):.2g}, {100 * pp.difference:+.1f} %); '
                if pp is not None else '')
        print(f'  Monte Carlo (GUM S1, {mc.draws} draws, {len(mc.results)} budgets): {head}'
              f'largest difference of a resolved result {100 * worst[1].difference:+.1f} % '
              f'({worst[0]}; every one in --json)', file=out)


def _print_identification(rec: Recommendation, out: TextIO) -> None:
    if rec.identification is None:
        return
    from rv_te_bench.report.analysis import describe_identification

    for line in describe_identification(rec.identification):
        print(f'    {line}', file=out)


def _print_one(res: AnalysisResult, out: TextIO) -> None:
    from rv_te_bench.report.analysis import report_title

    b = res.bench
    flag = '  [PARTIAL]' if res.partial else ''
    print(f'{report_title(res)}: bag {res.path}{flag}', file=out)
    print(f'  preset {b.preset or "(unknown)"} ({b.reducer_type or "-"}), i = {b.gear_ratio:.6g}, '
          f'f_w = {b.crank_per_output:.6g} f_out, ratio from {b.source}; '
          f'{res.blocks_read} blocks', file=out)
    if res.not_te_record:
        print(f'  TE: {res.not_te_record}', file=out)
    else:
        _print_te(res, out)
    _print_gaps(res, out)
    if not res.not_te_record:
        _print_recommendation(res, out)
    if res.hysteresis is not None:
        from rv_te_bench.cli._analyze_hysteresis import print_hysteresis

        print_hysteresis(res.hysteresis, out)
    for problem in res.problems:
        print(f'  {"PARTIAL" if res.partial else "note"}: {problem}', file=out)
    print(file=out)


def _print_te(res: AnalysisResult, out: TextIO) -> None:
    """The TE lines: zero, windows, p-p with U, spectrum, dominant line, encoders."""
    if res.te_reference is not None:
        print(f'  zero: {res.te_reference.describe()}', file=out)
    print(f'  {"window":>10} {"start[s]":>9} {"end[s]":>9} {"whole":>5} '
          f'{"TE p-p":>9} {"ampl":>9} {"mean":>9} {"std":>9} {"revs":>6} {"samples":>9}'
          '   (TE in arcmin)', file=out)
    t0 = res.windows[0].start_stamp_s if res.windows else 0.0
    for w in res.windows:
        print(f'  {w.index:>10} {w.start_stamp_s - t0:>9.3f} {w.end_stamp_s - t0:>9.3f} '
              f'{"yes" if w.complete else "no":>5} {_stats_row(w.stats)}', file=out)
    print(f'  {"cumulative":>10} {"":>9} {"":>9} {"":>5} {_stats_row(res.cumulative)}', file=out)
    _print_te_pp_u95(res, out)
    spec = res.spectrum
    if spec is None:
        print('  spectrum: none (no complete output revolution)', file=out)
    else:
        print(f'  spectrum: {spec.method}; f_out = {spec.output_hz:.5g} Hz, '
              f'f_w = {spec.crank_hz:.5g} Hz', file=out)
        width = max([22, *(len(ln.label) for ln in spec.lines)])
        print(f'    {"line":<{width}} {"output order":>12} {"crank order":>11} {"freq[Hz]":>10} '
              f'{"ampl[arcmin]":>12} {"+-U":>8} {"phase[deg]":>10} {"+-U":>7}', file=out)
        from rv_te_bench.report.analysis import PHASE_MIN_FRACTION

        strongest = max((ln.amplitude_rad for ln in spec.lines), default=0.0)
        for ln in spec.lines:
            # The phase of a line at the noise floor means nothing: print '-'.
            shown = ln.amplitude_rad > PHASE_MIN_FRACTION * strongest
            phase = (f'{float(rad_to_deg(ln.phase_rad)):>10.1f}' if shown else f'{"-":>10}')
            u_a, u_p = _line_u95(res, ln.label)
            u_p_text = f'{float(rad_to_deg(u_p)):>7.2g}' if shown and u_p is not None \
                else f'{"-":>7}'
            print(f'    {ln.label:<{width}} {ln.output_order:>12.6g} {ln.crank_order:>11.4g} '
                  f'{ln.frequency_hz:>10.4g} {_am(ln.amplitude_rad, 12)} '
                  f'{_am_u(u_a, 8)} {phase} {u_p_text}', file=out)
    if res.dominant is not None:
        d = res.dominant
        print(f'  dominant: {d.line.label} ({_am(d.line.amplitude_rad, 0)} arcmin): '
              f'{d.likely_source}', file=out)
    heads = (res.encoder or {}).get('heads') or {}
    for side in ('output', 'input'):
        if (heads.get(side) or {}).get('layout') or (heads.get(side) or {}).get('calibration'):
            print(f'  {side} encoder: {heads[side]["description"]}', file=out)
    note = (res.encoder or {}).get('once_per_rev') or {}
    if note and (res.dominant is None or abs(res.dominant.line.output_order - 1) > 1e-6):
        print(f'  {note["text"]}', file=out)


def _print_gaps(res: AnalysisResult, out: TextIO) -> None:
    if res.gaps:
        print(f'  gaps: {len(res.gaps)}', file=out)
        for g in res.gaps[:10]:
            print(f'    {g.kind} at seq {g.seq}: {g.detail}', file=out)
        if len(res.gaps) > 10:
            print(f'    ... {len(res.gaps) - 10} more (see --json)', file=out)
    else:
        print('  gaps: none', file=out)


def _print_recommendation(res: AnalysisResult, out: TextIO) -> None:
    from rv_te_bench.core.advice import modification_value

    rec = res.recommendation
    if rec.advice is None:
        print(f'  recommendation: {rec.reason}', file=out)
        _print_identification(rec, out)
    else:
        a = rec.advice
        print(f'  recommendation ({a.method}): {a.summary}; TE {a.te_metric} '
              f'{_am(a.te_before_rad, 0)} -> {_am(a.te_after_rad, 0)} arcmin', file=out)
        for m in a.modifications:
            print(f'    {m.factor} ({m.symbol}): {modification_value(m.current_value, m.unit)} -> '
                  f'{modification_value(m.recommended_value, m.unit)}', file=out)
        _print_identification(rec, out)
