"""rv-te launch reads ROS 2 YAML launch files: the supported subset, and a clear error naming the
tag, attribute or substitution for everything else (no ROS needed)."""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest
import yaml

from rv_te_bench.cli.launch import default_launch_file, default_session_file
from rv_te_bench.cli.main import main
from rv_te_bench.errors import ParameterFileError
from rv_te_bench.launch.launch_file import (
    EXEC_TO_NODE,
    find_package_share,
    is_launch_file,
    load_launch_file,
    parse_launch_arguments,
    session_from_launch,
)
from rv_te_bench.launch.node_specs import NODE_TYPES
from rv_te_bench.launch.session import build_session

NODE = '''\
- node:
    pkg: rv_te_bench
    exec: te_node
    name: te_node
'''


def write(tmp_path: Path, body: str, name: str = 'x.launch.yaml') -> Path:
    f = tmp_path / name
    f.write_text('launch:\n' + textwrap.dedent(body), encoding='utf-8')
    return f


def spec_of(path: Path, **kw: object):
    args = kw.pop('args', {})
    return session_from_launch(load_launch_file(path, args), **kw)  # type: ignore[arg-type]


def test_shipped_file_gives_the_default_session_parameters() -> None:
    """The launch file loads default_session.yaml for every node: the same parameters as the
    parameter-file path, plus what the file sets inline for ros2 launch."""
    spec = spec_of(Path(default_launch_file()))
    plain = build_session([default_session_file()])
    assert set(spec.nodes) == set(plain.nodes) == {'bench', 'te_node', 'compensation',
                                                   'recorder'}
    for node in plain.nodes:
        extra = {k: v for k, v in spec.parameters[node].items()
                 if k not in plain.parameters[node]}
        assert {k: spec.parameters[node][k] for k in plain.parameters[node]} == \
            plain.parameters[node]
        assert extra == {'bench': {'wait_for_nodes': ['te_node', 'recorder']},
                         'recorder': {'use_sim_time': True}}.get(node, {})
    assert spec.namespace == ''
    assert spec.launch_arguments['namespace'] == ''


@pytest.mark.parametrize(('body', 'needle'), [
    ('- group: {}\n', "tag 'group' is not supported by rv-te launch"),
    ('- include: {file: a.launch.py}\n', "tag 'include' is not supported"),
    (NODE.replace('name: te_node', 'name: te_node\n    respawn: true'),
     "attribute 'respawn' of 'node' is not supported"),
    ('- arg: {name: a, if: x}\n', "attribute 'if' of 'arg' is not supported"),
    (NODE.replace('name: te_node', 'name: $(anon te)'),
     'substitution $(anon) is not supported by rv-te launch'),
    (NODE.replace('name: te_node', 'name: $(var $(var a))'), 'nested substitutions are not'),
    (NODE.replace('name: te_node', 'name: $(var a'), 'unterminated substitution'),
    (NODE.replace('name: te_node', 'name: $(var nope)'), '$(var nope): no such launch argument'),
    (NODE.replace('pkg: rv_te_bench', 'pkg: demo_nodes_py'), "node pkg 'demo_nodes_py'"),
    (NODE.replace('exec: te_node', 'exec: talker'), "node exec 'talker' is not one of"),
    (NODE.replace('name: te_node', 'name: my_te'), "node name 'my_te' for exec 'te_node'"),
    (NODE + '    param:\n    - {name: p, param: []}\n', "param attribute 'param' is not"),
    (NODE + '    param:\n    - {name: window_revolutions}\n', 'param needs "from" or "name"'),
    (NODE + '    remap:\n    - {from: a}\n', 'remap needs exactly "from" and "to"'),
    ('- node: [1, 2]\n', "'node' must be a mapping"),
    ('- {node: {}, arg: {}}\n', 'each action is a one-key mapping'),
    ('- arg: {name: a}\n' + NODE, "launch argument 'a' has no default: give a:=VALUE"),
    ('- arg: {name: a, default: x, choice: [{value: y}]}\n' + NODE, "a:='x' is not one of y"),
    ('- let: {name: a, value: b}\n', 'no node to start'),
    ('  - 1\n', 'each action is a one-key mapping'),
])
def test_outside_the_subset_is_one_clear_error(tmp_path: Path, body: str, needle: str) -> None:
    f = write(tmp_path, body)
    with pytest.raises(ParameterFileError) as err:
        spec_of(f)
    assert needle in str(err.value)
    assert str(f) in str(err.value) and '\n' not in str(err.value)


def test_arguments_defaults_choices_and_undeclared(tmp_path: Path) -> None:
    f = write(tmp_path, '''\
        - arg: {name: ns, default: '', description: the namespace}
        - arg: {name: mode, default: fast, choice: [{value: fast}, {value: realtime}]}
        - let: {name: twice, value: $(var ns)x}
        - node:
            pkg: rv_te_bench
            exec: bench_node
            namespace: $(var ns)
            param:
            - {name: time_mode, value: $(var mode)}
            - {name: bench_id, value: $(var twice)}
        ''')
    spec = spec_of(f, args={'ns': 'b2', 'mode': 'realtime'})
    assert spec.namespace == '/b2'
    assert spec.parameters['bench']['time_mode'] == 'realtime'
    assert spec.parameters['bench']['bench_id'] == 'b2x'
    with pytest.raises(ParameterFileError, match="'mod' is not declared in the file"):
        load_launch_file(f, {'mod': 'fast'})
    with pytest.raises(ParameterFileError, match="mode:='slow' is not one of fast, realtime"):
        load_launch_file(f, {'mode': 'slow'})


def test_params_apply_in_order_and_values_are_read_as_yaml(tmp_path: Path) -> None:
    params = tmp_path / 'p.yaml'
    params.write_text(yaml.safe_dump({'/**/te_node': {'ros__parameters': {
        'window_revolutions': 3, 'decimated_rate_hz': 20.0}}}), encoding='utf-8')
    f = write(tmp_path, f'''\
        - arg: {{name: rate, default: '40'}}
        - node:
            pkg: rv_te_bench
            exec: te_node
            param:
            - {{name: window_revolutions, value: 2}}
            - from: {params}
            - {{name: decimated_rate_hz, value: $(var rate)}}
        ''')
    p = spec_of(f).parameters['te_node']
    assert p['window_revolutions'] == 3              # the file came later: it wins
    assert p['decimated_rate_hz'] == 40.0            # '40' read as YAML, coerced to double
    assert isinstance(p['decimated_rate_hz'], float)
    f2 = write(tmp_path, NODE + '    param:\n    - {name: window_revolutions, value: 0}\n',
               name='bad.launch.yaml')
    with pytest.raises(ParameterFileError, match=r"param 'window_revolutions'.*>= 1"):
        spec_of(f2)


def test_substitutions_env_dirname_find_pkg_share(tmp_path: Path,
                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    (tmp_path / 'p.yaml').write_text('te_node:\n  ros__parameters: {window_revolutions: 4}\n')
    f = write(tmp_path, NODE + '    param:\n    - from: $(dirname)/p.yaml\n'
              '    - {name: decimated_rate_hz, value: $(env RV_TE_TEST_RATE 25)}\n')
    monkeypatch.delenv('RV_TE_TEST_RATE', raising=False)
    assert spec_of(f).parameters['te_node'] == {'window_revolutions': 4,
                                                'decimated_rate_hz': 25.0}
    monkeypatch.setenv('RV_TE_TEST_RATE', '30')
    assert spec_of(f).parameters['te_node']['decimated_rate_hz'] == 30.0
    # find-pkg-share: an ament prefix that registers the package wins over the pip files
    monkeypatch.setenv('AMENT_PREFIX_PATH', '')
    assert find_package_share('rv_te_bench') / 'launch' / 'session.launch.yaml' == \
        Path(default_launch_file())
    prefix = tmp_path / 'install'
    (prefix / 'share' / 'ament_index' / 'resource_index' / 'packages').mkdir(parents=True)
    (prefix / 'share' / 'ament_index' / 'resource_index' / 'packages' / 'rv_te_bench').touch()
    monkeypatch.setenv('AMENT_PREFIX_PATH', str(prefix))
    assert find_package_share('rv_te_bench') == prefix / 'share' / 'rv_te_bench'
    with pytest.raises(ParameterFileError, match='find-pkg-share nav2_bringup'):
        find_package_share('nav2_bringup')


def test_one_namespace_and_remapping_list(tmp_path: Path) -> None:
    two = NODE.replace('exec: te_node\n    name: te_node', 'exec: recorder\n    name: recorder')
    f = write(tmp_path, NODE + '    namespace: a\n' + two + '    namespace: b\n')
    with pytest.raises(ParameterFileError, match='the nodes differ in namespace'):
        spec_of(f)
    g = write(tmp_path, NODE + '    remap: [{from: te/plot, to: plot}]\n' + two,
              name='g.launch.yaml')
    with pytest.raises(ParameterFileError, match='the nodes differ in remappings'):
        spec_of(g)
    h = write(tmp_path, (NODE + '    namespace: a\n    remap: [{from: te/plot, to: plot}]\n')
              + two + '    namespace: a\n    remap: [{from: te/plot, to: plot}]\n',
              name='h.launch.yaml')
    spec = spec_of(h, namespace='rig', remappings=['/clock:=/sim_clock'])
    assert spec.namespace == '/rig/a'                         # pushed in front
    assert spec.remappings == (('te/plot', 'plot'), ('/clock', '/sim_clock'))


def test_recorder_on_sim_time_needs_a_fast_bench() -> None:
    path = Path(default_launch_file())
    with pytest.raises(ParameterFileError, match='use_sim_time:=false'):
        spec_of(path, overrides=['bench.time_mode=realtime'])
    spec = spec_of(path, args={'use_sim_time': 'false'}, overrides=['bench.time_mode=realtime'])
    assert spec.parameters['recorder']['use_sim_time'] is False


def test_fast_bench_with_a_wall_clock_recorder_is_refused(
        capsys: pytest.CaptureFixture[str]) -> None:
    """Issue #22: `launch --default use_sim_time:=false` with a fast bench was accepted and
    recorded log times squeezed into the wall-clock duration: refused in one line."""
    path = Path(default_launch_file())
    with pytest.raises(ParameterFileError, match='squeeze'):
        spec_of(path, args={'use_sim_time': 'false'})   # the default bench is fast
    assert main(['launch', '--default', 'use_sim_time:=false', '--check']) == 1
    err = capsys.readouterr().err.strip()
    assert err.count('\n') == 0 and err.startswith('ERROR:') and 'use_sim_time:=true' in err
    spec = spec_of(path, args={'use_sim_time': 'false'}, overrides=['bench.time_mode=realtime'])
    assert spec.parameters['recorder']['use_sim_time'] is False   # the consistent pair


def test_nodes_subset_drops_them_from_the_bench_wait() -> None:
    spec = spec_of(Path(default_launch_file()), nodes=['bench', 'te_node'])
    assert spec.nodes == ('te_node', 'bench')
    assert spec.parameters['bench']['wait_for_nodes'] == ['te_node']


def test_exec_names_are_the_installed_executables() -> None:
    """EXEC_TO_NODE agrees with the ament setup.py's executables and the session's modules."""
    from tests.package.conftest import setup_py_value

    exes = setup_py_value('EXECUTABLES')
    for exe, node in EXEC_TO_NODE.items():
        assert exes[exe].split(':')[0] == NODE_TYPES[node][0]   # type: ignore[index]


def test_cli_detects_launch_files_and_arguments(tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    assert is_launch_file(default_launch_file())
    assert not is_launch_file(default_session_file())
    assert parse_launch_arguments(['a:=1', 'b:=']) == {'a': '1', 'b': ''}
    with pytest.raises(ParameterFileError, match="'a=1' is not of the form name:=value"):
        parse_launch_arguments(['a=1'])
    assert main(['launch', default_launch_file(), 'namespace:=rig1', '--check']) == 0
    out = capsys.readouterr().out
    assert 'in namespace /rig1' in out and 'use_sim_time:=true' in out
    assert main(['launch', default_session_file(), 'namespace:=rig1', '--check']) == 1
    assert 'need a launch file' in capsys.readouterr().err
    assert main(['launch', default_launch_file(), default_session_file(), '--check']) == 1
    assert 'a launch file runs alone' in capsys.readouterr().err
