"""ROS 2 YAML launch files (the ``launch:`` frontend format) for ``rv-te launch``.

One file serves ``ros2 launch rv_te_bench session.launch.yaml`` on a full ROS 2 install and
``rv-te launch session.launch.yaml`` here. rv-te reads the subset below into the same
:class:`~rv_te_bench.launch.session.SessionSpec` the parameter-file path builds, so a launch
file gets the same checks (every parameter against the node's declared ones before anything
starts), process layout, stop order and recording. Anything outside the subset is an error
that names the tag or attribute, never silently ignored.

Supported (``SUBSET``; the format is launch_yaml's, the attributes launch/launch_ros's)::

    launch:                       a list of actions, each a one-key mapping:
    - arg:   name (required), default, description, choice: [{value: ...}, ...]
    - let:   name, value
    - node:  pkg: rv_te_bench
             exec: bench_node | te_node | compensation_node | recorder | joint_state_adapter
             name: bench | te_node | compensation | recorder | joint_state_adapter (the node's
                   own; may be left out)
             namespace, output (accepted; node output always goes to the terminal)
             param: [{from: FILE}, {name: NAME, value: VALUE}, ...]   in order, later wins
             remap: [{from: FROM, to: TO}, ...]

Substitutions in strings: ``$(var NAME)``, ``$(env NAME [DEFAULT])``,
``$(find-pkg-share PKG)`` (an ament prefix on AMENT_PREFIX_PATH, else for rv_te_bench the
installed Python package, whose ``launch/`` holds the same files as ``share/rv_te_bench/launch``)
and ``$(dirname)`` (this file's folder). Parameter values given as strings are read as YAML
after substitution, as launch_ros does (``'true'`` is a bool). rv-te runs one namespace and one
remapping list for the whole session: nodes that differ in either are an error.
"""

from __future__ import annotations

import os
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rv_te_bench.errors import ParameterFileError, YamlInputError, YamlLimitError
from rv_te_bench.launch.node_specs import node_specs
from rv_te_bench.launch.session import (
    SessionSpec,
    build_session,
    check_session,
    normalise_namespace,
    parse_param_override,
)
from rv_te_bench.params import check_parameters, coerce_parameters
from rv_te_bench.safe_yaml import (
    DOCUMENT_LIMITS,
    SMALL_TEXT_LIMITS,
    brief,
    load_yaml,
    read_yaml_file,
)

__all__ = [
    'EXEC_TO_NODE',
    'SUBSET',
    'LaunchArg',
    'LaunchDescription',
    'LaunchNode',
    'is_launch_file',
    'load_launch_file',
    'parse_launch_arguments',
]

#: executable in lib/rv_te_bench (rv_te_bench_ros/setup.py) -> node name in the session
EXEC_TO_NODE = {'bench_node': 'bench', 'te_node': 'te_node',
                'compensation_node': 'compensation', 'recorder': 'recorder',
                'test_sequencer': 'test_sequencer', 'joint_state_adapter': 'joint_state_adapter'}
PACKAGE = 'rv_te_bench'
#: tag -> attributes rv-te launch understands (the rest of the format is an error)
SUBSET: dict[str, frozenset[str]] = {
    'arg': frozenset({'name', 'default', 'description', 'choice'}),
    'let': frozenset({'name', 'value'}),
    'node': frozenset({'pkg', 'exec', 'name', 'namespace', 'param', 'remap', 'output'}),
}
_SUBSTITUTIONS = ('var', 'env', 'find-pkg-share', 'dirname')
_SUBST = re.compile(r'\$\(([^()$]*)\)')


@dataclass(frozen=True)
class LaunchArg:
    """A declared launch argument (``arg``)."""

    name: str
    default: str | None
    description: str = ''
    choices: tuple[str, ...] = ()


@dataclass(frozen=True)
class LaunchNode:
    """A ``node`` action, substitutions done.

    Attributes:
        node: Node name in the session (bench, te_node, compensation, recorder).
        namespace: Its namespace as written ('' for none).
        params: In order: ``('file', Path)`` or ``('value', (name, value))``.
        remappings: ``(from, to)`` pairs.
    """

    node: str
    namespace: str
    params: tuple[tuple[str, Any], ...] = ()
    remappings: tuple[tuple[str, str], ...] = ()


@dataclass(frozen=True)
class LaunchDescription:
    """A parsed launch file: its arguments, their values and its nodes."""

    path: Path
    args: tuple[LaunchArg, ...]
    values: dict[str, str] = field(default_factory=dict)
    nodes: tuple[LaunchNode, ...] = ()


def _error(path: Path, where: str, what: str) -> ParameterFileError:
    return ParameterFileError(f'launch file {path}: {where}: {what}')


def _read(path: Path) -> Any:
    return read_yaml_file(path, what='launch file', limits=DOCUMENT_LIMITS)


def is_launch_file(path: str | Path) -> bool:
    """True when ``path`` is a YAML file whose top level is ``launch:`` (not a parameter file)."""
    p = Path(path)
    if not p.is_file():
        return False
    try:
        with p.open('rb') as f:
            head = f.read(64 * 1024).decode('utf-8', errors='replace')
    except OSError:
        return False
    return re.search(r'^launch:\s*$', head, flags=re.MULTILINE) is not None


def parse_launch_arguments(items: Sequence[str]) -> dict[str, str]:
    """``name:=value`` command-line items -> mapping (as ``ros2 launch`` takes them).

    Raises:
        ParameterFileError: An item that is not ``name:=value``.
    """
    out: dict[str, str] = {}
    for item in items:
        name, sep, value = item.partition(':=')
        if not sep or not re.fullmatch(r'[A-Za-z_][A-Za-z0-9_]*', name):
            msg = f'launch argument {item!r} is not of the form name:=value'
            raise ParameterFileError(msg)
        out[name] = value
    return out


def find_package_share(package: str) -> Path:
    """``$(find-pkg-share PKG)``: an ament prefix's share dir, or this package's files.

    Raises:
        ParameterFileError: The package is in no ament prefix (and is not rv_te_bench).
    """
    for prefix in filter(None, os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep)):
        marker = Path(prefix) / 'share' / 'ament_index' / 'resource_index' / 'packages'
        if (marker / package).is_file():
            return Path(prefix) / 'share' / package
    if package == PACKAGE:   # pip install: launch/ sits in the Python package
        return Path(__file__).resolve().parents[1]
    msg = f'$(find-pkg-share {package}): package not found on AMENT_PREFIX_PATH'
    raise ParameterFileError(msg)


class _Context:
    """Launch configurations and the file being read, for substitutions."""

    def __init__(self, path: Path, values: dict[str, str]) -> None:
        self.path = path
        self.values = values

    def substitute(self, text: str, where: str) -> str:
        def one(m: re.Match[str]) -> str:
            parts = m.group(1).split()
            name, args = (parts[0], parts[1:]) if parts else ('', [])
            if name == 'var' and len(args) == 1:
                if args[0] not in self.values:
                    raise _error(self.path, where, f'$(var {args[0]}): no such launch argument')
                return self.values[args[0]]
            if name == 'env' and len(args) in {1, 2}:
                value = os.environ.get(args[0], args[1] if len(args) == 2 else None)
                if value is None:
                    raise _error(self.path, where, f'$(env {args[0]}): not set')
                return value
            if name == 'find-pkg-share' and len(args) == 1:
                return str(find_package_share(args[0]))
            if name == 'dirname' and not args:
                return str(self.path.resolve().parent)
            if name in _SUBSTITUTIONS:
                raise _error(self.path, where, f'$({m.group(1)}): wrong number of arguments')
            raise _error(self.path, where, f'substitution $({name}) is not supported by rv-te '
                                           f'launch (supported: {", ".join(_SUBSTITUTIONS)})')

        if re.search(r'\$\([^)]*\$\(', text):
            raise _error(self.path, where, f'nested substitutions are not supported by rv-te '
                                           f'launch: {text!r}')
        out = _SUBST.sub(one, text)
        if '$(' in out:
            raise _error(self.path, where, f'unterminated substitution in {text!r}')
        return out

    def value(self, raw: Any, where: str) -> Any:
        """A ``param`` value: strings substituted, then read as YAML (launch_ros's rule)."""
        if isinstance(raw, str):
            text = self.substitute(raw, where)
            try:
                return (load_yaml(text, origin=f'launch file {self.path}: {where}',
                                  limits=SMALL_TEXT_LIMITS) if text.strip() else text)
            except YamlLimitError:
                raise
            except YamlInputError:
                return text
        if isinstance(raw, list):
            return [self.substitute(v, where) if isinstance(v, str) else v for v in raw]
        return raw


def _attrs(path: Path, tag: str, body: Any, where: str) -> dict[str, Any]:
    if not isinstance(body, dict):
        raise _error(path, where, f'{tag!r} must be a mapping of attributes')
    unknown = sorted(set(body) - SUBSET[tag])
    if unknown:
        raise _error(path, where, f'attribute {unknown[0]!r} of {tag!r} is not supported by '
                                  f'rv-te launch (supported: {", ".join(sorted(SUBSET[tag]))})')
    return body


def _string(path: Path, body: dict[str, Any], key: str, where: str) -> str:
    value = body.get(key)
    if not isinstance(value, str | int | float) or isinstance(value, bool):
        raise _error(path, where, f'attribute {key!r} must be a string')
    return str(value)


def load_launch_file(path: str | Path, arguments: Mapping[str, str] | None = None
                     ) -> LaunchDescription:
    """Read a launch file, apply ``arguments`` (``name -> value``) and every substitution.

    Raises:
        ParameterFileError: Bad YAML, a tag/attribute/substitution outside the subset, a
            missing or undeclared argument, an unknown executable or node name.
    """
    p = Path(path)
    data = _read(p)
    if not isinstance(data, dict) or set(data) != {'launch'} or not isinstance(
            data['launch'], list):
        raise _error(p, 'top level', 'must be "launch:" followed by a list of actions')
    given = dict(arguments or {})
    ctx = _Context(p, {})
    args: list[LaunchArg] = []
    nodes: list[LaunchNode] = []
    for i, action in enumerate(data['launch']):
        where = f'action {i + 1}'
        if not isinstance(action, dict) or len(action) != 1:
            raise _error(p, where, 'each action is a one-key mapping such as "- node: {...}"')
        tag, body = next(iter(action.items()))
        if tag not in SUBSET:
            raise _error(p, where, f'tag {tag!r} is not supported by rv-te launch (supported: '
                                   f'{", ".join(SUBSET)})')
        body = _attrs(p, tag, body, f'{where} ({tag})')
        if tag == 'arg':
            args.append(_arg(p, body, where, ctx, given))
        elif tag == 'let':
            name = _string(p, body, 'name', where)
            ctx.values[name] = ctx.substitute(_string(p, body, 'value', where), where)
        else:
            nodes.append(_node(p, body, where, ctx))
    undeclared = sorted(set(given) - {a.name for a in args})
    if undeclared:
        raise _error(p, 'arguments', f'{undeclared[0]!r} is not declared in the file '
                                     f'(declared: {", ".join(a.name for a in args) or "none"})')
    if not nodes:
        raise _error(p, 'launch', 'no node to start')
    return LaunchDescription(path=p, args=tuple(args), values=dict(ctx.values),
                             nodes=tuple(nodes))


def _arg(p: Path, body: dict[str, Any], where: str, ctx: _Context,
         given: Mapping[str, str]) -> LaunchArg:
    name = _string(p, body, 'name', where)
    default = ctx.substitute(_string(p, body, 'default', where), where) \
        if 'default' in body else None
    choices: tuple[str, ...] = ()
    if 'choice' in body:
        if not isinstance(body['choice'], list) or not all(
                isinstance(c, dict) and set(c) == {'value'} for c in body['choice']):
            raise _error(p, where, f'arg {name!r}: choice must be a list of {{value: ...}}')
        choices = tuple(str(c['value']) for c in body['choice'])
    value = given.get(name, default)
    if value is None:
        raise _error(p, where, f'launch argument {name!r} has no default: give {name}:=VALUE')
    if choices and value not in choices:
        raise _error(p, where, f'launch argument {name}:={value!r} is not one of '
                               f'{", ".join(choices)}')
    ctx.values[name] = value
    return LaunchArg(name=name, default=default, description=str(body.get('description', '')),
                     choices=choices)


def _node(p: Path, body: dict[str, Any], where: str, ctx: _Context) -> LaunchNode:
    pkg = ctx.substitute(_string(p, body, 'pkg', where), where) if 'pkg' in body else ''
    if pkg != PACKAGE:
        raise _error(p, where, f'node pkg {pkg!r}: rv-te launch starts the nodes of '
                               f'{PACKAGE} only')
    exe = ctx.substitute(_string(p, body, 'exec', where), where)
    if exe not in EXEC_TO_NODE:
        raise _error(p, where, f'node exec {exe!r} is not one of {", ".join(EXEC_TO_NODE)}')
    node = EXEC_TO_NODE[exe]
    name = ctx.substitute(_string(p, body, 'name', where), where) if 'name' in body else node
    if name != node:
        raise _error(p, where, f'node name {name!r} for exec {exe!r}: rv-te launch runs it as '
                               f'{node!r} (use a namespace to run two sessions)')
    ns = ctx.substitute(_string(p, body, 'namespace', where), where) \
        if 'namespace' in body else ''
    where = f'{where} (node {node})'
    params: list[tuple[str, Any]] = []
    for item in _entries(p, body, 'param', where):
        if set(item) == {'from'}:
            params.append(('file', Path(ctx.substitute(_string(p, item, 'from', where), where))))
        elif set(item) == {'name', 'value'}:
            pname = ctx.substitute(_string(p, item, 'name', where), where)
            params.append(('value', (pname, ctx.value(item['value'], f'{where} param {pname}'))))
        else:
            extra = sorted(set(item) - {'from', 'name', 'value'})
            what = (f'param attribute {extra[0]!r} is not supported by rv-te launch'
                    if extra else 'param needs "from" or "name" and "value"')
            raise _error(p, where, f'{what} (supported: {{from}} or {{name, value}})')
    remaps: list[tuple[str, str]] = []
    for item in _entries(p, body, 'remap', where):
        if set(item) != {'from', 'to'}:
            raise _error(p, where, 'remap needs exactly "from" and "to"')
        remaps.append((ctx.substitute(_string(p, item, 'from', where), where),
                       ctx.substitute(_string(p, item, 'to', where), where)))
    return LaunchNode(node=node, namespace=ns, params=tuple(params), remappings=tuple(remaps))


def _entries(p: Path, body: dict[str, Any], key: str, where: str) -> list[dict[str, Any]]:
    items = body.get(key, [])
    if not isinstance(items, list) or not all(isinstance(i, dict) for i in items):
        raise _error(p, where, f'{key!r} must be a list of mappings')
    return items


def session_from_launch(desc: LaunchDescription, *, overrides: Sequence[str] = (),
                        nodes: Sequence[str] | None = None, namespace: str = '',
                        remappings: Sequence[str] = (),
                        single_process: bool = False) -> SessionSpec:
    """The session a launch file describes, checked like a parameter-file session.

    Each node gets its ``param`` entries in order (a file's keys for that node, then inline
    values; later wins, as in launch_ros), then the ``--param`` overrides.

    Args:
        desc: From :func:`load_launch_file`.
        overrides: ``node.key=value`` items (``rv-te launch --param``).
        nodes: Start only these of the file's nodes (None: all).
        namespace: Pushed in front of the file's (relative) namespaces, as launch_ros's
            PushRosNamespace does (``rv-te launch --namespace``).
        remappings: ``from:=to`` items applied to every node after the file's own, as
            launch_ros's SetRemap does (``rv-te launch --remap``).
        single_process: All nodes in one process.

    Raises:
        ParameterFileError: A bad parameter (file, key and rule named), nodes in different
            namespaces or with different remappings, a node named twice or not in the file,
            a recorder on sim time beside a bench that publishes no /clock.
    """
    p = desc.path
    names = [n.node for n in desc.nodes]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise _error(p, 'nodes', f'node {twice[0]!r} appears more than once')
    chosen = [n for n in desc.nodes if nodes is None or n.node in nodes]
    missing = sorted(set(nodes or ()) - set(names))
    if missing:
        raise _error(p, '--nodes', f'unknown node {missing[0]!r}; the file starts '
                                   f'{", ".join(names)}')
    pushed = normalise_namespace(namespace)
    namespaces = {normalise_namespace(n.namespace if n.namespace.startswith('/')
                                      else f'{pushed}/{n.namespace}' if n.namespace else pushed)
                  for n in chosen}
    remaps = {n.remappings for n in chosen}
    if len(namespaces) > 1 or len(remaps) > 1:
        what = 'namespace' if len(namespaces) > 1 else 'remappings'
        raise _error(p, 'nodes', f'the nodes differ in {what}: rv-te launch runs one '
                                 f'{what} for the whole session')
    ns = namespaces.pop() if namespaces else ''
    extra = build_session([], remappings=remappings, nodes=['bench']).remappings
    params: dict[str, dict[str, Any]] = {}
    for n in chosen:
        values: dict[str, Any] = {}
        for kind, item in n.params:
            if kind == 'file':
                spec = build_session([item], namespace=ns, nodes=[n.node])
                values.update(spec.parameters[n.node])
                if spec.use_sim_time and n.node != 'bench':
                    values['use_sim_time'] = True
                continue
            name, value = item
            where = f'launch file {p}: node {n.node!r} param {name!r}'
            if name == 'use_sim_time':
                if not isinstance(value, bool):
                    msg = f'{where}: must be a bool, got {value!r}'
                    raise ParameterFileError(msg)
                values[name] = value
                continue
            check_parameters(node_specs(n.node), {name: value}, where=where)
            values.update(coerce_parameters(node_specs(n.node), {name: value}))
        params[n.node] = values
    for item in overrides:
        node, key, value = parse_param_override(item)
        if node not in params:
            msg = f'--param {brief(item)}: node {node!r} is not started ({", ".join(params)})'
            raise ParameterFileError(msg)
        check_parameters(node_specs(node), {key: value}, where=f'--param {brief(item)}')
        params[node].update(coerce_parameters(node_specs(node), {key: value}))
    bench = params.get('bench')
    if bench is not None and 'wait_for_nodes' in bench:   # a node left out is not waited for
        # (the live page's bridge, rv-te dashboard, is no node of the file but may be waited for)
        bench['wait_for_nodes'] = [w for w in bench['wait_for_nodes']
                                   if w in params or w == 'dashboard']
    recorder = params.get('recorder', {})
    if recorder.get('use_sim_time') and bench is not None and bench.get(
            'time_mode', 'realtime') != 'fast':
        raise _error(p, 'nodes', 'the recorder runs on sim time (use_sim_time) but the bench '
                                 'is in realtime mode and publishes no /clock: give '
                                 'use_sim_time:=false')
    if recorder.get('use_sim_time') is False and bench is not None and bench.get(
            'time_mode', 'realtime') == 'fast':
        # (issue #22) it would log a fast session at wall-clock time: squeezed log times
        raise _error(p, 'nodes', 'the bench is in fast (sim-time) mode but the recorder '
                                 'logs at wall-clock time (use_sim_time:=false): the bag would '
                                 'squeeze the session into its wall-clock duration; give '
                                 'use_sim_time:=true or bench.time_mode=realtime')
    spec = SessionSpec(nodes=tuple(params), namespace=ns, parameters=params,
                       remappings=(next(iter(remaps)) if remaps else ()) + extra,
                       single_process=single_process, launch_file=str(p.resolve()),
                       launch_arguments={a.name: desc.values[a.name] for a in desc.args})
    check_session(spec)   # what each node checks at start (rv-te launch --check runs it)
    return spec
