"""``rv-te launch``: a session (bench + TE + compensation + recorder) from parameter files."""

from __future__ import annotations

import argparse
import sys
from importlib import resources
from typing import Any

EPILOG = """\
examples:
  rv-te launch --default                        the packaged session (wang2020-2kv, 2 revs)
  rv-te launch --write-default session.yaml     write that session file to start from
  rv-te launch session.yaml --namespace bench1  a session under /bench1
  rv-te launch session.yaml --param bench.speed_rpm=600 --param recorder.output_dir=out/b
  rv-te launch session.yaml --nodes bench,te_node --single-process
  rv-te launch --nodes bench,te_node            two nodes of the packaged session
  rv-te launch session.yaml --check             run every start-up check and exit

Parameter files use the ROS 2 layout (node_name: ros__parameters: {...}); node names are
bench, te_node, compensation, recorder (optionally /namespace/node, or /** for all). They
are read as ROS reads them (1e5 is a number, yes a bool), at most 1 MiB, without aliases or
repeated keys. --check runs the checks each node runs at start (presets, model modes,
encoders, overrides, topic names and types, remap rules, the bag folder): a session that
passes it starts.
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


def register(subparsers: Any) -> None:  # noqa: ANN401
    """Add the ``launch`` subcommand."""
    p = subparsers.add_parser(
        'launch', help='run a session from ROS-style parameter files',
        description='Run bench + TE node + compensation node + recorder with parameters from '
                    'ROS 2 parameter files. Ctrl-C stops every node and finalises the bag.',
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('param_files', nargs='*', help='ROS 2 parameter files (YAML)')
    p.add_argument('--default', action='store_true', help='use the packaged default session')
    p.add_argument('--nodes', default=None,
                   help='comma-separated nodes to start (default: bench,te_node,compensation,'
                        'recorder); without a parameter file: the packaged session\'s '
                        'parameters for them')
    p.add_argument('--check', action='store_true',
                   help="run every node's start-up checks, start nothing")
    p.add_argument('--write-default', metavar='FILE', default=None,
                   help='write the packaged default session file to FILE (to edit) and exit')
    add_session_arguments(p)
    p.set_defaults(func=run)


def default_session_file() -> str:
    """Path of the packaged default parameter file."""
    return str(resources.files('rv_te_bench.launch').joinpath('default_session.yaml'))


def run(args: argparse.Namespace) -> int:
    """Validate, then run the session; 0 ok, 1 on a crash or a bad file."""
    from rv_te_bench.launch.session import build_session, run_session, run_single_process  # noqa: PLC0415, E501

    if args.write_default is not None:
        return _write_default(args.write_default)
    files = list(args.param_files)
    if args.default or (not files and args.nodes is not None):
        files.insert(0, default_session_file())
    if not files:
        print('ERROR: give a parameter file, --default or --nodes '
              '(rv-te launch --write-default session.yaml writes one to start from)',
              file=sys.stderr)
        return 2
    nodes = args.nodes if args.nodes is not None else 'bench,te_node,compensation,recorder'
    spec = build_session(files, namespace=args.namespace, overrides=args.params,
                         nodes=[n.strip() for n in nodes.split(',') if n.strip()],
                         remappings=args.remap, single_process=args.single_process)
    if args.check:
        print(f'ok: {", ".join(spec.nodes)} in namespace {spec.namespace or "/"}')
        return 0
    if spec.single_process:
        return run_single_process(spec)
    return run_session(spec)


def _write_default(target: str) -> int:
    """Copy the packaged session file to ``target`` (never over an existing file)."""
    from pathlib import Path  # noqa: PLC0415

    text = Path(default_session_file()).read_text(encoding='utf-8')
    try:
        with Path(target).open('x', encoding='utf-8') as f:
            f.write(text)
    except FileExistsError:
        print(f'ERROR: {target} exists already; not overwriting', file=sys.stderr)
        return 1
    print(f'wrote {target}: edit it, then: rv-te launch {target}', file=sys.stderr)
    return 0
