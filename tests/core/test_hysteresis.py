"""Hysteresis-curve metrics against closed-form loops written here (not by sim.torsion)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from rv_te_bench.core.hysteresis import (
    HysteresisConfig,
    RigidityRegion,
    dwell_points,
    hysteresis_metrics,
)
from rv_te_bench.errors import TeConfigError, TeInputError

TR = 100.0


def step_loop(k: float, b: float, tf: float, fractions: list[float],
              *, offset: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """A linear unit (stiffness k, free play b, Coulomb friction tf) under torque steps.

    Closed form of each branch: loading a flank at torque T sits at b/2 + (T - tf)/k past
    the centre, unloading at b/2 + (T + tf)/k; between |T| <= tf the output sticks.
    """
    up = fractions
    seq = ([f * TR for f in up] + [f * TR for f in up[-2::-1]]
           + [-f * TR for f in up[1:]] + [-f * TR for f in up[-2::-1]])
    t = np.array(seq)
    phi = np.empty_like(t)
    i_max, i_min = int(np.argmax(t)), int(np.argmin(t))
    for i, x in enumerate(t):
        if i <= i_max:                      # first loading (from the middle of the play)
            phi[i] = b / 2 + (x - tf) / k if x > tf else 0.0
        elif i <= i_min:                    # +T_R -> -T_R
            phi[i] = (b / 2 + (x + tf) / k if x + tf > 0 else
                      (-b / 2 + (x + tf) / k if x < -tf else b / 2))
            if x + tf <= 0 and x >= -tf:
                phi[i] = b / 2
        else:                               # -T_R -> 0
            phi[i] = -b / 2 + (x - tf) / k if x - tf < 0 else -b / 2
    return t, phi + offset


FRACTIONS = [0.0, 0.03, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0]


@pytest.mark.parametrize(('k', 'b', 'tf'), [(1e5, 2.9e-4, 0.0), (1e5, 2.9e-4, 1.5),
                                            (3e4, 0.0, 1.0), (6e5, 1e-3, 2.5)])
def test_linear_unit_with_friction(k: float, b: float, tf: float) -> None:
    t, phi = step_loop(k, b, tf, FRACTIONS, offset=0.37)
    m = hysteresis_metrics(t, phi, HysteresisConfig(rated_torque_nm=TR))
    assert_allclose(m.backlash_rad, b + 2 * tf / k, rtol=1e-12, atol=1e-15)
    assert_allclose(m.lost_motion_rad, b + 2 * 3.0 / k, rtol=1e-12)
    assert_allclose(m.rigidity_nm_per_rad['K'], (k, k), rtol=1e-9)
    assert m.lost_motion_torque_nm == pytest.approx(3.0)
    assert m.max_torque_nm == TR and m.min_torque_nm == -TR


def asymmetric_loop(kp: float, kn: float, b: float, tf: float,
                    fractions: list[float]) -> tuple[np.ndarray, np.ndarray]:
    """A unit whose positive flank has stiffness kp and negative flank kn (free play b,
    Coulomb friction tf), under the torque steps of :func:`step_loop`.

    Closed form: on the positive flank phi = b/2 + (T -+ tf)/kp (loading / unloading), on the
    negative one phi = -b/2 + (T +- tf)/kn; inside |T| <= tf the output sticks.
    """
    up = fractions
    t = np.array([f * TR for f in up] + [f * TR for f in up[-2::-1]]
                 + [-f * TR for f in up[1:]] + [-f * TR for f in up[-2::-1]])
    i_max, i_min = int(np.argmax(t)), int(np.argmin(t))
    phi = np.empty_like(t)
    for i, x in enumerate(t):
        if i <= i_max:                      # first loading, from the middle of the play
            phi[i] = b / 2 + (x - tf) / kp if x > tf else 0.0
        elif i <= i_min:                    # +T_R -> -T_R
            phi[i] = (b / 2 + (x + tf) / kp if x + tf > 0 else
                      -b / 2 + (x + tf) / kn if x < -tf else b / 2)
        else:                               # -T_R -> 0
            phi[i] = -b / 2 + (x - tf) / kn if x - tf < 0 else -b / 2
    return t, phi


@pytest.mark.parametrize(('kp', 'kn'), [(1e5, 4e4), (4e4, 1e5)])
@pytest.mark.parametrize('tf', [0.0, 1.5])
def test_asymmetric_unit_minimum_rigidity_is_the_softer_side(kp: float, kn: float,
                                                             tf: float) -> None:
    """A unit soft on one side (either one) has that side's rigidity as its minimum: the
    catalogue limit is a minimum, and the softer side is what a user's axis feels."""
    b = 2.9e-4
    t, phi = asymmetric_loop(kp, kn, b, tf, FRACTIONS)
    m = hysteresis_metrics(t, phi, HysteresisConfig(rated_torque_nm=TR))
    assert_allclose(m.rigidity_nm_per_rad['K'], (kp, kn), rtol=1e-9)
    assert m.rigidity_min_nm_per_rad('K') == pytest.approx(min(kp, kn), rel=1e-9)
    assert_allclose(m.backlash_rad, b + tf / kp + tf / kn, rtol=1e-12)
    assert_allclose(m.lost_motion_rad, b + 3.0 / kp + 3.0 / kn, rtol=1e-12)
    assert_allclose(m.lost_motion_mid_rad, (-b / 2 - 3.0 / kn, b / 2 + 3.0 / kp), rtol=1e-12)


def test_continuous_loop_area_and_nonlinear_secant() -> None:
    """Constant-speed loading of a hardening unit g(d) = c d^2 (d past the flank).

    Branch angles: d(T) = sqrt(T / c); loading branch at d(T - tf), unloading at d(T + tf).
    Loop area = 2 tf (phi_max - phi_min) (the loader's torque jumps by 2 tf at each turn).
    """
    c, b, tf = 4e9, 3e-4, 1.0

    def d(x: np.ndarray) -> np.ndarray:
        return np.sqrt(np.maximum(x, 0.0) / c)

    phi_max, phi_min = b / 2 + d(TR - tf), -b / 2 - d(TR - tf)
    n = 20001

    def g(p: np.ndarray) -> np.ndarray:
        return np.where(p > b / 2, c * (p - b / 2) ** 2,
                        np.where(p < -b / 2, -c * (-p - b / 2) ** 2, 0.0))

    # the unit was preloaded to -T_R: the first loading starts on the negative flank at
    # zero torque, on the same (steady) ascending path as the return from -T_R
    zero_up = -b / 2 - d(tf)
    up0 = np.linspace(zero_up, phi_max, n)
    down = np.linspace(phi_max, phi_min, 2 * n)
    back = np.linspace(phi_min, zero_up, n)
    t = np.r_[g(up0) + tf, g(down) - tf, g(back) + tf]
    phi = np.r_[up0, down, back]
    m = hysteresis_metrics(t, phi, HysteresisConfig(rated_torque_nm=TR))
    assert_allclose(m.backlash_rad, b + 2 * d(tf), rtol=1e-6)
    lm = b + d(3 - tf) + d(3 + tf)
    assert_allclose(m.lost_motion_rad, lm, rtol=1e-4)
    k = 50.0 / (d(TR - tf) - d(50.0 - tf))
    assert_allclose(m.rigidity_nm_per_rad['K'], (k, k), rtol=1e-4)
    assert_allclose(m.hysteresis_loss_j, 2 * tf * (phi_max - phi_min), rtol=2e-3)


def test_harmonic_drive_style_regions() -> None:
    """K1/K2/K3 of a piecewise-linear unit: each region's own stiffness."""
    t1, t2, k1, k2, k3 = 20.0, 60.0, 2e4, 5e4, 8e4
    tq = np.r_[np.linspace(0, TR, 51), np.linspace(TR, -TR, 101)[1:], np.linspace(-TR, 0, 51)[1:]]

    def defl(x: np.ndarray) -> np.ndarray:
        a = np.abs(x)
        out = np.where(a <= t1, a / k1, np.where(
            a <= t2, t1 / k1 + (a - t1) / k2, t1 / k1 + (t2 - t1) / k2 + (a - t2) / k3))
        return np.sign(x) * out

    phi = defl(tq)
    regions = (RigidityRegion('K1', 0.03, 0.2), RigidityRegion('K2', 0.2, 0.6),
               RigidityRegion('K3', 0.6, 1.0))
    m = hysteresis_metrics(tq, phi, HysteresisConfig(rated_torque_nm=TR,
                                                     rigidity_regions=regions))
    assert_allclose(m.rigidity_nm_per_rad['K1'], (k1, k1), rtol=1e-9)
    assert_allclose(m.rigidity_nm_per_rad['K2'], (k2, k2), rtol=1e-9)
    assert_allclose(m.rigidity_nm_per_rad['K3'], (k3, k3), rtol=1e-9)
    assert m.backlash_rad == pytest.approx(0.0, abs=1e-15)
    assert m.hysteresis_loss_j == pytest.approx(0.0, abs=1e-12)


def test_dwell_points_average_noise() -> None:
    rng = np.random.default_rng(3)
    t, phi = step_loop(1e5, 2.9e-4, 1.0, FRACTIONS)
    reps = 400
    tt = np.repeat(t, reps)
    noisy = np.repeat(phi, reps) + rng.normal(0.0, 5e-6, tt.size)   # ~1" noise
    tp, ap, count = dwell_points(tt, noisy)
    assert count.tolist() == [reps] * t.size
    m = hysteresis_metrics(tp, ap, HysteresisConfig(rated_torque_nm=TR))
    assert m.backlash_rad == pytest.approx(2.9e-4 + 2e-5, abs=1.5e-6)


@given(offset=st.floats(-10, 10), scale=st.floats(0.1, 10))
def test_offset_invariance_and_torque_scaling(offset: float, scale: float) -> None:
    """A constant angle offset changes nothing; scaling all torques scales the rigidity."""
    t, phi = step_loop(1e5, 2.9e-4, 1.0, FRACTIONS)
    ref = hysteresis_metrics(t, phi, HysteresisConfig(rated_torque_nm=TR))
    m = hysteresis_metrics(t, phi + offset, HysteresisConfig(rated_torque_nm=TR))
    assert_allclose(m.backlash_rad, ref.backlash_rad, atol=1e-12)
    assert_allclose(m.lost_motion_rad, ref.lost_motion_rad, atol=1e-12)
    s = hysteresis_metrics(t * scale, phi, HysteresisConfig(rated_torque_nm=TR * scale))
    assert_allclose(s.rigidity_nm_per_rad['K'][0], scale * ref.rigidity_nm_per_rad['K'][0],
                    rtol=1e-9)
    assert_allclose(s.hysteresis_loss_j, scale * ref.hysteresis_loss_j, rtol=1e-9)


def test_unreached_points_are_nan() -> None:
    t, phi = step_loop(1e5, 0.0, 0.0, [0.0, 0.03, 0.1, 0.3])   # stops at 30 % of T_R
    m = hysteresis_metrics(t, phi, HysteresisConfig(rated_torque_nm=TR))
    assert math.isnan(m.rigidity_nm_per_rad['K'][0])
    assert math.isnan(m.rigidity_min_nm_per_rad('K'))   # one side missing: no minimum
    assert math.isfinite(m.lost_motion_rad)


@pytest.mark.parametrize(('torque', 'angle', 'match'), [
    ([0, 1, 2], [0, 1, 2], 'at least 5'),
    ([0, -1, -2, -1, 0, 1], [0] * 6, 'positive torque first'),
    ([0, 1, 2, 1, 0], [0] * 5, 'positive torque first'),
    ([0, 1, float('nan'), -1, 0], [0] * 5, 'not finite'),
    ([0, 1, 2, -1, 0], [0] * 4, 'differ in length'),
])
def test_bad_records(torque: list[float], angle: list[float], match: str) -> None:
    with pytest.raises(TeInputError, match=match):
        hysteresis_metrics(torque, angle, HysteresisConfig(rated_torque_nm=TR))


@pytest.mark.parametrize(('kwargs', 'match'), [
    ({'rated_torque_nm': 0.0}, 'rated_torque_nm'),
    ({'rated_torque_nm': float('inf')}, 'rated_torque_nm'),
    ({'rated_torque_nm': 1.0, 'lost_motion_fraction': 0.0}, 'lost_motion_fraction'),
    ({'rated_torque_nm': 1.0, 'rigidity_regions': ()}, 'non-empty'),
    ({'rated_torque_nm': 1.0, 'rigidity_regions': (RigidityRegion('K', 0.1, 0.2),
                                                   RigidityRegion('K', 0.2, 0.3))}, 'unique'),
])
def test_bad_config(kwargs: dict, match: str) -> None:
    with pytest.raises(TeConfigError, match=match):
        HysteresisConfig(**kwargs)


@pytest.mark.parametrize(('lo', 'hi'), [(0.0, 0.5), (0.5, 0.5), (0.5, 1.2), (-0.1, 0.5)])
def test_bad_region(lo: float, hi: float) -> None:
    with pytest.raises(TeConfigError, match='lo_fraction < hi_fraction'):
        RigidityRegion('K', lo, hi)


def test_torque_points_cover_every_reading() -> None:
    cfg = HysteresisConfig(rated_torque_nm=200.0, lost_motion_fraction=0.05,
                           rigidity_regions=(RigidityRegion('K', 0.25, 0.75),))
    assert cfg.torque_points_nm() == (-200.0, -150.0, -50.0, -10.0, 0.0, 10.0, 50.0, 150.0,
                                      200.0)


@pytest.mark.parametrize('offset_rad', [0.0, 5.0, 300.0])
def test_loop_area_far_from_zero_keeps_its_digits(offset_rad: float) -> None:
    """A loop of tens of micro-radians read at an output angle of hundreds of radians (a
    life test's output after ~50 turns): the shoelace sums of the raw coordinates cancel
    away the area's digits (1.7e-7 relative at 300 rad, and the uncertainty budget's
    finite differences moved 2 % with the BLAS dot product's summation order). Closed
    form: the polygon of n points on an ellipse of half-axes A, B has the area
    n A B sin(2 pi / n) / 2."""
    from rv_te_bench.core.hysteresis import _loop_area

    n, half_a_rad, half_b_nm = 2000, 2e-5, 150.0
    u = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    area = _loop_area(half_b_nm * np.sin(u), offset_rad + half_a_rad * np.cos(u))
    exact = 0.5 * n * half_a_rad * half_b_nm * math.sin(2.0 * math.pi / n)
    assert area == pytest.approx(exact, rel=1e-9)
