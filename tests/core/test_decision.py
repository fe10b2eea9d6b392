"""Decision rules on constructed borderline cases (ISO 14253-1 zones, ILAC-G8 rules)."""

from __future__ import annotations

import math

import pytest

from rv_te_bench.core.decision import DecisionRule, decide, unit_verdict
from rv_te_bench.errors import TeConfigError

GUARDED = DecisionRule('guarded')


@pytest.mark.parametrize(('value', 'simple', 'guarded'), [
    (0.90, 'pass', 'pass'),            # inside by 0.10 >= U = 0.05: conformance proven
    (0.95, 'pass', 'pass'),            # exactly on the acceptance-zone edge
    (0.97, 'pass', 'indeterminate'),   # value + U straddles the limit
    (1.00, 'pass', 'indeterminate'),
    (1.03, 'fail', 'indeterminate'),   # value - U straddles the limit
    (1.06, 'fail', 'fail'),            # outside by more than U: non-conformance proven
])
def test_upper_limit_zones(value: float, simple: str, guarded: str) -> None:
    assert decide(value, 0.05, upper=1.0).verdict == simple
    assert decide(value, 0.05, upper=1.0, rule=GUARDED).verdict == guarded


def test_lower_limit_and_guard_fraction() -> None:
    # rigidity >= 196 with U = 10: 200 is inside by 4 < U -> indeterminate; with w = U/4 pass
    assert decide(200.0, 10.0, lower=196.0, rule=GUARDED).verdict == 'indeterminate'
    assert decide(200.0, 10.0, lower=196.0, rule=DecisionRule('guarded', 0.25)).verdict == 'pass'
    assert decide(180.0, 10.0, lower=196.0, rule=GUARDED).verdict == 'fail'


def test_probability_of_false_acceptance_is_the_normal_tail() -> None:
    d = decide(0.99, 0.05, upper=1.0)
    u = 0.025
    assert d.pfa == pytest.approx(0.5 * math.erfc(0.01 / u / math.sqrt(2)))
    assert d.borderline
    assert decide(0.5, 0.05, upper=1.0).pfa < 1e-12
    assert not decide(0.5, 0.05, upper=1.0).borderline
    # both limits: both tails
    two = decide(0.0, 2.0, lower=-1.0, upper=1.0)
    assert two.pfa == pytest.approx(2 * 0.5 * math.erfc(1.0 / math.sqrt(2)))


def test_unknown_uncertainty_and_bad_rules() -> None:
    d = decide(0.99, math.nan, upper=1.0, rule=GUARDED)
    assert d.verdict == 'pass' and math.isnan(d.pfa)
    with pytest.raises(TeConfigError, match='decision rule must be one of'):
        DecisionRule('lenient')
    with pytest.raises(TeConfigError, match='guard_fraction'):
        DecisionRule('guarded', 0.0)
    with pytest.raises(TeConfigError, match='finite lower or upper'):
        decide(1.0, 0.1)


def test_unit_verdict() -> None:
    assert unit_verdict(['pass', 'pass']) == 'pass'
    assert unit_verdict(['pass', 'indeterminate']) == 'indeterminate'
    assert unit_verdict(['indeterminate', 'fail']) == 'fail'
    assert unit_verdict(['pass', 'not_measured']) == 'fail'
