"""``rv-te demo``: the main job in one command.

wang2020-2kv at 300 rpm, RON 886 encoders at 1 kHz, two output revolutions faster than real
time; the full live graph (bench, TE node, compensation node, recorder) over the real
middleware with live progress; then the offline report from the recorded bag and a short
summary. Bag and report land in ``bags/<session>/``.
"""

from __future__ import annotations

import argparse
import math
import os
import signal
import sys
import time
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeAlias

from rv_te_bench.cli.launch import add_session_arguments, default_session_file
from rv_te_bench.errors import RvTeError
from sim.units import rad_to_arcmin, rad_to_deg

if TYPE_CHECKING:
    from rv_te_msgs.msg import CompensationAdvice

    from rv_te_bench.cli.argtypes import Subparsers
    from rv_te_bench.core.advice import Advice
    from rv_te_bench.launch.session import SessionSpec
    from rv_te_bench.nodes.monitor import SessionMonitor
    from rv_te_bench.report.results import AnalysisResult, Recommendation

    #: The advice the demo compares: offline (core) or live (the node's message).
    AnyAdvice: TypeAlias = Advice | CompensationAdvice

EPILOG = """\
examples:
  rv-te demo                                   the default session, report in bags/<session>/
  rv-te demo --param bench.speed_rpm=600       a faster input
  rv-te demo --revolutions 1 --out-dir out     shorter, elsewhere
"""


#: The live advice the demo waits for: the preset's Wang 2020 Eq. 21 optimum and the re-assembly of
#: this unit from its identified eccentricities.
WANTED_ADVICE = frozenset({'assembly-phases', 'identified-assembly-phases'})


#: After the bench's end and the drain: how long the demo waits for a complete window before
#: it stops waiting for an identified advice that needs one [s].
NO_WINDOW_GRACE_S = 5.0


def expected_advice(spec: SessionSpec, revolutions: float) -> tuple[frozenset[str], list[str]]:
    """The live advice this session can give, and why some cannot come (one line each).

    The identified re-assembly needs a complete TE window (``window_revolutions`` output
    revolutions of the TE node); a shorter run can never give it (issue #15: the demo waited
    the whole --advice-timeout-s for it)."""
    from rv_te_bench.launch.node_specs import node_specs

    def params(node: str) -> dict[str, Any]:
        return {**{p.name: p.default for p in node_specs(node)},
                **spec.parameters.get(node, {})}

    comp, te = params('compensation'), params('te_node')
    wanted = set(WANTED_ADVICE)
    why: list[str] = []
    if not comp['optimize_phases']:
        wanted.discard('assembly-phases')
    if not comp['identify']:
        wanted.discard('identified-assembly-phases')
    elif revolutions < float(te['window_revolutions']):
        wanted.discard('identified-assembly-phases')
        why.append(f'no identified advice can come: {revolutions:g} output revolutions give '
                   f"no complete TE window (a window is {te['window_revolutions']} "
                   'revolution(s)); run --revolutions 1 or more')
    return frozenset(wanted), why


def _raise_keyboard_interrupt(*_: object) -> None:
    raise KeyboardInterrupt


def register(subparsers: Subparsers) -> None:
    """Add the ``demo`` subcommand."""
    p = subparsers.add_parser(
        'demo', help='run the full live session on wang2020-2kv, then report and advise',
        description=__doc__, epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('--revolutions', type=float, default=2.0,
                   help='output revolutions to run (15.8 s each at 300 rpm)')
    p.add_argument('--out-dir', default='bags', help='where the session folder goes')
    p.add_argument('--session', default=None,
                   help='session folder name inside --out-dir (default: time-based, made '
                        'unique)')
    p.add_argument('--advice-timeout-s', type=float, default=90.0,
                   help='how long to wait for the compensation advice after the run')
    add_session_arguments(p, single_process=False)
    p.set_defaults(func=run)


def _fmt_arcmin(x_rad: float) -> str:
    return 'n/a' if not math.isfinite(x_rad) else f"{float(rad_to_arcmin(x_rad)):.3f}'"


def _progress_line(mon: SessionMonitor, target_revs: float) -> str:
    tops = ', '.join(f'{lbl} {_fmt_arcmin(a)}' for lbl, a in mon.top_lines(3)) or '-'
    return (f'[demo] rev {mon.revolutions:5.2f}/{target_revs:g} | TE p-p so far '
            f'{_fmt_arcmin(mon.cumulative_pp_rad)} | gaps {mon.gaps} | top lines: {tops}')


def run(args: argparse.Namespace) -> int:
    """Run the session, then the report; print the summary. 0 on success."""
    import rclpy

    from rv_te_bench.io.files import claim_folder, folder_name_problem
    from rv_te_bench.launch.node_specs import node_specs
    from rv_te_bench.launch.session import Session, build_session
    from rv_te_bench.nodes.common import make_executor
    from rv_te_bench.nodes.monitor import SessionMonitor

    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    if args.revolutions <= 0 or not math.isfinite(args.revolutions):
        print(f'ERROR: --revolutions must be > 0, got {args.revolutions}', file=sys.stderr)
        return 2
    if args.session is not None and (problem := folder_name_problem(args.session)):
        print(f'ERROR: --session {problem}', file=sys.stderr)
        return 2
    name = args.session or datetime.now(UTC).strftime('%Y%m%d-%H%M%S') + '-wang2020-2kv'
    session_dir = Path(args.out_dir) / name
    if session_dir.exists() and args.session:
        print(f'ERROR: session folder {session_dir} exists already', file=sys.stderr)
        return 1
    overrides = [f'recorder.output_dir={session_dir}', 'recorder.bag_name=bag',
                 f'bench.duration_output_revs={args.revolutions}', *args.params]
    spec = build_session([default_session_file()], namespace=args.namespace,
                         overrides=overrides, remappings=args.remap)
    # only once everything is valid; a default name gets -2, -3, ... when taken (two demos
    # started in the same second)
    session_dir = claim_folder(Path(args.out_dir), name, numbered=not args.session)
    if session_dir.name != name:
        name = session_dir.name
        spec.parameters.setdefault('recorder', {})['output_dir'] = str(session_dir)
    bag_dir = session_dir / 'bag'
    report_dir = session_dir / 'report'
    print(f'[demo] session {name}: {", ".join(spec.nodes)} '
          f'(namespace {spec.namespace or "/"}), bag -> {bag_dir}', file=sys.stderr)
    t_start = time.monotonic()
    ctx = rclpy.context.Context()
    ros_args = ['--ros-args'] + (['-r', f'__ns:={spec.namespace}'] if spec.namespace else [])
    rclpy.init(args=ros_args, context=ctx)
    mon = SessionMonitor(context=ctx)
    executor = make_executor('single', context=ctx)
    executor.add_node(mon)
    session = Session(spec)
    code = 0
    old_term = signal.signal(signal.SIGTERM, _raise_keyboard_interrupt)
    try:
        session.start()
        last_print = 0.0
        while True:
            executor.spin_once(timeout_sec=0.1)
            session.poll()
            if session.failures:
                code = 1
                break
            if time.monotonic() - last_print > 1.0:
                last_print = time.monotonic()
                print(_progress_line(mon, args.revolutions), file=sys.stderr, flush=True)
            if session.bench_done():
                break
        # drain: final windows, then the advice (the phase search takes a few seconds)
        wanted, why_not = expected_advice(spec, args.revolutions)
        for line in why_not:
            print(f'[demo] {line}', file=sys.stderr)
        deadline = time.monotonic() + args.advice_timeout_s
        end_drain = time.monotonic() + 3.0
        while time.monotonic() < deadline and not session.failures:
            executor.spin_once(timeout_sec=0.1)
            session.poll()
            if time.monotonic() > end_drain and 'identified-assembly-phases' in wanted and \
                    not any(w.window_complete for w in mon.windows) and \
                    time.monotonic() > end_drain + NO_WINDOW_GRACE_S:
                wanted = wanted - {'identified-assembly-phases'}
                print('[demo] no identified advice: the TE node closed no complete window '
                      '(nothing to identify the unit from)', file=sys.stderr)
            if time.monotonic() > end_drain and wanted <= set(mon.advice):
                break
        missing = sorted(wanted - set(mon.advice))
        if missing:
            print(f'[demo] no compensation advice {missing} received in time',
                  file=sys.stderr)
        print(_progress_line(mon, args.revolutions), file=sys.stderr, flush=True)
    except KeyboardInterrupt:
        print('[demo] interrupted: stopping the session', file=sys.stderr)
        code = 130
    finally:
        codes = session.stop()
        signal.signal(signal.SIGTERM, old_term)
        executor.shutdown()
        mon.destroy_node()
        rclpy.try_shutdown(context=ctx)
    bad = {k: c for k, c in codes.items() if c not in (0, None)}
    if bad or session.failures:
        print(f'ERROR: session ended badly: {session.failures or bad}', file=sys.stderr)
        return 1 if code == 0 else code
    t_live = time.monotonic() - t_start
    print(f'[demo] live session done in {t_live:.1f} s; analysing {bag_dir}', file=sys.stderr)
    try:
        comp = {**{p.name: p.default for p in node_specs('compensation')},
                **spec.parameters.get('compensation', {})}
        search = (float(comp['step_deg']), bool(comp['refine']))
        summary = _report(bag_dir, report_dir, dict(mon.advice), search)
    except RvTeError as exc:
        print(f'ERROR: report failed: {exc}', file=sys.stderr)
        return 1
    print(summary)
    print(f'\nbag:    {bag_dir}\nreport: {report_dir / "report.html"}')
    return code


def _report(bag_dir: Path, report_dir: Path, live_advice: dict[str, Any],
            search: tuple[float, bool]) -> str:
    """Offline analysis of the recorded bag -> report files; returns the summary text.

    ``search``: the compensation node's (step_deg, refine), so that the offline advice for
    this unit is searched as the live ones were.
    """
    from rv_te_bench.report.analysis import analyze_bag
    from rv_te_bench.report.html import write_report

    result = analyze_bag(bag_dir, advice_search=search)
    write_report([result], report_dir)
    return summary_text(result, live_advice)


def summary_text(result: AnalysisResult, live_advice: dict[str, Any] | None = None) -> str:
    """The short summary people read at the end of the demo.

    Args:
        result: The offline ``AnalysisResult`` of the recorded bag.
        live_advice: The advice the compensation node published, by method.
    """
    am = _fmt_arcmin
    c = result.cumulative
    lines = ['', '=== rv-te demo summary ===',
             f'reducer: {result.bench.preset or "?"} (i = {result.bench.gear_ratio:.6g}); '
             f'{c.revolutions:.2f} output revolutions, {c.n_samples} samples, '
             f'{len(result.complete_windows)} complete windows, {len(result.gaps)} gaps'
             + (' (PARTIAL)' if result.partial else ''),
             f'TE: peak-to-peak {am(c.pp_rad)}, amplitude {am(c.amplitude_rad)}, '
             f'mean {am(c.mean_rad)}, std {am(c.std_rad)}']
    if result.spectrum is not None:
        top = sorted(result.spectrum.lines, key=lambda ln: -ln.amplitude_rad)[:3]
        lines.append('spectrum (largest lines): ' + ', '.join(
            f'{ln.label} ({ln.frequency_hz:.3f} Hz) {am(ln.amplitude_rad)}' for ln in top))
    if result.dominant is not None:
        d = result.dominant
        lines.append(f'dominant harmonic: {d.line.label} at {d.line.frequency_hz:.3f} Hz, '
                     f'{am(d.line.amplitude_rad)}; likely source: {d.likely_source}')
    lines += recommendation_lines(result.recommendation, live_advice or {})
    return '\n'.join(lines)


def _phases_deg(advice: AnyAdvice) -> list[float]:
    return [float(rad_to_deg(m.recommended_value)) for m in advice.modifications]


def _current_deg(advice: AnyAdvice) -> list[float]:
    return [float(rad_to_deg(m.current_value)) for m in advice.modifications]


def _max_diff_deg(a: list[float], b: list[float]) -> float:
    return max(abs((x - y + 180.0) % 360.0 - 180.0) for x, y in zip(a, b, strict=True))


def _fmt_phases(advice: AnyAdvice) -> str:
    return '[' + ', '.join(f'{p:.1f}' for p in _phases_deg(advice)) + '] deg'


def _modification_lines(advice: AnyAdvice) -> list[str]:
    out = []
    for m in advice.modifications:
        if m.unit == 'rad':
            out.append(f'  {m.factor} ({m.symbol}): {float(rad_to_deg(m.current_value)):.1f}'
                       f' deg -> {float(rad_to_deg(m.recommended_value)):.1f} deg')
        else:
            out.append(f'  {m.factor} ({m.symbol}): {m.current_value:.6g} -> '
                       f'{m.recommended_value:.6g} {m.unit}')
    return out


def recommendation_lines(rec: Recommendation, live_advice: dict[str, Any]) -> list[str]:
    """The recommendation for this unit, and the preset's nominal optimum beside it, saying
    which is which and why the first is the one to apply (issue #15: the live log shows both).

    Args:
        rec: The offline analysis' ``Recommendation`` (from the whole recorded TE).
        live_advice: Live advice by method (``CompensationAdvice`` messages or ``Advice``);
            ``'assembly-phases'`` is the preset's nominal optimum.
    """
    am = _fmt_arcmin
    nominal = live_advice.get('assembly-phases')
    a = rec.advice if rec.available else None
    out: list[str] = []
    if a is None:
        out.append(f'recommendation for this unit: none ({rec.reason})')
    elif a.method != 'identified-assembly-phases':
        out.append(f'recommendation ({a.method}): {a.summary} [{rec.reason}]')
        out += _modification_lines(a)
        out.append(f'predicted TE ({a.te_metric}): {am(a.te_before_rad)} -> {am(a.te_after_rad)}')
        return out
    else:
        out.append('recommendation for this unit (identified-assembly-phases, from the '
                   'recorded TE):')
        out.append(f'  {a.summary}')
        out += _modification_lines(a)
        out.append(f'  predicted max |NLTE|: {am(a.te_before_rad)} -> {am(a.te_after_rad)}')
    if nominal is None:
        return out
    out.append(f"the preset's nominal optimum (assembly-phases, also in the live log): "
               f'{_fmt_phases(nominal)}, max |NLTE| {am(nominal.te_before_rad)} -> '
               f'{am(nominal.te_after_rad)}')
    if a is None:
        out.append('  it is not a recommendation for this unit: it assumes the unit was '
                   "assembled at the preset's nominal eccentricity phases")
        return out
    target = _max_diff_deg(_phases_deg(a), _phases_deg(nominal))
    current = _max_diff_deg(_current_deg(a), _current_deg(nominal))
    agree = (f'agree (within {target:.1f} deg)' if target <= 1.0 else
             f'differ by up to {target:.1f} deg only because the identified output-wheel '
             "eccentricity is not exactly the preset's and the optimum is flat there "
             f'(predicted max |NLTE| {am(a.te_after_rad)} vs {am(nominal.te_after_rad)})')
    where = (f'here within {current:.1f} deg of the nominal ones' if current <= 1.0 else
             f'here up to {current:.1f} deg from the nominal ones')
    out.append('why the first: both search the same phase grid with the same part magnitudes '
               "(the preset's unless measured ones are given), so their target phases "
               f'{agree}; but the nominal optimum assumes the unit is assembled at the '
               "preset's phases, while the first starts from this unit's own phases, "
               f'identified in its TE ({where}): only it says how far to turn each part of '
               'this unit and what TE to expect.')
    return out
