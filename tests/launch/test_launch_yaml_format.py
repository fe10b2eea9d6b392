"""The shipped rv_te_bench/launch/session.launch.yaml follows the ROS 2 YAML launch format, as
ros2/launch and ros2/launch_ros (jazzy) read it, checked without our own parser.

What the format is, from the sources (they are not installable here: no launch on PyPI):
* launch_yaml/launch_yaml/entity.py: the file is ``launch:`` with a list of one-key mappings
  (``Expected a len 1 dictionary``); attributes are the mapping's keys; an attribute read as a
  list of entities must be a list of mappings.
* launch/actions/declare_launch_argument.py ``parse``: ``arg`` has name, default, description,
  choice (a list of entities with ``value``); Action.parse adds ``if``/``unless``.
* launch_ros/actions/node.py ``Node.parse`` + ExecuteProcess.parse (cmd ignored): ``node`` has
  exec (required), pkg, name, node-name, exec_name, namespace, args, ros_args, remap (from, to),
  param, cwd, launch-prefix, output, respawn, respawn_delay, shell, env (+ if/unless);
  ``Node.parse_nested_parameters``: a param has ``from`` (and allow_substs) or ``name`` with
  ``value`` or nested ``param``, never both name and from.
* Substitutions: ``$(name args...)`` with the names launch and launch_ros expose to the
  frontend; ``$(var X)`` needs X declared before use (actions are visited in order).
"""

from __future__ import annotations

import ast
import re
from pathlib import Path
from typing import Any

import yaml

REPO = Path(__file__).resolve().parents[2]
LAUNCH_FILE = REPO / 'rv_te_bench' / 'launch' / 'session.launch.yaml'

ARG_ATTRS = {'name', 'default', 'description', 'choice', 'if', 'unless'}
NODE_ATTRS = {'exec', 'pkg', 'name', 'node-name', 'exec_name', 'namespace', 'args', 'ros_args',
              'remap', 'param', 'cwd', 'launch-prefix', 'output', 'respawn', 'respawn_delay',
              'shell', 'env', 'if', 'unless'}
OUTPUTS = {'screen', 'log', 'both'}
# launch: var, env, dirname, filename, anon, eval, command, find-exec, ...; launch_ros:
# find-pkg-share, find-pkg-prefix, exec-in-pkg, param
SUBSTITUTIONS = {'var', 'env', 'optenv', 'dirname', 'filename', 'anon', 'eval', 'command',
                 'find-exec', 'find-pkg-share', 'find-pkg-prefix', 'exec-in-pkg', 'param'}
NODE_NAME = re.compile(r'[A-Za-z_][A-Za-z0-9_]*')


def strings(value: Any) -> list[str]:
    if isinstance(value, str):
        return [value]
    if isinstance(value, list):
        return [s for v in value for s in strings(v)]
    if isinstance(value, dict):
        return [s for v in value.values() for s in strings(v)]
    return []


def substitutions(text: str) -> list[list[str]]:
    return [m.group(1).split() for m in re.finditer(r'\$\(([^()]*)\)', text)]


def setup_py_executables() -> set[str]:
    tree = ast.parse((REPO / 'rv_te_bench_ros' / 'setup.py').read_text(encoding='utf-8'))
    for node in tree.body:
        if isinstance(node, ast.Assign) and getattr(node.targets[0], 'id', '') == 'EXECUTABLES':
            return set(ast.literal_eval(node.value))
    raise AssertionError


def test_shipped_launch_file_follows_the_ros2_yaml_launch_format() -> None:
    doc = yaml.safe_load(LAUNCH_FILE.read_text(encoding='utf-8'))
    assert isinstance(doc, dict) and list(doc) == ['launch']
    assert isinstance(doc['launch'], list) and doc['launch']
    declared: set[str] = set()
    node_names = []
    package = re.search(r'<name>(\w+)</name>', (REPO / 'rv_te_bench_ros' / 'package.xml')
                        .read_text(encoding='utf-8')).group(1)
    executables = setup_py_executables()
    for action in doc['launch']:
        assert isinstance(action, dict) and len(action) == 1, action
        tag, body = next(iter(action.items()))
        assert isinstance(body, dict), action
        # substitutions: known names; $(var X) only after X is declared
        for text in strings(body):
            for sub in substitutions(text):
                assert sub and sub[0] in SUBSTITUTIONS, text
                if sub[0] == 'var':
                    assert sub[1:] and sub[1] in declared, f'$(var {sub[1:]}) before its arg'
        if tag == 'arg':
            assert set(body) <= ARG_ATTRS and isinstance(body['name'], str)
            assert isinstance(body.get('default', ''), str)          # read as a string
            for choice in body.get('choice', []):
                assert isinstance(choice, dict) and set(choice) == {'value'}
                assert isinstance(choice['value'], str)
            if 'choice' in body and 'default' in body:
                assert body['default'] in [c['value'] for c in body['choice']]
            declared.add(body['name'])
        elif tag == 'node':
            assert set(body) <= NODE_ATTRS, sorted(set(body) - NODE_ATTRS)
            assert isinstance(body['exec'], str) and body['exec'] in executables
            assert body['pkg'] == package
            assert NODE_NAME.fullmatch(body['name'])
            node_names.append(body['name'])
            assert body.get('output', 'screen') in OUTPUTS
            for param in body.get('param', []):
                assert isinstance(param, dict)
                assert not ({'name', 'from'} <= set(param)), param     # mutually exclusive
                if 'from' in param:
                    assert set(param) <= {'from', 'allow_substs'}
                else:
                    assert set(param) in ({'name', 'value'}, {'name', 'param'}), param
                    assert isinstance(param['name'], str)
            for remap in body.get('remap', []):
                assert isinstance(remap, dict) and set(remap) == {'from', 'to'}
        else:
            raise AssertionError(f'tag {tag!r} is not one this file is expected to use')
    assert sorted(node_names) == ['bench', 'compensation', 'recorder', 'te_node']
    assert len(set(node_names)) == len(node_names)


def test_parameter_files_it_loads_are_installed_and_ros_parameter_files() -> None:
    """$(find-pkg-share rv_te_bench)/launch/X must be a file setup.py installs into
    share/rv_te_bench/launch, in the ROS 2 parameter file layout with rcl node-name keys."""
    doc = yaml.safe_load(LAUNCH_FILE.read_text(encoding='utf-8'))
    setup_py = (REPO / 'rv_te_bench_ros' / 'setup.py').read_text(encoding='utf-8')
    assert "(f'share/{PACKAGE}/launch', _files('rv_te_bench/launch/*.yaml'))" in setup_py
    files = [a['arg']['default'] for a in doc['launch']
             if 'arg' in a and '$(find-pkg-share rv_te_bench)' in a['arg'].get('default', '')]
    assert files
    for f in files:
        rel = f.replace('$(find-pkg-share rv_te_bench)/launch/', '')
        params = yaml.safe_load((REPO / 'rv_te_bench' / 'launch' / rel).read_text())
        for key, body in params.items():
            assert re.fullmatch(r'(/\*\*)?(/[A-Za-z_][A-Za-z0-9_]*)*/?[A-Za-z_]\w*|/\*\*', key)
            assert list(body) == ['ros__parameters']
