"""``rv-te dashboard``: a live page of a session in any browser (no ROS on the viewing PC).

Serves one page on http://127.0.0.1:PORT/ for a session's namespace: the TE over the output
angle and over time (current and previous revolution, min/max envelope so that no sample is
lost on screen), speeds and torque, the order spectrum of the last closed window with its
labelled lines, the TE statistics per revolution, the session state (recorder, losses,
gaps, crashed nodes, advice) and, during ``rv-te test``, the plan, the step's progress, the
hysteresis curve, the metrics against their limits and the verdict. The same topics are
served over the Foxglove WebSocket protocol (Foxglove, Lichtblick) on --foxglove-port.

--host 0.0.0.0 (an office PC) needs the access token: it is printed at start as part of a
link; a request without it gets 403. The page only reads. Port in use: one line, exit 2.

Usage examples:
  rv-te dashboard                               the session in the root namespace
  rv-te dashboard --namespace bench1 --port 8761
  rv-te dashboard --host 0.0.0.0                for an office PC (prints the link with token)
  rv-te launch --default --dashboard            a session with its page
  rv-te test li2023-rv --serial LI-1 --operator kim --launch li2023-rv --dashboard
  rv-te replay bags/sample --rate 5 --dashboard
"""

from __future__ import annotations

import argparse
import sys
import time
from typing import TYPE_CHECKING, Any

from rv_te_bench.cli.argtypes import float_between

if TYPE_CHECKING:
    from rv_te_bench.cli.argtypes import Subparsers
    from rv_te_bench.dashboard.run import Dashboard

__all__ = ['EXIT_PORT_IN_USE', 'add_dashboard_arguments', 'register', 'run', 'start_dashboard']

EXIT_PORT_IN_USE = 2


def _port(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        msg = f'{text!r} is not a port number'
        raise argparse.ArgumentTypeError(msg) from None
    if not 0 <= v <= 65535:
        msg = f'port {v} is not in 0..65535'
        raise argparse.ArgumentTypeError(msg)
    return v


def add_dashboard_arguments(p: argparse.ArgumentParser, *, flag: bool) -> None:
    """The page's options; ``flag``: add ``--dashboard`` too (launch, test, replay)."""
    from rv_te_bench.dashboard.ports import DEFAULT_FOXGLOVE_PORT, DEFAULT_PORT

    g = p.add_argument_group('live page (rv-te dashboard)')
    if flag:
        g.add_argument('--dashboard', action='store_true',
                       help='serve the live page of this session (and the Foxglove WebSocket)')
    g.add_argument('--dashboard-host' if flag else '--host', dest='dashboard_host',
                   default='127.0.0.1', metavar='ADDR',
                   help='address to serve on; anything but loopback needs the printed token')
    g.add_argument('--dashboard-port' if flag else '--port', dest='dashboard_port',
                   type=_port, default=DEFAULT_PORT, metavar='PORT',
                   help=f'port of the page, 0 = any free one (default {DEFAULT_PORT})')
    g.add_argument('--foxglove-port', dest='foxglove_port', type=_port,
                   default=DEFAULT_FOXGLOVE_PORT, metavar='PORT',
                   help='port of the Foxglove WebSocket server, 0 = any free one '
                        f'(default {DEFAULT_FOXGLOVE_PORT})')
    g.add_argument('--no-foxglove', dest='no_foxglove', action='store_true',
                   help='no Foxglove WebSocket server')


def register(subparsers: Subparsers) -> None:
    """Add the ``dashboard`` subcommand."""
    p = subparsers.add_parser(
        'dashboard', help='live page of a session in any browser (and Foxglove WebSocket)',
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('--namespace', default='/', help='namespace of the session (default /)')
    p.add_argument('--duration', type=float_between(0.0, 1e7), default=0.0, metavar='S',
                   help='stop after S seconds (0 = until Ctrl-C)')
    add_dashboard_arguments(p, flag=False)
    p.set_defaults(func=run)


def start_dashboard(args: argparse.Namespace, *, namespace: str,
                    source: str) -> Dashboard | None:
    """Start the page for a command's session; None when a port is taken (line printed)."""
    from rv_te_bench.dashboard.foxglove_relay import FoxglovePortError
    from rv_te_bench.dashboard.run import Dashboard, DashboardOptions
    from rv_te_bench.dashboard.server import PortInUseError

    opts = DashboardOptions(namespace=namespace or '/', host=args.dashboard_host,
                            port=args.dashboard_port, source=source,
                            foxglove_port=None if args.no_foxglove else args.foxglove_port)
    dash = Dashboard(opts)
    try:
        dash.start()
    except PortInUseError as exc:
        print(f'ERROR: dashboard: {exc} (another dashboard or server?); choose another '
              'with --dashboard-port / --port', file=sys.stderr)
        return None
    except FoxglovePortError as exc:
        print(f'ERROR: dashboard: {exc}; choose another with --foxglove-port or use '
              '--no-foxglove', file=sys.stderr)
        return None
    except OSError as exc:
        print(f'ERROR: dashboard: cannot serve on {args.dashboard_host}:'
              f'{args.dashboard_port}: {exc.strerror or exc}', file=sys.stderr)
        return None
    dash.announce()
    return dash


def run(args: argparse.Namespace) -> int:
    """Serve until Ctrl-C (or --duration); 0 ok, 2 when a port is taken."""
    from rv_te_bench.launch.session import normalise_namespace

    ns = normalise_namespace(args.namespace) or '/'
    dash = start_dashboard(args, namespace=ns, source='live')
    if dash is None:
        return EXIT_PORT_IN_USE
    end = time.monotonic() + args.duration if args.duration > 0 else float('inf')
    try:
        while time.monotonic() < end:
            time.sleep(0.2)
    except KeyboardInterrupt:
        print('dashboard: stopped', file=sys.stderr)
    finally:
        dash.stop()
    return 0


def wait_for_dashboard(spec: Any) -> None:
    """Make the node that publishes a session's encoder blocks wait for the page's bridge
    too (its first blocks on screen): the bench, or the JointState adapter when the bench
    publishes joint states (a ros2_control bench), since the bridge never subscribes to
    ``joint_states`` and a bench waiting for it there held the session up for its whole
    wait (and the adapter gave up on its joints meanwhile)."""
    from rv_te_bench.launch.session import node_parameters

    if 'bench' not in spec.nodes:
        return
    bench = spec.parameters.get('bench', {})
    node = 'bench'
    if bench.get('output') == 'joint_state' or bench.get('ros2_control'):
        if 'joint_state_adapter' not in spec.nodes:
            return
        node = 'joint_state_adapter'
    waits = list(node_parameters(spec, node).get('wait_for_nodes', []))
    if 'dashboard' not in waits:
        waits.append('dashboard')
    spec.parameters.setdefault(node, {})['wait_for_nodes'] = waits


def watch_session(dash: Dashboard | None) -> Any:
    """An ``on_tick`` for :func:`rv_te_bench.launch.session.run_session`: the launcher's
    view of crashed nodes and the bench's end goes onto the page."""
    reported: set[str] = set()

    def on_tick(session: Any) -> None:
        if dash is None:
            return
        for name in session.crashed:
            if name not in reported:
                reported.add(name)
                dash.model.on_node_status(name, {'gone': True, 'level': 2,
                                                 'message': 'crashed (the launcher saw it '
                                                 'exit with an error)'})
        if session.bench_done():
            dash.model.set_state('finished (the bench ended)')

    return on_tick
