"""``rv-te launch``: a session (bench + TE + compensation + recorder) from a ROS 2 launch file
(the YAML frontend subset of :mod:`rv_te_bench.launch.launch_file`) or from parameter files."""

from __future__ import annotations

import argparse
import sys
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING

from rv_te_bench.cli.dashboard import add_dashboard_arguments
from rv_te_bench.errors import ParameterFileError

if TYPE_CHECKING:
    from rv_te_bench.cli.argtypes import Subparsers
    from rv_te_bench.launch.session import SessionSpec

EPILOG = """\
examples:
  rv-te launch --default                        the packaged session.launch.yaml (wang2020-2kv)
  rv-te launch --write-default session.yaml     write the default parameter file to start from
  rv-te launch session.yaml --namespace bench1  a session under /bench1 (parameter file)
  rv-te launch session.launch.yaml namespace:=bench1 use_sim_time:=false \\
      --param bench.time_mode=realtime
  rv-te launch session.yaml --param bench.speed_rpm=600 --param recorder.output_dir=out/b
  rv-te launch session.yaml --nodes bench,te_node --single-process
  rv-te launch --nodes bench,te_node            two nodes of the packaged session
  rv-te launch session.yaml --check             run every start-up check and exit

Two kinds of file:
* A ROS 2 launch file (YAML frontend, top level "launch:"), the same file that
  `ros2 launch rv_te_bench session.launch.yaml` runs on a full ROS 2 install; launch
  arguments as name:=value. rv-te runs this subset (anything else is an error naming the
  tag or attribute):
    arg   name, default, description, choice      let   name, value
    node  pkg (rv_te_bench), exec (bench_node, te_node, compensation_node, recorder,
          test_sequencer, joint_state_adapter), name (bench, te_node, compensation,
          recorder, test_sequencer, joint_state_adapter), namespace, output,
          param ({from: FILE} or {name, value}), remap ({from, to})
    substitutions $(var NAME) $(env NAME [DEFAULT]) $(find-pkg-share PKG) $(dirname)
  One namespace and one remapping list for the whole session; --namespace and --remap
  act on a launch file as PushRosNamespace and SetRemap do (in front of / after its own).
* ROS 2 parameter files (node_name: ros__parameters: {...}); node names are bench,
  te_node, compensation, recorder (optionally /namespace/node, /**/node, or /** for all).
  They are read as ROS reads them (1e5 is a number, yes a bool), at most 1 MiB, without
  aliases or repeated keys.
--check runs the checks each node runs at start (presets, model modes, encoders,
overrides, topic names and types, remap rules, the bag folder): a session that passes it
starts.
"""


def add_session_arguments(p: argparse.ArgumentParser, *, single_process: bool = True) -> None:
    """Arguments shared by ``launch`` and ``demo`` (the demo always runs a process per node)."""
    p.add_argument('--namespace', default='', help='namespace of every node, e.g. bench1')
    p.add_argument('--param', dest='params', action='append', default=[],
                   metavar='NODE.KEY=VALUE', help='override one node parameter (repeatable)')
    p.add_argument('--remap', action='append', default=[], metavar='FROM:=TO',
                   help='topic remapping applied to every node (repeatable)')
    if single_process:
        p.add_argument('--single-process', action='store_true',
                       help='all nodes in one process on one executor (default: one per node)')


def register(subparsers: Subparsers) -> None:
    """Add the ``launch`` subcommand."""
    p = subparsers.add_parser(
        'launch', help='run a session from a ROS 2 launch file or parameter files',
        description='Run bench + TE node + compensation node + recorder from a ROS 2 YAML '
                    'launch file or ROS 2 parameter files. Ctrl-C stops every node and '
                    'finalises the bag.',
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('param_files', nargs='*', metavar='FILE',
                   help='a ROS 2 launch file and its name:=value arguments, or ROS 2 '
                        'parameter files (YAML)')
    p.add_argument('--default', action='store_true',
                   help='run the packaged session.launch.yaml')
    p.add_argument('--nodes', default=None,
                   help='comma-separated nodes to start (default: all of the file, or bench, '
                        'te_node, compensation, recorder); without a file: the packaged '
                        'session\'s nodes')
    p.add_argument('--check', action='store_true',
                   help="run every node's start-up checks, start nothing")
    p.add_argument('--write-default', metavar='FILE', default=None,
                   help='write the packaged default session file to FILE (to edit) and exit')
    add_session_arguments(p)
    add_dashboard_arguments(p, flag=True)
    p.set_defaults(func=run)


def default_session_file() -> str:
    """Path of the packaged default parameter file."""
    return str(resources.files('rv_te_bench.launch').joinpath('default_session.yaml'))


def default_launch_file() -> str:
    """Path of the packaged launch file (the one ``ros2 launch`` finds in share/rv_te_bench)."""
    return str(resources.files('rv_te_bench.launch').joinpath('session.launch.yaml'))


def _spec_from_files(args: argparse.Namespace, nodes: list[str] | None) -> SessionSpec:
    """The SessionSpec of a launch file (with name:=value arguments) or of parameter files."""
    from rv_te_bench.launch import launch_file as lf
    from rv_te_bench.launch.session import build_session

    items = list(args.param_files)
    if args.default:
        items.insert(0, default_launch_file())
    launch_args = [i for i in items if ':=' in i]
    files = [i for i in items if ':=' not in i]
    if not files:
        msg = f'{launch_args[0]!r}: name:=value arguments need a launch file'
        raise ParameterFileError(msg)
    if launch_args and not Path(files[0]).exists():
        msg = f'launch file {files[0]!r} does not exist'
        raise ParameterFileError(msg)
    if lf.is_launch_file(files[0]):
        if len(files) > 1:
            msg = f'a launch file runs alone; {files[1]!r} would be a second file'
            raise ParameterFileError(msg)
        desc = lf.load_launch_file(files[0], lf.parse_launch_arguments(launch_args))
        return lf.session_from_launch(desc, overrides=args.params, nodes=nodes,
                                      namespace=args.namespace, remappings=args.remap,
                                      single_process=args.single_process)
    if launch_args:
        msg = f'{launch_args[0]!r}: name:=value arguments need a launch file'
        raise ParameterFileError(msg)
    return build_session(files, namespace=args.namespace, overrides=args.params,
                         nodes=nodes or None, remappings=args.remap,
                         single_process=args.single_process)


def run(args: argparse.Namespace) -> int:
    """Validate, then run the session; 0 ok, 1 on a crash or a bad file."""
    from rv_te_bench.launch.session import run_session, run_single_process

    if args.write_default is not None:
        return _write_default(args.write_default)
    if not args.param_files and not args.default and args.nodes is None:
        print('ERROR: give a launch file, a parameter file, --default or --nodes '
              '(rv-te launch --write-default session.yaml writes one to start from)',
              file=sys.stderr)
        return 2
    if not args.param_files:
        args.default = True
    chosen = [n.strip() for n in args.nodes.split(',') if n.strip()] if args.nodes else None
    spec = _spec_from_files(args, chosen)
    if args.check:
        print(f'ok: {", ".join(spec.nodes)} in namespace {spec.namespace or "/"}')
        values = spec.launch_arguments
        if values:
            print('launch arguments: ' + ', '.join(f'{k}:={v}' for k, v in values.items()))
        return 0
    if not getattr(args, 'dashboard', False):
        if spec.single_process:
            return run_single_process(spec)
        return run_session(spec)
    from rv_te_bench.cli.dashboard import (
        EXIT_PORT_IN_USE,
        start_dashboard,
        wait_for_dashboard,
        watch_session,
    )

    wait_for_dashboard(spec)
    dash = start_dashboard(args, namespace=spec.namespace or '/', source='rv-te launch')
    if dash is None:
        return EXIT_PORT_IN_USE
    try:
        if spec.single_process:
            return run_single_process(spec)
        return run_session(spec, on_tick=watch_session(dash))
    finally:
        dash.model.set_state('finished (the session ended)')
        dash.stop()


def _write_default(target: str) -> int:
    """Copy the packaged session file to ``target`` (never over an existing file)."""
    text = Path(default_session_file()).read_text(encoding='utf-8')
    try:
        with Path(target).open('x', encoding='utf-8') as f:
            f.write(text)
    except FileExistsError:
        print(f'ERROR: {target} exists already; not overwriting', file=sys.stderr)
        return 1
    print(f'wrote {target}: edit it, then: rv-te launch {target}', file=sys.stderr)
    return 0
