"""Tests of sim.kinematics against the numbers of DESIGN.md s.4 and the papers."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from sim.errors import PresetError
from sim.kinematics import (
    ReducerKinematics,
    kinematics_2kv,
    kinematics_from_preset,
    kinematics_rv,
)
from sim.presets import preset_from_text

WANG = (12, 36, 50, 52)


def test_wang2020_ratio_and_crank_speeds() -> None:
    kin = kinematics_2kv(*WANG)
    # i = 1 + (36/12) * 52 / (52 - 50) = 79 (exact in floating point to 1e-12)
    assert kin.kind == '2kv'
    assert kin.gear_ratio == pytest.approx(79.0, rel=1e-12)
    # crank relative to carrier -26 n_out, absolute -25 n_out (DESIGN.md s.4)
    assert kin.crank_rel_per_input * kin.gear_ratio == pytest.approx(-26.0, rel=1e-12)
    assert kin.crank_per_input * kin.gear_ratio == pytest.approx(-25.0, rel=1e-12)
    assert kin.crank_per_output == pytest.approx(25.0, rel=1e-12)


def test_wang2020_frequencies_at_300_rpm() -> None:
    kin = kinematics_2kv(*WANG)
    f = kin.frequencies(300.0 / 60.0)
    # Output period 15.8 s (paper's "major cycle"), f_w = 1.582 Hz, 52 f_w = 82.3 Hz
    assert 1.0 / f['output_hz'] == pytest.approx(15.8, rel=1e-9)
    assert kin.output_period_s(5.0) == pytest.approx(15.8, rel=1e-9)
    assert f['crank_hz'] == pytest.approx(1.582, abs=5e-4)
    assert f['crank_rel_hz'] == pytest.approx(26 / 15.8, rel=1e-9)
    assert f['mesh_stage2_hz'] == pytest.approx(82.3, abs=0.05)
    assert f['mesh_stage2_hz'] == pytest.approx(52 * f['crank_hz'], rel=1e-12)
    # stage 1: sun (12 teeth) against the carrier: 12 * (5 - 5/79) Hz
    assert f['mesh_stage1_hz'] == pytest.approx(12 * (5.0 - 5.0 / 79.0), rel=1e-12)
    assert f['input_hz'] == 5.0
    assert all(v > 0 for v in f.values())
    assert kin.frequencies(-5.0) == f


def test_mesh_orders_and_labels() -> None:
    kin = kinematics_2kv(*WANG)
    assert kin.mesh_orders_out == pytest.approx((36 * 26, 52 * 25), rel=1e-12)
    assert len(kin.mesh_labels) == 2
    assert '52 f_w' in kin.mesh_labels[1]


def test_rv_hu2020_table3_and_li2023() -> None:
    hu = kinematics_rv(22, 60, 39, 40)
    assert hu.kind == 'rv'
    assert hu.gear_ratio == pytest.approx(1 + 60 / 22 * 40, rel=1e-12)
    assert round(hu.gear_ratio, 2) == 110.09
    # absolute crank z_c / i x input, relative z_pin / i x input (DESIGN.md s.4)
    assert abs(hu.crank_per_input) == pytest.approx(39 / hu.gear_ratio, rel=1e-12)
    assert abs(hu.crank_rel_per_input) == pytest.approx(40 / hu.gear_ratio, rel=1e-12)
    assert hu.crank_per_output == pytest.approx(39.0, rel=1e-12)
    # pin mesh: 40 pins passed per absolute crank revolution
    assert hu.mesh_orders_out[1] == pytest.approx(40 * 39, rel=1e-12)
    li = kinematics_rv(1, 3, 39, 40)  # Li 2023: first-stage ratio 3, 40 pins
    assert li.gear_ratio == pytest.approx(121.0, rel=1e-12)


def test_member_angles_follow_ratios() -> None:
    kin = kinematics_2kv(*WANG)
    theta_in = np.linspace(0.0, 2 * math.pi * 79, 7)
    ang = kin.member_angles(theta_in)
    assert set(ang) == {'input', 'output', 'crank_abs', 'crank_rel'}
    assert_allclose(ang['output'][-1], 2 * math.pi, rtol=1e-12)
    assert_allclose(ang['crank_abs'][-1], -25 * 2 * math.pi, rtol=1e-12)
    assert_allclose(ang['crank_rel'][-1], -26 * 2 * math.pi, rtol=1e-12)
    # relative = absolute - carrier, at every sample
    assert_allclose(ang['crank_rel'], ang['crank_abs'] - ang['output'], atol=1e-9)


@given(z_sun=st.integers(1, 60), z_planet=st.integers(1, 120), z_gear=st.integers(1, 120),
       dz=st.integers(1, 6))
def test_2kv_willis_identity(z_sun: int, z_planet: int, z_gear: int, dz: int) -> None:
    # Independent check, rolling conditions per stage (carrier = output, speed w_c):
    # stage 2: gear spins at w_c, its centre orbits at w_abs inside the fixed ring:
    #   z_gear * (w_c - w_abs) = z_ring * (0 - w_abs);
    # stage 1 seen from the carrier: z_sun * (w_in - w_c) = -z_planet * w_rel, w_in = 1.
    z_ring = z_gear + dz
    kin = kinematics_2kv(z_sun, z_planet, z_gear, z_ring)
    w_c = 1.0 / kin.gear_ratio
    w_abs = kin.crank_per_input
    w_rel = kin.crank_rel_per_input
    assert z_gear * (w_c - w_abs) == pytest.approx(-z_ring * w_abs, rel=1e-9, abs=1e-12)
    assert z_sun * (1.0 - w_c) == pytest.approx(-z_planet * w_rel, rel=1e-9, abs=1e-12)
    assert w_rel == pytest.approx(w_abs - w_c, rel=1e-9, abs=1e-12)


@pytest.mark.parametrize(('args', 'needle'), [
    ((0, 36, 50, 52), 'z_sun'),
    ((12, -1, 50, 52), 'z_planet'),
    ((12, 36, 52, 52), 'z_ring'),
    ((12, 36, 53, 52), 'greater than'),
    ((12, 36, 50.0, 52), 'integer'),
    ((12, 36, True, 52), 'integer'),
])
def test_2kv_validation(args: tuple, needle: str) -> None:
    with pytest.raises(PresetError, match=needle):
        kinematics_2kv(*args)


def test_rv_validation_names_rule() -> None:
    with pytest.raises(PresetError, match=r'z_pin - z_cycloid must be 1'):
        kinematics_rv(22, 60, 38, 40)
    with pytest.raises(PresetError, match='z_cycloid'):
        kinematics_rv(22, 60, 0, 40)


def test_dataclass_rejects_bad_fields() -> None:
    good = kinematics_2kv(*WANG)
    fields = dict(good.__dict__)
    with pytest.raises(PresetError, match='kind'):
        ReducerKinematics(**{**fields, 'kind': 'harmonic'})
    with pytest.raises(PresetError, match='gear_ratio'):
        ReducerKinematics(**{**fields, 'gear_ratio': -79.0})
    with pytest.raises(PresetError, match='mesh_labels'):
        ReducerKinematics(**{**fields, 'mesh_labels': ('one',)})


def _preset(kind: str, teeth: tuple[int, int, int, int]) -> str:
    zs, zp, zg, zr = teeth
    return (f'name = "t"\nmodel = "x"\n[kinematics]\nkind = "{kind}"\n'
            f'z_sun = {{ value = {zs}, unit = "1", source = "s" }}\n'
            f'z_planet = {{ value = {zp}, unit = "1", source = "s" }}\n'
            f'z_gear = {{ value = {zg}, unit = "1", source = "s" }}\n'
            f'z_ring = {{ value = {zr}, unit = "1", source = "s" }}\n')


def test_from_preset_both_kinds() -> None:
    kin = kinematics_from_preset(preset_from_text(_preset('2kv', WANG)))
    assert kin.gear_ratio == pytest.approx(79.0, rel=1e-12)
    rv = kinematics_from_preset(preset_from_text(_preset('rv', (22, 60, 39, 40))))
    assert rv.kind == 'rv'
    assert rv.gear_ratio == pytest.approx(110.0909, abs=1e-4)


def test_from_preset_errors_name_the_key() -> None:
    with pytest.raises(PresetError, match=r'kinematics\.z_ring'):
        kinematics_from_preset(preset_from_text(_preset('rv', (22, 60, 39, 41))))
    with pytest.raises(PresetError, match=r'kinematics\.z_ring'):
        kinematics_from_preset(preset_from_text(_preset('2kv', (12, 36, 52, 50))))
    with pytest.raises(PresetError, match=r'kinematics\.kind'):
        kinematics_from_preset(preset_from_text(_preset('cyclo', WANG)))
    with pytest.raises(PresetError, match=r'kinematics\.z_gear'):
        kinematics_from_preset(preset_from_text('name = "t"\nmodel = "x"\n[kinematics]\n'
                                                'kind = "2kv"\nz_sun = 1\nz_planet = 2\n'
                                                'z_ring = 3\n'))
