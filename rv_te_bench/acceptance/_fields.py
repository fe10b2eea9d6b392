"""The checked reading of one YAML mapping of a plan (a step, the safety block): each key
popped, checked against its rule and bounds, and every failure a :class:`PlanError` that
names the file, the step, the key and the bad value.

Shared by the step kinds of :mod:`rv_te_bench.acceptance.plan` and
:mod:`rv_te_bench.acceptance.loss_steps` (a module of its own so that the kinds' parsers
import it, not each other).
"""

from __future__ import annotations

import math
from typing import Any, NoReturn

from rv_te_bench.acceptance._files import shown_keys
from rv_te_bench.errors import PlanError

__all__ = ['Fields']


class Fields:
    """Pops and checks the keys of one mapping; names where and what on failure."""

    def __init__(self, data: Any, where: str) -> None:
        if not isinstance(data, dict):
            msg = f'{where}: must be a mapping, got {type(data).__name__}'
            raise PlanError(msg)
        self.data = dict(data)
        self.where = where

    def fail(self, key: str, rule: str, value: object = None) -> NoReturn:
        got = '' if value is None else f', got {value!r}'
        msg = f'{self.where}: {key} {rule}{got}'
        raise PlanError(msg)

    def num(self, key: str, default: float | None = None, *, lo: float | None = None,
            lo_open: bool = False, hi: float | None = None) -> float:
        if key not in self.data:
            if default is None:
                self.fail(key, 'is required')
            return float(default)
        v = self.data.pop(key)
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            self.fail(key, 'must be a finite number', v)
        if lo is not None and (v <= lo if lo_open else v < lo):
            self.fail(key, f'must be {">" if lo_open else ">="} {lo:g}', v)
        if hi is not None and v > hi:
            self.fail(key, f'must be <= {hi:g}', v)
        return float(v)

    def integer(self, key: str, default: int, *, lo: int, hi: int | None = None) -> int:
        v = self.data.pop(key, default)
        if isinstance(v, bool) or not isinstance(v, int) or v < lo or (hi is not None
                                                                        and v > hi):
            rule = f'an integer >= {lo}' if hi is None else f'an integer in {lo}..{hi}'
            self.fail(key, f'must be {rule}', v)
        return int(v)

    def text(self, key: str, default: str | None = None, *,
             choices: tuple[str, ...] = ()) -> str:
        if key not in self.data:
            if default is None:
                self.fail(key, 'is required')
            return str(default)
        v = self.data.pop(key)
        if not isinstance(v, str) or not v.strip():
            self.fail(key, 'must be a non-empty string', v)
        if choices and v not in choices:
            self.fail(key, f'must be one of {list(choices)}', v)
        return v.strip()

    def flag(self, key: str, default: bool) -> bool:
        v = self.data.pop(key, default)
        if not isinstance(v, bool):
            self.fail(key, 'must be true or false', v)
        return v

    def numbers(self, key: str, default: list[float] | None = None, *,
                lo: float | None = None, hi: float | None = None,
                nonzero: bool = False) -> tuple[float, ...]:
        if key not in self.data and default is not None:
            return tuple(default)
        v = self.data.pop(key, None)
        if not isinstance(v, list) or not v or len(v) > 50:
            self.fail(key, 'must be a list of 1..50 numbers', v)
        out = []
        for j, x in enumerate(v):
            if isinstance(x, bool) or not isinstance(x, int | float) or not math.isfinite(x) \
                    or (lo is not None and x < lo) or (hi is not None and x > hi) \
                    or (nonzero and x == 0):
                rule = ('must be finite' + (f' and >= {lo:g}' if lo is not None else '')
                        + (f' and <= {hi:g}' if hi is not None else '')
                        + (' and non-zero' if nonzero else ''))
                self.fail(f'{key}[{j}]', rule, x)
            out.append(float(x))
        return tuple(out)

    def span(self, key: str, value: object) -> tuple[float, float]:
        """One [start, end] time range [s], 0 <= start < end."""
        if not isinstance(value, list) or len(value) != 2 or not all(
                not isinstance(x, bool) and isinstance(x, int | float) and math.isfinite(x)
                for x in value) or not 0 <= value[0] < value[1]:
            self.fail(key, 'must be [start, end] in seconds from the record\'s start, '
                      '0 <= start < end', value)
        return float(value[0]), float(value[1])

    def spans(self, key: str, count: int, what: str) -> tuple[tuple[float, float], ...]:
        """``count`` time ranges (one per ``what``), or none."""
        if key not in self.data:
            return ()
        v = self.data.pop(key)
        if not isinstance(v, list) or len(v) != count:
            self.fail(key, f'must list {count} [start, end] range(s), one per {what}', v)
        return tuple(self.span(f'{key}[{j}]', x) for j, x in enumerate(v))

    def done(self) -> None:
        if self.data:
            self.fail(f'unknown key(s) {shown_keys(self.data)}', 'are not allowed here')
