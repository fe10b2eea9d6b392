"""Hysteresis and identification budgets: each new input against its closed form or an
independent computation (issue 35).

* the second-order term of a fast encoder harmonic: amplitude k g^2 / 2 at order 2 k, its
  sensitivity |sum_j c_j exp(2 i k theta_j)| at the lost motion's four points (closed form);
  and the size of the term checked against the error function evaluated at positions read
  with the error (the simulator's way), computed here;
* a reported minimum: Clark's bias of min(X1, X2) against a Monte Carlo of two normals
  drawn here; every input at the larger of its sides' sensitivities;
* the local compliance of a curve that stiffens with load: the exact derivative of a
  quadratic;
* the identified eccentricities: the Gauss-Newton response of e_ot to an output-encoder
  harmonic against a finite difference of the full non-linear fit run twice.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from rv_te_bench.core.angle_fold import AngleFold
from rv_te_bench.core.bench_uncertainty import BenchUncertainty, EncoderErrorModel
from rv_te_bench.core.hysteresis import HysteresisConfig
from rv_te_bench.core.hysteresis_uncertainty import (
    hysteresis_budgets,
    local_compliance,
    min_budget,
    second_order_amplitude,
)
from rv_te_bench.core.identify import identify_folded
from rv_te_bench.core.identify_uncertainty import identification_budgets
from rv_te_bench.core.phases import EccentricGeometry, delta_pair_m
from rv_te_bench.core.uncertainty import combine, type_b
from rv_te_bench.core.units import arcsec_to_rad

AS = float(arcsec_to_rad(1.0))


def _linear_cycle(k: float, play: float, tr: float) -> tuple[np.ndarray, np.ndarray]:
    """0 -> +T_R -> 0 -> -T_R -> 0 in steps, a linear unit with free play (written here)."""
    fr = [0.0, 0.03, 0.1, 0.5, 1.0]
    up = [f * tr for f in fr]
    seq = up + up[-2::-1] + [-t for t in up[1:]] + [-t for t in up[-2::-1]]
    t = np.array(seq)
    a = np.empty_like(t)
    side = 1.0
    for j, tj in enumerate(t):
        side = 1.0 if tj > 0 else -1.0 if tj < 0 else side
        a[j] = side * play / 2 + tj / k
    return t, a


def test_second_order_term_of_the_interpolation_error() -> None:
    k, tr, n = 2e5, 100.0, 36_000
    g = 0.4 * AS
    t, a = _linear_cycle(k, 1e-4, tr)
    enc = EncoderErrorModel(model='e', signal_periods=n, interpolation_rad=g)
    bench = BenchUncertainty(encoder_in=EncoderErrorModel(model='ideal'), encoder_out=enc)
    theta0 = 0.3
    buds = hysteresis_budgets(t, a, HysteresisConfig(rated_torque_nm=tr), bench=bench,
                              theta_out_rad=theta0)
    x = buds['lost_motion_rad'].input(f'output encoder: interpolation (order {n})')
    assert x.half_width == pytest.approx(g, rel=1e-12)
    lt = 0.03 * tr
    idx = [int(np.flatnonzero(np.isclose(t, v))[j]) for v, j in ((lt, 0), (lt, 1), (-lt, 0),
                                                                 (-lt, 1))]
    th = theta0 + a[idx] - a[0]
    c = np.array([0.5, 0.5, -0.5, -0.5])
    # closed form: lost motion error = sum_j c_j e(theta_j true), to second order
    # g sin(n th + rho) - (n g^2 / 2) sin(2 (n th + rho)), one phase rho for both
    rho = np.linspace(0, 2 * np.pi, 20_000)[:, None]
    f = np.sum(c * (g * np.sin(n * th + rho)
                    - n * g * g / 2 * np.sin(2 * (n * th + rho))), axis=1)
    assert x.distribution == 'tabulated'
    assert x.sensitivity == pytest.approx(np.max(np.abs(f)) / g, rel=2e-5)
    assert x.contribution == pytest.approx(np.std(f), rel=1e-3)
    first_only = abs(np.sum(c * np.exp(1j * n * th)))
    assert x.sensitivity > first_only    # the second order widens it here
    # its interval: the tabulated values are (nearly) the only input; measured = true + f,
    # so the true value lies in [y - q(97.725 %), y - q(2.275 %)] of f (GUM S1 7.7, the
    # probabilistically symmetric interval: f is skewed by its second-order term)
    q_lo, q_hi = np.quantile(f, [0.02275, 0.97725])
    b = buds['lost_motion_rad']
    assert b.inputs[0] is x and b.shares[0] > 0.99
    assert b.expanded == pytest.approx((q_hi - q_lo) / 2, rel=0.02)
    lo, hi = b.interval
    assert lo - b.value == pytest.approx(-q_hi, abs=0.02 * b.expanded)
    assert hi - b.value == pytest.approx(-q_lo, abs=0.02 * b.expanded)
    # the term is real: the error function at positions read with the error, minus its
    # first-order value, for every phase, lies within the second-order amplitude (+ third)
    rho = np.linspace(0, 2 * np.pi, 721)[:, None]
    th_m = np.linspace(0.0, 1e-3, 50)[None, :]            # read positions
    th_true = th_m.copy()
    for _ in range(30):                                    # theta_m = theta + e(theta)
        th_true = th_m - g * np.sin(n * th_true + rho)
    exact = g * np.sin(n * th_true + rho)
    first = g * np.sin(n * th_m + rho)
    second = -second_order_amplitude(n, g) * np.sin(2 * (n * th_m + rho))
    assert np.max(np.abs(exact - first)) == pytest.approx(second_order_amplitude(n, g),
                                                          rel=0.05)
    assert np.max(np.abs(exact - first - second)) < 0.1 * second_order_amplitude(n, g)


def test_a_slow_harmonic_has_no_second_order_input() -> None:
    t, a = _linear_cycle(2e5, 1e-4, 100.0)
    enc = EncoderErrorModel(model='e', graduation=((2, 0.3 * AS),))
    bench = BenchUncertainty(encoder_in=EncoderErrorModel(model='ideal'), encoder_out=enc)
    buds = hysteresis_budgets(t, a, HysteresisConfig(rated_torque_nm=100.0), bench=bench,
                              theta_out_rad=0.0)
    x = buds['backlash_rad'].input('output encoder: graduation, order 2')
    assert 'second order' not in x.note


def test_min_budget_bias_is_clarks_and_inputs_take_the_larger_sensitivity() -> None:
    u = 2.0
    a = combine('a', 5.0, [type_b('x', sensitivity=1.0, distribution='normal', u=u),
                           type_b('y', sensitivity=3.0, distribution='normal', u=0.1)])
    b = combine('b', 5.0, [type_b('x', sensitivity=0.5, distribution='normal', u=u),
                           type_b('y', sensitivity=4.0, distribution='normal', u=0.1)])
    m = min_budget('m', a, b)
    assert m.value == 5.0
    assert m.input('x').sensitivity == 1.0 and m.input('y').sensitivity == 4.0
    # E[min(X1, X2)] of two independent normals with equal means, Monte Carlo here
    rng = np.random.default_rng(1)
    draws = rng.normal(0, a.u_c, 400_000), rng.normal(0, b.u_c, 400_000)
    bias_mc = -float(np.mean(np.minimum(*draws)))
    assert m.bias_low_bound == pytest.approx(bias_mc, rel=0.01)
    lo, hi = m.interval
    assert lo == pytest.approx(5.0 - m.expanded)
    assert hi == pytest.approx(5.0 + m.expanded + m.bias_low_bound)
    assert m.u95 == pytest.approx(m.expanded + m.bias_low_bound)
    # sides far apart (the data show the separation): no bias, the smaller side's value
    far = combine('b', 5.0 + 20 * a.u_c, list(b.inputs))
    m2 = min_budget('m', a, far)
    assert m2.value == 5.0 and m2.bias_low_bound < 1e-6 * a.u_c
    assert [p.measurand for p in m2.parts] == ['a', 'b']


def test_rigidity_is_the_smaller_side_with_its_budget_over_both() -> None:
    k, tr = 2e5, 100.0
    t, a = _linear_cycle(k, 1e-4, tr)
    a = np.where(t < 0, a * 1.0, a)
    # a unit stiffer on the negative side: the positive side is the smaller
    a = np.where(t < 0, np.sign(t) * 0.5e-4 + t / (1.2 * k), a)
    enc = EncoderErrorModel(model='e', signal_periods=500, interpolation_rad=0.2 * AS)
    bench = BenchUncertainty(encoder_in=EncoderErrorModel(model='ideal'), encoder_out=enc)
    buds = hysteresis_budgets(t, a, HysteresisConfig(rated_torque_nm=tr), bench=bench,
                              theta_out_rad=0.4)
    rig = buds['torsional_rigidity_K_nm_per_rad']
    pos, neg = rig.parts
    assert pos.value == pytest.approx(k) and neg.value == pytest.approx(1.2 * k)
    assert rig.value == pytest.approx(k)
    name = 'output encoder: interpolation (order 500)'
    assert rig.input(name).sensitivity == pytest.approx(
        max(pos.input(name).sensitivity, neg.input(name).sensitivity))


def test_local_compliance_of_a_stiffening_curve_is_its_derivative() -> None:
    c1, c2 = 1e-5, -4e-9                  # phi = c1 t + c2 t |t|: stiffer with load
    fr = np.array([0.0, 0.03, 0.1, 0.2, 0.3, 0.5, 0.7, 1.0]) * 500.0
    t = np.r_[fr, fr[-2::-1], -fr[1:], -fr[-2::-1]]
    phi = c1 * t + c2 * t * np.abs(t)
    comp = local_compliance(t, phi)
    want = c1 + 2 * c2 * np.abs(t)
    inner = (np.abs(t) > 0) & (np.abs(t) < 500.0)
    np.testing.assert_allclose(comp[inner], want[inner], rtol=1e-9)
    # the secant of the old rule would have understated it at the 3 % point
    j = 1
    assert comp[j] > (phi[2] - phi[1]) / (t[2] - t[1])


@pytest.fixture(scope='module')
def wang_geometry() -> EccentricGeometry:
    return EccentricGeometry(e_m=(10e-6, 12e-6, 4e-6, 10e-6),
                             phases_rad=tuple(np.radians([90.0, -30.0, 45.0, 60.0])),
                             alpha_rad=math.radians(35.266), r_p_m=0.06108,
                             crank_order=-25.0)


def _record(geom: EccentricGeometry, extra: np.ndarray | None = None) -> AngleFold:
    phi = np.linspace(0.0, 2 * np.pi, 40_000, endpoint=False)
    d1, d2 = delta_pair_m(phi, geom)
    te = np.maximum(d1, d2) / geom.r_p_m
    rng = np.random.default_rng(3)
    te = te + 0.01 * AS * rng.standard_normal(phi.size)
    if extra is not None:
        te = te + extra
    fold = AngleFold()
    fold.add(phi, te)
    return fold, phi


def test_identified_e_ot_responds_to_an_order_1_encoder_error_as_a_refit_does(
        wang_geometry: EccentricGeometry) -> None:
    g = 0.5 * AS
    enc = EncoderErrorModel(model='e', graduation=((1, g),))
    bench = BenchUncertainty(encoder_in=EncoderErrorModel(model='ideal'), encoder_out=enc)
    fold, phi = _record(wang_geometry)
    folded = fold.result()
    ident = identify_folded(folded, wang_geometry, split=False)
    buds = identification_budgets(ident, folded, gear_ratio=79.0, bench=bench)
    x = buds['e_ot_m'].input('output encoder: graduation, order 1')
    # independent: run the non-linear fit again on the record plus eps sin / cos (phi)
    eps = 1e-3 * g
    resp = []
    for f in (np.sin, np.cos):
        fold2, _ = _record(wang_geometry, eps * f(phi))
        i2 = identify_folded(fold2.result(), wang_geometry, split=False)
        resp.append((i2.e_m['e_ot'] - ident.e_m['e_ot']) / eps)
    assert x.sensitivity == pytest.approx(math.hypot(*resp), rel=0.02)
    # an order-1 error of 1" is of the size of e_ot's TE (r_p x angle): sensitivity near r_p
    assert 0.2 * wang_geometry.r_p_m < x.sensitivity < 2 * wang_geometry.r_p_m
    assert buds['e_ot_m'].value == pytest.approx(10e-6, rel=1e-3)


def _cycles() -> list[tuple[np.ndarray, np.ndarray, HysteresisConfig]]:
    """Load cycles of points the budget's per-point weights are checked on: plain steps,
    runs of points at one torque (a reading averages them), a back branch that stops
    short of zero torque (a reading at its end or NaN), several rigidity regions, torques
    that miss the read torques (interpolated), a unit stiffer on one side."""
    from rv_te_bench.core.hysteresis import RigidityRegion

    rng = np.random.default_rng(39)
    out = []
    t, a = _linear_cycle(2e5, 1e-4, 100.0)
    out.append((t, a + 1e-8 * rng.standard_normal(t.size), HysteresisConfig(100.0)))
    reps = rng.integers(1, 4, t.size)
    out.append((np.repeat(t, reps), np.repeat(a, reps) + 1e-8 * rng.standard_normal(
        reps.sum()), HysteresisConfig(100.0, lost_motion_fraction=0.1)))
    out.append((t[:-2], a[:-2] + 2.0, HysteresisConfig(100.0)))
    tr = 450.0
    f = np.r_[np.linspace(0, 1, 13), np.linspace(0.93, -1, 25), np.linspace(-0.9, 0, 10)]
    tq = f * tr + rng.normal(0.0, 0.4, f.size)
    tq[0] = 0.0
    side = np.where(np.arange(f.size) < 13, 1.0, np.where(np.arange(f.size) < 38, 1.0, -1.0))
    ang = 3e-4 * side * (f != 0) + np.where(tq > 0, tq / 1.1e5, tq / 0.8e5) \
        + 1e-7 * rng.standard_normal(f.size)
    regions = (RigidityRegion('K1', 0.03, 0.25), RigidityRegion('K2', 0.25, 0.7),
               RigidityRegion('K3', 0.7, 1.0))
    out.append((tq, ang, HysteresisConfig(tr, rigidity_regions=regions)))
    return out


@pytest.mark.parametrize('case', range(4))
def test_point_weights_are_those_of_moving_each_point_and_computing_again(case: int) -> None:
    """The budget reads again only what a moved point enters: its weights must be, bit for
    bit, the metrics of hysteresis_metrics recomputed with each point moved (done here)."""
    from rv_te_bench.core.hysteresis import PointCycle, hysteresis_metrics
    from rv_te_bench.core.hysteresis_uncertainty import _named, _point_weights

    t, a, cfg = _cycles()[case]

    def metrics(aa: np.ndarray) -> dict[str, float]:
        m = hysteresis_metrics(t, aa, cfg)
        out = {'lost_motion_rad': m.lost_motion_rad, 'backlash_rad': m.backlash_rad,
               'hysteresis_loss_j': m.hysteresis_loss_j}
        for r in cfg.rigidity_regions:
            out[f'torsional_rigidity_{r.name}_pos'] = m.rigidity_nm_per_rad[r.name][0]
            out[f'torsional_rigidity_{r.name}_neg'] = m.rigidity_nm_per_rad[r.name][1]
        return out

    base = metrics(a)
    step = 1e-9
    want = {n: np.zeros(t.size) for n in base}
    for j in range(t.size):
        bump = np.zeros(t.size)
        bump[j] = step
        new = metrics(a + bump)
        for n in base:
            d = (new[n] - base[n]) / step
            want[n][j] = d if math.isfinite(d) else 0.0
    got = _point_weights(PointCycle(t, cfg), a, base, step)
    assert got.keys() == want.keys()
    for n in want:
        assert np.array_equal(got[n], want[n]), n
    assert any(np.count_nonzero(w) for w in want.values())
    m = hysteresis_metrics(t, a, cfg)
    cyc = PointCycle(t, cfg)
    r = cyc.cycle(cyc.readings(a))
    fast = _named(r.backlash_rad, r.lost_motion_rad, cyc.loss(a), r.rigidity_nm_per_rad)
    full = _named(m.backlash_rad, m.lost_motion_rad, m.hysteresis_loss_j,
                  m.rigidity_nm_per_rad)
    assert fast.keys() == full.keys()
    np.testing.assert_array_equal(list(fast.values()), list(full.values()))   # NaN == NaN
