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


def test_an_asymmetric_interval_guards_each_side_with_its_own_reach() -> None:
    """A p-p reads high by up to b (its interval reaches U + b below the value, U above):
    against an upper limit conformance needs value + U <= limit, not value + U + b."""
    d = decide(0.97, 0.05, upper=1.0, rule=GUARDED, u_below=0.05, u_above=0.02)
    assert d.verdict == 'pass' and d.guard == pytest.approx(0.02)
    assert decide(0.97, 0.05, upper=1.0, rule=GUARDED).verdict == 'indeterminate'
    # non-conformance of that p-p needs value - (U + b) > limit
    assert decide(1.04, 0.05, upper=1.0, rule=GUARDED, u_below=0.05,
                  u_above=0.02).verdict == 'indeterminate'
    assert decide(1.06, 0.05, upper=1.0, rule=GUARDED, u_below=0.05,
                  u_above=0.02).verdict == 'fail'
    # a minimum of two sides reads low: its interval reaches further above; a lower limit
    # is guarded with the reach below
    d = decide(200.0, 8.0, lower=196.0, rule=GUARDED, u_below=3.0, u_above=8.0)
    assert d.verdict == 'pass'
    assert decide(190.0, 8.0, lower=196.0, rule=GUARDED, u_below=3.0,
                  u_above=8.0).verdict == 'indeterminate'
    # the PFA uses the reach towards the limit: normal with u = u_above / k
    d = decide(0.99, 0.05, upper=1.0, u_below=0.09, u_above=0.02)
    assert d.pfa == pytest.approx(0.5 * math.erfc(0.01 / 0.01 / math.sqrt(2)), rel=1e-9)
