"""Tests of rv_te_bench.core.spc against published constants, closed forms and simulation.

References: the control-chart factor table of ASTM STP 15D / Montgomery, "Introduction to
Statistical Quality Control", Appendix VI (d2, d3, A2, D3, D4), three decimals; Nelson
(1984) and the Western Electric Handbook (1956) for the run rules.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from rv_te_bench.core import spc
from rv_te_bench.errors import SpcError

# n: (d2, d3) from the published table
TABLE = {2: (1.128, 0.853), 3: (1.693, 0.888), 4: (2.059, 0.880), 5: (2.326, 0.864),
         6: (2.534, 0.848), 7: (2.704, 0.833), 8: (2.847, 0.820), 9: (2.970, 0.808),
         10: (3.078, 0.797), 15: (3.472, 0.756), 20: (3.735, 0.729), 25: (3.931, 0.708)}
# n: (A2, D3, D4) from the same table
FACTORS = {2: (1.880, 0.0, 3.267), 5: (0.577, 0.0, 2.114), 7: (0.419, 0.076, 1.924),
           10: (0.308, 0.223, 1.777)}


@pytest.mark.parametrize(('n', 'ref'), TABLE.items())
def test_d2_d3_equal_the_published_table(n: int, ref: tuple[float, float]) -> None:
    assert spc.d2(n) == pytest.approx(ref[0], abs=6e-4)
    assert spc.d3(n) == pytest.approx(ref[1], abs=6e-4)


@pytest.mark.parametrize('n', [0, 1, 26, 2.5])
def test_bad_subgroup_size(n: object) -> None:
    with pytest.raises(SpcError, match='subgroup size'):
        spc.d2(n)  # type: ignore[arg-type]


def test_individuals_closed_form() -> None:
    """Alternating 0, 1: MR-bar = 1, sigma = 1 / d2(2), centre 0.5, UCL = 0.5 + 3 / 1.128,
    MR UCL = D4(2) = 3.267 (published)."""
    x = np.tile([0.0, 1.0], 10)
    ch = spc.individuals_chart(x)
    assert ch.centre == pytest.approx(0.5)
    assert ch.process_sigma == pytest.approx(1 / 1.128, rel=1e-3)
    assert ch.ucl[0] == pytest.approx(0.5 + 3 / 1.128, rel=1e-3)
    assert ch.lcl[0] == pytest.approx(0.5 - 3 / 1.128, rel=1e-3)
    assert ch.spread_ucl[0] == pytest.approx(3.267, rel=1e-3)
    assert math.isnan(ch.spread[0])
    # 20 points strictly alternating: N4 (14 alternating) fires at point 13 and after;
    # every |z| = 0.5 * 1.128 = 0.56 < 1, so N7 (15 within 1 sigma) fires from point 14
    assert ch.first_signal() == 13
    assert {(h.rule, h.index) for h in ch.hits if h.index <= 14} == {('N4', 13), ('N4', 14),
                                                                     ('N7', 14)}


def test_baseline_sets_the_limits() -> None:
    """Limits come from the baseline only: a later shift does not widen them."""
    rng = np.random.default_rng(1)
    x = np.concatenate([rng.normal(10.0, 1.0, 30), rng.normal(16.0, 1.0, 10)])
    base_only = spc.individuals_chart(x[:30])
    ch = spc.individuals_chart(x, baseline=slice(0, 30))
    assert ch.centre == pytest.approx(base_only.centre)
    assert ch.process_sigma == pytest.approx(base_only.process_sigma)
    assert set(ch.out_of_control) >= set(range(30, 40)) - {30}  # all shifted points beyond


def test_xbar_r_matches_a2_d3_d4_for_constant_lots() -> None:
    """Lots of 5: X-bar limits = X-bar-bar +- A2 R-bar; R limits D3 R-bar, D4 R-bar."""
    rng = np.random.default_rng(7)
    vals = rng.normal(2.0, 0.3, 5 * 12)
    lots = [f'L{i // 5}' for i in range(vals.size)]
    ch = spc.xbar_r_chart(vals, lots)
    means = vals.reshape(12, 5).mean(1)
    ranges = np.ptp(vals.reshape(12, 5), axis=1)
    a2, d3_, d4_ = FACTORS[5]
    assert ch.centre == pytest.approx(means.mean())
    assert ch.spread_centre == pytest.approx(ranges.mean())
    assert ch.ucl[0] == pytest.approx(means.mean() + a2 * ranges.mean(), rel=2e-3)
    assert ch.lcl[0] == pytest.approx(means.mean() - a2 * ranges.mean(), rel=2e-3)
    assert ch.spread_ucl[0] == pytest.approx(d4_ * ranges.mean(), rel=2e-3)
    assert ch.spread_lcl[0] == pytest.approx(d3_ * ranges.mean(), abs=1e-9)
    np.testing.assert_allclose(ch.values, means)
    assert list(ch.sizes) == [5] * 12


def test_xbar_r_rejects_single_unit_lots() -> None:
    with pytest.raises(SpcError, match="lot 'B' has 1 unit"):
        spc.xbar_r_chart([1.0, 2.0, 3.0], ['A', 'A', 'B'])


@pytest.mark.parametrize(('z', 'rule', 'index'), [
    ([0, 0, 0, 3.5, 0], 'N1', 3),
    ([0.5] * 9, 'N2', 8),
    ([-2, -1.5, -1, -0.5, 0, 0.5], 'N3', 5),
    ([2.5, 0, 2.2], 'N5', 2),
    ([1.5, 1.2, 0, 1.1, 1.3], 'N6', 4),
    ([0.1, -0.1] * 7 + [0.2], 'N7', 14),
    ([1.5, -1.5] * 4, 'N8', 7),
])
def test_nelson_rules_fire_at_the_completing_point(z: list[float], rule: str,
                                                   index: int) -> None:
    hits = [h for h in spc.run_rules(np.array(z, dtype=float)) if h.rule == rule]
    assert hits, spc.run_rules(np.array(z, dtype=float))
    assert hits[0].index == index


@pytest.mark.parametrize(('z', 'rule'), [
    ([0.5] * 8, 'N2'),                       # 8 on one side: not yet Nelson's 9
    ([-2, -1.5, -1, -0.5, 0], 'N3'),         # 5 increasing
    ([2.5, 0, -2.2], 'N5'),                  # beyond 2 sigma on both sides
    ([1.5, 1.2, 0, -1.1, 1.3], 'N6'),        # 3 of 5 on one side
])
def test_nelson_rules_do_not_fire_short_of_the_pattern(z: list[float], rule: str) -> None:
    assert rule not in {h.rule for h in spc.run_rules(np.array(z, dtype=float))}


def test_western_electric_eight_in_a_row() -> None:
    hits = spc.run_rules(np.full(8, 0.3), rules='western-electric')
    assert [(h.rule, h.index) for h in hits] == [('WE4', 7)]


def test_step_change_detected_at_or_soon_after_the_step_not_before() -> None:
    """A 3-sigma step at unit 40 of an in-control series (baseline units 0-29): for one
    seed the first signal is at the step or within 5 units after it, never before."""
    rng = np.random.default_rng(2024)
    x = rng.normal(0.0, 1.0, 60)
    x[40:] += 3.0
    ch = spc.individuals_chart(x, baseline=slice(0, 30))
    first = ch.first_signal()
    assert first is not None
    assert 40 <= first <= 45, [(h.rule, h.index) for h in ch.hits]


def test_step_change_statistics_over_many_series() -> None:
    """Over 400 simulated series: a 2-sigma step at unit 50 is signalled within 10 units in
    >= 90 % of the series (median delay <= 4), and before the step (a false alarm among 50
    in-control units with the 8 Nelson rules) in at most 45 % of them (each rule has an
    in-control false-alarm rate near 0.3-0.5 %; 50 points x 8 rules ~ 25-35 %)."""
    rng = np.random.default_rng(99)
    delays, early = [], 0
    for _ in range(400):
        x = rng.normal(0.0, 1.0, 80)
        x[50:] += 2.0
        ch = spc.individuals_chart(x, baseline=slice(0, 40))
        before = [h for h in ch.hits if h.index < 50]
        early += bool(before)
        after = [h.index for h in ch.hits if h.index >= 50]
        delays.append(after[0] - 50 if after else 99)
    delays_a = np.array(delays)
    assert np.mean(delays_a <= 10) >= 0.90
    assert np.median(delays_a) <= 4
    assert early / 400 <= 0.45


def test_capability_closed_form() -> None:
    """Values with mean 0.6 and a tolerance (0, 1]: Cp = 1 / (6 s), Cpk = 0.4 / (3 s)."""
    x = np.array([0.5, 0.7, 0.6, 0.5, 0.7])
    cap = spc.capability(x, sigma_within=0.1, lsl=0.0, usl=1.0)
    assert cap.mean == pytest.approx(0.6)
    assert cap.cp == pytest.approx(1.0 / 0.6)
    assert cap.cpk == pytest.approx(0.4 / 0.3)
    s = float(np.std(x, ddof=1))
    assert cap.pp == pytest.approx(1.0 / (6 * s))
    assert cap.ppk == pytest.approx(0.4 / (3 * s))
    assert cap.fraction_out == 0.0


def test_capability_one_sided() -> None:
    """TE <= 1 arcmin is one-sided: no Cp, Cpk = (USL - mean) / 3 sigma."""
    cap = spc.capability([0.5, 0.9, 1.1], sigma_within=0.2, usl=1.0)
    assert cap.cp is None
    assert cap.cpk == pytest.approx((1.0 - 2.5 / 3) / 0.6)
    assert cap.fraction_out == pytest.approx(1 / 3)


@pytest.mark.parametrize(('kwargs', 'match'), [
    ({}, 'lower or an upper'),
    ({'lsl': 2.0, 'usl': 1.0}, 'must be below'),
    ({'usl': math.nan}, 'usl must be finite'),
])
def test_capability_bad_limits(kwargs: dict, match: str) -> None:
    with pytest.raises(SpcError, match=match):
        spc.capability([1.0, 2.0], sigma_within=1.0, **kwargs)


def test_bad_values_named() -> None:
    with pytest.raises(SpcError, match=r'values\[2\] is nan'):
        spc.individuals_chart([1.0, 2.0, math.nan])
    with pytest.raises(SpcError, match='do not vary'):
        spc.individuals_chart([1.0, 1.0, 1.0])
    with pytest.raises(SpcError, match='at least 2'):
        spc.individuals_chart([1.0, 2.0, 3.0], baseline=[1])
