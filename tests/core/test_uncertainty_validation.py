"""The budgets validated two ways, small N (benchmarks/bench_uncertainty.py runs the full N):

* Monte Carlo propagation through the measurement model itself (GUM Supplement 1) agrees
  with the law of propagation's U within 5 % on every metric;
* over simulated units and benches whose encoder, DAQ and torque-sensor errors are drawn
  from the stated distributions (sim.encoders.remounted, BenchConfig.daq_skew_s,
  ProgramSimulator torque errors), the simulator's true value lies inside the interval.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from rv_te_bench.core.bench_uncertainty import BenchUncertainty
from rv_te_bench.core.uncertainty_mc import (
    mc_hysteresis,
    mc_identification,
    mc_line,
    mc_te_pp,
)
from tests.benchmark_loader import load_benchmark

BENCH = load_benchmark('bench_uncertainty')


@pytest.fixture(scope='module')
def bench() -> BenchUncertainty:
    return BenchUncertainty.defaults('heidenhain-ron886', 'heidenhain-ron886')


def test_monte_carlo_agrees_with_the_law_of_propagation(bench: BenchUncertainty) -> None:
    rng = np.random.default_rng(7)
    r = BENCH.te_run(rng, bench, unit_phases=False)
    res = [mc_te_pp(r['pp'], r['phi'], r['te'], gear_ratio=r['ratio'], bench=bench,
                    draws=2000, rng=rng, theta_out_offset_rad=r['offset'])]
    for ln, a, p, _ in r['lines'].values():
        res += mc_line(a, p, r['phi'], r['te'], ln.output_order, gear_ratio=r['ratio'],
                       bench=bench, draws=4000, rng=rng, theta_out_offset_rad=r['offset'])
    h = BENCH.hyst_run(rng, bench)
    res += mc_hysteresis(h['budgets'], h['t'], h['a'], h['cfg'], bench=bench,
                         theta_out_rad=h['theta_out'], draws=1000, rng=rng,
                         counts=h['counts']).values()
    # nine metrics, and the two sides of the rigidity (its minimum is not smooth where the
    # sides cross: the law of propagation is checked on each side, the minimum's budget
    # must contain the Monte Carlo interval of the minimum)
    assert len(res) == 11
    for m in res:
        if m.measurand == 'torsional_rigidity_K_nm_per_rad':
            assert m.contained, (m.interval_gum, m.low, m.high)
        else:
            assert abs(m.difference) < 0.05, (m.measurand, m.u_gum, m.u_mc)
    # Supplement 1, 8: the interval's two ends, not only its width. The hysteresis loss's
    # error is skewed (the interpolation error's second-order term; docs/UNCERTAINTY.md):
    # its interval is not symmetric about the value, and both ends must agree
    loss = next(m for m in res if m.measurand == 'hysteresis_loss_j')
    lo, hi = loss.interval_gum
    assert abs(lo - loss.low) < 0.05 * loss.u_gum, (lo, loss.low, loss.u_gum)
    assert abs(hi - loss.high) < 0.05 * loss.u_gum, (hi, loss.high, loss.u_gum)


def test_a_planted_error_in_a_sensitivity_is_caught(bench: BenchUncertainty) -> None:
    """The check can fail: halve the p-p budget's graduation sensitivities -> MC differs."""
    from dataclasses import replace

    rng = np.random.default_rng(8)
    r = BENCH.te_run(rng, bench, unit_phases=False)
    bad = r['pp']
    halved = [replace(x, sensitivity=x.sensitivity / 2) if 'graduation' in x.name else x
              for x in bad.inputs]
    from rv_te_bench.core.uncertainty import combine

    wrong = combine(bad.measurand, bad.value, halved, bias_bound=bad.bias_bound)
    m = mc_te_pp(wrong, r['phi'], r['te'], gear_ratio=r['ratio'], bench=bench, draws=3000,
                 rng=rng, theta_out_offset_rad=r['offset'])
    assert m.difference > 0.3


@pytest.mark.slow
def test_coverage_over_simulated_units(bench: BenchUncertainty) -> None:
    rng = np.random.default_rng(35)
    n = 40
    hits: dict[str, int] = {}
    for _ in range(n):
        r = BENCH.te_run(rng, bench, unit_phases=True)
        checks = [('te_pp', r['pp'], r['pp_true'], False)]
        for name, (_, a, p, tl) in r['lines'].items():
            checks += [(f'{name} amplitude', a, tl.amplitude_rad, False),
                       (f'{name} phase', p, tl.phase_rad, True)]
        checks += [(f'identified {k}', b, true, k.endswith('_rad'))
                   for k, (b, true) in r['ident'].items()]
        h = BENCH.hyst_run(rng, bench)
        checks += [(k, b, h['true'][k], False) for k, b in h['budgets'].items()]
        for name, b, true, phase in checks:
            hits[name] = hits.get(name, 0) + int(BENCH._covered(b, true, phase=phase))
    # 95 % nominal; 40 units: >= 34 covered keeps a false alarm below ~3 %
    low = {k: v for k, v in hits.items() if v < 34}
    assert not low, (hits, n)
    assert math.isfinite(sum(hits.values()))


@pytest.mark.slow
def test_identification_monte_carlo_agrees(bench: BenchUncertainty) -> None:
    """The identified eccentricities: refitting the record with drawn encoder errors (the
    non-linear least squares itself) against the Gauss-Newton budget, within 5 % + the
    Monte Carlo's own sampling error at 400 draws (~3.5 % of U at 95 %)."""
    rng = np.random.default_rng(12)
    r = BENCH.te_run(rng, bench, unit_phases=True)
    folded, ident = r['ident_fit']
    res = mc_identification({n: b for n, (b, _) in r['ident'].items()}, folded, ident,
                            gear_ratio=r['ratio'], bench=bench, draws=400, rng=rng)
    assert len(res) == 6
    for m in res.values():
        assert abs(m.difference) < 0.085, (m.measurand, m.u_gum, m.u_mc)


def test_a_short_record_monte_carlo_agrees_on_bags_sample() -> None:
    """bags/sample holds two output revolutions: every line's repeatability rests on two
    windows (one dof). Supplement 1 samples that type A as a one-dof t; the budget's k must
    follow its tails. Before the few-dof t was convolved (k = t_p(nu_eff) by
    Welch-Satterthwaite) the crank lines' Monte Carlo U was 4-28 % above the budget's on
    this record (20,000 draws; docs/UNCERTAINTY.md); the check must see that too."""
    rows = BENCH.sample_bag_check(6000)
    by_name = {name: (r, u_ws) for name, r, u_ws in rows}
    assert {'line 1 f_w amplitude', 'line 2 f_w amplitude',
            'line f_w - f_out amplitude'} <= set(by_name)
    lines = [(n, r) for n, r, _ in rows if n.startswith('line ')]
    assert len(lines) >= 8            # the lines this record resolves (amplitude > 10 U)
    # 6000 draws: the 95.45 % half-width is known to ~2 % (heavy tails); 5 % is the issue's
    for name, r in lines:
        assert abs(r.difference) < 0.05, (name, r.u_gum, r.u_mc)
    # the old k is caught by the same check (it can fail)
    for name in ('line 2 f_w amplitude', 'line f_w - f_out amplitude'):
        r, u_ws = by_name[name]
        assert r.u_mc / u_ws - 1.0 > 0.06, (name, r.u_mc, u_ws)
