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
