"""Tests of the simulated scales with several read heads (sim.read_heads, sim.encoders).

The truth is the tests' own exact-geometry model (:mod:`tests.scale_reference`: eccentric
centre by ``arg``, tilted circle by ``atan2``, no linearisation), not sim's formulas.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.encoders import (
    EncoderSpec,
    ReadHead,
    SimulatedEncoder,
    encoder_preset,
    encoder_spec_with,
    with_heads,
)
from sim.errors import ModelInputError
from sim.read_heads import (
    eccentricity_angle_rad,
    equally_spaced_heads,
    graduation_from_grade,
    tilt_amplitude_rad,
)
from tests.scale_reference import ARCSEC_RAD, Scale


def _scale_pair(rng: np.random.Generator, *, n_heads: int = 4, index_rad: float = 0.0,
                ) -> tuple[EncoderSpec, Scale]:
    """One scale described twice: as sim's spec and as the tests' geometry."""
    grad = graduation_from_grade(1.0, rng, orders=(1, 2, 3, 5, 8))
    heads = equally_spaced_heads(n_heads, rng, interpolation_rad=0.1 * ARCSEC_RAD)
    ecc_m, radius_m, tilt = 5e-6, 0.05, 3e-4
    psi, chi = 1.1, 0.4
    spec = EncoderSpec(
        name='ring', counts_per_rev=None, graduation_orders=grad.orders,
        graduation_amplitudes_rad=grad.amplitudes_rad, graduation_phases_rad=grad.phases_rad,
        eccentricity_amplitude_rad=eccentricity_angle_rad(ecc_m, 2 * radius_m),
        eccentricity_phase_rad=psi, heads=heads, signal_periods=18_000, tilt_rad=tilt,
        tilt_phase_rad=chi, scale_index_rad=index_rad, scale_diameter_m=2 * radius_m,
        serial='SC-7')
    ref = Scale(radius_m=radius_m, eccentricity_m=ecc_m, psi_rad=psi, tilt_rad=tilt,
                chi_rad=chi, index_rad=index_rad, orders=grad.orders,
                amplitudes_rad=grad.amplitudes_rad, phases_rad=grad.phases_rad, lines=18_000,
                heads_rad=tuple(h.angle_rad for h in heads),
                interp_rad=tuple(h.interpolation_rad for h in heads),
                interp_phase_rad=tuple(h.interpolation_phase_rad for h in heads))
    return spec, ref


@pytest.mark.parametrize('index_deg', [0.0, 180.0, 120.0])
def test_head_readings_match_the_exact_geometry(index_deg: float) -> None:
    """Every head of a scale 5 um off centre on 100 mm (+-20.6"), tilted 0.3 mrad, with a
    graduation error and interpolation error, reads what exact geometry gives, within the
    second-order terms the linear model leaves out ((e/R)^2 ~ 0.002")."""
    spec, ref = _scale_pair(np.random.default_rng(36), index_rad=math.radians(index_deg))
    theta = np.linspace(-3.0, 9.0, 20_011)
    got = SimulatedEncoder(spec, np.random.default_rng(0)).measure_heads(theta)
    want = ref.readings(theta)
    assert got.shape == (4, theta.size)
    err = np.max(np.abs(got - want)) / ARCSEC_RAD
    assert err < 0.005, err
    # and the error is there to be found: the heads differ by tens of arcseconds
    assert np.max(np.abs(got[0] - got[1])) / ARCSEC_RAD > 20.0


def test_eccentricity_is_412_e_over_d() -> None:
    """DESIGN.md s.7: 5 um on a 100 mm ring -> +-20.6" (41" p-p), from the geometry."""
    assert eccentricity_angle_rad(5e-6, 0.1) / ARCSEC_RAD == pytest.approx(412.53 * 5 / 100,
                                                                           rel=1e-4)
    ref = Scale(radius_m=0.05, eccentricity_m=5e-6)
    theta = np.linspace(0.0, 2 * math.pi, 4001)
    err = (ref.readings(theta)[0] - theta) / ARCSEC_RAD
    assert float(np.ptp(err)) == pytest.approx(41.25, rel=1e-3)


def test_tilt_is_tau_squared_over_four_at_order_two() -> None:
    tau = 2e-3
    ref = Scale(tilt_rad=tau, chi_rad=0.3)
    u = np.linspace(0.0, 2 * math.pi, 8192, endpoint=False)
    err = ref.readings(u)[0] - u
    amp = np.abs(np.fft.rfft(err))[2] * 2 / u.size
    assert amp == pytest.approx(tilt_amplitude_rad(tau), rel=1e-3)


def test_one_head_spec_reads_as_before_with_the_same_draws() -> None:
    """A spec without heads: measure_heads is measure (same numbers, same random draws)."""
    spec = encoder_preset('heidenhain-ron886')
    theta = np.linspace(0.0, 50.0, 5000)
    a = SimulatedEncoder(spec, np.random.default_rng(4)).measure(theta)
    b = SimulatedEncoder(spec, np.random.default_rng(4)).measure_heads(theta)
    np.testing.assert_array_equal(b, a[None, :])
    assert 'heads' not in spec.to_plain()


def test_each_head_has_its_own_noise() -> None:
    heads = (ReadHead(0.0, noise_sigma_rad=1e-5), ReadHead(math.pi, noise_sigma_rad=3e-5))
    spec = EncoderSpec(name='x', counts_per_rev=None, heads=heads)
    theta = np.linspace(0.0, 1.0, 200_000)
    r = SimulatedEncoder(spec, np.random.default_rng(1)).measure_heads(theta) - theta
    np.testing.assert_allclose(r.std(axis=1), [1e-5, 3e-5], rtol=0.02)
    assert abs(np.corrcoef(r)[0, 1]) < 0.01


def test_graduation_from_grade_stays_in_the_band() -> None:
    rng = np.random.default_rng(2)
    g = graduation_from_grade(1.5, rng)
    amps = np.array(g.amplitudes_rad) / ARCSEC_RAD
    assert amps.sum() == pytest.approx(1.5)
    np.testing.assert_allclose(amps * np.array(g.orders), amps[0], rtol=1e-12)   # 1/k law
    u = np.linspace(0.0, 2 * math.pi, 20_000)
    curve = sum(a * np.sin(k * u + p) for k, a, p in zip(g.orders, g.amplitudes_rad,
                                                         g.phases_rad, strict=True))
    assert np.max(np.abs(curve)) / ARCSEC_RAD <= 1.5
    with pytest.raises(ModelInputError, match='orders must be distinct'):
        graduation_from_grade(1.0, rng, orders=(1, 1))


def test_with_heads_moves_the_interpolation_error_to_the_heads() -> None:
    ron = encoder_preset('heidenhain-ron886')
    assert 36_000 in ron.graduation_orders
    spec = with_heads(ron, equally_spaced_heads(2))
    assert spec.signal_periods == 36_000
    assert 36_000 not in spec.graduation_orders
    assert spec.n_heads == 2
    assert spec.head_angles_rad == pytest.approx((0.0, math.pi))
    assert spec.to_plain()['heads'][1]['angle_rad'] == pytest.approx(math.pi)
    with pytest.raises(ModelInputError, match='at least one'):
        with_heads(ron, ())


def test_bad_head_values_are_named() -> None:
    with pytest.raises(ModelInputError, match='noise_sigma_rad'):
        ReadHead(0.0, noise_sigma_rad=-1.0)
    with pytest.raises(ModelInputError, match='heads must be'):
        EncoderSpec(name='x', counts_per_rev=None, heads=(1.0,))  # type: ignore[arg-type]
    with pytest.raises(ModelInputError, match='tilt_rad'):
        encoder_spec_with(encoder_preset('ideal'), tilt_rad=math.nan)
