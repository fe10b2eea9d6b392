"""Static torsion models per preset against their papers' own functions and closed forms."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from sim import hu2020, li2023, wang2020
from sim.errors import ModelInputError, PresetError
from sim.presets import load_preset
from sim.program import (
    DriveSegment,
    OutputSpeedSegment,
    ProgramSimulator,
    TorqueSegment,
    program_from_plain,
    program_to_plain,
)
from sim.torsion import TorsionCurve, TorsionParams, expected_metrics, torsion_curve

ARCMIN = math.pi / 10800

NO_ECC = ['eccentricity.e_p1_m=0', 'eccentricity.e_p2_m=0', 'eccentricity.e_g_m=0',
          'eccentricity.e_ot_m=0']


def test_wang_without_eccentricity_is_two_springs_and_the_set_backlash() -> None:
    """Eq. 18 with Delta_1 = Delta_2 = 0: both pairs carry, stiffness 2 k r_p^2; Eq. 9: B."""
    k, b = 6.0e7, 1.5 * ARCMIN
    p = load_preset('wang2020-2kv', [*NO_ECC, f'mesh.stiffness_n_m={k}',
                                     f'backlash.b1_t0_rad={b}', f'backlash.b2_t0_rad={b}'])
    c = torsion_curve(p, 1.234)
    r = p['stage2.r_p_m']
    assert c.backlash_rad == pytest.approx(b, rel=1e-12)
    t = np.array([10.0, 100.0, 300.0])
    assert_allclose(c.deflection_rad(t, side=1), t / (2 * k * r * r), rtol=1e-9)
    assert_allclose(c.deflection_rad(t, side=-1), t / (2 * k * r * r), rtol=1e-9)


@pytest.mark.parametrize('theta_in', [0.0, 7.3, 40.0, 123.4])
def test_wang_backlash_is_eq9_at_the_locked_position(theta_in: float) -> None:
    p = load_preset('wang2020-2kv')
    params = wang2020.Wang2kvParams.from_preset(p)
    c = torsion_curve(p, theta_in)
    eq9 = float(wang2020.backlash_rad(theta_in / params.kinematics.gear_ratio, params))
    assert c.backlash_rad == pytest.approx(eq9, abs=1e-12)
    # the uneven load: one pair alone below the knee, so the first slope is k r_p^2
    inc = wang2020.mesh_increments_m(theta_in / params.kinematics.gear_ratio, params)
    gap_m = abs(float(inc.delta1_m - inc.delta2_m))
    knee_nm = gap_m * params.r_p_m * params.mesh_stiffness_n_m
    if knee_nm > 1.0:
        # reverse torque loads the drive flanks: single pair below the knee
        t = 0.5 * knee_nm
        assert c.deflection_rad(t, side=-1) == pytest.approx(
            t / (params.mesh_stiffness_n_m * params.r_p_m ** 2), rel=1e-6)


def test_hu_curve_is_the_tca_rotation() -> None:
    # the TCA alone: no free play, no parts in series (sim.torsion adds both)
    p = load_preset('hu2020-rv', ['torsion.clearance_rad=0.0',
                                  'torsion.series_stiffness_nm_rad=0.0'])
    params = hu2020.HuRvParams.from_preset(p)
    c = torsion_curve(p)
    for t in (50.0, 392.0, 784.0):
        tca = hu2020.tooth_contact_analysis(params, t)
        beta = tca.delta_max_m / params.r_c_m
        beta0 = float(np.min(tca.clearance_m / tca.lever_arm_m))
        assert float(c.deflection_rad(t, side=1)) == pytest.approx(beta - beta0, rel=2e-3)
        assert c.backlash_rad == pytest.approx(2 * beta0, rel=1e-9)


def test_li_curve_is_the_lumped_static_stiffness() -> None:
    p = load_preset('li2023-rv', ['torsion.clearance_rad=2e-4'])
    m = li2023.build_te_model(p, 'dte')
    i = m.state_index('output')
    rot = m.static_response(0.0, 0.0)[i] - m.static_response(0.0, 300.0)[i]
    c = torsion_curve(p)
    assert float(c.deflection_rad(300.0, side=1)) == pytest.approx(rot, rel=1e-9)
    assert c.backlash_rad == pytest.approx(2e-4)


def test_series_stiffness_adds_compliance() -> None:
    base = torsion_curve(load_preset('li2023-rv'))
    soft = torsion_curve(load_preset('li2023-rv', ['torsion.series_stiffness_nm_rad=1e6']))
    assert float(soft.deflection_rad(200.0, side=1)) == pytest.approx(
        float(base.deflection_rad(200.0, side=1)) + 200.0 / 1e6, rel=1e-12)


def linear_curve(k: float = 1e5, b: float = 2e-4, tf: float = 1.0) -> TorsionCurve:
    t = np.linspace(0.0, 200.0, 5)
    return TorsionCurve(t, t / k, t / k, b, tf)


def test_play_operator_closed_form() -> None:
    k, b, tf = 1e5, 2e-4, 1.0
    c = linear_curve(k, b, tf)
    prog = np.array([0.0, 0.5, 5.0, 100.0, 99.0, 50.0, 0.0, -0.5, -5.0, -100.0, 0.0])
    phi = c.angle_under_torque(prog, 0.0)
    expect = [0.0, 0.0, b / 2 + 4.0 / k, b / 2 + 99.0 / k, b / 2 + 99.0 / k,
              b / 2 + 51.0 / k, b / 2 + 1.0 / k, b / 2 + 0.5 / k, -b / 2 - 4.0 / k,
              -b / 2 - 99.0 / k, -b / 2 - 1.0 / k]
    assert_allclose(phi, expect, rtol=0, atol=1e-15)
    # the elastic torque inverts the flank angles
    assert_allclose(c.elastic_torque_nm(np.array(expect[2:4])), [4.0, 99.0], rtol=1e-12)
    assert c.torque_under_motion([0.0], 1)[0] == pytest.approx(tf)
    assert c.angle_at_torque(50.0, 1) == pytest.approx(b / 2 + 49.0 / k)
    assert c.angle_at_torque(-50.0, -1) == pytest.approx(-b / 2 - 49.0 / k)


def test_expected_metrics_linear() -> None:
    k, b, tf = 1e5, 2e-4, 1.0
    e = expected_metrics(linear_curve(k, b, tf), rated_torque_nm=100.0)
    assert e.backlash_rad == pytest.approx(b + 2 * tf / k)
    assert e.lost_motion_rad == pytest.approx(b + 2 * 3.0 / k)
    assert e.rigidity_nm_per_rad['K'] == pytest.approx((k, k))


@pytest.mark.parametrize(('override', 'match'), [
    ('torsion.friction_torque_nm=-1', 'friction_torque_nm'),
    ('torsion.friction_torque_nm=500', 'friction_torque_nm'),
    ('torsion.clearance_rad=-1e-4', 'clearance_rad'),
    ('torsion.rated_torque_nm=0', 'rated_torque_nm'),
])
def test_bad_torsion_values_are_named(override: str, match: str) -> None:
    with pytest.raises(PresetError, match=match):
        TorsionParams.from_preset(load_preset('li2023-rv', [override]))


@pytest.mark.parametrize('bad', [
    ([0, 1], [0, 1], [0, 1.0], -1.0, 0.0),       # negative backlash
    ([1, 2], [0, 1], [0, 1.0], 0.0, 0.0),        # grid not from zero
    ([0, 1], [0, 0.0], [0, 1.0], 0.0, 0.0),      # flat deflection
])
def test_bad_curve_tables(bad: tuple) -> None:
    with pytest.raises(ModelInputError):
        TorsionCurve(np.array(bad[0], float), np.array(bad[1], float), np.array(bad[2], float),
                     bad[3], bad[4])


# --------------------------------------------------------------------------- programs


def test_program_round_trip_and_errors() -> None:
    prog = program_from_plain([
        {'kind': 'drive', 'speed_rpm': 300, 'duration_s': 1.0, 'load_nm': 5},
        {'kind': 'torque', 'torque_nm': 10, 'duration_s': 0.5},
        {'kind': 'output_speed', 'speed_rad_s': -1e-3, 'target_torque_nm': -10},
    ])
    assert program_from_plain(program_to_plain(prog)) == prog
    for items, match in (([], 'non-empty'), ([{'kind': 'fly'}], "kind 'fly' unknown"),
                         ([{'kind': 'drive', 'speed_rpm': 0, 'duration_s': 1}], 'non-zero'),
                         ([{'kind': 'torque', 'torque_nm': 1}], 'segment 0'),
                         ([{'kind': 'torque', 'torque_nm': 1, 'duration_s': 1, 'x': 1}],
                          "unknown field")):
        with pytest.raises(ModelInputError, match=match):
            program_from_plain(items)


def test_program_blocks_clock_and_locked_input() -> None:
    sim = ProgramSimulator(preset='li2023-rv', te_mode='dte', encoder_in='ideal',
                           encoder_out='ideal', sample_rate_hz=1000.0, block_size=100)
    n = sim.load((DriveSegment(speed_rpm=600.0, duration_s=0.25),
                  TorqueSegment(torque_nm=200.0, duration_s=0.1),
                  OutputSpeedSegment(speed_rad_s=-2e-3, target_torque_nm=-100.0)))
    seqs, segs, theta_in, torque, t0 = [], [], [], [], []
    while sim.running:
        b, i = sim.next_block()
        seqs.append(b.seq)
        segs.append(i)
        theta_in.append(b.theta_in_rad)
        torque.append(b.torque_out_nm)
        t0.append(b.t0_s)
    assert seqs == list(range(n))
    assert segs[:3] == [0, 0, 0] and segs[3] == 1          # 0.25 s -> 3 blocks of 0.1 s
    assert_allclose(np.diff(t0), 0.1, rtol=1e-12)
    th = np.concatenate(theta_in)
    assert np.all(th[300:] == th[300])                        # locked where the drive stopped
    assert th[300] == pytest.approx(600 * 2 * math.pi / 60 * 0.3, rel=1e-12)
    # the loader ends at the target (applied -100 N m: the bench's load is +100 N m)
    assert torque[-1][-1] == pytest.approx(100.0, rel=1e-9)
    assert np.all(torque[3] == -200.0)


def test_program_same_seed_same_data() -> None:
    def run(seed: int) -> np.ndarray:
        sim = ProgramSimulator(preset='wang2020-2kv', seed=seed)
        sim.load((DriveSegment(speed_rpm=300.0, duration_s=0.2),
                  TorqueSegment(torque_nm=30.0, duration_s=0.2)))
        out = []
        while sim.running:
            out.append(sim.next_block()[0].theta_out_rad)
        return np.concatenate(out)

    assert np.array_equal(run(4), run(4))
    assert not np.array_equal(run(4), run(5))


def test_output_speed_target_behind_is_refused() -> None:
    sim = ProgramSimulator(preset='li2023-rv', te_mode='dte')
    with pytest.raises(ModelInputError, match='not ahead'):
        sim.load((TorqueSegment(torque_nm=100.0, duration_s=0.1),
                  OutputSpeedSegment(speed_rad_s=1e-3, target_torque_nm=50.0)))


def test_reverse_drive_moves_to_the_other_flank() -> None:
    """Backwards at no load the 2K-V's TE is the tooth-back curve: forward + Eq. 9."""
    p = load_preset('wang2020-2kv')
    params = wang2020.Wang2kvParams.from_preset(p)
    sim = ProgramSimulator(preset='wang2020-2kv', encoder_in='ideal', encoder_out='ideal')
    sim.load((DriveSegment(speed_rpm=-300.0, duration_s=0.5),))
    b = sim.next_block()[0]
    th_out = b.theta_in_true_rad / params.kinematics.gear_ratio
    assert_allclose(b.te_true_rad, wang2020.nlte_rad(th_out, params)
                    + wang2020.backlash_rad(th_out, params), atol=1e-15)
