"""Temperature rise (core.thermal_metrics) against the first-order step response written
out here: t_s = tau ln(dT / (tau r)), rise = dT (1 - exp(-t_s / tau)); the record comes from
the simulated case (sim.thermal, an exact zero-order-hold recursion) read by a Pt100."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rv_te_bench.core.thermal_metrics import temperature_rise
from rv_te_bench.errors import TeInputError
from sim.bench_sensors import SimulatedSensor, sensor_preset
from sim.presets import load_preset
from sim.thermal import ThermalParams, ThermalState


def _record(power_w: float, seconds: float, fs: float, sensor: str, seed: int = 1
            ) -> tuple[np.ndarray, np.ndarray, ThermalParams]:
    params = ThermalParams.from_preset(load_preset('rv-80e-101'))
    state = ThermalState(params)
    n = int(seconds * fs)
    temps = state.advance(np.full(n, power_w), 1.0 / fs)
    reading = SimulatedSensor(sensor_preset(sensor), np.random.default_rng(seed)).measure(temps)
    return np.arange(n) / fs, reading, params


@pytest.mark.parametrize(('sensor', 'limit', 'tol_s'), [
    ('ideal-temperature', 0.05, 2.0), ('pt100-class-a', 0.05, 60.0),
    ('pt100-class-a', 0.2, 30.0)])
def test_settle_time_and_rise_are_the_analytic_step_response(sensor: str, limit: float,
                                                             tol_s: float) -> None:
    power = 150.0
    t, y, p = _record(power, 6000.0, 1.0, sensor)
    g = p.h_conv_w_m2k * p.surface_area_m2 + p.mount_conductance_w_k
    tau = p.case_mass_kg * p.specific_heat_j_kgk / g
    d_inf = power / g
    ts = tau * math.log(d_inf / (tau * limit / 60.0))
    rise = d_inf * (1.0 - math.exp(-ts / tau))
    r = temperature_rise(t, y, rate_limit_k_per_min=limit, window_s=120.0)
    assert r.settled
    assert r.settle_time_s == pytest.approx(ts, abs=tol_s)
    # the rise at a time off by dt is off by the rate there (limit) x dt, + sensor offset
    assert r.rise_k == pytest.approx(rise, abs=limit / 60 * tol_s + 0.02)
    assert r.decided_at_s == pytest.approx(r.settle_time_s + 60.0, abs=1.0)
    assert abs(r.final_rate_k_per_min) < limit


def test_not_settled_reports_the_rise_so_far() -> None:
    t, y, _ = _record(150.0, 600.0, 1.0, 'ideal-temperature')
    r = temperature_rise(t, y, rate_limit_k_per_min=0.05, window_s=60.0)
    assert not r.settled and math.isnan(r.settle_time_s)
    assert r.rise_k == pytest.approx(y[-1] - y[0], abs=0.05)
    assert r.final_rate_k_per_min > 0.05


def test_bad_settings_are_named() -> None:
    t = np.arange(100.0)
    with pytest.raises(TeInputError, match='window_s'):
        temperature_rise(t, t, rate_limit_k_per_min=0.1, window_s=80.0)
    with pytest.raises(TeInputError, match='rate_limit_k_per_min'):
        temperature_rise(t, t, rate_limit_k_per_min=0.0, window_s=10.0)
    with pytest.raises(TeInputError, match='strictly increasing'):
        temperature_rise(np.zeros(100), t, rate_limit_k_per_min=0.1, window_s=10.0)
