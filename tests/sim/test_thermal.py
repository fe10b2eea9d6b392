"""The lumped case model of sim.thermal against its analytic solutions."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.errors import ModelInputError, PresetError
from sim.presets import available_presets, load_preset, preset_from_text
from sim.thermal import ThermalParams, ThermalState, step_response_degc

P = ThermalParams(case_mass_kg=9.0, specific_heat_j_kgk=460.0, surface_area_m2=0.11,
                  h_conv_w_m2k=12.0, mount_conductance_w_k=6.0, ambient_degc=20.0)


def test_derived_constants() -> None:
    g = 12.0 * 0.11 + 6.0
    assert P.conductance_w_k == pytest.approx(g)
    assert P.time_constant_s == pytest.approx(9.0 * 460.0 / g)
    assert P.steady_temp_degc(150.0) == pytest.approx(20.0 + 150.0 / g)


@pytest.mark.parametrize('rate_hz', [1.0, 100.0, 1000.0])
def test_sampled_integration_is_the_step_response(rate_hz: float) -> None:
    """A constant loss switched on at t = 0: the sampled temperatures equal
    T_inf + (T0 - T_inf) exp(-t/tau), written out here, over 5 time constants in blocks
    of 997 samples."""
    state = ThermalState(P, temp0_degc=25.0)
    tau, g = P.time_constant_s, P.conductance_w_k
    n_total = int(5 * tau * rate_hz)
    block = 997
    temps = np.concatenate([state.advance(np.full(min(block, n_total - k), 200.0),
                                          1.0 / rate_hz)
                            for k in range(0, n_total, block)])
    t = np.arange(n_total) / rate_hz
    t_inf = 20.0 + 200.0 / g
    want = t_inf + (25.0 - t_inf) * np.exp(-t / tau)
    # exact recursion: only float rounding accumulates (~1e-9 K over 2.8 M steps)
    np.testing.assert_allclose(temps, want, rtol=0, atol=1e-7)
    np.testing.assert_allclose(temps, step_response_degc(t, 200.0, 25.0, P), atol=1e-7)


def test_cooling_and_piecewise_loss() -> None:
    """On 600 s at 300 W, then off: cooling from where it was towards the ambient."""
    state = ThermalState(P)
    state.advance(np.full(600, 300.0), 1.0)
    t1 = state.temp_degc
    assert t1 == pytest.approx(float(step_response_degc(600.0, 300.0, 20.0, P)), abs=1e-9)
    cool = state.advance(np.zeros(1200), 1.0)
    tau = P.time_constant_s
    np.testing.assert_allclose(cool, 20.0 + (t1 - 20.0) * np.exp(-np.arange(1200) / tau),
                               atol=1e-9)
    state.reset()
    assert state.temp_degc == 20.0


def test_settle_time_is_where_the_rate_falls_below() -> None:
    rate = 0.1 / 60.0                                 # 0.1 K/min
    ts = P.settle_time_s(200.0, 20.0, rate)
    tau, rise = P.time_constant_s, 200.0 / P.conductance_w_k
    dtdt = lambda t: rise / tau * math.exp(-t / tau)  # noqa: E731
    assert dtdt(ts) == pytest.approx(rate, rel=1e-9)
    assert dtdt(ts * 0.99) > rate
    assert P.settle_time_s(0.0, 20.0, rate) == 0.0


def test_presets_have_thermal_sections() -> None:
    for name in available_presets():
        p = ThermalParams.from_preset(load_preset(name))
        assert 60.0 < p.time_constant_s < 7200.0


def test_bad_values_named() -> None:
    with pytest.raises(ModelInputError, match=r'thermal\.case_mass_kg must be finite and > 0'):
        ThermalParams(0.0, 460.0, 0.1, 10.0, 1.0, 20.0)
    with pytest.raises(ModelInputError, match='must lose heat somewhere'):
        ThermalParams(1.0, 460.0, 0.0, 10.0, 0.0, 20.0)
    with pytest.raises(ModelInputError, match='finite 1-D'):
        ThermalState(P).advance(np.array([1.0, np.nan]), 0.1)
    with pytest.raises(ModelInputError, match=r'dt_s must be finite and > 0'):
        ThermalState(P).advance(np.ones(3), 0.0)
    bare = preset_from_text('name = "x"\nmodel = "wang2020-2kv"\n[thermal]\ncase_mass_kg = 1.0\n')
    with pytest.raises(PresetError, match=r"'x' has no thermal\.specific_heat_j_kgk"):
        ThermalParams.from_preset(bare)


def test_the_bench_simulator_imports_no_scipy_signal() -> None:
    """A bench node of a default session (NLTE, no losses) never filters a temperature:
    importing sim.bench (through sim.loss_bench and sim.thermal) must not import
    scipy.signal, ~0.9 CPU s (it pulls scipy.stats and scipy.optimize) in every bench
    process and launcher; the lfilter is imported where the temperature is stepped."""
    import subprocess
    import sys

    code = ('import sys, sim.bench, sim.thermal; '
            'print(sorted(m for m in ("scipy.signal", "scipy.stats", "scipy.optimize") '
            'if m in sys.modules))')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         timeout=120, check=True).stdout
    assert out.strip() == '[]'
