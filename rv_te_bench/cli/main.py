"""The ``rv-te`` command: one subcommand per module in ``rv_te_bench.cli``.

Each subcommand module has ``register(subparsers)`` (adds its parser, sets ``func``) and
``run(args) -> int``. Exit codes: 0 ok, 1 failed (one ``ERROR: ...`` line on stderr),
2 bad usage (argparse), 130 interrupted.
"""

from __future__ import annotations

import sys

# A Ctrl-C while the command starts (its imports take ~1 s, more on a busy machine) ends it
# quietly, here or in main()'s own handler, never in a traceback (issue #16). Only the
# interpreter's own start-up (site, the .pth files: ~0.1 s) stays outside our reach.
try:
    import argparse
    import importlib
    import os
    from typing import TYPE_CHECKING

    from rv_te_bench import __version__
except KeyboardInterrupt:
    print('interrupted', file=sys.stderr)
    raise SystemExit(130) from None

if TYPE_CHECKING:
    from collections.abc import Sequence

# Order of appearance in --help.
SUBCOMMAND_MODULES = (
    'demo', 'launch', 'dashboard', 'bench', 'record', 'replay', 'import_', 'info', 'analyze',
    'test', 'ack', 'unit_report', 'model',
    'optimize_phases', 'compensate', 'identify', 'selfcal', 'presets', 'results', 'spc',
    'msa', 'fleet',
)

EXAMPLES = """\
examples:
  rv-te demo                                   full live session + report on wang2020-2kv
  rv-te presets                                list reducer presets
  rv-te presets wang2020-2kv                   every value with unit and source
  rv-te model wang2020-2kv --kind nlte --json  NLTE statistics of one output revolution
  rv-te optimize-phases wang2020-2kv --json    Wang 2020 Eq. 21 assembly-phase optimisation
  rv-te compensate hu2020-rv --te-arcmin 1.2   tooth-profile compensation (Hu 2020)
  rv-te launch --default                       bench + TE + compensation + recorder
  rv-te launch --default --dashboard           ... with its live page in the browser
  rv-te info bags/sample                       first look: duration, topics, bench, unit, gaps
  rv-te analyze bags/sample --report out/rep   offline report from a recorded bag
  rv-te replay bags/sample --rate 10           publish a bag with its recorded timing
  rv-te fleet analyze bags/ --workers 2        many bags on Dask into the results store
  rv-te results --verdict fail                 the recorded units, filtered
  rv-te spc te_pp_revolution_max_rad --usl 1   control chart across units
  rv-te msa demo                               measurement-system study on the simulated bench
  rv-te test rv-80e --serial SN1 --operator kim --launch rv-80e-101
                                               acceptance test of a unit: verdict + report
  rv-te unit-report out/tests/RV80E-0042_*/bag  the same test again from its bag (no ROS)
"""


def build_parser() -> argparse.ArgumentParser:
    """The full parser with every subcommand registered."""
    parser = argparse.ArgumentParser(
        prog='rv-te',
        description='Transmission-error testing of precision robot reducers (RV, 2K-V) '
                    'with ROS 2 Jazzy.',
        epilog=EXAMPLES, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--version', action='version', version=f'rv-te-bench {__version__}')
    sub = parser.add_subparsers(dest='command', metavar='COMMAND')
    for name in SUBCOMMAND_MODULES:
        module = importlib.import_module(f'rv_te_bench.cli.{name}')
        module.register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``rv-te``; returns the exit code."""
    _tolerant_stdout()
    try:
        from rv_te_bench.errors import RvTeError
        from rv_te_bench.safe_yaml import one_line
        from sim.errors import SimError

        parser = build_parser()
        args = parser.parse_args(argv)
    except KeyboardInterrupt:   # Ctrl-C while the subcommands import
        print('interrupted', file=sys.stderr)
        return 130
    func = getattr(args, 'func', None)
    if func is None:
        parser.print_help(sys.stderr)
        return 2
    try:
        code = int(func(args))
        sys.stdout.flush()   # a closed pipe shows here, not at interpreter exit
    except BrokenPipeError:
        return _quiet_broken_pipe()
    except (RvTeError, SimError) as exc:
        print(f'ERROR: {one_line(exc)}', file=sys.stderr)
        return 1
    except OSError as exc:   # files and folders: unwritable, a file where a folder goes...
        print(f'ERROR: {exc.strerror or exc}: {exc.filename or ""}'.rstrip(': '),
              file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print('interrupted', file=sys.stderr)
        return 130
    return code


def _tolerant_stdout() -> None:
    """Print paths with undecodable bytes (surrogates) escaped instead of failing."""
    for stream in (sys.stdout, sys.stderr):
        reconfigure = getattr(stream, 'reconfigure', None)
        if reconfigure is not None:
            try:
                reconfigure(errors='backslashreplace')
            except (ValueError, OSError):   # detached or closed stream
                pass


def _quiet_broken_pipe() -> int:
    """``rv-te ... | head -1``: the reader left; that is no error of ours (exit 0, silent).

    stdout is pointed at /dev/null so that the interpreter's final flush stays quiet too.
    """
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):   # not a real file (a test's capture): nothing to flush
        pass
    return 0


if __name__ == '__main__':
    sys.exit(main())
