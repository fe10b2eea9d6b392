"""Tests of sim.encoders: closed-form error cases, quantisation statistics, presets, validation."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from sim.encoders import (
    ENCODER_PRESETS,
    EncoderSpec,
    SimulatedEncoder,
    encoder_preset,
    encoder_spec_with,
)
from sim.errors import ModelInputError, PresetError

ARCSEC = math.pi / 648000.0


def _clean(spec: EncoderSpec) -> EncoderSpec:
    """The spec with every error term off (quantisation only)."""
    return encoder_spec_with(spec, graduation_orders=(), graduation_amplitudes_rad=(),
                             graduation_phases_rad=(), eccentricity_amplitude_rad=0.0,
                             noise_sigma_rad=0.0)


def test_ideal_returns_the_true_angle_exactly() -> None:
    theta = np.array([-12.5, 0.0, 1e-9, 3.0, 2.0 * math.pi * 1e5 + 0.123, 3.1e7])
    out = SimulatedEncoder(encoder_preset('ideal'), np.random.default_rng(0)).measure(theta)
    np.testing.assert_array_equal(out, theta)
    assert out is not theta
    assert encoder_preset('ideal').resolution_rad == 0.0


def test_quantisation_floors_to_the_count() -> None:
    # 8 counts per rev: q = pi/4. Values chosen away from count boundaries.
    spec = EncoderSpec(name='coarse', counts_per_rev=8)
    enc = SimulatedEncoder(spec, np.random.default_rng(0))
    q = math.pi / 4
    theta = np.array([0.1, 0.9, 7.0, -0.1, 100.0, -100.0])
    # floor(theta / q): 0, 1, 8, -1, 127, -128
    expected = q * np.array([0, 1, 8, -1, 127, -128])
    np.testing.assert_allclose(enc.measure(theta), expected, rtol=0, atol=1e-12)


def test_quantisation_error_is_uniform_on_minus_q_to_zero() -> None:
    spec = _clean(encoder_preset('heidenhain-ron886'))
    q = 2 * math.pi / 36e6
    assert spec.resolution_rad == pytest.approx(q, rel=1e-15)
    theta = np.random.default_rng(7).uniform(-50.0, 50.0, 100_000)
    err = SimulatedEncoder(spec, np.random.default_rng(0)).measure(theta) - theta
    # every error in (-q, 0]; slack 1e-6 q for float64 rounding at |theta| <= 50 rad
    assert err.max() <= 1e-6 * q
    assert err.min() >= -q * (1 + 1e-6)
    # uniform on (-q, 0]: mean -q/2 (standard error q/sqrt(12 N) = 9e-4 q; allow 5e-3 q),
    # standard deviation q/sqrt(12) (relative standard error 1/sqrt(1.25 N) ~ 0.3 %; allow 2 %)
    assert err.mean() == pytest.approx(-q / 2, abs=5e-3 * q)
    assert err.std() == pytest.approx(q / math.sqrt(12), rel=0.02)


@given(theta=hnp.arrays(np.float64, st.integers(1, 50),
                        elements=st.floats(-1e4, 1e4, allow_nan=False)))
def test_readings_are_whole_counts_not_above_the_true_angle(theta: np.ndarray) -> None:
    spec = EncoderSpec(name='q', counts_per_rev=2**20)
    q = 2 * math.pi / 2**20
    out = SimulatedEncoder(spec, np.random.default_rng(0)).measure(theta)
    counts = out / q
    np.testing.assert_allclose(counts, np.round(counts), rtol=0, atol=1e-6)
    assert np.all(out - theta <= 1e-6 * q)
    assert np.all(out - theta >= -q * (1 + 1e-6))


def test_graduation_and_eccentricity_at_known_angles() -> None:
    a2, e1 = 2e-6, 5e-7
    spec = EncoderSpec(name='g', counts_per_rev=None, graduation_orders=(2,),
                       graduation_amplitudes_rad=(a2,), graduation_phases_rad=(0.0,),
                       eccentricity_amplitude_rad=e1, eccentricity_phase_rad=math.pi / 2)
    enc = SimulatedEncoder(spec, np.random.default_rng(0))
    # sin(2 theta) is +1 at pi/4, -1 at 3 pi/4, 0 at 0 and pi/2; cos(theta) is 1, -1/sqrt2 ...
    theta = np.array([0.0, math.pi / 4, math.pi / 2, 3 * math.pi / 4, math.pi])
    expected_err = np.array([e1, a2 + e1 / math.sqrt(2), 0.0,
                             -a2 - e1 / math.sqrt(2), -e1])
    np.testing.assert_allclose(enc.measure(theta) - theta, expected_err, rtol=0, atol=1e-15)
    # a function of the angle: the same 200 revolutions later (float64 of ~1257 rad: 2e-13)
    far = theta + 2 * math.pi * 200
    np.testing.assert_allclose(enc.measure(far) - far, expected_err, rtol=0, atol=1e-12)


@pytest.mark.parametrize('name', sorted(ENCODER_PRESETS))
def test_preset_error_rms_over_a_revolution(name: str) -> None:
    """Without quantisation, RMS over a whole revolution = sqrt(sum a^2/2 + e^2/2 + sigma^2).

    Expectation computed here from the fields (orders are distinct and none is 1 in the
    presets). N = 200,000 uniformly spaced angles: the harmonic part is exact; the noise part
    has a relative standard error ~0.2 %: tolerance 1 %.
    """
    spec = encoder_spec_with(encoder_preset(name), counts_per_rev=None)
    assert 1 not in spec.graduation_orders
    ms = (sum(a * a for a in spec.graduation_amplitudes_rad) / 2
          + spec.eccentricity_amplitude_rad ** 2 / 2 + spec.noise_sigma_rad ** 2)
    theta = np.linspace(0.0, 2 * math.pi, 200_000, endpoint=False) + 3000.0
    err = SimulatedEncoder(spec, np.random.default_rng(1)).measure(theta) - theta
    assert math.sqrt(np.mean(err ** 2)) == pytest.approx(math.sqrt(ms), rel=0.01, abs=1e-15)
    assert spec.error_mean_square_rad2 == pytest.approx(ms, rel=1e-12, abs=0)


def test_noise_has_the_stated_sigma_and_comes_from_the_rng() -> None:
    sigma = 0.05 * ARCSEC
    spec = EncoderSpec(name='n', counts_per_rev=None, noise_sigma_rad=sigma)
    theta = np.linspace(0.0, 10.0, 50_000)
    r1 = SimulatedEncoder(spec, np.random.default_rng(3)).measure(theta)
    r2 = SimulatedEncoder(spec, np.random.default_rng(3)).measure(theta)
    r3 = SimulatedEncoder(spec, np.random.default_rng(4)).measure(theta)
    np.testing.assert_array_equal(r1, r2)
    assert not np.array_equal(r1, r3)
    # sample std of 50,000 normals: relative standard error 1/sqrt(2N) = 0.3 %; allow 2 %
    assert np.std(r1 - theta) == pytest.approx(sigma, rel=0.02)
    assert abs(np.mean(r1 - theta)) < 5 * sigma / math.sqrt(theta.size)


def test_presets_carry_sources_and_stay_within_their_class() -> None:
    assert {'ideal', 'heidenhain-ron886', 'renishaw-resm', 'renishaw-resolute'} <= set(
        ENCODER_PRESETS)
    for name, spec in ENCODER_PRESETS.items():
        assert spec.name == name
        assert spec.source
        assert spec.assumptions
        # stated rule: sum of amplitudes + eccentricity + 3 sigma <= accuracy class
        assert spec.worst_case_error_rad <= spec.accuracy_class_arcsec * ARCSEC * (1 + 1e-9)
    assert encoder_preset('heidenhain-ron886').accuracy_class_arcsec == 1.0
    assert encoder_preset('renishaw-resm').accuracy_class_arcsec == 0.38
    assert encoder_preset('renishaw-resolute').resolution_rad == 2 * math.pi / 2**32
    assert encoder_preset('renishaw-resolute').counts_per_rev == 4_294_967_296


def test_unknown_encoder_lists_the_known_ones() -> None:
    with pytest.raises(PresetError, match=r"unknown encoder 'ron999'.*heidenhain-ron886"):
        encoder_preset('ron999')


@pytest.mark.parametrize(('changes', 'pattern'), [
    ({'counts_per_rev': 0}, r'counts_per_rev must be in \[1'),
    ({'counts_per_rev': 1.5}, 'counts_per_rev must be an integer'),
    ({'noise_sigma_rad': -1e-9}, r'noise_sigma_rad must be finite and >= 0'),
    ({'noise_sigma_rad': float('nan')}, 'noise_sigma_rad must be finite'),
    ({'eccentricity_amplitude_rad': float('inf')}, 'eccentricity_amplitude_rad must be finite'),
    ({'graduation_orders': (2, 3)}, 'must have the same length'),
    ({'graduation_orders': (0, 3, 4, 5)}, 'graduation_orders must be integers >= 1'),
    ({'graduation_amplitudes_rad': (-1.0, 0.0, 0.0, 0.0)},
     'graduation_amplitudes_rad must be finite and >= 0'),
    ({'name': ''}, 'name must be a non-empty string'),
    ({'wobble_rad': 1.0}, r"no field\(s\) \['wobble_rad'\]"),
])
def test_bad_spec_values_name_the_field_and_rule(changes: dict, pattern: str) -> None:
    with pytest.raises(ModelInputError, match=pattern):
        encoder_spec_with(encoder_preset('heidenhain-ron886'), **changes)


def test_spec_with_keeps_other_fields_and_validates() -> None:
    base = encoder_preset('renishaw-resm')
    new = encoder_spec_with(base, noise_sigma_rad=0.0)
    assert new.noise_sigma_rad == 0.0
    assert new.graduation_amplitudes_rad == base.graduation_amplitudes_rad
    assert base.noise_sigma_rad > 0  # the preset itself is unchanged


def test_measure_rejects_bad_input() -> None:
    enc = SimulatedEncoder(encoder_preset('ideal'), np.random.default_rng(0))
    with pytest.raises(ModelInputError, match='1-D'):
        enc.measure(np.zeros((2, 3)))
    with pytest.raises(ModelInputError, match='finite'):
        enc.measure(np.array([0.0, np.nan]))
    with pytest.raises(ModelInputError, match=r'numpy\.random\.Generator'):
        SimulatedEncoder(encoder_preset('ideal'), 42)  # type: ignore[arg-type]
