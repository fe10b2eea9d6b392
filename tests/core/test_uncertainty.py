"""GUM budgets: the engine against GUM's own numbers, each input against its closed form.

Reference values: GUM (JCGM 100:2008) G.2.3 (k = 1.65 for a rectangular at 95 %), Table G.2
(t_p(nu) at p = 95.45 %: nu = 4 -> 2.87, nu = 10 -> 2.28), G.4.1 (Welch-Satterthwaite); the
triangular and arcsine quantiles from their closed-form CDFs written here.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from rv_te_bench.core.bench_uncertainty import (
    BenchUncertainty,
    EncoderErrorModel,
    bench_uncertainty_from_plain,
    default_encoder_errors,
)
from rv_te_bench.core.hysteresis import HysteresisConfig
from rv_te_bench.core.hysteresis_uncertainty import hysteresis_budgets
from rv_te_bench.core.te_uncertainty import line_budgets, te_pp_budget
from rv_te_bench.core.uncertainty import (
    UncertaintyInput,
    combine,
    coverage_factor,
    t_quantile,
    type_a,
    type_b,
    welch_satterthwaite,
)
from rv_te_bench.core.units import arcsec_to_rad
from rv_te_bench.errors import TeConfigError, TeInputError

AS = float(arcsec_to_rad(1.0))


# --------------------------------------------------------------------------------------
# the engine


@pytest.mark.parametrize(('shape', 'p', 'k_ref'), [
    ('rectangular', 0.95, 0.95 * math.sqrt(3.0)),                       # GUM G.2.3: 1.65
    ('triangular', 0.9545, math.sqrt(6.0) * (1.0 - math.sqrt(1.0 - 0.9545))),
    ('arcsine', 0.9545, math.sqrt(2.0) * math.sin(math.pi / 2 * 0.9545)),
    ('normal', 0.9545, 2.0),
])
def test_coverage_factor_of_one_input_is_its_quantile(shape: str, p: float, k_ref: float) -> None:
    x = type_b('x', sensitivity=3.0, distribution=shape, u=0.7) if shape == 'normal' else \
        type_b('x', sensitivity=3.0, distribution=shape, half_width=0.7)
    k, _ = coverage_factor([x], p)
    assert k == pytest.approx(k_ref, abs=2e-3)


@pytest.mark.parametrize(('dof', 't_ref'), [(4, 2.87), (10, 2.28), (2, 4.53)])
def test_t_factor_matches_gum_table_g2(dof: int, t_ref: float) -> None:
    assert t_quantile(0.9545, float(dof)) == pytest.approx(t_ref, abs=0.01)
    obs = np.arange(dof + 1, dtype=float) ** 1.3
    k, basis = coverage_factor([type_a('a', obs)])
    assert basis.startswith('t') and k == pytest.approx(t_ref, abs=0.01)


def _k_normal_plus_t(share: float, nu: float) -> float:
    """The 95.45 % coverage factor of Y = N(0, 1 - share) + sqrt(share) T_nu (unit u_c), by
    scipy quadrature of P(|Y| <= y) = int f_t(t) [Phi((y - a t)/b) - Phi((-y - a t)/b)] dt
    and a root finder: independent of the code's FFT convolution."""
    from scipy import integrate, optimize
    from scipy.special import gammaln, ndtr

    a, b = math.sqrt(share), math.sqrt(1.0 - share)
    c = math.exp(gammaln((nu + 1) / 2) - gammaln(nu / 2)) / math.sqrt(nu * math.pi)

    def inside(y: float) -> float:
        def f(t: float) -> float:         # Student's t density times P(|Y| <= y | T = t)
            return float(c * (1 + t * t / nu) ** (-(nu + 1) / 2)
                         * (ndtr((y - a * t) / b) - ndtr((-y - a * t) / b)))
        return float(integrate.quad(f, -np.inf, np.inf, limit=400)[0])

    return float(optimize.brentq(lambda y: inside(y) - math.erf(math.sqrt(2.0)), 0.5, 100.0))


@pytest.mark.parametrize(('share', 'nu'), [(0.006, 1.0), (0.0027, 1.0), (0.1, 1.0),
                                           (0.3, 2.0), (0.6, 5.0), (0.0001, 1.0)])
def test_a_type_a_with_few_dof_keeps_its_tails(share: float, nu: float) -> None:
    """Two windows (one dof) with a small share: Welch-Satterthwaite's nu_eff = nu / share^2
    gives k = 2.00; the distribution (what Supplement 1's Monte Carlo samples) needs more,
    e.g. 2.338 at 0.6 % (scipy quadrature). The old k failed this by 14.5 %."""
    from scipy import stats

    xs = [type_b('n', sensitivity=1.0, distribution='normal', u=math.sqrt(1 - share)),
          UncertaintyInput(name='a', kind='A', u=math.sqrt(share), sensitivity=1.0,
                           distribution='t', dof=nu)]
    k, basis = coverage_factor(xs)
    assert k == pytest.approx(_k_normal_plus_t(share, nu), rel=2e-3)
    assert basis.startswith('t (nu_i =')
    ws = stats.t.ppf(0.5 + 0.9545 / 2, nu / share ** 2)
    if share * nu ** -0.5 > 0.002:          # where WS is wrong by more than the tolerance
        assert k > ws * 1.01
    # a lone one-dof type A: GUM Table G.2's t_95.45(1) = 13.97
    one = UncertaintyInput(name='a', kind='A', u=2.0, sensitivity=0.5, distribution='t',
                           dof=1.0)
    assert coverage_factor([one])[0] == pytest.approx(stats.t.ppf(0.5 + 0.9545 / 2, 1),
                                                      rel=2e-3)


def test_many_dof_still_take_welch_satterthwaite() -> None:
    """nu_i >= 30: WS is within 1 % of the distribution; k = t_p(nu_eff) as GUM G.4."""
    from scipy import stats

    xs = [type_b('n', sensitivity=1.0, distribution='normal', u=0.8),
          UncertaintyInput(name='a', kind='A', u=0.6, sensitivity=1.0, distribution='t',
                           dof=40.0)]
    k, basis = coverage_factor(xs)
    nu = 40.0 / 0.36 ** 2
    assert basis.startswith('t (nu_eff')
    assert k == pytest.approx(stats.t.ppf(0.5 + 0.9545 / 2, nu), rel=1e-4)
    assert k == pytest.approx(_k_normal_plus_t(0.36, 40.0), rel=0.01)


def test_two_equal_rectangulars_give_the_triangular_factor() -> None:
    x = type_b('x', sensitivity=1.0, distribution='rectangular', half_width=1.0)
    k, basis = coverage_factor([x, x])
    assert basis == 'distribution'
    assert k == pytest.approx(math.sqrt(6.0) * (1.0 - math.sqrt(1.0 - 0.9545)), abs=3e-3)


def test_welch_satterthwaite_and_budget_arithmetic() -> None:
    # G.4.1 with u1 = 1 (nu 4) and u2 = 2 (nu inf): nu_eff = 25 / (1 / 4) = 100
    assert welch_satterthwaite([1.0, 2.0], [4.0, math.inf]) == pytest.approx(100.0)
    a = type_b('a', sensitivity=2.0, distribution='normal', u=1.5)      # 3
    b = type_b('b', sensitivity=-1.0, distribution='normal', u=4.0)     # 4
    bud = combine('y', 1.0, [a, b, None])
    assert bud.u_c == pytest.approx(5.0)
    assert [x.name for x in bud.inputs] == ['b', 'a']
    assert_allclose(bud.shares, [16 / 25, 9 / 25])
    assert bud.expanded == pytest.approx(2.0 * 5.0, rel=1e-9)   # k = 2 at p = 95.45 %
    assert bud.u95 == bud.expanded
    assert_allclose(bud.interval, (1.0 - 10.0, 11.0), rtol=1e-9)


def test_bad_inputs_are_named() -> None:
    with pytest.raises(TeInputError, match="input 'q': u must be"):
        type_b('q', sensitivity=1.0, distribution='normal', u=-1.0)
    with pytest.raises(TeInputError, match='distribution must be one of'):
        type_b('q', sensitivity=1.0, distribution='gamma', u=1.0)  # type: ignore[arg-type]
    assert type_a('one', [1.0]) is None


# --------------------------------------------------------------------------------------
# bench description and defaults


def test_ron886_defaults_spread_the_data_sheet_band_as_a_rectangular() -> None:
    m = default_encoder_errors('heidenhain-ron886')
    band = 0.6 * AS                      # +-1" system accuracy less +-0.4" per signal period
    assert sum(g * g / 2 for _, g in m.graduation) == pytest.approx(band ** 2 / 3, rel=1e-12)
    assert m.interpolation_rad == pytest.approx(0.4 * AS)
    assert m.signal_periods == 36_000
    assert not default_encoder_errors('acme-9000').known


def test_bench_description_section_sets_eccentricity_and_rejects_typos() -> None:
    base = BenchUncertainty.defaults('renishaw-resolute', 'renishaw-resolute')
    b = bench_uncertainty_from_plain({
        'encoders': {'output': {'eccentricity_um': 5.0, 'eccentricity_u_um': 1.0,
                                'scale_diameter_mm': 100.0}},
        'daq_skew_ns': 25, 'torque_sensor': {'accuracy_class_pct': 0.05, 'nominal_nm': 500},
        'temperature': {'spread_k': 0.5}}, base)
    # DESIGN.md s.7: 5 um on a 100 mm scale = +-20.6"
    assert b.encoder_out.eccentricity_rad / AS == pytest.approx(20.6, abs=0.05)
    assert b.daq_skew_s == pytest.approx(25e-9)
    assert b.torque_zero_nm == pytest.approx(0.25)
    assert b.temperature_spread_k == 0.5
    with pytest.raises(TeConfigError, match=r"unknown key\(s\) \['daq_skew'\]"):
        bench_uncertainty_from_plain({'daq_skew': 1}, base)
    with pytest.raises(TeConfigError, match='needs scale_diameter_mm'):
        bench_uncertainty_from_plain({'encoders': {'input': {'eccentricity_um': 1}}}, base)


# --------------------------------------------------------------------------------------
# TE p-p: each input against its closed form


def _bench(**kw: object) -> BenchUncertainty:
    enc = EncoderErrorModel(model='test', graduation=((2, 0.5 * AS),), signal_periods=1000,
                            interpolation_rad=0.1 * AS, noise_sigma_rad=0.01 * AS,
                            resolution_rad=0.05 * AS, cte_mismatch_per_k=2e-6)
    return BenchUncertainty(encoder_in=EncoderErrorModel(model='ideal'), encoder_out=enc, **kw)


def _pp(bench: BenchUncertainty, **kw: object):
    args = {'phi_max_rad': 0.3, 'phi_min_rad': 1.9, 'gear_ratio': 79.0, 'bench': bench,
            'per_revolution_rad': [1e-3, 1.0004e-3, 0.9997e-3]}
    args.update(kw)
    return te_pp_budget('te_pp_rad', 1e-3, **args)


def test_pp_graduation_harmonic_is_an_arcsine_of_2_sin_k_delta_over_2() -> None:
    b = _pp(_bench()).input('output encoder: graduation, order 2')
    delta = 1.9 - 0.3
    assert b.distribution == 'arcsine'
    assert b.contribution == pytest.approx(0.5 * AS / math.sqrt(2) * 2 * abs(math.sin(delta)))
    # doubling the amplitude doubles the contribution
    enc2 = EncoderErrorModel(model='test', graduation=((2, 1.0 * AS),))
    b2 = _pp(BenchUncertainty(encoder_in=EncoderErrorModel(model='ideal'), encoder_out=enc2)
             ).input('output encoder: graduation, order 2')
    assert b2.contribution == pytest.approx(2 * b.contribution, rel=1e-12)


def test_pp_mounting_eccentricity_of_a_scale_is_an_order_1_arcsine() -> None:
    """A ring scale mounted e off its axis reads 2 e / D sin(theta + rho) (DESIGN.md s.7);
    its measured value and its uncertainty enter as one order-1 harmonic of amplitude
    hypot(e, u(e)) (phase unknown): on a p-p with extremes Delta apart, c = 2 |sin(Delta/2)|."""
    base = BenchUncertainty(encoder_in=EncoderErrorModel(model='ideal'),
                            encoder_out=EncoderErrorModel(model='ring'))
    delta = 1.9 - 0.3
    contrib = []
    for e_um, u_um in ((2.0, 0.0), (2.0, 1.5), (4.0, 0.0)):
        bench = bench_uncertainty_from_plain({'encoders': {'output': {
            'eccentricity_um': e_um, 'eccentricity_u_um': u_um,
            'scale_diameter_mm': 200.0}}}, base)
        x = _pp(bench).input('output encoder: mounting eccentricity (order 1)')
        amp = 2 * math.hypot(e_um, u_um) * 1e-6 / 0.2
        assert x.distribution == 'arcsine'
        assert x.contribution == pytest.approx(amp / math.sqrt(2) * 2 * abs(math.sin(delta / 2)),
                                               rel=1e-12)
        contrib.append(x.contribution)
    assert contrib[1] == pytest.approx(contrib[0] * 2.5 / 2.0)     # hypot(2, 1.5) = 2.5
    assert contrib[2] == pytest.approx(2 * contrib[0])


def test_pp_input_encoder_harmonic_turns_i_times_and_is_divided_by_i() -> None:
    enc = EncoderErrorModel(model='in', graduation=((3, 1.0 * AS),))
    bench = BenchUncertainty(encoder_in=enc, encoder_out=EncoderErrorModel(model='ideal'))
    x = _pp(bench).input('input encoder: graduation, order 3')
    delta_in = 79.0 * (1.9 - 0.3)
    assert x.contribution == pytest.approx(AS / math.sqrt(2) * 2 * abs(math.sin(3 * delta_in / 2))
                                           / 79.0)


def test_pp_quantisation_skew_temperature_and_repeatability() -> None:
    bud = _pp(_bench(daq_skew_s=1e-6, temperature_spread_k=2.0), speed_spread_rad_s=0.05)
    q = 0.05 * AS
    assert bud.input('output encoder: quantisation at the two extremes').contribution == \
        pytest.approx(math.sqrt(2) * q / 2 / math.sqrt(3))
    assert bud.input('DAQ timing skew between the channels').contribution == \
        pytest.approx(0.05 * 1e-6 / math.sqrt(3))
    assert bud.input('output encoder: temperature (scale/mount expansion mismatch)'
                     ).contribution == pytest.approx(2e-6 * 1.6 * 1.0 / math.sqrt(3))
    rep = bud.input('repeatability: p-p of one revolution over the run')
    assert rep.kind == 'A' and rep.dof == 2
    assert rep.u == pytest.approx(np.std([1e-3, 1.0004e-3, 0.9997e-3], ddof=1))
    # the fast errors (interpolation 0.1", noise) bound a one-sided bias, not a variance
    z = math.sqrt(2 * math.log(1e4))
    assert bud.bias_bound == pytest.approx(2 * (0.1 * AS + z * 0.01 * AS))
    assert bud.u95 == pytest.approx(bud.expanded + bud.bias_bound)


def test_pp_without_repeats_uses_the_data_sheet_noise() -> None:
    bud = _pp(_bench(), per_revolution_rad=[1e-3])
    x = bud.input('output encoder: read-head noise at the two extremes')
    assert x.contribution == pytest.approx(math.sqrt(2) * 0.01 * AS)
    assert any('no type A' in n for n in bud.notes)


def test_pp_sampling_resolution() -> None:
    bud = _pp(_bench(), samples_per_rev=1000.0, dominant=(1e-3, 25.0))
    half = 1e-3 * (25 * 2 * math.pi / 1000) ** 2 / 8
    assert bud.input('sampling: extremes between samples').contribution == pytest.approx(
        math.sqrt(2) * half / math.sqrt(3))


# --------------------------------------------------------------------------------------
# lines


def test_line_of_the_harmonics_order_gets_the_arcsine_others_do_not() -> None:
    bench = _bench(daq_skew_s=1e-6)
    a, p = line_budgets('2 f_out', 2e-4, 0.4, 2.0, gear_ratio=79.0, bench=bench,
                        output_hz=0.5, samples_per_rev=4096, n_samples=4096)
    g = a.input('output encoder: graduation, order 2')
    assert g.contribution == pytest.approx(0.5 * AS / math.sqrt(2))
    assert p.input('output encoder: graduation, order 2').contribution == pytest.approx(
        0.5 * AS / math.sqrt(2) / 2e-4)
    assert p.input('DAQ timing skew between the channels').contribution == pytest.approx(
        2.0 * 2 * math.pi * 0.5 * 1e-6 / math.sqrt(3))
    s = 4096 / 2.0
    assert a.input('resampling to the angle grid (cubic)').contribution == pytest.approx(
        2e-4 * 0.015 * (2 * math.pi / s) ** 4 / math.sqrt(3))
    a3, _ = line_budgets('3 f_out', 2e-4, 0.4, 3.0, gear_ratio=79.0, bench=bench,
                         output_hz=0.5)
    assert not any('graduation' in x.name for x in a3.inputs)


def test_line_repeatability_over_windows() -> None:
    amps = [2.0e-4, 2.1e-4, 1.9e-4, 2.05e-4]
    phases = [0.40, 0.42, 0.38, 0.41]
    a, p = line_budgets('1 f_w', float(np.mean(amps)), 0.4025, 25.0, gear_ratio=79.0,
                        bench=_bench(), output_hz=0.06, window_amplitudes_rad=amps,
                        window_phases_rad=phases)
    x = a.input('repeatability over the windows')
    assert x.u == pytest.approx(np.std(amps, ddof=1) / 2) and x.dof == 3
    y = p.input('repeatability over the windows')
    assert y.u == pytest.approx(np.std(np.array(phases) - 0.4025, ddof=1) / 2)


# --------------------------------------------------------------------------------------
# hysteresis: a linear unit with free play, written here


def _linear_cycle(k: float, play: float, tr: float) -> tuple[np.ndarray, np.ndarray]:
    fr = [0.0, 0.03, 0.1, 0.5, 1.0]
    up = [f * tr for f in fr]
    seq = up + up[-2::-1] + [-t for t in up[1:]] + [-t for t in up[-2::-1]]
    t = np.array(seq)
    a = np.empty_like(t)
    side = 1.0
    for j, tj in enumerate(t):
        if tj > 0:
            side = 1.0
        elif tj < 0:
            side = -1.0
        a[j] = side * play / 2 + tj / k
    return t, a


def test_hysteresis_gain_error_moves_rigidity_by_k_times_epsilon() -> None:
    k, tr = 2e5, 100.0
    t, a = _linear_cycle(k, 1e-4, tr)
    enc = EncoderErrorModel(model='ideal')
    bench = BenchUncertainty(encoder_in=enc, encoder_out=enc, torque_gain_rel=2e-3,
                             torque_zero_nm=0.1)
    buds = hysteresis_budgets(t, a, HysteresisConfig(rated_torque_nm=tr), bench=bench,
                              theta_out_rad=0.0)
    rig = buds['torsional_rigidity_K_nm_per_rad']
    assert rig.value == pytest.approx(k)
    # a sensor reading t (1 + e) holds the unit at t / (1 + e): the measured K is
    # k (1 + e), so the gain's sensitivity on K is k
    gain = rig.input('torque sensor: sensitivity (gain)')
    assert abs(gain.sensitivity) == pytest.approx(k, rel=1e-4)
    # a zero error shifts both points along the flank: K unchanged; lost motion too
    assert rig.input('torque sensor: zero and linearity').contribution <= 1e-7 * k
    lm = buds['lost_motion_rad']
    assert lm.value == pytest.approx(1e-4 + 2 * 0.03 * tr / k)
    # lost motion's gain sensitivity: the +-t points move by e t / k each: 2 t / k per unit
    assert abs(lm.input('torque sensor: sensitivity (gain)').sensitivity) == pytest.approx(
        2 * 0.03 * tr / k, rel=1e-6)


def test_hysteresis_encoder_harmonic_on_lost_motion_is_the_closed_form() -> None:
    k, tr = 2e5, 100.0
    t, a = _linear_cycle(k, 1e-4, tr)
    n = 500
    enc = EncoderErrorModel(model='e', signal_periods=n, interpolation_rad=0.2 * AS)
    bench = BenchUncertainty(encoder_in=EncoderErrorModel(model='ideal'), encoder_out=enc)
    theta0 = 0.7
    buds = hysteresis_budgets(t, a, HysteresisConfig(rated_torque_nm=tr), bench=bench,
                              theta_out_rad=theta0)
    x = buds['lost_motion_rad'].input(f'output encoder: interpolation (order {n})')
    # lost motion = (a_asc(+t) + a_desc(+t) - a_asc(-t) - a_desc(-t)) / 2 at the four points
    lt = 0.03 * tr
    idx = [int(np.flatnonzero(np.isclose(t, v))[j]) for v, j in ((lt, 0), (lt, 1), (-lt, 0),
                                                                 (-lt, 1))]
    th = theta0 + a[idx] - a[0]
    c = np.array([0.5, 0.5, -0.5, -0.5])
    ref = abs(np.sum(c * np.exp(1j * n * th)))
    assert x.sensitivity == pytest.approx(ref, rel=1e-5)


def test_tabulated_input_of_a_sine_is_the_arcsine() -> None:
    """A shape tabulated on a uniform phase grid of sin: the same u and k as the arcsine."""
    ph = np.linspace(0, 2 * np.pi, 3600, endpoint=False)
    tab = type_b('t', sensitivity=2.0, distribution='tabulated', half_width=0.5,
                 shape=np.sin(ph))
    arc = type_b('a', sensitivity=2.0, distribution='arcsine', half_width=0.5)
    assert tab.u == pytest.approx(arc.u, rel=1e-9)
    assert tab.half_width == pytest.approx(0.5)
    k_tab, basis = coverage_factor([tab])
    assert basis == 'distribution'
    assert k_tab == pytest.approx(coverage_factor([arc])[0], abs=3e-3)
    with pytest.raises(TeInputError, match='tabulated'):
        type_b('t', sensitivity=1.0, distribution='tabulated', half_width=1.0, shape=[0.0] * 9)


@pytest.mark.parametrize('sign', [1.0, -1.0])
def test_a_skewed_tabulated_input_gets_its_probabilistically_symmetric_interval(
        sign: float) -> None:
    """A harmonic with its second-order term, f(rho) = sin(rho) + 0.3 cos(2 rho) over a
    uniform phase, is skewed (its extremes are 1.3 and ... below -1). With a normal input
    beside it, P(S <= s) = mean over rho of Phi((s - c f(rho)) / sigma) (computed here on
    a fine grid of rho, scipy root finder): the budget's interval of the true value is
    [y - q_hi, y - q_lo] (measured = true + S), its U the half-width, shifted."""
    from scipy import optimize
    from scipy.special import ndtr

    rho = np.linspace(0.0, 2 * np.pi, 4000, endpoint=False)
    f = np.sin(rho) + 0.3 * np.cos(2 * rho)
    g, sigma = 2.0, 0.4
    x = type_b('h', sensitivity=sign * 1.5, distribution='tabulated', half_width=g,
               shape=f)
    n = type_b('n', sensitivity=1.0, distribution='normal', u=sigma)
    vals = sign * 1.5 * g * f / float(np.max(np.abs(f)))

    def cdf(s: float) -> float:
        return float(np.mean(ndtr((s - vals) / sigma)))

    p = math.erf(math.sqrt(2.0))
    q_lo = optimize.brentq(lambda s: cdf(s) - (1 - p) / 2, -20, 20)
    q_hi = optimize.brentq(lambda s: cdf(s) - (1 + p) / 2, -20, 20)
    b = combine('y', 10.0, [x, n])
    lo, hi = b.interval
    assert lo == pytest.approx(10.0 - q_hi, abs=0.01 * (q_hi - q_lo) / 2)
    assert hi == pytest.approx(10.0 - q_lo, abs=0.01 * (q_hi - q_lo) / 2)
    assert b.expanded == pytest.approx((q_hi - q_lo) / 2, rel=0.01)
    assert abs(b.shift) > 0.05 * b.expanded            # skewed: not symmetric about y
    assert b.u95 == pytest.approx(max(10.0 - lo, hi - 10.0))
    # a symmetric budget keeps shift 0 and y +- k u_c
    s = combine('y', 1.0, [n, type_b('r', sensitivity=1.0, distribution='rectangular',
                                     half_width=1.0)])
    assert s.shift == 0.0 and s.interval == (1.0 - s.expanded, 1.0 + s.expanded)
