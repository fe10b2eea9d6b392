"""The one "finite real number (and > 0, >= 0 or non-zero)" check of the package.

``sim`` may not import ``rv_te_bench`` (the layering contract), so the rule lives here and
:func:`rv_te_bench.core._checks.finite_positive` is written on it. The message names the
quantity, the rule and the value given: ``'<label> must be finite and > 0, got -1'``.
"""

from __future__ import annotations

import math
from typing import Any, Literal, TypeAlias

import numpy as np

from sim.errors import ModelInputError

__all__ = ['Rule', 'real_number']

#: '' any finite number; '>0' positive; '>=0' not negative; '!=0' not zero.
Rule: TypeAlias = Literal['', '>0', '>=0', '!=0']

_RULE_TEXT = {'': '', '>0': ' and > 0', '>=0': ' and >= 0', '!=0': ' and non-zero'}


def _holds(v: float, rule: Rule) -> bool:
    if rule == '>0':
        return v > 0.0
    if rule == '>=0':
        return v >= 0.0
    if rule == '!=0':
        return v != 0.0
    return True


def real_number(label: str, value: Any, rule: Rule = '', *,
                error: type[Exception] = ModelInputError, coerce: bool = False) -> float:
    """``value`` as a float when it is a finite real number that keeps ``rule``.

    Args:
        label: What it is, for the message (``''``: the message starts at "must").
        value: The value given (Any: with ``coerce`` it goes to ``float()`` as it is, a
            TypeError caught).
        rule: The sign rule on top of "finite" (see :data:`Rule`).
        error: The exception class to raise (the caller's domain error).
        coerce: Take anything ``float()`` takes (text too); without it only int, float
            and numpy numbers are numbers (not bool).

    Raises:
        error: ``'<label> must be a real number, got <value!r>'`` or
            ``'<label> must be finite[ and <rule>], got <value!r>'``.

    Examples:
        >>> real_number('ramp.duration_s', 2)
        2.0
        >>> real_number('ramp.duration_s', -1, '>0')
        Traceback (most recent call last):
        ...
        sim.errors.ModelInputError: ramp.duration_s must be finite and > 0, got -1
    """
    head = f'{label} must' if label else 'must'
    if coerce:
        try:
            v = float(value)
        except (TypeError, ValueError):
            msg = f'{head} be a real number, got {value!r}'
            raise error(msg) from None
    elif isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        msg = f'{head} be a real number, got {value!r}'
        raise error(msg)
    else:
        v = float(value)
    if not (math.isfinite(v) and _holds(v, rule)):
        msg = f'{head} be finite{_RULE_TEXT[rule]}, got {value!r}'
        raise error(msg)
    return v
