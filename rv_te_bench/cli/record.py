"""``rv-te record``: record the suite's topics to a rosbag2 (MCAP) bag.

Usage examples:
  rv-te record --out out/bags --duration 60
  rv-te record --namespace /bench1 --compression lz4 --name run7
  rv-te record --topics bench/encoders bench/info --metadata 'operator: kim'
  rv-te record --use-sim-time                  log time = a fast bench's /clock
"""

from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING, Any

from rv_te_bench.cli.argtypes import float_between, int_between

if TYPE_CHECKING:
    from rclpy.context import Context

    from rv_te_bench.cli.argtypes import Subparsers

__all__ = ['FLUSH_RANGE_S', 'MAX_DURATION_S', 'MAX_SPLIT_BYTES', 'MAX_STALL_BUFFER_BYTES',
           'register', 'run']

#: The recorder node's parameter ranges (duration_s, split_duration_s; flush_interval_s;
#: split_size_bytes; stall_buffer_bytes): checked here so that an error names the flag.
MAX_DURATION_S = 1e7
FLUSH_RANGE_S = (0.01, 60.0)
MAX_SPLIT_BYTES = 1 << 62
MAX_STALL_BUFFER_BYTES = 1 << 40


def register(subparsers: Subparsers) -> None:
    """Add the ``record`` subcommand to ``subparsers``."""
    parser = subparsers.add_parser(
        'record', help='record topics to a rosbag2 (MCAP) bag',
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--topics', nargs='+', metavar='TOPIC', default=None,
                        help='topics to record (relative names resolve under --namespace); '
                             'default: every topic the suite publishes, /diagnostics, /clock')
    parser.add_argument('--out', default='out/bags', metavar='DIR',
                        help='folder in which the bag folder is created (default: %(default)s)')
    parser.add_argument('--name', default='',
                        help='bag folder name inside --out (default: rv_te_<UTC time>, with '
                             '_2, _3, ... if taken)')
    parser.add_argument('--namespace', default='/', help='namespace of the session')
    parser.add_argument('--compression', choices=['zstd', 'lz4', 'none'], default='zstd',
                        help='MCAP chunk compression (default: %(default)s)')
    parser.add_argument('--duration', type=float_between(0.0, MAX_DURATION_S), default=0.0,
                        metavar='S', help=f'stop after S seconds (0..{MAX_DURATION_S:g}); 0: '
                                          'until Ctrl-C (default: %(default)s)')
    parser.add_argument('--flush-interval', type=float_between(*FLUSH_RANGE_S), default=1.0,
                        metavar='S',
                        help='longest time a message stays in memory [s], {:g}..{:g} '
                             '(default: %(default)s)'.format(*FLUSH_RANGE_S))
    parser.add_argument('--split-size', type=int_between(0, MAX_SPLIT_BYTES), default=0,
                        metavar='BYTES',
                        help=f'start a new .mcap file past this size (0..{MAX_SPLIT_BYTES}); '
                             '0: never (default: %(default)s)')
    parser.add_argument('--split-duration', type=float_between(0.0, MAX_DURATION_S),
                        default=0.0, metavar='S',
                        help=f'start a new .mcap file after S seconds (0..{MAX_DURATION_S:g}); '
                             '0: never')
    parser.add_argument('--use-sim-time', action='store_true',
                        help='log time = /clock (a fast bench\'s simulated time), as '
                             'ros2 bag record --use-sim-time')
    parser.add_argument('--metadata', default='', metavar='YAML',
                        help='YAML mapping stored in the bag (preset, operator, ...)')
    parser.add_argument('--stall-buffer', type=int_between(0, MAX_STALL_BUFFER_BYTES),
                        default=64 << 20, metavar='BYTES',
                        help='messages held in memory while the disk is full '
                             f'(0..{MAX_STALL_BUFFER_BYTES}); beyond it they are lost and '
                             'counted (default: %(default)s)')
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Record until ``--duration`` passes or SIGINT/SIGTERM; 0 ok, 1 error or data lost."""
    from rv_te_bench.io.files import folder_name_problem
    from rv_te_bench.launch.session import normalise_namespace

    args.namespace = normalise_namespace(args.namespace) or '/'   # one line if invalid
    if args.name and (problem := folder_name_problem(args.name)):
        print(f'ERROR: --name {problem}', file=sys.stderr)
        return 2
    try:
        from rclpy.parameter import Parameter

        from rv_te_bench.nodes.common import run_node
        from rv_te_bench.nodes.recorder import RecorderNode
    except ImportError as exc:
        print(f'ERROR: recording needs ROS 2 (rclpy): {exc}', file=sys.stderr)
        return 1
    overrides = [
        Parameter('output_dir', value=str(args.out)),
        Parameter('bag_name', value=args.name),
        Parameter('compression', value=args.compression),
        Parameter('duration_s', value=float(args.duration)),
        Parameter('flush_interval_s', value=float(args.flush_interval)),
        Parameter('split_size_bytes', value=int(args.split_size)),
        Parameter('split_duration_s', value=float(args.split_duration)),
        Parameter('session_metadata_yaml', value=args.metadata),
        Parameter('use_sim_time', value=bool(args.use_sim_time)),
        Parameter('stall_buffer_bytes', value=int(args.stall_buffer)),
    ]
    if args.topics:
        overrides.append(Parameter('topics', value=list(args.topics)))
    made: list[Any] = []

    def factory(ctx: Context) -> RecorderNode:
        node = RecorderNode(context=ctx, namespace=args.namespace,
                            parameter_overrides=overrides)
        made.append(node)
        return node

    code = run_node(factory, ['rv-te-record'])
    if made:
        node = made[0]
        print(f'bag: {node.bag_path}')
        lost = node.lost
        for topic, count in sorted(node.written.items()):
            print(f'  {topic}: {count} messages' +
                  (f' ({lost[topic]} lost: disk full)' if lost.get(topic) else ''))
        for topic, (gaps, missing) in sorted(node.gaps.items()):
            if gaps:
                print(f'  {topic}: {gaps} sequence gaps, {missing} blocks missing')
        if n_lost := sum(lost.values()):
            for line in node.loss_report():
                print(f'  {line}')
            print(f'ERROR: {n_lost} messages received could not be written to {node.bag_path} '
                  f'(disk full); the bag holds the {sum(node.written.values())} listed above',
                  file=sys.stderr)
    return code
