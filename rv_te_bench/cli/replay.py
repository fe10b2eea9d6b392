"""``rv-te replay``: publish a recorded bag with its timing.

Usage examples:
  rv-te replay out/bags/rv_te_20260101_120000
  rv-te replay BAG --rate 5 --topics /bench/encoders /bench/info
  rv-te replay BAG --loop --clock        # consumers run with use_sim_time:=true
"""

from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING, Any

from rv_te_bench.cli.argtypes import float_between
from rv_te_bench.cli.dashboard import add_dashboard_arguments

if TYPE_CHECKING:
    from rclpy.context import Context

    from rv_te_bench.cli.argtypes import Subparsers

__all__ = ['RATE_RANGE', 'START_OFFSET_RANGE_S', 'WAIT_RANGE_S', 'register', 'run']

#: The replay node's parameter ranges (rate, start_offset_s, wait_for_subscribers_s).
RATE_RANGE = (0.001, 1000.0)
START_OFFSET_RANGE_S = (0.0, 1e7)
WAIT_RANGE_S = (0.0, 3600.0)


def register(subparsers: Subparsers) -> None:
    """Add the ``replay`` subcommand to ``subparsers``."""
    parser = subparsers.add_parser(
        'replay', help='publish a recorded bag with its timing',
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('bag', help='bag folder (or .mcap file)')
    parser.add_argument('--rate', type=float_between(*RATE_RANGE), default=1.0, metavar='R',
                        help='playback speed factor, {:g}..{:g} (default: %(default)s)'.format(
                            *RATE_RANGE))
    parser.add_argument('--loop', action='store_true', help='start again at the end')
    parser.add_argument('--topics', nargs='+', metavar='TOPIC', default=None,
                        help='topics to play (default: all)')
    parser.add_argument('--start-offset', type=float_between(*START_OFFSET_RANGE_S),
                        default=0.0, metavar='S',
                        help='skip the first S seconds of the bag, 0..{1:g} (default: '
                             '%(default)s)'.format(*START_OFFSET_RANGE_S))
    parser.add_argument('--clock', action='store_true',
                        help='publish the playback time on /clock')
    parser.add_argument('--wait-for-subscribers', type=float_between(*WAIT_RANGE_S),
                        default=0.0, metavar='S',
                        help='wait up to S seconds (0..{1:g}) for a subscriber on every '
                             'topic'.format(*WAIT_RANGE_S))
    add_dashboard_arguments(parser, flag=True)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Play the bag once (or until Ctrl-C with ``--loop``); 0 ok, 1 error."""
    try:
        from rclpy.parameter import Parameter

        from rv_te_bench.nodes.common import run_node
        from rv_te_bench.nodes.replay import ReplayNode
    except ImportError as exc:
        print(f'ERROR: replay needs ROS 2 (rclpy): {exc}', file=sys.stderr)
        return 1
    overrides = [
        Parameter('bag', value=str(args.bag)),
        Parameter('rate', value=float(args.rate)),
        Parameter('loop', value=bool(args.loop)),
        Parameter('start_offset_s', value=float(args.start_offset)),
        Parameter('clock', value=bool(args.clock)),
        Parameter('wait_for_subscribers_s', value=float(args.wait_for_subscribers)),
    ]
    if args.topics:
        overrides.append(Parameter('topics', value=list(args.topics)))
    made: list[Any] = []

    def factory(ctx: Context) -> ReplayNode:
        node = ReplayNode(context=ctx, parameter_overrides=overrides)
        made.append(node)
        return node

    dash = None
    if getattr(args, 'dashboard', False):
        from rv_te_bench.cli.dashboard import EXIT_PORT_IN_USE, start_dashboard

        dash = start_dashboard(args, namespace='/', source=f'rv-te replay {args.bag}')
        if dash is None:
            return EXIT_PORT_IN_USE
        import time

        time.sleep(2.0)   # discovery: the page's bridge is there before the first message
    try:
        code = run_node(factory, ['rv-te-replay'], linger_s=0.5)
    finally:
        if dash is not None:
            dash.model.set_state('finished (the replay ended)')
            dash.stop()
    if made:
        for topic, count in sorted(made[0].published.items()):
            print(f'{topic}: {count} messages published')
    return code
