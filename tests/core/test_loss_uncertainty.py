"""Budgets of the whole-reducer results (core/loss_uncertainty.py) against hand computations.

Every expected value is written out here from the measurement model (eta = T_out d theta_out
/ (T_in d theta_in); a mean torque; the torque at a breakaway; a temperature rise), the
sensor classes propagated by hand, and the coverage factor of the known shapes in closed
form (GUM G.2.3: a rectangular of half-width a has U = p a; two equal rectangulars make a
triangular, U = a' (1 - sqrt(1 - p)) with a' the sum of the half-widths)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rv_te_bench.core.loss_uncertainty import (
    breakaway_budget,
    efficiency_budget,
    mean_torque_budget,
    plateau_type_a,
    temperature_rise_budget,
)

P = math.erf(math.sqrt(2.0))        # 95.45 %


def test_efficiency_classes_propagated_by_hand() -> None:
    """T_in 10 N m (class band +-0.05 N m), T_out 600 N m (+-3 N m), ratio 1/79, ideal
    encoders, steady torques (no type A): u(eta)/eta = sqrt((0.05/sqrt3/10)^2 +
    (3/sqrt3/600)^2); the two relative bands are equal (0.5 %), so the sum is triangular of
    half-width 2 x 0.5 % eta and U = that x (1 - sqrt(1 - p))."""
    t_in, t_out, d_in = 10.0, 600.0, 79 * 2 * math.pi
    d_out = 2 * math.pi
    eta = t_out * d_out / (t_in * d_in)                    # 0.7595
    b = efficiency_budget(eta, torque_in_nm=np.full(500, t_in),
                          torque_out_nm=np.full(500, t_out), d_theta_in_rad=d_in,
                          d_theta_out_rad=d_out, class_in_nm=0.05, class_out_nm=3.0)
    rel = math.hypot(0.05 / math.sqrt(3) / t_in, 3.0 / math.sqrt(3) / t_out)
    assert b.u_c == pytest.approx(eta * rel, rel=1e-9)
    assert b.expanded == pytest.approx(2 * 0.005 * eta * (1 - math.sqrt(1 - P)), rel=3e-3)
    names = {x.name for x in b.inputs}
    assert {'input torque transducer: class', 'output torque transducer: class'} <= names
    # a class error of the output transducer moves eta by eta / T_out per N m: planted as
    # a reading 3 N m high, the efficiency moves by 3 eta / 600, within U of this budget
    shifted = (t_out + 3.0) * d_out / (t_in * d_in)
    assert abs(shifted - eta) == pytest.approx(b.input('output torque transducer: class')
                                               .sensitivity * 3.0, rel=1e-9)


def test_efficiency_encoder_increments_and_plateau_scatter() -> None:
    """Encoder increments q on each shaft: the travel over the window is a difference of two
    readings, triangular of half-width q: u = q / sqrt(6), relative to the travel. A
    ripple on the output torque: type A by the block means, s(means) / sqrt(10), 9 dof."""
    rng = np.random.default_rng(1)
    q = 2 * math.pi / 2 ** 20
    d_in, d_out = 1.0, 0.5
    ripple = 600.0 + 2.0 * np.sin(np.arange(1000) * 0.05) + rng.normal(0, 0.5, 1000)
    eta = 0.8
    b = efficiency_budget(eta, torque_in_nm=np.full(1000, 10.0), torque_out_nm=ripple,
                          d_theta_in_rad=d_in, d_theta_out_rad=d_out, class_in_nm=0.0,
                          class_out_nm=0.0, q_in_rad=q, q_out_rad=q)
    ang_in = b.input('input encoder: travel over the window (two readings)')
    assert ang_in.u == pytest.approx(q / math.sqrt(6), rel=1e-12)
    assert ang_in.contribution == pytest.approx(eta * q / math.sqrt(6) / d_in, rel=1e-9)
    a = b.input('output torque: mean over the plateau')
    means = ripple.reshape(10, 100).mean(axis=1)
    assert a.u == pytest.approx(np.std(means, ddof=1) / math.sqrt(10), rel=1e-12)
    assert a.dof == 9 and a.sensitivity == pytest.approx(eta / np.mean(ripple))


def test_no_load_torque_class_alone_is_a_rectangular() -> None:
    """A steady 1.2 N m on a transducer of +-0.1 N m class band: U = p x 0.1 N m."""
    b = mean_torque_budget('no_load_torque_nm', 1.2, np.full(200, 1.2), class_nm=0.1)
    assert b.u_c == pytest.approx(0.1 / math.sqrt(3), rel=1e-12)
    assert b.expanded == pytest.approx(P * 0.1, rel=2e-3)
    assert b.interval == pytest.approx((1.2 - b.expanded, 1.2 + b.expanded))


def test_breakaway_reads_high_by_the_ramp_increment() -> None:
    """Ramp 20 N m/s sampled at 1 kHz: the first sample past the threshold is up to 0.02 N m
    late; class band +-0.5 N m, reading noise 0.01 N m (40 dof). Interval:
    [y - U - 0.02, y + U], U from rectangular + normal-ish t."""
    b = breakaway_budget('back_driving_torque', 50.0, class_nm=0.5, ramp_rate_nm_s=20.0,
                         sample_rate_hz=1000.0, ramp_residual_nm=(0.01, 40))
    assert b.bias_bound == pytest.approx(0.02)
    assert b.u_c == pytest.approx(math.hypot(0.5 / math.sqrt(3), 0.01), rel=1e-12)
    lo, hi = b.interval
    assert 50.0 - lo == pytest.approx(b.expanded + 0.02)
    assert hi - 50.0 == pytest.approx(b.expanded)
    # the rectangular dominates (99.9 % of u_c^2): U close to p x 0.5
    assert b.expanded == pytest.approx(P * 0.5, rel=0.01)


def test_temperature_rise_budget_against_the_fits_by_hand() -> None:
    """A rise of 20 K read by a Pt100 class A: the slope term 0.002 x 20 K = 0.04 K
    (rectangular); noise sigma through the fits: the start is a parabola's value at the
    first sample (leverage of that point in a quadratic least squares, computed here with
    numpy.linalg.lstsq on the unscaled times), the settled value a line's centre
    (sigma / sqrt(n))."""
    rng = np.random.default_rng(3)
    dt, w = 1.0, 60.0
    t = np.arange(0.0, 3600.0, dt)
    y = 20 + 20 * (1 - np.exp(-t / 600.0)) + rng.normal(0, 0.02, t.size)
    b = temperature_rise_budget(20.0, t, y, window_s=w)
    n = round(w / dt) + 1
    x = t[:n]
    line = np.polyfit(x - x.mean(), y[:n], 1)
    sigma = np.std(y[:n] - np.polyval(line, x - x.mean()), ddof=2)
    a_mat = np.vstack([np.ones(n), x, x * x]).T
    cov = np.linalg.inv(a_mat.T @ a_mat)
    h0 = cov[0, 0]                                       # leverage at x = 0 (t[0])
    assert b.input('temperature sensor: slope term (Pt100 IEC 60751 class A)').u == \
        pytest.approx(0.04 / math.sqrt(3), rel=1e-12)
    assert b.input('start: parabola through the first window, at its start').u == \
        pytest.approx(sigma * math.sqrt(h0), rel=1e-6)
    assert b.input("settled: centre of the settled window's line").u == \
        pytest.approx(sigma / math.sqrt(n), rel=1e-12)
    assert b.u_c == pytest.approx(math.sqrt((0.04 / math.sqrt(3)) ** 2 + sigma ** 2 * h0
                                            + sigma ** 2 / n), rel=1e-6)


def test_plateau_type_a_needs_two_blocks() -> None:
    assert plateau_type_a('x', [1.0, 2.0, 3.0]) is None
    assert plateau_type_a('x', [1.0] * 40).u == 0.0


def test_guarded_rule_applies_to_a_breakaway_with_its_bias() -> None:
    """Starting torque <= 1.0 N m; read 0.995 N m, class band +-0.01 N m (U = 0.0095),
    ramp 20 N m/s at 1 kHz (reads high by up to 0.02): the interval [0.9655, 1.0045]
    straddles the limit (conformance not proven) -> INDETERMINATE under guarded
    acceptance, PASS under simple; read 0.97 the interval ends at 0.9795: PASS."""
    from rv_te_bench.acceptance import evaluate, parse_tolerance
    from rv_te_bench.acceptance._loss_results import _m

    def verdict(value: float, rule: str) -> str:
        b = breakaway_budget('starting_torque', value, class_nm=0.01, ramp_rate_nm_s=20.0,
                             sample_rate_hz=1000.0)
        assert b.u_above == pytest.approx(P * 0.01, rel=3e-3)     # no bias upwards
        prof = parse_tolerance({'profile': 'p', 'decision_rule': rule,
                                'limits': {'starting_torque_nm': {'max': 1.0}}})
        verdicts, _, _ = evaluate([_m('starting_torque_nm', 's', 'N m', value, '', b)], prof)
        return next(v.verdict for v in verdicts if v.name == 'starting_torque_nm')

    assert verdict(0.995, 'simple') == 'pass'
    assert verdict(0.995, 'guarded') == 'indeterminate'
    assert verdict(0.97, 'guarded') == 'pass'
