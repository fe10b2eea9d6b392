"""``rv-te bench``: run the simulated bench node alone."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from rv_te_bench.cli.argtypes import Subparsers

EPILOG = """\
examples:
  rv-te bench                                  wang2020-2kv, RON 886, 1 kHz, real time
  rv-te bench --param speed_rpm=600 --param time_mode=fast --param duration_s=30
  rv-te bench --param preset=li2023-rv --param te_mode=dte --namespace bench2
"""


def register(subparsers: Subparsers) -> None:
    """Add the ``bench`` subcommand."""
    p = subparsers.add_parser(
        'bench', help='run the simulated bench node alone',
        description='Publish encoder blocks from a reducer model on bench/encoders.',
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('param_files', nargs='*', help='ROS 2 parameter files (bench: ...)')
    p.add_argument('--param', dest='params', action='append', default=[], metavar='KEY=VALUE',
                   help='bench parameter (repeatable), e.g. speed_rpm=600')
    p.add_argument('--namespace', default='', help='namespace, e.g. bench1')
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Validate the parameters, then run the bench until its duration ends or Ctrl-C."""
    from rv_te_bench.launch.session import build_session, run_single_process

    spec = build_session(args.param_files, namespace=args.namespace,
                         overrides=[f'bench.{p}' for p in args.params], nodes=['bench'])
    return run_single_process(spec)
