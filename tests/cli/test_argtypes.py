"""cli/argtypes: the argparse ``type=`` converters (a bad value is a usage error naming it)."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

import pytest

from rv_te_bench.cli.argtypes import (
    finite_float,
    float_between,
    int_between,
    nonnegative_int,
    positive_float,
    positive_int,
)

if TYPE_CHECKING:
    from collections.abc import Callable


@pytest.mark.parametrize(('parse', 'text', 'expected'), [
    (finite_float, '-1.5', -1.5), (finite_float, '0', 0.0), (positive_float, '2e-3', 2e-3),
    (nonnegative_int, '0', 0), (positive_int, '7', 7), (float_between(0.0, 1.0), '1', 1.0),
    (int_between(2, 100_000), '2', 2), (int_between(2, 100_000), '100000', 100_000),
])
def test_good_values(parse: Callable[[str], object], text: str, expected: float) -> None:
    got = parse(text)
    assert got == expected
    assert type(got) is type(expected)


@pytest.mark.parametrize(('parse', 'text', 'message'), [
    (finite_float, 'abc', "not a number: 'abc'"),
    (finite_float, 'nan', "must be finite, got 'nan'"),
    (finite_float, '-inf', "must be finite, got '-inf'"),
    (finite_float, 'x' * 80, "not a number: '" + 'x' * 50 + "'"),
    (positive_float, '0', "must be finite and > 0, got '0'"),
    (positive_float, 'one', "not a number: 'one'"),
    (nonnegative_int, '-1', "must be >= 0, got '-1'"),
    (positive_int, '1.5', "not an integer: '1.5'"),
    (float_between(0.0, 1.0), '1.01', "must be between 0 and 1, got '1.01'"),
    (int_between(2, 100_000), '1', "must be >= 2, got '1'"),
    (int_between(2, 100_000), '100001', "must be <= 100000, got '100001'"),
])
def test_bad_values_are_usage_errors_naming_the_text(parse: Callable[[str], object], text: str,
                                                       message: str) -> None:
    with pytest.raises(argparse.ArgumentTypeError) as info:
        parse(text)
    assert str(info.value) == message
