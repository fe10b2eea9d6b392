"""sim._checks.real_number: the one finite-number rule (the message names label, rule, value)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rv_te_bench.core._checks import finite_positive
from sim._checks import real_number
from sim.errors import ModelInputError


@pytest.mark.parametrize(('value', 'rule', 'expected'), [
    (2, '', 2.0), (-2.5, '', -2.5), (np.float32(0.5), '>0', 0.5), (np.int64(3), '>0', 3.0),
    (0.0, '>=0', 0.0), (-1.0, '!=0', -1.0),
])
def test_accepted_values_come_back_as_float(value: object, rule: str, expected: float) -> None:
    got = real_number('x', value, rule)  # type: ignore[arg-type]
    assert type(got) is float
    assert got == expected


@pytest.mark.parametrize(('value', 'rule', 'message'), [
    (True, '', "ramp.duration_s must be a real number, got True"),
    ('3', '', "ramp.duration_s must be a real number, got '3'"),
    (None, '>0', 'ramp.duration_s must be a real number, got None'),
    (math.nan, '', 'ramp.duration_s must be finite, got nan'),
    (math.inf, '>=0', 'ramp.duration_s must be finite and >= 0, got inf'),
    (0, '>0', 'ramp.duration_s must be finite and > 0, got 0'),
    (-1e-9, '>=0', 'ramp.duration_s must be finite and >= 0, got -1e-09'),
    (0.0, '!=0', 'ramp.duration_s must be finite and non-zero, got 0.0'),
])
def test_refused_values_name_label_rule_and_value(value: object, rule: str, message: str) -> None:
    with pytest.raises(ModelInputError) as info:
        real_number('ramp.duration_s', value, rule)  # type: ignore[arg-type]
    assert str(info.value) == message


def test_coerce_takes_text_and_raises_the_callers_error() -> None:
    assert real_number('step_deg', '10', '>0', coerce=True) == 10.0
    with pytest.raises(KeyError, match="step_deg must be a real number, got 'ten'"):
        real_number('step_deg', 'ten', '>0', error=KeyError, coerce=True)
    with pytest.raises(ValueError, match=r"^must be finite and > 0, got '-1'$"):
        real_number('', '-1', '>0', error=ValueError, coerce=True)


def test_finite_positive_is_the_same_rule() -> None:
    assert finite_positive('2.5', 'gear_ratio', ValueError) == 2.5
    with pytest.raises(ValueError, match=r'^gear_ratio must be finite and > 0, got 0\.0$'):
        finite_positive(0.0, 'gear_ratio', ValueError)
    with pytest.raises(ValueError, match='could not convert'):   # float()'s own error
        finite_positive('abc', 'gear_ratio', RuntimeError)
