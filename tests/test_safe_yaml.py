"""The one bounded YAML loader (rv_te_bench.safe_yaml): limits, typing as rcl types, messages.

The 'ros' scalar typing is checked against rcl itself: the same spellings given to a real
rclpy node as ``-p name:=value`` (rcl's YAML value parser) must come back with the same type
and value.
"""

from __future__ import annotations

import math
import time

import pytest
import yaml

from rv_te_bench.errors import YamlInputError, YamlLimitError
from rv_te_bench.safe_yaml import (
    BAG_METADATA_LIMITS,
    PARAMETER_FILE_LIMITS,
    SMALL_TEXT_LIMITS,
    YamlLimits,
    brief,
    dump_ros_yaml,
    load_yaml,
    ros_scalar,
)


def alias_bomb(levels: int = 9, fan: int = 9) -> str:
    """The billion-laughs document: ~1 KB, fan**levels leaves once expanded."""
    lines = ['a0: &a0 ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]']
    for i in range(1, levels):
        lines.append(f'a{i}: &a{i} [' + ', '.join([f'*a{i - 1}'] * fan) + ']')
    return '\n'.join(lines) + '\n'


LIMITS = YamlLimits(max_bytes=1 << 20, max_depth=32, max_aliases=1000, max_nodes=100_000)


@pytest.mark.timeout(20)
def test_alias_bomb_is_refused_fast_by_expanded_size() -> None:
    text = alias_bomb()
    assert len(text) < 1200
    assert len(yaml.safe_load(text)['a8']) == 9   # a real bomb: PyYAML builds it (shared)
    t0 = time.perf_counter()
    with pytest.raises(YamlLimitError, match='more than 100000 YAML nodes'):
        load_yaml(text, origin='bomb', limits=LIMITS)
    assert time.perf_counter() - t0 < 2.0


def test_aliases_are_refused_where_rcl_refuses_them() -> None:
    with pytest.raises(YamlLimitError, match=r'aliases \(\*name\) are not allowed'):
        load_yaml('a: &x 1\nb: *x\n', origin='p', limits=PARAMETER_FILE_LIMITS)
    assert load_yaml('a: &x 1\nb: *x\n', origin='m', limits=LIMITS) == {'a': 1, 'b': 1}


def test_self_referencing_and_undefined_aliases() -> None:
    with pytest.raises(YamlInputError, match='refers to itself'):
        load_yaml('a: &x [1, *x]\n', origin='m', limits=LIMITS)
    with pytest.raises(YamlInputError):
        load_yaml('a: *nope\n', origin='m', limits=LIMITS)


@pytest.mark.timeout(20)
def test_depth_is_bounded_without_recursion() -> None:
    deep = '[' * 100_000 + ']' * 100_000
    with pytest.raises(YamlLimitError, match='nested deeper than 32 levels'):
        load_yaml(deep, origin='deep', limits=LIMITS)
    ok = '[' * 32 + ']' * 32
    assert load_yaml(ok, origin='ok', limits=LIMITS) is not None


def test_size_is_checked_before_parsing() -> None:
    with pytest.raises(YamlLimitError, match='larger than 64 KiB'):
        load_yaml('a: ' + 'x' * (64 << 10), origin='value', limits=SMALL_TEXT_LIMITS)


def test_duplicate_keys_and_non_scalar_keys() -> None:
    with pytest.raises(YamlInputError, match=r"line 2: key 'a' appears twice"):
        load_yaml('a: 1\na: 2\n', origin='f', limits=LIMITS)
    assert load_yaml('a: 1\na: 2\n', origin='f', limits=LIMITS, unique_keys=False) == {'a': 2}
    with pytest.raises(YamlInputError, match='mapping key must be a scalar'):
        load_yaml('? [1, 2]\n: 3\n', origin='f', limits=LIMITS)


@pytest.mark.parametrize('text', [
    '!!python/object/apply:os.system ["true"]', 'a: !!python/name:os.system', 'a: !custom 1',
    '--- 1\n--- 2\n'])
def test_code_tags_and_multiple_documents_are_refused(text: str) -> None:
    with pytest.raises(YamlInputError):
        load_yaml(text, origin='f', limits=LIMITS)


def test_yaml_typing_matches_safe_load_on_ordinary_data() -> None:
    text = ('a: 1\nb: 1.5\nc: true\nd: null\ne: [x, 2, 3.0]\nf: {g: "1", h: 2001-12-14}\n'
            'i: .inf\nj: 0x10\nk: "quoted"\nl: ~\n')
    assert load_yaml(text, origin='f', limits=LIMITS) == yaml.safe_load(text)


def test_messages_cut_long_values() -> None:
    long_key = 'k' * 5000
    with pytest.raises(YamlInputError) as info:
        load_yaml(f'{long_key}: 1\n{long_key}: 2\n', origin='f', limits=LIMITS)
    assert len(str(info.value)) < 200
    assert len(brief('x' * 10**6)) < 70
    assert len(brief([[['y' * 1000] * 1000] * 1000])) < 200


# Spellings and what rcl makes of them (checked against rcl below; quoted ones are strings).
ROS_SPELLINGS = [
    '1.0e12', '1e5', '1E+3', '+.5e-3', '.5', '5.', '0x10', '-0x1f', '010', '0777', '08', '0x1.8p1',
    '9223372036854775807', '9223372036854775808', '-9223372036854775808',
    '0xFFFFFFFFFFFFFFFFFF', '99999999999999999999', '+5', '-0', 'yes', 'y', 'Y', 'N', 'no',
    'True', 'on', 'OFF', 'null', '~', '1_000', '2001-12-14', '1:30', '0o17', '0b101', '0x', '1e',
    'e5', '1.2.3', 'abc', 'inf', 'Infinity', '-Infinity', '+inf', 'INF', '-.inf', '.Inf', 'nan',
    'NaN', 'nan(12)', '1e999', '1e-400', '1e-310',
]


def same(a: object, b: object) -> bool:
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return type(a) is type(b) and a == b


def test_ros_typing_of_the_issue_cases() -> None:
    # 1.0e12 is a string in YAML 1.1 (PyYAML) but a double for rcl
    assert yaml.safe_load('1.0e12') == '1.0e12'
    assert same(ros_scalar('1.0e12', quoted=False), 1.0e12)
    assert same(ros_scalar('1e5', quoted=False), 1e5)
    assert same(ros_scalar('1e5', quoted=True), '1e5')
    assert same(ros_scalar('y', quoted=False), True)   # PyYAML: 'y'
    assert same(ros_scalar('null', quoted=False), 'null')   # PyYAML: None
    with pytest.raises(YamlInputError, match='no value'):
        load_yaml('a:\n', origin='f', limits=PARAMETER_FILE_LIMITS, scalars='ros')


@pytest.mark.ros
@pytest.mark.timeout(60)
def test_ros_typing_equals_rcl_for_every_spelling(ros_domain_id: int) -> None:
    rclpy = pytest.importorskip('rclpy')
    args = ['--ros-args']
    for i, v in enumerate(ROS_SPELLINGS):
        args += ['-p', f'p{i}:={v}']
    ctx = rclpy.context.Context()
    rclpy.init(args=args, context=ctx, domain_id=ros_domain_id)
    try:
        node = rclpy.create_node('probe', context=ctx,
                                 automatically_declare_parameters_from_overrides=True)
        try:
            got = {v: node.get_parameter(f'p{i}').value for i, v in enumerate(ROS_SPELLINGS)}
        finally:
            node.destroy_node()
    finally:
        rclpy.try_shutdown(context=ctx)
    wrong = {v: (got[v], ros_scalar(v, quoted=False)) for v in ROS_SPELLINGS
             if not same(got[v], ros_scalar(v, quoted=False))}
    assert not wrong


def test_ros_dump_reads_back_as_written() -> None:
    data = {'/bench': {'ros__parameters': {
        'a': 'y', 'b': '1e5', 'c': [1.0, 2.0], 'd': True, 'e': math.inf, 'f': 'two\nlines',
        'g': [], 'h': ['x', 'on', 'null'], 'i': 3}}}
    text = dump_ros_yaml(data)
    assert '&' not in text and '*' not in text
    assert load_yaml(text, origin='f', limits=PARAMETER_FILE_LIMITS, scalars='ros') == data


@pytest.mark.timeout(30)
def test_largest_allowed_metadata_reads_in_bounded_time() -> None:
    """A 4 MiB metadata.yaml (the limit; ~24,000 split files) parses in a few seconds."""
    lines = ['rosbag2_bagfile_information:', '  relative_file_paths:']
    size, i = 60, 0
    while size < (4 << 20) - 200:
        lines.append(f'    - rv_te_20260101_000000_{i}.mcap')
        size += len(lines[-1]) + 1
        i += 1
    text = '\n'.join(lines) + '\n'
    t0 = time.perf_counter()
    doc = load_yaml(text, origin='metadata', limits=BAG_METADATA_LIMITS)
    assert len(doc['rosbag2_bagfile_information']['relative_file_paths']) == i
    assert time.perf_counter() - t0 < 20.0
