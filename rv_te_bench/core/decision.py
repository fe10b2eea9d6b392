"""Decision rules for conformity with a tolerance (ISO 14253-1, ILAC-G8:2019, JCGM 106).

A measured value y with expanded uncertainty U (k = 2, 95.45 %) is judged against a
tolerance [L, H] (either side may be open) under a stated rule:

* **simple acceptance** (ILAC-G8 4.2.1, "shared risk"): PASS when L <= y <= H, else FAIL;
  U plays no part in the verdict (the probability of false acceptance is still reported).
* **guarded acceptance** with a guard band w = f U (ILAC-G8 4.2.2; ISO 14253-1 takes
  w = U): PASS when y lies in the acceptance zone [L + w, H - w] (conformance proven),
  FAIL when y lies outside [L - w, H + w] (non-conformance proven), otherwise
  INDETERMINATE (neither proven: the value and its uncertainty straddle a limit).

The probability of false acceptance of a result (JCGM 106 7.5, normal with u = U / k):
the probability that the true value lies outside [L, H] given y,
``PFA = Phi((L - y) / u) + Phi((y - H) / u)``; shown for borderline results (a PASS
within 2 U of a limit). A unit passes when every limited metric passes, fails when one
fails, and is indeterminate otherwise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

from rv_te_bench.errors import TeConfigError

__all__ = ['DECISION_RULES', 'Decision', 'DecisionRule', 'Verdict', 'decide', 'unit_verdict']

Verdict = Literal['pass', 'fail', 'indeterminate']
DECISION_RULES = ('simple', 'guarded')


@dataclass(frozen=True)
class DecisionRule:
    """How a value with its U is judged.

    Attributes:
        kind: ``'simple'`` (simple acceptance) or ``'guarded'`` (guarded acceptance).
        guard_fraction: w / U of the guarded rule (> 0; 1 = ISO 14253-1).
    """

    kind: str = 'simple'
    guard_fraction: float = 1.0

    def __post_init__(self) -> None:
        """Validate (TeConfigError names the field)."""
        if self.kind not in DECISION_RULES:
            msg = f'decision rule must be one of {list(DECISION_RULES)}, got {self.kind!r}'
            raise TeConfigError(msg)
        f = self.guard_fraction
        if isinstance(f, bool) or not isinstance(f, int | float) or not (
                math.isfinite(f) and 0 < f <= 3):
            msg = f'guard_fraction must lie in (0, 3], got {f!r}'
            raise TeConfigError(msg)

    def describe(self) -> str:
        """The rule in one sentence (the report states it)."""
        if self.kind == 'simple':
            return ('simple acceptance (ILAC-G8 4.2.1): pass when the value is within the '
                    'limit; the uncertainty is stated, not applied')
        w = 'w = U' if self.guard_fraction == 1 else f'w = {self.guard_fraction:g} U'
        return (f'guarded acceptance (ISO 14253-1, ILAC-G8 4.2.2), guard band {w}: pass when '
                'the value is inside the limit by w, fail when outside by w, else '
                'indeterminate')


@dataclass(frozen=True)
class Decision:
    """The verdict of one value (SI).

    Attributes:
        verdict: ``'pass'``, ``'fail'`` or ``'indeterminate'``.
        margin: Distance to the nearer limit, positive inside [measurand unit].
        guard: The guard band w applied (0 for simple acceptance).
        pfa: Probability that the true value lies outside the limits (normal, u = U / k);
            NaN without an uncertainty.
        borderline: The value lies within 2 U of a limit.
    """

    verdict: Verdict
    margin: float
    guard: float
    pfa: float
    borderline: bool


def _phi(x: float) -> float:
    return 0.5 * math.erfc(-x / math.sqrt(2.0))


def decide(value: float, u95: float, *, lower: float = math.nan, upper: float = math.nan,
           rule: DecisionRule | None = None, k: float = 2.0, u_below: float = math.nan,
           u_above: float = math.nan) -> Decision:
    """Judge ``value`` (with expanded uncertainty ``u95``) against [lower, upper].

    Args:
        value: Measured value.
        u95: Its expanded uncertainty U (>= 0; NaN: unknown, judged as U = 0 with
            pfa NaN).
        lower, upper: Limits (NaN: that side open); at least one finite.
        rule: The decision rule (default simple acceptance).
        k: Coverage factor of U (for the PFA's standard uncertainty).
        u_below, u_above: How far below / above the value its interval reaches, when the
            interval is not symmetric (a one-sided bias: a p-p reads high, a minimum of two
            sides low); NaN: ``u95``. The guard band towards a limit is the interval's
            reach on that limit's side: conformance with an upper limit is proven when
            value + w_above <= upper, non-conformance when value - w_below > upper.

    Examples:
        A TE of 0.99' against <= 1' with U = 0.05': simple acceptance passes it,
        guarded acceptance (w = U) cannot prove conformance:

        >>> decide(0.99, 0.05, upper=1.0).verdict
        'pass'
        >>> d = decide(0.99, 0.05, upper=1.0, rule=DecisionRule('guarded'))
        >>> d.verdict, round(d.pfa, 3)
        ('indeterminate', 0.345)
    """
    rule = rule or DecisionRule()
    if not (math.isfinite(lower) or math.isfinite(upper)):
        msg = 'decide needs a finite lower or upper limit'
        raise TeConfigError(msg)
    if not math.isfinite(value):
        msg = f'decide needs a finite value, got {value!r}'
        raise TeConfigError(msg)
    u_known = math.isfinite(u95) and u95 >= 0
    big_u = u95 if u_known else 0.0
    below = u_below if (u_known and math.isfinite(u_below) and u_below >= 0) else big_u
    above = u_above if (u_known and math.isfinite(u_above) and u_above >= 0) else big_u
    f = rule.guard_fraction if rule.kind == 'guarded' else 0.0
    # per limit: (margin inside, guard to prove conformance, guard to prove non-conformance,
    #             standard uncertainty towards it)
    sides = []
    if math.isfinite(upper):
        sides.append((upper - value, f * above, f * below, above / k))
    if math.isfinite(lower):
        sides.append((value - lower, f * below, f * above, below / k))
    margin, guard, _, _ = min(sides, key=lambda x: x[0])
    pfa = math.nan
    if u_known:
        pfa = 0.0
        for m, _, _, u in sides:
            pfa += _phi(-m / u) if u > 0 else (0.0 if m >= 0 else 1.0)
    verdict: Verdict
    if rule.kind == 'simple':
        verdict = 'pass' if margin >= 0 else 'fail'
    elif any(m < -g_fail for m, _, g_fail, _ in sides):
        verdict = 'fail'
    elif all(m >= g_pass for m, g_pass, _, _ in sides):
        verdict = 'pass'
    else:
        verdict = 'indeterminate'
    return Decision(verdict=verdict, margin=margin, guard=guard, pfa=pfa,
                    borderline=u_known and abs(margin) <= 2.0 * max(below, above))


def unit_verdict(verdicts: list[str]) -> Verdict:
    """The unit's verdict from its limited metrics' verdicts: any fail (or a limit not
    measured) -> fail, else any indeterminate -> indeterminate, else pass.

    Examples:
        >>> unit_verdict(['pass', 'indeterminate']), unit_verdict(['pass', 'fail'])
        ('indeterminate', 'fail')
    """
    if any(v in ('fail', 'not_measured') for v in verdicts):
        return 'fail'
    if any(v == 'indeterminate' for v in verdicts):
        return 'indeterminate'
    return 'pass'
