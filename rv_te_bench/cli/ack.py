"""``rv-te ack``: acknowledge the operator step a running test waits for.

A plan's operator steps ("mount the unit", "lock the input shaft") make the
``test_sequencer`` wait; ``rv-te test`` asks in its terminal, and from any other terminal
(or an HMI script) this command answers: it calls the sequencer's ``test/acknowledge``
service (``std_srvs/Trigger``). Exit code 0 when a waiting step was acknowledged, 1 when
none was waiting or no sequencer answered.

Usage examples:
  rv-te ack
  rv-te ack --namespace bench1
"""

from __future__ import annotations

import argparse
import contextlib
import sys
import time
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from rv_te_bench.cli.argtypes import Subparsers

__all__ = ['acknowledge', 'register', 'run']


def register(subparsers: Subparsers) -> None:
    """Add the ``ack`` subcommand."""
    p = subparsers.add_parser(
        'ack', help='acknowledge the operator step a running test waits for',
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('--namespace', default='/', help='namespace of the session')
    p.add_argument('--wait-s', type=float, default=10.0,
                   help='how long to wait for the test_sequencer [s]')
    p.set_defaults(func=run)


def acknowledge(node: object, executor: object, *, wait_s: float) -> tuple[bool, str]:
    """Call ``test/acknowledge`` from ``node`` (spun on ``executor``): (success, message)."""
    from std_srvs.srv import Trigger

    client = node.create_client(Trigger, 'test/acknowledge')   # type: ignore[attr-defined]
    try:
        end = time.monotonic() + wait_s
        while not client.service_is_ready():
            if time.monotonic() > end:
                return False, (f'no test_sequencer answers test/acknowledge within '
                               f'{wait_s:g} s')
            executor.spin_once(timeout_sec=0.1)   # type: ignore[attr-defined]
        future = client.call_async(Trigger.Request())
        while not future.done():
            if time.monotonic() > end + 5.0:
                return False, 'the test_sequencer did not answer'
            executor.spin_once(timeout_sec=0.1)   # type: ignore[attr-defined]
        res = future.result()
        return bool(res.success), str(res.message)
    finally:
        node.destroy_client(client)   # type: ignore[attr-defined]


def run(args: argparse.Namespace) -> int:
    """Acknowledge; 0 when a waiting operator step was acknowledged."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor

    from rv_te_bench.launch.session import normalise_namespace

    ctx = rclpy.context.Context()
    rclpy.init(context=ctx)
    node = rclpy.create_node('rv_te_ack', context=ctx,
                             namespace=normalise_namespace(args.namespace) or '/')
    executor = SingleThreadedExecutor(context=ctx)
    executor.add_node(node)
    try:
        ok, message = acknowledge(node, executor, wait_s=args.wait_s)
    finally:
        with contextlib.suppress(Exception):
            executor.shutdown()
            node.destroy_node()
        rclpy.try_shutdown(context=ctx)
    if ok:
        print(message)
        return 0
    print(f'ERROR: {message}', file=sys.stderr)
    return 1
