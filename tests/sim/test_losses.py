"""The loss laws of sim.losses against closed forms computed here.

Each law is re-derived in this file from the parameters and its published form (Schlenk's
exponents, Palmgren's M0/M1, the Changenet-Velex churning exponents), not taken from the
module: the energy balance P_in - P_out = sum of losses, the forward/backward mesh
efficiencies 1/(1+f) and 1-f, the starting and back-driving torques from the static
values, the inertia term.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sim.errors import ModelInputError, PresetError
from sim.losses import LossModel, LossParams, palmgren_m0_nm
from sim.presets import Preset, available_presets, load_preset, preset_from_text

RPM = 2 * math.pi / 60


def model(name: str = 'rv-80e-101', **changes: float) -> LossModel:
    m = LossModel.from_preset(load_preset(name))
    if changes:
        m = LossModel(dataclasses.replace(m.params, **changes), m.lubricant)
    return m


def independent_terms(m: LossModel, w: np.ndarray, load: np.ndarray, temp_c: float):
    """Each loss torque at the input, written out here from the laws."""
    p = m.params
    nu = m.lubricant.viscosity_mm2_s(temp_c)
    nu_ref = m.lubricant.viscosity_mm2_s(p.reference_temp_degc)
    w_ref = p.reference_speed_rpm * RPM
    aw, at = np.abs(w), np.abs(load)
    f = p.mesh_loss_ref * (at / p.reference_torque_nm) ** 0.2 * (aw / w_ref) ** -0.2 \
        * (nu / nu_ref) ** -0.05
    f = np.minimum(f, p.mesh_loss_static)
    n_b = aw / RPM * p.bearing_speed_ratio                       # rpm of the bearings
    x = nu * n_b
    m0_nmm = np.where(x >= 2024.0, 1e-7 * p.bearing_f0 * x ** (2 / 3),
                      160e-7 * p.bearing_f0) * (p.bearing_dm_m * 1000) ** 3
    b0 = m0_nmm / 1000 * p.bearing_count * p.bearing_speed_ratio
    b1 = p.bearing_f1 * p.bearing_load_n_per_nm * at * p.bearing_dm_m * p.bearing_speed_ratio
    ch = p.churn_torque_ref_nm * (aw / w_ref) ** 0.59 * (nu / nu_ref) ** 0.21
    return f, b0, b1, ch, p.seal_torque_nm


@settings(max_examples=60, deadline=None)
@given(rpm=st.floats(-3000, 3000).filter(lambda v: abs(v) > 1.0),
       load=st.floats(-1200, 1200), temp=st.floats(-10, 90))
def test_energy_balance(rpm: float, load: float, temp: float) -> None:
    """P_in - P_out = mesh + bearing (load) + bearing (drag) + churning + seals, with each
    loss computed here; both power-flow directions and every temperature."""
    m = model()
    w = np.array([rpm * RPM])
    ld = np.array([load])
    t_in = m.input_torque_nm(w, ld, temp)
    p_in = t_in * w
    p_out = ld * w / m.params.gear_ratio
    f, b0, b1, ch, seal = independent_terms(m, w, ld, temp)
    losses = (f * abs(load) / m.params.gear_ratio + b0 + b1 + ch + seal) * abs(w)
    assert p_in - p_out == pytest.approx(losses, rel=1e-9, abs=1e-9)
    assert m.loss_powers(w, ld, temp).total_w == pytest.approx(losses, rel=1e-9, abs=1e-9)
    assert np.all(losses > 0)


def test_mesh_efficiencies_forward_and_backward() -> None:
    """Mesh losses only: forward efficiency 1/(1+f), backward (output drives) 1 - f."""
    m = model(bearing_f0=0.0, bearing_f1=0.0, churn_torque_ref_nm=0.0, seal_torque_nm=0.0)
    p = m.params
    w = p.reference_speed_rpm * RPM
    f = p.mesh_loss_ref            # at the reference point every factor is 1
    eta = m.efficiency(w, p.reference_torque_nm, p.reference_temp_degc)
    assert float(eta) == pytest.approx(1 / (1 + f), rel=1e-12)
    # reverse power flow: the load drives (negative load at positive speed)
    t_in = float(m.input_torque_nm(w, -p.reference_torque_nm, p.reference_temp_degc))
    back = (t_in * w) / (-p.reference_torque_nm * w / p.gear_ratio)
    assert back == pytest.approx(1 - f, rel=1e-12)


def test_input_torque_is_load_over_i_eta_plus_drag() -> None:
    """T_in = T_out / (i eta_mesh) + no-load drag when the bearing load term is off."""
    m = model(bearing_f1=0.0)
    p = m.params
    for rpm, temp in ((500.0, 20.0), (2000.0, 45.0)):
        w = rpm * RPM
        load = 0.6 * p.reference_torque_nm
        f, b0, _, ch, seal = independent_terms(m, np.array([w]), np.array([load]), temp)
        eta_mesh = 1 / (1 + f)
        want = load / (p.gear_ratio * eta_mesh) + (b0 + ch + seal)
        assert float(m.input_torque_nm(w, load, temp)) == pytest.approx(float(want[0]),
                                                                         rel=1e-12)
        assert float(m.no_load_torque_nm(w, temp)) == pytest.approx(float((b0 + ch + seal)[0]))


def test_no_load_torque_trends() -> None:
    """Falls as the oil warms, rises with speed (what catalogues show)."""
    m = model()
    w = np.array([250.0, 500.0, 1000.0, 2000.0, 3000.0]) * RPM
    cold, warm = m.no_load_torque_nm(w, 10.0), m.no_load_torque_nm(w, 50.0)
    assert np.all(np.diff(cold) > 0) and np.all(np.diff(warm) > 0)
    assert np.all(warm < cold)


def test_palmgren_continuous_and_low_speed_branch() -> None:
    f0, dm = 10.0, 0.04
    lo = float(palmgren_m0_nm(1.0, 1.0, f0, dm))
    assert lo == pytest.approx(160e-7 * f0 * 40.0 ** 3 / 1000, rel=1e-12)
    knee = 160.0 ** 1.5
    assert float(palmgren_m0_nm(knee * (1 - 1e-9), 1.0, f0, dm)) == pytest.approx(lo)
    assert float(palmgren_m0_nm(knee * (1 + 1e-9), 1.0, f0, dm)) == pytest.approx(lo)
    hi = float(palmgren_m0_nm(100.0, 1000.0, f0, dm))
    assert hi == pytest.approx(1e-7 * f0 * 1e5 ** (2 / 3) * 40.0 ** 3 / 1000, rel=1e-12)


def test_starting_and_back_driving_from_the_static_values() -> None:
    """Breakaway = k_s x (Palmgren low branch + seals) + (1 + f_s) T / i + bearing load;
    back-driving balances (1 - f_s) T_bd / i against it; self-locking gives inf."""
    m = model()
    p = m.params
    d0 = p.bearing_count * p.bearing_speed_ratio * 160e-7 * p.bearing_f0 \
        * (p.bearing_dm_m * 1000) ** 3 / 1000 + p.seal_torque_nm
    c1 = p.bearing_f1 * p.bearing_load_n_per_nm * p.bearing_dm_m * p.bearing_speed_ratio
    assert float(m.starting_torque_nm()) == pytest.approx(p.static_to_kinetic * d0, rel=1e-12)
    load = 300.0
    assert float(m.starting_torque_nm(load)) == pytest.approx(
        p.static_to_kinetic * d0 + (1 + p.mesh_loss_static) * load / p.gear_ratio + c1 * load,
        rel=1e-12)
    t_bd = m.back_driving_torque_nm()
    assert (1 - p.mesh_loss_static) * t_bd / p.gear_ratio == pytest.approx(
        p.static_to_kinetic * d0 + c1 * t_bd, rel=1e-12)
    # breakaway is above the running drag at the lowest speeds (static > kinetic)
    assert float(m.starting_torque_nm()) > float(m.no_load_torque_nm(1e-3, 20.0))
    locked = model(mesh_loss_static=1.05)
    assert locked.back_driving_torque_nm() == math.inf


def test_held_shaft_and_inertia() -> None:
    m = model()
    i = m.params.gear_ratio
    assert float(m.input_torque_nm(0.0, 500.0, 20.0)) == pytest.approx(500.0 / i)
    assert float(m.loss_powers(0.0, 500.0, 20.0).total_w) == 0.0
    w, alpha = 100.0, 250.0
    extra = m.input_torque_nm(w, 200.0, 20.0, alpha_in_rad_s2=alpha) \
        - m.input_torque_nm(w, 200.0, 20.0)
    assert float(extra) == pytest.approx(m.params.inertia_in_kgm2 * alpha, rel=1e-12)


def test_every_preset_has_a_loss_model() -> None:
    for name in available_presets():
        m = LossModel.from_preset(load_preset(name))
        assert 0.5 < float(m.efficiency(1000 * RPM, m.params.reference_torque_nm, 20.0)) < 1
        assert 0 < m.back_driving_torque_nm() < m.params.reference_torque_nm


def test_bad_input_named() -> None:
    m = model()
    with pytest.raises(ModelInputError, match='load_nm must be finite'):
        m.input_torque_nm(1.0, float('nan'), 20.0)
    with pytest.raises(ModelInputError, match=r'losses\.static_to_kinetic must be >= 1'):
        dataclasses.replace(m.params, static_to_kinetic=0.5)
    with pytest.raises(ModelInputError, match=r'mesh_loss_static \(.*\) must be >= mesh_loss_ref'):
        dataclasses.replace(m.params, mesh_loss_static=0.0)
    with pytest.raises(ModelInputError, match=r'losses\.bearing_dm_m must be finite and > 0'):
        dataclasses.replace(m.params, bearing_dm_m=0.0)
    base = load_preset('rv-80e-101')
    bad = Preset(base.name, base.model, base.description,
                 {**base.values, 'losses.gear_ratio': base.values['losses.seal_torque_nm']})
    with pytest.raises(PresetError, match=r"unknown key losses\.gear_ratio"):
        LossParams.from_preset(bad)
    short = Preset(base.name, base.model, base.description,
                   {k: v for k, v in base.values.items() if k != 'losses.bearing_f1'})
    with pytest.raises(PresetError, match=r"has no losses\.bearing_f1"):
        LossParams.from_preset(short)
    bare = preset_from_text('name = "x"\nmodel = "wang2020-2kv"\n')
    with pytest.raises(PresetError, match=r"'x' has no \[losses\] section"):
        LossParams.from_preset(bare)


def test_override_reaches_the_model() -> None:
    m = LossModel.from_preset(load_preset('rv-80e-101', ['losses.seal_torque_nm=0.5']))
    assert m.params.seal_torque_nm == 0.5
