"""params.ParamSpec: types, ranges, choices, rules, coercion and the file check."""

from __future__ import annotations

import math
import warnings

import pytest

from rv_te_bench.errors import ParameterFileError
from rv_te_bench.params import ParamSpec, check_parameters, coerce_parameters, coerce_value

RATE = ParamSpec('sample_rate_hz', 'double', 1000.0, 'Sample rate [Hz]', min_value=1.0,
                 max_value=1e5)
MODE = ParamSpec('mode', 'string', 'nlte', 'TE model [-]', choices=('nlte', 'dte'))
OLD = ParamSpec('rate_hz', 'double', 1000.0, 'Sample rate [Hz]', deprecated_by='sample_rate_hz')


@pytest.mark.parametrize(('spec', 'value', 'problem'), [
    (RATE, 500, None),
    (RATE, 0.5, 'must be >= 1, got 0.5'),
    (RATE, 2e5, 'must be <= 100000'),
    (RATE, math.inf, 'must be finite'),
    (RATE, True, 'must be a number'),
    (RATE, '1000', 'must be a number'),
    (MODE, 'dte', None),
    (MODE, 'xyz', "must be one of ['nlte', 'dte']"),
    (ParamSpec('n', 'int', 1, 'Count [-]', min_value=0), 1.0, 'must be an integer'),
    (ParamSpec('on', 'bool', False, 'Switch [-]'), 1, 'must be a bool'),
    (ParamSpec('xs', 'double_array', [], 'Values [-]'), [1.0, math.nan], 'finite numbers'),
    (ParamSpec('ss', 'string_array', [], 'Names [-]'), ['a', 1], 'a list of strings'),
])
def test_check(spec: ParamSpec, value: object, problem: str | None) -> None:
    got = spec.check(value)
    if problem is None:
        assert got is None
    else:
        assert got is not None
        assert problem in got


def test_a_rule_runs_after_the_type() -> None:
    spec = ParamSpec('name', 'string', 'ok', 'Folder [-]',
                     rule=lambda v: 'must not contain /' if '/' in v else None)
    assert spec.check('a/b') == 'must not contain /'
    assert spec.check(3) == 'must be a string, got 3'


def test_a_bad_default_or_type_is_a_programming_error() -> None:
    with pytest.raises(ValueError, match='default must be >= 1'):
        ParamSpec('r', 'double', 0.0, 'Rate [Hz]', min_value=1.0)
    with pytest.raises(ValueError, match="type 'float'"):
        ParamSpec('r', 'float', 0.0, 'Rate [Hz]')


def test_coercion_is_lossless_only() -> None:
    assert coerce_value(RATE, 300) == 300.0
    assert isinstance(coerce_value(RATE, 300), float)
    assert coerce_value(RATE, True) is True
    assert coerce_parameters((RATE,), {'sample_rate_hz': 2, 'other': 3}) == {
        'sample_rate_hz': 2.0, 'other': 3}


def test_check_parameters_names_where_key_and_rule() -> None:
    with pytest.raises(ParameterFileError, match=r"bench.yaml \(te\): parameter 'mode' must "):
        check_parameters((RATE, MODE), {'mode': 'x'}, where='bench.yaml (te)')
    with pytest.raises(ParameterFileError, match='unknown parameter'):
        check_parameters((RATE,), {'nope': 1}, where='f')
    with pytest.raises(ParameterFileError, match="'use_sim_time' must be a bool"):
        check_parameters((RATE,), {'use_sim_time': 'yes'}, where='f')
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter('always')
        check_parameters((OLD,), {'rate_hz': 5.0}, where='f')
    assert any("use 'sample_rate_hz'" in str(w.message) for w in caught)


# ------------------------------------------------------------------ the typed records
def _record() -> type:
    import dataclasses

    from rv_te_bench.params import param

    @dataclasses.dataclass(frozen=True)
    class RateParams:
        sample_rate_hz: float = param(1000.0, 'Sample rate [Hz]', min_value=1.0, max_value=1e5)
        mode: str = param('nlte', 'TE model [-]', choices=('nlte', 'dte'))
        waits: tuple[str, ...] = param(['recorder'], 'Nodes waited for [-]')
        on: bool = param(False, 'Switch [-]', read_only=False)

    return RateParams


def test_a_record_declares_the_specs_it_is_built_from() -> None:
    """The record's fields are the specs (type from the annotation, list defaults as for
    rclpy), and the values a node declared come back as its frozen record."""
    import dataclasses

    from rv_te_bench.params import param_specs, params_changed, params_record

    rec = _record()
    specs = param_specs(rec)
    assert [(s.name, s.type, s.default) for s in specs] == [
        ('sample_rate_hz', 'double', 1000.0), ('mode', 'string', 'nlte'),
        ('waits', 'string_array', ['recorder']), ('on', 'bool', False)]
    assert specs[0] == RATE                       # the same descriptor, range and all
    assert specs[1] == MODE
    assert not specs[3].read_only
    p = params_record(rec, {'sample_rate_hz': 250.0, 'waits': ['a', 'b'], 'use_sim_time': True})
    assert (p.sample_rate_hz, p.mode, p.waits, p.on) == (250.0, 'nlte', ('a', 'b'), False)
    with pytest.raises(dataclasses.FrozenInstanceError):
        p.sample_rate_hz = 1.0  # type: ignore[misc]
    with pytest.raises(AttributeError):
        _ = p.sample_rate   # type: ignore[attr-defined]  (misspelt: mypy says so too)
    q = params_changed(p, {'on': True, 'waits': ['c'], 'unknown': 1})
    assert (q.on, q.waits, p.on) == (True, ('c',), False)


def test_a_record_field_without_param_or_with_another_type_is_refused() -> None:
    import dataclasses

    from rv_te_bench.params import param, param_specs

    @dataclasses.dataclass(frozen=True)
    class Plain:
        rate_hz: float = 1.0

    @dataclasses.dataclass(frozen=True)
    class Listed:
        xs: list[float] = param((), 'Values [-]')  # noqa: RUF009 - the point

    with pytest.raises(ValueError, match=r'Plain.rate_hz: a parameter record field needs'):
        param_specs(Plain)
    with pytest.raises(ValueError, match=r'Listed.xs: .*got .list\[float\].'):
        param_specs(Listed)


def test_the_launcher_reads_every_node_record_without_ros() -> None:
    """rv-te launch checks parameter files against the records before any node starts:
    importing them loads no rclpy and no message package (a subprocess, a clean import)."""
    import os
    import subprocess
    import sys

    code = ('import sys; from rv_te_bench.launch.node_specs import NODE_PARAMS, node_specs; '
            '[node_specs(n) for n in NODE_PARAMS]; '
            "bad = sorted(m for m in sys.modules if m.split('.')[0] in "
            "{'rclpy', 'rv_te_msgs', 'rcl_interfaces'}); print(bad); sys.exit(1 if bad else 0)")
    env = {k: v for k, v in os.environ.items() if k != '_ROS_WHEELS_BOOTSTRAP_COMPLETE'}
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         env=env, timeout=120, check=False)
    assert out.returncode == 0, out.stdout + out.stderr
