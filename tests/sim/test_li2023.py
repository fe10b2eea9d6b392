"""Tests of sim.li2023 (Li 2023 RV lumped-parameter model).

Expected values come from the paper (Table 1 ratio, 31.9 deg pressure angle, 0.78"/17.25"
DTE), closed forms (involute contact ratio, cycloid curvature, Hertz line contact,
static deflection = load / stiffness along the kinematic chain, modal step response) or
exact properties (kinematic motion is deflection-free, block-by-block = one-shot).
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.linalg import eigh

from sim.errors import ModelInputError, PresetError
from sim.kinematics import kinematics_from_preset
from sim.li2023 import (
    Li2023DteModel,
    _cycloid_curvature_radius,
    _hertz_stiffness,
    build_te_model,
    ltca,
    params_from_preset,
)
from sim.models import build_te_model as registry_build
from sim.presets import load_preset
from sim.units import rad_to_arcsec, rpm_to_rad_s

PAPER_BETA_DEG = 31.9          # Li 2023 s.4.1, unmodified profile
PAPER_DTE_PP_NO_ERR_ARCSEC = 0.78
PAPER_DTE_PP_ERR_ARCSEC = 17.25


@pytest.fixture(scope='module')
def preset():
    return load_preset('li2023-rv')


@pytest.fixture(scope='module')
def params(preset):
    return params_from_preset(preset)


def _model(preset, **overrides: str) -> Li2023DteModel:
    return build_te_model(preset.with_overrides(overrides), 'dte')


def _drive(n: int, fs_hz: float = 1000.0, rpm: float = 1500.0, load_nm: float = 450.0,
           t0_s: float = 0.0) -> tuple[np.ndarray, ...]:
    t = t0_s + np.arange(n) / fs_hz
    w = float(rpm_to_rad_s(rpm))
    return t, w * t, np.full(n, w), np.full(n, load_nm)


# ---------------------------------------------------------------------------- preset

def test_preset_values_have_unit_and_source(preset) -> None:
    assert preset.model == 'li2023-rv'
    for row in preset.describe_rows():
        if row['key'] == 'errors.enabled' or row['key'] == 'kinematics.kind':
            continue
        assert row['unit'], row['key']
        assert row['source'], row['key']
        if 'assumption' in row['source']:
            assert row['note'], f'{row["key"]}: assumptions must say why'


def test_ratio_is_table1_value(preset) -> None:
    kin = kinematics_from_preset(preset)
    assert kin.gear_ratio == pytest.approx(121.0, abs=1e-12)      # Table 1: i = 121
    assert _model(preset).kinematics.gear_ratio == pytest.approx(121.0, abs=1e-12)


def test_contact_ratio_matches_involute_geometry(preset, params) -> None:
    # standard contact ratio of an external involute pair, computed from Table 1 here
    m, a = params.module_m, math.radians(params.pressure_angle_deg)
    r1, r2 = m * params.z_sun / 2, m * params.z_planet / 2
    ha = preset['geometry.addendum_coefficient']
    ra1, ra2 = r1 + ha * m, r2 + ha * m
    rb1, rb2 = r1 * math.cos(a), r2 * math.cos(a)
    eps = (math.sqrt(ra1**2 - rb1**2) + math.sqrt(ra2**2 - rb2**2)
           - (r1 + r2) * math.sin(a)) / (math.pi * m * math.cos(a))
    assert params.sun_planet_contact_ratio == pytest.approx(eps, abs=5e-4)


@pytest.mark.parametrize(('key', 'value'), [
    ('mass.sun_kg', '-1.0'), ('stiffness.turning_arm_bearing_n_m', '0.0'),
    ('material.poisson', '1.5'), ('layout.n_cranks', '0'), ('kinematics.z_ring', '41'),
    ('stiffness.sun_planet_contact_ratio', '2.5'), ('errors.cam_ecc_m', '-1e-6'),
])
def test_bad_preset_value_names_key(preset, key: str, value: str) -> None:
    with pytest.raises(PresetError, match=key.split('.')[-1]):
        params_from_preset(preset.with_overrides({key: value}))


def test_unknown_mode_is_named(preset) -> None:
    with pytest.raises(ModelInputError, match='nlte'):
        build_te_model(preset, 'nlte')


def test_registry_builds_the_model(preset) -> None:
    model = registry_build(preset, 'dte')
    assert isinstance(model, Li2023DteModel)
    assert model.ndof == 6 * 3 + 3 * 2 + 6


def test_dof_count_follows_layout(preset) -> None:
    model = _model(preset, **{'layout.n_cranks': '2', 'layout.n_discs': '1'})
    assert model.ndof == 6 * 2 + 3 * 1 + 6


# ---------------------------------------------------------------------------- LTCA

def test_cycloid_curvature_matches_closed_form(params) -> None:
    # theoretical-profile radius rho0 = r_p S^3 / (K1 (1 + z_p) cos th - (1 + z_p K1^2)),
    # S = sqrt(1 + K1^2 - 2 K1 cos th) (cycloid-drive textbooks; > 0: concave tooth)
    p = params
    k1 = p.eccentricity_m * p.z_pin / p.pin_circle_radius_m
    th = np.linspace(0.05, 2 * np.pi - 0.05, 37)
    rho0 = (p.pin_circle_radius_m * (1 + k1**2 - 2 * k1 * np.cos(th)) ** 1.5
            / (k1 * (1 + p.z_pin) * np.cos(th) - (1 + p.z_pin * k1**2)))
    rho_c = _cycloid_curvature_radius(th, p)
    # tooth = locus offset inwards by the pin radius: convex r - r_rp, concave r + r_rp
    expected = np.where(rho0 < 0, -rho0 - p.pin_radius_m, -(rho0 + p.pin_radius_m))
    np.testing.assert_allclose(rho_c, expected, rtol=1e-9)


def test_hertz_stiffness_equals_eq2_by_hand(params) -> None:
    p = params
    force, rho_c = 500.0, 0.02
    c = (1 - 0.3**2) / 206e9
    r_star = 1 / (1 / 0.003 + 1 / 0.02)
    b = math.sqrt(4 * force * r_star * 2 * c / (math.pi * 0.012))    # Hertz half-width
    k = math.pi * 0.012 / (2 * (c * (math.log(4 * 0.02 / b) - 0.5)
                                + c * (math.log(4 * 0.003 / b) - 0.5)))
    got = _hertz_stiffness(np.array([force]), np.array([rho_c]), p)[0]
    assert got == pytest.approx(k, rel=1e-12)
    assert 1e8 < got < 1e9                       # order of a steel pin contact


def test_equivalent_pressure_angle_near_paper(params) -> None:
    res = ltca(params)
    beta_deg = np.degrees(res.pressure_angle_rad)
    # paper: 31.5..32.1 deg, mean 31.9; tolerance 1.5 deg (Eq. 2 contact-width convention
    # and the curvature model are not fully specified in the paper)
    assert abs(beta_deg.mean() - PAPER_BETA_DEG) < 1.5
    assert np.ptp(beta_deg) < 1.5
    # unmodified profile, no backlash: every pin on the loaded half touches (Eq. 3)
    assert set(np.unique(res.contacts)) <= {params.z_pin // 2 - 1, params.z_pin // 2}


def test_ltca_moment_equilibrium_and_rigid_limit(params) -> None:
    # Rigid-profile limit (constant pin stiffness): beta from Eq. 5 with F_i ~ l_i, computed
    # here independently; the Hertz LTCA must stay within 1 deg of it.
    p = params
    k1 = p.eccentricity_m * p.z_pin / p.pin_circle_radius_m
    th = 2 * np.pi * np.arange(p.z_pin) / p.z_pin + 1e-3
    lever = np.sin(th) / np.sqrt(1 + k1**2 - 2 * k1 * np.cos(th))   # l_i / r_c
    lever = lever[lever > 0]
    beta_rigid = math.degrees(math.atan(np.sum(lever * np.sqrt(1 - lever**2))
                                        / np.sum(lever**2)))
    res = ltca(p, crank_angle_rad=np.array([1e-3]))
    assert abs(math.degrees(res.pressure_angle_rad[0]) - beta_rigid) < 1.0
    # doubling the torque changes k_cr only through the Hertz log terms (< 10 %)
    k_lo = ltca(p, torque_nm=100.0).mesh_stiffness_n_m.mean()
    k_hi = ltca(p, torque_nm=200.0).mesh_stiffness_n_m.mean()
    assert 1.0 < k_hi / k_lo < 1.1


def test_ltca_rejects_bad_torque(params) -> None:
    with pytest.raises(ModelInputError, match='torque_nm'):
        ltca(params, torque_nm=-1.0)


# ------------------------------------------------------------------- stiffness matrix

def _kinematic_motion(model: Li2023DteModel, theta_in: float, d_in: float) -> np.ndarray:
    """Rigid-body motion for an input advance d_in at input angle theta_in (by hand)."""
    p, lay = model.params, model._lay
    i = p.gear_ratio
    th_o, th_crank = d_in / i, -p.z_cycloid * d_in / i     # output; crank abs = -z_c out
    q = np.zeros(model.ndof)
    q[2] = d_in
    for k in range(lay.m):
        psi = 2 * np.pi * k / lay.m
        e_t = np.array([-np.sin(psi), np.cos(psi)])
        for base in (lay.planet[k], lay.crank[k]):
            q[base:base + 2] = th_o * p.crank_circle_radius_m * e_t
            q[base + 2] = th_crank
    phi_rel = theta_in * p.z_pin / i * -1.0                  # crank rel. = -z_r out
    for j in range(lay.n):
        phi = phi_rel + 2 * np.pi * j / lay.n
        q[lay.disc[j]:lay.disc[j] + 2] = (p.eccentricity_m * th_crank
                                          * np.array([-np.sin(phi), np.cos(phi)]))
        q[lay.disc[j] + 2] = th_o
    q[lay.out + 2] = th_o
    return q


def test_kinematic_motion_deflects_only_the_input_shaft(preset) -> None:
    model = _model(preset)
    thetas = np.array([0.0, 0.37, 2.9, 17.3, 101.0])
    stiff = model.stiffness_matrix(thetas)
    for theta, k in zip(thetas, stiff, strict=True):
        q = _kinematic_motion(model, float(theta), 1e-3)
        force = k @ q
        expected = np.zeros(model.ndof)
        expected[2] = model.params.k_sun_torsion_nm_rad * 1e-3
        np.testing.assert_allclose(force, expected, atol=1e-6 * abs(expected[2]))


def test_stiffness_symmetric_positive_definite(preset) -> None:
    stiff = _model(preset).stiffness_matrix(np.linspace(0.0, 40.0, 7))
    np.testing.assert_allclose(stiff, np.swapaxes(stiff, 1, 2), rtol=0, atol=1e-3)
    assert np.all(np.linalg.eigvalsh(stiff) > 0)


_STIFF_KEYS = ('stiffness.sun_torsional_nm_rad', 'stiffness.sun_radial_n_m',
               'stiffness.crank_torsional_nm_rad', 'stiffness.crank_bending_n_m',
               'stiffness.crank_bearing_n_m', 'stiffness.turning_arm_bearing_n_m',
               'stiffness.output_radial_n_m', 'stiffness.sun_planet_mesh_n_m',
               'stiffness.pin_mesh_n_m')


def _all_rigid_but(preset, keep: str) -> dict[str, str]:
    """Overrides that make every spring 1e6 x stiffer except ``keep`` (no harmonics)."""
    ov = {k: str(preset[k] * 1e6) for k in _STIFF_KEYS if k != keep}
    ov.update({'stiffness.sun_planet_harmonics': '0', 'stiffness.pin_mesh_harmonics': '0',
               'errors.enabled': 'false'})
    return ov


def test_static_te_input_shaft_only(preset) -> None:
    # only k_st flexible: output torque T reaches the input as T / i, twists the shaft by
    # T / (i k_st), the output follows at 1 / i: TE = -T / (i^2 k_st)
    model = _model(preset, **_all_rigid_but(preset, 'stiffness.sun_torsional_nm_rad'))
    load = 450.0
    te = model.static_response(0.7, load)[model._lay.out + 2]
    i, k_st = 121.0, preset['stiffness.sun_torsional_nm_rad']
    # tolerance: the 'rigid' springs keep ~1e-4 of the compliance
    assert te == pytest.approx(-load / (i**2 * k_st), rel=1e-3)


def test_static_te_pin_mesh_only(preset) -> None:
    # only the pin mesh flexible, sun held: carrier rotation phi turns the cranks by
    # phi (1 + z_s / z_p) relative to the sun and the disc by phi; the pin-mesh deflection
    # is e cos(beta) phi (1 + z_s / z_p + z_c) per disc, so
    # TE = -T / (N k_cr (e cos(beta) (1 + z_s / z_p + z_c))^2)
    model = _model(preset, **_all_rigid_but(preset, 'stiffness.pin_mesh_n_m'))
    p, load = model.params, 450.0
    te = model.static_response(1.3, load)[model._lay.out + 2]
    lever = p.eccentricity_m * math.cos(model.beta_rad) * (
        1 + p.z_sun / p.z_planet + p.z_cycloid)
    assert te == pytest.approx(-load / (p.n_discs * p.k_pin_mesh_n_m * lever**2), rel=1e-3)


# ------------------------------------------------------------------------ integration

def test_newmark_matches_modal_step_response(preset) -> None:
    # Input at rest -> K constant; no damping. A load step on the output has the exact
    # modal solution sum_k phi_k phi_k^T F (1 - cos w_k t) / w_k^2 (eigh of K, M here).
    model = _model(preset, **{'errors.enabled': 'false', 'damping.zeta': '0.0',
                              'solver.max_step_s': '1e-6'})
    k = model.stiffness_matrix(np.array([0.0]))[0]
    w2, modes = eigh(k, model.mass_matrix)                     # mass-normalised modes
    io = model._lay.out + 2
    load, tau = 450.0, 1e-8                                    # ramp of tau ~ a step
    t = np.concatenate([[0.0, tau], tau + np.arange(1, 151) * 1e-5])
    n = t.size
    te = model.te_rad(t, np.zeros(n), np.zeros(n), np.r_[0.0, np.full(n - 1, load)])
    ts = np.clip(t - tau / 2.0, 0.0, None)[:, None]            # ramp ~ step at tau / 2
    gain = modes[io] * (-load) * modes[io] / w2
    exact = (1.0 - np.cos(np.sqrt(w2) * ts)) @ gain
    scale = np.abs(exact).max()
    np.testing.assert_allclose(te, exact, rtol=0, atol=1e-4 * scale)   # Newmark, w h < 0.07
    # the static part is the static deflection load / stiffness along the output
    static = np.linalg.solve(k, -load * np.eye(k.shape[0])[io])[io]
    assert gain.sum() == pytest.approx(static, rel=1e-9)


def test_block_by_block_equals_one_shot(preset) -> None:
    t, th, om, ld = _drive(700)
    one = _model(preset).te_rad(t, th, om, ld)
    model = _model(preset)
    parts = [model.te_rad(t[a:b], th[a:b], om[a:b], ld[a:b])
             for a, b in ((0, 1), (1, 64), (64, 65), (65, 400), (400, 700))]
    np.testing.assert_allclose(np.concatenate(parts), one, rtol=0, atol=1e-15)
    model.reset()
    np.testing.assert_allclose(model.te_rad(t, th, om, ld), one, rtol=0, atol=1e-15)


def test_state_size_stays_flat(preset) -> None:
    model = _model(preset)
    for k in range(5):
        t, th, om, ld = _drive(100, t0_s=0.1 * k)
        model.te_rad(t, th, om, ld)
        assert model._state.shape == (3 * model.ndof,)
    assert len(model._ops_cache) <= 65


def test_te_rad_input_checks(preset) -> None:
    model = _model(preset)
    t, th, om, ld = _drive(10)
    with pytest.raises(ModelInputError, match='1-D'):
        model.te_rad(t, th[:-1], om, ld)
    with pytest.raises(ModelInputError, match='increasing'):
        model.te_rad(t[::-1], th, om, ld)
    with pytest.raises(ModelInputError, match='finite'):
        model.te_rad(t, np.where(t > 0.004, np.nan, th), om, ld)
    model.te_rad(t, th, om, ld)
    with pytest.raises(ModelInputError, match='increasing'):
        model.te_rad(t, th, om, ld)                          # time went back


def test_sun_eccentricity_excites_no_torsion(preset) -> None:
    # Three equally spaced planets meshing in phase (z_s psi_i = 0 mod 2 pi): a sun
    # eccentricity is a pure translational excitation, decoupled from the TE.
    off = {k: '0.0' for k in preset.keys()  # noqa: SIM118 - a Preset is no dict: no __iter__
           if k.startswith('errors.') and k.endswith('_m')}
    t, th, om, ld = _drive(150)
    ideal = _model(preset, **{'errors.enabled': 'false'}).te_rad(t, th, om, ld)
    ecc = _model(preset, **{**off, 'errors.sun_ecc_m': '5e-6'}).te_rad(t, th, om, ld)
    np.testing.assert_allclose(ecc, ideal, rtol=0, atol=1e-9 * np.abs(ideal).max())
    e_cr = _model(preset, **{**off, 'errors.pin_composite_m': '5e-6'}).te_rad(t, th, om, ld)
    assert np.abs(e_cr - ideal).max() > 1e-3 * np.abs(ideal).max()


# --------------------------------------------------------------- acceptance (paper)

@pytest.fixture(scope='module')
def one_revolution(preset):
    """DTE [arcsec] over one output revolution at 1500 rpm, 450 N m, 1 kHz, both cases."""
    fs, warm = 1000.0, 500
    nrev = round(fs * 121 / 25.0)                       # 4840 samples = 1 output rev
    t, th, om, ld = _drive(warm + nrev, fs_hz=fs)
    out = {}
    for enabled in ('false', 'true'):
        te = _model(preset, **{'errors.enabled': enabled}).te_rad(t, th, om, ld)
        out[enabled] = rad_to_arcsec(te[warm:])
    return out


def test_dte_without_errors_below_one_arcsec(one_revolution) -> None:
    dte = one_revolution['false']
    assert np.ptp(dte) < 1.0                                 # paper 0.78"
    assert np.ptp(dte) > 0.1 * PAPER_DTE_PP_NO_ERR_ARCSEC    # mesh excitation is there


def test_dte_with_errors_ten_times_larger(one_revolution) -> None:
    pp_ideal = np.ptp(one_revolution['false'])
    pp_err = np.ptp(one_revolution['true'])
    assert pp_err >= 10.0 * pp_ideal
    assert 0.5 * PAPER_DTE_PP_ERR_ARCSEC < pp_err < 2.0 * PAPER_DTE_PP_ERR_ARCSEC


def test_error_spectrum_has_more_orders(one_revolution) -> None:
    # one output revolution -> FFT bin k is output order k; single-sided peak amplitude
    def lines(x: np.ndarray, threshold_arcsec: float = 0.05) -> set[int]:
        amp = 2.0 * np.abs(np.fft.rfft(x - x.mean())) / x.size
        return set(np.nonzero(amp > threshold_arcsec)[0].tolist())

    ideal, err = lines(one_revolution['false']), lines(one_revolution['true'])
    # ideal: the two mesh orders, stage 1 z_p (i - 1) / ... = 1440, pins z_r z_c = 1560
    assert {1440, 1560} <= ideal
    assert ideal < err                                       # strictly more orders
    assert 1 in err                                          # once per output revolution


def test_response_records_states_consistently(preset) -> None:
    t, th, om, ld = _drive(120)
    te = _model(preset).te_rad(t, th, om, ld)
    model = _model(preset)
    idx = [model.state_index('output', 0, 'theta'), model.state_index('disc', 1, 'x'),
           model.state_index('output', 0, 'theta', 'v')]
    resp = model.response(t, th, om, ld, idx)
    assert resp.shape == (120, 3)
    np.testing.assert_allclose(resp[:, 0], te, rtol=0, atol=1e-15)
    # velocity state against the central difference of the angle (1 kHz, ~300 Hz content)
    rate = np.gradient(resp[:, 0], t)
    assert np.corrcoef(rate[5:-5], resp[5:-5, 2])[0, 1] > 0.9
    with pytest.raises(ModelInputError, match='member'):
        model.state_index('ring', 0)
    with pytest.raises(ModelInputError, match='state_indices'):
        model.response(t + 1.0, th, om, ld, [3 * model.ndof])


def test_dte_without_errors_below_one_arcsec_at_10khz(preset) -> None:
    # the continuous waveform (10 kHz samples, 1e-4 s steps) peaks a little higher than
    # its 1 kHz samples; still below 1" (paper 0.78")
    t, th, om, ld = _drive(4000, fs_hz=10_000.0)
    dte = rad_to_arcsec(_model(preset, **{'errors.enabled': 'false'}).te_rad(t, th, om, ld))
    assert np.ptp(dte[1500:]) < 1.0


def test_mesh_stiffness_waves(preset) -> None:
    # Eq. 9: rectangular wave k1 / 2 k1 with the double-pair zone (eps - 1) of the period;
    # Eq. 11: the pin-mesh curve scaled to the preset mean (paper 1.24e9 N/m)
    model = _model(preset, **{'stiffness.sun_planet_harmonics': '60'})
    p = model.params
    n = 4000
    sun_rel = np.arange(n) / n * 2 * np.pi / p.z_sun           # one stage-1 mesh period
    theta_in = sun_rel * p.gear_ratio / (p.gear_ratio - 1)
    ksp, _ = model._mesh_stiffness(model._angles(theta_in))
    k1 = p.k_sun_planet_n_m / p.sun_planet_contact_ratio
    assert ksp[:, 0].mean() == pytest.approx(p.k_sun_planet_n_m, rel=1e-9)
    assert np.mean(ksp[:, 0] > 1.5 * k1) == pytest.approx(p.sun_planet_contact_ratio - 1,
                                                          abs=0.02)
    crank = np.arange(n) / n * 2 * np.pi / p.z_pin             # one pin-mesh period
    _, kcr = model._mesh_stiffness(model._angles(crank / model.kinematics.crank_per_input))
    assert kcr.mean() == pytest.approx(preset['stiffness.pin_mesh_n_m'], rel=1e-9)


@settings(max_examples=8, deadline=None)
@given(cuts=st.lists(st.integers(1, 239), max_size=4, unique=True))
def test_any_block_split_equals_one_shot(cuts: list[int]) -> None:
    preset = load_preset('li2023-rv')
    t, th, om, ld = _drive(240, fs_hz=2000.0, rpm=700.0, load_nm=200.0)
    ld = ld * (1.0 + 0.3 * np.sin(7.0 * t))                    # varying load as well
    one = _model(preset).te_rad(t, th, om, ld)
    model = _model(preset)
    edges = [0, *sorted(cuts), 240]
    parts = [model.te_rad(t[a:b], th[a:b], om[a:b], ld[a:b])
             for a, b in itertools.pairwise(edges)]
    np.testing.assert_allclose(np.concatenate(parts), one, rtol=0, atol=1e-15)


@pytest.mark.parametrize('nu', ['0.7', '1.0', '0.5'])
def test_li2023_rejects_impossible_poisson_ratio(nu: str) -> None:
    from sim.li2023 import build_te_model

    with pytest.raises(PresetError, match=r'material\.poisson'):
        build_te_model(load_preset('li2023-rv', [f'material.poisson={nu}']), 'dte')


@pytest.mark.parametrize('errors', ['false', 'true'])
def test_te_path_equals_full_state_stepping(preset, errors: str) -> None:
    """The TE path (z = [p; a2 M w], watched displacements only) and the stepping on the
    whole state x = [q, v, a] (taken when a velocity is watched as well) are two codings
    of one Newmark scheme: equal to rounding over 0.2 s at 10 kHz, blocks of 100, with a
    load change, and the state handed over between them in both directions."""
    a_model = _model(preset, **{'errors.enabled': errors})
    b_model = _model(preset, **{'errors.enabled': errors})
    io = a_model.state_index('output')
    iv = a_model.state_index('output', kind='v')
    t, th, om, ld = _drive(2000, fs_hz=10_000.0)
    ld[1000:] = 300.0
    te_a, te_b = [], []
    for s in range(0, t.size, 100):
        sl = slice(s, s + 100)
        # A: TE path, then whole state; B: the other way round (hand-over both ways)
        wa, wb = ([io], [io, iv]) if s < 1000 else ([io, iv], [io])
        te_a.append(a_model.response(t[sl], th[sl], om[sl], ld[sl], wa)[:, 0])
        te_b.append(b_model.response(t[sl], th[sl], om[sl], ld[sl], wb)[:, 0])
    te_a, te_b = np.concatenate(te_a), np.concatenate(te_b)
    assert rad_to_arcsec(np.abs(te_a - te_b).max()) < 1e-9
    assert rad_to_arcsec(np.ptp(te_a)) > 0.1


def test_without_the_direct_lapack_call_the_te_is_the_same(preset, monkeypatch) -> None:
    """Where SciPy's Cython LAPACK table cannot be reached (``_DPOSV`` is None), the TE path
    falls back to the whole-state stepping through SciPy's dposv wrapper: the same TE to
    rounding as the direct call, over 0.1 s at 10 kHz with the Table 3 errors."""
    import sim.li2023 as li

    assert li._DPOSV is not None, 'the direct LAPACK call is not available here'
    direct = _model(preset, **{'errors.enabled': 'true'})
    io = direct.state_index('output')
    t, th, om, ld = _drive(1000, fs_hz=10_000.0)
    te_direct = np.concatenate([direct.response(t[s:s + 100], th[s:s + 100], om[s:s + 100],
                                                ld[s:s + 100], [io])[:, 0]
                                for s in range(0, t.size, 100)])
    monkeypatch.setattr(li, '_DPOSV', None)
    wrapped = _model(preset, **{'errors.enabled': 'true'})
    calls: list[int] = []
    real = li._dposv

    def counting(*args: object, **kwargs: object) -> object:
        calls.append(1)
        return real(*args, **kwargs)

    monkeypatch.setattr(li, '_dposv', counting)
    te_wrapped = np.concatenate([wrapped.response(t[s:s + 100], th[s:s + 100],
                                                  om[s:s + 100], ld[s:s + 100], [io])[:, 0]
                                 for s in range(0, t.size, 100)])
    assert len(calls) == t.size - 1        # a wrapped solve per step after the first sample
    assert rad_to_arcsec(np.abs(te_direct - te_wrapped).max()) < 1e-9
    assert rad_to_arcsec(np.ptp(te_direct)) > 0.1
