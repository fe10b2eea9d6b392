"""argparse ``type=`` converters shared by the subcommands (a bad value is a usage error)."""

from __future__ import annotations

import argparse
import math
from typing import TYPE_CHECKING, TypeAlias

from rv_te_bench.core._checks import finite_positive

if TYPE_CHECKING:
    from collections.abc import Callable

    #: What each subcommand's ``register(subparsers)`` receives (``add_subparsers()``).
    Subparsers: TypeAlias = argparse._SubParsersAction[argparse.ArgumentParser]


def _number(text: str) -> float:
    """``float(text)``; a usage error naming the text (its first 50 characters) when not one."""
    try:
        return float(text)
    except ValueError:
        msg = f'not a number: {text[:50]!r}'
        raise argparse.ArgumentTypeError(msg) from None


def finite_float(text: str) -> float:
    """A finite number."""
    value = _number(text)
    if not math.isfinite(value):
        msg = f'must be finite, got {text!r}'
        raise argparse.ArgumentTypeError(msg)
    return value


def positive_float(text: str) -> float:
    """A finite number > 0."""
    _number(text)
    return finite_positive(text, '', argparse.ArgumentTypeError)   # names the text given


def int_at_least(text: str, minimum: int) -> int:
    """An integer >= ``minimum``."""
    try:
        value = int(text)
    except ValueError:
        msg = f'not an integer: {text[:50]!r}'
        raise argparse.ArgumentTypeError(msg) from None
    if value < minimum:
        msg = f'must be >= {minimum}, got {text!r}'
        raise argparse.ArgumentTypeError(msg)
    return value


def nonnegative_int(text: str) -> int:
    """An integer >= 0."""
    return int_at_least(text, 0)


def positive_int(text: str) -> int:
    """An integer >= 1."""
    return int_at_least(text, 1)


def float_between(lo: float, hi: float) -> Callable[[str], float]:
    """An argparse type: a finite number in [lo, hi] (argparse names the flag on error)."""

    def parse(text: str) -> float:
        value = _number(text)
        if not (math.isfinite(value) and lo <= value <= hi):
            msg = f'must be between {lo:g} and {hi:g}, got {text!r}'
            raise argparse.ArgumentTypeError(msg)
        return value

    parse.__name__ = 'number'   # argparse's "invalid number value" wording
    return parse


def int_between(lo: int, hi: int) -> Callable[[str], int]:
    """An argparse type: an integer in [lo, hi]."""

    def parse(text: str) -> int:
        value = int_at_least(text, lo)
        if value > hi:
            msg = f'must be <= {hi}, got {text!r}'
            raise argparse.ArgumentTypeError(msg)
        return value

    parse.__name__ = 'integer'
    return parse


def nonempty_text(text: str) -> str:
    """An argparse type: text with something besides blanks (a serial, an operator)."""
    if not text.strip():
        msg = f'must not be empty, got {text!r}'
        raise argparse.ArgumentTypeError(msg)
    return text
