"""A bad parameter file stops the launch before any node starts, naming file, key and rule."""

from __future__ import annotations

from pathlib import Path

import pytest

from rv_te_bench.errors import ParameterFileError
from rv_te_bench.launch.session import build_session, normalise_namespace

GOOD = """\
bench:
  ros__parameters:
    preset: wang2020-2kv
    sample_rate_hz: 1000.0
    block_size: 100
    time_mode: fast
te_node:
  ros__parameters:
    window_revolutions: 1
/bench2/bench:
  ros__parameters:
    speed_rpm: 600.0
"""


def write(tmp_path: Path, text: str, name: str = 'session.yaml') -> Path:
    p = tmp_path / name
    p.write_text(text, encoding='utf-8')
    return p


def test_good_file_is_accepted_and_namespaced_keys_select(tmp_path: Path) -> None:
    f = write(tmp_path, GOOD)
    spec = build_session([f])
    assert spec.parameters['bench']['sample_rate_hz'] == 1000.0
    assert 'speed_rpm' not in spec.parameters['bench']  # meant for /bench2 only
    spec2 = build_session([f], namespace='bench2')
    assert spec2.namespace == '/bench2'
    assert spec2.parameters['bench']['speed_rpm'] == 600.0


@pytest.mark.parametrize(('body', 'needles'), [
    ('bench:\n  ros__parameters:\n    sample_rat_hz: 10.0\n',
     ["'sample_rat_hz'", 'unknown parameter']),
    ('bench:\n  ros__parameters:\n    sample_rate_hz: fast\n',
     ["'sample_rate_hz'", 'must be a number']),
    ('bench:\n  ros__parameters:\n    sample_rate_hz: -5.0\n',
     ["'sample_rate_hz'", 'must be >= 1']),
    ('bench:\n  ros__parameters:\n    block_size: 0\n', ["'block_size'", 'must be >= 1']),
    ('bench:\n  ros__parameters:\n    block_size: 10.5\n', ["'block_size'", 'integer']),
    ('bench:\n  ros__parameters:\n    time_mode: warp\n', ["'time_mode'", 'one of']),
    ('bench:\n  ros__parameters:\n    overrides: gear.z_sun=13\n',
     ["'overrides'", 'list of strings']),
    ('te_node:\n  ros__parameters:\n    decimated_rate_hz: .nan\n',
     ["'decimated_rate_hz'", 'finite']),
    ('te_node:\n  ros__parameters:\n    window_revolutions: 1.5\n',
     ["'window_revolutions'", 'integer']),
    ('benchh:\n  ros__parameters:\n    speed_rpm: 1.0\n', ["'benchh'", 'unknown node']),
    ('bench:\n  parameters:\n    speed_rpm: 1.0\n', ['ros__parameters']),
    ('bench: [1, 2\n', ['not valid YAML']),
    ('- 1\n- 2\n', ['top level']),
    ('/**:\n  ros__parameters:\n    no_such_param: 1\n', ["'no_such_param'", 'no node']),
    ('/**:\n  ros__parameters:\n    use_sim_time: 3\n', ["'use_sim_time'", 'bool']),
])
def test_bad_file_names_file_key_and_rule(tmp_path: Path, body: str,
                                          needles: list[str]) -> None:
    f = write(tmp_path, body)
    with pytest.raises(ParameterFileError) as info:
        build_session([f])
    text = str(info.value)
    assert str(f) in text
    for n in needles:
        assert n in text, text


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(ParameterFileError, match='cannot read'):
        build_session([tmp_path / 'nope.yaml'])


@pytest.mark.parametrize(('item', 'needle'), [
    ('bench.sample_rate_hz=0', 'must be >= 1'),
    ('bench.nope=1', "unknown parameter 'nope'"),
    ('nobody.speed_rpm=1', "unknown node 'nobody'"),
    ('speed_rpm=1', 'node.key=value'),
])
def test_bad_param_override(item: str, needle: str) -> None:
    with pytest.raises(ParameterFileError, match=needle):
        build_session([], overrides=[item])


def test_integer_override_for_double_is_accepted() -> None:
    spec = build_session([], overrides=['bench.speed_rpm=600'])
    assert spec.parameters['bench']['speed_rpm'] == 600.0
    assert isinstance(spec.parameters['bench']['speed_rpm'], float)


@pytest.mark.parametrize('ns', ['1abc', 'a b', 'a//b', 'a-b'])
def test_bad_namespace(ns: str) -> None:
    with pytest.raises(ParameterFileError, match='namespace'):
        normalise_namespace(ns)


def test_bad_remap_and_unknown_node() -> None:
    with pytest.raises(ParameterFileError, match='from:=to'):
        build_session([], remappings=['bench/encoders'])
    with pytest.raises(ParameterFileError, match="unknown node 'viewer'"):
        build_session([], nodes=['bench', 'viewer'])


def test_packaged_default_session_is_valid() -> None:
    from rv_te_bench.cli.launch import default_session_file

    spec = build_session([default_session_file()])
    assert spec.parameters['bench']['preset'] == 'wang2020-2kv'
    assert spec.parameters['bench']['sample_rate_hz'] == 1000.0


def test_integer_in_a_file_for_a_double_is_coerced(tmp_path: Path) -> None:
    # ROS users write 300 for 300.0; rclpy would reject the integer for a double parameter
    f = write(tmp_path, 'bench:\n  ros__parameters:\n    speed_rpm: 600\n'
                        'te_node:\n  ros__parameters:\n    mesh_orders: [936, 1300]\n')
    spec = build_session([f])
    assert spec.parameters['bench']['speed_rpm'] == 600.0
    assert isinstance(spec.parameters['bench']['speed_rpm'], float)
    assert all(isinstance(x, float) for x in spec.parameters['te_node']['mesh_orders'])


def test_deprecated_crank_per_input_still_accepted_with_a_warning(tmp_path: Path) -> None:
    """Parameter files written before te_node's crank_per_input became crank_per_output (the
    name rv-te analyze uses) still launch, with a warning naming the replacement (#15)."""
    f = write(tmp_path, 'te_node:\n  ros__parameters:\n    gear_ratio: 79.0\n'
                        '    crank_per_input: -0.31645569620253167\n')
    with pytest.warns(FutureWarning, match="'crank_per_input' is deprecated; use "
                                           "'crank_per_output'"):
        spec = build_session([f])
    assert spec.parameters['te_node']['crank_per_input'] == pytest.approx(-25 / 79)
    new = write(tmp_path, 'te_node:\n  ros__parameters:\n    gear_ratio: 79.0\n'
                          '    crank_per_output: 25.0\n', name='new.yaml')
    assert build_session([new]).parameters['te_node']['crank_per_output'] == 25.0
