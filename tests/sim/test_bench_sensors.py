"""Torque and temperature sensors of sim.bench_sensors: class band, statistics, errors."""

from __future__ import annotations

import numpy as np
import pytest

from sim.bench_sensors import (
    SENSOR_PRESETS,
    SensorSpec,
    SimulatedSensor,
    nominal_range,
    sensor_preset,
    torque_sensor,
)
from sim.errors import ModelInputError, PresetError


@pytest.mark.parametrize(('needed', 'want'), [(0.7, 1.0), (1.0, 1.0), (1.01, 2.0),
                                              (9.65, 10.0), (11.0, 20.0), (1176.0, 2000.0),
                                              (4000.0, 5000.0)])
def test_nominal_range_1_2_5(needed: float, want: float) -> None:
    assert nominal_range(needed) == pytest.approx(want)


@pytest.mark.parametrize('cls', [0.05, 0.1, 0.2, 0.5])
def test_class_band_is_kept(cls: float) -> None:
    s = torque_sensor(500.0, cls)
    assert s.worst_case_error == pytest.approx(cls / 100 * 500.0, rel=1e-12)
    assert s.worst_case_error <= cls / 100 * 500.0 * (1 + 1e-12)


def test_readings_have_the_stated_errors() -> None:
    """Mean error = offset + gain x value, scatter = noise_rms (seeded, 200k samples)."""
    spec = torque_sensor(20.0, 0.1)
    sensor = SimulatedSensor(spec, np.random.default_rng(7))
    true = np.full(200_000, 12.5)
    err = sensor.measure(true) - true
    want_bias = spec.zero_offset + spec.gain_error * 12.5
    assert err.mean() == pytest.approx(want_bias, abs=5 * spec.noise_rms / np.sqrt(true.size))
    assert err.std(ddof=1) == pytest.approx(spec.noise_rms, rel=0.01)
    ideal = SimulatedSensor(sensor_preset('ideal-torque'), np.random.default_rng(1))
    np.testing.assert_array_equal(ideal.measure(true), true)


def test_pt100_within_class_a() -> None:
    spec = SENSOR_PRESETS['pt100-class-a']
    for t in (0.0, 50.0, 100.0):
        assert spec.zero_offset + 3 * spec.noise_rms <= 0.15 + 0.002 * abs(t)


def test_bad_specs_named() -> None:
    with pytest.raises(ModelInputError, match="quantity must be 'torque' or 'temperature'"):
        SensorSpec('x', 'speed', 1.0, 0.1)
    with pytest.raises(ModelInputError, match=r'gain_error must lie within \+-0.5'):
        SensorSpec('x', 'torque', 1.0, 0.1, gain_error=0.7)
    with pytest.raises(ModelInputError, match=r'full_scale must be finite and > 0'):
        SensorSpec('x', 'torque', 0.0, 0.1)
    with pytest.raises(PresetError, match="unknown sensor 'nope'; known sensors"):
        sensor_preset('nope')
    with pytest.raises(ModelInputError, match='needs a SensorSpec'):
        SimulatedSensor('pt100-class-a', np.random.default_rng())  # type: ignore[arg-type]
